// Ray table of a warped layer: each texel's projection point, through the exact
// inverse of its warp and crop (lib/mapping.glsl's binary searches). Built once per
// layer and frame, so the footprint pass, which visits each texel once per triangle
// covering it, reads the inverse with one fetch instead of searching again.
#include "lib/mapping.glsl"

void main()
{
  vec2 uv = (gl_FragCoord.xy - ow_tile_origin) / ow_resolution;
  ow_ray_xy = ow_map_inverse(ow_warp_rows, ow_warp_cols, ow_layer_slot, ow_warp_size, ow_crop, uv);
}
