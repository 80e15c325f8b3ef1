// The veil of a shadow map: the see-through surfaces (0 < alpha < 1) a texel's
// ray crosses, which the map's one depth a texel cannot hold. Three R32UI words per atlas
// texel, each filled in any order by atomics:
// - ow_veil_optical: the crossings' optical depths -ln(1 - alpha), in units of
//   1 / OW_OPTICAL_SCALE, so their sum gives the product of (1 - alpha), the light that
//   passes all of them (as the exact pass sums them per sample);
// - ow_veil_near: the nearest crossing's normalised depth d, as the bits of 1 - d
//   (positive floats order as their bits, so the largest word is the nearest crossing;
//   0, the cleared word, is "no crossing");
// - ow_veil_far: the farthest crossing, its depth in the high OW_VEIL_DEPTH_BITS and its
//   1 - alpha in the low bits, so the largest word carries the farthest one's light.
// A receiver before the nearest crossing gets all the light, one beyond the farthest the
// whole product, one between them the product without the farthest: exact for up to two
// crossings a texel, the receiver's own surface among them (docs/materials.md).
#define OW_VEIL_DEPTH_BITS 20
#define OW_VEIL_LIGHT_BITS 12
const float OW_VEIL_DEPTH_STEPS = float((1 << OW_VEIL_DEPTH_BITS) - 1);
const float OW_VEIL_LIGHT_STEPS = float((1 << OW_VEIL_LIGHT_BITS) - 1);

void ow_veil_add(ivec2 texel, float alpha, float depth)
{
  float d = clamp(depth, 0.0, 1.0);
  imageAtomicAdd(ow_veil_optical, texel, uint(-log(1.0 - alpha) * OW_OPTICAL_SCALE + 0.5));
  imageAtomicMax(ow_veil_near, texel, floatBitsToUint(1.0 - d));
  uint far = (uint(d * OW_VEIL_DEPTH_STEPS + 0.5) << OW_VEIL_LIGHT_BITS)
             | uint((1.0 - alpha) * OW_VEIL_LIGHT_STEPS + 0.5);
  imageAtomicMax(ow_veil_far, texel, far);
}

// The light the veil of `texel` lets through to a receiver at normalised depth `depth`
// (already moved towards the light by the map's bias).
float ow_veil_light(ivec2 texel, float depth)
{
  uint near = imageLoad(ow_veil_near, texel).x;
  if (near == 0u || depth <= 1.0 - uintBitsToFloat(near)) {
    return 1.0;
  }
  float all_of_it = exp(-float(imageLoad(ow_veil_optical, texel).x) / OW_OPTICAL_SCALE);
  uint far = imageLoad(ow_veil_far, texel).x;
  if (depth > float(far >> OW_VEIL_LIGHT_BITS) / OW_VEIL_DEPTH_STEPS) {
    return all_of_it;
  }
  float far_light = float(far & ((1u << OW_VEIL_LIGHT_BITS) - 1u)) / OW_VEIL_LIGHT_STEPS;
  return min(all_of_it / max(far_light, 1.0 / OW_VEIL_LIGHT_STEPS), 1.0);
}
