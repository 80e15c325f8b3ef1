// Layer map transform: projection xy -> DV crop -> warp -> map uv, and back.
// Mirrors LayerMapping in addon/core/warping.py. `crop` holds (lo.x, lo.y, scale.x, scale.y)
// with uv_crop = (uv_full - lo) * scale; `warp_size` 0 means no warp.
// Programs built with OW_NO_WARP (the plain depth and shadow-test variants) compile
// the warp out: a software rasteriser runs a uniform branch with masked lanes, so
// dead warp code still costs every fragment.
#include "lib/warp.glsl"

vec2 ow_map_forward(sampler2D rows, sampler2D cols, int slot, int warp_size, vec4 crop, vec2 xy,
                    out float magnification)
{
  vec2 uv = ((xy * 0.5 + 0.5) - crop.xy) * crop.zw;
  // Magnification = the smallest singular value of d(map uv)/d(uncropped uv): a texel's
  // preimage is at most 1/magnification texels of the plain map across, shear included.
  mat2 jacobian = mat2(crop.z, 0.0, 0.0, crop.w);
#ifndef OW_NO_WARP
  if (warp_size > 0) {
    mat2 warp_jacobian;
    uv = ow_warp_jacobian(rows, cols, slot, warp_size, uv, warp_jacobian);
    jacobian = warp_jacobian * jacobian;
  }
#endif
  magnification = ow_min_singular(jacobian);
  return uv;
}

vec2 ow_map_inverse(sampler2D rows, sampler2D cols, int slot, int warp_size, vec4 crop, vec2 uv)
{
#ifndef OW_NO_WARP
  if (warp_size > 0) {
    uv = ow_unwarp(rows, cols, slot, warp_size, uv);
  }
#endif
  return (crop.xy + uv / crop.zw) * 2.0 - 1.0;
}
