// Count-map scatter (thesis Algorithm 3, steps 2 and 6): one invocation per view
// sample adds one to the count-map texel it maps to, with imageAtomicAdd on R32UI, so
// counts are exact integers. Every drawn layer goes out in the same dispatch: layer
// slot s writes the tile at x = ow_slot_tile[s] * ow_count_size (OW_NO_TILE: not drawn).
// ow_scatter_mode: OW_SCATTER_CROP = after the DV crop, OW_SCATTER_ROWS = also through the row warps,
// OW_SCATTER_WARP = through the full warp (the importance map). With ow_weighted != 0 a sample adds
// its importance weight, which the positions' w holds (an integer >= 1 where the
// pixel hit, 0 where it missed), instead of one: the warp analysis counts weights,
// the count statistics count samples. Variants built for one mode define
// OW_SCATTER_MODE (shaders.scatter_variant), so the other modes compile out. Built with
// OW_LINK (mode 2), the pass links each sample into its texel's list instead of counting.
#include "lib/projection.glsl"
#include "lib/layers.glsl"
#include "lib/mapping.glsl"
#include "lib/projective.glsl"

#ifdef OW_SCATTER_MODE
#define OW_MODE OW_SCATTER_MODE
#else
#define OW_MODE ow_scatter_mode
#endif

// Sample `index` (of the `size` sample texture; `pw` its position and weight) goes to the
// texel of tile `tile` that holds its map position `uv`.
void ow_scatter_to(int index, ivec2 size, vec4 pw, int tile, vec2 uv)
{
  // Points outside [0, 1)^2, or NaN, are dropped, as in warping.scatter_counts (the
  // numpy oracle); written so that a NaN fails the test instead of reaching floor().
  if (!(all(greaterThanEqual(uv, vec2(0.0))) && all(lessThan(uv, vec2(1.0))))) {
    return;
  }
  ivec2 texel = min(ivec2(floor(uv * float(ow_count_size))), ivec2(ow_count_size - 1));
#ifdef OW_LINK
  // The irregular z-buffer's lists (shaders.link_variant): the sample goes to the front of
  // its texel's list. A texel of ow_counts holds the list's head (0: empty, else sample
  // index + 1), ow_next the rest, so the list lengths are the counts of mode 2.
  uint previous = imageAtomicExchange(ow_counts, texel + ivec2(tile * ow_count_size, 0), uint(index + 1));
  imageStore(ow_next, ivec2(index % size.x, index / size.x), uvec4(previous));
#else
  uint amount = ow_weighted != 0 ? uint(pw.w + 0.5) : 1u;
  imageAtomicAdd(ow_counts, texel + ivec2(tile * ow_count_size, 0), amount);
#endif
}

void main()
{
  ivec2 size = textureSize(ow_positions, 0);
  int index = int(gl_GlobalInvocationID.x);
  if (index >= size.x * size.y) {
    return;
  }
  vec4 pw = texelFetch(ow_positions, ivec2(index % size.x, index / size.x), 0);
#ifndef OW_FIXED_KIND
  if (ow_projective != 0) {
    // A spot's or sun's map: its one layer, through the matrix the shadow test projects
    // with (lib/projective.glsl); a sample behind the map goes nowhere.
    float w;
    vec2 uv = ow_projective_uvz(ow_map_matrix, pw.xyz, w).xy;
    if (pw.w >= 0.5 && w > 0.0) {
      ow_scatter_to(index, size, pw, 0, uv);
    }
    return;
  }
#endif
  float dist = length(pw.xyz);
  if (pw.w < 0.5 || !(dist > 0.0)) {
    return;
  }
  vec3 dir = pw.xyz / dist;
  vec3 ldir = ow_light_rot * dir;
  if (ow_hemi != 0 && ldir.z >= 0.0) {
    return;
  }
  int slot = ow_pick_slot(ow_param, ldir);
  int tile = ow_slot_tile[slot];
  if (tile <= OW_NO_TILE) {
    return;
  }
  // A warped layer's crop is in its rows table, even where this mode applies no warp.
  vec4 crop = ow_crop_of(ow_warp_rows, slot, ow_warp_size, ow_layer_crop[slot]);
  vec2 xy = ow_project(ow_layer_kind, ow_layer_rot[slot] * dir);
  vec2 uv = ((xy * 0.5 + 0.5) - crop.xy) * crop.zw;
  if (OW_MODE == OW_SCATTER_ROWS) {
    uv = ow_apply_row_warp(ow_warp_rows, slot, ow_warp_size, uv);
  }
  else if (OW_MODE == OW_SCATTER_WARP) {
    float magnification;
    uv = ow_map_forward(ow_warp_rows, ow_warp_cols, slot, ow_warp_size, crop, xy, magnification);
  }
  ow_scatter_to(index, size, pw, tile, uv);
}
