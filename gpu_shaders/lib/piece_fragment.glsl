// This fragment's piece (OW_PIECES), from the flat varyings lib/footprint_piece.glsl
// writes: its axis and radii (v_piece_a, v_piece_b), its curve's run of pieces, whether it
// is a ribbon's (v_piece_curve), the planes that end its curve (v_piece_cut_a, _b), and a
// ribbon's curve directions at its ends (v_piece_ta, v_piece_tb). The maps
// (lib/footprint_ray.glsl) and the exact pass (lib/exact_piece.glsl) ask it the same
// question: does a segment meet it as Cycles' ray would.
#include "lib/blockers.glsl"

// Whether this fragment's piece is a ribbon's (resident._piece_uvs).
bool ow_piece_ribbon()
{
  return v_piece_curve.z > 0.5;
}

// Whether the segment p + s d, s past `lo`, meets this fragment's piece (ow_segment_piece).
bool ow_piece_blocks(vec3 p, vec3 d, float lo)
{
  return ow_segment_piece(p, d, v_piece_a.xyz, v_piece_b.xyz, v_piece_a.w, v_piece_b.w, lo, ow_piece_ribbon(),
                          v_piece_cut_a, v_piece_cut_b, v_piece_ta, v_piece_tb);
}
