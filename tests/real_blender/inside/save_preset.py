"""Inside a real Blender binary, background (`blender -b FILE --python THIS -- OUT_BLEND PRESET`):
build PRESET with the comparison panel's Build and save it, alone, as OUT_BLEND (the file an
artist would hand to the panel's Current scene or to `omniwarp compare --blend`)."""
from __future__ import annotations

import sys

import bpy

out, preset = sys.argv[sys.argv.index("--") + 1:][:2]
before = bpy.context.window.scene
before.omniwarp_compare.source = "PRESET"
before.omniwarp_compare.preset = preset
bpy.ops.omniwarp.build_preset()
built = bpy.context.window.scene
assert built != before, "Build made no new scene"
bpy.data.scenes.remove(before)
bpy.ops.wm.save_as_mainfile(filepath=out)
