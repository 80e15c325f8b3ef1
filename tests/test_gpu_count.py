"""count_gpu_objects counts the distinct Blender GPU objects a holder keeps (no bpy needed)."""
from __future__ import annotations

from addon.render.backends.blender.draw import GBuffer
from addon.render.backends.blender.gpu_objects import count_gpu_objects


class GPUTexture:
    """Stands in for gpu.types.GPUTexture: only the type's name matters to the count."""


class GPUFrameBuffer:
    """Stands in for gpu.types.GPUFrameBuffer."""


def test_one_object_held_twice_counts_once_and_containers_are_walked():
    shared, other, target = GPUTexture(), GPUTexture(), GPUFrameBuffer()
    gbuffer = GBuffer({"ow_gb_position": shared, "ow_gb_normal": other}, (4, 4))
    holder = {"a": [shared, (shared, target)], "b": {"deep": {other}}, "gbuffer": gbuffer, "n": 3}
    assert count_gpu_objects(holder) == 3
    assert count_gpu_objects(gbuffer, holder, [gbuffer]) == 3
    assert count_gpu_objects({}, [], None) == 0


def test_cycles_are_walked_once():
    ring: list = [GPUTexture()]
    ring.append(ring)
    assert count_gpu_objects(ring) == 1
