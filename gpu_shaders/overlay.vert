// A screen-space rectangle (pixels) for one overlay thumbnail.
void main()
{
  v_uv = ow_corner;
  vec2 pixel = ow_rect.xy + ow_corner * ow_rect.zw;
  gl_Position = vec4(pixel / ow_target_size * 2.0 - 1.0, 0.0, 1.0);
}
