// Reading a spot's or sun's map for the soft filter (lib/soft.glsl, shaders.soft_of): the
// shadow test's map (ow_map_matrix, lib/projective.glsl; looked up by shadow_test.frag's
// ow_map_texel) at world points, and its stored depths put back in the world.

// Along the line origin + s dir, the map's z01 is a ratio of two linear functions of s:
// the s where it equals a stored texel's z01 (under the hard test's rule, ow_depth_offset
// and the inverted PSM light included), so that a texel's blocker can be put back in the
// world, on whichever line through it the caller looks along.
float ow_map_line_depth(vec3 origin, vec3 dir, float stored)
{
  float z01 = stored + ow_depth_offset;
  float zs = ((ow_map_inverted != 0) ? 1.0 - z01 : z01) * 2.0 - 1.0;
  mat4 m = ow_map_matrix;
  vec4 c0 = m * vec4(origin, 1.0);
  vec4 c1 = m * vec4(dir, 0.0);
  float denom = c1.z - zs * c1.w;
  return (abs(denom) > 1e-30) ? (zs * c0.w - c0.z) / denom : 1e30;
}

// A spot's tap, in ow_point_tap's terms: the spot's map read along the light-centred
// direction d, its blocker's distance from the light along d, and the veil's light to
// distance `depth`.
vec2 ow_spot_tap(vec3 d, float depth)
{
  ivec2 texel;
  float z01;
  if (!ow_map_texel(d * depth, texel, z01)) {
    return vec2(1e30, 1.0);
  }
  float stored = texelFetch(ow_atlas, texel, 0).r;
  float light = 1.0;
#ifdef OW_VEIL
  light = ow_veil_light(texel, z01 - ow_depth_offset);
#endif
  return vec2((stored >= 1.0) ? 1e30 : ow_map_line_depth(vec3(0.0), d, stored), light);
}

