// Depth pass, fragment stage: exact normalised radial distance to the triangle.
// The ray through this texel's own direction meets the triangle's plane at
// t = c / dot(n, dir), so depth is exact even where interpolation would not be.
#include "lib/projection.glsl"

void main()
{
  vec2 xy = (gl_FragCoord.xy - ow_tile_origin) / ow_resolution * 2.0 - 1.0;
  vec3 dir = transpose(ow_layer_rot) * ow_unproject(ow_layer_kind, xy);
  float t = v_plane.w / dot(v_plane.xyz, dir);
  if (!(t > 0.0) || isinf(t)) {
    t = v_distance;  // grazing ray: fall back to the interpolated distance
  }
  // Texels at the border of a tessellated triangle may lie just off the true
  // triangle; clamping to the triangle's distance range keeps them sane.
  t = clamp(t, v_range.x, v_range.y);
  float depth = clamp((t - ow_near) / (ow_far - ow_near), 0.0, 1.0);
  gl_FragDepth = depth;
  ow_depth = depth;
}
