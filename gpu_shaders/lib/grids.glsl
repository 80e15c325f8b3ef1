// Heterogeneous media (core/media.py's GridMedium): density grids times an
// extinction per unit density, marched along the segment from each view sample to the
// light by the shadow test's grids variant (shaders.grids_of). A grid is a 2D texture of
// its z slices side by side (passes/media.py's grid_texels: slice k at column k % cols,
// row k / cols, each nx by ny texels), read with texelFetch and blended trilinearly here,
// as core/media.py's density_at does (the numpy oracle): the same numbers on both backends.

// The density of grid g at index-space point x (voxel (i, j, k) centred at (i, j, k)),
// trilinear between voxel centres, the edge voxels held out to the grid's half-voxel rim.
float ow_grid_density(int g, vec3 x)
{
  vec4 size = ow_grid_size[g];  // nx, ny, nz, slices a row
  ivec3 n = ivec3(size.xyz);
  int cols = int(size.w);
  vec3 base = floor(x);
  vec3 f = x - base;
  float total = 0.0;
  for (int c = 0; c < 8; c++) {
    ivec3 corner = clamp(ivec3(base) + ivec3(c & 1, (c >> 1) & 1, (c >> 2) & 1), ivec3(0), n - 1);
    ivec2 texel = ivec2(corner.x + (corner.z % cols) * n.x, corner.y + (corner.z / cols) * n.y);
    float value;
    if (g == 0) {
      value = texelFetch(ow_grid0, texel, 0).r;
    } else if (g == 1) {
      value = texelFetch(ow_grid1, texel, 0).r;
    } else if (g == 2) {
      value = texelFetch(ow_grid2, texel, 0).r;
    } else {
      value = texelFetch(ow_grid3, texel, 0).r;
    }
    vec3 w = mix(1.0 - f, f, vec3(ivec3(c & 1, (c >> 1) & 1, (c >> 2) & 1)));
    total += w.x * w.y * w.z * value;
  }
  return total;
}

// The RGB optical depth of the light-centred segment p -> q through the grids: each grid's
// part of it (clipped to its extent in index space) by the midpoint rule, in steps of at
// most half a voxel (OW_GRID_MAX_STEPS at most).
vec3 ow_grid_depth(vec3 p, vec3 q)
{
  vec3 depth = vec3(0.0);
  float world = length(q - p);
  for (int g = 0; g < OW_GRID_MAX; g++) {
    if (g >= ow_grid_count) {
      break;
    }
    vec3 a = (ow_grid_to_index[g] * vec4(p, 1.0)).xyz;
    vec3 b = (ow_grid_to_index[g] * vec4(q, 1.0)).xyz;
    vec3 d = b - a;
    vec3 lo = vec3(-0.5);
    vec3 hi = ow_grid_size[g].xyz - 0.5;
    float t0 = 0.0;
    float t1 = 1.0;
    for (int axis = 0; axis < 3; axis++) {
      if (abs(d[axis]) < 1e-30) {
        if (a[axis] < lo[axis] || a[axis] > hi[axis]) {
          t1 = -1.0;
        }
        continue;
      }
      float s0 = (lo[axis] - a[axis]) / d[axis];
      float s1 = (hi[axis] - a[axis]) / d[axis];
      t0 = max(t0, min(s0, s1));
      t1 = min(t1, max(s0, s1));
    }
    if (!(t1 > t0)) {
      continue;
    }
    int steps = int(clamp(ceil((t1 - t0) * length(d) / 0.5), 1.0, float(OW_GRID_MAX_STEPS)));
    float dt = (t1 - t0) / float(steps);
    float sum = 0.0;
    for (int s = 0; s < steps; s++) {
      sum += ow_grid_density(g, a + d * (t0 + (float(s) + 0.5) * dt));
    }
    depth += ow_grid_sigma[g].rgb * (sum * dt * world);
  }
  return depth;
}

// The light sample p (light-centred) keeps through the grids, the mean over RGB: towards a
// point light's centre, or upstream along a sun's axis (ow_grid_reach past p); a sized
// light's (ow_grid_light_kind: an OW_LIGHT_* code; 0 for a hard light) towards each of
// its ow_grid_light_count points, averaged (core/light_shape.stratified_points: a sphere's
// on the disk facing the sample, an area light's in its frame, a sun's directions towards it).
float ow_grid_kept(vec3 p)
{
  bool sized = ow_grid_light_kind == OW_LIGHT_SPHERE || ow_grid_light_kind == OW_LIGHT_AREA
               || ow_grid_light_kind == OW_LIGHT_SUN_DISK;
  int count = sized ? clamp(ow_grid_light_count, 1, OW_GRID_LIGHT_POINTS) : 1;
  vec3 w = -p / max(length(p), 1e-30);  // towards a sphere's centre
  vec3 helper = (abs(w.z) < 0.9) ? vec3(0.0, 0.0, 1.0) : vec3(1.0, 0.0, 0.0);
  vec3 a = normalize(cross(w, helper));
  vec3 b = cross(w, a);
  float kept = 0.0;
  for (int k = 0; k < count; k++) {
    vec3 point = ow_grid_light_points[k].xyz;
    vec3 q;
    if (ow_grid_light_kind == OW_LIGHT_SPHERE) {
      q = point.x * a + point.y * b;
    } else if (ow_grid_light_kind == OW_LIGHT_AREA) {
      q = ow_grid_light_frame * point;
    } else if (ow_grid_light_kind == OW_LIGHT_SUN_DISK) {
      q = p + (ow_grid_light_frame * point) * ow_grid_reach;
    } else {
      q = (ow_sun != 0) ? p - ow_light_axis * ow_grid_reach : vec3(0.0);
    }
    vec3 light = exp(-ow_grid_depth(p, q));
    kept += (light.r + light.g + light.b) / 3.0;
  }
  return kept / float(count);
}
