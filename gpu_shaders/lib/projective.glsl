// Projective (spot and sun) maps: one 4x4 matrix from light-centred world space to the
// map's clip space, uv = ndc.xy * 0.5 + 0.5, z01 = ndc.z * 0.5 + 0.5. Mirrors
// addon/core/perspective.py (project, texel_footprint).
#include "lib/edges.glsl"

// Row i of a 4x4 matrix without its translation (GLSL indexes m[column][row]).
vec3 ow_matrix_row(mat4 m, int i)
{
  return vec3(m[0][i], m[1][i], m[2][i]);
}

// uv and z01 of a light-centred point; `w` <= 0 means the point is behind the map.
vec3 ow_projective_uvz(mat4 m, vec3 p, out float w)
{
  vec4 c = m * vec4(p, 1.0);
  w = c.w;
  return (c.xyz / c.w) * 0.5 + 0.5;
}

// World size of one texel at p: (1 / res) / the smallest singular value of the 2x3
// Jacobian d(uv)/dp. Its null direction is the light ray, so this is the widest a
// texel's footprint gets across the ray.
float ow_projective_footprint(mat4 m, vec3 p, float resolution)
{
  vec4 c = m * vec4(p, 1.0);
  vec3 row_x = ow_matrix_row(m, 0);
  vec3 row_y = ow_matrix_row(m, 1);
  vec3 row_w = ow_matrix_row(m, 3);
  vec3 gx = 0.5 * (row_x * c.w - c.x * row_w) / (c.w * c.w);
  vec3 gy = 0.5 * (row_y * c.w - c.y * row_w) / (c.w * c.w);
  // Eigenvalues of the 2x2 Gram matrix; the small one as det / large (no cancellation).
  float a = dot(gx, gx);
  float b = dot(gx, gy);
  float d = dot(gy, gy);
  float large = 0.5 * (a + d) + sqrt(max(0.25 * (a - d) * (a - d) + b * b, 0.0));
  float small = max(a * d - b * b, 0.0) / max(large, 1e-30);
  return 1.0 / (resolution * sqrt(max(small, 1e-30)));
}

// A conservative box (u0, u1, v0, v1) in uv of a triangle's image in a projective map, for
// the exact pass's footprints: the part of the triangle in front of the map (clip w >=
// w_min, Sutherland-Hodgman in clip space, where the map is linear) and the box of its
// projected corners. A projective map takes the clipped triangle to the polygon of those
// corners, so the box is the image's own; a parallel (sun) map has w = 1 everywhere and
// clips nothing. Empty (u0 > u1) when no part is in front.
vec4 ow_projective_box(mat4 m, vec3 v0, vec3 v1, vec3 v2, float w_min)
{
  vec4 c[3] = vec4[3](m * vec4(v0, 1.0), m * vec4(v1, 1.0), m * vec4(v2, 1.0));
  vec4 box = vec4(1e30, -1e30, 1e30, -1e30);
  for (int i = 0; i < 3; i++) {
    vec4 a = c[i];
    vec4 b = c[(i + 1) % 3];
    bool a_in = a.w >= w_min;
    if (a_in) {
      vec2 xy = a.xy / a.w;
      box = vec4(min(box.x, xy.x), max(box.y, xy.x), min(box.z, xy.y), max(box.w, xy.y));
    }
    if (a_in != (b.w >= w_min)) {
      vec2 xy = mix(a.xy, b.xy, (w_min - a.w) / (b.w - a.w)) / w_min;  // the crossing, at w = w_min
      box = vec4(min(box.x, xy.x), max(box.y, xy.x), min(box.z, xy.y), max(box.w, xy.y));
    }
  }
  return (box.x > box.y) ? box : box * 0.5 + 0.5;
}

// The exact pass's edge plane of a parallel (sun) light travelling along `axis`, through
// the edge (a, b) and containing the light's direction: the limit of a point light's plane
// through the light and the edge as the light recedes along -axis. A normal axis x (b - a)
// and a point `at` of the edge, so that a sample p's side is dot(p - at, normal); the
// vertices are taken in one order whichever triangle asks (as the point lights' relative
// edges in lib/footprint.glsl), so neighbours sharing the edge split the samples without a gap.
void ow_parallel_edge(vec3 axis, vec3 a, vec3 b, out vec3 normal, out vec3 at)
{
  bool swap = ow_edge_swapped(a, b);
  vec3 lo = swap ? b : a;
  vec3 hi = swap ? a : b;
  precise vec3 n = cross(axis, hi - lo);
  normal = swap ? -n : n;
  at = lo;
}

// The sign a sun light's edge sides take inside the triangle: that of axis . ((v1 - v0) x
// (v2 - v0)), the limit of a point light's det(v0, v1, v2); 0 for a triangle seen edge-on
// from the sun (within OW_EDGE_ON, as a point light's edge planes in lib/footprint.glsl), which covers
// no ray.
float ow_parallel_orientation(vec3 axis, vec3 v0, vec3 v1, vec3 v2)
{
  vec3 normal = cross(v1 - v0, v2 - v0);
  float c = dot(axis, normal);
  return (abs(c) > OW_EDGE_ON * length(normal)) ? sign(c) : 0.0;
}

// A tighter conservative cover than the box for a triangle wholly in front of a projective
// map, whose image is the triangle of its projected corners a, b, c (uv): each edge's line
// moved outward by the support of a square of half-side `grow` (|n.x| + |n.y|) grow, so
// every texel whose square, grown by the same slack as the box's, meets the image has its
// centre inside; `corner` 0-2 of the moved lines' triangle (3 repeats 2, as the quad's
// corners of the projective depth pass). False where that triangle is not smaller than
// `box_area`: a sliver's moved corners run far out along its sharp angles.
bool ow_dilated_triangle(vec2 a, vec2 b, vec2 c, float grow, int corner, float box_area, out vec2 uv)
{
  uv = vec2(0.0);
  vec2 p[3] = vec2[3](a, b, c);
  float turn = sign((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x));
  vec3 line[3];  // outward unit normal n and offset d: n . x <= d inside
  for (int i = 0; i < 3; i++) {
    vec2 e = p[(i + 1) % 3] - p[i];
    vec2 n = turn * vec2(e.y, -e.x) / max(length(e), 1e-30);
    line[i] = vec3(n, dot(n, p[i]) + grow * (abs(n.x) + abs(n.y)));
  }
  vec2 q[3];
  for (int k = 0; k < 3; k++) {
    vec3 l0 = line[(k + 2) % 3];  // the edge into corner k, then the one out of it
    vec3 l1 = line[k];
    float det = l0.x * l1.y - l0.y * l1.x;
    q[k] = vec2(l0.z * l1.y - l0.y * l1.z, l0.x * l1.z - l0.z * l1.x) / det;
  }
  float area = 0.5 * abs((q[1].x - q[0].x) * (q[2].y - q[0].y) - (q[1].y - q[0].y) * (q[2].x - q[0].x));
  if (turn == 0.0 || !(area < box_area)) {
    return false;  // no area (seen edge-on), a sliver, or not finite
  }
  uv = q[min(corner, 2)];
  return true;
}
