// An object's vertices from its vertex texture (resident.py), light-centred: the
// footprint pass's vertex stage pulls its triangle's or piece's, and the exact pass's
// fragments a piece's curve (lib/exact_piece.glsl).

// Vertex `index`, light-centred: its double-single parts (texels 2i and 2i + 1) minus the
// light's in the object's frame, hi from hi and lo from lo, before the object's matrix
// (resident.py). `precise` keeps the compiler from reassociating the sums.
vec3 ow_pull(int index)
{
  int texel = 2 * index;
  vec3 hi = texelFetch(ow_vertices, ivec2(texel % OW_VERTEX_WIDTH, texel / OW_VERTEX_WIDTH), 0).xyz;
  texel += 1;
  vec3 lo = texelFetch(ow_vertices, ivec2(texel % OW_VERTEX_WIDTH, texel / OW_VERTEX_WIDTH), 0).xyz;
  precise vec3 local = (hi - ow_light_hi) + (lo - ow_light_lo);
  return ow_object_linear * local;
}

// The w of vertex `index`'s hi texel (its lo texel's with `lo`): a see-through part's UV,
// a piece's radii and its curve's run of pieces (resident._piece_uvs).
float ow_pull_w(int index, bool lo)
{
  int texel = 2 * index + (lo ? 1 : 0);
  return texelFetch(ow_vertices, ivec2(texel % OW_VERTEX_WIDTH, texel / OW_VERTEX_WIDTH), 0).w;
}

// A length in the object's frame, in world units: times its largest axis scale (a bound
// under a non-uniform scale).
float ow_object_length(float r)
{
  return r * max(length(ow_object_linear[0]), max(length(ow_object_linear[1]), length(ow_object_linear[2])));
}
