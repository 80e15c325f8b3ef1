// Count-map scatter: one point per view sample, added into the texel it maps to.
// ow_scatter_mode: 0 = after the DV crop, 1 = also through the row warps (step 6 of
// Algorithm 3), 2 = through the full warp (the importance map).
#include "lib/projection.glsl"
#include "lib/layers.glsl"
#include "lib/mapping.glsl"

void main()
{
  gl_PointSize = 1.0;
  gl_Position = vec4(4.0, 4.0, 0.0, 1.0);  // outside the target: not counted
  int index = int(ow_index);
  ivec2 size = textureSize(ow_positions, 0);
  vec4 pw = texelFetch(ow_positions, ivec2(index % size.x, index / size.x), 0);
  float dist = length(pw.xyz);
  if (pw.w < 0.5 || !(dist > 0.0)) {
    return;
  }
  vec3 dir = pw.xyz / dist;
  vec3 ldir = ow_light_rot * dir;
  if ((ow_hemi != 0 && ldir.z >= 0.0) || ow_pick_slot(ow_param, ldir) != ow_layer_slot) {
    return;
  }
  vec2 xy = ow_project(ow_layer_kind, ow_layer_rot * dir);
  vec2 uv = ((xy * 0.5 + 0.5) - ow_crop.xy) * ow_crop.zw;
  if (ow_scatter_mode == 1) {
    uv = ow_apply_row_warp(ow_warp_rows, ow_layer_slot, ow_warp_size, uv);
  }
  else if (ow_scatter_mode == 2) {
    float magnification;
    uv = ow_map_forward(ow_warp_rows, ow_warp_cols, ow_layer_slot, ow_warp_size, ow_crop, xy, magnification);
  }
  gl_Position = vec4(uv * 2.0 - 1.0, 0.0, 1.0);
}
