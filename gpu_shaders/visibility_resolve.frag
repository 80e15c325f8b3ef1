// A frame's visibility and flag per sample, copied where a compositor samples them (the
// samples' layout, row 0 at the bottom), with the exact pass's marks applied when
// ow_marks != 0 (core/alpha.hits_visibility): 0 past an opaque crossing, else
// exp(-optical depth). The viewport keeps one per light and never reads it back.
void main()
{
  ivec2 pix = ivec2(gl_FragCoord.xy);
  vec2 result = texelFetch(ow_test, pix, 0).xy;
  if (ow_marks != 0) {
    uint word = imageLoad(ow_hits, pix).x;
    float depth = float(word & (OW_HIT_OPAQUE - 1u)) / OW_OPTICAL_SCALE;
    result.x *= ((word & OW_HIT_OPAQUE) != 0u) ? 0.0 : exp(-depth);
  }
  ow_visibility = result;
}
