// Preview composite of one light's shadow test over the view.
// ow_draw_base 0: only darken shadowed surfaces (alpha-blended over the viewport);
// 1: also draw a grey Lambert base (headless preview image).
// ow_reproject 1: the visibility is an earlier view's (blender_draw.Reprojection).

// The earlier view's result where this pixel's point `p` lands in it, if that pixel saw
// the same surface (within ow_old_tolerance times its clip w); else lit and tested.
vec2 ow_reprojected(vec3 p)
{
  vec4 clip = ow_old_view_proj * vec4(p, 1.0);
  ivec2 size = textureSize(ow_old_position, 0);
  if (clip.w <= 0.0) {
    return vec2(1.0, 0.0);
  }
  vec2 ndc = clip.xy / clip.w;
  ivec2 pix = ivec2(floor((ndc * 0.5 + 0.5) * vec2(size)));
  if (any(lessThan(pix, ivec2(0))) || any(greaterThanEqual(pix, size))) {
    return vec2(1.0, 0.0);
  }
  vec4 seen = texelFetch(ow_old_position, pix, 0);
  if (seen.w < 0.5 || distance(seen.xyz, p) > ow_old_tolerance * clip.w) {
    return vec2(1.0, 0.0);  // a surface the earlier view did not see there
  }
  return texelFetch(ow_visibility, pix, 0).xy;
}

void main()
{
  ivec2 size = textureSize(ow_gb_position, 0);
  ivec2 pix = clamp(ivec2(gl_FragCoord.xy / ow_target_size * vec2(size)), ivec2(0), size - 1);
  vec4 p = texelFetch(ow_gb_position, pix, 0);
  vec3 n = texelFetch(ow_gb_normal, pix, 0).xyz;
  vec2 result = (ow_reproject != 0) ? ow_reprojected(p.xyz) : texelFetch(ow_visibility, pix, 0).xy;
  if (p.w < 0.5) {
    ow_color = (ow_draw_base != 0) ? vec4(0.05, 0.05, 0.06, 1.0) : vec4(0.0);
    return;
  }
  // A sun lights along one direction; a point or spot light from its position.
  vec3 to_light = (ow_sun != 0) ? ow_light_dir : ow_light_pos - p.xyz;
  float diffuse = max(dot(n, normalize(to_light)), 0.0);
  if (result.y == 2.0) {
    diffuse = 0.0;  // outside the emission (behind a hemispherical light, outside a spot cone)
  }
  bool shadowed = result.y == 0.0 && result.x < 0.5 && diffuse > 0.0;
  float darken = shadowed ? ow_strength : 0.0;
  if (ow_draw_base != 0) {
    float lit = 0.15 + 0.75 * diffuse * (1.0 - darken);
    ow_color = vec4(vec3(lit), 1.0);
  }
  else {
    ow_color = vec4(0.0, 0.0, 0.0, darken);
  }
}
