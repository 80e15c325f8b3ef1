"""What differs between the Blender lines the extension runs on (4.2, 4.5, 5.x), in one place.

Below both the render layer (Blender's `gpu` module) and the scene readers and reference
(bpy's data): every module that must ask which line it runs on imports `compat.blender`.
Importable without Blender: each check imports bpy or gpu only when called.
"""
