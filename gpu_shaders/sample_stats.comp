// Planning statistics over the view samples; addon/core/samples.py is the numpy
// oracle and names the fields (STAT_FIELDS, emitted here as OW_STAT_* defines).
// ow_stats_pass 0: count, pixel rectangle, view-depth range, light-centred box, the
// largest coordinate and the occupied slots, as integers at texels [0, OW_STAT_COUNT).
// ow_stats_pass 1: the histogram of view depths over [ow_depth_lo, ow_depth_hi], at
// texels OW_STAT_COUNT + bin (log-spaced bins when ow_log_bins != 0).
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

void ow_put_max(int field, uint value)
{
  imageAtomicMax(ow_stats, ivec2(field, 0), value);
}

void main()
{
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
      float t = (ow_log_bins != 0) ? log(max(depth, ow_depth_lo) / ow_depth_lo) / log(ow_depth_hi / ow_depth_lo)
                                   : (depth - ow_depth_lo) / (ow_depth_hi - ow_depth_lo);
      int bin = (ow_depth_hi > ow_depth_lo) ? clamp(int(floor(t * float(OW_HIST_BINS))), 0, OW_HIST_BINS - 1) : 0;
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
