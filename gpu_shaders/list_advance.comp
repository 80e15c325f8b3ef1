// Between two rounds of the exact pass (shaders.ADVANCE_PROGRAM): one invocation per
// texel of the heads strip moves its list's head past the ow_advance_steps entries the
// last round walked, so the next round's fragments start where those stopped. A texel
// whose list goes on widens its tile's box in ow_work (OW_WORK_BOX + 4 * tile: the
// complement of x0 and y0, and x1, y1, all by atomicMax, so a zeroed image is an empty
// box), the scissor of the next round.
void main()
{
  ivec2 size = imageSize(ow_counts);
  int index = int(gl_GlobalInvocationID.x);
  if (index >= size.x * size.y) {
    return;
  }
  ivec2 texel = ivec2(index % size.x, index / size.x);
  uint node = imageLoad(ow_counts, texel).x;
  if (node == 0u) {
    return;
  }
  int width = imageSize(ow_next).x;
  for (int step = 0; step < ow_advance_steps && node != 0u; step++) {
    int sample_index = int(node) - 1;
    node = imageLoad(ow_next, ivec2(sample_index % width, sample_index / width)).x;
  }
  imageStore(ow_counts, texel, uvec4(node));
  if (node != 0u) {
    int tile = texel.x / ow_tile_size;
    int x = texel.x - tile * ow_tile_size;
    int base = OW_WORK_BOX + 4 * tile;
    imageAtomicMax(ow_work, ivec2(base, 0), ~uint(x));
    imageAtomicMax(ow_work, ivec2(base + 1, 0), ~uint(texel.y));
    imageAtomicMax(ow_work, ivec2(base + 2, 0), uint(x + 1));
    imageAtomicMax(ow_work, ivec2(base + 3, 0), uint(texel.y + 1));
  }
}
