// A see-through material's alpha at a surface point: the GLSL of
// addon/core/alpha.py's AlphaMap.sample, its numpy oracle (tests/gl/test_alpha_glsl.py).
// The image is one R32F channel, row 0 at v = 0; ow_alpha_mode is the interpolation
// (OW_INTERPOLATION_*) plus OW_ALPHA_INTERPOLATIONS times the extension (OW_EXTENSION_*). The
// filtering is done here with texelFetch, not by a sampler, so both backends and every
// driver give Cycles' lookup exactly. The transfer is a 1-row R32F table over [0, 1].

// a mod n for any sign of a (GLSL's % is undefined for negative operands).
int ow_alpha_mod(int a, int n)
{
  return a - n * int(floor(float(a) / float(n)));
}

int ow_alpha_wrap(int i, int n, int extension)
{
  if (extension == OW_EXTENSION_REPEAT) {
    return ow_alpha_mod(i, n);
  }
  if (extension == OW_EXTENSION_MIRROR) {
    int m = ow_alpha_mod(i, 2 * n);
    return (m < n) ? m : 2 * n - 1 - m;
  }
  return clamp(i, 0, n - 1);
}

float ow_alpha_texel(ivec2 at, ivec2 size, int extension)
{
  if (extension == OW_EXTENSION_CLIP && (at.x < 0 || at.y < 0 || at.x >= size.x || at.y >= size.y)) {
    return 0.0;  // clip: nothing outside the image
  }
  ivec2 idx = ivec2(ow_alpha_wrap(at.x, size.x, extension), ow_alpha_wrap(at.y, size.y, extension));
  return texelFetch(ow_alpha_image, idx, 0).x;
}

float ow_alpha_at(vec2 uv)
{
  ivec2 size = textureSize(ow_alpha_image, 0);
  int extension = ow_alpha_mode / OW_ALPHA_INTERPOLATIONS;
  int interpolation = ow_alpha_mode % OW_ALPHA_INTERPOLATIONS;
  // Far outside the square the int conversion would overflow; the wrap is periodic anyway
  // only to within float32's resolution there.
  vec2 x = clamp(uv, vec2(-1e6), vec2(1e6)) * vec2(size);
  float value;
  if (interpolation == OW_INTERPOLATION_CLOSEST) {
    value = ow_alpha_texel(ivec2(floor(x)), size, extension);
  } else {
    x -= 0.5;
    vec2 base = floor(x);
    vec2 f = x - base;
    ivec2 i = ivec2(base);
    float a = ow_alpha_texel(i, size, extension);
    float b = ow_alpha_texel(i + ivec2(1, 0), size, extension);
    float c = ow_alpha_texel(i + ivec2(0, 1), size, extension);
    float d = ow_alpha_texel(i + ivec2(1, 1), size, extension);
    value = mix(mix(a, b, f.x), mix(c, d, f.x), f.y);
  }
  int n = textureSize(ow_alpha_transfer, 0).x;
  float t = clamp(value, 0.0, 1.0) * float(n - 1);
  int k = min(int(floor(t)), n - 2);
  float lo = texelFetch(ow_alpha_transfer, ivec2(k, 0), 0).x;
  float hi = texelFetch(ow_alpha_transfer, ivec2(k + 1, 0), 0).x;
  return mix(lo, hi, t - float(k));
}
