// Depth pass, vertex stage: project a light-centred vertex into one layer.
#include "lib/projection.glsl"

void main()
{
  vec3 local_pos = ow_layer_rot * ow_position;
  v_distance = length(ow_position);
  v_plane = ow_plane;
  v_range = ow_range;
  if (ow_layer_kind == OW_KIND_PARABOLOID) {
    // Triangles were split at the seam on the CPU, so 1 + v.z >= 1 here.
    gl_Position = vec4(ow_paraboloid_project(local_pos), 0.0, 1.0);
  }
  else {
    // 90 degree perspective; z only clips to [clip_near, far], the stored depth is radial.
    float n = ow_clip_near;
    float f = ow_far;
    float zc = (local_pos.z * (f + n) - 2.0 * f * n) / (f - n);
    gl_Position = vec4(local_pos.xy, zc, local_pos.z);
  }
}
