"""bpy layer of OmniWarp: properties, operators, panels, viewport preview and
overlay. Only this package (and `addon.reference`) may import bpy at module level;
`registration.CLASSES` lists what Blender registers."""
