// The shadow segments' tree (core/ray_tree.py): whether a triangle crosses the segment
// p + t d, t in (eps, 1), walked without a stack from one node number, so that a walk cut
// at its budget of visits goes on later from where it stopped. The includer declares the
// samplers ow_tree_boxes (two texels a node from node 0: lo, hi) and ow_tree_tris (three a
// slot: its corners), both OW_RAY_TREE_WIDTH texels wide, and the uniform ow_tree_leaves.

vec4 ow_tree_texel(sampler2D table, int index)
{
  return texelFetch(table, ivec2(index % OW_RAY_TREE_WIDTH, index / OW_RAY_TREE_WIDTH), 0);
}

// Whether p + t d meets node's box for some t in [0, 1] (the slab test; an empty leaf's box
// lies beyond every segment).
bool ow_tree_box(int node, vec3 p, vec3 inv_d)
{
  vec3 t0 = (ow_tree_texel(ow_tree_boxes, 2 * node).xyz - p) * inv_d;
  vec3 t1 = (ow_tree_texel(ow_tree_boxes, 2 * node + 1).xyz - p) * inv_d;
  vec3 near = min(t0, t1);
  vec3 far = max(t0, t1);
  return max(max(near.x, near.y), max(near.z, 0.0)) <= min(min(far.x, far.y), min(far.z, 1.0));
}

// Whether the segment crosses triangle (a, b, c) at t in (eps, 1): inside the three edge
// planes through p, edges closed (a shared edge's plane is its neighbour's negated exactly,
// so no segment slips between two triangles), and crossing the triangle's plane there.
bool ow_tree_crosses(vec3 a, vec3 b, vec3 c, vec3 p, vec3 d, float eps)
{
  precise vec3 ra = a - p;
  precise vec3 rb = b - p;
  precise vec3 rc = c - p;
  precise vec3 sides = vec3(dot(cross(ra, rb), d), dot(cross(rb, rc), d), dot(cross(rc, ra), d));
  bool inside = all(greaterThanEqual(sides, vec3(0.0))) || all(lessThanEqual(sides, vec3(0.0)));
  vec3 n = cross(b - a, c - a);
  float along = dot(n, d);
  if (!inside || along == 0.0) {
    return false;
  }
  float t = dot(n, ra) / along;
  return t > eps && t < 1.0;
}

// The node after `node` and its subtree (0: the walk is done): up past every right child,
// then to the right sibling. Without a loop: the trailing ones of the number go.
int ow_tree_next(int node)
{
  int up = findLSB(~node);
  node >>= up;
  return node == 0 ? 0 : node + 1;
}

// Walks on from `node` (1 for a new segment) while `budget` lasts, one unit a box and one
// a triangle: OW_TREE_BLOCKED, OW_TREE_CLEAR, or OW_TREE_CUT with `node` where to go on.
int ow_tree_walk(vec3 p, vec3 d, float eps, inout int node, inout int budget)
{
  vec3 inv_d = 1.0 / d;
  while (node != 0) {
    if (budget <= 0) {
      return OW_TREE_CUT;
    }
    budget -= 1;
    bool inside = ow_tree_box(node, p, inv_d);
    if (inside && node < ow_tree_leaves) {
      node *= 2;
      continue;
    }
    if (inside) {
      int first = 3 * OW_RAY_TREE_LEAF * (node - ow_tree_leaves);
      budget -= OW_RAY_TREE_LEAF;
      for (int k = 0; k < OW_RAY_TREE_LEAF; k++) {
        int at = first + 3 * k;
        if (ow_tree_crosses(ow_tree_texel(ow_tree_tris, at).xyz, ow_tree_texel(ow_tree_tris, at + 1).xyz,
                            ow_tree_texel(ow_tree_tris, at + 2).xyz, p, d, eps)) {
          node = 0;
          return OW_TREE_BLOCKED;
        }
      }
    }
    node = ow_tree_next(node);
  }
  return OW_TREE_CLEAR;
}
