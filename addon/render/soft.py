"""The soft filter's uniforms for a sized light (lib/soft.glsl, issue 27): one place that
turns a light's shape and the frame's settings into what the shadow test reads."""
from __future__ import annotations

import functools

import numpy as np

from ..core.light_shape import Area, LightShape, Sphere, stratified_points
from ..core.scene import LightSpec
from .frame import ShadowSettings
from .shaders import SOFT_KINDS, SOFT_MAX_POINTS, SOFT_MAX_SEARCH


@functools.lru_cache(maxsize=32)
def _points(shape: LightShape, count: int, size: int) -> np.ndarray:
    """The light's fixed pattern of `count` points as a uniform array (size, 4), zero-padded."""
    out = np.zeros((size, 4))
    out[:count, :3] = stratified_points(shape, count)
    out.setflags(write=False)
    return out


def filters(light: LightSpec, settings: ShadowSettings) -> bool:
    """True when the frame's maps are filtered by the light's size: a sized sphere or area
    light on a point-light parameterization's depth test (the exact pass and the spot and
    sun maps are not filtered yet)."""
    return (light.sized and isinstance(light.shape, (Sphere, Area)) and light.is_point
            and not settings.exact)


def soft_uniforms(light: LightSpec, settings: ShadowSettings) -> dict:
    """The shadow test's soft uniforms; ow_soft_count 0 (the hard test) when not `filters`."""
    if not filters(light, settings):
        return {"ow_soft_count": 0}
    count, search = settings.light_samples, settings.search_samples
    return {"ow_soft_points": _points(light.shape, count, SOFT_MAX_POINTS), "ow_soft_count": count,
            "ow_soft_search_points": _points(light.shape, search, SOFT_MAX_SEARCH), "ow_soft_search": search,
            "ow_soft_kind": SOFT_KINDS[light.shape.kind]}
