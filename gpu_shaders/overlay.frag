// Map thumbnail: OW_OVERLAY_DEPTH = depth in grey (1 = empty, drawn dark blue), OW_OVERLAY_COUNT = count
// on a log heat scale normalised by ow_max, OW_OVERLAY_LEGEND = the heat legend (u = value),
// OW_OVERLAY_TRANSMITTANCE = the light the media let through past a texel (passes/media.py's
// read_haze) in grey (1 = no medium, drawn dark blue).
vec3 ow_heat(float t)
{
  t = clamp(t, 0.0, 1.0);
  vec3 a = vec3(0.0, 0.0, 0.02);
  vec3 b = vec3(0.45, 0.05, 0.55);
  vec3 c = vec3(0.95, 0.45, 0.1);
  vec3 d = vec3(1.0, 1.0, 0.75);
  return (t < 0.33) ? mix(a, b, t / 0.33) : (t < 0.66) ? mix(b, c, (t - 0.33) / 0.33) : mix(c, d, (t - 0.66) / 0.34);
}

void main()
{
  if (ow_mode == OW_OVERLAY_LEGEND) {
    ow_color = vec4(ow_heat(v_uv.x), 1.0);
    return;
  }
  ivec2 size = textureSize(ow_image, 0);
  ivec2 texel = clamp(ivec2(v_uv * vec2(size)), ivec2(0), size - 1);
  float value = texelFetch(ow_image, texel, 0).r;
  if (ow_mode == OW_OVERLAY_DEPTH) {
    ow_color = (value >= 1.0) ? vec4(0.02, 0.03, 0.12, 1.0) : vec4(vec3(1.0 - 0.85 * value), 1.0);
  }
  else if (ow_mode == OW_OVERLAY_TRANSMITTANCE) {
    ow_color = (value >= 1.0) ? vec4(0.02, 0.03, 0.12, 1.0) : vec4(vec3(value), 1.0);
  }
  else {
    ow_color = vec4(ow_heat(log(1.0 + value) / log(1.0 + max(ow_max, 1.0))), 1.0);
  }
}
