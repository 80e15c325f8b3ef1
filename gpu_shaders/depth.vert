// Depth pass, vertex stage: project a light-centred vertex into one layer.
#include "lib/projection.glsl"
#include "lib/mapping.glsl"

void main()
{
  vec3 local_pos = ow_layer_rot * ow_position;
  v_distance = length(ow_position);
  v_plane = ow_plane;
  v_range = ow_range;
  if (ow_layer_kind == OW_KIND_PARABOLOID || ow_mapped != 0) {
    // Paraboloid pieces were split at the seam on the CPU (1 + v.z >= 1); cube
    // pieces of a cropped or warped face were clipped to z > 0 on the CPU. Either
    // way the map position is final here, so w = 1 and depth comes from the
    // fragment stage.
    float magnification;
    vec2 xy = ow_project(ow_layer_kind, local_pos);
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
