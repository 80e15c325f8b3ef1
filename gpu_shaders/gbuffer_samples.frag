// The shadow test's light-centred sample positions from a G-buffer, on the GPU: the
// viewport's G-buffer is never read back and uploaded again. The light comes as a
// float32 pair (hi + lo), so the difference of a position and a nearby light is exact
// up to the G-buffer's own float32 rounding. w = 1 where the pixel hit geometry.
void main()
{
  vec4 world = texelFetch(ow_gb_position, ivec2(gl_FragCoord.xy), 0);
  ow_sample = (world.w > 0.5) ? vec4((world.xyz - ow_light_hi) - ow_light_lo, 1.0) : vec4(0.0);
}
