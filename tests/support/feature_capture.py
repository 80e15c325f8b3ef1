"""Capture the feature scene in a child process: Cycles references and every reading of its geometry.

    python tests/support/feature_capture.py SCENE.blend OUT_DIR

Writes OUT_DIR/ref_<light>.npz (the Cycles reference of each light) and
OUT_DIR/readings.npz with three readings of the scene's triangles, each per owner:
`render` (the render depsgraph, what Cycles sees), `viewport` (the viewport
depsgraph) and `raw` (each mesh object's own data, no modifiers, in world space).
`readings.json` lists the owners of each reading and what each light's rule says.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

LIGHTS = ("LampA", "LampB", "LampC")


def main(argv: list[str]) -> int:
    import bpy
    import numpy as np

    from addon.reference.capture import capture, evaluated_depsgraph
    from addon.readers.render_geometry import collect, local_triangles, render_triangles
    from addon.readers.shadow_rule import ShadowRule

    blend, out = Path(argv[0]), Path(argv[1])
    out.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.open_mainfile(filepath=str(blend.resolve()), load_ui=False)
    scene = bpy.context.scene
    layer = scene.view_layers[0]
    for light in LIGHTS:
        capture(scene, light=light).save(out / f"ref_{light}.npz")

    arrays: dict[str, np.ndarray] = {}
    listing: dict[str, list] = {}
    readings = {"render": render_triangles(scene, layer), "viewport": collect(evaluated_depsgraph(scene, layer))}
    for reading, found in readings.items():
        listing[reading] = []
        for index, (owner, tris) in enumerate(zip(found.owners, found.triangles)):
            arrays[f"{reading}_{index}"] = tris
            listing[reading].append([owner.name, owner.parent])
    listing["raw"] = []
    for index, obj in enumerate(o for o in bpy.data.objects if o.type == "MESH"):
        matrix = np.array(obj.matrix_world, dtype=np.float64)
        local = local_triangles(obj, None).reshape(-1, 3).astype(np.float64)
        arrays[f"raw_{index}"] = (local @ matrix[:3, :3].T + matrix[:3, 3]).reshape(-1, 3, 3).astype(np.float32)
        listing["raw"].append([obj.name, None])
    rules = {light: ShadowRule.for_light(scene, bpy.data.objects[light]) for light in LIGHTS}
    listing["blocks"] = {light: [rule.blocks(name, parent) for name, parent in listing["render"]]
                         for light, rule in rules.items()}
    listing["seen"] = [rules["LampA"].seen(name, parent) for name, parent in listing["render"]]
    listing["lights"] = {light: {name: rule.lights(name) for name in ("slab", "ground")}
                         for light, rule in rules.items()}
    np.savez_compressed(out / "readings.npz", **arrays)
    (out / "readings.json").write_text(json.dumps(listing, indent=1), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
