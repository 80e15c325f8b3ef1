// Footprint pass of a medium's part in the maps (shaders.medium_of): where the
// texel's ray from the light meets the triangle, the crossing goes to the texel's haze
// (lib/media.glsl). No depth is stored: a medium is no surface.
// - A point light's layer: the texel's ray (lib/footprint_ray.glsl), inside the triangle's
//   three edge planes by lib/media.glsl's rule for a ray on an edge.
// - A spot's or sun's map: the triangle is rasterised as it is projected (footprint.vert),
//   and GL's own rule covers a texel centre on a shared edge once; the crossing is the
//   fragment's point, its distance along the light's ray: from a spot, its distance; for a
//   sun, its place along the axis past ow_media_offset.
#include "lib/footprint_ray.glsl"
#include "lib/media.glsl"

void main()
{
#ifndef OW_FIXED_KIND
  if (ow_projective != 0) {
    // The texel centre's line through the map (its near and far points, homogeneous: a
    // PSM's line may pass through infinity between them) met with the triangle's plane:
    // exact where the depth buffer's z would be rounded.
    vec2 ndc = (gl_FragCoord.xy - ow_tile_origin) / ow_resolution * 2.0 - 1.0;
    mat4 to_light = inverse(ow_map_matrix);
    vec4 near_point = to_light * vec4(ndc, -1.0, 1.0);
    vec4 far_point = to_light * vec4(ndc, 1.0, 1.0);
    vec4 plane = vec4(v_plane.xyz, -v_plane.w);
    float across = dot(plane, far_point - near_point);
    if (across == 0.0) {
      discard;
    }
    vec4 met = near_point - (far_point - near_point) * (dot(plane, near_point) / across);
    vec3 x = met.xyz / met.w;  // light-centred
    // Which way the light's ray goes through the plane (from the light: a spot's ray is x).
    bool entering = dot(v_plane.xyz, (ow_sun != 0) ? ow_light_axis : x) < 0.0;
    float u = (ow_sun != 0) ? dot(x, ow_light_axis) + ow_media_offset : length(x);
    ow_haze_add(ivec2(gl_FragCoord.xy), max(u, 0.0), entering);
    discard;
  }
#endif
  vec3 dir = ow_texel_ray();
  if (!(ow_medium_inside(dot(dir, v_edge0), v_edge0) && ow_medium_inside(dot(dir, v_edge1), v_edge1)
        && ow_medium_inside(dot(dir, v_edge2), v_edge2))) {
    discard;
  }
  float along = dot(v_plane.xyz, dir);
  float t = v_plane.w / along;
  if (!(t > 0.0)) {
    discard;  // behind the light, or grazing in float32 rounding
  }
  ow_haze_add(ivec2(gl_FragCoord.xy), t * length(dir), along < 0.0);
  discard;
}
