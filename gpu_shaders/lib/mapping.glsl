// Layer map transform: projection xy -> DV crop -> warp -> map uv, and back.
// Mirrors LayerMapping in addon/core/warping.py. A crop holds (lo.x, lo.y, scale.x, scale.y)
// with uv_crop = (uv_full - lo) * scale; `warp_size` 0 means no warp.
// Programs built with OW_NO_WARP (the plain depth and shadow-test variants) compile
// the warp out: a software rasteriser runs a uniform branch with masked lanes, so
// dead warp code still costs every fragment.
#include "lib/warp.glsl"

// A warped layer's DV crop is its rows table's texel (A, slot A + 1), written where the
// warp is built (warp_build.comp on the GPU, pack_warp_table on the host); the uniform
// `crop` is an unwarped layer's.
vec4 ow_crop_of(sampler2D rows, int slot, int warp_size, vec4 crop)
{
#ifndef OW_NO_WARP
  if (warp_size > 0) {
    return texelFetch(rows, ivec2(warp_size, slot * warp_size + 1), 0);
  }
#endif
  return crop;
}

// Map uv of projection point xy, and J = d(map uv)/d(uncropped uv) (crop and warp).
vec2 ow_map_forward_jacobian(sampler2D rows, sampler2D cols, int slot, int warp_size, vec4 crop, vec2 xy,
                             out mat2 jacobian)
{
  crop = ow_crop_of(rows, slot, warp_size, crop);
  vec2 uv = ((xy * 0.5 + 0.5) - crop.xy) * crop.zw;
  jacobian = mat2(crop.z, 0.0, 0.0, crop.w);
#ifndef OW_NO_WARP
  if (warp_size > 0) {
    mat2 warp_jacobian;
    uv = ow_warp_jacobian(rows, cols, slot, warp_size, uv, warp_jacobian);
    jacobian = warp_jacobian * jacobian;
  }
#endif
  return uv;
}

vec2 ow_map_forward(sampler2D rows, sampler2D cols, int slot, int warp_size, vec4 crop, vec2 xy,
                    out float magnification)
{
  mat2 jacobian;
  vec2 uv = ow_map_forward_jacobian(rows, cols, slot, warp_size, crop, xy, jacobian);
  // Magnification = the smallest singular value of d(map uv)/d(uncropped uv): a texel's
  // preimage is at most 1/magnification texels of the plain map across, shear included.
  magnification = ow_min_singular(jacobian);
  return uv;
}

vec2 ow_map_inverse(sampler2D rows, sampler2D cols, int slot, int warp_size, vec4 crop, vec2 uv)
{
  crop = ow_crop_of(rows, slot, warp_size, crop);
#ifndef OW_NO_WARP
  if (warp_size > 0) {
    uv = ow_unwarp(rows, cols, slot, warp_size, uv);
  }
#endif
  return (crop.xy + uv / crop.zw) * 2.0 - 1.0;
}

#ifndef OW_NO_WARP
// Inverse of the map at `uv` by two Newton steps on the forward map, started from a
// nearby projection point `xy_start` (interpolated from the vertices of a host-built
// stream). The warp is fold-free (det J > 0), so every step is defined. Only depth.frag's
// warped variant calls it, and no method draws a warped host stream any more (unfold
// takes no warp; the warped maps go through the footprint pass and its ray table, the
// exact inverse), so it is kept only while that variant is.
const int OW_NEWTON_STEPS = 2;

vec2 ow_map_inverse_near(sampler2D rows, sampler2D cols, int slot, int warp_size, vec4 crop, vec2 uv,
                         vec2 xy_start)
{
  vec2 xy = xy_start;
  for (int step = 0; step < OW_NEWTON_STEPS; step++) {
    mat2 jacobian;
    vec2 residual = uv - ow_map_forward_jacobian(rows, cols, slot, warp_size, crop, xy, jacobian);
    // d(map uv)/d(xy) = J / 2, since uncropped uv = xy / 2 + 1/2.
    xy += 2.0 * (inverse(jacobian) * residual);
  }
  return xy;
}
#endif
