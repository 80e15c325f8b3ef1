// Planning statistics over the view samples; addon/core/samples.py is the numpy
// oracle and names the fields (STAT_FIELDS, emitted here as OW_STAT_* defines).
// ow_stats_pass 0: count, pixel rectangle, view-depth range, light-centred box, the
// largest coordinate and the occupied slots, as integers at texels [0, OW_STAT_COUNT).
// ow_stats_pass 1: the histogram of view depths over the range pass 0 left in the image,
// grown by rounding as core.samples.depth_slack grows it, at texels OW_STAT_COUNT + bin
// (log-spaced bins for a perspective view in front of the camera).
// ow_stats_pass 2 (one work group): the bins of the percentile cut's samples and the
// bins' spacing, at the fields cut_lo, cut_hi and cut_log (core.samples.cut_bins).
// The last pass (2, or 3 "copy" without a histogram; one work group) copies the
// OW_STAT_COUNT fields into ow_stats_out, which the host reads once: a texture of the
// fields alone, since Blender's gpu reads whole textures (the histogram is 4 KB).
// An invocation reduces OW_STAT_SPAN samples in registers and then writes each field
// with one atomic: a sixteenth of the atomics on the same few texels. Minimums are
// stored as the maximum of their complement, so the image starts from zeros.
#include "lib/layers.glsl"

// An order-preserving uint key of a float: a < b iff key(a) < key(b).
uint ow_ordered(float v)
{
  uint bits = floatBitsToUint(v);
  return (bits & 0x80000000u) != 0u ? ~bits : (bits | 0x80000000u);
}

// The float of an order-preserving key (the inverse of ow_ordered).
float ow_unordered(uint key)
{
  return uintBitsToFloat((key & 0x80000000u) != 0u ? (key & 0x7FFFFFFFu) : ~key);
}

void ow_put_max(int field, uint value)
{
  imageAtomicMax(ow_stats, ivec2(field, 0), value);
}

uint ow_field(int field)
{
  return imageLoad(ow_stats, ivec2(field, 0)).x;
}

// Pass 0's view-depth range, grown by rounding, and whether its bins are log-spaced.
vec2 ow_depth_range(out bool log_bins)
{
  float reach = ow_unordered(ow_field(OW_STAT_reach));
  vec3 axis = abs(ow_view_axis);
  float slack = OW_ROUNDING * (3.0 * reach * max(axis.x, max(axis.y, axis.z)) + abs(ow_view_offset));
  vec2 range = vec2(ow_unordered(~ow_field(OW_STAT_depth_lo)) - slack, ow_unordered(ow_field(OW_STAT_depth_hi)) + slack);
  log_bins = ow_ortho == 0 && range.x > 0.0;
  return range;
}

// Pass 2: core.samples.cut_ranks in integers (the percentile in OW_CUT_STEPS steps), split
// so that no product passes 32 bits: last * q / steps = (a q) + (b q) / steps. Then the
// first bin whose running count exceeds each rank (np.searchsorted(cumsum, rank + 1)),
// by the whole group: invocation t sums chunk t of the histogram into the texel after it,
// counts the chunks before its own, and walks its chunk for a rank that falls in it. A
// GPU runs a serial loop at its memory latency, so none walks the whole histogram.
// Called by every invocation of the group (it has barriers).
void ow_cut()
{
  int lane = int(gl_LocalInvocationID.x);
  const int chunk = OW_HIST_BINS / OW_CUT_CHUNKS;
  int first = OW_STAT_COUNT + lane * chunk;
  uint sum = 0u;
  for (int k = 0; k < chunk; k++) {
    sum += ow_field(first + k);
  }
  imageStore(ow_stats, ivec2(OW_STAT_COUNT + OW_HIST_BINS + lane, 0), uvec4(sum));
  memoryBarrierImage();
  barrier();
  uint n = ow_field(OW_STAT_count);
  if (n == 0u || OW_CUT_Q == 0) {
    return;
  }
  uint before = 0u;
  for (int c = 0; c < lane; c++) {
    before += ow_field(OW_STAT_COUNT + OW_HIST_BINS + c);
  }
  uint last = n - 1u, steps = uint(OW_CUT_STEPS), q = uint(OW_CUT_Q);
  uint a = last / steps, b = last % steps;
  uvec2 ranks = uvec2(a * q + (b * q) / steps, a * (steps - q) + (b * (steps - q) + steps - 1u) / steps);
  for (int end = 0; end < 2; end++) {
    uint rank = ranks[end];
    int bin = -1;
    if (rank >= before && rank - before < sum) {
      uint running = before;
      for (int k = 0; k < chunk && bin < 0; k++) {
        running += ow_field(first + k);
        if (running > rank) {
          bin = lane * chunk + k;
        }
      }
    }
    else if (lane == OW_CUT_CHUNKS - 1 && rank >= before + sum) {
      bin = OW_HIST_BINS;  // past every sample (not reached: the ranks are below the count)
    }
    if (bin >= 0) {
      imageStore(ow_stats, ivec2(end == 0 ? OW_STAT_cut_lo : OW_STAT_cut_hi, 0), uvec4(uint(bin) + 1u));
    }
  }
  if (lane == 0) {
    bool log_bins;
    ow_depth_range(log_bins);
    imageStore(ow_stats, ivec2(OW_STAT_cut_log, 0), uvec4(log_bins ? 2u : 1u));
  }
}

// The fields into the texture the host reads (one invocation, after the group's barrier).
void ow_copy_fields()
{
  for (int field = 0; field < OW_STAT_COUNT; field++) {
    imageStore(ow_stats_out, ivec2(field, 0), uvec4(ow_field(field)));
  }
}

void main()
{
  if (ow_stats_pass == OW_STATS_CUT || ow_stats_pass == OW_STATS_COPY) {
    if (ow_stats_pass == OW_STATS_CUT) {
      ow_cut();
      memoryBarrierImage();
      barrier();  // the cut's bins, before one invocation copies the fields
    }
    if (gl_LocalInvocationID.x == 0u) {
      ow_copy_fields();
    }
    return;
  }
  bool log_bins = false;
  vec2 range = vec2(0.0);
  if (ow_stats_pass == OW_STATS_HISTOGRAM) {
    range = ow_depth_range(log_bins);
  }
  ivec2 size = textureSize(ow_positions, 0);
  int total = size.x * size.y;
  int first = int(gl_GlobalInvocationID.x) * OW_STAT_SPAN;
  if (first >= total) {
    return;
  }
  uint count = 0u;
  uint col_lo = 0xFFFFFFFFu, col_hi = 0u, row_lo = 0xFFFFFFFFu, row_hi = 0u;
  float depth_lo = 3.4e38, depth_hi = -3.4e38, reach = 0.0;
  vec3 lo = vec3(3.4e38), hi = vec3(-3.4e38);
  uint sides = 0u, faces = 0u;
  for (int k = 0; k < OW_STAT_SPAN; k++) {
    int index = first + k;
    if (index >= total) {
      break;
    }
    ivec2 texel = ivec2(index % size.x, index / size.x);
    vec4 pw = texelFetch(ow_positions, texel, 0);
    if (pw.w < 0.5) {
      continue;  // a miss (the upload zeroes misses and non-finite positions)
    }
    float depth = dot(pw.xyz, ow_view_axis) + ow_view_offset;
    if (ow_stats_pass == OW_STATS_HISTOGRAM) {
      float t = log_bins ? log(max(depth, range.x) / range.x) / log(range.y / range.x)
                         : (depth - range.x) / (range.y - range.x);
      int bin = (range.y > range.x) ? clamp(int(floor(t * float(OW_HIST_BINS))), 0, OW_HIST_BINS - 1) : 0;
      imageAtomicAdd(ow_stats, ivec2(OW_STAT_COUNT + bin, 0), 1u);
      continue;
    }
    count += 1u;
    col_lo = min(col_lo, uint(texel.x));
    col_hi = max(col_hi, uint(texel.x));
    row_lo = min(row_lo, uint(texel.y));
    row_hi = max(row_hi, uint(texel.y));
    depth_lo = min(depth_lo, depth);
    depth_hi = max(depth_hi, depth);
    lo = min(lo, pw.xyz);
    hi = max(hi, pw.xyz);
    vec3 a = abs(pw.xyz);
    reach = max(reach, max(a.x, max(a.y, a.z)));
    vec3 local = ow_light_rot * pw.xyz;
    if (ow_hemi == 0 || local.z < 0.0) {
      sides |= 1u << uint(ow_pick_slot(OW_PARAM_DPSM, local));
      faces |= 1u << uint(ow_pick_slot(OW_PARAM_CUBE, local));
    }
  }
  if (count == 0u) {
    return;
  }
  imageAtomicAdd(ow_stats, ivec2(OW_STAT_count, 0), count);
  ow_put_max(OW_STAT_col_lo, ~col_lo);
  ow_put_max(OW_STAT_col_hi, col_hi);
  ow_put_max(OW_STAT_row_lo, ~row_lo);
  ow_put_max(OW_STAT_row_hi, row_hi);
  ow_put_max(OW_STAT_depth_lo, ~ow_ordered(depth_lo));
  ow_put_max(OW_STAT_depth_hi, ow_ordered(depth_hi));
  ow_put_max(OW_STAT_x_lo, ~ow_ordered(lo.x));
  ow_put_max(OW_STAT_y_lo, ~ow_ordered(lo.y));
  ow_put_max(OW_STAT_z_lo, ~ow_ordered(lo.z));
  ow_put_max(OW_STAT_x_hi, ow_ordered(hi.x));
  ow_put_max(OW_STAT_y_hi, ow_ordered(hi.y));
  ow_put_max(OW_STAT_z_hi, ow_ordered(hi.z));
  ow_put_max(OW_STAT_reach, ow_ordered(reach));
  imageAtomicOr(ow_stats, ivec2(OW_STAT_sides, 0), sides);
  imageAtomicOr(ow_stats, ivec2(OW_STAT_faces, 0), faces);
}
