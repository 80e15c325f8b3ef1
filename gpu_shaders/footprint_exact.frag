// The exact pass (the irregular z-buffer, shaders.exact_variant), fragment stage: instead
// of a depth, each fragment walks its texel's list of view samples and marks those whose
// segment to the light the triangle crosses (lib/exact_walk.glsl); the counting, the
// see-through (OW_ALPHA), the sized light's (OW_EXACT_SOFT) and the pieces' (OW_PIECES)
// variants of it too.
#ifdef OW_ALPHA
#include "lib/footprint_alpha.glsl"
#endif
#ifdef OW_EXACT_SOFT
#include "lib/exact_soft_mark.glsl"
#endif
#ifdef OW_PIECES
#include "lib/exact_piece.glsl"
#endif
#ifdef OW_MEDIUM
#include "lib/media.glsl"
#ifdef OW_EXACT_SOFT
#include "lib/exact_soft_medium.glsl"
#endif
#endif
#include "lib/exact_walk.glsl"

void main()
{
  ow_exact_walk();
  discard;
}
