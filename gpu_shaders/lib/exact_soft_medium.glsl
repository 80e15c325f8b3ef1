// A medium's crossings under a sized light (shaders.medium_of of the exact soft pass):
// each sample keeps the optical depths of ow_media_points of the light's points
// (a stratified share, lib/media.glsl's ow_media_point), three words a point (lib/media.glsl's
// ow_media_mark), and the frame's reader and resolve weigh in the mean of the light they
// keep. The segment from sample p to point k crosses the triangle where lib/exact_soft_mark.glsl's
// test says (its edge planes through p, its point's sides and plane cut), with a side of
// exactly 0 counted for one of the two triangles of an edge (lib/media.glsl's rule); the
// crossing's distance from p goes in, signed by whether the walk from the light point
// enters the medium there (the segment towards the light leaves the plane's front).
void ow_medium_soft_entry(vec3 p, ivec2 at, ivec2 size)
{
  float h;
  vec3 e0, e1, e2;
  if (!ow_exact_soft_edges(p, h, e0, e1, e2)) {
    return;
  }
  OwLightView view = ow_light_view(p);
  bool sun = int(ow_exact_light.x) == OW_LIGHT_SUN_DISK;
  for (int j = 0; j < ow_media_points; j++) {
    vec3 segment = ow_light_segment(p, view, ow_media_point(j));  // a sun's: the unit direction
    vec3 sides = vec3(dot(e0, segment), dot(e1, segment), dot(e2, segment));
    if (!(ow_medium_inside(sides.x, e0) && ow_medium_inside(sides.y, e1) && ow_medium_inside(sides.z, e2))) {
      continue;
    }
    float along = dot(v_plane.xyz, segment);
    if (along == 0.0) {
      continue;
    }
    float f = -h / along;  // where the plane cuts the segment (a sun's: the distance)
    float len = sun ? 1.0 : length(segment);
    if (sun ? (f > ow_exact_eps * length(p)) : (f > ow_exact_eps && f < 1.0)) {
      ow_media_mark_point(at, size, j, ((along > 0.0) ? f : -f) * len);
    }
  }
}
