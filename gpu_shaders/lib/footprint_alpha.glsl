// A see-through triangle of the footprint pass (shaders.alpha_of): the material's alpha
// where a ray from the light meets it (footprint_alpha.frag, footprint_exact.frag).
#include "lib/alpha.glsl"

// The alpha where a ray from the light along `d` meets the triangle: barycentrics from
// the edge planes through the light (v_edge_i = orientation * v_i x v_i+1), whose dot
// products with d are proportional to them, then the corners' UVs.
float ow_alpha_along(vec3 d)
{
  vec3 w = vec3(dot(d, v_edge1), dot(d, v_edge2), dot(d, v_edge0));
  w /= (w.x + w.y + w.z);
  return ow_alpha_at(w.x * v_uv01.xy + w.y * v_uv01.zw + w.z * v_uv2);
}
