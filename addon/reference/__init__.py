"""Cycles ground truth: per-pixel position, geometric normal and visibility, and its cache.

`data` is numpy only. `blender_scene` and `capture` need `bpy`, but import it lazily
(inside functions), so importing this package never requires Blender. `cache`
serves cached references without `bpy` and only imports it to render a new one.
"""
