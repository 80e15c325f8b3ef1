// Depth pass, fragment stage: normalised radial distance to the triangle, exact on
// the texel centre's own ray. The centre is taken back through the crop (and, for a
// warped layer, the warp: Newton steps from the interpolated projection point, see
// lib/mapping.glsl) to its ray, which meets the triangle's plane at t = c / dot(n, dir),
// however coarse the tessellation.
#include "lib/projection.glsl"
#include "lib/mapping.glsl"

void main()
{
  // A paraboloid or cube variant is never projective.
#ifndef OW_FIXED_KIND
  if (ow_projective != 0) {
    // The map's own depth z01 = gl_FragCoord.z. An inverted light (PSM: a point light
    // behind the camera plane, seen in post-perspective space) keeps the FARTHEST
    // fragment, so it stores 1 - z01 under the same LESS test.
    float z01 = (ow_map_inverted != 0) ? 1.0 - gl_FragCoord.z : gl_FragCoord.z;
    gl_FragDepth = z01;
    ow_depth = z01;
    return;
  }
#endif
  vec2 uv = (gl_FragCoord.xy - ow_tile_origin) / ow_resolution;
  mat3 rot = ow_layer_rot;
  // A paraboloid or cube variant is never an unfold.
#ifndef OW_FIXED_KIND
  if (ow_unfold_split > OW_NO_SPLIT && uv.x >= 1.0) {
    uv.x -= 1.0;  // the second unfold half, whose frame has y and z negated
    rot = mat3(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0) * rot;
  }
#endif
#ifdef OW_NO_WARP
  vec2 xy = ow_map_inverse(ow_warp_rows, ow_warp_cols, ow_layer_slot, ow_warp_size, ow_crop, uv);
#else
  vec2 xy = (ow_warp_size > 0)
      ? ow_map_inverse_near(ow_warp_rows, ow_warp_cols, ow_layer_slot, ow_warp_size, ow_crop, uv, v_map_xy)
      : ow_map_inverse(ow_warp_rows, ow_warp_cols, ow_layer_slot, ow_warp_size, ow_crop, uv);
#endif
  vec3 dir = transpose(rot) * ow_unproject(ow_layer_kind, xy);
  float t = v_plane.w / dot(v_plane.xyz, dir);
  if (!(t > 0.0) || isinf(t)) {
    t = v_distance;  // grazing ray: fall back to the interpolated distance
  }
  // A texel at the border of a tessellated triangle may lie just off the true
  // triangle; it stores the plane's continuation, unclamped. That is right for a
  // coplanar neighbour, and a farther depth can only lose the depth test to a nearer
  // real surface. Until 2026-12-01 t was clamped to the triangle's distance range:
  // the lower end, the plane's distance, can never bind (|t| >= |c| for a unit dir;
  // clamping to the exact nearest point changed no pixel either), and the upper end,
  // the farthest corner, stored depths too near on grazing receivers, which the
  // warped maps' many triangle borders turned into false shadow
  // (docs/notebook/2026-12-warping.md).
  float depth = clamp((t - ow_near) / (ow_far - ow_near), 0.0, 1.0);
  gl_FragDepth = depth;
  ow_depth = depth;
}
