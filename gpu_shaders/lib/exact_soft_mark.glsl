// The exact pass's test of a sized light (shaders.exact_soft_of), for
// footprint_exact.frag: per view sample, which of the light's points (lib/exact_soft.glsl)
// this triangle blocks, a cluster of points decided whole where the light as a whole allows.
#include "lib/exact_soft.glsl"
#include "lib/soft_reach.glsl"

// Whether the light as a whole decides triangle (plane v_plane, edge planes e0..e2 through
// p, inner sides positive) for sample p at height h over its plane: -1 when no point of the
// light can be blocked, 1 when every point is (an umbra), 0 when each point is to be tested.
// A sphere or area light is held by the sphere of radius ow_exact_reach about the light
// centre (-p from p); a sun's directions by the cone of half angle ow_exact_light.y about
// the frame's +Z.
// Whether every segment from sample p (at height h over the triangle's plane) to the light
// crosses that plane more than ow_exact_eps from p: the whole light lies beyond it, a sun's
// cone of directions wholly leaves towards it.
bool ow_exact_crossing(vec3 p, float h)
{
  if (int(ow_exact_light.x) == OW_LIGHT_SUN_DISK) {
    float nc = dot(v_plane.xyz, ow_exact_frame[2]);
    return h * nc < 0.0 && abs(nc) > ow_exact_light.z && abs(h) > ow_exact_eps * length(p);
  }
  float centre_h = -dot(v_plane.xyz, v_edge_at0);  // the light centre's height
  return centre_h * h < 0.0 && abs(centre_h) > ow_exact_reach
         && abs(h) > ow_exact_eps * (abs(h) + abs(centre_h) + ow_exact_reach);
}

int ow_exact_soft_whole(vec3 p, float h, vec3 e0, vec3 e1, vec3 e2)
{
  vec3 lengths = vec3(length(e0), length(e1), length(e2));
  if (int(ow_exact_light.x) == OW_LIGHT_SUN_DISK) {
    // A ray p + t l crosses the plane at t = -h / (n . l) > 0. Within the cone, n . l keeps
    // the sign of n . c where |n . c| exceeds the half angle's sine.
    vec3 c = ow_exact_frame[2];
    float nc = dot(v_plane.xyz, c);
    float sin_half = ow_exact_light.z;
    if (h * nc >= 0.0 && abs(nc) > sin_half) {
      return -1;  // every direction leaves the plane on the sample's side
    }
    vec3 toward = vec3(dot(e0, c), dot(e1, c), dot(e2, c));
    if (any(lessThan(toward, -lengths * sin_half))) {
      return -1;  // the cone wholly outside one edge plane
    }
    // Inside all three, wholly crossing the plane, and |t| >= |h| > eps |p| for every ray.
    return (all(greaterThan(toward, lengths * sin_half)) && ow_exact_crossing(p, h)) ? 1 : 0;
  }
  float centre_h = -dot(v_plane.xyz, v_edge_at0);  // the light centre's height
  if (centre_h * h > 0.0 && abs(centre_h) >= ow_exact_reach) {
    return -1;  // the whole light on the sample's side of the plane
  }
  // The light's sphere (centre -p from p) against the wedge of the three planes: wholly
  // outside one of them, no segment crosses; wholly inside all three and wholly beyond the
  // triangle's plane, every segment does.
  vec3 reach = lengths * ow_exact_reach;
  vec3 centre_side = vec3(dot(e0, -p), dot(e1, -p), dot(e2, -p));
  if (any(lessThan(centre_side, -reach))) {
    return -1;
  }
  return (all(greaterThan(centre_side, reach)) && ow_exact_crossing(p, h)) ? 1 : 0;
}

// Whether a triangle decides light cluster c (points c * OW_EXACT_SOFT_CLUSTER on) for a
// sample as a whole: -1 when every point lies outside an edge plane, 1 when every point
// lies inside all three and `crossing` says each segment crosses the plane, 0 when its
// points are to be tested one by one. The cluster's box (ow_exact_bounds) bounds the
// points' weights in the axes along0..2 (the per-point test's): an area light's
// (x, y, -1) and a sun's (x, y, z) directly; a sphere's (sin_t cos phi, sin_t sin phi,
// cos_t) through the cap's polar angle at this sample, monotone in the box's u. Each edge's
// side is linear in the weights, so the box gives its least and greatest value; a margin
// of 1e-4 of their size keeps a point whose own test rounds the other way to that test.
int ow_exact_cluster(int c, OwLightView view, mat3 side_matrix, bool crossing)
{
  vec3 lo = ow_exact_bounds[2 * c].xyz;
  vec3 hi = ow_exact_bounds[2 * c + 1].xyz;
  vec3 w_lo = lo;
  vec3 w_hi = hi;
  int kind = int(ow_exact_light.x);
  if (kind == OW_LIGHT_AREA) {
    w_lo.z = -1.0;
    w_hi.z = -1.0;
  } else if (kind == OW_LIGHT_SPHERE) {
    vec2 near = ow_cap_polar(view, vec4(lo.x, 0.0, 0.0, 0.0));  // the least polar angle
    vec2 far = ow_cap_polar(view, vec4(hi.x, 0.0, 0.0, 0.0));
    // sin_t in [near.y, far.y] (>= 0) times cos phi in [lo.y, hi.y], and sin phi likewise.
    w_lo = vec3(min(near.y * lo.y, far.y * lo.y), min(near.y * lo.z, far.y * lo.z), far.x);
    w_hi = vec3(max(near.y * hi.y, far.y * hi.y), max(near.y * hi.z, far.y * hi.z), near.x);
  }
  vec3 mid = side_matrix * (0.5 * (w_lo + w_hi));
  vec3 half_range = mat3(abs(side_matrix[0]), abs(side_matrix[1]), abs(side_matrix[2])) * (0.5 * (w_hi - w_lo));
  vec3 margin = 1e-4 * (half_range + abs(mid));
  if (any(lessThan(mid + half_range, -margin))) {
    return -1;
  }
  return (crossing && all(greaterThan(mid - half_range, margin))) ? 1 : 0;
}

// Whether triangle may block some light point of sample p (not culled by the light's reach,
// not p's own plane); then h, p's height over its plane, and e0..e2, the edge planes
// through p with inner sides positive (each edge's vertices in one order for every
// triangle that has it: neighbours get the same normals negated).
bool ow_exact_soft_edges(vec3 p, out float h, out vec3 e0, out vec3 e1, out vec3 e2)
{
  h = 0.0;
  e0 = e1 = e2 = vec3(0.0);
  // Farther from the triangle's image than the light's angle from it: nothing to shadow
  // (a sun's v_cull never culls).
  vec3 dir = p * inversesqrt(max(dot(p, p), 1e-30));
  float reach_sin = v_cull0.w;
  if (reach_sin <= 1.0) {
    // The sample's own distance cuts tighter than the footprint's growth, which holds for
    // the farthest sample (lib/soft_reach.glsl's ow_soft_reach_sin): a receiver just
    // behind its blocker is cut far tighter. A sample nearer the centre than the whole
    // triangle (and R < d here) has no segment that crosses it.
    float d = v_cull1.w;
    float dist = length(p);
    if (dist < d) {
      return false;
    }
    reach_sin = min(reach_sin, ow_soft_reach_sin(d, ow_exact_reach, dist) + 1e-4);
  }
  if (dot(dir, v_cull0.xyz) < -reach_sin || dot(dir, v_cull1.xyz) < -reach_sin || dot(dir, v_cull2.xyz) < -reach_sin) {
    return false;
  }
  precise float height = dot(v_plane.xyz, p - v_edge_at0);  // p's height over the triangle's plane
  if (height == 0.0) {
    return false;  // on the plane: the receiver itself
  }
  h = height;
  // Edge planes through p, each edge's vertices in one order for every triangle that has
  // it: neighbours get the same normal negated, and no segment passes between them. The
  // segment crosses the triangle when it lies on the inner side of all three, that side
  // being the one of det(v0 - p, v1 - p, v2 - p), whose sign is -sign(h).
  float side = (h > 0.0) ? -1.0 : 1.0;
  precise vec3 c0 = cross(v_edge_at0 - p, v_edge_hi0.xyz - p);
  precise vec3 c1 = cross(v_edge_at1 - p, v_edge_hi1.xyz - p);
  precise vec3 c2 = cross(v_edge_at2 - p, v_edge_hi2.xyz - p);
  e0 = c0 * (v_edge_hi0.w * side);  // times +-1: exact
  e1 = c1 * (v_edge_hi1.w * side);
  e2 = c2 * (v_edge_hi2.w * side);
  return true;
}

// A sized light (lib/exact_soft.glsl): the light points of sample p (light-centred, at
// texel `at` of the sample texture, `rows` its height) whose segment this triangle
// crosses, more than ow_exact_eps of its length from p, set their bits in p's words. A
// sun's rays go on forever: they must cross more than ow_exact_eps |p| from p, as the hard
// sun's do (ow_projective_blocks).
void ow_exact_soft_mark(vec3 p, ivec2 at, int rows)
{
  float h;
  vec3 e0, e1, e2;
  if (!ow_exact_soft_edges(p, h, e0, e1, e2)) {
    return;
  }
  int whole = ow_exact_soft_whole(p, h, e0, e1, e2);
  if (whole < 0) {
    return;
  }
  if (whole > 0) {
#ifndef OW_ALPHA
    for (int w = 0; w * 32 < ow_exact_points; w++) {
      imageAtomicOr(ow_hits, at + ivec2(0, w * rows), ow_exact_word_points(w));
    }
    return;
#endif
  }
  // Each point's segment against the edge planes and the triangle's plane, as affine
  // functions of its pattern entry (lib/exact_soft.glsl): for a sphere, seg = t d with
  // d = sin_t (c a + s b) + cos_t w, so e . seg has the sign of sin_t (c e.a + s e.b) +
  // cos_t e.w; for an area light, seg = F (x, y, 0) - p, so e . seg = x e.F0 + y e.F1 - e.p;
  // for a sun, the direction F (x, y, z), so e . l = x e.F0 + y e.F1 + z e.F2.
  OwLightView view = ow_light_view(p);
  bool sphere = int(ow_exact_light.x) == OW_LIGHT_SPHERE;
  bool sun = int(ow_exact_light.x) == OW_LIGHT_SUN_DISK;
  float sun_min = ow_exact_eps * length(p);  // a sun's ray must cross beyond this
  mat3 edges = transpose(mat3(e0, e1, e2));  // rows: the three edge normals
  vec3 n = v_plane.xyz;
  vec3 along0 = sphere ? view.a : ow_exact_frame[0];
  vec3 along1 = sphere ? view.b : ow_exact_frame[1];
  vec3 along2 = sphere ? view.w : (sun ? ow_exact_frame[2] : p);
  vec3 side0 = edges * along0;  // each edge's dot product with the three axes
  vec3 side1 = edges * along1;
  vec3 side2 = edges * along2;
  vec3 height = vec3(dot(n, along0), dot(n, along1), dot(n, along2));
  // Every segment crosses the triangle's plane in its span (ow_exact_soft_whole's umbra test
  // without the edges): then a cluster inside all three edge planes is blocked whole.
  bool crossing = ow_exact_crossing(p, h);
#ifdef OW_ALPHA
  crossing = false;  // a see-through triangle blocks a share of the points: each is looked up
#endif
  mat3 side_matrix = mat3(side0, side1, side2);  // weights -> the three edges' sides
  for (int w = 0; w * 32 < ow_exact_points; w++) {
    int count = min(32, ow_exact_points - 32 * w);
    uint all_points = ow_exact_word_points(w);
    ivec2 word_at = at + ivec2(0, w * rows);
    // Points other triangles blocked already need no test (a stale read only tests more).
    uint blocked = imageLoad(ow_hits, word_at).x;
    if ((blocked & all_points) == all_points) {
      continue;
    }
    uint word = 0u;
    for (int first = 0; first < count; first += OW_EXACT_SOFT_CLUSTER) {
      int last = min(count, first + OW_EXACT_SOFT_CLUSTER);
      uint span = uint(last - first);
      uint cluster_bits = ((span == 32u) ? 0xFFFFFFFFu : ((1u << span) - 1u)) << uint(first);
      if ((blocked & cluster_bits) == cluster_bits) {
        continue;
      }
      int decided = ow_exact_cluster((32 * w + first) / OW_EXACT_SOFT_CLUSTER, view, side_matrix, crossing);
      if (decided != 0) {
        word |= (decided > 0) ? cluster_bits : 0u;
        continue;
      }
      for (int j = first; j < last; j++) {
        if (((blocked >> uint(j)) & 1u) != 0u) {
          continue;
        }
        int k = 32 * w + j;
        vec4 pattern = ow_exact_pattern[k];
        vec3 weights;  // the segment (or its direction) in the axes along0..2
        vec2 polar = vec2(1.0, 0.0);
        if (sphere) {
          polar = ow_cap_polar(view, pattern);
          weights = vec3(polar.y * pattern.y, polar.y * pattern.z, polar.x);
        } else {
          weights = sun ? pattern.xyz : vec3(pattern.x, pattern.y, -1.0);
        }
        vec3 sides = weights.x * side0 + weights.y * side1 + weights.z * side2;
        if (all(greaterThanEqual(sides, vec3(0.0)))) {
          float along = dot(weights, height);  // n . seg, over t for a sphere
          float f = -h / (sphere ? along * ow_cap_distance(view, polar) : along);  // where the plane cuts it
          if (sun ? (f > sun_min) : (f > ow_exact_eps && f < 1.0)) {
#ifdef OW_ALPHA
            // A see-through crossing blocks the points whose fixed threshold its alpha passes:
            // a share alpha of them (thresholds a permutation of the points, so not the
            // spatial pattern); several such crossings count as the one of largest alpha.
            float alpha = ow_alpha_along(p + f * ow_light_segment(p, view, k));
            float threshold = (float((k * 37 + 11) % ow_exact_points) + 0.5) / float(ow_exact_points);
            if (alpha >= OW_OPAQUE_ALPHA || (alpha > OW_CLEAR_ALPHA && alpha > threshold)) {
              word |= 1u << uint(j);
            }
#else
            word |= 1u << uint(j);
#endif
          }
        }
      }
    }
    if (word != 0u) {
      imageAtomicOr(ow_hits, word_at, word);
    }
  }
}
