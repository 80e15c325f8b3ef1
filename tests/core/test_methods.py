"""The method registry (`addon/core/methods.py`): one consistent entry per method."""
from __future__ import annotations

import pytest

from addon.core import methods
from addon.core.errors import InputError
from addon.core.frames import parameterizations_for, takes_exact, takes_warp
from addon.core.scene import POINT_EMISSIONS, PROJECTIVE_EMISSIONS


def test_entries_are_consistent():
    """Fits follow frames.parameterizations_for; warps, cut and AA only where the pipeline takes them."""
    assert len(methods.names()) == len(set(methods.names())) == 15
    for name, entry in methods.METHODS.items():
        assert entry.name == name
        assert entry.description and "\n" not in entry.description
        if entry.external:
            assert entry.parameterization is None and entry.emissions == POINT_EMISSIONS + PROJECTIVE_EMISSIONS
            continue
        assert entry.emissions == tuple(e for e in POINT_EMISSIONS + PROJECTIVE_EMISSIONS
                                        if entry.parameterization_for(e) in parameterizations_for(e))
        for emission in entry.emissions:
            parameterization = entry.parameterization_for(emission)
            assert entry.warp_for(emission) == "none" or takes_warp(parameterization)
            assert not entry.exact or takes_exact(parameterization)
        assert entry.warp == "none" or takes_warp(entry.parameterization)
        assert not entry.cut or entry.parameterization == "ipsm"
        assert not entry.edge_aa or entry.parameterization == "unfold"
    assert methods.label_for("dpsm", "notw", exact=True) == "exact"
    assert methods.label_for("dpsm", "notw") == "dpsm+notw"
    assert methods.external_methods() == ("eevee",)
    assert set(methods.pipeline_methods()) | {"eevee"} == set(methods.names())


def test_lookups_and_messages():
    assert methods.parse_methods(" dpsm , ipsm+cut ") == ("dpsm", "ipsm+cut")
    with pytest.raises(InputError, match="unknown method 'warp9'.*unfold\\+aa"):
        methods.parse_methods("dpsm,warp9")
    with pytest.raises(InputError, match="no methods given"):
        methods.parse_methods(" , ")
    assert methods.fits("psm", "sun") and not methods.fits("psm", "omni")
    assert methods.fits_text("spot") == "spot and sun lights take exact, sm, psm, eevee"
    assert methods.fits_text("spot", pipeline_only=True) == "spot and sun lights take exact, sm, psm"
    assert "eevee" in methods.fits_text("omni") and "eevee" not in methods.fits_text("omni", pipeline_only=True)
    with pytest.raises(InputError, match="does not fit an omni light"):
        methods.check_fits("sm", "omni")
    with pytest.raises(InputError, match="outside the pipeline"):
        methods.check_fits("eevee", "omni", pipeline_only=True)
    assert methods.default_method("hemi") == "dpsm+notw" and methods.default_method("sun") == "psm"
    assert methods.label_for("ipsm", "rtw") == "ipsm+rtw"  # a light's own settings no entry has


@pytest.mark.parametrize("emission", PROJECTIVE_EMISSIONS)
def test_exact_fits_spot_and_sun_lights_over_their_own_map(emission):
    """One row named `exact` for every light: the NoTW-warped dual paraboloid for point
    lights, the light's plain map (sm, which takes no warp) for spot cones and suns; the
    settings a light panel makes of sm with Exact are named `exact` too."""
    from addon.render.frame import settings_for

    entry = methods.check_fits("exact", emission, pipeline_only=True)
    assert (entry.parameterization_for(emission), entry.warp_for(emission)) == ("sm", "none")
    assert (entry.parameterization_for("omni"), entry.warp_for("hemi")) == ("dpsm", "notw")
    assert "exact" in methods.fitting(emission, pipeline_only=True)
    settings = settings_for("exact", 512, emission)
    assert (settings.parameterization, settings.warp, settings.exact) == ("sm", "none", True)
    assert settings_for("exact", 512).parameterization == "dpsm"
    assert methods.label_for("sm", exact=True) == "exact" and methods.label_for("sm") == "sm"
    assert methods.label_for("psm", exact=True) == "psm+exact"  # no entry draws it
    with pytest.raises(InputError, match="exact.*not psm"):
        settings_for("psm", 512, emission).__class__("psm", 512, exact=True)


def test_an_emission_is_named_with_its_article():
    assert [methods.light_phrase(e) for e in ("omni", "hemi", "spot", "sun")] == [
        "an omni light", "a hemi light", "a spot light", "a sun light"]
