// The exact pass's test of a piece (OW_PIECES, lib/blockers.glsl) for one view sample p
// (light-centred), for lib/exact_walk.glsl: whether the segment from p to the light meets
// the piece more than ow_exact_eps of its length from p (the receiver's own surface left
// out, as for triangles), unless p lies on the piece's curve (a point's own sphere, a
// strand's pieces: Cycles never shadows a point with the primitive it lies on, and a
// curve is one primitive; core/blockers.Pieces), as p's normal tells. That is asked only
// of a segment the piece blocks, so its walk over the curve's pieces is rare. A sun's
// segment runs from p against its direction, past the piece; it must meet it more than
// ow_exact_eps |p| from p. A sized light (OW_EXACT_SOFT) tests each of its points'
// segments (lib/exact_soft.glsl).
#include "lib/piece_fragment.glsl"
#include "lib/vertex_pull.glsl"

// Whether p, of normal n, lies on this fragment's piece's curve: on one of its run of
// pieces (v_piece_curve: first, count; ow_on_piece), cut by the curve's end planes.
bool ow_on_own_curve(vec3 p, vec3 n)
{
  int first = int(v_piece_curve.x + 0.5);
  int count = int(v_piece_curve.y + 0.5);
  bool ribbon = ow_piece_ribbon();
  for (int j = first; j < first + count; j++) {
    float ra = ow_object_length(ow_pull_w(3 * j, false));
    float rb = ow_object_length(ow_pull_w(3 * j + 1, false));
    if (ow_on_piece(p, n, ow_pull(3 * j), ow_pull(3 * j + 1), ra, rb, ribbon, v_piece_cut_a, v_piece_cut_b)) {
      return true;
    }
  }
  return false;
}

// Sample `at`'s unit normal (its true normal, facing the camera).
vec3 ow_sample_normal(ivec2 at)
{
  return normalize(texelFetch(ow_normals, at, 0).xyz);
}

// A segment towards a sun, as the parameter's scale: long enough to pass every point of
// the piece (|a - p| <= |a| + |p|).
float ow_piece_sun_reach(vec3 p)
{
  return length(p) + max(length(v_piece_a.xyz), length(v_piece_b.xyz)) + max(v_piece_a.w, v_piece_b.w) + 1.0;
}

#ifdef OW_EXACT_SOFT
// The light points whose segments from p meet the piece set their bits in p's words.
void ow_piece_soft_mark(vec3 p, ivec2 at, int rows)
{
  OwLightView view = ow_light_view(p);
  bool sun = int(ow_exact_light.x) == OW_LIGHT_SUN_DISK;
  float reach = sun ? ow_piece_sun_reach(p) : 1.0;
  float lo = sun ? ow_exact_eps * length(p) / reach : ow_exact_eps;
  int own = -1;  // whether p lies on the piece's curve: not yet asked
  for (int w = 0; w * 32 < ow_exact_points; w++) {
    int count = min(32, ow_exact_points - 32 * w);
    ivec2 word_at = at + ivec2(0, w * rows);
    uint blocked = imageLoad(ow_hits, word_at).x;  // a stale read only tests more
    uint word = 0u;
    for (int j = 0; j < count; j++) {
      if (((blocked >> uint(j)) & 1u) == 0u && ow_piece_blocks(p, ow_light_segment(p, view, 32 * w + j) * reach, lo)) {
        if (own < 0) {
          own = ow_on_own_curve(p, ow_sample_normal(at)) ? 1 : 0;  // asked once, at the first blocked point
        }
        if (own > 0) {
          return;
        }
        word |= 1u << uint(j);
      }
    }
    if (word != 0u) {
      imageAtomicOr(ow_hits, word_at, word);
    }
  }
}
#endif

// Sample `at` (p) marked opaque where the piece blocks its light.
void ow_piece_exact_entry(ivec2 at, vec3 p)
{
#ifdef OW_EXACT_SOFT
  ow_piece_soft_mark(p, at, textureSize(ow_positions, 0).y);
#else
#ifndef OW_FIXED_KIND
  if (ow_projective != 0 && ow_sun != 0) {
    float reach = ow_piece_sun_reach(p);
    if (ow_piece_blocks(p, -ow_light_axis * reach, ow_exact_eps * length(p) / reach)
        && !ow_on_own_curve(p, ow_sample_normal(at))) {
      imageAtomicOr(ow_hits, at, OW_HIT_OPAQUE);
    }
    return;
  }
#endif
  if (dot(p, p) > 0.0 && ow_piece_blocks(p, -p, ow_exact_eps) && !ow_on_own_curve(p, ow_sample_normal(at))) {
    imageAtomicOr(ow_hits, at, OW_HIT_OPAQUE);
  }
#endif
}
