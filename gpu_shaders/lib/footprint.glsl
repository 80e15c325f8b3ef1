// Footprints of a triangle's curved image, and the exact inside test: the GLSL of
// addon/core/footprint.py (its docstring has the derivations). Light-centred vertices
// in a layer's local frame (axis along +Z). A box is (x0, x1, y0, y1) in projection
// coordinates; an empty one has x0 > x1.
//
// In float32 the boxes match the float64 ones to 1e-4 map units, except where a
// vertex lies within about 1e-4 of the light and the triangle is clipped at the seam:
// the crossing point's direction is then good to about 1e-3. A depth pass built on
// these boxes must dilate them by a texel (tests/gl/test_footprint_glsl.py); the
// footprint depth pass (footprint.vert) does.

#include "lib/warp.glsl"
#include "lib/edges.glsl"

const vec4 OW_EMPTY_BOX = vec4(1.0, -1.0, 1.0, -1.0);
// A triangle is seen edge-on when its plane passes within max(OW_EDGE_ON |v0|, distance)
// of the light: |det(v0, v1, v2)| <= that times |(v1 - v0) x (v2 - v0)|. The determinant is
// formed from the edge vectors, whose float32 rounding is relative to the triangle's own
// size, so a tiny triangle far from the light keeps its orientation (the numpy side uses
// 1e-12 for the relative part; float32 needs a wider margin). `distance` is the scene's
// own tolerance (1e-9 of the depth range's far end, as the host's sanitiser had it): a
// vertex placed "at" the light lands within rounding of it, and must not then cover half
// the sphere. OW_EDGE_ON comes from the host (shaders.SHARED_DEFINES).

// Edge-plane normals n_i = v_i x v_{i+1}; returns det's sign, 0 for a triangle seen edge-on.
// A neighbour computes its shared edge's normal from the same two vertices, so the two
// inside tests split the rays along that edge without a gap.
float ow_edge_planes(vec3 v0, vec3 v1, vec3 v2, float distance, out vec3 n0, out vec3 n1, out vec3 n2)
{
  n0 = cross(v0, v1);
  n1 = cross(v1, v2);
  n2 = cross(v2, v0);
  vec3 normal = cross(v1 - v0, v2 - v0);
  float det = dot(v0, normal);
  return (abs(det) > max(OW_EDGE_ON * length(v0), distance) * length(normal)) ? sign(det) : 0.0;
}

// The exact pass's edge plane through the light and the edge (a, b): a normal (a x b, as
// ow_edge_planes gives it) and a point `at` on the plane, so that a sample p's side is
// dot(p - at, normal). For p near the edge, a sample just beside an occluder, that keeps
// the precision the plain dot(p, a x b) loses in float32 when the edge subtends a small
// angle (8e-6 of 10 units on stress_million, against a true margin of 1.3e-6).
// The vertices are taken in one order whichever triangle asks, so a neighbour sharing the
// edge gets the same numbers negated, and the two tests still split the samples without
// a gap.
void ow_relative_edge(vec3 a, vec3 b, out vec3 normal, out vec3 at)
{
  bool swap = ow_edge_swapped(a, b);
  vec3 lo = swap ? b : a;
  vec3 hi = swap ? a : b;
  precise vec3 n = cross(lo, hi - lo);
  normal = swap ? -n : n;
  at = lo;
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

// Chords (in map units) below which a paraboloid box bounds the arcs by their sag:
// great circles map to circles of radius >= 1 in the map, and an arc inside the unit
// disk is at most half of its circle, so it strays at most c^2 / 4 from its chord c.
// Beyond this the arcs' exact extremes are cheaper than the slack (at 0.05 it is 6e-4).
const float OW_SAG_CHORD = 0.05;

// Box of the triangle's image in a paraboloid layer (its part with z >= 0).
vec4 ow_paraboloid_box(vec3 v0, vec3 v1, vec3 v2)
{
  vec3 p[4];
  int count = ow_clip_z(v0, v1, v2, 0.0, p);
  if (count < 3) {
    return OW_EMPTY_BOX;
  }
  vec4 box = vec4(1e30, -1e30, 1e30, -1e30);
  vec2 image[4];
  float chord = 0.0;
  for (int i = 0; i < 4; i++) {
    if (i >= count) {
      break;
    }
    image[i] = (length(p[i]) > 0.0) ? ow_stereographic(p[i]) : vec2(0.0);
  }
  for (int i = 0; i < 4; i++) {
    if (i >= count) {
      break;
    }
    if (length(p[i]) > 0.0) {
      ow_box_add(image[i], box);
    }
    chord = max(chord, length(image[(i + 1) % count] - image[i]));
  }
  if (chord < OW_SAG_CHORD && min(min(length(p[0]), length(p[1])), length(p[2])) > 0.0) {
    float sag = 0.25 * chord * chord;
    return clamp(box + vec4(-sag, sag, -sag, sag), -1.0, 1.0);
  }
  for (int i = 0; i < 4; i++) {
    if (i >= count) {
      break;
    }
    if (length(p[i]) > 0.0) {
      ow_arc_extend(p[i], p[(i + 1) % count], box);
    }
  }
  return box;
}

// Box of the triangle's image on a cube face (its part with z >= near), clamped to the
// face; empty when the image misses the face.
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
      vec2 xy = p[i].xy / p[i].z;
      box = vec4(min(box.x, xy.x), max(box.y, xy.x), min(box.z, xy.y), max(box.w, xy.y));
    }
  }
  if (box.x > 1.0 || box.y < -1.0 || box.z > 1.0 || box.w < -1.0) {
    return OW_EMPTY_BOX;  // beside the face: no texel of it sees the triangle
  }
  return clamp(box, -1.0, 1.0);
}

#ifndef OW_NO_WARP
// A conservative box of the warped image of the uv box (u0, u1, v0, v1): the warp grows
// along each axis, and its offsets change across by at most `shear` (rows, columns)
// per unit (footprint.warp_box in addon/core/footprint.py).
vec4 ow_warp_box(sampler2D rows, sampler2D cols, int slot, int size, vec4 box, vec2 shear)
{
  float slope;
  float v_mid = 0.5 * (box.z + box.w);
  float v_half = 0.5 * (box.w - box.z);
  float w0 = box.x + ow_family_offset(rows, slot, size, box.x, v_mid, slope) - shear.x * v_half;
  float w1 = box.y + ow_family_offset(rows, slot, size, box.y, v_mid, slope) + shear.x * v_half;
  float w_mid = 0.5 * (w0 + w1);
  float w_half = 0.5 * (w1 - w0);
  float z0 = box.z + ow_family_offset(cols, slot, size, box.z, w_mid, slope) - shear.y * w_half;
  float z1 = box.w + ow_family_offset(cols, slot, size, box.w, w_mid, slope) + shear.y * w_half;
  return vec4(w0, w1, z0, z1);
}
#endif
