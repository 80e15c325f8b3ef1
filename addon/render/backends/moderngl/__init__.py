"""The moderngl device: no Blender, no window; its GLSL headers, its uniform buffers and the
GL calls moderngl does not give (through ctypes)."""
