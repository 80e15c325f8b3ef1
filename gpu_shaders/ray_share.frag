// An area light's share at each view sample by shadow segments through the segments' tree
// (lib/ray_tree.glsl), one segment per light point, each point weighed as the exact pass
// weighs it (both cosines over the squared distance). Everything is in the light's frame
// (the light at the origin, emitting along -Z). A turn spends at most ow_budget units of
// work a sample (shaders.RAY_TREE_BUDGET) and leaves its state for the next turn: ow_state
// holds the next point and the node to go on from, ow_sums the weights seen so far.
#include "lib/ray_tree.glsl"

void main()
{
  ivec2 at = ivec2(gl_FragCoord.xy);
  vec4 sample_at = texelFetch(ow_samples, at, 0);  // light-frame position; w: 1 on geometry
  vec4 state = texelFetch(ow_state_in, at, 0);  // next point, node to go on from, visits
  vec4 sums = texelFetch(ow_sums_in, at, 0);  // lit weight, all weight
  int point = int(state.x);
  int node = int(state.y);
  float visits = state.z;
  if (sample_at.w < 0.5 || point >= ow_points) {
    ow_state_out = state;
    ow_sums_out = sums;
    return;
  }
  vec3 p = sample_at.xyz;
  vec3 n = texelFetch(ow_normals, at, 0).xyz;
  int budget = ow_budget;
  while (point < ow_points && budget > 0) {
    vec3 q = texelFetch(ow_points_table, ivec2(point, 0), 0).xyz;
    vec3 d = q - p;
    float len = length(d);
    float weight = (len > 0.0) ? max(dot(d, n), 0.0) * max(d.z, 0.0) / (len * len * len * len) : 0.0;
    int before = budget;
    int verdict = (weight > 0.0) ? ow_tree_walk(p, d, ow_tree_eps, node, budget) : OW_TREE_CLEAR;
    visits += float(before - budget);
    if (verdict == OW_TREE_CUT) {
      break;
    }
    sums.y += weight;
    sums.x += (verdict == OW_TREE_CLEAR) ? weight : 0.0;
    point += 1;
    node = 1;
  }
  ow_state_out = vec4(float(point), float(node), visits, 0.0);
  ow_sums_out = sums;
}
