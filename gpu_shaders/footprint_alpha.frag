// Footprint depth pass of a see-through part (shaders.alpha_of): footprint.frag's coverage
// and depth (lib/footprint_ray.glsl), then the material's alpha where the texel's ray meets
// the triangle decides what the texel keeps.
#include "lib/footprint_ray.glsl"
#include "lib/footprint_alpha.glsl"
#include "lib/veil.glsl"

// An opaque point stores its depth; a partly transparent one goes to the texel's veil
// (lib/veil.glsl) and a clear one nowhere. Both of those leave the depth untouched. The
// fragment writes its depth, so it runs whatever the depth test says, and every crossing
// reaches the veil.
void ow_see_through(float alpha, float depth)
{
  if (alpha < OW_OPAQUE_ALPHA) {
    if (alpha > OW_CLEAR_ALPHA) {
      ow_veil_add(ivec2(gl_FragCoord.xy), alpha, depth);
    }
    discard;
  }
}

void main()
{
#ifndef OW_FIXED_KIND
  if (ow_projective != 0) {
    float z01 = ow_projective_z01();
    ow_see_through(ow_alpha_at(v_uv), z01);
    gl_FragDepth = z01;
    ow_depth = z01;
    return;
  }
#endif
  vec3 dir = ow_texel_ray();
  float depth = ow_footprint_depth(dir);
  ow_see_through(ow_alpha_along(dir), depth);
  gl_FragDepth = depth;
  ow_depth = depth;
}
