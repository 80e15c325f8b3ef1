// The exact pass's walk (shaders.exact_variant), for footprint_exact.frag: each fragment
// walks its texel's list of view samples and marks those whose segment to the light this
// triangle crosses. A sized light's test is lib/exact_soft_mark.glsl's (OW_EXACT_SOFT).

#ifndef OW_FIXED_KIND
// The exact pass over a spot's or sun's map. Whether this triangle blocks the
// light of sample p (light-centred); `sides` are p's sides of the three edge planes,
// positive inside (footprint.vert: planes through a spot, or containing a sun's direction).
// A spot is a point light: the plane must cut the segment from the light to p, more than
// ow_exact_eps of its length before p, as in ow_exact_walk. A sun shines along
// ow_light_axis from infinitely far: the ray from p towards it, p - t axis, meets the plane
// at t = h / (n . axis) (h: p's height over the plane, from a point of it), which must lie
// upstream by more than ow_exact_eps |p|, the same share of p's distance from the origin,
// which is what float32 rounds p to.
bool ow_projective_blocks(vec3 p, out vec3 sides)
{
  precise float side0 = dot(p - v_edge_at0, v_edge0);
  precise float side1 = dot(p - v_edge_at1, v_edge1);
  precise float side2 = dot(p - v_edge_at2, v_edge2);
  sides = vec3(side0, side1, side2);
  if (!(side0 >= 0.0 && side1 >= 0.0 && side2 >= 0.0)) {
    return false;
  }
  precise float h = dot(v_plane.xyz, p - v_edge_at0);
  if (ow_sun != 0) {
    float q = dot(v_plane.xyz, ow_light_axis);
    return q != 0.0 && h / q > ow_exact_eps * length(p);
  }
  float s = dot(v_plane.xyz, p);
  return s != 0.0 && v_plane.w / s > 0.0 && h / s > ow_exact_eps;
}

// Sample p (light-centred, n its normal) lifted off its own surface towards the light, by
// ow_exact_lift_share of its distance from the origin. float32 rounds p by about 1e-7 of that
// distance, so on a surface edge-on to the light p would lie on either side of its own
// plane, and of its neighbours' edge planes, by chance (sun_field's first hay bale is
// turned to the sun's azimuth: its faces are parallel to the light, and half their samples
// were shadowed by the box itself). Cycles starts its shadow rays on the lit side too.
vec3 ow_exact_lift(vec3 p, vec3 n)
{
  vec3 to_light = (ow_sun != 0) ? -ow_light_axis : -p;
  return p + ((dot(n, to_light) < 0.0) ? -n : n) * (ow_exact_lift_share * length(p));
}

#endif

// A face laid over the sample's own (a Mirror modifier that lays a copy onto the
// original, overlapping coplanar faces): Cycles' shadow ray skips only the primitive it
// leaves from, so another face through the point shadows it from every point of the
// light. A triangle that another coplanar face of its object overlaps (v_overlapped:
// core/coplanar.py), parallel to the sample's face (OW_TWIN_COS), that holds sample p
// (light-centred, not lifted) strictly inside its edges, within OW_TWIN_SHARE of p's
// distance of its plane, sets OW_HIT_TWIN: the first one to do so is the sample's own face,
// a second one marks it shadowed (core/alpha.py). Strictly inside: two faces that share an
// edge hold a point on it neither of them. Cycles shadows a point on a twin face when float32
// rounding leaves it on or behind the twin's plane: always on a face along the axes (the
// point's coordinate is the plane's), by chance on a sloped one; this always does.
void ow_exact_twin(ivec2 at, vec3 p)
{
  if (v_overlapped == 0.0 || abs(dot(texelFetch(ow_normals, at, 0).xyz, v_plane.xyz)) < OW_TWIN_COS) {
    return;
  }
  precise float side0 = dot(p - v_edge_at0, v_edge0);
  precise float side1 = dot(p - v_edge_at1, v_edge1);
  precise float side2 = dot(p - v_edge_at2, v_edge2);
  if (!(side0 > 0.0 && side1 > 0.0 && side2 > 0.0)) {
    return;
  }
  precise float h = dot(v_plane.xyz, p - v_edge_at0);
  if (abs(h) <= OW_TWIN_SHARE * length(p)) {
    uint before = imageAtomicOr(ow_hits, at, OW_HIT_TWIN);
    if ((before & OW_HIT_TWIN) != 0u) {
      imageAtomicOr(ow_hits, at, OW_HIT_OPAQUE);
    }
  }
}

// Mark sample `at` as crossed by this triangle: opaque, or the optical depth of a
// see-through crossing (core/alpha.py), its UV from the barycentrics, which the edge sides
// are proportional to (side i to the weight of the vertex opposite edge i).
void ow_exact_mark(ivec2 at, vec3 sides)
{
#ifdef OW_ALPHA
  vec3 w = sides.yzx / (sides.x + sides.y + sides.z);
  float alpha = ow_alpha_at(w.x * v_uv01.xy + w.y * v_uv01.zw + w.z * v_uv2);
  if (alpha >= OW_OPAQUE_ALPHA) {
    imageAtomicOr(ow_hits, at, OW_HIT_OPAQUE);
  } else if (alpha > OW_CLEAR_ALPHA) {
    imageAtomicAdd(ow_hits, at, uint(-log(1.0 - alpha) * OW_OPTICAL_SCALE + 0.5));
  }
#else
  imageAtomicOr(ow_hits, at, OW_HIT_OPAQUE);
#endif
}

#ifdef OW_MEDIUM
#ifndef OW_EXACT_SOFT
// A medium's triangle (shaders.medium_of, lib/media.glsl): where the segment from the light
// to sample p crosses it, more than ow_exact_eps of the way from the sample, the crossing's
// distance from the sample goes to the sample's optical depths, signed by whether the walk
// from the light enters the medium there. A spot's or sun's sample is lifted off its
// surface as for an opaque triangle; a sun's walk comes along its axis from upstream.
void ow_medium_entry(ivec2 at, vec3 p)
{
  ivec2 size = textureSize(ow_positions, 0);
  vec3 q = p;
#ifndef OW_FIXED_KIND
  if (ow_projective != 0) {
    q = ow_exact_lift(p, texelFetch(ow_normals, at, 0).xyz);
  }
#endif
  precise float side0 = dot(q - v_edge_at0, v_edge0);
  precise float side1 = dot(q - v_edge_at1, v_edge1);
  precise float side2 = dot(q - v_edge_at2, v_edge2);
  if (!(ow_medium_inside(side0, v_edge0) && ow_medium_inside(side1, v_edge1) && ow_medium_inside(side2, v_edge2))) {
    return;
  }
  precise float h = dot(v_plane.xyz, q - v_edge_at0);  // q's height over the triangle's plane
#ifndef OW_FIXED_KIND
  if (ow_projective != 0 && ow_sun != 0) {
    float across = dot(v_plane.xyz, ow_light_axis);
    float t = h / across;  // q - t axis lies on the plane
    if (across != 0.0 && t > ow_exact_eps * length(q)) {
      ow_media_mark(at, size, (across < 0.0) ? t : -t);
    }
    return;
  }
#endif
  float along = dot(v_plane.xyz, q);
  if (along == 0.0 || !(v_plane.w / along > 0.0)) {
    return;  // the plane meets the segment's line behind the light
  }
  float rest = h / along;  // the crossing's distance from the sample, over |q|
  if (rest > ow_exact_eps && rest < 1.0) {
    ow_media_mark(at, size, ((along < 0.0) ? rest : -rest) * length(q));
  }
}
#endif
#endif

// One list entry: sample `at` (p light-centred) marked if this triangle blocks its light: a
// sized light's points (the soft variant's mark, above), a spot's or a sun's segment
// (ow_projective_blocks), or the segment to a point light.
void ow_exact_entry(ivec2 at, vec3 p)
{
#ifdef OW_MEDIUM
#ifdef OW_EXACT_SOFT
  ow_medium_soft_entry(p, at, textureSize(ow_positions, 0));  // lib/exact_soft_medium.glsl
#else
  ow_medium_entry(at, p);  // a medium's crossing (lib/media.glsl)
#endif
  return;
#endif
#ifdef OW_PIECES
  ow_piece_exact_entry(at, p);  // a piece of hair or a point (lib/exact_piece.glsl)
  return;
#endif
#ifdef OW_EXACT_SOFT
  ow_exact_soft_mark(p, at, textureSize(ow_positions, 0).y);
  return;
#endif
#ifndef OW_ALPHA
  ow_exact_twin(at, p);
#endif
#ifndef OW_FIXED_KIND
  if (ow_projective != 0) {
    vec3 sides;
    if (ow_projective_blocks(ow_exact_lift(p, texelFetch(ow_normals, at, 0).xyz), sides)) {
      ow_exact_mark(at, sides);
    }
    return;
  }
#endif
  float s = dot(v_plane.xyz, p);
  precise float side0 = dot(p - v_edge_at0, v_edge0);
  precise float side1 = dot(p - v_edge_at1, v_edge1);
  precise float side2 = dot(p - v_edge_at2, v_edge2);
  if (side0 >= 0.0 && side1 >= 0.0 && side2 >= 0.0 && s != 0.0) {
    // The plane cuts the segment at f = w / s (1 at the sample); 1 - f = h / s with h the
    // sample's height over the plane, taken from a point of it, not as s - w: the
    // margin test keeps its precision for an occluder just in front of the sample.
    precise float h = dot(v_plane.xyz, p - v_edge_at0);
    if (v_plane.w / s > 0.0 && h / s > ow_exact_eps) {
      ow_exact_mark(at, vec3(side0, side1, side2));
    }
  }
}

// The irregular z-buffer (shaders.exact_variant): this fragment's texel holds a list of
// view samples (ow_counts: head, ow_next: links; sample index + 1, 0 ends it). A sample
// is shadowed by this triangle when its segment from the light crosses it: its own
// direction lies inside the three edge planes, and the triangle's plane cuts the segment
// before the sample, by more than ow_exact_eps of its length (the receiver's own surface
// is left out). Marked in ow_hits. A fragment walks at most ow_exact_bound entries; a
// longer list is counted in ow_work and finished by the next round, which starts where
// this one stopped (list_advance.comp moves the heads on), so every entry is walked once.
void ow_exact_walk()
{
  ivec2 texel = ivec2(gl_FragCoord.xy - ow_tile_origin);
  int res = int(ow_resolution);
  uint node = imageLoad(ow_counts, texel + ivec2(ow_exact_tile * res, 0)).x;
  int width = textureSize(ow_positions, 0).x;
  int step = 0;
  for (; step < ow_exact_bound && node != 0u; step++) {
    int index = int(node) - 1;
    ivec2 at = ivec2(index % width, index / width);
    ow_exact_entry(at, texelFetch(ow_positions, at, 0).xyz);  // light-centred
    node = imageLoad(ow_next, at).x;
  }
  if (node != 0u) {
    imageAtomicAdd(ow_work, ivec2(OW_WORK_CUT, 0), 1u);
  }
#ifdef OW_EXACT_COUNT
  // A measurement frame (shaders.EXACT_COUNT_DEFINE): the entries walked and the fragments
  // that walked them, this round's work (the host folds it round by round).
  imageAtomicAdd(ow_work, ivec2(OW_WORK_ENTRIES, 0), uint(step));
  imageAtomicAdd(ow_work, ivec2(OW_WORK_FRAGMENTS, 0), 1u);
#endif
}
