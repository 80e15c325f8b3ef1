// Footprint depth pass, fragment stage: exact coverage and depth at the texel centre.
// The centre goes back through the warp and crop to its own ray: read from the layer's
// ray table (ray_table.frag, the exact inverse) when warped, computed when not; the triangle covers the texel when that ray lies inside its three
// edge planes (lib/footprint.glsl's inside test), and the depth is where the ray meets
// the triangle's plane. Nothing is tessellated, so this holds however large the
// triangle and however curved its image.
#include "lib/projection.glsl"
#include "lib/mapping.glsl"
#ifdef OW_ALPHA
#include "lib/alpha.glsl"
#ifdef OW_VEIL
#include "lib/veil.glsl"
#endif

// The alpha where a ray from the light along `d` meets the triangle: barycentrics from
// the edge planes through the light (v_edge_i = orientation * v_i x v_i+1), whose dot
// products with d are proportional to them, then the corners' UVs.
float ow_alpha_along(vec3 d)
{
  vec3 w = vec3(dot(d, v_edge1), dot(d, v_edge2), dot(d, v_edge0));
  w /= (w.x + w.y + w.z);
  return ow_alpha_at(w.x * v_uv01.xy + w.y * v_uv01.zw + w.z * v_uv2);
}
#endif

#ifdef OW_VEIL
// A see-through surface in a map (shaders.alpha_of): an opaque point stores its depth;
// a partly transparent one goes to the texel's veil (lib/veil.glsl) and a clear one
// nowhere. Both of those leave the depth untouched. The fragment writes its depth, so
// it runs whatever the depth test says, and every crossing reaches the veil.
void ow_see_through(float alpha, float depth)
{
  if (alpha < OW_OPAQUE_ALPHA) {
    if (alpha > OW_CLEAR_ALPHA) {
      ow_veil_add(ivec2(gl_FragCoord.xy), alpha, depth);
    }
    discard;
  }
}
#endif

#ifdef OW_EXACT_SOFT
#include "lib/exact_soft.glsl"
#include "lib/soft_reach.glsl"

// Whether the light as a whole decides triangle (plane v_plane, edge planes e0..e2 through
// p, inner sides positive) for sample p at height h over its plane: -1 when no point of the
// light can be blocked, 1 when every point is (an umbra), 0 when each point is to be tested.
// A sphere or area light is held by the sphere of radius ow_exact_reach about the light
// centre (-p from p); a sun's directions by the cone of half angle ow_exact_light.y about
// the frame's +Z.
// Whether every segment from sample p (at height h over the triangle's plane) to the light
// crosses that plane more than ow_exact_eps from p: the whole light lies beyond it, a sun's
// cone of directions wholly leaves towards it.
bool ow_exact_crossing(vec3 p, float h)
{
  if (int(ow_exact_light.x) == 3) {
    float nc = dot(v_plane.xyz, ow_exact_frame[2]);
    return h * nc < 0.0 && abs(nc) > ow_exact_light.z && abs(h) > ow_exact_eps * length(p);
  }
  float centre_h = -dot(v_plane.xyz, v_edge_at0);  // the light centre's height
  return centre_h * h < 0.0 && abs(centre_h) > ow_exact_reach
         && abs(h) > ow_exact_eps * (abs(h) + abs(centre_h) + ow_exact_reach);
}

int ow_exact_soft_whole(vec3 p, float h, vec3 e0, vec3 e1, vec3 e2)
{
  vec3 lengths = vec3(length(e0), length(e1), length(e2));
  if (int(ow_exact_light.x) == 3) {
    // A ray p + t l crosses the plane at t = -h / (n . l) > 0. Within the cone, n . l keeps
    // the sign of n . c where |n . c| exceeds the half angle's sine.
    vec3 c = ow_exact_frame[2];
    float nc = dot(v_plane.xyz, c);
    float sin_half = ow_exact_light.z;
    if (h * nc >= 0.0 && abs(nc) > sin_half) {
      return -1;  // every direction leaves the plane on the sample's side
    }
    vec3 toward = vec3(dot(e0, c), dot(e1, c), dot(e2, c));
    if (any(lessThan(toward, -lengths * sin_half))) {
      return -1;  // the cone wholly outside one edge plane
    }
    // Inside all three, wholly crossing the plane, and |t| >= |h| > eps |p| for every ray.
    return (all(greaterThan(toward, lengths * sin_half)) && ow_exact_crossing(p, h)) ? 1 : 0;
  }
  float centre_h = -dot(v_plane.xyz, v_edge_at0);  // the light centre's height
  if (centre_h * h > 0.0 && abs(centre_h) >= ow_exact_reach) {
    return -1;  // the whole light on the sample's side of the plane
  }
  // The light's sphere (centre -p from p) against the wedge of the three planes: wholly
  // outside one of them, no segment crosses; wholly inside all three and wholly beyond the
  // triangle's plane, every segment does.
  vec3 reach = lengths * ow_exact_reach;
  vec3 centre_side = vec3(dot(e0, -p), dot(e1, -p), dot(e2, -p));
  if (any(lessThan(centre_side, -reach))) {
    return -1;
  }
  return (all(greaterThan(centre_side, reach)) && ow_exact_crossing(p, h)) ? 1 : 0;
}

// Whether a triangle decides light cluster c (points c * OW_EXACT_SOFT_CLUSTER on) for a
// sample as a whole: -1 when every point lies outside an edge plane, 1 when every point
// lies inside all three and `crossing` says each segment crosses the plane, 0 when its
// points are to be tested one by one. The cluster's box (ow_exact_bounds) bounds the
// points' weights in the axes along0..2 (the per-point test's): an area light's
// (x, y, -1) and a sun's (x, y, z) directly; a sphere's (sin_t cos phi, sin_t sin phi,
// cos_t) through the cap's polar angle at this sample, monotone in the box's u. Each edge's
// side is linear in the weights, so the box gives its least and greatest value; a margin
// of 1e-4 of their size keeps a point whose own test rounds the other way to that test.
int ow_exact_cluster(int c, OwLightView view, mat3 side_matrix, bool crossing)
{
  vec3 lo = ow_exact_bounds[2 * c].xyz;
  vec3 hi = ow_exact_bounds[2 * c + 1].xyz;
  vec3 w_lo = lo;
  vec3 w_hi = hi;
  int kind = int(ow_exact_light.x);
  if (kind == 2) {
    w_lo.z = -1.0;
    w_hi.z = -1.0;
  } else if (kind == 1) {
    vec2 near = ow_cap_polar(view, vec4(lo.x, 0.0, 0.0, 0.0));  // the least polar angle
    vec2 far = ow_cap_polar(view, vec4(hi.x, 0.0, 0.0, 0.0));
    // sin_t in [near.y, far.y] (>= 0) times cos phi in [lo.y, hi.y], and sin phi likewise.
    w_lo = vec3(min(near.y * lo.y, far.y * lo.y), min(near.y * lo.z, far.y * lo.z), far.x);
    w_hi = vec3(max(near.y * hi.y, far.y * hi.y), max(near.y * hi.z, far.y * hi.z), near.x);
  }
  vec3 mid = side_matrix * (0.5 * (w_lo + w_hi));
  vec3 half_range = mat3(abs(side_matrix[0]), abs(side_matrix[1]), abs(side_matrix[2])) * (0.5 * (w_hi - w_lo));
  vec3 margin = 1e-4 * (half_range + abs(mid));
  if (any(lessThan(mid + half_range, -margin))) {
    return -1;
  }
  return (crossing && all(greaterThan(mid - half_range, margin))) ? 1 : 0;
}

// A sized light (lib/exact_soft.glsl): the light points of sample p (light-centred, at
// texel `at` of the sample texture, `rows` its height) whose segment this triangle
// crosses, more than ow_exact_eps of its length from p, set their bits in p's words. A
// sun's rays go on forever: they must cross more than ow_exact_eps |p| from p, as the hard
// sun's do (ow_projective_blocks).
void ow_exact_soft_mark(vec3 p, ivec2 at, int rows)
{
  // Farther from the triangle's image than the light's angle from it: nothing to shadow
  // (a sun's v_cull never culls).
  vec3 dir = p * inversesqrt(max(dot(p, p), 1e-30));
  float reach_sin = v_cull0.w;
  if (reach_sin <= 1.0) {
    // The sample's own distance cuts tighter than the footprint's growth, which holds for
    // the farthest sample (lib/soft_reach.glsl's ow_soft_reach_sin): a receiver just
    // behind its blocker is cut far tighter. A sample nearer the centre than the whole
    // triangle (and R < d here) has no segment that crosses it.
    float d = v_cull1.w;
    float dist = length(p);
    if (dist < d) {
      return;
    }
    reach_sin = min(reach_sin, ow_soft_reach_sin(d, ow_exact_reach, dist) + 1e-4);
  }
  if (dot(dir, v_cull0.xyz) < -reach_sin || dot(dir, v_cull1.xyz) < -reach_sin || dot(dir, v_cull2.xyz) < -reach_sin) {
    return;
  }
  precise float h = dot(v_plane.xyz, p - v_edge_at0);  // p's height over the triangle's plane
  if (h == 0.0) {
    return;  // on the plane: the receiver itself
  }
  // Edge planes through p, each edge's vertices in one order for every triangle that has
  // it: neighbours get the same normal negated, and no segment passes between them. The
  // segment crosses the triangle when it lies on the inner side of all three, that side
  // being the one of det(v0 - p, v1 - p, v2 - p), whose sign is -sign(h).
  float side = (h > 0.0) ? -1.0 : 1.0;
  precise vec3 e0 = cross(v_edge_at0 - p, v_edge_hi0.xyz - p);
  precise vec3 e1 = cross(v_edge_at1 - p, v_edge_hi1.xyz - p);
  precise vec3 e2 = cross(v_edge_at2 - p, v_edge_hi2.xyz - p);
  e0 *= v_edge_hi0.w * side;
  e1 *= v_edge_hi1.w * side;
  e2 *= v_edge_hi2.w * side;
  int whole = ow_exact_soft_whole(p, h, e0, e1, e2);
  if (whole < 0) {
    return;
  }
  if (whole > 0) {
#ifndef OW_ALPHA
    for (int w = 0; w * 32 < ow_exact_points; w++) {
      imageAtomicOr(ow_hits, at + ivec2(0, w * rows), ow_exact_word_points(w));
    }
    return;
#endif
  }
  // Each point's segment against the edge planes and the triangle's plane, as affine
  // functions of its pattern entry (lib/exact_soft.glsl): for a sphere, seg = t d with
  // d = sin_t (c a + s b) + cos_t w, so e . seg has the sign of sin_t (c e.a + s e.b) +
  // cos_t e.w; for an area light, seg = F (x, y, 0) - p, so e . seg = x e.F0 + y e.F1 - e.p;
  // for a sun, the direction F (x, y, z), so e . l = x e.F0 + y e.F1 + z e.F2.
  OwLightView view = ow_light_view(p);
  bool sphere = int(ow_exact_light.x) == 1;
  bool sun = int(ow_exact_light.x) == 3;
  float sun_min = ow_exact_eps * length(p);  // a sun's ray must cross beyond this
  mat3 edges = transpose(mat3(e0, e1, e2));  // rows: the three edge normals
  vec3 n = v_plane.xyz;
  vec3 along0 = sphere ? view.a : ow_exact_frame[0];
  vec3 along1 = sphere ? view.b : ow_exact_frame[1];
  vec3 along2 = sphere ? view.w : (sun ? ow_exact_frame[2] : p);
  vec3 side0 = edges * along0;  // each edge's dot product with the three axes
  vec3 side1 = edges * along1;
  vec3 side2 = edges * along2;
  vec3 height = vec3(dot(n, along0), dot(n, along1), dot(n, along2));
  // Every segment crosses the triangle's plane in its span (ow_exact_soft_whole's umbra test
  // without the edges): then a cluster inside all three edge planes is blocked whole.
  bool crossing = ow_exact_crossing(p, h);
#ifdef OW_ALPHA
  crossing = false;  // a see-through triangle blocks a share of the points: each is looked up
#endif
  mat3 side_matrix = mat3(side0, side1, side2);  // weights -> the three edges' sides
  for (int w = 0; w * 32 < ow_exact_points; w++) {
    int count = min(32, ow_exact_points - 32 * w);
    uint all_points = ow_exact_word_points(w);
    ivec2 word_at = at + ivec2(0, w * rows);
    // Points other triangles blocked already need no test (a stale read only tests more).
    uint blocked = imageLoad(ow_hits, word_at).x;
    if ((blocked & all_points) == all_points) {
      continue;
    }
    uint word = 0u;
    for (int first = 0; first < count; first += OW_EXACT_SOFT_CLUSTER) {
      int last = min(count, first + OW_EXACT_SOFT_CLUSTER);
      uint span = uint(last - first);
      uint cluster_bits = ((span == 32u) ? 0xFFFFFFFFu : ((1u << span) - 1u)) << uint(first);
      if ((blocked & cluster_bits) == cluster_bits) {
        continue;
      }
      int decided = ow_exact_cluster((32 * w + first) / OW_EXACT_SOFT_CLUSTER, view, side_matrix, crossing);
      if (decided != 0) {
        word |= (decided > 0) ? cluster_bits : 0u;
        continue;
      }
      for (int j = first; j < last; j++) {
        if (((blocked >> uint(j)) & 1u) != 0u) {
          continue;
        }
        int k = 32 * w + j;
        vec4 pattern = ow_exact_pattern[k];
        vec3 weights;  // the segment (or its direction) in the axes along0..2
        vec2 polar = vec2(1.0, 0.0);
        if (sphere) {
          polar = ow_cap_polar(view, pattern);
          weights = vec3(polar.y * pattern.y, polar.y * pattern.z, polar.x);
        } else {
          weights = sun ? pattern.xyz : vec3(pattern.x, pattern.y, -1.0);
        }
        vec3 sides = weights.x * side0 + weights.y * side1 + weights.z * side2;
        if (all(greaterThanEqual(sides, vec3(0.0)))) {
          float along = dot(weights, height);  // n . seg, over t for a sphere
          float f = -h / (sphere ? along * ow_cap_distance(view, polar) : along);  // where the plane cuts it
          if (sun ? (f > sun_min) : (f > ow_exact_eps && f < 1.0)) {
#ifdef OW_ALPHA
            // A see-through crossing blocks the points whose fixed threshold its alpha passes:
            // a share alpha of them (thresholds a permutation of the points, so not the
            // spatial pattern); several such crossings count as the one of largest alpha.
            float alpha = ow_alpha_along(p + f * ow_light_segment(p, view, k));
            float threshold = (float((k * 37 + 11) % ow_exact_points) + 0.5) / float(ow_exact_points);
            if (alpha >= OW_OPAQUE_ALPHA || (alpha > OW_CLEAR_ALPHA && alpha > threshold)) {
              word |= 1u << uint(j);
            }
#else
            word |= 1u << uint(j);
#endif
          }
        }
      }
    }
    if (word != 0u) {
      imageAtomicOr(ow_hits, word_at, word);
    }
  }
}
#endif

#ifdef OW_EXACT
#ifndef OW_FIXED_KIND
// The exact pass over a spot's or sun's map (issue 27). Whether this triangle blocks the
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
#endif

#ifdef OW_EXACT
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

// One list entry: sample `at` (p light-centred) marked if this triangle blocks its light: a
// sized light's points (the soft variant's mark, above), a spot's or a sun's segment
// (ow_projective_blocks), or the segment to a point light.
void ow_exact_entry(ivec2 at, vec3 p)
{
#ifdef OW_EXACT_SOFT
  ow_exact_soft_mark(p, at, textureSize(ow_positions, 0).y);
  return;
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
#endif

void main()
{
#ifdef OW_EXACT
  ow_exact_walk();
  discard;
#endif
#ifndef OW_FIXED_KIND
  if (ow_projective != 0) {
    // As in depth.frag: the map's own depth; an inverted light (PSM) keeps the farthest.
    float z01 = (ow_map_inverted != 0) ? 1.0 - gl_FragCoord.z : gl_FragCoord.z;
#ifdef OW_VEIL
    ow_see_through(ow_alpha_at(v_uv), z01);
#endif
    gl_FragDepth = z01;
    ow_depth = z01;
    return;
  }
#endif
  vec2 uv = (gl_FragCoord.xy - ow_tile_origin) / ow_resolution;
#ifdef OW_NO_WARP
  vec2 xy = ow_map_inverse(ow_warp_rows, ow_warp_cols, ow_layer_slot, ow_warp_size, ow_crop, uv);
#else
  vec2 xy = (ow_warp_size > 0) ? texelFetch(ow_ray_table, ivec2(gl_FragCoord.xy), 0).xy
                               : ow_map_inverse(ow_warp_rows, ow_warp_cols, ow_layer_slot, 0, ow_crop, uv);
#endif
  vec3 dir = transpose(ow_layer_rot) * ow_unproject(ow_layer_kind, xy);
  if (dot(dir, v_edge0) < 0.0 || dot(dir, v_edge1) < 0.0 || dot(dir, v_edge2) < 0.0) {
    discard;  // the texel's ray passes beside the triangle
  }
  float t = v_plane.w / dot(v_plane.xyz, dir);
  if (!(t > 0.0)) {
    discard;  // grazing, in float32 rounding
  }
  float depth = clamp((t - ow_near) / (ow_far - ow_near), 0.0, 1.0);
#ifdef OW_VEIL
  ow_see_through(ow_alpha_along(dir), depth);
#endif
  gl_FragDepth = depth;
  ow_depth = depth;
}
