// Paraboloid and cube-face projections; mirrors addon/core/projection.py.
// Layer-local frames have the layer axis along +Z. Map coordinates xy lie in [-1, 1]^2.

#define OW_KIND_PARABOLOID 0
#define OW_KIND_CUBE 1

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

vec2 ow_project(int kind, vec3 p)
{
  return (kind == OW_KIND_PARABOLOID) ? ow_paraboloid_project(p) : ow_cube_project(p);
}

vec3 ow_unproject(int kind, vec2 xy)
{
  return (kind == OW_KIND_PARABOLOID) ? ow_paraboloid_unproject(xy) : ow_cube_unproject(xy);
}

// Upper bound of the angle one texel spans at map point xy (see texel_angle in projection.py).
float ow_texel_angle(int kind, vec2 xy, float resolution)
{
  float r2 = dot(xy, xy);
  float step_xy = 2.0 / resolution;
  return (kind == OW_KIND_PARABOLOID) ? step_xy * 2.0 / (1.0 + r2) : step_xy / sqrt(1.0 + r2);
}
