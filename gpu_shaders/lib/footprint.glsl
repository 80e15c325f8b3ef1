// Footprints of a triangle's curved image, and the exact inside test: the GLSL of
// addon/core/footprint.py (its docstring has the derivations). Light-centred vertices
// in a layer's local frame (axis along +Z). A box is (x0, x1, y0, y1) in projection
// coordinates; an empty one has x0 > x1.
//
// In float32 the boxes match the float64 ones to 1e-4 map units, except where a
// vertex lies within about 1e-4 of the light and the triangle is clipped at the seam:
// the crossing point's direction is then good to about 1e-3. A depth pass built on
// these boxes must dilate them by a texel (tests/gl/test_footprint_glsl.py). Not yet
// used by a program: the GPU-resident depth pass of issue 17 will include it.

const vec4 OW_EMPTY_BOX = vec4(1.0, -1.0, 1.0, -1.0);
// A triangle whose |det(v0, v1, v2)| is below this share of |v0| |v1| |v2| is seen
// edge-on (the numpy side uses 1e-12; float32 needs a wider margin).
const float OW_EDGE_ON = 1e-6;

// Edge-plane normals n_i = v_i x v_{i+1}; returns det's sign, 0 for a triangle seen edge-on.
float ow_edge_planes(vec3 v0, vec3 v1, vec3 v2, out vec3 n0, out vec3 n1, out vec3 n2)
{
  n0 = cross(v0, v1);
  n1 = cross(v1, v2);
  n2 = cross(v2, v0);
  float det = dot(n0, v2);
  float scale = length(v0) * length(v1) * length(v2);
  return (abs(det) > OW_EDGE_ON * scale) ? sign(det) : 0.0;
}

// The ray direction d lies inside the triangle's three edge planes (and not behind the light).
bool ow_inside(vec3 d, vec3 n0, vec3 n1, vec3 n2, float orientation)
{
  return orientation != 0.0 && dot(d, n0) * orientation >= 0.0 && dot(d, n1) * orientation >= 0.0
      && dot(d, n2) * orientation >= 0.0;
}

// The part of the triangle with z >= z_min: up to four vertices (Sutherland-Hodgman).
int ow_clip_z(vec3 v0, vec3 v1, vec3 v2, float z_min, out vec3 p[4])
{
  vec3 v[3] = vec3[3](v0, v1, v2);
  int count = 0;
  for (int i = 0; i < 3; i++) {
    vec3 a = v[i];
    vec3 b = v[(i + 1) % 3];
    bool a_in = a.z >= z_min;
    bool b_in = b.z >= z_min;
    if (a_in && count < 4) {
      p[count++] = a;
    }
    if (a_in != b_in && count < 4) {
      p[count++] = mix(a, b, (z_min - a.z) / (b.z - a.z));
    }
  }
  for (int i = count; i < 4; i++) {
    p[i] = vec3(0.0);
  }
  return count;
}

vec2 ow_stereographic(vec3 v)
{
  vec3 u = normalize(v);
  return u.xy / max(1.0 + u.z, 1e-30);
}

void ow_box_add(vec2 xy, inout vec4 box)
{
  xy = clamp(xy, vec2(-1.0), vec2(1.0));  // z >= 0: the unit disk, up to rounding
  box = vec4(min(box.x, xy.x), max(box.y, xy.x), min(box.z, xy.y), max(box.w, xy.y));
}

// Grow `box` by the paraboloid x and y extremes inside the minor arc from a to b.
void ow_arc_extend(vec3 a, vec3 b, inout vec4 box)
{
  a = normalize(a);
  b = normalize(b);
  vec3 e = b - dot(a, b) * a;
  float len = length(e);
  if (len < 1e-12) {
    return;
  }
  e /= len;
  float span = atan(len, dot(a, b));
  for (int k = 0; k < 2; k++) {
    float radius = length(vec2(e[k], a[k]));
    float rhs = a[k] * e.z - e[k] * a.z;
    if (radius < 1e-12 || abs(rhs) > radius) {
      continue;
    }
    float phase = atan(a[k], e[k]);  // e_k cos t - a_k sin t = radius cos(t + phase)
    float base = acos(clamp(rhs / radius, -1.0, 1.0));
    for (int s = 0; s < 2; s++) {
      float t = (s == 0 ? base : -base) - phase;
      t = mod(t, 6.28318530717958647692);
      if (t > 0.0 && t < span) {
        ow_box_add(ow_stereographic(cos(t) * a + sin(t) * e), box);
      }
    }
  }
}

// Box of the triangle's image in a paraboloid layer (its part with z >= 0).
vec4 ow_paraboloid_box(vec3 v0, vec3 v1, vec3 v2)
{
  vec3 p[4];
  int count = ow_clip_z(v0, v1, v2, 0.0, p);
  if (count < 3) {
    return OW_EMPTY_BOX;
  }
  vec4 box = vec4(1e30, -1e30, 1e30, -1e30);
  for (int i = 0; i < 4; i++) {
    if (i >= count) {
      break;
    }
    vec3 q = p[(i + 1) % count];
    if (length(p[i]) > 0.0) {
      ow_box_add(ow_stereographic(p[i]), box);
      ow_arc_extend(p[i], q, box);
    }
  }
  return box;
}

// Box of the triangle's image on a cube face (its part with z >= near), clamped to the face.
vec4 ow_cube_box(vec3 v0, vec3 v1, vec3 v2, float near)
{
  vec3 p[4];
  int count = ow_clip_z(v0, v1, v2, near, p);
  if (count < 3) {
    return OW_EMPTY_BOX;
  }
  vec4 box = vec4(1e30, -1e30, 1e30, -1e30);
  for (int i = 0; i < 4; i++) {
    if (i < count) {
      ow_box_add(p[i].xy / p[i].z, box);
    }
  }
  return box;
}
