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

#ifdef OW_EXACT
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
    vec3 p = texelFetch(ow_positions, at, 0).xyz;  // light-centred
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
#ifdef OW_ALPHA
        // A see-through crossing: its optical depth, summed in any order (core/alpha.py).
        float alpha = ow_alpha_along(p);
        if (alpha >= OW_OPAQUE_ALPHA) {
          imageAtomicOr(ow_hits, at, OW_HIT_OPAQUE);
        } else if (alpha > OW_CLEAR_ALPHA) {
          imageAtomicAdd(ow_hits, at, uint(-log(1.0 - alpha) * OW_OPTICAL_SCALE + 0.5));
        }
#else
        imageAtomicOr(ow_hits, at, OW_HIT_OPAQUE);
#endif
      }
    }
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

// This texel's list walked, as ow_exact_walk walks it (the bound, the rounds, the counting
// variant), testing each sample with ow_projective_blocks.
void ow_exact_walk_projective()
{
  ivec2 texel = ivec2(gl_FragCoord.xy - ow_tile_origin);
  int res = int(ow_resolution);
  uint node = imageLoad(ow_counts, texel + ivec2(ow_exact_tile * res, 0)).x;
  int width = textureSize(ow_positions, 0).x;
  int step = 0;
  for (; step < ow_exact_bound && node != 0u; step++) {
    int index = int(node) - 1;
    ivec2 at = ivec2(index % width, index / width);
    vec3 p = ow_exact_lift(texelFetch(ow_positions, at, 0).xyz, texelFetch(ow_normals, at, 0).xyz);
    vec3 sides;
    if (ow_projective_blocks(p, sides)) {
      ow_exact_mark(at, sides);
    }
    node = imageLoad(ow_next, at).x;
  }
  if (node != 0u) {
    imageAtomicAdd(ow_work, ivec2(OW_WORK_CUT, 0), 1u);
  }
#ifdef OW_EXACT_COUNT
  imageAtomicAdd(ow_work, ivec2(OW_WORK_ENTRIES, 0), uint(step));
  imageAtomicAdd(ow_work, ivec2(OW_WORK_FRAGMENTS, 0), 1u);
#endif
}
#endif
#endif

void main()
{
#ifdef OW_EXACT
#ifndef OW_FIXED_KIND
  if (ow_projective != 0) {
    ow_exact_walk_projective();
    discard;
  }
#endif
#endif
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
