"""A Blender scene read as Cycles renders it: triangles, hair and points from the render
depsgraph, each light's rule of what blocks it, materials' alpha and media, density grids,
a light's size, and what no method draws. Read-only; used by the reference (reference/)
and by the viewport's scene cache (blender/)."""
