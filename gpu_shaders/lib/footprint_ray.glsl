// The footprint depth pass's coverage and depth at the texel centre (footprint.frag,
// footprint_alpha.frag). The centre goes back through the warp and crop to its own ray:
// read from the layer's ray table (ray_table.frag, the exact inverse) when warped, computed
// when not; the triangle covers the texel when that ray lies inside its three edge planes
// (lib/footprint.glsl's inside test), and the depth is where the ray meets the triangle's
// plane. Nothing is tessellated, so this holds however large the triangle and however
// curved its image.
#include "lib/projection.glsl"
#include "lib/mapping.glsl"

#ifndef OW_FIXED_KIND
// A spot's or sun's map: as in depth.frag, the map's own depth; an inverted light (PSM)
// keeps the farthest.
float ow_projective_z01()
{
  return (ow_map_inverted != 0) ? 1.0 - gl_FragCoord.z : gl_FragCoord.z;
}
#endif

// The light-centred direction of this texel's centre.
vec3 ow_texel_ray()
{
  vec2 uv = (gl_FragCoord.xy - ow_tile_origin) / ow_resolution;
#ifdef OW_NO_WARP
  vec2 xy = ow_map_inverse(ow_warp_rows, ow_warp_cols, ow_layer_slot, ow_warp_size, ow_crop, uv);
#else
  vec2 xy = (ow_warp_size > 0) ? texelFetch(ow_ray_table, ivec2(gl_FragCoord.xy), 0).xy
                               : ow_map_inverse(ow_warp_rows, ow_warp_cols, ow_layer_slot, 0, ow_crop, uv);
#endif
  return transpose(ow_layer_rot) * ow_unproject(ow_layer_kind, xy);
}

// The normalised depth where the ray `dir` meets the triangle; the fragment is discarded
// where the ray passes beside it.
float ow_footprint_depth(vec3 dir)
{
  if (dot(dir, v_edge0) < 0.0 || dot(dir, v_edge1) < 0.0 || dot(dir, v_edge2) < 0.0) {
    discard;  // the texel's ray passes beside the triangle
  }
  float t = v_plane.w / dot(v_plane.xyz, dir);
  if (!(t > 0.0)) {
    discard;  // grazing, in float32 rounding
  }
  return clamp((t - ow_near) / (ow_far - ow_near), 0.0, 1.0);
}

#ifdef OW_PIECES
#include "lib/piece_fragment.glsl"

// A piece's normalised depth at this texel (OW_PIECES): where the texel's ray leaves it
// (lib/blockers.glsl's ow_piece_span); the fragment is discarded where the ray passes
// beside it. The far side, not the near one (second-depth shadow maps, Wang and Molnar
// 1994): a point on a strand or a point cloud's sphere is never shadowed by its own
// primitive in Cycles, and a point on the far side faces away from the light. A layer's
// ray runs from the light to twice the far distance; a spot's from the light through the
// map's far plane, a sun's from the map's near plane to its far one, and the depth is the
// map's own there (an inverted PSM's kept farthest, as ow_projective_z01 keeps it). A ray
// that meets the piece only where Cycles draws nothing (past a curve's end plane, beside a
// ribbon's end: lib/piece_fragment.glsl) passes it.

float ow_piece_depth()
{
  vec3 a = v_piece_a.xyz;
  vec3 b = v_piece_b.xyz;
#ifndef OW_FIXED_KIND
  if (ow_projective != 0) {
    vec2 ndc = (gl_FragCoord.xy - ow_tile_origin) / ow_resolution * 2.0 - 1.0;
    mat4 to_light = inverse(ow_map_matrix);
    vec4 near_point = to_light * vec4(ndc, -1.0, 1.0);
    vec4 far_point = to_light * vec4(ndc, 1.0, 1.0);
    vec3 p1 = far_point.xyz / far_point.w;
    vec3 p0 = (ow_sun != 0) ? near_point.xyz / near_point.w : vec3(0.0);
    vec2 span = ow_piece_span(p0, p1, a, b, v_piece_a.w, v_piece_b.w);
    if (span.x < 0.0 || !ow_piece_blocks(p0, p1 - p0, 0.0)) {
      discard;
    }
    vec4 clip = ow_map_matrix * vec4(mix(p0, p1, span.y), 1.0);
    if (!(clip.w > 0.0)) {
      discard;
    }
    float z01 = clamp(clip.z / clip.w * 0.5 + 0.5, 0.0, 1.0);
    return (ow_map_inverted != 0) ? 1.0 - z01 : z01;
  }
#endif
  vec3 dir = normalize(ow_texel_ray());
  float reach = 2.0 * ow_far;
  vec2 span = ow_piece_span(vec3(0.0), dir * reach, a, b, v_piece_a.w, v_piece_b.w);
  if (span.x < 0.0 || !ow_piece_blocks(vec3(0.0), dir * reach, 0.0)) {
    discard;
  }
  return clamp((span.y * reach - ow_near) / (ow_far - ow_near), 0.0, 1.0);
}
#endif
