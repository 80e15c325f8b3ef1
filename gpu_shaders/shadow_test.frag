


// Shadow test: one fragment per view sample. Positions are light-centred world
// coordinates (w >= 1, the sample's importance weight, where the pixel hit geometry;
// 0 where it missed). Output: x = visibility
// (1 lit, 0 shadowed), y = flag (OW_FLAG_TESTED, OW_FLAG_NO_GEOMETRY, OW_FLAG_OUTSIDE the emission
// domain or at the light, OW_FLAG_NOT_DRAWN: its layer was not drawn; frame.FrameResult.flags).
#include "lib/projection.glsl"
#include "lib/layers.glsl"
#include "lib/mapping.glsl"
#include "lib/projective.glsl"
// Outside the variants' blocks: the loader includes a file once, preprocessor-blind, and both
// soft variants (lib/soft.glsl, lib/exact_soft.glsl) weigh a spot's cone with it.
#include "lib/spot_cone.glsl"
// The same for the media's helpers: the haze variant and the exact soft media variant read them.
#include "lib/media.glsl"
#ifdef OW_VEIL
#include "lib/veil.glsl"
#endif
#ifdef OW_HAZE
#include "lib/haze.glsl"
#endif
#ifdef OW_GRIDS
#include "lib/grids.glsl"
#endif

// A spot's or sun's map (sm, psm) at a light-centred point: its z01 (the map's depth, PSM's
// inverted light turned round), and the atlas texel holding it, or false outside the map.
float ow_map_z01(vec3 x, out vec2 uv, out float w)
{
  vec3 uvz = ow_projective_uvz(ow_map_matrix, x, w);
  uv = uvz.xy;
  return (ow_map_inverted != 0) ? 1.0 - uvz.z : uvz.z;
}

bool ow_map_texel(vec3 x, out ivec2 texel, out float z01)
{
  vec2 uv;
  float w;
  z01 = ow_map_z01(x, uv, w);
  texel = ivec2(0);
  if (!(w > 0.0) || any(lessThan(uv, vec2(0.0))) || any(greaterThan(uv, vec2(1.0)))) {
    return false;
  }
  int res = int(ow_resolution);
  texel = clamp(ivec2(floor(uv * ow_resolution)), ivec2(0), ivec2(res - 1)) + ivec2(ow_layer_tile[0].xy);
  return true;
}

#ifdef OW_SOFT
#include "lib/soft_map.glsl"

// One light-centred direction d looked up in the layer that holds it, as the test below
// reads its own: the map's distance from the light (1e30 where nothing was drawn, outside
// the hemisphere, the drawn layers or the cleared box) and the light the veil lets
// through to distance `depth` (lib/soft.glsl's taps).
vec2 ow_point_tap(vec3 d, float depth)
{
#ifndef OW_FIXED_KIND
  if (ow_projective != 0) {
    return ow_spot_tap(d, depth);  // a spot's map (lib/soft_map.glsl)
  }
#endif
  vec3 ld = ow_light_rot * d;
  if (ow_hemi != 0 && ld.z >= 0.0) {
    return vec2(1e30, 1.0);
  }
  int slot = ow_pick_slot(ow_param, ld);
  vec4 tile = ow_layer_tile[slot];
  if (tile.z < 0.5) {
    return vec2(1e30, 1.0);
  }
  vec2 xy = ow_project(ow_layer_kind, ow_layer_rot[slot] * d);
  float magnification;
  vec2 uv = ow_map_forward(ow_warp_rows, ow_warp_cols, slot, ow_warp_size, ow_layer_crop[slot], xy,
                           magnification);
  int res = int(ow_resolution);
  ivec2 texel = clamp(ivec2(floor(uv * ow_resolution)), ivec2(0), ivec2(res - 1));
  vec4 box = ow_layer_box[slot];
  if (any(lessThan(vec2(texel), box.xy)) || any(greaterThanEqual(vec2(texel), box.zw))) {
    return vec2(1e30, 1.0);
  }
  float stored = texelFetch(ow_atlas, texel + ivec2(tile.xy), 0).r;
  float light = 1.0;
#ifdef OW_VEIL
  light = ow_veil_light(texel + ivec2(tile.xy), (depth - ow_near) / (ow_far - ow_near));
#endif
  return vec2((stored >= 1.0) ? 1e30 : ow_near + stored * (ow_far - ow_near), light);
}
#include "lib/soft.glsl"
#endif

// Spot and sun maps (sm, psm). Same bias rule as the point-light maps, in world
// space: a normal offset and a move towards the light, in texel footprints; then the
// constant depth offset of the map (perspective.py).
vec2 ow_projective_test(vec3 p, vec3 n)
{
  float dist = length(p);
  vec3 dir = p / max(dist, 1e-30);
  if (ow_sun == 0 && !(dot(dir, ow_light_axis) >= ow_spot_cos)) {
    return vec2(0.0, OW_FLAG_OUTSIDE);  // outside the spot cone (or at the light)
  }
  vec3 to_light = (ow_sun != 0) ? -ow_light_axis : -dir;
  float cos_i = dot(n, to_light);
  if (cos_i < 0.0) {
    n = -n;
    cos_i = -cos_i;
  }
  float footprint = ow_projective_footprint(ow_map_matrix, p, ow_resolution);
  float tan_i = sqrt(max(1.0 - cos_i * cos_i, 0.0)) / max(cos_i, 0.05);
  vec3 q = p + n * (ow_bias_normal * footprint)
           + to_light * (footprint * (ow_bias_const + ow_bias_slope * min(tan_i, 20.0)));
  ivec2 texel;
  float z01;
  if (!ow_map_texel(q, texel, z01)) {
    return vec2(1.0, OW_FLAG_NOT_DRAWN);  // outside the map: the plan fits the map to every view sample
  }
  float stored = texelFetch(ow_atlas, texel, 0).r;
  // A cleared texel (1.0: nothing drawn) is empty, even for a receiver beyond the
  // occluders' far plane (one that casts no shadow itself, see shadow_rule.py).
  float visibility = (stored >= 1.0 || z01 - ow_depth_offset <= stored) ? 1.0 : 0.0;
#ifdef OW_VEIL
  if (visibility > 0.0) {
    visibility *= ow_veil_light(texel, z01 - ow_depth_offset);
  }
#endif
#ifdef OW_SOFT
  // A sized spot or sun: the share of the light the receiver sees (lib/soft.glsl), with the
  // hard test's offsets as one world bias at the receiver.
  float bias = footprint * (ow_bias_const + ow_bias_normal + ow_bias_slope * min(tan_i, 20.0));
  visibility = (ow_sun != 0) ? ow_sun_soft_visibility(p, n, bias, visibility)
                             : ow_soft_visibility(p, n, bias, visibility);
#endif
#ifdef OW_HAZE
  // Through the media along the texel's ray: a spot's distance, a sun's place on its axis
  // (footprint_medium.frag).
  float u = (ow_sun != 0) ? dot(p, ow_light_axis) + ow_media_offset : dist;
  visibility *= ow_media_light_kept(ow_haze_depth(texel, u));
#endif
  return vec2(visibility, OW_FLAG_TESTED);
}


#ifdef OW_EXACT_SOFT
#include "lib/exact_soft.glsl"

// The exact pass's answer for a sized light: the weighted share of the light points it left
// unmarked in this sample's words (n towards the light); the plain share where no point
// weighs (a receiver grazed by the whole light).
float ow_exact_soft_surfaces(vec3 p, vec3 n, ivec2 pix, int rows)
{
  // Most samples are wholly lit or wholly shadowed: then the share is 1 or 0 whatever the
  // weights, and only a penumbra's samples weigh their points.
  uint words[OW_EXACT_SOFT_MAX_POINTS / 32];
  uint any_blocked = 0u;
  uint all_blocked = 0xFFFFFFFFu;
  for (int w = 0; w * 32 < ow_exact_points; w++) {
    uint valid = ow_exact_word_points(w);
    words[w] = imageLoad(ow_hits, pix + ivec2(0, w * rows)).x & valid;
    any_blocked |= words[w];
    all_blocked &= words[w] | ~valid;
  }
  if (any_blocked == 0u) {
    return 1.0;
  }
  if (all_blocked == 0xFFFFFFFFu) {
    return 0.0;
  }
  OwLightView view = ow_light_view(p);
  float lit = 0.0;
  float total = 0.0;
  int open = 0;
  for (int k = 0; k < ow_exact_points; k++) {
    float weight = ow_light_weight(ow_light_segment(p, view, k), n);
    bool blocked = ((words[k >> 5] >> uint(k & 31)) & 1u) != 0u;
    total += weight;
    if (!blocked) {
      lit += weight;
      open++;
    }
  }
  return (total > 0.0) ? lit / total : float(open) / float(ow_exact_points);
}

#ifdef OW_EXACT_SOFT_MEDIA
// The light the media keep along the segments of the light points the exact pass followed
// through them (lib/media.glsl's ow_media_point), weighed as the surfaces''
// points are and over those the surfaces leave open: the surfaces' share times this is the
// weighted mean over the light of what both let through, however a penumbra of surfaces
// and one of media overlap. `len`: the segment's length, for the media around the light.
float ow_exact_soft_media(vec3 p, vec3 n, ivec2 pix, ivec2 size)
{
  OwLightView view = ow_light_view(p);
  bool sun = int(ow_exact_light.x) == OW_LIGHT_SUN_DISK;
  float kept_open = 0.0, weight_open = 0.0, kept_all = 0.0, weight_all = 0.0, plain = 0.0;
  for (int j = 0; j < ow_media_points; j++) {
    int k = ow_media_point(j);
    vec3 segment = ow_light_segment(p, view, k);
    float kept = ow_media_light_kept(ow_media_depth(pix, size, j) + ow_media_light * (sun ? length(p) : length(segment)));
    float weight = ow_light_weight(segment, n);
    bool blocked = ((imageLoad(ow_hits, pix + ivec2(0, (k >> 5) * size.y)).x >> uint(k & 31)) & 1u) != 0u;
    plain += kept;
    kept_all += weight * kept;
    weight_all += weight;
    if (!blocked) {
      kept_open += weight * kept;
      weight_open += weight;
    }
  }
  if (weight_open > 0.0) {
    return kept_open / weight_open;
  }
  return (weight_all > 0.0) ? kept_all / weight_all : plain / float(max(ow_media_points, 1));
}
#endif

float ow_exact_soft_share(vec3 p, vec3 n, ivec2 pix)
{
  ivec2 size = textureSize(ow_positions, 0);
  float share = ow_exact_soft_surfaces(p, n, pix, size.y);
#ifdef OW_EXACT_SOFT_MEDIA
  if (share > 0.0) {
    share *= ow_exact_soft_media(p, n, pix, size);
  }
#endif
  return share;
}
#endif

void ow_test_sample()
{
  ivec2 pix = ivec2(gl_FragCoord.xy);
  vec4 pw = texelFetch(ow_positions, pix, 0);
  if (pw.w < 0.5) {
    ow_result = vec2(0.0, OW_FLAG_NO_GEOMETRY);
    return;
  }
  vec3 p = pw.xyz;
  vec3 n = texelFetch(ow_normals, pix, 0).xyz;
  // A paraboloid or cube variant is never projective.
#ifndef OW_FIXED_KIND
  if (ow_projective != 0) {
    ow_result = ow_projective_test(p, n);
#ifdef OW_EXACT_SOFT
    // A sized spot's or sun's exact pass: its marks weighed, the normal towards the light.
    // Its atlas holds no depth, so only the cone decides (OW_FLAG_OUTSIDE); a sample whose biased
    // lookup fell off the map's edge (OW_FLAG_NOT_DRAWN) is in the lists all the same.
    if (ow_result.y != OW_FLAG_OUTSIDE) {
      vec3 to_light = (ow_sun != 0) ? -ow_light_axis : -p;
      ow_result = vec2(ow_exact_soft_share(p, (dot(n, to_light) < 0.0) ? -n : n, pix), OW_FLAG_TESTED);
    }
#endif
    return;
  }
#endif
  float dist = length(p);
  if (!(dist > 0.0)) {
    ow_result = vec2(1.0, OW_FLAG_OUTSIDE);
    return;
  }
  vec3 dir = p / dist;
  float cos_i = dot(n, -dir);
  if (cos_i < 0.0) {
    n = -n;  // offset towards the side the light sees
    cos_i = -cos_i;
  }
  vec3 ldir = ow_light_rot * dir;
  if (ow_hemi != 0 && ldir.z >= 0.0) {
    ow_result = vec2(0.0, OW_FLAG_OUTSIDE);
    return;
  }
  int slot = ow_pick_slot(ow_param, ldir);
  mat3 layer_rot = ow_layer_rot[slot];
  vec2 xy = ow_project(ow_layer_kind, layer_rot * dir);
  mat2 jacobian;
  ow_map_forward_jacobian(ow_warp_rows, ow_warp_cols, slot, ow_warp_size, ow_layer_crop[slot], xy, jacobian);
  float texel_size = dist * ow_texel_angle(ow_layer_kind, xy, ow_resolution);  // plain-map texel, world units
  // One texel of this (cropped, warped) map seen from the light, at the sample, at its
  // widest: the constant bias.
  float footprint = texel_size / max(ow_min_singular(jacobian), 1e-30);
  // The surface's depth changes along g, the map image of the normal's part across
  // the ray, and the normal offset moves the lookup along g. So the offset and the
  // slope bias need the texel's width along g only (ow_texel_reach; equal to the
  // footprint on plain maps): a warp that compresses across g no longer inflates them.
  // g by a finite difference of the exact projection, 1e-3 rad along that part.
  float footprint_along = footprint;
  vec3 across = n + cos_i * dir;
  float across_len = length(across);
  if (across_len > 1e-4) {
    vec2 g = ow_project(ow_layer_kind, layer_rot * normalize(dir + across * (1e-3 / across_len))) - xy;
    float g_len = length(g);
    if (g_len > 0.0) {
      footprint_along = texel_size * ow_texel_reach(jacobian, g / g_len);
    }
  }

  // Normal offset (in texel widths along g), then project the moved point exactly
  // per pixel (Osman et al.): never interpolate map coordinates.
  vec3 q = p + n * (ow_bias_normal * footprint_along);
  float qdist = length(q);
  vec3 qdir = q / qdist;
  vec3 qldir = ow_light_rot * qdir;
  if (ow_hemi != 0 && qldir.z >= 0.0) {
    q = p;
    qdist = dist;
    qdir = dir;
    qldir = ldir;
  }
  slot = ow_pick_slot(ow_param, qldir);
  vec4 tile = ow_layer_tile[slot];
  if (tile.z < 0.5) {
    ow_result = vec2(1.0, OW_FLAG_NOT_DRAWN);
    return;
  }
  xy = ow_project(ow_layer_kind, ow_layer_rot[slot] * qdir);
  int res = int(ow_resolution);
  float magnification;
  vec2 uv = ow_map_forward(ow_warp_rows, ow_warp_cols, slot, ow_warp_size, ow_layer_crop[slot], xy,
                           magnification);
  ivec2 texel = clamp(ivec2(floor(uv * ow_resolution)), ivec2(0), ivec2(res - 1));
  vec4 box = ow_layer_box[slot];  // texels (x0, y0, x1, y1) cleared and drawn this frame
  if (any(lessThan(vec2(texel), box.xy)) || any(greaterThanEqual(vec2(texel), box.zw))) {
    ow_result = vec2(1.0, OW_FLAG_TESTED);  // outside: empty, as a cleared texel would be (lit)
#ifdef OW_EXACT_SOFT
    ow_result.x = ow_exact_soft_share(p, n, pix);
#endif
    return;
  }
  float stored = texelFetch(ow_atlas, texel + ivec2(tile.xy), 0).r;
  float t_map = ow_near + stored * (ow_far - ow_near);
  float tan_i = sqrt(max(1.0 - cos_i * cos_i, 0.0)) / max(cos_i, 0.05);
  float bias = footprint * ow_bias_const + footprint_along * ow_bias_slope * min(tan_i, 20.0);
  // The range [near, far] bounds the occluders only; a receiver that blocks nothing
  // (visible_shadow off, shadow linking) may lie beyond far. A cleared texel (1.0:
  // nothing drawn; drawn depths stay below it, projection.depth_range) is empty.
  float visibility = (stored >= 1.0 || qdist - bias <= t_map) ? 1.0 : 0.0;
#ifdef OW_VEIL
  if (visibility > 0.0) {
    // Through the see-through surfaces in front, under the same bias (lib/veil.glsl).
    visibility *= ow_veil_light(texel + ivec2(tile.xy), (qdist - bias - ow_near) / (ow_far - ow_near));
  }
#endif
  if (ow_edge_radius > 0 && visibility > 0.5) {
    // Edge-distance antialiasing (dual sphere-unfolding paper): a lit sample z texels
    // (Manhattan) from a nearer occluder's edge is dimmed, down to just above one half
    // next to it, so the binary lit/shadowed call never changes, only its softness.
    float z = texelFetch(ow_edges, texel + ivec2(tile.xy), 0).r;
    visibility = 0.5 + 0.5 * z / float(ow_edge_radius + 1);
  }
#ifdef OW_SOFT
  // A sized light: the share of the light the receiver sees, around the hard answer.
  visibility = ow_soft_visibility(p, n, bias, visibility);
#endif
#ifdef OW_EXACT_SOFT
  // The exact pass of a sized light (its atlas holds no depth, so the test above lit it).
  visibility *= ow_exact_soft_share(p, n, pix);
#endif
#ifdef OW_HAZE
  // Through the media between the light and the receiver, along the texel's ray (a sized
  // light's too: its centre's).
  visibility *= ow_media_light_kept(ow_haze_depth(texel + ivec2(tile.xy), dist));
#endif
  ow_result = vec2(visibility, OW_FLAG_TESTED);
}

// The test, then with OW_GRIDS (shaders.grids_of) the light the density grids let through
// along the sample's segment (lib/grids.glsl), for every method alike.
void main()
{
  ow_test_sample();
#ifdef OW_GRIDS
  if (ow_result.y == OW_FLAG_TESTED && ow_result.x > 0.0) {
    ow_result.x *= ow_grid_kept(texelFetch(ow_positions, ivec2(gl_FragCoord.xy), 0).xyz);
  }
#endif
}
