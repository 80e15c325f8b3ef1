// Projective (spot and sun) maps: one 4x4 matrix from light-centred world space to the
// map's clip space, uv = ndc.xy * 0.5 + 0.5, z01 = ndc.z * 0.5 + 0.5. Mirrors
// addon/core/perspective.py (project, texel_footprint).

// uv and z01 of a light-centred point; `w` <= 0 means the point is behind the map.
vec3 ow_projective_uvz(mat4 m, vec3 p, out float w)
{
  vec4 c = m * vec4(p, 1.0);
  w = c.w;
  return (c.xyz / c.w) * 0.5 + 0.5;
}

// World size of one texel at p: (1 / res) / the smallest singular value of the 2x3
// Jacobian d(uv)/dp. Its null direction is the light ray, so this is the widest a
// texel's footprint gets across the ray.
float ow_projective_footprint(mat4 m, vec3 p, float resolution)
{
  vec4 c = m * vec4(p, 1.0);
  // Rows of M (GLSL indexes m[column][row]).
  vec3 row_x = vec3(m[0][0], m[1][0], m[2][0]);
  vec3 row_y = vec3(m[0][1], m[1][1], m[2][1]);
  vec3 row_w = vec3(m[0][3], m[1][3], m[2][3]);
  vec3 gx = 0.5 * (row_x * c.w - c.x * row_w) / (c.w * c.w);
  vec3 gy = 0.5 * (row_y * c.w - c.y * row_w) / (c.w * c.w);
  // Eigenvalues of the 2x2 Gram matrix; the small one as det / large (no cancellation).
  float a = dot(gx, gx);
  float b = dot(gx, gy);
  float d = dot(gy, gy);
  float large = 0.5 * (a + d) + sqrt(max(0.25 * (a - d) * (a - d) + b * b, 0.0));
  float small = max(a * d - b * b, 0.0) / max(large, 1e-30);
  return 1.0 / (resolution * sqrt(max(small, 1e-30)));
}
