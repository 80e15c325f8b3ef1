// The exact pass of a sized light by segments (passes/segments.py): one invocation a view
// sample walks the segment from it to each of the light's points (lib/exact_soft.glsl's
// ow_light_segment) through the segments' tree over the light-centred triangles
// (lib/ray_tree.glsl), and sets point k's bit in the sample's words where a triangle
// crosses it, as the lists' walk does (lib/exact_soft_mark.glsl). A turn spends at most
// ow_budget units of work a sample; the sample's place is kept in ow_walk (at (x, y) the
// next point, at (x, y + H) the node to go on from, 0 for a new walk) and ow_work's first
// word counts the samples a turn left unfinished.
#include "lib/exact_soft.glsl"
#include "lib/ray_tree.glsl"

void main()
{
  ivec2 size = textureSize(ow_positions, 0);
  int index = int(gl_GlobalInvocationID.x);
  if (index >= size.x * size.y) {
    return;
  }
  ivec2 at = ivec2(index % size.x, index / size.x);
  int point = int(imageLoad(ow_walk, at).x);
  vec4 sample_at = texelFetch(ow_positions, at, 0);
  if (point >= ow_exact_points || sample_at.w <= 0.0) {
    return;
  }
  vec3 p = sample_at.xyz;  // light-centred
  ivec2 node_at = at + ivec2(0, size.y);
  int node = max(int(imageLoad(ow_walk, node_at).x), 1);
  OwLightView view = ow_light_view(p);
  bool sun = int(ow_exact_light.x) == OW_LIGHT_SUN_DISK;
  // A point the shadow test gives no weight (behind the receiver, outside a spot's cone)
  // needs no walk, unless no point has weight: then the test counts the open points. The
  // test weighs with the normal turned towards the light's centre in most branches, as
  // given in one: a receiver whose normal faces away from the centre walks every point.
  vec3 n = texelFetch(ow_normals, at, 0).xyz;
  bool weighed = false;
  for (int k = 0; k < ow_exact_points && !weighed && dot(n, sun ? ow_exact_frame[2] : -p) >= 0.0; k++) {
    weighed = ow_light_weight(ow_light_segment(p, view, k), n) > 0.0;
  }
  // A sun's segment is a direction: it goes on past the whole tree, and must cross more
  // than ow_exact_eps |p| from p, as the lists' walk asks.
  float eps = sun ? ow_exact_eps * length(p) / ow_sun_reach : ow_exact_eps;
  int budget = ow_budget;
  uint word = 0u;
  int word_index = point / 32;
  while (point < ow_exact_points) {
    vec3 d = ow_light_segment(p, view, point);
    int verdict = OW_TREE_CLEAR;
    if (!weighed || ow_light_weight(d, n) > 0.0) {
      verdict = ow_tree_walk(p, sun ? d * ow_sun_reach : d, eps, node, budget);
      if (verdict == OW_TREE_CUT) {
        break;
      }
    }
    word |= (verdict == OW_TREE_BLOCKED) ? (1u << uint(point - 32 * word_index)) : 0u;
    point += 1;
    node = 1;
    if (point / 32 != word_index || point >= ow_exact_points) {
      if (word != 0u) {
        ivec2 word_at = at + ivec2(0, word_index * size.y);
        imageStore(ow_hits, word_at, imageLoad(ow_hits, word_at) | uvec4(word));
      }
      word = 0u;
      word_index = point / 32;
    }
  }
  if (word != 0u) {  // a word cut short: its bits so far
    ivec2 word_at = at + ivec2(0, word_index * size.y);
    imageStore(ow_hits, word_at, imageLoad(ow_hits, word_at) | uvec4(word));
  }
  imageStore(ow_walk, at, uvec4(uint(point)));
  imageStore(ow_walk, node_at, uvec4(uint(node)));
  if (point < ow_exact_points) {
    imageAtomicAdd(ow_work, ivec2(0, 0), 1u);
  }
}
