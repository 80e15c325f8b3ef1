"""The count statistics of a frame (docs/design.md section 4): view samples per shadow
texel before and after the layer mappings, for the overlay, `preview` and the reports.
Measurement, not part of the timed frame."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core import perspective
from ..core.errors import InputError
from ..core.plan import hit_points
from ..core.scene import LightSpec
from .frame import FrameResult, GBufferSamples, ShadowSettings, ViewSamples


@dataclass
class CountStatistics:
    """View samples per shadow texel, before and after the layer mappings (docs/design.md section 4)."""

    before: dict[int, np.ndarray]  # slot -> count map of the plain projection, map resolution
    after: dict[int, np.ndarray]  # slot -> importance map: counts through crop and warp

    @property
    def max_count_before(self) -> float:
        return float(max((m.max() for m in self.before.values()), default=0.0))

    @property
    def max_count_after(self) -> float:
        return float(max((m.max() for m in self.after.values()), default=0.0))

    @property
    def texel_utilization(self) -> float:
        """Share of the drawn texels that resolve at least one view sample."""
        total = sum(m.size for m in self.after.values())
        used = sum(int(np.count_nonzero(m)) for m in self.after.values())
        return used / total if total else 0.0


def projective_counts(projective: perspective.ProjectiveMap, light: LightSpec, samples: ViewSamples,
                      resolution: int) -> np.ndarray:
    """Count map (row 0 = v = 0) of the view samples through a spot or sun map, in numpy."""
    pts = hit_points(samples.positions, samples.hit) - light.position
    uv, _, w = perspective.project(projective, pts)
    inside = (w > 0.0) & np.all((uv >= 0.0) & (uv < 1.0), axis=1)
    texel = np.floor(uv[inside] * resolution).astype(np.int64)
    flat = np.bincount(texel[:, 1] * resolution + texel[:, 0], minlength=resolution * resolution)
    return flat.reshape(resolution, resolution).astype(np.float32)


def count_statistics(pipeline: Any, light: LightSpec, settings: ShadowSettings,
                     result: FrameResult, samples: ViewSamples | GBufferSamples | None = None) -> CountStatistics:
    """Scatter the samples (still uploaded from the last frame) at the map resolution,
    through `pipeline` (a pipeline.ShadowPipeline: its count_maps; not imported, it imports this).

    Not part of the timed frame: this is measurement. The warp tables of the frame
    must still be bound, which holds right after `render`. Spot and sun maps count
    in numpy and need `samples` (G-buffer samples are read back for it).
    """
    # The frame's own resolution: a sized light's exact pass lists coarser (soft.list_resolution).
    res = result.layout.resolution if result.layout is not None else settings.resolution
    if result.plan.projective is not None:
        if samples is None:
            raise InputError("count statistics of a spot or sun map need the view samples")
        if isinstance(samples, GBufferSamples):
            samples = samples.read_back()
        counts = projective_counts(result.plan.projective, light, samples, res)
        return CountStatistics({0: counts}, {0: counts})
    before = pipeline.count_maps(light, result.plan, {}, res, 0)
    # A frame maps all its drawn layers or none (a warp, an ipsm zoom or a cut), and
    # count_maps counts an unmapped layer plainly anyway.
    after = pipeline.count_maps(light, result.plan, result.mappings, res, 2) if result.mappings else before
    return CountStatistics(before, after)
