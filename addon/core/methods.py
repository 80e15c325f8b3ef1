"""The shadow methods this build implements, each described once.

Every consumer reads this registry: `omniwarp compare` and `preview` (the method
lists of their `--help`, validation, which method fits which light), the compare
rows (`render.pipeline.settings_for` builds a method's `ShadowSettings`), the
headless preview, the light panel's tooltips and the comparison panel's checkboxes.

A method is a parameterization, a warp and two options (IPSM's skewed cut, unfold's
edge-distance antialiasing), or an *external* method that is measured outside the
pipeline (`eevee`: Blender's own shadows, rendered in a child process). The lights
a pipeline method fits follow from `frames.parameterizations_for`.

A method may take another parameterization for spot and sun lights (`projective`):
`exact` is the irregular z-buffer over the NoTW-warped dual paraboloid for point
lights and over the light's own plain map (`sm`) for spot cones and suns, one row
named `exact` either way. `Method.parameterization_for` and `Method.warp_for` say what
it draws for an emission; every consumer asks them.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

from .errors import InputError
from .frames import parameterizations_for, takes_warp
from .scene import POINT_EMISSIONS, PROJECTIVE_EMISSIONS

log = logging.getLogger(__name__)

EMISSIONS: tuple[str, ...] = POINT_EMISSIONS + PROJECTIVE_EMISSIONS

# What each parameterization and warp does and costs: the light panel's enum tooltips.
PARAMETERIZATION_TEXT: dict[str, str] = {
    "dpsm": "Two paraboloid maps, one per hemisphere. Cost: at most two passes; each triangle is drawn "
            "over a box around its curved image and every texel tests its own ray, so no tessellation",
    "cube": "Six 90° perspective faces. Cost: up to six passes (each redraws the geometry it sees), "
            "no tessellation",
    "ipsm": "One paraboloid map aimed at the view and zoomed to the cone that holds it, when the light is "
            "outside the view; otherwise (or with Cull off) it falls back to the dual paraboloid. Cost: one "
            "pass, drawn as the dual paraboloid's are (no tessellation)",
    "unfold": "Dual sphere-unfolding: both hemispheres side by side in one map, drawn in a single pass. "
              "Cost: one pass, with tessellation, and seam triangles drawn into both halves; takes no warp",
    "sm": "One plain shadow map: the spot's cone, or for a sun a parallel box fitted to what the view "
          "needs. Cost: one pass, no tessellation; takes no warp",
    "psm": "Perspective shadow map (Stamminger & Drettakis 2002): one map taken after the camera's "
           "perspective, so texels gather near the camera. Cost: one pass, no tessellation; it is "
           "itself a global warp, so it takes no other",
}
WARP_TEXT: dict[str, str] = {
    "none": "Uniform shadow map: no analysis pass, no ray table",
    "notw": "Non-orthogonal texture warping: moves map resolution to where the camera needs it. "
            "Cost: an analysis pass over the view samples, a ray table per map, and larger boxes around "
            "the triangles (the warp widens them)",
    "rtw": "Rectilinear texture warping (Rosen 2012), offered as a comparison to NoTW. "
           "Cost: the same analysis pass, ray table and triangle boxes",
}


@dataclass(frozen=True)
class Method:
    """One method: what the pipeline draws for it, or that it is measured elsewhere."""

    name: str
    parameterization: str | None  # None for an external method
    warp: str
    cut: bool  # ipsm only: the skewed axis and a crop fitted to the frustum
    edge_aa: bool  # unfold only: the paper's edge-distance antialiasing
    emissions: tuple[str, ...]  # the light emissions it can shadow
    description: str  # one line, for help texts and tooltips
    external: bool = False  # measured outside the pipeline (no ShadowSettings)
    exact: bool = False  # the irregular z-buffer over the map instead of its depths
    # The parameterization it draws for spot and sun lights, where that is not
    # `parameterization` (exact: the sm map); None: the same for every light.
    projective: str | None = None

    @property
    def pipeline(self) -> bool:
        """True when `ShadowPipeline` draws it."""
        return not self.external

    def parameterization_for(self, emission: str) -> str | None:
        """The parameterization it draws for a light of this emission (None when external)."""
        if self.projective is not None and emission in PROJECTIVE_EMISSIONS:
            return self.projective
        return self.parameterization

    def warp_for(self, emission: str) -> str:
        """Its warp for a light of this emission: none where that parameterization takes none."""
        parameterization = self.parameterization_for(emission)
        return self.warp if parameterization is not None and takes_warp(parameterization) else "none"

    def fits(self, emission: str) -> bool:
        """True when the method can shadow a light of this emission."""
        return emission in self.emissions


def _pipeline(name: str, parameterization: str, description: str, warp: str = "none", cut: bool = False,
              edge_aa: bool = False, exact: bool = False, projective: str | None = None) -> Method:
    def drawn(emission: str) -> str:
        return projective if projective is not None and emission in PROJECTIVE_EMISSIONS else parameterization

    emissions = tuple(e for e in EMISSIONS if drawn(e) in parameterizations_for(e))
    return Method(name, parameterization, warp, cut, edge_aa, emissions, description, exact=exact,
                  projective=projective)


_ENTRIES: tuple[Method, ...] = (
    _pipeline("dpsm", "dpsm", "dual paraboloid maps (at most two passes, exact curved footprints)"),
    _pipeline("cube", "cube", "cube maps (up to six passes, no tessellation)"),
    _pipeline("dpsm+notw", "dpsm", "dual paraboloid maps with NoTW warping (an analysis pass and a ray table per map)",
              warp="notw"),
    _pipeline("cube+notw", "cube", "cube maps with NoTW warping (an analysis pass and a ray table per map)", warp="notw"),
    _pipeline("dpsm+rtw", "dpsm", "dual paraboloid maps with RTW warping, for comparison with NoTW", warp="rtw"),
    _pipeline("cube+rtw", "cube", "cube maps with RTW warping, for comparison with NoTW", warp="rtw"),
    _pipeline("ipsm", "ipsm", "one paraboloid map zoomed to the view cone when the light is outside the view, "
                              "else dual paraboloid maps"),
    _pipeline("ipsm+notw", "ipsm", "ipsm with NoTW warping (an analysis pass and a ray table per map)", warp="notw"),
    _pipeline("ipsm+cut", "ipsm", "ipsm with the skewed cut: a tilted axis and a crop fitted to the view frustum",
              cut=True),
    _pipeline("unfold", "unfold", "dual sphere-unfolding (both halves in one pass)"),
    _pipeline("unfold+aa", "unfold", "dual sphere-unfolding with the paper's edge-distance antialiasing",
              edge_aa=True),
    _pipeline("exact", "dpsm", "exact hard shadows: an irregular z-buffer (the view samples in per-texel lists, "
                               "each triangle tested against them) over the NoTW-warped dual paraboloid, or over "
                               "a spot's or sun's own map",
              warp="notw", exact=True, projective="sm"),
    _pipeline("sm", "sm", "one uniform shadow map (spot and sun lights)"),
    _pipeline("psm", "psm", "a perspective shadow map in the camera's post-perspective space (spot and sun lights)"),
    # Blender's own shadows, rendered by EEVEE in a child process at the light's default and a
    # finer shadow resolution (so --resolutions do not apply): the anchor row of a comparison.
    Method("eevee", None, "none", False, False, EMISSIONS,
           "Blender's own EEVEE shadows, rendered in a child process (every light type; --resolutions do not apply)",
           external=True),
)
METHODS: dict[str, Method] = {entry.name: entry for entry in _ENTRIES}

# compare --methods: the plain maps and what warping does to them, side by side.
DEFAULT_METHODS: tuple[str, ...] = ("dpsm", "cube", "dpsm+notw", "cube+notw")
_DEFAULT_PREVIEW = {"point": "dpsm+notw", "projective": "psm"}  # preview, for lights without settings


def names() -> tuple[str, ...]:
    """Every method, in registry order."""
    return tuple(METHODS)


def pipeline_methods() -> tuple[str, ...]:
    """The methods the pipeline draws (every one but the external ones)."""
    return tuple(name for name, entry in METHODS.items() if entry.pipeline)


def external_methods() -> tuple[str, ...]:
    """The methods measured outside the pipeline (eevee)."""
    return tuple(name for name, entry in METHODS.items() if entry.external)


def method(name: str) -> Method:
    """The entry of `name`; an InputError naming the known methods if there is none."""
    entry = METHODS.get(name)
    if entry is None:
        raise InputError(f"unknown method {name!r}; this build implements: {', '.join(METHODS)}")
    return entry


def parse_methods(text: str) -> tuple[str, ...]:
    """Comma list of method names; none or an unknown name is an InputError."""
    given = tuple(s.strip() for s in text.split(",") if s.strip())
    if not given:
        raise InputError("no methods given; known: " + ", ".join(METHODS))
    for name in given:
        method(name)
    return given


def fits(name: str, emission: str) -> bool:
    """True when method `name` can shadow a light of this emission."""
    return method(name).fits(emission)


def fitting(emission: str, pipeline_only: bool = False) -> tuple[str, ...]:
    """The methods a light of this emission takes, in registry order (only the
    pipeline's with `pipeline_only`, as the preview draws)."""
    return tuple(name for name, entry in METHODS.items()
                 if entry.fits(emission) and (entry.pipeline or not pipeline_only))


def fits_text(emission: str, pipeline_only: bool = False) -> str:
    """Which methods a light of this emission takes, for messages."""
    kind = "spot and sun lights" if emission in PROJECTIVE_EMISSIONS else "point lights"
    return f"{kind} take " + ", ".join(fitting(emission, pipeline_only))


def light_phrase(emission: str) -> str:
    """'an omni light', 'a spot light': an emission named in a sentence."""
    article = "an" if emission[:1] in ("a", "e", "i", "o", "u") else "a"
    return f"{article} {emission} light"


def check_fits(name: str, emission: str, pipeline_only: bool = False) -> Method:
    """The entry of `name`, or an InputError when it does not fit a light of this emission
    (or, with `pipeline_only`, is not drawn by the pipeline)."""
    entry = method(name)
    if pipeline_only and entry.external:
        raise InputError(f"method {name} is measured outside the pipeline; "
                         f"only these can be drawn: {', '.join(pipeline_methods())}")
    if not entry.fits(emission):
        raise InputError(f"method {name} does not fit {light_phrase(emission)} "
                         f"({fits_text(emission, pipeline_only)})")
    return entry


def default_method(emission: str) -> str:
    """The preview's method for a light without OmniWarp settings."""
    return _DEFAULT_PREVIEW["projective" if emission in PROJECTIVE_EMISSIONS else "point"]


def label_for(parameterization: str, warp: str = "none", cut: bool = False, edge_aa: bool = False,
              exact: bool = False) -> str:
    """The method name of these settings, for any light the method fits (sm with exact is
    `exact`); settings no entry has (e.g. a light's ipsm + RTW) get the same
    'parameterization+warp' form."""
    for name, entry in METHODS.items():
        for emission in entry.emissions:
            if ((entry.parameterization_for(emission), entry.warp_for(emission), entry.cut, entry.edge_aa,
                 entry.exact) == (parameterization, warp, cut, edge_aa, exact)):
                return name
    return "+".join([parameterization] + ([warp] if warp != "none" else []) + (["cut"] if cut else [])
                    + (["aa"] if edge_aa else []) + (["exact"] if exact else []))


def help_list() -> str:
    """Every method name, comma separated, for the command line's help."""
    return ", ".join(METHODS)
