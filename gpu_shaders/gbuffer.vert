// G-buffer: world position and geometric normal per pixel, from the view's matrices.
void main()
{
  v_world = ow_world;
  v_normal = ow_face_normal;
  gl_Position = ow_view_proj * vec4(ow_world, 1.0);
}
