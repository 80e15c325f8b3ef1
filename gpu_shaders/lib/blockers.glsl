// The blockers that are not triangles: spheres (point clouds) and a strand's
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

// Whether p, of unit normal n, lies on the piece a -> b (radius ra -> rb along it) as
// Cycles intersects it, within OW_OWN_SLACK of the radius there plus float32's rounding
// of p: a round piece: on its surface with n within OW_OWN_COS of the direction from the
// axis, either way (the true normal faces the camera); a ribbon: within its radius, in the
// plane through the axis normal to n (a ribbon faces the ray that meets it); nothing past
// its curve's end planes cut_a and cut_b (ow_capped_tube). core/blockers._on_piece.
bool ow_on_piece(vec3 p, vec3 n, vec3 a, vec3 b, float ra, float rb, bool ribbon, vec4 cut_a, vec4 cut_b)
{
  if (dot(cut_a.xyz, p) + cut_a.w < 0.0 || dot(cut_b.xyz, p) + cut_b.w < 0.0) {
    return false;
  }
  vec3 d2 = b - a;
  float ee = dot(d2, d2);
  float u = (ee > 0.0) ? clamp(dot(p - a, d2) / ee, 0.0, 1.0) : 0.0;
  vec3 radial = p - (a + u * d2);
  float dist = length(radial);
  float radius = mix(ra, rb, u);
  float slack = OW_OWN_SLACK * radius + 1e-6 * length(p);
  float along = dot(radial, n);
  if (ribbon) {
    return dist <= radius + slack && abs(along) <= slack;
  }
  return abs(dist - radius) <= slack && abs(along) >= OW_OWN_COS * dist;
}

// Whether the segment p + s d, given that it passes within r of the piece a -> b, meets it
// as Cycles' tube of radius r, which its curve's end planes cut_a and cut_b (n, w: n . x +
// w >= 0 on the curve's side; zero: none) end rather than a half sphere: some point from
// eps on lies within the cylinder and on the curve's side of both (core/blockers._capped_tube).
bool ow_capped_tube(vec3 p, vec3 d, vec3 a, vec3 b, float r, float eps, vec4 cut_a, vec4 cut_b)
{
  vec3 d2 = b - a;
  float ee = dot(d2, d2);
  vec3 axis = (ee > 0.0) ? d2 * inversesqrt(ee) : vec3(0.0);
  vec3 w = (p - a) - dot(p - a, axis) * axis;
  vec3 v = d - dot(d, axis) * axis;
  float qa = dot(v, v);
  float qb = 2.0 * dot(w, v);
  float qc = dot(w, w) - r * r;
  float lo;
  float hi;
  if (qa > 0.0) {
    float disc = qb * qb - 4.0 * qa * qc;
    if (disc < 0.0) {
      return false;
    }
    lo = (-qb - sqrt(disc)) / (2.0 * qa);
    hi = (-qb + sqrt(disc)) / (2.0 * qa);
  } else if (qc <= 0.0) {
    lo = -3.0e38;
    hi = 3.0e38;
  } else {
    return false;
  }
  for (int side = 0; side < 2; side++) {
    vec4 plane = (side == 0) ? cut_a : cut_b;
    float start = dot(plane.xyz, p) + plane.w;  // start + s rate >= 0 on the curve's side
    float rate = dot(plane.xyz, d);
    if (rate > 0.0) {
      lo = max(lo, -start / rate);
    } else if (rate < 0.0) {
      hi = min(hi, -start / rate);
    } else if (start < 0.0) {
      return false;
    }
  }
  return max(lo, eps) <= min(hi, 1.0);
}

// Whether the segment p + s d meets the ribbon's stretch a -> b (half width ra -> rb along
// it) as Cycles meets a ribbon: facing the ray, where the ray's line passes the axis line,
// at the axis's depth there, which must lie on the segment more than OW_RIBBON_AVOIDANCE
// half widths from p (Cycles ignores nearer hits), and past eps. The stretch ends across
// the curve's directions at its ends, ta and tb, seen across the ray
// (core/blockers._segment_ribbon).
bool ow_segment_ribbon(vec3 p, vec3 d, vec3 a, vec3 b, float ra, float rb, float eps, vec3 ta, vec3 tb)
{
  vec3 d2 = b - a;
  float aa = dot(d, d);
  float ee = dot(d2, d2);
  float bb = dot(d, d2);
  float denom = aa * ee - bb * bb;
  if (!(aa > 0.0) || !(denom > 1e-12 * aa * ee)) {
    return false;  // seen edge on
  }
  vec3 r = p - a;
  float s = (bb * dot(d2, r) - dot(d, r) * ee) / denom;
  float u = (bb * s + dot(d2, r)) / ee;
  vec3 gap = p + s * d - (a + u * d2);
  float radius = mix(ra, rb, clamp(u, 0.0, 1.0));
  vec3 across_a = ta - dot(ta, d) / aa * d;
  vec3 across_b = tb - dot(tb, d) / aa * d;
  float near = OW_RIBBON_AVOIDANCE * radius * inversesqrt(aa);
  return dot(r, across_a) >= 0.0 && dot(p - b, across_b) <= 0.0 && dot(gap, gap) <= radius * radius
         && s >= max(eps, near) && s <= 1.0;
}

// Whether the segment p + s d, s in [eps, 1], meets the piece: passes within its radius,
// on the curve's side of its end planes cut_a and cut_b where Cycles' tube ends
// (ow_capped_tube); a ribbon's piece as ow_segment_ribbon (ta, tb: the curve's directions
// at its ends) (core/blockers._segment_capsule).
bool ow_segment_piece(vec3 p, vec3 d, vec3 a, vec3 b, float ra, float rb, float eps, bool ribbon, vec4 cut_a,
                      vec4 cut_b, vec3 ta, vec3 tb)
{
  if (ribbon) {
    return ow_segment_ribbon(p, d, a, b, ra, rb, eps, ta, tb);
  }
  vec3 c = ow_piece_closest(p, d, a, b, ra, rb, eps);
  bool cut = cut_a.xyz != vec3(0.0) || cut_b.xyz != vec3(0.0);
  return c.y <= c.z * c.z && (!cut || ow_capped_tube(p, d, a, b, c.z, eps, cut_a, cut_b));
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
