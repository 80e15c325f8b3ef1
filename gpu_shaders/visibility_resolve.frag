// A frame's visibility and flag per sample, copied where a compositor samples them (the
// samples' layout, row 0 at the bottom), with the exact pass's marks applied when
// ow_marks != 0 (core/alpha.hits_visibility): 0 past an opaque crossing, else
// exp(-optical depth); and with ow_media_on the light its media keep (passes/media.py).
// The viewport keeps one per light and never reads it back.
#include "lib/media.glsl"
void main()
{
  ivec2 pix = ivec2(gl_FragCoord.xy);
  vec2 result = texelFetch(ow_test, pix, 0).xy;
  if (ow_marks != 0) {
    uint word = imageLoad(ow_hits, pix).x;
    float depth = float(word & (OW_HIT_TWIN - 1u)) / OW_OPTICAL_SCALE;
    result.x *= ((word & OW_HIT_OPAQUE) != 0u) ? 0.0 : exp(-depth);
  }
  if (ow_media_on != 0) {
    // The media's optical depths (lib/media.glsl), and those around the light, per light point
    // the exact pass followed (one for a hard light): the mean of the light they keep.
    ivec2 size = textureSize(ow_positions, 0);
    vec3 around = ow_media_light * length(texelFetch(ow_positions, pix, 0).xyz);
    float kept = 0.0;
    for (int j = 0; j < ow_media_points; j++) {
      kept += ow_media_light_kept(ow_media_depth(pix, size, j) + around);
    }
    result.x *= kept / float(max(ow_media_points, 1));
  }
  ow_visibility = result;
}
