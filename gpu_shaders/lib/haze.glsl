// The shadow test's read of a map's haze (shaders.haze_of; lib/media.glsl describes it and
// footprint_medium.frag writes it).
#include "lib/media.glsl"

// The optical depth per channel of the texel's haze at `u` along the light's ray (a
// distance from the light, or a sun's place on its axis).
vec3 ow_haze_depth(ivec2 texel, float u)
{
  vec3 around = ow_media_light * u;  // the media the light lies in, in optical depth a metre
  uint near_bits = imageLoad(ow_haze_near, texel).x;
  if (near_bits == 0u) {
    return around;
  }
  vec3 whole = vec3(float(int(imageLoad(ow_haze_r, texel).x)), float(int(imageLoad(ow_haze_g, texel).x)),
                    float(int(imageLoad(ow_haze_b, texel).x))) / ow_media_scale;
  float last = uintBitsToFloat(imageLoad(ow_haze_far, texel).x);
  float first = any(greaterThan(ow_media_light, vec3(0.0))) ? 0.0 : uintBitsToFloat(~near_bits);
  if (u >= last) {
    return whole;
  }
  if (u <= first) {
    return around;
  }
  return mix(ow_media_light * first, whole, (u - first) / max(last - first, 1e-30));
}
