// Exact soft shadows of a sized light (shaders.exact_soft_of, issue 27): the irregular
// z-buffer samples the light per view sample. Each sample p (light-centred) sees N fixed
// points of the light; a triangle over p's texel marks, in N bits of the sample's words,
// the points whose segment from p it crosses (footprint.frag), and the shadow test weighs
// the unmarked ones (shadow_test.frag). The same points and weights as the numpy oracle
// (tests/support/soft_oracle.py), which follows how Cycles samples the light:
// - a sphere (ow_exact_light.x == 1, radius .y): its cap seen from p, uniform in solid
//   angle, each point weighted by the cosine at the receiver;
// - an area light (2; size .y by .z, outline .w: 0 rectangle, 1 ellipse, in the light's
//   frame ow_exact_frame): uniform over its surface, weighted by both cosines over the
//   squared distance.
// Points k < ow_exact_points come from one cell each of a square grid (shaders: N is a
// square), jittered by the R2 sequence, as core/light_shape.stratified_unit_square.

const float OW_R2 = 1.32471795724474602596;

// Point k of n in [0, 1)^2: one per cell of a cols x rows grid, cols = ceil(sqrt(n)).
vec2 ow_stratified(int k, int n)
{
  int cols = int(sqrt(float(n)));
  if (cols * cols < n) {
    cols += 1;
  }
  int rows = (n + cols - 1) / cols;
  vec2 jitter = fract(vec2(0.5) + float(k) * vec2(1.0 / OW_R2, 1.0 / (OW_R2 * OW_R2)));
  return (vec2(float(k % cols), float(k / cols)) + jitter) / vec2(float(cols), float(rows));
}

// Shirley and Chiu's concentric map of [0, 1)^2 onto the unit disk (light_shape.unit_disk).
vec2 ow_concentric(vec2 uv)
{
  vec2 a = 2.0 * uv - 1.0;
  if (a.x == 0.0 && a.y == 0.0) {
    return vec2(0.0);
  }
  const float quarter = 0.78539816339744830962;
  float r = (abs(a.x) > abs(a.y)) ? a.x : a.y;
  float phi = (abs(a.x) > abs(a.y)) ? quarter * (a.y / a.x) : 2.0 * quarter - quarter * (a.x / a.y);
  return r * vec2(cos(phi), sin(phi));
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

// The segment from p to light point k (p + segment lies on the light).
vec3 ow_light_segment(vec3 p, OwLightView view, int k)
{
  vec2 uv = ow_stratified(k, ow_exact_points);
  if (int(ow_exact_light.x) == 1) {
    float cos_t = 1.0 - uv.x * view.one_minus_cos;
    float sin_t = sqrt(max(1.0 - cos_t * cos_t, 0.0));
    float phi = 6.28318530717958647692 * uv.y;
    vec3 d = sin_t * (cos(phi) * view.a + sin(phi) * view.b) + cos_t * view.w;
    // The near side of the sphere along d: dist cos_t - sqrt(r^2 - (dist sin_t)^2).
    float r = ow_exact_light.y;
    float off = view.dist * sin_t;
    float t = view.dist * cos_t - sqrt(max(r * r - off * off, 0.0));
    return t * d;
  }
  vec2 xy = (ow_exact_light.w > 0.5) ? 0.5 * ow_concentric(uv) : uv - 0.5;
  vec3 q = ow_exact_frame * vec3(xy * ow_exact_light.yz, 0.0);
  return q - p;
}

// The weight of light point k's segment at a receiver of normal n (towards the light).
float ow_light_weight(vec3 segment, vec3 n)
{
  float len = length(segment);
  if (!(len > 0.0)) {
    return 0.0;
  }
  float cos_r = max(dot(segment, n), 0.0) / len;
  if (int(ow_exact_light.x) == 1) {
    return cos_r;
  }
  // An area light emits along its -Z: the segment from the receiver meets it from below.
  float cos_e = max(dot(segment, ow_exact_frame[2]), 0.0) / len;
  return cos_r * cos_e / (len * len);
}
