// G-buffer from resident objects: each triangle's vertices are pulled from the object's
// vertex texture (as footprint.vert pulls them) and placed by the object's matrix, so the
// scene is not sent again for every view. The footprint pass's corner buffer drives it,
// OW_FOOTPRINT_VERTICES vertices a triangle: corners 0-2 are the triangle, the others
// repeat corner 0, a triangle of no area that draws nothing.
vec3 ow_world_vertex(int index)
{
  int texel = 2 * index;
  vec3 hi = texelFetch(ow_vertices, ivec2(texel % OW_VERTEX_WIDTH, texel / OW_VERTEX_WIDTH), 0).xyz;
  texel += 1;
  vec3 lo = texelFetch(ow_vertices, ivec2(texel % OW_VERTEX_WIDTH, texel / OW_VERTEX_WIDTH), 0).xyz;
  return ow_object_linear * (hi + lo) + ow_object_origin;
}

#ifdef OW_ALPHA
// Vertex `index`'s UV (the w of its two texels, resident.vertex_texels).
vec2 ow_vertex_uv(int index)
{
  int texel = 2 * index;
  float u = texelFetch(ow_vertices, ivec2(texel % OW_VERTEX_WIDTH, texel / OW_VERTEX_WIDTH), 0).w;
  texel += 1;
  return vec2(u, texelFetch(ow_vertices, ivec2(texel % OW_VERTEX_WIDTH, texel / OW_VERTEX_WIDTH), 0).w);
}
#endif

void main()
{
  int corner = clamp(int(ow_corner + 0.5), 0, OW_FOOTPRINT_VERTICES - 1);
  int base = 3 * (gl_VertexID / OW_FOOTPRINT_VERTICES);
  vec3 a = ow_world_vertex(base);
  vec3 b = ow_world_vertex(base + 1);
  vec3 c = ow_world_vertex(base + 2);
  vec3 p = (corner == 1) ? b : ((corner == 2) ? c : a);
  v_world = p;
#ifdef OW_ALPHA
  int own = (corner == 1) ? 1 : ((corner == 2) ? 2 : 0);
  v_uv = ow_vertex_uv(base + own);  // perspective-correct across the triangle
#endif
  v_normal = cross(b - a, c - a);
  gl_Position = ow_view_proj * vec4(p, 1.0);
}
