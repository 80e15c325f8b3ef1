// The blockers that are not triangles (issue 42): spheres (point clouds) and a strand's
// pieces (capsules: a sphere swept from a to b, its radius from ra to rb), as the
// footprint pass draws them (footprint.vert and .frag with OW_CAPSULES) and the exact
// pass tests them per view sample. A sphere is a piece with a == b. core/blockers.py is
// the numpy oracle (tests/gl/test_blockers_glsl.py).

// The closest approach of the segment p + s d, s in [lo, 1], to the piece a -> b: the
// closest points of the two segments (Ericson, Real-Time Collision Detection 5.1.9), s
// kept in [lo, 1]. Returns (s, the squared gap, the piece's radius there).
vec3 ow_piece_closest(vec3 p, vec3 d, vec3 a, vec3 b, float ra, float rb, float lo)
{
  vec3 d2 = b - a;
  vec3 r = p - a;
  float aa = dot(d, d);
  float ee = dot(d2, d2);
  if (!(aa > 0.0)) {
    return vec3(lo, dot(r, r), ra);
  }
  float cc = dot(d, r);
  float s;
  float u = 0.0;
  if (!(ee > 0.0)) {
    s = clamp(-cc / aa, lo, 1.0);  // a sphere: the segment's point closest to its centre
  } else {
    float bb = dot(d, d2);
    float ff = dot(d2, r);
    float denom = aa * ee - bb * bb;
    s = (denom > 1e-12 * aa * ee) ? clamp((bb * ff - cc * ee) / denom, lo, 1.0) : lo;
    u = (bb * s + ff) / ee;
    if (u < 0.0) {
      s = clamp(-cc / aa, lo, 1.0);
    } else if (u > 1.0) {
      s = clamp((bb - cc) / aa, lo, 1.0);
    }
    u = clamp(u, 0.0, 1.0);
  }
  vec3 gap = p + s * d - (a + u * d2);
  return vec3(s, dot(gap, gap), mix(ra, rb, u));
}

// Whether p lies within the piece a -> b (radius ra -> rb along it), grown by float32's
// rounding of p (core/blockers._within).
bool ow_within(vec3 p, vec3 a, vec3 b, float ra, float rb)
{
  vec3 d2 = b - a;
  float ee = dot(d2, d2);
  float u = (ee > 0.0) ? clamp(dot(p - a, d2) / ee, 0.0, 1.0) : 0.0;
  vec3 gap = p - (a + u * d2);
  float reach = mix(ra, rb, u) + 1e-6 * length(p);
  return dot(gap, gap) <= reach * reach;
}

// Whether the segment p + s d, s in [eps, 1], passes within the piece's radius.
bool ow_segment_piece(vec3 p, vec3 d, vec3 a, vec3 b, float ra, float rb, float eps)
{
  vec3 c = ow_piece_closest(p, d, a, b, ra, rb, eps);
  return c.y <= c.z * c.z;
}

// The segment from a light-centred sample p to the light (the origin), from `eps` of its
// length on, against a sphere of centre c and radius r, and against a piece; not where p
// lies in it, grown by OW_OWN_SLACK (its own region: Cycles never shadows a point with
// the primitive it lies on). core/blockers._segment_capsule's default.
bool ow_segment_sphere(vec3 p, vec3 c, float r, float eps)
{
  float own = r * (1.0 + OW_OWN_SLACK);
  return dot(p, p) > 0.0 && !ow_within(p, c, c, own, own) && ow_segment_piece(p, -p, c, c, r, r, eps);
}

bool ow_segment_capsule(vec3 p, vec3 a, vec3 b, float ra, float rb, float eps)
{
  float grow = 1.0 + OW_OWN_SLACK;
  return dot(p, p) > 0.0 && !ow_within(p, a, b, ra * grow, rb * grow) && ow_segment_piece(p, -p, a, b, ra, rb, eps);
}

// Where the segment p0 -> p1 passes through the piece, as its parameters in [0, 1]
// (entry, exit), or (-1, -1) where it passes beside it: the closest approach less and plus
// the half chord of a sphere of the radius there. For a piece seen aslant both lie
// between the true entry and exit.
vec2 ow_piece_span(vec3 p0, vec3 p1, vec3 a, vec3 b, float ra, float rb)
{
  vec3 d = p1 - p0;
  vec3 c = ow_piece_closest(p0, d, a, b, ra, rb, 0.0);
  if (!(c.y <= c.z * c.z)) {
    return vec2(-1.0);
  }
  float half_chord = sqrt(max(c.z * c.z - c.y, 0.0)) / max(length(d), 1e-30);
  return vec2(max(c.x - half_chord, 0.0), min(c.x + half_chord, 1.0));
}
