// Footprint pass of a medium's part in the maps (shaders.medium_of, issue 43): where the
// texel's ray from the light meets the triangle (lib/footprint_ray.glsl's ray, with
// lib/media.glsl's rule for a ray on an edge), the crossing goes to the texel's haze. No
// depth is stored: a medium is no surface.
#include "lib/footprint_ray.glsl"
#include "lib/media.glsl"

void main()
{
  vec3 dir = ow_texel_ray();
  if (!(ow_medium_inside(dot(dir, v_edge0), v_edge0) && ow_medium_inside(dot(dir, v_edge1), v_edge1)
        && ow_medium_inside(dot(dir, v_edge2), v_edge2))) {
    discard;
  }
  float along = dot(v_plane.xyz, dir);
  float t = v_plane.w / along;
  if (!(t > 0.0)) {
    discard;  // behind the light, or grazing in float32 rounding
  }
  ow_haze_add(ivec2(gl_FragCoord.xy), t * length(dir), along < 0.0);
  discard;
}
