// Soft shadows of a sized light from its maps (shaders.soft_of):
// percentage-closer soft shadows whose kernel is the light itself. Needs the shadow test's
// ow_point_tap (shadow_test.frag), which looks one light-centred direction up in whichever
// layer holds it, through the layer's projection, crop and warp, so a kernel crosses the
// paraboloids' seam and the cube's edges, and keeps its world size through any warp. It
// returns the map's distance along the direction (1e30 where nothing was drawn) and the
// light the veil lets through to the given depth.
//
// The light's points ow_soft_points (core/light_shape.stratified_points, light frame) give
// the kernel, and a pattern of fewer, ow_soft_search_points, the blocker search: the
// segment from the receiver p to light point q crosses the sphere of a
// blocker's distance t from the light at x = p + s (q - p), s = 1 - t / |p|; the map is
// read along x's direction and compared with the receiver's own plane along that ray, so
// a tilted receiver does not shadow itself. First a blocker search along each segment at
// a few distances, then, at the blockers' mean distance, one tap per light point: the
// visibility is the share of taps the map finds lit.

// The frame the light's pattern lies in, light-centred world coordinates: an area light's
// own; for a sphere, the disk of its radius that faces the receiver p (its normal along p),
// made once per receiver; a sun's own (its points are directions).
mat3 ow_soft_frame(vec3 p)
{
  if (ow_soft_kind != OW_LIGHT_SPHERE) {
    return transpose(ow_light_rot);
  }
  vec3 w = normalize(p);
  vec3 a = normalize(cross(w, abs(w.z) < 0.9 ? vec3(0.0, 0.0, 1.0) : vec3(1.0, 0.0, 0.0)));
  return mat3(a, cross(w, a), w);
}

// The receiver's tangent plane (normal n, towards the light, through p) along the
// light-centred direction d: its distance from the light, or `fallback` when d grazes it.
float ow_plane_depth(vec3 n, vec3 p, vec3 d, float fallback)
{
  float dn = dot(n, d);
  return (dn < -1e-4) ? dot(n, p) / dn : fallback;
}

#include "lib/spot_cone.glsl"

// A tap's weight, with `emitted` from the light point to the receiver: for a spot, its
// cone's (lib/spot_cone.glsl); for an area light of spread below 180 degrees
// (ow_soft_spread not OW_NO_SPREAD, render/soft.py's spread_tangent) max(tan(spread / 2) - tan a, 0),
// a the angle from the light's normal, its -Z; else 1.
float ow_soft_tap_weight(vec3 emitted)
{
  if (ow_soft_kind == OW_LIGHT_SPHERE) {
    return ow_spot_cone_weight(emitted, -transpose(ow_light_rot)[2], ow_soft_spot);
  }
  if (ow_soft_kind != OW_LIGHT_AREA || ow_soft_spread < OW_NO_SPREAD_BELOW) {
    return 1.0;
  }
  float len = length(emitted);
  float cos_e = dot(emitted, -transpose(ow_light_rot)[2]) / max(len, 1e-30);
  if (!(cos_e > 0.0)) {
    return 0.0;
  }
  return max(ow_soft_spread - sqrt(max(1.0 - cos_e * cos_e, 0.0)) / cos_e, 0.0);
}

// The soft visibility at p (normal n towards the light, bias in world units at the
// receiver); `centre` is the hard test's visibility, kept where the search finds no blocker.
float ow_soft_visibility(vec3 p, vec3 n, float bias, float centre)
{
  float dist = length(p);
  mat3 frame = ow_soft_frame(p);
  float sum_t = 0.0;
  int blockers = 0;
  for (int j = 0; j < ow_soft_search; j++) {
    vec3 q = frame * ow_soft_search_points[j].xyz;
    for (int k = 1; k <= OW_SOFT_SEARCH_STEPS; k++) {
      // Points of the segment from the receiver towards the light point, denser near the
      // receiver, where a penumbra's blockers matter most.
      float f = pow(float(k) / float(OW_SOFT_SEARCH_STEPS + 1), 2.0);
      vec3 d = normalize(p + f * (q - p));
      float t_recv = ow_plane_depth(n, p, d, dist);
      float t_map = ow_point_tap(d, t_recv).x;
      if (t_map < t_recv - bias * (t_recv / dist)) {
        sum_t += t_map;
        blockers++;
      }
    }
  }
  if (blockers == 0) {
    return centre;
  }
  float t_b = sum_t / float(blockers);
  float s = clamp(1.0 - t_b / dist, 0.0, 1.0);
  float lit = 0.0;
  float total = 0.0;
  for (int j = 0; j < ow_soft_count; j++) {
    vec3 q = frame * ow_soft_points[j].xyz;
    vec3 d = normalize(p + s * (q - p));
    float t_recv = ow_plane_depth(n, p, d, dist);
    float limit = t_recv - bias * (t_recv / dist);
    vec2 tap = ow_point_tap(d, limit);
    float weight = ow_soft_tap_weight(p - q);
    lit += (tap.x >= limit) ? weight * tap.y : 0.0;
    total += weight;
  }
  return (total > 0.0) ? lit / total : centre;
}

// A sun's soft visibility at p (normal n towards the sun, bias in world units). Its points
// are directions l towards it (the frame's +Z is -ow_light_axis); the ray p + u l meets a
// blocker's depth, an axial distance D upstream of p, at u = D / (l . c). The blocker search
// follows each search direction through the map (its texels hold the nearest surface along
// the sun's rays) and puts each blocker it finds back on its ray; the filter then reads the
// map where each light direction's ray reaches their mean depth, and compares with the
// receiver's own plane along the sun's ray through that point.
float ow_sun_soft_visibility(vec3 p, vec3 n, float bias, float centre)
{
  vec3 c = -ow_light_axis;  // towards the sun
  mat3 frame = ow_soft_frame(p);
  float nc = dot(n, c);
  // How far upstream the map reaches from p (its z01 = 0 plane, along c).
  float top = max(-ow_map_line_depth(p, ow_light_axis, -ow_depth_offset), 0.0);
  float sum_d = 0.0;
  int blockers = 0;
  for (int j = 0; j < ow_soft_search; j++) {
    vec3 l = frame * ow_soft_search_points[j].xyz;
    float lc = max(dot(l, c), 1e-3);
    for (int k = 1; k <= OW_SOFT_SEARCH_STEPS; k++) {
      float f = pow(float(k) / float(OW_SOFT_SEARCH_STEPS + 1), 2.0);
      vec3 x = p + (f * top / lc) * l;
      ivec2 texel;
      float z01;
      if (!ow_map_texel(x, texel, z01)) {
        continue;
      }
      float stored = texelFetch(ow_atlas, texel, 0).r;
      if (stored >= 1.0) {
        continue;
      }
      // The blocker on the sun's ray through x, and the receiver's plane on that ray.
      float s_b = ow_map_line_depth(x, ow_light_axis, stored);
      float s_r = (abs(nc) > 1e-4) ? dot(n, p - x) / -nc : 0.0;
      if (s_b < s_r - bias) {
        sum_d += dot(x + s_b * ow_light_axis - p, c);
        blockers++;
      }
    }
  }
  if (blockers == 0) {
    return centre;
  }
  float depth = max(sum_d / float(blockers), 0.0);
  float lit = 0.0;
  for (int j = 0; j < ow_soft_count; j++) {
    vec3 l = frame * ow_soft_points[j].xyz;
    vec3 x = p + (depth / max(dot(l, c), 1e-3)) * l;
    ivec2 texel;
    float z01;
    if (!ow_map_texel(x, texel, z01)) {
      lit += 1.0;
      continue;
    }
    float stored = texelFetch(ow_atlas, texel, 0).r;
    float s_r = (abs(nc) > 1e-4) ? dot(n, p - x) / -nc : 0.0;
    float light = 1.0;
    vec2 y_uv;
    float y_w;
    // The receiver's plane on the sun's ray through x, less the bias: its depth in the map.
    float y01 = ow_map_z01(x + (s_r - bias) * ow_light_axis, y_uv, y_w);
#ifdef OW_VEIL
    light = ow_veil_light(texel, y01 - ow_depth_offset);
#endif
    lit += (stored >= 1.0 || y01 - ow_depth_offset <= stored) ? light : 0.0;
  }
  return lit / float(ow_soft_count);
}
