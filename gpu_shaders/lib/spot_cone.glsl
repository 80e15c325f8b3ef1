// A spot's cone as Cycles weighs each sample of a sized spot (render/soft.py's spot_cone):
// the light leaving a point of the sphere along `emitted` (towards the receiver, any
// length) is smoothstep((cos a - cos half) * smooth), a the angle from the spot's `axis`;
// with no blend (smooth 0) a step at the cone's edge. spot.x OW_NO_SPOT (below OW_NO_SPOT_BELOW): not a spot.
float ow_spot_cone_weight(vec3 emitted, vec3 axis, vec2 spot)
{
  if (spot.x < OW_NO_SPOT_BELOW) {
    return 1.0;
  }
  float c = dot(emitted, axis) / max(length(emitted), 1e-30);
  if (!(spot.y > 0.0)) {
    return (c > spot.x) ? 1.0 : 0.0;
  }
  float x = clamp((c - spot.x) * spot.y, 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}
