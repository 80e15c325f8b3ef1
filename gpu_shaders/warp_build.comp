// The NoTW analysis on the GPU (thesis Algorithm 3, steps 3-7): the DV crop's bounds and
// the warp tables are built from the count strip the scatter left (scatter.comp), and
// written where the next passes read them; addon/core/warping.py is the numpy oracle
// (dv_crop_from_counts, notw_rows, notw_cols) and names the constants.
//
// The strip holds one A x A count map per drawn layer: tile t at columns t A .. t A + A - 1,
// row = v. Each step is its own program (OW_STEP) and dispatch:
//  OW_WARP_CROP    one invocation per strip texel: the occupied cells' first and last
//                  column and row per tile, as maxima (a minimum as the maximum of its
//                  complement, so the image starts from zeros) at ow_bounds (4 t .. 4 t + 3).
//  OW_WARP_CROP_STORE  one invocation per tile: the DV crop from those bounds, grown by
//                  OW_CROP_MARGIN cells (warping.dv_crop_from_bounds), stored as (lo, scale)
//                  at texel (A, slot A + 1) of the rows table, where every warped pass
//                  reads it (lib/mapping.glsl's ow_crop_of). Nothing is read back.
//  OW_WARP_LINE_BLUR  one invocation per cell: the counts blurred along the family's lines
//                  (ow_family: rows, the map's rows; columns, its columns) at ow_work.
//  OW_WARP_LINES   one invocation per (tile, line): the line's offsets (eq. 4.7, floor
//                  share and steepness clamp) at ow_work columns 0 .. A and its total at
//                  column A + 1 (float bits).
//  OW_WARP_SMOOTH_*  the smoothing across lines (below), in four wide steps: the lines'
//                  weights; the denominator at every candidate window (1, 2, 4, ...);
//                  each candidate's largest shear, a node an invocation; the narrowest
//                  window that leaves the shear under OW_SHEAR_LIMIT (else the first past
//                  A / 2), its smoothed offsets written to the output columns, and the
//                  window and shear at ow_info.
//  OW_WARP_RTW_*   RTW's one function of the family (no smoothing), in three wide steps.
//  OW_WARP_PACK    one invocation per texel of the table (ow_table, the layout of
//                  passes/samples.pack_warp_table): nodes k and k + 1 of function i and of
//                  function i + 1; column A holds the shear and the window. It also
//                  reduces the family's steepest slope into ow_info, which with the
//                  shears and the crop's scale lets a host size point sprites.


uint ow_bits(float value)
{
  return floatBitsToUint(value);
}

float ow_work_value(int tile, int line, int k)
{
  return uintBitsToFloat(imageLoad(ow_work, ivec2(k, tile * ow_count_size + line)).x);
}

void ow_set_work(int tile, int line, int k, float value)
{
  imageStore(ow_work, ivec2(k, tile * ow_count_size + line), uvec4(ow_bits(value)));
}

// The count at position `k` along line `line` of tile `tile`'s map, in the family's order.
float ow_count(int tile, int line, int k)
{
  int size = ow_count_size;
  ivec2 cell = (ow_family == OW_FAMILY_ROWS) ? ivec2(k, line) : ivec2(line, k);
  return float(imageLoad(ow_counts, ivec2(tile * size + cell.x, cell.y)).x);
}

void ow_crop_bounds(int index)
{
  int size = ow_count_size;
  if (index >= size * size * ow_tiles) {
    return;
  }
  int x = index % (size * ow_tiles);
  int y = index / (size * ow_tiles);
  if (imageLoad(ow_counts, ivec2(x, y)).x == 0u) {
    return;
  }
  int tile = x / size;
  uint col = uint(x % size);
  imageAtomicMax(ow_bounds, ivec2(4 * tile + 0, 0), ~col);
  imageAtomicMax(ow_bounds, ivec2(4 * tile + 1, 0), col);
  imageAtomicMax(ow_bounds, ivec2(4 * tile + 2, 0), ~uint(y));
  imageAtomicMax(ow_bounds, ivec2(4 * tile + 3, 0), uint(y));
}

// Every step keeps its per-line numbers in the work image, never in private arrays: a
// software rasteriser (llvmpipe) takes tens of seconds to compile a float[256] indexed at
// run time. A line's columns 0 .. A hold its densities, then its offsets; column A + 1
// its total; the smoothed (or RTW's) offsets go to columns OW_OUT_COLUMN .. + A.
#define OW_OUT_COLUMN (ow_count_size + 4)

// warping.offsets_from_counts of line `line`, whose densities columns 0 .. A - 1 hold
// (`total` their sum > 0): its offsets replace them at columns 0 .. A.
void ow_write_offsets(int tile, int line, float total)
{
  int size = ow_count_size;
  for (int k = 0; k < size; k++) {
    float share = ow_work_value(tile, line, k);
    ow_set_work(tile, line, k, (1.0 - OW_FLOOR_SHARE) * (share / total) + OW_FLOOR_SHARE / float(size));
  }
  // Water filling (warping._cap_density): cap every share at OW_MAX_SLOPE / A and scale
  // the others up so that they still sum to 1. The capped set only grows, largest shares
  // first, so the loop ends at the exact set the sorted version finds.
  float cap = OW_MAX_SLOPE / float(size);
  float scale = 1.0;
  int capped = 0;
  for (int round = 0; round < size; round++) {
    float rest = 0.0;
    int count = 0;
    for (int k = 0; k < size; k++) {
      float share = ow_work_value(tile, line, k);
      if (share * scale > cap * (1.0 + 1e-6)) {
        count++;
      }
      else {
        rest += share;
      }
    }
    if (count == capped) {
      break;
    }
    capped = count;
    scale = (1.0 - float(count) * cap) / max(rest, 1e-30);
  }
  float running = 0.0;
  for (int k = 0; k < size; k++) {
    running += min(ow_work_value(tile, line, k) * scale, cap);
    ow_set_work(tile, line, k, running);  // the cumulative share up to node k + 1
  }
  // Node k's offset from the cumulative share up to it (column k - 1): downwards, so that
  // each read comes before its column is overwritten.
  for (int k = size - 1; k >= 1; k--) {
    ow_set_work(tile, line, k, ow_work_value(tile, line, k - 1) / running - float(k) / float(size));
  }
  ow_set_work(tile, line, 0, 0.0);
  ow_set_work(tile, line, size, 0.0);
}

void ow_write_identity(int tile, int line)
{
  for (int k = 0; k <= ow_count_size; k++) {
    ow_set_work(tile, line, k, 0.0);  // an empty line: the identity
  }
}

// NoTW's lines in two steps. First an invocation a cell: the line's counts blurred along
// it by the tent, divided by the tent of ones so that a uniform line stays uniform up to
// its ends (warping.tent_filter zero-pads).
void ow_line_blur(int index)
{
  int size = ow_count_size;
  int k = index % size;
  int line = (index / size) % size;
  int tile = index / size / size;
  if (tile >= ow_tiles) {
    return;
  }
  float sum = 0.0;
  float weight = 0.0;
  for (int d = -ow_along; d <= ow_along; d++) {
    int j = k + d;
    if (j >= 0 && j < size) {
      float w = 1.0 - float(abs(d)) / float(ow_along + 1);
      sum += w * ow_count(tile, line, j);
      weight += w;
    }
  }
  ow_set_work(tile, line, k, sum / weight);
}

// Then an invocation a (tile, line): the line's offsets and its total.
void ow_line(int index)
{
  int size = ow_count_size;
  if (index >= size * ow_tiles) {
    return;
  }
  int tile = index / size;
  int line = index % size;
  float total = 0.0;
  for (int k = 0; k < size; k++) {
    total += ow_work_value(tile, line, k);
  }
  if (total > 0.0) {
    ow_write_offsets(tile, line, total);
  }
  else {
    ow_write_identity(tile, line);
  }
  ow_set_work(tile, line, size + 1, max(total, 0.0));
}

// RTW (warping.rtw_from_counts): the family's one function, from the largest count across
// each position, blurred by a zero-padded tent of half-width ow_along, written to every
// line's output, with the window and a shear of 0 (its lines are equal). Three steps, each
// wide: the largest across (an invocation a position, into line 1's columns); the blur and
// offsets (an invocation a tile, into line 0's); the spread (an invocation an output node).
void ow_rtw_top(int index)
{
  int size = ow_count_size;
  int k = index % size;
  int tile = index / size;
  if (tile >= ow_tiles) {
    return;
  }
  float top = 0.0;
  for (int line = 0; line < size; line++) {
    top = max(top, ow_count(tile, line, k));
  }
  ow_set_work(tile, 1, k, top);
}

void ow_rtw(int tile)
{
  int size = ow_count_size;
  if (tile >= ow_tiles) {
    return;
  }
  float total = 0.0;
  for (int k = 0; k < size; k++) {
    float sum = 0.0;
    for (int d = -ow_along; d <= ow_along; d++) {
      int j = k + d;
      if (j >= 0 && j < size) {
        sum += (1.0 - float(abs(d)) / float(ow_along + 1)) * ow_work_value(tile, 1, j);
      }
    }
    ow_set_work(tile, 0, k, sum);
    total += sum;
  }
  if (total > 0.0) {
    ow_write_offsets(tile, 0, total);
  }
  else {
    ow_write_identity(tile, 0);
  }
  imageStore(ow_info, ivec2(OW_INFO_WINDOW + 2 * ow_family, tile), uvec4(uint(ow_along)));
  imageStore(ow_info, ivec2(OW_INFO_SHEAR + 2 * ow_family, tile), uvec4(ow_bits(0.0)));
}

void ow_rtw_spread(int index)
{
  int width = ow_count_size + 1;
  int k = index % width;
  int line = (index / width) % ow_count_size;
  int tile = index / width / ow_count_size;
  if (tile >= ow_tiles) {
    return;
  }
  ow_set_work(tile, line, OW_OUT_COLUMN + k, ow_work_value(tile, 0, k));
}

// The smoothing (warping.choose_window, smooth_offsets) in four steps, each wide: the
// candidate windows are tried side by side, each column of each by an invocation of its
// own, so that no invocation walks more than one pass over the tile's lines (a GPU runs
// a long serial loop at its memory latency). Work columns: A + 2 holds each line's total
// over the tile's largest (its weight); OW_DEN_COLUMN(j) the tent of the weights plus the
// prior at candidate window j. ow_info (a row a tile, shaders/constants.WARP_INFO) holds
// the populated lines and their weights' sum, and each candidate's largest shear.
#define OW_WEIGHT_COLUMN (ow_count_size + 2)
#define OW_DEN_COLUMN(j) (2 * ow_count_size + 5 + (j))

uint ow_info_value(int column, int tile)
{
  return imageLoad(ow_info, ivec2(column, tile)).x;
}

// The candidate windows 1, 2, 4, ...: those below A / 2, then the first at or past it.
int ow_window_count()
{
  int count = 1;
  while ((1 << (count - 1)) < ow_count_size / 2) {
    count++;
  }
  return count;
}

// A compensated running sum: (sum, its lost low part) plus `value`.
vec2 ow_kahan_add(vec2 sum, float value)
{
  float y = value - sum.y;
  float t = sum.x + y;
  return vec2(t, (t - sum.x) - y);
}

// What ow_tent_pass does with the tent at each line.
#define OW_TENT_DEN 0
#define OW_TENT_SHEAR 1
#define OW_TENT_STORE 2

// The tent's input at line j: the line's weight (k < 0) or its weight times its offset at
// node k; 0 outside the tile's lines (warping.tent_filter zero-pads).
float ow_tent_value(int tile, int j, int k)
{
  if (j < 0 || j >= ow_count_size) {
    return 0.0;
  }
  float weight = ow_work_value(tile, j, OW_WEIGHT_COLUMN);
  return k < 0 ? weight : weight * ow_work_value(tile, j, k);
}

// warping.tent_filter across lines at half-width `window` (weights 1 - |d| / n, n = window
// + 1) of the weights (k < 0) or of node k's weighted offsets, by running sums: f is the
// forward box of width n at padded line p, g the same box n lines back, b the backward box
// of f. Then by `mode`: OW_TENT_DEN stores the tent plus `prior` at work column
// `den_column` (the smoothing's denominator); OW_TENT_SHEAR returns the largest step of the
// smoothed column between neighbouring lines times A (warping.max_shear); OW_TENT_STORE
// writes the smoothed column to node k's output (warping.smooth_offsets).
float ow_tent_pass(int tile, int k, int window, int mode, float prior, int den_column)
{
  int size = ow_count_size;
  int n = window + 1;
  // Each running sum carries its rounding error (Kahan), so that float32 keeps the
  // numpy oracle's offsets to a few 1e-6 over hundreds of lines.
  vec2 f = vec2(0.0);
  vec2 g = vec2(0.0);
  vec2 b = vec2(0.0);
  float previous = 0.0;
  float shear = 0.0;
  for (int p = 0; p < size + window; p++) {
    float lagged = ow_tent_value(tile, p - n, k);
    f = ow_kahan_add(ow_kahan_add(f, ow_tent_value(tile, p, k)), -lagged);
    g = ow_kahan_add(ow_kahan_add(g, lagged), -ow_tent_value(tile, p - 2 * n, k));
    b = ow_kahan_add(ow_kahan_add(b, f.x), -g.x);
    int i = p - window;
    if (i < 0) {
      continue;
    }
    float tent = b.x / float(n);
    if (mode == OW_TENT_DEN) {
      ow_set_work(tile, i, den_column, tent + prior);
      continue;
    }
    float den = ow_work_value(tile, i, den_column);
    float smoothed = den > 0.0 ? tent / den : 0.0;
    if (i > 0) {
      shear = max(shear, abs(smoothed - previous) * float(size));
    }
    previous = smoothed;
    if (mode == OW_TENT_STORE) {
      ow_set_work(tile, i, OW_OUT_COLUMN + k, smoothed);
    }
  }
  return shear;
}

// Step 1, an invocation a tile: each line's weight (its total over the tile's largest),
// the populated lines and their weights' sum.
void ow_smooth_weights(int tile)
{
  int size = ow_count_size;
  if (tile >= ow_tiles) {
    return;
  }
  float top = 0.0;
  for (int i = 0; i < size; i++) {
    top = max(top, ow_work_value(tile, i, size + 1));
  }
  uint populated = 0u;
  float sum = 0.0;
  for (int i = 0; i < size; i++) {
    float weight = top > 0.0 ? ow_work_value(tile, i, size + 1) / top : 0.0;
    ow_set_work(tile, i, OW_WEIGHT_COLUMN, weight);
    if (weight > 0.0) {
      populated++;
      sum += weight;
    }
  }
  imageStore(ow_info, ivec2(OW_INFO_POPULATED, tile), uvec4(populated));
  imageStore(ow_info, ivec2(OW_INFO_WEIGHT_SUM, tile), uvec4(ow_bits(sum)));
}

// Step 2, an invocation a (tile, candidate j): the denominator at window 2^j, and the
// candidate's shear reset for step 3.
void ow_smooth_den(int index)
{
  int tile = index / OW_WARP_WINDOWS;
  int j = index % OW_WARP_WINDOWS;
  if (tile >= ow_tiles || j >= ow_window_count()) {
    return;
  }
  float populated = float(ow_info_value(OW_INFO_POPULATED, tile));
  if (populated == 0.0) {
    return;  // every line empty: step 4 keeps them as they are
  }
  float prior = OW_IDENTITY_PRIOR * uintBitsToFloat(ow_info_value(OW_INFO_WEIGHT_SUM, tile)) / populated;
  ow_tent_pass(tile, -1, 1 << j, OW_TENT_DEN, prior, OW_DEN_COLUMN(j));
  imageStore(ow_info, ivec2(OW_INFO_WINDOW_SHEAR + j, tile), uvec4(0u));
}

// Step 3, an invocation a (tile, candidate j, node k): node k's largest shear at window 2^j,
// reduced over the nodes (a non-negative float orders as its bits).
void ow_smooth_shear(int index)
{
  int width = ow_count_size + 1;
  int k = index % width;
  int tile = index / width / OW_WARP_WINDOWS;
  int j = (index / width) % OW_WARP_WINDOWS;
  if (tile >= ow_tiles || j >= ow_window_count()) {
    return;
  }
  uint populated = ow_info_value(OW_INFO_POPULATED, tile);
  if (populated == 0u) {
    return;
  }
  float shear = ow_tent_pass(tile, k, 1 << j, OW_TENT_SHEAR, 0.0, OW_DEN_COLUMN(j));
  imageAtomicMax(ow_info, ivec2(OW_INFO_WINDOW_SHEAR + j, tile), ow_bits(shear));
}

// Step 4, an invocation a (tile, node k): the narrowest candidate below A / 2 whose shear
// is under OW_SHEAR_LIMIT, else the last; node k smoothed at it. Node 0's invocation stores
// the window and its shear.
void ow_smooth_store(int index)
{
  int size = ow_count_size;
  int k = index % (size + 1);
  int tile = index / (size + 1);
  if (tile >= ow_tiles) {
    return;
  }
  int window = 0;
  float shear = 0.0;
  uint populated = ow_info_value(OW_INFO_POPULATED, tile);
  if (populated == 0u) {
    for (int i = 0; i < size; i++) {
      ow_set_work(tile, i, OW_OUT_COLUMN + k, ow_work_value(tile, i, k));  // every line empty: as they are
    }
  }
  else {
    int last = ow_window_count() - 1;
    int j = 0;
    shear = uintBitsToFloat(ow_info_value(OW_INFO_WINDOW_SHEAR, tile));
    while (j < last && shear > OW_SHEAR_LIMIT) {
      j++;
      shear = uintBitsToFloat(ow_info_value(OW_INFO_WINDOW_SHEAR + j, tile));
    }
    window = 1 << j;
    ow_tent_pass(tile, k, window, OW_TENT_STORE, 0.0, OW_DEN_COLUMN(j));
  }
  if (k == 0) {
    imageStore(ow_info, ivec2(OW_INFO_WINDOW + 2 * ow_family, tile), uvec4(uint(window)));
    imageStore(ow_info, ivec2(OW_INFO_SHEAR + 2 * ow_family, tile), uvec4(ow_bits(shear)));
  }
}

void ow_crop_store(int tile)
{
  if (tile >= ow_tiles) {
    return;
  }
  float size = float(ow_count_size);
  vec4 crop = vec4(0.0, 0.0, 1.0, 1.0);  // an empty map keeps the whole map
  uint lo_col = imageLoad(ow_bounds, ivec2(4 * tile + 0, 0)).x;
  if (lo_col != 0u) {  // the complement of a column index is never 0 once a cell counted
    vec2 first = vec2(float(~lo_col), float(~imageLoad(ow_bounds, ivec2(4 * tile + 2, 0)).x));
    vec2 last = vec2(float(imageLoad(ow_bounds, ivec2(4 * tile + 1, 0)).x),
                     float(imageLoad(ow_bounds, ivec2(4 * tile + 3, 0)).x));
    vec2 lo = clamp((first - OW_CROP_MARGIN) / size, 0.0, 1.0);
    vec2 hi = clamp((last + 1.0 + OW_CROP_MARGIN) / size, 0.0, 1.0);
    crop = vec4(lo, 1.0 / (hi - lo));
  }
  imageStore(ow_table, ivec2(ow_count_size, ow_tile_slot[tile] * ow_count_size + 1), crop);
  // Its scale, beside the families' shears, for a host that sizes point sprites (passes/warp.py).
  imageStore(ow_info, ivec2(OW_INFO_CROP_SCALE, tile), uvec4(ow_bits(crop.z)));
  imageStore(ow_info, ivec2(OW_INFO_CROP_SCALE + 1, tile), uvec4(ow_bits(crop.w)));
  imageStore(ow_info, ivec2(OW_INFO_SLOPE, tile), uvec4(0u));  // each family's steepest slope, from pack
  imageStore(ow_info, ivec2(OW_INFO_SLOPE + 1, tile), uvec4(0u));
}

void ow_pack(int index)
{
  int size = ow_count_size;
  int width = size + 1;
  if (index >= width * size * ow_tiles) {
    return;
  }
  int k = index % width;
  int row = index / width;
  int tile = row / size;
  int i = row % size;
  int slot = ow_tile_slot[tile];
  vec4 texel;
  if (k == size && i == 1) {
    return;  // the rows table's crop (ow_crop_store); unused in the columns table
  }
  if (k == size) {
    texel = i == 0 ? vec4(uintBitsToFloat(imageLoad(ow_info, ivec2(OW_INFO_SHEAR + 2 * ow_family, tile)).x),
                          float(imageLoad(ow_info, ivec2(OW_INFO_WINDOW + 2 * ow_family, tile)).x), 0.0, 0.0)
                   : vec4(0.0);
  }
  else {
    int next = min(i + 1, size - 1);
    texel = vec4(ow_work_value(tile, i, OW_OUT_COLUMN + k), ow_work_value(tile, i, OW_OUT_COLUMN + k + 1),
                 ow_work_value(tile, next, OW_OUT_COLUMN + k), ow_work_value(tile, next, OW_OUT_COLUMN + k + 1));
    // The family's steepest d(offset)/d(along) (footprint_runs._slopes), at least 0: a
    // non-negative float orders as its bits.
    float slope = max((texel.y - texel.x) * float(size), 0.0);
    imageAtomicMax(ow_info, ivec2(OW_INFO_SLOPE + ow_family, tile), ow_bits(slope));
  }
  imageStore(ow_table, ivec2(k, slot * size + i), texel);
}

// Each step is a program of its own (shaders.warp_step_variant defines OW_STEP), so that
// the simple steps carry none of the others' private arrays.
void main()
{
  int index = int(gl_GlobalInvocationID.x);
#if OW_STEP == OW_WARP_CROP
  ow_crop_bounds(index);
#elif OW_STEP == OW_WARP_CROP_STORE
  ow_crop_store(index);
#elif OW_STEP == OW_WARP_LINE_BLUR
  ow_line_blur(index);
#elif OW_STEP == OW_WARP_LINES
  ow_line(index);
#elif OW_STEP == OW_WARP_SMOOTH_WEIGHTS
  ow_smooth_weights(index);
#elif OW_STEP == OW_WARP_SMOOTH_DEN
  ow_smooth_den(index);
#elif OW_STEP == OW_WARP_SMOOTH_SHEAR
  ow_smooth_shear(index);
#elif OW_STEP == OW_WARP_SMOOTH_STORE
  ow_smooth_store(index);
#elif OW_STEP == OW_WARP_RTW_TOP
  ow_rtw_top(index);
#elif OW_STEP == OW_WARP_RTW
  ow_rtw(index);
#elif OW_STEP == OW_WARP_RTW_SPREAD
  ow_rtw_spread(index);
#else
  ow_pack(index);
#endif
}
