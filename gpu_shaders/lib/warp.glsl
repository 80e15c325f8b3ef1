// NoTW / RTW warps; mirrors addon/core/warping.py (Warp.forward, .inverse, .slopes).
// Tables are RGBA32F textures of width A + 1 and height 6 * A (backend.pack_warp_table):
// the A functions of layer slot s occupy rows s * A .. s * A + A - 1, and texel (k, i)
// holds nodes k and k + 1 (at k / A and (k + 1) / A) of function i in .xy and of
// function i + 1 in .zw, so one fetch serves one evaluation. Offsets are interpolated
// linearly along the nodes and between neighbouring function centres with mix():
// fixed-function filtering has too few weight bits.

// Texel (A, s * A) of a table holds slot s's family's largest shear |d offset / d across|
// (and its smoothing window): the bound the footprint pass's boxes widen by.
vec2 ow_warp_shears(sampler2D rows, sampler2D cols, int slot, int size)
{
  ivec2 info = ivec2(size, slot * size);
  return vec2(texelFetch(rows, info, 0).x, texelFetch(cols, info, 0).x);
}

struct OwBlend {
  int i0;
  int i1;
  float f;
};

OwBlend ow_blend(float across, int size)
{
  float t = across * float(size) - 0.5;
  OwBlend b;
  b.i0 = clamp(int(floor(t)), 0, size - 1);
  b.i1 = min(b.i0 + 1, size - 1);
  b.f = clamp(t - float(b.i0), 0.0, 1.0);
  return b;
}

float ow_node_value(sampler2D table, int base, OwBlend b, int k, int size)
{
  // Node `size` (the right end) is the second node of the last texel.
  vec4 q = texelFetch(table, ivec2(min(k, size - 1), base + b.i0), 0);
  vec2 o = (k < size) ? q.xz : q.yw;
  return float(k) / float(size) + mix(o.x, o.y, b.f);
}

// Offset of the family at `along`, blended `across`; `slope` gets d(offset)/d(along)
// and `shear` d(offset)/d(across).
float ow_family_offset2(sampler2D table, int slot, int size, float along, float across, out float slope,
                        out float shear)
{
  OwBlend b = ow_blend(across, size);
  int base = slot * size;
  float s = along * float(size);
  int k = clamp(int(floor(s)), 0, size - 1);
  float fr = clamp(s - float(k), 0.0, 1.0);
  // Functions i0 and i0 + 1 (= b.i1, or i0 itself at the slot's last function).
  vec4 q = texelFetch(table, ivec2(k, base + b.i0), 0);
  float a0 = q.x;
  float a1 = q.y;
  float c0 = q.z;
  float c1 = q.w;
  bool inside = along >= 0.0 && along <= 1.0;
  slope = inside ? mix(a1 - a0, c1 - c0, b.f) * float(size) : 0.0;
  float t = across * float(size) - 0.5;
  bool blending = t > 0.0 && t < float(size - 1);
  shear = blending ? (mix(c0, c1, fr) - mix(a0, a1, fr)) * float(size) : 0.0;
  return mix(mix(a0, a1, fr), mix(c0, c1, fr), b.f);
}

float ow_family_offset(sampler2D table, int slot, int size, float along, float across, out float slope)
{
  float shear;
  return ow_family_offset2(table, slot, size, along, across, slope, shear);
}

// Solve x + offset(x; across) = warped by binary search over the nodes (increasing).
float ow_family_inverse(sampler2D table, int slot, int size, float warped, float across)
{
  if (warped < 0.0 || warped > 1.0) {
    return warped;  // the warp is the identity outside the map
  }
  OwBlend b = ow_blend(across, size);
  int base = slot * size;
  int lo = 0;
  int hi = size;
  for (int step = 0; step < 16 && hi - lo > 1; step++) {
    int mid = (lo + hi) / 2;
    if (ow_node_value(table, base, b, mid, size) <= warped) {
      lo = mid;
    }
    else {
      hi = mid;
    }
  }
  float x0 = ow_node_value(table, base, b, lo, size);
  float x1 = ow_node_value(table, base, b, lo + 1, size);
  float frac = (warped - x0) / max(x1 - x0, 1e-30);
  return (float(lo) + frac) / float(size);
}

// Full warp (eq. 4.9): rows first, then columns indexed by the row-warped u.
// `jacobian` gets d(u', v')/d(u, v) (column-major: J[0] = d/du, J[1] = d/dv).
vec2 ow_warp_jacobian(sampler2D rows, sampler2D cols, int slot, int size, vec2 uv, out mat2 jacobian)
{
  float su, shear_u, sv, shear_v;
  float u2 = uv.x + ow_family_offset2(rows, slot, size, uv.x, uv.y, su, shear_u);
  float v2 = uv.y + ow_family_offset2(cols, slot, size, uv.y, u2, sv, shear_v);
  float du_du = 1.0 + su;
  float du_dv = shear_u;
  // v' = v + o_y(v; u'(u, v)): the chain rule through u'.
  jacobian = mat2(du_du, shear_v * du_du, du_dv, 1.0 + sv + shear_v * du_dv);
  return vec2(u2, v2);
}

vec2 ow_warp(sampler2D rows, sampler2D cols, int slot, int size, vec2 uv, out vec2 slopes)
{
  mat2 j;
  vec2 w = ow_warp_jacobian(rows, cols, slot, size, uv, j);
  slopes = vec2(j[0][0], j[1][1] - j[0][1] * j[1][0] / j[0][0]);  // dv'/dv at fixed u'
  return w;
}

// Smallest singular value of a 2x2 matrix: the least a texel is magnified in any direction.
float ow_min_singular(mat2 m)
{
  float a = dot(m[0], m[0]);
  float b = dot(m[0], m[1]);
  float c = dot(m[1], m[1]);
  float mean = 0.5 * (a + c);
  float spread = sqrt(max(0.25 * (a - c) * (a - c) + b * b, 0.0));
  return sqrt(max(mean - spread, 0.0));
}

// Plain-map texels one map texel spans along unit plain-map direction g, where J =
// d(map uv)/d(plain uv): the width ||J^-T g||_1 of the texel's preimage J^-1 S (S the
// unit square) along g, capped at 1/sigma_min, the isotropic reach the bias used
// before. At J = I the width is 1 to sqrt(2), so plain maps stay at the cap, 1; through
// a sheared or anisotropic warp it is the width along g that a normal offset must
// cover, since the surface's depth changes along g (texel_reach in
// addon/core/warping.py mirrors this).
float ow_texel_reach(mat2 jacobian, vec2 g)
{
  float cap = 1.0 / max(ow_min_singular(jacobian), 1e-30);
  vec2 pre = transpose(inverse(jacobian)) * g;
  return min(abs(pre.x) + abs(pre.y), cap);
}

// Row warp only (the second scatter of Algorithm 3).
vec2 ow_apply_row_warp(sampler2D rows, int slot, int size, vec2 uv)
{
  float su;
  return vec2(uv.x + ow_family_offset(rows, slot, size, uv.x, uv.y, su), uv.y);
}

vec2 ow_unwarp(sampler2D rows, sampler2D cols, int slot, int size, vec2 uvw)
{
  float v = ow_family_inverse(cols, slot, size, uvw.y, uvw.x);
  float u = ow_family_inverse(rows, slot, size, uvw.x, v);
  return vec2(u, v);
}
