"""The device on Blender's `gpu` module (OpenGL, Vulkan), its GPU objects, and the drawing
around the pipeline the viewport needs: the G-buffer, the shadow composite, the overlay."""
