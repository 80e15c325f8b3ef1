// Depth pass, vertex stage: project a light-centred vertex into one layer.
#include "lib/projection.glsl"
#include "lib/mapping.glsl"

void main()
{
  vec3 local_pos = ow_layer_rot * ow_position;
  v_distance = length(ow_position);
  v_plane = ow_plane;
  v_map_xy = vec2(0.0);  // set below for cropped or warped layers (the fragment stage's start point)
  // A paraboloid or cube variant is neither projective nor an unfold.
#ifndef OW_FIXED_KIND
  if (ow_projective != 0) {
    // Spot or sun map (sm, psm): one 4x4 projective matrix; the GPU clips linearly,
    // which is exact for a projective map.
    gl_Position = ow_map_matrix * vec4(ow_position, 1.0);
    return;
  }
  if (ow_unfold_split > OW_NO_SPLIT) {
    // Dual sphere-unfolding: half 0's triangles come first in the stream, half 1's
    // after `ow_unfold_split`. Half 1's frame is half 0's with y and z negated. The
    // viewport spans the `ow_unfold_halves` tiles, half 0 on the left.
    float half_index = (gl_VertexID >= ow_unfold_split) ? 1.0 : 0.0;
    if (half_index > 0.5) {
      local_pos = vec3(local_pos.x, -local_pos.y, -local_pos.z);
    }
    vec2 uv = ow_unfold_project(local_pos) * 0.5 + 0.5;
    float x = (uv.x + half_index) / float(ow_unfold_halves);
    gl_Position = vec4(x * 2.0 - 1.0, uv.y * 2.0 - 1.0, 0.0, 1.0);
    return;
  }
#endif
  if (OW_KIND(ow_layer_kind) == OW_KIND_PARABOLOID || ow_mapped != 0) {
    // Paraboloid pieces were split at the seam on the CPU (1 + v.z >= 1); cube
    // pieces of a cropped or warped face were clipped to z > 0 on the CPU. Either
    // way the map position is final here, so w = 1 and depth comes from the
    // fragment stage.
    float magnification;
    vec2 xy = ow_project(ow_layer_kind, local_pos);
    v_map_xy = xy;
    vec2 uv = ow_map_forward(ow_warp_rows, ow_warp_cols, ow_layer_slot, ow_warp_size, ow_crop, xy,
                             magnification);
    gl_Position = vec4(uv * 2.0 - 1.0, 0.0, 1.0);
  }
  else {
    // 90 degree perspective; z only clips to [clip_near, far], the stored depth is radial.
    float n = ow_clip_near;
    float f = ow_far;
    float zc = (local_pos.z * (f + n) - 2.0 * f * n) / (f - n);
    gl_Position = vec4(local_pos.xy, zc, local_pos.z);
  }
}
