// Homogeneous media (core/media.py): a medium's closed triangles are no surface;
// the light a receiver gets through them is exp(-sigma L) per channel, L the length of its
// segment to the light inside the medium. Each crossing of the segment adds its signed
// distance: entering the medium (against the triangle's outward normal, walking from the
// light) or leaving it. Sums are 32-bit integers in the frame's units (a medium part's sigma
// uniform holds sigma times core/media.fixed_scale's units per optical depth), so atomics add
// them in any order and two's complement wraps back.

// Whether a direction on the inner side of an edge plane: `side` its signed distance,
// `edge` the plane's normal. On the plane (side 0), as if moved by (e, e^2, e^3) for a
// vanishing e: the side of the normal's first non-zero component. Two triangles sharing
// the edge have exactly opposite normals (lib/footprint.glsl), so a crossing on the edge
// counts once, not twice or never (core/media.py's inside_edge, its oracle).
bool ow_medium_inside(float side, vec3 edge)
{
  if (side != 0.0) {
    return side > 0.0;
  }
  float first = (edge.x != 0.0) ? edge.x : ((edge.y != 0.0) ? edge.y : edge.z);
  return first > 0.0;
}

// Fixed-point units of a signed length times one channel's sigma (rounded to nearest).
uint ow_medium_units(float length_signed, float sigma)
{
  return uint(int(floor(length_signed * sigma + 0.5)));
}

// Where channel c of light point j of the sample at `pix` lies in the media words: blocks of the
// samples' `size`, `across` points a row of blocks and three rows of blocks a row of points
// (passes/media.py's SampleMedia); a hard light's one point: three blocks down.
ivec2 ow_media_word(ivec2 pix, ivec2 size, int across, int j, int c)
{
  return pix + ivec2((j % across) * size.x, (3 * (j / across) + c) * size.y);
}

#ifdef OW_MEDIA_WORDS
// Programs that hold the exact pass's words (ow_media, ow_media_across, ow_media_scale,
// ow_media_index: shaders.MEDIA_WORDS_DEFINE).

// The optical depths (RGB) of light point j of the sample at `pix` (of the samples' `size`).
vec3 ow_media_depth(ivec2 pix, ivec2 size, int j)
{
  return vec3(float(int(imageLoad(ow_media, ow_media_word(pix, size, ow_media_across, j, 0)).x)),
              float(int(imageLoad(ow_media, ow_media_word(pix, size, ow_media_across, j, 1)).x)),
              float(int(imageLoad(ow_media, ow_media_word(pix, size, ow_media_across, j, 2)).x))) / ow_media_scale;
}

// The pattern index (in lib/exact_soft.glsl's table of light points) of the j-th light point a
// sample follows through the media: a share spread over the light as the whole pattern is
// (passes/media.py's share_points), four indices a vec4.
int ow_media_point(int j)
{
  return int(ow_media_index[j >> 2][j & 3]);
}
#endif

#ifdef OW_MEDIUM
#ifdef OW_EXACT
// The exact pass: the sample at `at` (of the samples' `size`) gets a crossing's signed
// optical depth per channel, for its light point j (0 for a hard light;
// lib/exact_soft_medium.glsl), where ow_media_word puts it. `s`: the crossing's distance
// from the sample, positive when the walk from the light enters the medium there.
void ow_media_mark_point(ivec2 at, ivec2 size, int j, float s)
{
  imageAtomicAdd(ow_media, ow_media_word(at, size, ow_media_across, j, 0), ow_medium_units(s, ow_medium_sigma.r));
  imageAtomicAdd(ow_media, ow_media_word(at, size, ow_media_across, j, 1), ow_medium_units(s, ow_medium_sigma.g));
  imageAtomicAdd(ow_media, ow_media_word(at, size, ow_media_across, j, 2), ow_medium_units(s, ow_medium_sigma.b));
}

void ow_media_mark(ivec2 at, ivec2 size, float s)
{
  ow_media_mark_point(at, size, 0, s);
}

#endif
#ifdef OW_HAZE
// A map's haze: the media a texel's ray from the light crosses, in five R32UI words a texel
// (shaders.HAZE_IMAGES): per channel, A = the sum of sigma u over the crossings, u their
// distance from the light, minus where the ray enters and plus where it leaves; the nearest
// crossing's u (its bits inverted, so the largest word is the nearest; 0: none) and the
// farthest's. Past the last crossing a ray is outside every medium, so a receiver there gets
// the optical depth A; one before the first, sigma_light times its distance (the media
// around the light); between the two, the line between those (exact for one convex medium,
// a box or a sphere of fog, with the receiver inside it or not).
void ow_haze_add(ivec2 texel, float u, bool entering)
{
  float signed_u = entering ? -u : u;
  imageAtomicAdd(ow_haze_r, texel, ow_medium_units(signed_u, ow_medium_sigma.r));
  imageAtomicAdd(ow_haze_g, texel, ow_medium_units(signed_u, ow_medium_sigma.g));
  imageAtomicAdd(ow_haze_b, texel, ow_medium_units(signed_u, ow_medium_sigma.b));
  imageAtomicMax(ow_haze_near, texel, ~floatBitsToUint(u));
  imageAtomicMax(ow_haze_far, texel, floatBitsToUint(u));
}
#endif
#endif

// The reference's visibility of RGB optical depths: the mean of the light each channel keeps.
float ow_media_light_kept(vec3 depth)
{
  vec3 kept = exp(-max(depth, vec3(0.0)));
  return (kept.r + kept.g + kept.b) / 3.0;
}
