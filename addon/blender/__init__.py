"""bpy layer of OmniWarp: properties, operators, panels, viewport preview and
overlay. Only this package (and `addon.reference`) may import bpy at module level.

* `properties`: the settings stored in .blend files (`light.omniwarp`,
  `scene.omniwarp`) and helpers that turn them into pipeline inputs.
* `panels`: the Light-properties panel and the 3D viewport sidebar tab.
* `registration`: what Blender registers (`CLASSES`, the settings pointers and
  the runtime modules with draw/depsgraph handlers), in order.

Nothing is imported here, so importing the package needs no bpy.
"""
