// Layer choice for a light-local direction; mirrors pick_slot in addon/core/frames.py.
// The OW_PARAM_* codes come from the host (shaders.PARAM_CODES).

int ow_pick_slot(int parameterization, vec3 d)
{
  if (parameterization == OW_PARAM_IPSM) {
    return 0;  // one paraboloid along the cone axis holds every sample
  }
  if (parameterization == OW_PARAM_DPSM || parameterization == OW_PARAM_UNFOLD) {
    return (d.z <= 0.0) ? 0 : 1;
  }
  vec3 a = abs(d);
  if (a.x >= a.y && a.x >= a.z) {
    return (d.x >= 0.0) ? 0 : 1;
  }
  if (a.y >= a.z) {
    return (d.y >= 0.0) ? 2 : 3;
  }
  return (d.z >= 0.0) ? 4 : 5;
}
