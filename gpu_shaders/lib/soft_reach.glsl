// How far a sized light's shadow reaches across its map, for the exact pass's footprints
// (lib/soft_footprint.glsl) and walk (lib/exact_soft_mark.glsl): no uniforms, so either stage takes it.
// A segment from p (D from the centre) to a light point q (|q| <= R) meets the triangle
// (|x| >= d_min) at x = p + s (q - p) only where s <= (D - d_min) / (D - R), as
// |x| <= (1 - s) D + s R, and x's direction differs from p's by at most asin(s R / d_min):
// the sine of that angle for a sample D = `far` from the centre, or for D -> infinity,
// R / d_min, when `far` is 0 (not known). It grows with D: the footprints take the farthest
// sample's, the walk each sample's own.
float ow_soft_reach_sin(float d_min, float reach, float far)
{
  float s = reach / d_min;
  return (far > 0.0) ? s * clamp((far - d_min) / max(far - reach, 1e-30), 0.0, 1.0) : s;
}

