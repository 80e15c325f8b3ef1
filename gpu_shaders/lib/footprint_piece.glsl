// The footprint pass's vertex stage for pieces (OW_PIECES: resident.py's parts of hair and
// points), included by footprint.vert after its helpers (ow_layer_position,
// ow_box_corner). A piece is a sphere swept from a to b, its radius from ra to rb; its
// fragments find where their texel's ray passes through it (lib/footprint_ray.glsl,
// the maps) or walk the texel's samples (lib/exact_piece.glsl, the exact pass).
//
// Its footprint is the box of the image of its oriented bounding box: every ray from the
// light that meets the solid box meets one of its twelve faces, so the union of the
// faces' boxes (the triangles' own box functions, in every layer kind, warp and map) holds
// the piece's image; a light inside the box sees it in every direction.
#include "lib/blockers.glsl"

// Corner indices of the box's twelve triangles (bit 0: along the axis, 1 and 2: across it).
const ivec3 OW_BOX_FACES[12] = ivec3[12](ivec3(0, 2, 6), ivec3(0, 6, 4), ivec3(1, 5, 7), ivec3(1, 7, 3),
                                         ivec3(0, 4, 5), ivec3(0, 5, 1), ivec3(2, 3, 7), ivec3(2, 7, 6),
                                         ivec3(0, 1, 3), ivec3(0, 3, 2), ivec3(4, 6, 7), ivec3(4, 7, 5));

// One face triangle's box: in the layer's projection xy, or in a projective map's uv.
vec4 ow_piece_face_box(vec3 t0, vec3 t1, vec3 t2, float soft_grow)
{
#ifndef OW_FIXED_KIND
  if (ow_projective != 0) {
#ifdef OW_EXACT_SOFT
    return ow_soft_projective_box(ow_map_matrix, t0, t1, t2, soft_grow);
#else
    return ow_projective_box(ow_map_matrix, t0, t1, t2, ow_clip_near);
#endif
  }
#endif
  vec3 l0 = ow_layer_rot * t0;
  vec3 l1 = ow_layer_rot * t1;
  vec3 l2 = ow_layer_rot * t2;
#ifdef OW_EXACT_SOFT
  return ow_soft_box(l0, l1, l2, OW_KIND(ow_layer_kind), soft_grow);
#else
  return (OW_KIND(ow_layer_kind) == OW_KIND_PARABOLOID) ? ow_paraboloid_box(l0, l1, l2)
                                                      : ow_cube_box(l0, l1, l2, ow_clip_near);
#endif
}

// The box of the piece's image (empty: x0 > x1), through its oriented bounding box.
vec4 ow_piece_box(vec3 a, vec3 b, float r, float soft_grow)
{
  vec3 axis = b - a;
  float len = length(axis);
  vec3 e = (len > 0.0) ? axis / len : vec3(0.0, 0.0, 1.0);
  vec3 u = normalize(cross(e, (abs(e.x) < 0.9) ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0)));
  vec3 v = cross(e, u);
  vec3 mid = 0.5 * (a + b);
  float half_len = 0.5 * len + r;
  if (abs(dot(mid, e)) <= half_len && abs(dot(mid, u)) <= r && abs(dot(mid, v)) <= r) {
    // The light inside the box: every direction (the whole layer or map).
#ifndef OW_FIXED_KIND
    if (ow_projective != 0) {
      return vec4(0.0, 1.0, 0.0, 1.0);
    }
#endif
    return vec4(-1.0, 1.0, -1.0, 1.0);
  }
  vec3 c[8];
  for (int i = 0; i < 8; i++) {
    c[i] = mid + e * (((i & 1) != 0) ? half_len : -half_len) + u * (((i & 2) != 0) ? r : -r)
           + v * (((i & 4) != 0) ? r : -r);
  }
  vec4 box = vec4(1e30, -1e30, 1e30, -1e30);
  for (int f = 0; f < 12; f++) {
    ivec3 face = OW_BOX_FACES[f];
    vec4 own = ow_piece_face_box(c[face.x], c[face.y], c[face.z], soft_grow);
    if (own.x <= own.y && own.z <= own.w) {
      box = vec4(min(box.x, own.x), max(box.y, own.y), min(box.z, own.z), max(box.w, own.w));
    }
  }
  return box;
}

// Both ends beyond one plane of the occluder region by more than the radius.
bool ow_piece_outside_region(vec3 a, vec3 b, float r)
{
  for (int i = 0; i < OW_REGION_PLANES; i++) {
    if (i >= ow_region_count) {
      break;
    }
    vec4 p = ow_region_planes[i];
    float slack = ow_region_slack + r * length(p.xyz);
    if (dot(p.xyz, a) - p.w > slack && dot(p.xyz, b) - p.w > slack) {
      return true;
    }
  }
  return false;
}

void ow_piece_vertex(int corner)
{
#ifdef OW_POINTS
  int base = 3 * gl_VertexID;
#else
  int base = 3 * (gl_VertexID / OW_FOOTPRINT_VERTICES);
#endif
  vec3 a = ow_pull(base);
  vec3 b = ow_pull(base + 1);
  float ra = ow_object_length(ow_pull_w(base, false));
  float rb = ow_object_length(ow_pull_w(base + 1, false));
  float r = max(ra, rb);
  v_piece_a = vec4(a, ra);
  v_piece_b = vec4(b, rb);
  // Its curve's run of pieces (lib/exact_piece.glsl leaves a sample on the curve
  // unshadowed) and 1 for a ribbon (resident._piece_uvs).
  float first = ow_pull_w(base, true);
  float count = ow_pull_w(base + 1, true);
  int index = base / 3;
  int first_i = int(first + 0.5);
  int last_i = int(first + count - 0.5);
  v_piece_curve = vec3(first, count, ow_pull_w(base + 2, false));
  // The planes that end its curve, across its direction at its first and last points,
  // as Cycles ends a curve's tube (core/blockers.Pieces.end_planes); none for a point or
  // a closed (linear) curve.
  v_piece_cut_a = vec4(0.0);
  v_piece_cut_b = vec4(0.0);
  if (ow_pull_w(base + 2, true) < 0.5) {
    vec3 a0 = ow_pull(3 * first_i);
    vec3 b0 = ow_pull(3 * first_i + 1);
    vec3 a1 = ow_pull(3 * last_i);
    vec3 b1 = ow_pull(3 * last_i + 1);
    if (a0 != b0) {
      vec3 n0 = normalize(b0 - a0);
      v_piece_cut_a = vec4(n0, -dot(n0, a0));
    }
    if (a1 != b1) {
      vec3 n1 = normalize(a1 - b1);
      v_piece_cut_b = vec4(n1, -dot(n1, b1));
    }
  }
  // A ribbon's stretch ends across the curve's direction at its ends: the bisectors of its
  // own and its neighbours' (core/blockers.Pieces.joint_tangents).
  vec3 unit = (a != b) ? normalize(b - a) : vec3(0.0);
  v_piece_ta = unit;
  v_piece_tb = unit;
  if (v_piece_curve.z > 0.5) {
    if (index > first_i) {
      vec3 before = ow_pull(base - 2) - ow_pull(base - 3);
      v_piece_ta += (dot(before, before) > 0.0) ? normalize(before) : vec3(0.0);
    }
    if (index < last_i) {
      vec3 after = ow_pull(base + 4) - ow_pull(base + 3);
      v_piece_tb += (dot(after, after) > 0.0) ? normalize(after) : vec3(0.0);
    }
  }
  // The triangles' flat inputs: unused by a piece's fragments, written all the same.
  v_plane = vec4(0.0);
  v_edge0 = vec3(0.0);
  v_edge1 = vec3(0.0);
  v_edge2 = vec3(0.0);
#ifdef OW_EXACT
  v_edge_at0 = vec3(0.0);
  v_edge_at1 = vec3(0.0);
  v_edge_at2 = vec3(0.0);
  v_overlapped = 0.0;
#endif
  float soft_grow = 0.0;
#ifdef OW_EXACT_SOFT
  v_edge_hi0 = vec4(0.0);
  v_edge_hi1 = vec4(0.0);
  v_edge_hi2 = vec4(0.0);
  v_cull0 = vec4(0.0);
  v_cull1 = vec4(0.0);
  v_cull2 = vec4(0.0);
  // The light's reach grows the footprint as a triangle's (lib/soft_footprint.glsl), from
  // the piece's least distance to the light's centre.
  vec3 ab = b - a;
  float along = (dot(ab, ab) > 0.0) ? clamp(-dot(a, ab) / dot(ab, ab), 0.0, 1.0) : 0.0;
  float d_min = max(length(a + along * ab) - r, 0.0);
  soft_grow = ow_soft_grow(d_min, ow_exact_reach, ow_exact_far);
#endif
  const vec4 parked = vec4(2.0, 2.0, 2.0, 1.0);  // outside the clip volume: nothing drawn
  if (!(r > 0.0) || ow_piece_outside_region(a, b, r)) {
    gl_Position = parked;
    return;
  }
  vec4 box = ow_piece_box(a, b, r, soft_grow);
  if (!(box.x <= box.y && box.z <= box.w)) {
    gl_Position = parked;  // behind the layer's half-space, beside the face or the map
    return;
  }
#ifndef OW_FIXED_KIND
  if (ow_projective != 0) {
    float grow = ow_dilate / ow_resolution;
    box += vec4(-grow, grow, -grow, grow);
    gl_Position = ow_box_meets_map(box) ? ow_box_corner(box, corner) : parked;
    return;
  }
#endif
  gl_Position = ow_layer_position(box, corner);
}
