// One order of an edge's two vertices whichever triangle asks (the lexicographic one), so
// that neighbours sharing the edge compute its plane from the same numbers, negated, and
// split the samples along it without a gap (lib/footprint.glsl, lib/projective.glsl).

// True when the edge (a, b) is taken the other way round, as (b, a).
bool ow_edge_swapped(vec3 a, vec3 b)
{
  return a.x > b.x || (a.x == b.x && (a.y > b.y || (a.y == b.y && a.z > b.z)));
}
