// Footprints of a triangle for a sized light (the exact soft pass, footprint.vert with
// OW_EXACT_SOFT): the texels whose samples the triangle may shadow from any point of the
// light, the light being inside a sphere of radius R = ow_exact_reach about its centre.
//
// Why an angle: a segment from a sample p to a light point q crosses the triangle at
// x = (1 - s) p + s q, so x - s q = (1 - s) p: x's direction from the centre differs from
// p's by a part s q across p, at most R long, at distance |x| >= d_min from the centre.
// While d_min > sqrt(2) R that angle is acute and at most asin(R / d_min): p's direction
// lies within that angle of the triangle's image. A triangle nearer the light than
// 1.5 R covers its whole layers. Light-centred vertices in the layer's frame (axis +Z).

#include "lib/soft_reach.glsl"

// Distance from the light (the origin) to the triangle (a, b, c): the closest point by
// its Voronoi region (Ericson, Real-Time Collision Detection, 5.1.5).
float ow_origin_distance(vec3 a, vec3 b, vec3 c)
{
  vec3 ab = b - a;
  vec3 ac = c - a;
  vec3 ap = -a;
  float d1 = dot(ab, ap);
  float d2 = dot(ac, ap);
  if (d1 <= 0.0 && d2 <= 0.0) {
    return length(a);
  }
  vec3 bp = -b;
  float d3 = dot(ab, bp);
  float d4 = dot(ac, bp);
  if (d3 >= 0.0 && d4 <= d3) {
    return length(b);
  }
  float vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    return length(a + ab * (d1 / (d1 - d3)));
  }
  vec3 cp = -c;
  float d5 = dot(ab, cp);
  float d6 = dot(ac, cp);
  if (d6 >= 0.0 && d5 <= d6) {
    return length(c);
  }
  float vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    return length(a + ac * (d2 / (d2 - d6)));
  }
  float va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    return length(b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))));
  }
  float denom = 1.0 / (va + vb + vc);
  return length(a + ab * (vb * denom) + ac * (vc * denom));
}

const vec4 OW_WHOLE_BOX = vec4(-1.0, 1.0, -1.0, 1.0);

// The stereographic box of the cap of axis `axis` (unit) and half angle `spread`: a cap
// that leaves out the projection's pole (-Z) maps to a disk, whose diameter lies on the
// axis's meridian between the images of the cap's two boundary points there.
vec4 ow_cap_paraboloid_box(vec3 axis, float spread)
{
  float polar = acos(clamp(axis.z, -1.0, 1.0));
  if (polar - spread >= 1.5707963267948966) {
    return OW_EMPTY_BOX;  // wholly behind the layer's hemisphere
  }
  if (polar + spread >= 3.14159265358979) {
    return OW_WHOLE_BOX;  // holds the pole: its image is the disk's outside
  }
  float rho0 = tan(0.5 * (polar - spread));
  float rho1 = tan(0.5 * (polar + spread));
  float len = length(axis.xy);
  vec2 along = (len > 1e-12) ? axis.xy / len : vec2(1.0, 0.0);
  vec2 centre = 0.5 * (rho0 + rho1) * along;
  float radius = 0.5 * (rho1 - rho0);
  return clamp(vec4(centre.x - radius, centre.x + radius, centre.y - radius, centre.y + radius), -1.0, 1.0);
}

// Extremes of x / z (with the axis's x and z) over a cap in front of the face (axis.z >
// sin(spread)): the planes through the light tangent to the cone, x = k z.
vec2 ow_cap_slopes(float ax, float az, float s)
{
  float root = sqrt(max(ax * ax + az * az - s * s, 0.0));
  float denom = az * az - s * s;
  return vec2(ax * az - s * root, ax * az + s * root) / denom;
}

// The cube face's box of the same cap: empty when the cap lies beyond one of the face's
// four side planes, the face's whole square when it reaches behind the face's plane.
vec4 ow_cap_cube_box(vec3 axis, float spread)
{
  float s = sin(min(spread, 1.5707963267948966));
  const float root_half = 0.70710678118654752;
  if (spread < 1.5707963267948966) {
    if (dot(axis, vec3(1.0, 0.0, -1.0)) * root_half > s || dot(axis, vec3(-1.0, 0.0, -1.0)) * root_half > s
        || dot(axis, vec3(0.0, 1.0, -1.0)) * root_half > s || dot(axis, vec3(0.0, -1.0, -1.0)) * root_half > s) {
      return OW_EMPTY_BOX;
    }
  }
  if (!(axis.z > s) || spread >= 1.5707963267948966) {
    return OW_WHOLE_BOX;
  }
  vec2 kx = ow_cap_slopes(axis.x, axis.z, s);
  vec2 ky = ow_cap_slopes(axis.y, axis.z, s);
  vec4 box = vec4(kx.x, kx.y, ky.x, ky.y);
  if (box.x > 1.0 || box.y < -1.0 || box.z > 1.0 || box.w < -1.0) {
    return OW_EMPTY_BOX;
  }
  return clamp(box, -1.0, 1.0);
}

// The grown footprint's box in the layer (projection coordinates): the cap around the
// triangle's directions widened by the light's angle; on a paraboloid, a triangle wholly in
// front also keeps within that angle of its own box (the map's scale is at most 1 there).
// The angle by which a sample's direction from the light's centre may differ from that of
// the point where one of its segments to the light crosses a triangle d_min from the centre
// (lib/soft_reach.glsl), a little over for float32 rounding; above pi / 2 (the whole
// sphere) when d_min <= 1.5 R.
float ow_soft_grow(float d_min, float reach, float far)
{
  return (d_min > 1.5 * reach) ? asin(ow_soft_reach_sin(d_min, reach, far)) + 1e-4 : 4.0;
}

// The cap (unit axis, half angle) that holds the directions of a triangle's corners from
// the light, and so of the whole triangle; false where no cap of less than a hemisphere
// does (the triangle surrounds the light, or spans half its sky).
bool ow_direction_cap(vec3 l0, vec3 l1, vec3 l2, out vec3 axis, out float spread)
{
  vec3 n0 = normalize(l0);
  vec3 n1 = normalize(l1);
  vec3 n2 = normalize(l2);
  vec3 sum = n0 + n1 + n2;
  axis = vec3(0.0, 0.0, 1.0);
  spread = 4.0;
  if (length(sum) < 1e-3) {
    return false;
  }
  axis = normalize(sum);
  spread = acos(clamp(min(min(dot(axis, n0), dot(axis, n1)), dot(axis, n2)), -1.0, 1.0));
  return spread < 1.5707963267948966;
}

vec4 ow_soft_box(vec3 l0, vec3 l1, vec3 l2, int kind, float grow)
{
  if (grow > 1.5707963267948966) {
    return OW_WHOLE_BOX;
  }
  vec3 axis;
  float spread;
  if (!ow_direction_cap(l0, l1, l2, axis, spread)) {
    return OW_WHOLE_BOX;
  }
  spread += grow;
  if (kind != OW_KIND_PARABOLOID) {
    return ow_cap_cube_box(axis, spread);
  }
  vec4 box = ow_cap_paraboloid_box(axis, spread);
  if (l0.z >= 0.0 && l1.z >= 0.0 && l2.z >= 0.0 && box.x <= box.y) {
    vec4 own = ow_paraboloid_box(l0, l1, l2) + vec4(-grow, grow, -grow, grow);
    box = vec4(max(box.x, own.x), min(box.y, own.y), max(box.z, own.z), min(box.w, own.w));
  }
  return box;
}

// A spot's map (lib/projective.glsl): clip x = r_x . d and w = r_w . d for a light-centred
// direction d (its rows have no translation). Over the cap of directions (unit axis a,
// half angle s), x / w = k reaches its extremes where the plane (r_x - k r_w) . d = 0 is
// tangent to the cone: ((r_x - k r_w) . a)^2 = sin^2 s |r_x - k r_w|^2, a quadratic in k
// whose leading term is (r_w . a)^2 - sin^2 s |r_w|^2, positive exactly when the whole cap
// lies in front of the map's eye plane. The box in uv (u0, u1, v0, v1); the whole map when
// the cap reaches behind that plane.
vec2 ow_cone_ratio_range(vec3 r, vec3 rw, vec3 axis, float s2, float lead)
{
  float ra = dot(r, axis);
  float wa = dot(rw, axis);
  float b = -2.0 * (ra * wa - s2 * dot(r, rw));
  float c = ra * ra - s2 * dot(r, r);
  float root = sqrt(max(b * b - 4.0 * lead * c, 0.0));
  return vec2(-b - root, -b + root) / (2.0 * lead);
}

vec4 ow_projective_cap_box(mat4 m, vec3 axis, float spread)
{
  const vec4 whole = vec4(0.0, 1.0, 0.0, 1.0);
  if (spread >= 1.5707963267948966) {
    return whole;
  }
  vec3 rx = ow_matrix_row(m, 0);
  vec3 ry = ow_matrix_row(m, 1);
  vec3 rw = ow_matrix_row(m, 3);
  float sin_s = sin(spread);
  float s2 = sin_s * sin_s;
  float wa = dot(rw, axis);
  float lead = wa * wa - s2 * dot(rw, rw);
  if (!(wa > 0.0) || !(lead > 1e-6 * dot(rw, rw))) {
    return whole;
  }
  vec2 kx = ow_cone_ratio_range(rx, rw, axis, s2, lead);
  vec2 ky = ow_cone_ratio_range(ry, rw, axis, s2, lead);
  return vec4(kx, ky) * 0.5 + 0.5;
}

// The grown footprint of a triangle in a spot's or sun's map (uv box, unclamped), for the
// exact pass of its sized light:
// - a spot's sphere: the cap of the triangle's directions widened by `grow`, the angle the
//   light subtends from it (ow_soft_grow), through the map's perspective;
// - a sun's disk: a ray from a receiver p towards the sun crosses the triangle at x, so p
//   lies downstream of x by at most the map's far depth less the triangle's nearest, and
//   aside by that times the tangent of the half angle (ow_exact_light.w): the triangle's
//   own box grown by it, through the map's scale across the light.
vec4 ow_soft_projective_box(mat4 m, vec3 v0, vec3 v1, vec3 v2, float grow)
{
  if (int(ow_exact_light.x) == OW_LIGHT_SUN_DISK) {
    vec4 box = ow_projective_box(m, v0, v1, v2, 0.0);
    float z_min = min(min((m * vec4(v0, 1.0)).z, (m * vec4(v1, 1.0)).z), (m * vec4(v2, 1.0)).z);
    // Receivers lie in the map's depth range (z <= 1, in clip units of length 1 / |r_z|).
    float aside = max(1.0 - z_min, 0.0) / max(length(ow_matrix_row(m, 2)), 1e-30) * ow_exact_light.w * 1.001;
    vec2 g = 0.5 * aside * vec2(length(ow_matrix_row(m, 0)), length(ow_matrix_row(m, 1)));
    return box + vec4(-g.x, g.x, -g.y, g.y);
  }
  vec3 axis;
  float spread;
  if (grow > 1.5707963267948966 || !ow_direction_cap(v0, v1, v2, axis, spread)) {
    return vec4(0.0, 1.0, 0.0, 1.0);
  }
  return ow_projective_cap_box(m, axis, spread + grow);
}
