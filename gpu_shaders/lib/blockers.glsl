// The blockers that are not triangles, as the exact pass will test them per view sample
// (issue 42): whether the segment from a light-centred sample p to the light (the origin)
// meets a sphere or a strand's piece, beyond `eps` of its length from p (the receiver's
// own surface left out, as the triangles' walk leaves it out). core/blockers.py is the
// numpy oracle (tests/gl/test_blockers_glsl.py).

// The segment's point at s in [eps, 1] is p (1 - s): s = 0 at the sample, 1 at the light.

// Sphere of centre c and radius r.
bool ow_segment_sphere(vec3 p, vec3 c, float r, float eps)
{
  float pp = dot(p, p);
  if (!(pp > 0.0)) {
    return false;
  }
  float s = clamp(1.0 - dot(c, p) / pp, eps, 1.0);
  vec3 gap = p * (1.0 - s) - c;
  return dot(gap, gap) <= r * r;
}

// A strand's piece from a to b, its radius from ra to rb along it, with sphere ends (a
// swept sphere): the closest points of the two segments (Ericson, Real-Time Collision
// Detection 5.1.9), the segment's parameter kept in [eps, 1], and the radius at the
// piece's one.
bool ow_segment_capsule(vec3 p, vec3 a, vec3 b, float ra, float rb, float eps)
{
  vec3 d1 = -p;
  vec3 d2 = b - a;
  vec3 r = p - a;
  float aa = dot(d1, d1);
  float ee = dot(d2, d2);
  if (!(aa > 0.0)) {
    return false;
  }
  if (!(ee > 0.0)) {
    return ow_segment_sphere(p, a, ra, eps);
  }
  float bb = dot(d1, d2);
  float cc = dot(d1, r);
  float ff = dot(d2, r);
  float denom = aa * ee - bb * bb;
  float s = (denom > 1e-12 * aa * ee) ? clamp((bb * ff - cc * ee) / denom, eps, 1.0) : eps;
  float u = (bb * s + ff) / ee;
  if (u < 0.0) {
    s = clamp(-cc / aa, eps, 1.0);
  }
  else if (u > 1.0) {
    s = clamp((bb - cc) / aa, eps, 1.0);
  }
  u = clamp(u, 0.0, 1.0);
  vec3 gap = p + s * d1 - (a + u * d2);
  float radius = mix(ra, rb, u);
  return dot(gap, gap) <= radius * radius;
}
