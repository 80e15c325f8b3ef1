// Exact soft shadows of a sized light (shaders.exact_soft_of): the irregular
// z-buffer samples the light per view sample. Each sample p (light-centred) sees N fixed
// points of the light; a triangle over p's texel marks, in N bits of the sample's words,
// the points whose segment from p it crosses (lib/exact_soft_mark.glsl), and the shadow test weighs
// the unmarked ones (shadow_test.frag). The same points and weights as the numpy oracle
// (tests/support/soft_oracle.py), which follows how Cycles samples the light:
// - a sphere (ow_exact_light.x OW_LIGHT_SPHERE, radius .y): its cap seen from p, uniform in solid
//   angle, each point weighted by the cosine at the receiver, and for a spot by its cone
//   (lib/spot_cone.glsl, ow_exact_spot);
// - an area light (OW_LIGHT_AREA; size .y by .z, outline .w: OW_OUTLINE_*, in the light's
//   frame ow_exact_frame): uniform over its surface, weighted by both cosines over the
//   squared distance, and by max(tan(spread / 2) - tan a, 0) at angle a from its normal
//   where its spread is below 180 degrees (ow_exact_spread not OW_NO_SPREAD);
// - a sun's disk (OW_LIGHT_SUN_DISK; half angle .y, its sine .z and tangent .w): directions towards it
//   (the frame's +Z) within the half angle, uniform in solid angle, each weighted by the
//   cosine at the receiver. Its "segment" is the unit direction: the ray goes on forever.
// Point k < ow_exact_points comes from the host's table ow_exact_pattern (render/soft.py,
// core/light_shape's fixed stratified pattern): for a sphere (u, cos phi, sin phi), the cap
// point of polar share u and azimuth phi; for an area light (x, y), its place in the light's
// frame, sizes included; for a sun (x, y, z), the direction in the light's frame.

#include "lib/spot_cone.glsl"

// The bits of word w that hold light points (all 32 but in a last, partial word).
uint ow_exact_word_points(int w)
{
  int left = ow_exact_points - 32 * w;
  return (left >= 32) ? 0xFFFFFFFFu : ((1u << uint(max(left, 0))) - 1u);
}

// What a sample needs to place its light points: a sphere's cap frame (towards the light,
// two axes across it) and the cap's extent; an area light needs nothing per sample.
struct OwLightView {
  vec3 w;
  vec3 a;
  vec3 b;
  float dist;
  float one_minus_cos;  // 1 - cos of the cap's half angle, kept precise for small lights
};

OwLightView ow_light_view(vec3 p)
{
  OwLightView view;
  view.dist = length(p);
  view.w = -p / max(view.dist, 1e-30);
  vec3 helper = (abs(view.w.z) < 0.9) ? vec3(0.0, 0.0, 1.0) : vec3(1.0, 0.0, 0.0);
  view.a = normalize(cross(view.w, helper));
  view.b = cross(view.w, view.a);
  float s = min(ow_exact_light.y / max(view.dist, 1e-30), 1.0);
  view.one_minus_cos = s * s / (1.0 + sqrt(max(1.0 - s * s, 0.0)));
  return view;
}

// The cap's polar angle of pattern entry `pattern` as seen from the sample: cos and sin.
vec2 ow_cap_polar(OwLightView view, vec4 pattern)
{
  float cos_t = 1.0 - pattern.x * view.one_minus_cos;
  return vec2(cos_t, sqrt(max(1.0 - cos_t * cos_t, 0.0)));
}

// The distance from the sample to the sphere's near side along a cap direction.
float ow_cap_distance(OwLightView view, vec2 polar)
{
  float r = ow_exact_light.y;
  float off = view.dist * polar.y;
  return view.dist * polar.x - sqrt(max(r * r - off * off, 0.0));
}

// The segment from p to light point k (p + segment lies on the light); a sun's direction.
vec3 ow_light_segment(vec3 p, OwLightView view, int k)
{
  vec4 pattern = ow_exact_pattern[k];
  if (int(ow_exact_light.x) == OW_LIGHT_SUN_DISK) {
    return ow_exact_frame * pattern.xyz;
  }
  if (int(ow_exact_light.x) == OW_LIGHT_SPHERE) {
    vec2 polar = ow_cap_polar(view, pattern);
    vec3 d = polar.y * (pattern.y * view.a + pattern.z * view.b) + polar.x * view.w;
    return ow_cap_distance(view, polar) * d;
  }
  return ow_exact_frame * vec3(pattern.xy, 0.0) - p;
}

// The weight of light point k's segment at a receiver of normal n (towards the light).
float ow_light_weight(vec3 segment, vec3 n)
{
  float len = length(segment);
  if (!(len > 0.0)) {
    return 0.0;
  }
  float cos_r = max(dot(segment, n), 0.0) / len;
  if (int(ow_exact_light.x) != OW_LIGHT_AREA) {
    // A spot's cone weighs what each point of its sphere sends the receiver (the light's -Z).
    return cos_r * ow_spot_cone_weight(-segment, -ow_exact_frame[2], ow_exact_spot);
  }
  // An area light emits along its -Z: the segment from the receiver meets it from below.
  float cos_e = max(dot(segment, ow_exact_frame[2]), 0.0) / len;
  float weight = cos_r * cos_e / (len * len);
  if (ow_exact_spread >= OW_NO_SPREAD_BELOW) {
    // A spread below 180 degrees (render/soft.py's spread_tangent): Cycles' soft-box grid.
    float tan_e = sqrt(max(1.0 - cos_e * cos_e, 0.0)) / max(cos_e, 1e-30);
    weight *= max(ow_exact_spread - tan_e, 0.0);
  }
  return weight;
}
