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
// The angle the light's reach subtends from a triangle d_min from its centre, a little
// over for float32 rounding; above pi / 2 (the whole sphere) when d_min <= 1.5 R.
float ow_soft_grow(float d_min, float reach)
{
  return (d_min > 1.5 * reach) ? asin(reach / d_min) + 1e-4 : 4.0;
}

vec4 ow_soft_box(vec3 l0, vec3 l1, vec3 l2, int kind, float grow)
{
  if (grow > 1.5707963267948966) {
    return OW_WHOLE_BOX;
  }
  vec3 n0 = normalize(l0);
  vec3 n1 = normalize(l1);
  vec3 n2 = normalize(l2);
  vec3 sum = n0 + n1 + n2;
  if (length(sum) < 1e-3) {
    return OW_WHOLE_BOX;  // the triangle surrounds the light
  }
  vec3 axis = normalize(sum);
  float spread = acos(clamp(min(min(dot(axis, n0), dot(axis, n1)), dot(axis, n2)), -1.0, 1.0));
  if (spread >= 1.5707963267948966) {
    return OW_WHOLE_BOX;  // no cap of at most a hemisphere holds it
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
