// Footprint depth pass, vertex stage (vertex pulling).
//
// Six vertices per triangle, two triangles of one quad: vertex i belongs to triangle
// i / 6, and the corner buffer holds i % 6 (a plain draw: software rasterisers run
// instanced draws of a few vertices each far slower). Built with OW_POINTS, one vertex
// per triangle instead: a point sprite over the box, for the chunks whose boxes the host
// has bounded below OW_MAX_POINT_SIZE texels (parameterizations.footprint_ranges).
//
// The triangle's vertices come from the object's vertex texture, light-centred, and give
// the flat inputs of the exact per-texel test: the three edge planes through the light
// and the triangle's plane. The corners span a conservative box of the triangle's curved
// image in the cropped, warped layer (lib/footprint.glsl), dilated by `ow_dilate` texels
// for float32 rounding. Triangles seen edge-on, outside the occluder region or outside
// the layer draw nothing: every vertex goes to one point outside the clip volume.
#include "lib/projection.glsl"
#include "lib/mapping.glsl"
#include "lib/footprint.glsl"
#include "lib/projective.glsl"
#include "lib/vertex_pull.glsl"
#ifdef OW_EXACT_SOFT
#include "lib/soft_footprint.glsl"
#endif


#ifdef OW_ALPHA
// Vertex `index`'s UV: u in its hi texel's w, v in its lo texel's (resident.vertex_texels).
vec2 ow_pull_uv(int index)
{
  return vec2(ow_pull_w(index, false), ow_pull_w(index, true));
}
#endif

// All three corners beyond one plane of the occluder region (plan.outside_region).
bool ow_outside_region(vec3 v0, vec3 v1, vec3 v2)
{
  for (int i = 0; i < OW_REGION_PLANES; i++) {
    if (i >= ow_region_count) {
      break;
    }
    vec4 p = ow_region_planes[i];
    float slack = ow_region_slack;
    if (dot(p.xyz, v0) - p.w > slack && dot(p.xyz, v1) - p.w > slack && dot(p.xyz, v2) - p.w > slack) {
      return true;
    }
  }
  return false;
}

#ifndef OW_FIXED_KIND
// A uv box (u0, u1, v0, v1) that is not empty and meets the map (false too where not finite).
bool ow_box_meets_map(vec4 box)
{
  return box.x <= box.y && box.x <= 1.0 && box.y >= 0.0 && box.z <= 1.0 && box.w >= 0.0;
}

// The clip position of the quad's `corner` over a uv box, clamped to the map.
vec4 ow_box_corner(vec4 box, int corner)
{
  box = clamp(box, 0.0, 1.0);
  vec2 uv = vec2(((corner & 1) != 0) ? box.y : box.x, ((corner & 2) != 0) ? box.w : box.z);
  return vec4(uv * 2.0 - 1.0, 0.0, 1.0);
}
#endif

#ifdef OW_EXACT
#ifndef OW_FIXED_KIND
// The exact pass over a sun's map: the edge planes that contain the light's direction
// (lib/projective.glsl) in place of the planes through the light; returns the orientation.
float ow_sun_edges(vec3 v0, vec3 v1, vec3 v2)
{
  float orientation = ow_parallel_orientation(ow_light_axis, v0, v1, v2);
  vec3 n0, n1, n2;
  ow_parallel_edge(ow_light_axis, v0, v1, n0, v_edge_at0);
  ow_parallel_edge(ow_light_axis, v1, v2, n1, v_edge_at1);
  ow_parallel_edge(ow_light_axis, v2, v0, n2, v_edge_at2);
  v_edge0 = n0 * orientation;
  v_edge1 = n1 * orientation;
  v_edge2 = n2 * orientation;
  return orientation;
}

// The exact pass over a spot's or sun's map: a conservative cover of the triangle's image
// (its part in front of the map), grown by `ow_dilate` texels, so that every texel whose
// square meets the image gets a fragment; the rasterised triangle itself would miss the
// texels whose centres lie outside it. The image's own triangle with its edges moved out
// where the triangle lies wholly in front and that is smaller (about half the fragments
// of a box on a plain mesh), else the quad over the image's box; `corner` as the layers'
// quads.
vec4 ow_projective_quad(vec3 v0, vec3 v1, vec3 v2, int corner)
{
  vec4 box = ow_projective_box(ow_map_matrix, v0, v1, v2, ow_clip_near);
  float grow = ow_dilate / ow_resolution;
  box += vec4(-grow, grow, -grow, grow);
  if (!ow_box_meets_map(box)) {
    return vec4(2.0, 2.0, 2.0, 1.0);  // behind the map or beside it: nothing drawn
  }
  vec4 c0 = ow_map_matrix * vec4(v0, 1.0);
  vec4 c1 = ow_map_matrix * vec4(v1, 1.0);
  vec4 c2 = ow_map_matrix * vec4(v2, 1.0);
  vec2 corner_uv;
  if (min(min(c0.w, c1.w), c2.w) >= ow_clip_near
      && ow_dilated_triangle(c0.xy / c0.w * 0.5 + 0.5, c1.xy / c1.w * 0.5 + 0.5, c2.xy / c2.w * 0.5 + 0.5, grow,
                             corner, (box.y - box.x) * (box.w - box.z), corner_uv)) {
    return vec4(corner_uv * 2.0 - 1.0, 0.0, 1.0);
  }
  return ow_box_corner(box, corner);
}

#ifdef OW_EXACT_SOFT
// The exact pass of a sized spot or sun over its map: the quad over the triangle's grown
// footprint (lib/soft_footprint.glsl's ow_soft_projective_box), grown by `ow_dilate` texels.
vec4 ow_soft_projective_quad(vec3 v0, vec3 v1, vec3 v2, int corner, float grow)
{
  float dilate = ow_dilate / ow_resolution;
  vec4 box = ow_soft_projective_box(ow_map_matrix, v0, v1, v2, grow) + vec4(-dilate, dilate, -dilate, dilate);
  if (!ow_box_meets_map(box)) {
    return vec4(2.0, 2.0, 2.0, 1.0);  // beside the map (or not finite): nothing drawn
  }
  return ow_box_corner(box, corner);
}
#endif
#endif
#endif

// The quad's corner (bit 0: high x, bit 1: high y) of each of the six vertices.
const int OW_QUAD_CORNER[OW_FOOTPRINT_VERTICES] = int[OW_FOOTPRINT_VERTICES](0, 1, 2, 2, 1, 3);

// Where vertex `corner` of a footprint goes, for its box in the layer's projection xy
// (x0, x1, y0, y1), not empty: projection xy -> uncropped uv -> cropped uv (affine,
// increasing) -> warped uv, grown by `ow_dilate` texels; outside the clip volume where
// that misses the (cropped) map. As a point sprite (OW_POINTS) it also sets the size.
vec4 ow_layer_position(vec4 box, int corner)
{
  vec4 crop = ow_crop_of(ow_warp_rows, ow_layer_slot, ow_warp_size, ow_crop);
  box = (box * 0.5 + 0.5 - crop.xxyy) * crop.zzww;
#ifndef OW_NO_WARP
  if (ow_warp_size > 0) {
    box = ow_warp_box(ow_warp_rows, ow_warp_cols, ow_layer_slot, ow_warp_size, box,
                      ow_warp_shears(ow_warp_rows, ow_warp_cols, ow_layer_slot, ow_warp_size));
  }
#endif
  float grow = ow_dilate / ow_resolution;
  box += vec4(-grow, grow, -grow, grow);
  if (box.x > 1.0 || box.y < 0.0 || box.z > 1.0 || box.w < 0.0) {
    return vec4(2.0, 2.0, 2.0, 1.0);  // outside the (cropped) map: nothing drawn
  }
  box = clamp(box, 0.0, 1.0);
#ifdef OW_POINTS
  // The square of side extent + 1 texel around the box's centre holds the box; its
  // centre lies in the tile, so the point is not clipped, and the scissor keeps it there.
  gl_PointSize = min(max(box.y - box.x, box.w - box.z) * ow_resolution + 1.0, float(OW_MAX_POINT_SIZE));
  if (corner < 0) {
    gl_PointSize = 0.0;  // never (corners are >= 0): keeps the corner attribute in the program
  }
  return vec4(vec2(box.x + box.y, box.z + box.w) - 1.0, 0.0, 1.0);
#else
  vec2 uv = vec2(((corner & 1) != 0) ? box.y : box.x, ((corner & 2) != 0) ? box.w : box.z);
  return vec4(uv * 2.0 - 1.0, 0.0, 1.0);
#endif
}

#ifdef OW_PIECES
#include "lib/footprint_piece.glsl"
#endif

void main()
{
  int corner = OW_QUAD_CORNER[clamp(int(ow_corner + 0.5), 0, OW_FOOTPRINT_VERTICES - 1)];
#ifdef OW_PIECES
  ow_piece_vertex(corner);
  return;
#endif
#ifdef OW_POINTS
  int base = 3 * gl_VertexID;
#else
  int base = 3 * (gl_VertexID / OW_FOOTPRINT_VERTICES);
#endif
  vec3 v0 = ow_pull(base);
  vec3 v1 = ow_pull(base + 1);
  vec3 v2 = ow_pull(base + 2);
  vec3 normal = cross(v1 - v0, v2 - v0);
  normal /= max(length(normal), 1e-30);
  v_plane = vec4(normal, dot(normal, v0));
  vec3 n0, n1, n2;
  float orientation = ow_edge_planes(v0, v1, v2, ow_edge_on_distance, n0, n1, n2);
#ifdef OW_EXACT
  // The samples' side of each edge, relative to a point of it (lib/footprint.glsl).
  ow_relative_edge(v0, v1, n0, v_edge_at0);
  ow_relative_edge(v1, v2, n1, v_edge_at1);
  ow_relative_edge(v2, v0, n2, v_edge_at2);
#ifdef OW_ALPHA
  v_overlapped = 0.0;  // a see-through part's w holds its UVs
#else
  v_overlapped = ow_pull_w(base, false);  // 1: a coplanar face of the object overlaps this one
#endif
#endif
#ifdef OW_EXACT_SOFT
  // A sized light's walk tests each edge from the sample: the edge's other vertex, and in
  // w -1 where ow_relative_edge swapped the pair (lo = v_edge_at, hi = this).
  v_edge_hi0 = ow_edge_swapped(v0, v1) ? vec4(v0, -1.0) : vec4(v1, 1.0);
  v_edge_hi1 = ow_edge_swapped(v1, v2) ? vec4(v1, -1.0) : vec4(v2, 1.0);
  v_edge_hi2 = ow_edge_swapped(v2, v0) ? vec4(v2, -1.0) : vec4(v0, 1.0);
  // The samples a triangle may shadow lie within `soft_grow` of its image from the light's
  // centre (lib/soft_footprint.glsl): the walk leaves out those farther than that from
  // one of its edges' great circles (v_cull: unit normals inwards, w the angle's sine).
  // A sun's rays come from no centre: its walk takes no such cut (reach_sin 2). v_cull1.w
  // carries the triangle's distance from the centre, a little under for float32 rounding,
  // for the walk's cut by the sample's own distance (lib/exact_soft_mark.glsl).
  bool soft_sun = int(ow_exact_light.x) == OW_LIGHT_SUN_DISK;
  float d_min = ow_origin_distance(v0, v1, v2);
  float soft_grow = ow_soft_grow(d_min, ow_exact_reach, ow_exact_far);
  float reach_sin = (soft_grow < 1.5707963267948966 && !soft_sun) ? sin(soft_grow) : 2.0;
  vec3 c0 = n0 * orientation;
  vec3 c1 = n1 * orientation;
  vec3 c2 = n2 * orientation;
  v_cull0 = vec4(c0 / max(length(c0), 1e-30), reach_sin);
  v_cull1 = vec4(c1 / max(length(c1), 1e-30), d_min * (1.0 - 1e-4));
  v_cull2 = vec4(c2 / max(length(c2), 1e-30), 0.0);
  // Seen edge-on from the light's centre, a triangle still shadows from its other points.
  if (length(cross(v1 - v0, v2 - v0)) > 0.0 && orientation == 0.0) {
    orientation = 1.0;
  }
#endif
  v_edge0 = n0 * orientation;
  v_edge1 = n1 * orientation;
  v_edge2 = n2 * orientation;
#ifdef OW_EXACT
#ifndef OW_FIXED_KIND
#ifndef OW_EXACT_SOFT
  if (ow_projective != 0 && ow_sun != 0) {
    orientation = ow_sun_edges(v0, v1, v2);  // a sized sun's walk tests edges from the sample
  }
#endif
#endif
#endif
#ifdef OW_ALPHA
  vec2 uv0 = ow_pull_uv(base);
  vec2 uv1 = ow_pull_uv(base + 1);
  vec2 uv2 = ow_pull_uv(base + 2);
  v_uv01 = vec4(uv0, uv1);
  v_uv2 = uv2;
  v_uv = (corner == 0) ? uv0 : ((corner == 1) ? uv1 : uv2);  // the projective path's corners
#endif
  const vec4 parked = vec4(2.0, 2.0, 2.0, 1.0);  // outside the clip volume: nothing drawn
  if (orientation == 0.0 || ow_outside_region(v0, v1, v2)) {
    gl_Position = parked;
    return;
  }
#ifdef OW_EXACT
#ifndef OW_FIXED_KIND
  if (ow_projective != 0) {
#ifdef OW_EXACT_SOFT
    gl_Position = ow_soft_projective_quad(v0, v1, v2, corner, soft_grow);
#else
    gl_Position = ow_projective_quad(v0, v1, v2, corner);
#endif
    return;
  }
#endif
#endif
#ifndef OW_FIXED_KIND
  if (ow_projective != 0) {
    // Spot or sun map: the triangle itself, projected linearly (exact); the quad's
    // fourth corner repeats the third, so its second triangle has no area.
    vec3 v = (corner == 0) ? v0 : ((corner == 1) ? v1 : v2);
    gl_Position = ow_map_matrix * vec4(v, 1.0);
    return;
  }
#endif
  vec3 l0 = ow_layer_rot * v0;
  vec3 l1 = ow_layer_rot * v1;
  vec3 l2 = ow_layer_rot * v2;
#ifdef OW_EXACT_SOFT
  vec4 box = ow_soft_box(l0, l1, l2, OW_KIND(ow_layer_kind), soft_grow);
#else
  vec4 box = (OW_KIND(ow_layer_kind) == OW_KIND_PARABOLOID) ? ow_paraboloid_box(l0, l1, l2)
                                                          : ow_cube_box(l0, l1, l2, ow_clip_near);
#endif
  if (box.x > box.y) {
    gl_Position = parked;  // behind the layer's half-space, or beside the cube face
    return;
  }
  gl_Position = ow_layer_position(box, corner);
}
