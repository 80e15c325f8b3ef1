// Paraboloid and cube-face projections; mirrors addon/core/projection.py.
// Layer-local frames have the layer axis along +Z. Map coordinates xy lie in [-1, 1]^2.
// The OW_KIND_* codes come from the host (shaders.SHARED_DEFINES).

#define OW_PI 3.14159265358979

// A program variant built for one layer kind (shaders.program_variant) defines
// OW_FIXED_KIND: the kind argument becomes a constant, so the compiler folds the other
// kinds' branches away instead of running them with masked lanes.
#ifdef OW_FIXED_KIND
#define OW_KIND(kind) OW_FIXED_KIND
#else
#define OW_KIND(kind) (kind)
#endif

// Brabec et al. 2002, eq. 3: the halfway vector scaled to z = 1 (stereographic projection).
vec2 ow_paraboloid_project(vec3 p)
{
  vec3 v = p / max(length(p), 1e-30);
  return v.xy / max(1.0 + v.z, 1e-30);
}

// Inverse stereographic projection: v = (2x, 2y, 1 - r^2) / (1 + r^2).
vec3 ow_paraboloid_unproject(vec2 xy)
{
  float r2 = dot(xy, xy);
  return vec3(2.0 * xy, 1.0 - r2) / (1.0 + r2);
}

vec2 ow_cube_project(vec3 p)
{
  return p.xy / max(p.z, 1e-30);
}

vec3 ow_cube_unproject(vec2 xy)
{
  return normalize(vec3(xy, 1.0));
}

// Sphere unfolding (Stockli Contreras et al., eq. 1): azimuthal equidistant about +Z,
// radius = angle from the pole / pi, so the whole sphere fills the unit disk.
vec2 ow_unfold_project(vec3 p)
{
  vec3 v = p / max(length(p), 1e-30);
  float rho = length(v.xy);
  float theta = atan(rho, v.z);
  return (rho > 1e-30) ? v.xy * (theta / (OW_PI * rho)) : vec2((v.z < 0.0) ? 1.0 : 0.0, 0.0);
}

vec3 ow_unfold_unproject(vec2 xy)
{
  float r = length(xy);
  float theta = OW_PI * r;
  float ratio = (r > 1e-30) ? sin(theta) / r : OW_PI;
  return vec3(xy * ratio, cos(theta));
}

vec2 ow_project(int kind, vec3 p)
{
  kind = OW_KIND(kind);
  if (kind == OW_KIND_UNFOLD) {
    return ow_unfold_project(p);
  }
  return (kind == OW_KIND_PARABOLOID) ? ow_paraboloid_project(p) : ow_cube_project(p);
}

vec3 ow_unproject(int kind, vec2 xy)
{
  kind = OW_KIND(kind);
  if (kind == OW_KIND_UNFOLD) {
    return ow_unfold_unproject(xy);
  }
  return (kind == OW_KIND_PARABOLOID) ? ow_paraboloid_unproject(xy) : ow_cube_unproject(xy);
}

// Upper bound of the angle one texel spans at map point xy (see texel_angle in projection.py).
float ow_texel_angle(int kind, vec2 xy, float resolution)
{
  kind = OW_KIND(kind);
  float r2 = dot(xy, xy);
  float step_xy = 2.0 / resolution;
  if (kind == OW_KIND_UNFOLD) {
    return OW_PI * step_xy;  // radially pi per unit radius; tangentially at most that
  }
  return (kind == OW_KIND_PARABOLOID) ? step_xy * 2.0 / (1.0 + r2) : step_xy / sqrt(1.0 + r2);
}
