"""The method registry (`addon/core/methods.py`): one consistent entry per method."""
from __future__ import annotations

import pytest

from addon.core import methods
from addon.core.errors import InputError
from addon.core.frames import parameterizations_for, takes_warp
from addon.core.scene import POINT_EMISSIONS, PROJECTIVE_EMISSIONS


def test_entries_are_consistent():
    """Fits follow frames.parameterizations_for; warps, cut and AA only where the pipeline takes them."""
    assert len(methods.names()) == len(set(methods.names())) == 15
    for name, entry in methods.METHODS.items():
        assert entry.name == name
        assert entry.description and "\n" not in entry.description
        if entry.external:
            assert entry.parameterization is None and entry.emissions == POINT_EMISSIONS
            continue
        assert entry.emissions == tuple(e for e in POINT_EMISSIONS + PROJECTIVE_EMISSIONS
                                        if entry.parameterization in parameterizations_for(e))
        assert entry.warp == "none" or takes_warp(entry.parameterization)
        assert not entry.cut or entry.parameterization == "ipsm"
        assert not entry.edge_aa or entry.parameterization == "unfold"
        assert not entry.exact or entry.parameterization in ("dpsm", "cube", "ipsm")
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
    assert methods.fits_text("spot") == "spot and sun lights take sm, psm"
    assert "eevee" in methods.fits_text("omni") and "eevee" not in methods.fits_text("omni", pipeline_only=True)
    with pytest.raises(InputError, match="does not fit an omni light"):
        methods.check_fits("sm", "omni")
    with pytest.raises(InputError, match="outside the pipeline"):
        methods.check_fits("eevee", "omni", pipeline_only=True)
    assert methods.default_method("hemi") == "dpsm+notw" and methods.default_method("sun") == "psm"
    assert methods.label_for("ipsm", "rtw") == "ipsm+rtw"  # a light's own settings no entry has
