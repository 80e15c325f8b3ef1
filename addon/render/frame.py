"""The data of one shadow frame: its settings, its view samples, and what it produced.

`ShadowSettings` names a registered method's parameterization, resolution, warp and
options; `ViewSamples` are the camera's per-pixel receivers; `PreparedGeometry` and
`FrameResult` are what `pipeline.ShadowPipeline.render` returns.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core import frames, validate
from ..core import methods as method_registry
from ..core.errors import BackendError, InputError
from ..core.frames import POINT_PARAMETERIZATIONS, PROJECTIVE_PARAMETERIZATIONS, Parameterization
from ..core.plan import Plan
from ..core.scene import CameraSpec, LightSpec
from ..core.warping import LayerMapping
from .backend import AtlasLayout
from .shaders import EXACT_SOFT_MAX_POINTS, SOFT_MAX_POINTS, SOFT_MAX_SEARCH

MIN_RESOLUTION = 16
# The exact pass's points of a sized light per view sample, by default (ShadowSettings).
# 256: at 64 the pattern's own error kept a dense scene's large lights (the artist file's
# 0.25 m Lamp, its 1.2 x 0.8 m Softbox) above 2 x the reference's noise + 0.05; at 256 every
# measured light is within it (docs/soft.md).
EXACT_SAMPLES = 256
LIGHT_SAMPLES = 36  # the soft filter's default points a sample (a 6 x 6 grid)


MAX_RESOLUTION = 4096


WARP_KINDS = ("none", "notw", "rtw")


def analysis_size_for(resolution: int) -> int:
    """Count-map side A for a map resolution: an eighth of the map, within [64, 256].

    The chosen smoothing windows span tens of rows even at A = 128 (docs/warping.md),
    so a finer count map adds cost (scatter, read-back, per-row work, tessellation
    against more kinks) without changing the measured error beyond noise.
    """
    return int(min(256, max(64, resolution // 8)))


# The largest bias accepted, in texel footprints: far beyond any useful value (the UI's
# soft range ends at 4), and below it Blender's FLT_MAX for an infinite value is refused.
MAX_BIAS = 100.0


@dataclass(frozen=True)
class BiasSettings:
    """Bias in units of one texel's footprint at the sample (see shadow_test.frag)."""

    constant: float = 0.3
    slope: float = 0.7
    normal: float = 0.7

    def __post_init__(self) -> None:
        # NaN or inf would shadow (or light) every pixel without a word: refuse it by name.
        for name in ("constant", "slope", "normal"):
            value = validate.finite_number(f"bias {name}", getattr(self, name), 0.0, MAX_BIAS)
            object.__setattr__(self, name, value)


@dataclass(frozen=True)
class ShadowSettings:
    parameterization: Parameterization
    resolution: int
    bias: BiasSettings = BiasSettings()
    cull: bool = True
    tessellation_tolerance: float = 1.0  # texels of chord-to-arc bend
    warp: str = "none"  # "none", "notw" or "rtw"
    analysis_size: int | None = None  # count-map side A; None = analysis_size_for(resolution)
    cut: bool = False  # ipsm only: skewed axis and a crop fitted to the frustum (thesis 4.1.4)
    edge_aa: bool = False  # unfold only: the paper's edge-distance antialiasing (edge_aa_parameters)
    # dpsm, cube, ipsm, sm (frames.EXACT_PARAMETERIZATIONS): the irregular z-buffer over
    # the (warped) map instead of its depths (the `exact` method)
    exact: bool = False
    # A sized light (core/light_shape.py): its points the soft filter reads per sample, and
    # how many of them the blocker search follows (lib/soft.glsl); a hard light reads none.
    # LIGHT_SAMPLES, a square: a count that leaves the pattern's last grid row part-filled
    # spreads its points unevenly (32 erred more than 25 on every soft preset).
    light_samples: int = LIGHT_SAMPLES
    search_samples: int = 8
    # The exact pass of a sized light: its points per view sample (lib/exact_soft.glsl), a
    # square, one point per cell of a square grid.
    exact_samples: int = EXACT_SAMPLES
    # The exact pass of a sized light over a scene of opaque triangles walks one segment a
    # light point through a box tree (passes/segments.py) instead of its lists: the same
    # marks at a cost that grows with the log of the triangles. False keeps the lists.
    exact_segments: bool = True

    def __post_init__(self) -> None:
        known = POINT_PARAMETERIZATIONS + PROJECTIVE_PARAMETERIZATIONS
        if self.parameterization not in known:
            raise InputError(f"unknown parameterization {self.parameterization!r}; use one of {', '.join(known)}")
        if self.warp != "none" and not frames.takes_warp(self.parameterization):
            raise InputError(f"{self.parameterization} takes no warp; warps apply to "
                             f"{', '.join(frames.WARPABLE_PARAMETERIZATIONS)}")
        if self.edge_aa and self.parameterization != "unfold":
            raise InputError("edge-distance antialiasing is the unfold method's option (unfold+aa)")
        if self.exact and not frames.takes_exact(self.parameterization):
            raise InputError(f"the exact (irregular z-buffer) pass draws footprints: "
                             f"{', '.join(frames.EXACT_PARAMETERIZATIONS)}, not {self.parameterization}")
        if self.warp not in WARP_KINDS:
            raise InputError(f"unknown warp {self.warp!r}; use one of {', '.join(WARP_KINDS)}")
        if not (MIN_RESOLUTION <= int(self.resolution) <= MAX_RESOLUTION):
            raise InputError(f"resolution {self.resolution} out of range [{MIN_RESOLUTION}, {MAX_RESOLUTION}]")
        if not isinstance(self.bias, BiasSettings):
            raise InputError(f"bias must be a BiasSettings, got {type(self.bias).__name__}")
        validate.finite_number("tessellation tolerance (texels)", self.tessellation_tolerance, 1e-3, 1e3)
        for name, most in (("light_samples", SOFT_MAX_POINTS), ("search_samples", SOFT_MAX_SEARCH)):
            value = getattr(self, name)
            if not (isinstance(value, int) and 1 <= value <= most):
                raise InputError(f"{name} {value!r} must be a whole number in [1, {most}]")
        check_exact_samples(self.exact_samples)


def check_exact_samples(samples: object, name: str = "exact_samples") -> int:
    """A sized light's points per view sample in the exact pass: a square number (one point a
    cell of a square grid, so the pattern stays even) in [1, EXACT_SOFT_MAX_POINTS]."""
    if not (isinstance(samples, int) and 1 <= samples <= EXACT_SOFT_MAX_POINTS
            and math.isqrt(samples) ** 2 == samples):
        raise InputError(f"{name} {samples!r}: must be a square number (4, 16, 64, ...) "
                         f"in [1, {EXACT_SOFT_MAX_POINTS}]")
    return samples


def settings_for(method: str, resolution: int, emission: str = "omni", **fields) -> ShadowSettings:
    """The `ShadowSettings` of a registered pipeline method (`core/methods.py`) at `resolution`,
    for a light of `emission` (a method may draw another parameterization for spot and
    sun lights: `Method.parameterization_for`).

    `fields` sets the other settings (cull, bias, ...); the method's own ones
    (parameterization, warp, cut, edge_aa, exact) come from its registry entry only.
    """
    entry = method_registry.method(method)
    parameterization = entry.parameterization_for(emission)
    if parameterization is None:
        raise InputError(f"{method} is measured outside the pipeline; it has no shadow-map settings")
    return ShadowSettings(parameterization, resolution, warp=entry.warp_for(emission), cut=entry.cut,
                          edge_aa=entry.edge_aa, exact=entry.exact, **fields)


# Largest importance weight one view sample may carry: weights travel in a float32
# (the positions' w), exact for integers far beyond this, and relative weights need
# no more range.
MAX_IMPORTANCE = 65536.0


# The scatter sums weights in 32-bit unsigned counters; all samples may land in one
# texel (stress_one_texel), so the total over the frame must fit one.
MAX_IMPORTANCE_TOTAL = 2**32 - 1


@dataclass(frozen=True)
class Measure:
    """What a frame does besides its shadows, for measurement: none of it changes the
    visibility. `keep_atlas` reads the maps (and media haze) back into the result (the
    overlay, the report's images); `sync_stages` waits at the end of each stage, so that
    each stage's wall time holds its GPU work (`compare`, `preview`); `count_work` makes the
    exact pass count the list entries it walks (its own program variant, slower)."""

    keep_atlas: bool = False
    sync_stages: bool = False
    count_work: bool = False


PLAIN = Measure()  # a frame as the viewport draws it: nothing read back, nothing waited for


@dataclass
class ViewSamples:
    """Per-pixel view samples; row 0 is the TOP image row (as the reference stores it).

    `importance` weights each sample in the warp analysis (thesis 4.2.1: the warp
    follows an importance, and the count map is its plain stand-in): a sample of
    weight k counts as k samples in the count maps the warps are built from. None
    means 1 everywhere, the thesis's count map. The count statistics of a frame
    (max_count_before/after) always count samples, not weights.
    """

    positions: np.ndarray  # (H, W, 3) world
    normals: np.ndarray  # (H, W, 3) world, unit
    hit: np.ndarray  # (H, W) bool
    camera: CameraSpec | None  # None: no camera (no view frustum), so no layer culling
    importance: np.ndarray | None = None  # (H, W) weights in [1, MAX_IMPORTANCE], rounded to integers

    @property
    def shape(self) -> tuple[int, ...]:
        return self.hit.shape

    def importance_weights(self) -> np.ndarray | None:
        """The importance as rounded float32 weights, checked; None when not given.

        Raises InputError naming the problem: a shape other than the hit mask's, a
        weight that is not finite or lies outside [1, MAX_IMPORTANCE] on a hit pixel,
        or hit weights that sum past MAX_IMPORTANCE_TOTAL.
        """
        if self.importance is None:
            return None
        weights = np.asarray(self.importance, dtype=np.float64)
        if weights.shape != self.hit.shape:
            raise InputError(f"importance has shape {weights.shape}; the view samples are {self.hit.shape}")
        used = weights[self.hit]
        bad = ~(np.isfinite(used) & (used >= 1.0) & (used <= MAX_IMPORTANCE))
        if bad.any():
            raise InputError(f"importance weights must be finite and in [1, {MAX_IMPORTANCE:g}]; "
                             f"{int(bad.sum())} hit pixels are not (first: {used[bad][0]!r})")
        rounded = np.rint(weights)
        total = float(rounded[self.hit].sum())
        if total > MAX_IMPORTANCE_TOTAL:
            raise InputError(f"importance weights sum to {total:.0f}; a count-map texel holds at most "
                             f"{MAX_IMPORTANCE_TOTAL} (2^32 - 1), and every sample may land in one")
        return rounded.astype(np.float32)


def _frozen(array: np.ndarray) -> bool:
    """Whether an array's data cannot change in place: it and every array it views are read-only."""
    while isinstance(array, np.ndarray):
        if array.flags.writeable:
            return False
        array = array.base
    return True


@dataclass(frozen=True, eq=False)
class ResidentSamples:
    """What uploaded samples were: these very arrays (held, so no other array can take their
    place), centred on this light position. Two keys match by identity, not by value."""

    arrays: tuple[np.ndarray | None, ...]
    light: bytes

    def matches(self, other: object) -> bool:
        return (isinstance(other, ResidentSamples) and self.light == other.light
                and all(a is b for a, b in zip(self.arrays, other.arrays)))


def resident_samples_key(samples: ViewSamples, light: LightSpec) -> ResidentSamples | None:
    """The key under which a frame's uploaded samples stay on the GPU for the next frame;
    None when an array could change in place (it is writable, or views a writable one),
    so the samples must be uploaded every frame. `compare` hands its frames read-only
    samples (`samples_from_reference`), so a row uploads them once."""
    arrays = (samples.positions, samples.normals, samples.hit, samples.importance)
    if not all(a is None or _frozen(a) for a in arrays):
        return None
    return ResidentSamples(arrays, np.asarray(light.position, dtype=np.float64).tobytes())


@dataclass
class GBufferSamples:
    """View samples that stay on the GPU: a Blender G-buffer's position and normal
    textures (backends/blender/draw.GBuffer), world positions with w = 1 on geometry.

    The pipeline makes them the shadow test's samples on the GPU
    (`BlenderGPUBackend.samples_from_gbuffer`): nothing is read back or uploaded. Every
    sample weighs 1. `read_back` gives them as arrays, for measurements that need them
    on the host (the count statistics of a spot or sun map), never for a frame.
    """

    textures: dict[str, Any]  # "ow_gb_position", "ow_gb_normal"
    size: tuple[int, int]  # (W, H)
    camera: CameraSpec | None
    read_back: Callable[[], ViewSamples]

    @property
    def shape(self) -> tuple[int, int]:
        return self.size[1], self.size[0]


@dataclass
class PreparedGeometry:
    """What a frame drew: the depth range, and either resident footprints or (unfold)
    host-built vertex streams."""

    streams: dict[int, np.ndarray]  # unfold: slot 0 -> (n, VERTEX_FLOATS) float32, both halves
    near: float
    far: float
    skipped_at_upload: int  # unfold: every sanitised triangle; resident: non-finite and zero-area ones
    tessellated_triangles: int  # triangles added by tessellation (unfold only)
    unfold_split: int = -1  # unfold: the first vertex of half 1 in the one stream; -1 otherwise
    # Resident frames: counts, on the host and only when asked (a measurement, never part
    # of a timed frame), the triangles past the GPU's culling and those seen edge-on.
    measure: Callable[[], tuple[int, int]] | None = None
    _measured: tuple[int, int] | None = None

    def _counts(self) -> tuple[int, int]:
        if self._measured is None:
            self._measured = self.measure()
        return self._measured

    @property
    def triangles_drawn(self) -> int:
        """Triangles drawn, summed over the layers (after culling and, for unfold, tessellation)."""
        if self.measure is None:
            return int(sum(len(s) for s in self.streams.values()) // 3)
        return self._counts()[0]

    @property
    def skipped_triangles(self) -> int:
        """Triangles that cannot cast a shadow: non-finite, zero-area, or seen edge-on from the light."""
        return self.skipped_at_upload + (self._counts()[1] if self.measure is not None else 0)


# What a frame leaves on the GPU until it is read: (visibility, flags, GPU ms per stage or None).
FrameReader = Callable[[], tuple[np.ndarray, np.ndarray, "dict[str, float] | None"]]


@dataclass
class FrameResult:
    """What `ShadowPipeline.render` made. The visibility stays on the GPU until it is first
    read (`visibility`, `flags` or `gpu_ms`): a frame itself never waits for it."""

    time_ms: dict[str, float]  # wall ms per stage (docs/design.md section 3)
    plan: Plan
    geometry: PreparedGeometry
    layout: AtlasLayout | None
    texels: int
    atlas: np.ndarray | None = None
    # The maps' transmittance past each atlas texel's media (passes/media.read_haze), read
    # with the atlas; None without media.
    haze: np.ndarray | None = None
    tile_of_slot: dict[int, int] = field(default_factory=dict)
    mappings: dict[int, LayerMapping] = field(default_factory=dict)
    count_maps: dict[int, np.ndarray] = field(default_factory=dict)  # analysis count map per slot
    boxes: dict[int, tuple[int, int, int, int]] = field(default_factory=dict)  # slot -> readable texel box
    # The exact pass's counters as the backend folds them (passes.exact.exact_work; None for
    # the other methods): read them through `exact_work`, which completes the frame first.
    exact_counts: dict[str, int] | None = field(default=None, repr=False)
    reader: FrameReader | None = field(default=None, repr=False)  # reads what is still on the GPU
    exact_marks: bool = False  # whether the visibility is the test's times the exact pass's marks
    # What the frame left to its first read: the exact pass's later rounds, whose need only
    # the GPU's counters tell (passes.exact.finish_lists). None once done, or when nothing is.
    completer: Callable[[], None] | None = field(default=None, repr=False)
    _read: tuple | None = field(default=None, repr=False)

    @property
    def exact_work(self) -> dict[str, int] | None:
        """The exact pass's work (passes.exact.exact_work): walks that went on into a later
        round, the rounds after the first, and on a count_work frame the list entries
        walked, the fragments that walked them and the later rounds' entries."""
        if self.exact_counts is None:
            return None
        self.complete()
        return dict(self.exact_counts)

    def complete(self) -> None:
        """Do what the frame left to its first read (a read of a few counters, and the exact
        pass's later rounds when its lists overflowed their first)."""
        if self.completer is not None:
            completer, self.completer = self.completer, None
            completer()

    @property
    def pending(self) -> bool:
        """Whether the visibility is still on the GPU, unread."""
        return self._read is None

    def resolve(self) -> None:
        """Read what the frame left on the GPU (once; the pipeline does it before the next
        frame overwrites it)."""
        if self._read is None:
            self.complete()
            self._read = self.reader()
            self.reader = None

    def discard(self) -> None:
        """Never read what the frame left on the GPU (a caller that keeps the visibility
        there, `ShadowPipeline.visibility_into`): nothing is read back for it, and asking
        for its visibility, flags or GPU times afterwards is an error."""
        if self._read is None:
            self._read = ()
            self.reader = self.completer = None

    def _field(self, index: int, what: str):
        self.resolve()
        if not self._read:
            raise BackendError(f"the frame's {what} was discarded on the GPU (FrameResult.discard)")
        return self._read[index]

    @property
    def visibility(self) -> np.ndarray:
        """(H, W) float32, 1 lit / 0 shadowed, row 0 at the top."""
        return self._field(0, "visibility")

    @property
    def flags(self) -> np.ndarray:
        """(H, W) int8: 0 tested, 1 no geometry, 2 outside emission, 3 layer not drawn."""
        return self._field(1, "flags")

    @property
    def gpu_ms(self) -> dict[str, float] | None:
        """GPU ms per stage from timer queries, with their `total`; None where the backend has
        no timer queries (Blender's `gpu`)."""
        return self._field(2, "GPU times")

    @property
    def passes(self) -> int:
        return self.plan.passes


def check_light_fits(light: LightSpec, parameterization: str) -> None:
    """InputError unless the method suits the light: the omnidirectional methods take a
    point light (omni or hemi), sm and psm a spot (cone below 180 degrees) or a sun."""
    fitting = frames.parameterizations_for(light.emission)
    if parameterization not in fitting:
        needs = ("a spot (cone below 180 degrees) or sun light" if parameterization in PROJECTIVE_PARAMETERIZATIONS
                 else "a point light (omni or 180 degree spot)")
        raise InputError(f"{parameterization} needs {needs}; a {light.emission} light takes {', '.join(fitting)}")
