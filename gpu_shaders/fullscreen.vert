// One triangle covering the target; ow_corner is (-1,-1), (3,-1), (-1,3).
void main()
{
  gl_Position = vec4(ow_corner, 0.0, 1.0);
}
