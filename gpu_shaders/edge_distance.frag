// Edge-distance map of the dual sphere-unfolding paper's antialiasing, in two
// separable passes over the shadow-map atlas (Stockli Contreras et al., section 2):
//   pass 0: X(i, j) = min |i - k| over |i - k| <= R with a depth step at (k, j),
//   pass 1: Z(i, j) = min over |h - j| <= R of |j - h| + X(i, h),
// the Manhattan distance to the nearest step within R texels (R + 1 = none). A step
// counts only towards a NEARER neighbour (P_k <= P_ij - eps): the receiver side of
// an occluder's silhouette, not the occluder's own rim (the paper uses |P_ij - P_kj|).
// Searches stay inside the texel's own tile.

bool ow_edge_in_tile(ivec2 texel, ivec2 tile_origin, int tile_size)
{
  ivec2 local = texel - tile_origin;
  return all(greaterThanEqual(local, ivec2(0))) && all(lessThan(local, ivec2(tile_size)));
}

void main()
{
  ivec2 texel = ivec2(gl_FragCoord.xy);
  int size = int(ow_edge_tile_size);
  ivec2 tile_origin = (texel / size) * size;
  int radius = ow_edge_radius;
  float best = float(radius + 1);
  if (ow_edge_pass == OW_EDGE_ALONG_X) {
    float centre = texelFetch(ow_atlas, texel, 0).r;
    for (int d = 1; d <= radius; ++d) {
      for (int s = -1; s <= 1; s += 2) {
        ivec2 k = texel + ivec2(s * d, 0);
        if (ow_edge_in_tile(k, tile_origin, size)
            && texelFetch(ow_atlas, k, 0).r <= centre - ow_edge_eps) {
          best = min(best, float(d));
        }
      }
    }
  }
  else {
    for (int h = -radius; h <= radius; ++h) {
      ivec2 k = texel + ivec2(0, h);
      if (ow_edge_in_tile(k, tile_origin, size)) {
        best = min(best, float(abs(h)) + texelFetch(ow_edge_x, k, 0).r);
      }
    }
  }
  ow_edge = min(best, float(radius + 1));
}
