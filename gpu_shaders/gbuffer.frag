// Geometric normals are turned towards the camera, as Cycles' True Normal is.
// ow_camera_pos is homogeneous: the eye (w = 1), or for an orthographic view the
// direction towards the camera (w = 0), the same for every pixel.
#ifdef OW_ALPHA
#include "lib/alpha.glsl"
#endif

void main()
{
#ifdef OW_ALPHA
  if (ow_alpha_at(v_uv) < 0.5) {
    discard;  // the camera sees a see-through surface where alpha >= 1/2, as the reference does
  }
#endif
  vec3 n = normalize(v_normal);
  if (dot(n, ow_camera_pos.xyz - ow_camera_pos.w * v_world) < 0.0) {
    n = -n;
  }
  ow_gb_position = vec4(v_world, 1.0);
  ow_gb_normal = vec4(n, 1.0);
}
