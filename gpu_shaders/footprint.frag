// Footprint depth pass, fragment stage: exact coverage and depth at the texel centre
// (lib/footprint_ray.glsl), a triangle's or a piece's (OW_PIECES). Its see-through variant
// is footprint_alpha.frag, the exact pass footprint_exact.frag.
#include "lib/footprint_ray.glsl"

void main()
{
#ifdef OW_PIECES
  float piece = ow_piece_depth();
  gl_FragDepth = piece;
  ow_depth = piece;
  return;
#endif
#ifndef OW_FIXED_KIND
  if (ow_projective != 0) {
    float z01 = ow_projective_z01();
    gl_FragDepth = z01;
    ow_depth = z01;
    return;
  }
#endif
  float depth = ow_footprint_depth(ow_texel_ray());
  gl_FragDepth = depth;
  ow_depth = depth;
}
