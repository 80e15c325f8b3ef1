"""The error figure against the Cycles reference (docs/design.md section 5)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .scene import LightSpec

UNSHADOWED_EPS = 1e-6
# A reference visibility strictly inside this band is fractional: light through see-through
# surfaces (a curtain, a filtered cut-out edge). The binary error leaves such
# pixels out, as neither lit nor shadowed; the soft error measures them.
FRACTIONAL_BAND = (0.02, 0.98)
# A receiver lit within this cosine of edge-on has no shadow to measure: its shadow ray runs
# inside its own surface, so whether it meets the faces beside it is float32 rounding, in
# Cycles as anywhere (docs/exact.md: sun_field's hay bale face, cos 2.6e-6, where a float64
# ray cast disagrees with Cycles on every pixel Cycles shadows). The light it gets is below
# 1e-5 of a facing receiver's. Float32 rounds a position p by about 6e-8 |p|, which a ray
# at this cosine leaves behind within a metre at 100 m.
GRAZING_COS = 1e-5


def reference_visibility(shadowed: np.ndarray, unshadowed: np.ndarray, eps: float = UNSHADOWED_EPS) -> np.ndarray:
    """Cycles visibility: shadowed / unshadowed >= 0.5 where unshadowed > eps."""
    sh = np.asarray(shadowed, dtype=np.float64)
    un = np.asarray(unshadowed, dtype=np.float64)
    ratio = np.divide(sh, un, out=np.zeros_like(sh), where=un > eps)
    return (un > eps) & (ratio >= 0.5)


def reference_ratio(shadowed: np.ndarray, unshadowed: np.ndarray, eps: float = UNSHADOWED_EPS) -> np.ndarray:
    """Cycles visibility as a fraction: shadowed / unshadowed in [0, 1], 0 where unshadowed <= eps."""
    sh = np.asarray(shadowed, dtype=np.float64)
    un = np.asarray(unshadowed, dtype=np.float64)
    return np.clip(np.divide(sh, un, out=np.zeros_like(sh), where=un > eps), 0.0, 1.0)


def evaluable_mask(position: np.ndarray, normal: np.ndarray, hit: np.ndarray, unshadowed: np.ndarray,
                   light: LightSpec, eps: float = UNSHADOWED_EPS) -> np.ndarray:
    """Pixels that count: hit geometry, face the light by more than GRAZING_COS, lie in the
    emission domain and get light.

    The domain is every direction for omni, the half space in front of the axis for
    hemi, the cone of full angle `light.spot_size` around the axis for spot, and all
    of space for a sun, whose light arrives along `light.axis` everywhere.
    """
    pos = np.asarray(position, dtype=np.float64)
    if light.emission == "sun":
        # A sun has a direction only: the way to the light is -axis at every receiver.
        to_light = np.broadcast_to(-light.axis, pos.shape)
    else:
        to_light = light.position - pos
    nrm = np.asarray(normal, dtype=np.float64)
    # cos(normal, to_light) > GRAZING_COS, without dividing by the lengths.
    reach = np.linalg.norm(nrm, axis=-1) * np.linalg.norm(to_light, axis=-1)
    facing = np.einsum("...i,...i->...", nrm, to_light) > GRAZING_COS * reach
    mask = np.asarray(hit, dtype=bool) & facing & (np.asarray(unshadowed) > eps)
    mask &= np.all(np.isfinite(pos), axis=-1)
    if light.emission == "hemi":
        mask &= (-to_light) @ light.axis > 0.0
    elif light.emission == "spot":
        # angle(axis, pos - light) < spot_size / 2, without dividing by the distance;
        # the boundary itself is out, as for hemi (Cycles gives it no light either).
        cos_half = np.cos(0.5 * float(light.spot_size))
        mask &= (-to_light) @ light.axis > cos_half * np.linalg.norm(to_light, axis=-1)
    return mask


@dataclass
class ErrorFigure:
    error_pct: float
    false_shadow_pct: float
    false_lit_pct: float
    evaluated_pixels: int


def error_figure(estimate_lit: np.ndarray, reference_lit: np.ndarray, evaluable: np.ndarray) -> ErrorFigure:
    """Mismatch share of evaluated pixels, split into false shadow and false lit."""
    est = np.asarray(estimate_lit, dtype=bool)
    ref = np.asarray(reference_lit, dtype=bool)
    ev = np.asarray(evaluable, dtype=bool)
    n = int(np.count_nonzero(ev))
    if n == 0:
        return ErrorFigure(0.0, 0.0, 0.0, 0)
    false_shadow = int(np.count_nonzero(ev & ref & ~est))
    false_lit = int(np.count_nonzero(ev & ~ref & est))
    return ErrorFigure(100.0 * (false_shadow + false_lit) / n, 100.0 * false_shadow / n, 100.0 * false_lit / n, n)


def soft_error_pct(visibility: np.ndarray, reference_lit: np.ndarray, evaluable: np.ndarray) -> float:
    """Mean |visibility - reference| over evaluated pixels, in %; the reference is binary
    (lit) or fractional (`reference_ratio`). For a binary estimate and reference it
    equals the mismatch share. Non-finite visibility counts as fully wrong."""
    ev = np.asarray(evaluable, dtype=bool)
    if not ev.any():
        return 0.0
    vis = np.clip(np.nan_to_num(np.asarray(visibility, dtype=np.float64)[ev], nan=-1.0), 0.0, 1.0)
    ref = np.asarray(reference_lit, dtype=np.float64)[ev]
    bad = ~np.isfinite(np.asarray(visibility, dtype=np.float64)[ev])
    diff = np.where(bad, 1.0, np.abs(vis - ref))
    return float(100.0 * diff.mean())


@dataclass
class Judgement:
    """An estimate against the reference: the binary figure on the decisive pixels, the
    soft error on all of them, the fractional pixels' own soft error, and a sized light's
    reference noise in the soft error's unit."""

    figure: ErrorFigure
    soft_error_pct: float
    fractional_pixels: int
    fractional_soft_error_pct: float | None  # None without fractional pixels
    reference_noise_pct: float | None = None  # None for a noise-free (hard) reference

    def columns(self) -> dict:
        """The results columns (rows.make_row) besides the figure."""
        return {"soft_error_pct": self.soft_error_pct,
                "fractional_pixels": self.fractional_pixels or None,
                "fractional_soft_error_pct": self.fractional_soft_error_pct,
                "reference_noise_pct": self.reference_noise_pct}


def judge(visibility: np.ndarray, shadowed: np.ndarray, unshadowed: np.ndarray,
          evaluable: np.ndarray, sized: bool = False, noise: np.ndarray | None = None) -> Judgement:
    """The one way an estimate's visibility (H, W) is scored against Cycles' two passes.

    A hard light's binary figure leaves its fractional pixels out (see-through light,
    filtered rims). A sized light's penumbra is what is measured, so its figure counts
    every evaluated pixel on the side of 0.5 it falls; `noise` (H, W), the
    reference's own per pixel, gives reference_noise_pct = 100 x its mean there."""
    ratio = reference_ratio(shadowed, unshadowed)
    ev = np.asarray(evaluable, dtype=bool)
    fractional = ev & (ratio > FRACTIONAL_BAND[0]) & (ratio < FRACTIONAL_BAND[1])
    vis = np.asarray(visibility, dtype=np.float64)
    figure = error_figure(vis > 0.5, ratio >= 0.5, ev if sized else ev & ~fractional)
    count = int(np.count_nonzero(fractional))
    noise_pct = None
    if noise is not None:
        noise_pct = float(100.0 * np.asarray(noise, dtype=np.float64)[ev].mean()) if ev.any() else 0.0
    return Judgement(figure, soft_error_pct(vis, ratio, ev), count,
                     soft_error_pct(vis, ratio, fractional) if count else None, noise_pct)


def mismatch_image(grey_source: np.ndarray, estimate_lit: np.ndarray, reference_lit: np.ndarray,
                   evaluable: np.ndarray) -> np.ndarray:
    """RGB uint8 image: the reference rendering in grey, mismatches painted red.

    False shadow is pure red, false lit a lighter red, so both read as errors
    (as in the thesis figures) yet stay distinguishable.
    """
    src = np.asarray(grey_source, dtype=np.float64)
    finite = src[np.isfinite(src) & (src > 0)]
    top = float(np.percentile(finite, 99)) if finite.size else 1.0
    # NaN would cast to an undefined uint8; +inf saturates like the brightest pixel.
    src = np.nan_to_num(src, nan=0.0, posinf=top, neginf=0.0)
    grey = np.clip(src / max(top, 1e-12), 0.0, 1.0) ** (1 / 2.2)
    grey = 0.15 + 0.7 * grey
    img = np.repeat((grey * 255).astype(np.uint8)[..., None], 3, axis=-1)
    ev = np.asarray(evaluable, dtype=bool)
    est = np.asarray(estimate_lit, dtype=bool)
    ref = np.asarray(reference_lit, dtype=bool)
    img[ev & ref & ~est] = (230, 20, 20)
    img[ev & ~ref & est] = (255, 120, 120)
    return img


def write_mismatch_image(image_dir: Path, stem: str, grey_source: np.ndarray, estimate_lit: np.ndarray,
                         reference_lit: np.ndarray, evaluable: np.ndarray) -> str:
    """Write `mismatch_image` as `<stem>_mismatch.png` in `image_dir` (made if missing);
    the row's path to it, relative to the results folder."""
    from .png import write_png

    image_dir.mkdir(parents=True, exist_ok=True)
    write_png(image_dir / f"{stem}_mismatch.png", mismatch_image(grey_source, estimate_lit, reference_lit, evaluable))
    return f"images/{stem}_mismatch.png"
