"""The bpy settings and panels of OmniWarp (addon.blender.properties / panels /
registration), in background bpy.

The runtime modules (viewport draw handlers, depsgraph cache) belong to other
tests: `RUNTIME_MODULES` is patched to () and the viewport module that the
property callbacks call is replaced by a recorder.
"""
from __future__ import annotations

import logging
import math
import re
from types import ModuleType, SimpleNamespace

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from addon.blender import events, panels, properties, registration  # noqa: E402
from addon.core import methods as method_registry  # noqa: E402
from addon.core.errors import InputError  # noqa: E402
from addon.render.pipeline import BiasSettings, ShadowSettings  # noqa: E402

pytestmark = pytest.mark.blender

PG_NAME = re.compile(r"OMNIWARP_PG_[a-z][a-z0-9_]*")
PT_NAME = re.compile(r"OMNIWARP_PT_[a-z][a-z0-9_]*")


# ----------------------------------------------------------------------------
# fakes
# ----------------------------------------------------------------------------
class ViewportRecorder:
    """Stands in for the viewport's event listeners: records what the callbacks ask for."""

    def __init__(self) -> None:
        self.calls: list[tuple] = []

    def request_update(self, reason: str) -> None:
        self.calls.append(("request_update", reason))

    def set_preview_enabled(self, context, enabled: bool) -> None:
        self.calls.append(("set_preview_enabled", enabled))


class FakeLayout:
    """Records what a panel draws and checks every `prop()` names a real RNA property."""

    def __init__(self, record: list[tuple] | None = None) -> None:
        self.record: list[tuple] = [] if record is None else record
        self.use_property_split = False
        self.use_property_decorate = True
        self.active = True
        self.enabled = True
        self.alignment = "EXPAND"

    def prop(self, data, attr: str, **kwargs) -> None:
        assert attr in data.bl_rna.properties, f"{type(data).__name__} has no property {attr!r}"
        getattr(data, attr)
        self.record.append(("prop", attr, self))  # the layout, to check its active/enabled

    def label(self, text: str = "", icon: str = "NONE", **kwargs) -> None:
        self.record.append(("label", text))

    def separator(self, **kwargs) -> None:
        self.record.append(("separator",))

    def _child(self, kind: str) -> FakeLayout:
        self.record.append((kind,))
        return FakeLayout(self.record)

    def row(self, **kwargs) -> FakeLayout:
        return self._child("row")

    def column(self, **kwargs) -> FakeLayout:
        return self._child("column")

    def box(self) -> FakeLayout:
        return self._child("box")

    def props(self) -> list[str]:
        return [r[1] for r in self.record if r[0] == "prop"]

    def labels(self) -> list[str]:
        return [r[1] for r in self.record if r[0] == "label"]

    def layout_of(self, attr: str) -> FakeLayout:
        """The (sub)layout that drew property `attr`."""
        return next(r[2] for r in self.record if r[:2] == ("prop", attr))


def draw_panel(panel_cls: type, context, header: bool = False) -> FakeLayout:
    """Run a panel's draw (or draw_header) against a FakeLayout."""
    layout = FakeLayout()
    fake_self = SimpleNamespace(layout=layout)
    (panel_cls.draw_header if header else panel_cls.draw)(fake_self, context)
    return layout


# ----------------------------------------------------------------------------
# fixtures
# ----------------------------------------------------------------------------
@pytest.fixture
def recorder(monkeypatch: pytest.MonkeyPatch) -> ViewportRecorder:
    rec = ViewportRecorder()
    monkeypatch.setattr(events, "_LISTENERS", {"request_update": rec.request_update,
                                               "set_preview_enabled": rec.set_preview_enabled})
    return rec


@pytest.fixture
def no_runtime(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(registration, "RUNTIME_MODULES", ())


@pytest.fixture
def registered(no_runtime, recorder: ViewportRecorder):
    registration.unregister()  # start clean whatever ran before
    registration.register()
    yield recorder
    registration.unregister()


@pytest.fixture
def make_light(registered):
    """Factory for light datablocks; removes them afterwards."""
    made: list = []

    def make(kind: str = "POINT", spot_deg: float | None = None):
        light = bpy.data.lights.new(f"omniwarp_test_{kind.lower()}", kind)
        if spot_deg is not None:
            light.spot_size = math.radians(spot_deg)
        made.append(light)
        return light

    yield make
    for light in made:
        bpy.data.lights.remove(light)


@pytest.fixture
def light_object(make_light):
    """A factory for light objects linked to the current scene; unlinked and removed afterwards."""
    made: list = []

    def make(name: str, kind: str = "POINT", enabled: bool = True):
        light = make_light(kind)
        light.omniwarp.enabled = enabled
        obj = bpy.data.objects.new(name, light)
        bpy.context.scene.collection.objects.link(obj)
        made.append(obj)
        return obj

    yield make
    for obj in made:
        bpy.data.objects.remove(obj)


# ----------------------------------------------------------------------------
# registration
# ----------------------------------------------------------------------------
def _is_registered() -> bool:
    return hasattr(bpy.types.Light, "omniwarp") or hasattr(bpy.types.Scene, "omniwarp")


def test_register_unregister_round_trip_twice(no_runtime) -> None:
    registration.unregister()
    for _ in range(2):
        registration.register()
        assert hasattr(bpy.types.Light, "omniwarp")
        assert hasattr(bpy.types.Scene, "omniwarp")
        assert all(cls.is_registered for cls in registration.CLASSES)
        light = bpy.data.lights.new("omniwarp_round_trip", "POINT")
        try:
            assert isinstance(light.omniwarp, properties.OMNIWARP_PG_light)
        finally:
            bpy.data.lights.remove(light)
        registration.unregister()
        assert not _is_registered()
        assert not any(cls.is_registered for cls in registration.CLASSES)
    registration.unregister()  # unregistering again must not raise
    assert not _is_registered()


def test_classes_ordered_and_named() -> None:
    names = [cls.__name__ for cls in registration.CLASSES]
    groups = [cls for cls in registration.CLASSES if issubclass(cls, bpy.types.PropertyGroup)]
    panel_classes = [cls for cls in registration.CLASSES if issubclass(cls, bpy.types.Panel)]
    assert len(groups) + len(panel_classes) == len(names) == len(set(names))
    assert registration.CLASSES[: len(groups)] == tuple(groups), "PropertyGroups come first"
    for cls in groups:
        assert PG_NAME.fullmatch(cls.__name__), cls.__name__
    for cls in panel_classes:
        assert PT_NAME.fullmatch(cls.__name__), cls.__name__
        assert cls.bl_idname == cls.__name__
        assert cls.bl_label
        parent = getattr(cls, "bl_parent_id", "")
        if parent:
            assert parent in names[: names.index(cls.__name__)], f"{cls.__name__}: parent {parent} registered later"
    assert {group for _, _, group in registration.POINTERS} == set(groups)
    assert [m.__name__.rpartition(".")[2] for m in registration.RUNTIME_MODULES] == ["scene_cache", "viewport"]


def _fake_runtime(name: str, log: list[str], fail: bool = False) -> ModuleType:
    module = ModuleType(f"{registration.__package__}.{name}")

    def register() -> None:
        log.append(f"register {name}")
        assert hasattr(bpy.types.Light, "omniwarp"), "runtime modules register after the pointers"
        if fail:
            raise RuntimeError(f"{name} failed on purpose")

    def unregister() -> None:
        log.append(f"unregister {name}")
        assert hasattr(bpy.types.Light, "omniwarp"), "runtime modules unregister before the pointers go"

    module.register, module.unregister = register, unregister
    return module


def test_runtime_modules_called_in_order_and_reverse(monkeypatch: pytest.MonkeyPatch) -> None:
    log: list[str] = []
    names = (_fake_runtime("_test_rt_a", log), _fake_runtime("_test_rt_b", log))
    monkeypatch.setattr(registration, "RUNTIME_MODULES", ())
    registration.unregister()  # start clean, without the fakes
    monkeypatch.setattr(registration, "RUNTIME_MODULES", names)
    registration.register()
    registration.unregister()
    assert log == ["register _test_rt_a", "register _test_rt_b", "unregister _test_rt_b", "unregister _test_rt_a"]
    assert not _is_registered()


def test_failed_register_rolls_back(monkeypatch: pytest.MonkeyPatch) -> None:
    log: list[str] = []
    names = (_fake_runtime("_test_rt_ok", log), _fake_runtime("_test_rt_bad", log, fail=True))
    monkeypatch.setattr(registration, "RUNTIME_MODULES", ())
    registration.unregister()  # start clean, without the fakes
    monkeypatch.setattr(registration, "RUNTIME_MODULES", names)
    with pytest.raises(RuntimeError, match="on purpose"):
        registration.register()
    assert log == ["register _test_rt_ok", "register _test_rt_bad", "unregister _test_rt_ok"]
    assert not _is_registered()
    assert not any(cls.is_registered for cls in registration.CLASSES)


# ----------------------------------------------------------------------------
# properties
# ----------------------------------------------------------------------------
def test_light_defaults(make_light) -> None:
    props = make_light("POINT").omniwarp
    assert props.enabled is False
    assert props.emission == "AUTO"
    assert props.parameterization == "DPSM"
    assert props.warp == "NONE"
    assert props.resolution == 1024
    assert props.bias_constant == pytest.approx(0.3)
    assert props.bias_slope == pytest.approx(0.7)
    assert props.bias_normal == pytest.approx(0.7)
    assert props.cull is True


def test_light_ranges(make_light) -> None:
    props = make_light("POINT").omniwarp
    props.resolution = 100
    assert props.resolution == 256
    props.resolution = 100000
    assert props.resolution == 4096
    props.bias_slope = -1.0
    assert props.bias_slope == 0.0
    rna = properties.OMNIWARP_PG_light.bl_rna.properties
    assert (rna["resolution"].hard_min, rna["resolution"].hard_max) == (256, 4096)
    assert rna["resolution"].subtype == "NONE"
    for name in ("bias_constant", "bias_slope", "bias_normal"):
        assert rna[name].hard_min == 0.0
        assert (rna[name].soft_min, rna[name].soft_max) == (0.0, 4.0)
    assert [i.identifier for i in rna["emission"].enum_items] == ["AUTO", "OMNI", "HEMI"]
    assert [i.identifier for i in rna["warp"].enum_items] == ["NONE", "NOTW", "RTW"]
    # A dynamic enum: the class's RNA lists no items, the light's callback does.
    assert list(rna["parameterization"].enum_items_static) == []
    # Stable numbers: .blend files store them.
    assert [(item[0], item[3]) for item in properties.PARAMETERIZATION_ITEMS] == [
        ("DPSM", 0), ("CUBE", 1), ("IPSM", 2), ("UNFOLD", 3), ("SM", 4), ("PSM", 5)]


def test_scene_defaults_and_ranges(registered) -> None:
    settings = bpy.context.scene.omniwarp
    assert settings.preview_enabled is False
    assert settings.shadow_strength == pytest.approx(0.6)
    assert settings.overlay_enabled is True
    assert set(settings.overlay_maps) == {"DEPTH", "COUNT", "IMPORTANCE"}
    assert settings.overlay_size == 160
    assert settings.overlay_corner == "BOTTOM_LEFT"
    assert settings.overlay_stats is True
    assert settings.camera_resolution_scale == pytest.approx(0.5)
    assert settings.throttle_ms == 250
    rna = properties.OMNIWARP_PG_scene.bl_rna.properties
    assert rna["overlay_maps"].is_enum_flag
    assert [i.identifier for i in rna["overlay_corner"].enum_items] == [
        "BOTTOM_LEFT", "BOTTOM_RIGHT", "TOP_LEFT", "TOP_RIGHT"]
    for name, lo, hi in (("shadow_strength", 0.0, 1.0), ("overlay_size", 64, 512),
                         ("camera_resolution_scale", 0.1, 1.0), ("throttle_ms", 0, 2000)):
        assert rna[name].hard_min == pytest.approx(lo), name
        assert rna[name].hard_max == pytest.approx(hi), name
    try:
        settings.overlay_size = 8
        assert settings.overlay_size == 64
        settings.camera_resolution_scale = 3.0
        assert settings.camera_resolution_scale == pytest.approx(1.0)
        settings.overlay_maps = {"COUNT"}
        assert set(settings.overlay_maps) == {"COUNT"}
    finally:
        for name in ("overlay_size", "camera_resolution_scale", "overlay_maps"):
            settings.property_unset(name)


@pytest.mark.parametrize("group", ["OMNIWARP_PG_light", "OMNIWARP_PG_scene"])
def test_every_property_has_a_description(registered, group: str) -> None:
    rna = getattr(properties, group).bl_rna.properties
    own = [p for p in rna if p.identifier not in ("rna_type", "name")]
    assert own
    for prop in own:
        assert len(prop.description) > 20, f"{group}.{prop.identifier} needs a tooltip"
        assert prop.name, f"{group}.{prop.identifier} needs a UI name"
        if prop.type == "ENUM":
            for item in prop.enum_items:
                assert item.description, f"{group}.{prop.identifier}: item {item.identifier} needs a tooltip"
    if group == "OMNIWARP_PG_light":  # the dynamic enum's items are not in the class's RNA
        for identifier, name, description, _number in properties.PARAMETERIZATION_ITEMS:
            assert name and len(description) > 40, f"parameterization item {identifier} needs a tooltip"


def test_cost_is_in_the_tooltips(make_light) -> None:
    rna = properties.OMNIWARP_PG_light.bl_rna.properties
    assert "6 × resolution²" in rna["resolution"].description
    items = {identifier: description for identifier, _, description, _ in properties.PARAMETERIZATION_ITEMS}
    assert "no tessellation" in items["DPSM"] and "six passes" in items["CUBE"]
    assert "one pass" in items["IPSM"] and "no tessellation" in items["IPSM"] and "falls back" in items["IPSM"]
    assert "single pass" in items["UNFOLD"] and "tessellat" in items["UNFOLD"] and "no warp" in items["UNFOLD"]
    for name in ("SM", "PSM"):
        assert "one pass" in items[name] and "no tessellation" in items[name], name
    assert "Stamminger" in items["PSM"]
    # Blender shows the callback's tooltips for the light's own items only.
    sun = make_light("SUN").omniwarp
    assert bpy.types.UILayout.enum_item_description(sun, "parameterization", "PSM") == items["PSM"]
    assert bpy.types.UILayout.enum_item_name(sun, "parameterization", "DPSM") == ""
    warps = {i.identifier: i.description for i in rna["warp"].enum_items}
    assert "analysis" in warps["NOTW"] and "ray table" in warps["NOTW"] and "triangles" in warps["NOTW"]
    assert "comparison" in warps["RTW"]


def test_update_callbacks_reach_the_viewport(make_light, registered) -> None:
    recorder = registered
    props = make_light("POINT").omniwarp
    recorder.calls.clear()
    for name, value in (("enabled", True), ("emission", "HEMI"), ("parameterization", "CUBE"),
                        ("warp", "NOTW"), ("resolution", 512), ("bias_constant", 1.0),
                        ("bias_slope", 1.0), ("bias_normal", 1.0), ("exact", True), ("cull", False)):
        setattr(props, name, value)
        assert recorder.calls[-1] == ("request_update", "light settings"), name
    assert len(recorder.calls) == 10

    settings = bpy.context.scene.omniwarp
    recorder.calls.clear()
    try:
        settings.preview_enabled = True
        assert recorder.calls == [("set_preview_enabled", True)]
        settings.preview_enabled = False
        assert recorder.calls[-1] == ("set_preview_enabled", False)
    finally:
        settings.property_unset("preview_enabled")


def test_callbacks_without_viewport_module(monkeypatch: pytest.MonkeyPatch, make_light) -> None:
    monkeypatch.setattr(events, "_LISTENERS", {})
    props = make_light("POINT").omniwarp
    props.resolution = 2048  # no viewport: nothing to notify, no error
    assert props.resolution == 2048
    settings = bpy.context.scene.omniwarp
    try:
        settings.preview_enabled = True
        settings.overlay_size = 200
    finally:
        settings.property_unset("preview_enabled")
        settings.property_unset("overlay_size")


def test_viewport_listens_only_while_registered(monkeypatch: pytest.MonkeyPatch) -> None:
    from addon.blender import viewport

    monkeypatch.setattr(events, "_LISTENERS", {})
    viewport.register()
    try:
        assert events._LISTENERS == {"request_update": viewport.request_update,
                                     "set_preview_enabled": viewport.set_preview_enabled,
                                     "last_error": viewport.last_error}
    finally:
        viewport.unregister()
    assert events._LISTENERS == {}
    assert events.notify("last_error", default="") == ""


# ----------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------
@pytest.mark.parametrize(("kind", "spot_deg", "expected"), [
    ("POINT", None, "omni"),
    ("SPOT", 180.0, "hemi"),
    ("SPOT", 179.0, "hemi"),
    ("SPOT", 178.0, "spot"),
    ("SPOT", 45.0, "spot"),
    ("SUN", None, "sun"),
])
def test_effective_emission_auto(make_light, kind: str, spot_deg: float | None, expected: str) -> None:
    assert properties.effective_emission(make_light(kind, spot_deg)) == expected


def test_effective_emission_explicit(make_light) -> None:
    point, wide = make_light("POINT"), make_light("SPOT", 180.0)
    narrow, sun = make_light("SPOT", 60.0), make_light("SUN")
    point.omniwarp.emission = "HEMI"
    wide.omniwarp.emission = "OMNI"
    assert properties.effective_emission(point) == "hemi"
    assert properties.effective_emission(wide) == "omni"
    # An explicit choice on a narrow spot still means the point-light treatment.
    narrow.omniwarp.emission = "OMNI"
    assert properties.effective_emission(narrow) == "omni"
    narrow.omniwarp.emission = "HEMI"
    assert properties.effective_emission(narrow) == "hemi"
    # A sun's light is parallel whatever was chosen.
    sun.omniwarp.emission = "OMNI"
    assert properties.effective_emission(sun) == "sun"


def test_is_supported_light(make_light) -> None:
    assert properties.is_supported_light(make_light("POINT"))
    assert properties.is_supported_light(make_light("SPOT"))
    assert properties.is_supported_light(make_light("SUN"))
    assert properties.is_supported_light(make_light("AREA"))
    assert not properties.is_supported_light(None)


def test_an_area_light_is_a_sized_hemispherical_light(make_light) -> None:
    """One-sided, so the hemispherical methods; its size scaled by the object (issue 27)."""
    light = make_light("AREA")
    light.shape, light.size, light.size_y = "RECTANGLE", 1.2, 0.8
    assert properties.effective_emission(light) == "hemi"
    assert _item_ids(light) == POINT_ITEMS
    obj = bpy.data.objects.new("area_probe", light)
    try:
        obj.matrix_world = ((2.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 1.0, 3.0), (0.0, 0.0, 0.0, 1.0))
        spec = properties.light_spec_for(obj)
        assert spec.emission == "hemi" and spec.sized
        assert spec.shape.outline == "rectangle"
        assert spec.shape.size_x == pytest.approx(2.4) and spec.shape.size_y == pytest.approx(0.8)
    finally:
        bpy.data.objects.remove(obj)


POINT_ITEMS = ["DPSM", "CUBE", "IPSM", "UNFOLD"]
PROJECTIVE_ITEMS = ["SM", "PSM"]


def _item_ids(light) -> list[str]:
    return [item[0] for item in properties.parameterization_items(light.omniwarp, bpy.context)]


@pytest.mark.parametrize(("kind", "spot_deg", "emission", "expected"), [
    ("POINT", None, "AUTO", POINT_ITEMS),
    ("POINT", None, "HEMI", POINT_ITEMS),
    ("SPOT", 180.0, "AUTO", POINT_ITEMS),
    ("SPOT", 60.0, "AUTO", PROJECTIVE_ITEMS),
    ("SPOT", 60.0, "OMNI", POINT_ITEMS),
    ("SPOT", 60.0, "HEMI", POINT_ITEMS),
    ("SUN", None, "AUTO", PROJECTIVE_ITEMS),
    ("SUN", None, "OMNI", PROJECTIVE_ITEMS),
])
def test_parameterization_items_fit_the_light(make_light, kind: str, spot_deg: float | None, emission: str,
                                              expected: list[str]) -> None:
    light = make_light(kind, spot_deg)
    light.omniwarp.emission = emission
    assert _item_ids(light) == expected
    assert [name.upper() for name in properties.valid_parameterizations(light)] == expected
    # Blender takes exactly these: the others are refused with a TypeError.
    for identifier, *_ in properties.PARAMETERIZATION_ITEMS:
        if identifier in expected:
            light.omniwarp.parameterization = identifier
            assert light.omniwarp.parameterization == identifier
        else:
            with pytest.raises(TypeError):
                light.omniwarp.parameterization = identifier


def test_parameterization_items_are_cached(make_light) -> None:
    """The callback hands out the module's lists, never fresh ones (Blender keeps their strings)."""
    point, sun = make_light("POINT"), make_light("SUN")
    first = properties.parameterization_items(point.omniwarp, None)
    assert properties.parameterization_items(point.omniwarp, None) is first
    assert properties.parameterization_items(sun.omniwarp, None) is properties.parameterization_items(sun.omniwarp,
                                                                                                      None)
    assert first in properties._PARAMETERIZATION_ITEM_CACHE.values()


def test_switching_point_to_sun_falls_back_to_psm(make_light, caplog: pytest.LogCaptureFixture) -> None:
    light = make_light("POINT")
    props = light.omniwarp
    props.parameterization = "CUBE"
    props.warp = "NOTW"
    light.type = "SUN"
    light = bpy.data.lights[light.name]  # the same ID, now a SunLight
    with caplog.at_level(logging.DEBUG, logger=properties.__name__):
        settings = properties.shadow_settings_for(light)  # must not raise
    assert (settings.parameterization, settings.warp) == ("psm", "none")
    assert "does not fit its sun emission; using psm" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.DEBUG, logger=properties.__name__):
        properties.shadow_settings_for(make_light("SUN"))  # a fresh sun: nothing stored, nothing to report
    assert "does not fit" not in caplog.text
    assert properties.effective_parameterization(light) == "psm"
    if properties._HAS_GET_TRANSFORM:
        assert light.omniwarp.parameterization == "PSM"  # Blender 5.0+: the field shows what is used
    else:
        assert properties.stored_parameterization(light) == "cube"  # kept; the panel notes the fallback
    light.type = "POINT"  # the stored choice comes back with a type it fits
    light = bpy.data.lights[light.name]
    settings = properties.shadow_settings_for(light)
    assert (settings.parameterization, settings.warp) == ("cube", "notw")


def test_narrowing_a_spot_falls_back_to_psm(make_light) -> None:
    light = make_light("SPOT", 180.0)
    light.omniwarp.parameterization = "IPSM"
    assert properties.shadow_settings_for(light).parameterization == "ipsm"
    light.spot_size = math.radians(60.0)
    assert properties.shadow_settings_for(light).parameterization == "psm"
    light.omniwarp.parameterization = "SM"
    light.spot_size = math.radians(180.0)  # wide again: sm does not fit a hemispherical light
    assert properties.shadow_settings_for(light).parameterization == "dpsm"


def test_unknown_stored_number_falls_back(make_light, capfd: pytest.CaptureFixture[str]) -> None:
    point, sun = make_light("POINT"), make_light("SUN")
    for light in (point, sun):
        light.omniwarp["parameterization"] = 42  # e.g. written by a newer version of the extension
    capfd.readouterr()
    assert properties.shadow_settings_for(point).parameterization == "dpsm"
    assert properties.shadow_settings_for(sun).parameterization == "psm"
    assert panels._light_summary(sun) == "PSM, 1024 px, sun"
    # Resolving a stale value must not make Blender print "matches no enum" on every read
    # (its log goes to stdout or stderr, depending on the version).
    captured = capfd.readouterr()
    assert "matches no enum" not in captured.out + captured.err


@pytest.mark.parametrize(("kind", "spot_deg", "parameterization", "warp", "expected_warp"), [
    ("POINT", None, "DPSM", "NOTW", "notw"),
    ("POINT", None, "CUBE", "RTW", "rtw"),
    ("POINT", None, "IPSM", "NOTW", "notw"),
    ("POINT", None, "UNFOLD", "NOTW", "none"),
    ("POINT", None, "UNFOLD", "RTW", "none"),
    ("SPOT", 60.0, "SM", "RTW", "none"),
    ("SPOT", 60.0, "PSM", "NOTW", "none"),
    ("SUN", None, "SM", "NOTW", "none"),
    ("SUN", None, "PSM", "RTW", "none"),
])
def test_shadow_settings_for_forces_no_warp(make_light, kind: str, spot_deg: float | None, parameterization: str,
                                           warp: str, expected_warp: str) -> None:
    light = make_light(kind, spot_deg)
    light.omniwarp.parameterization = parameterization
    light.omniwarp.warp = warp
    settings = properties.shadow_settings_for(light)  # ShadowSettings refuses a warp it cannot take
    assert (settings.parameterization, settings.warp) == (parameterization.lower(), expected_warp)
    assert light.omniwarp.warp == warp  # the stored warp is kept for a method that takes one


@pytest.mark.parametrize("parameterization", ["DPSM", "CUBE"])
@pytest.mark.parametrize("warp", ["NONE", "NOTW", "RTW"])
def test_shadow_settings_for(make_light, parameterization: str, warp: str) -> None:
    light = make_light("POINT")
    props = light.omniwarp
    props.parameterization = parameterization
    props.warp = warp
    props.resolution = 2048
    props.bias_constant, props.bias_slope, props.bias_normal = 0.25, 1.5, 2.0
    props.cull = False
    settings = properties.shadow_settings_for(light)
    assert isinstance(settings, ShadowSettings)
    assert settings.parameterization == parameterization.lower()
    assert settings.warp == warp.lower()
    assert settings.resolution == 2048
    assert settings.bias == BiasSettings(constant=0.25, slope=1.5, normal=2.0)
    assert settings.cull is False
    assert settings.exact is False
    props.exact = True
    assert properties.shadow_settings_for(light).exact is (parameterization in ("DPSM", "CUBE", "IPSM"))


@pytest.mark.parametrize(("kind", "spot_deg", "expected"), [
    ("POINT", None, "dpsm"),
    ("SPOT", 180.0, "dpsm"),
    ("SPOT", 45.0, "psm"),  # the default item (DPSM) does not fit a spot cone
    ("SUN", None, "psm"),
])
def test_shadow_settings_for_defaults(make_light, kind: str, spot_deg: float | None, expected: str) -> None:
    settings = properties.shadow_settings_for(make_light(kind, spot_deg))
    assert settings == ShadowSettings(parameterization=expected, resolution=1024, bias=BiasSettings(), cull=True,
                                      warp="none")


def test_light_spec_for(make_light) -> None:
    from mathutils import Euler, Matrix

    light = make_light("SPOT", 180.0)
    light.energy = 250.0
    obj = bpy.data.objects.new("omniwarp_test_spec", light)
    try:
        obj.matrix_world = Matrix.Translation((1.0, -2.0, 3.0)) @ Euler((math.pi, 0.0, 0.0)).to_matrix().to_4x4()
        spec = properties.light_spec_for(obj)
        assert spec.emission == "hemi"
        assert spec.energy == pytest.approx(250.0)
        assert spec.matrix_world.shape == (4, 4) and spec.matrix_world.dtype == np.float64
        np.testing.assert_allclose(spec.position, [1.0, -2.0, 3.0])
        np.testing.assert_allclose(spec.axis, [0.0, 0.0, 1.0], atol=1e-6)  # local -Z turned upward
        assert spec.spot_size == pytest.approx(math.pi)  # a hemispherical light keeps the default
        light.omniwarp.emission = "OMNI"
        assert properties.light_spec_for(obj).emission == "omni"
    finally:
        bpy.data.objects.remove(obj)


def test_light_spec_for_spot_and_sun(make_light) -> None:
    spot, sun = make_light("SPOT", 60.0), make_light("SUN")
    sun.energy = 3.0
    objects = [bpy.data.objects.new(f"omniwarp_test_{light.type.lower()}", light) for light in (spot, sun)]
    try:
        spec = properties.light_spec_for(objects[0])
        assert spec.emission == "spot"
        assert spec.spot_size == pytest.approx(math.radians(60.0), abs=1e-6)  # float32 in Blender
        assert spec.spot_size == float(spot.spot_size)
        spot.omniwarp.emission = "OMNI"  # the point-light treatment: no cone
        assert properties.light_spec_for(objects[0]).emission == "omni"
        spec = properties.light_spec_for(objects[1])
        assert (spec.emission, spec.energy) == ("sun", pytest.approx(3.0))
    finally:
        for obj in objects:
            bpy.data.objects.remove(obj)


def test_light_spec_for_rejects_non_lights(registered) -> None:
    mesh = bpy.data.meshes.new("omniwarp_test_mesh")
    obj = bpy.data.objects.new("omniwarp_test_mesh", mesh)
    try:
        with pytest.raises(TypeError, match="not a light"):
            properties.light_spec_for(obj)
    finally:
        bpy.data.objects.remove(obj)
        bpy.data.meshes.remove(mesh)


# ----------------------------------------------------------------------------
# panels
# ----------------------------------------------------------------------------
def test_light_panel_poll(make_light) -> None:
    poll = panels.OMNIWARP_PT_light.poll
    assert poll(SimpleNamespace(light=make_light("POINT")))
    assert poll(SimpleNamespace(light=make_light("SPOT")))
    assert poll(SimpleNamespace(light=make_light("SUN")))
    assert poll(SimpleNamespace(light=make_light("AREA")))  # a one-sided, sized hemispherical light
    assert not poll(SimpleNamespace(light=None))  # e.g. a mesh is active
    assert not poll(SimpleNamespace())


def test_light_panel_poll_with_active_object(make_light) -> None:
    """With the real context: a light object active gives context.object.data as the light."""
    view_layer = bpy.context.view_layer
    light = make_light("POINT")
    obj = bpy.data.objects.new("omniwarp_test_active", light)
    mesh = bpy.data.meshes.new("omniwarp_test_active_mesh")
    mesh_obj = bpy.data.objects.new("omniwarp_test_active_mesh", mesh)
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.scene.collection.objects.link(mesh_obj)
    previous = view_layer.objects.active
    try:
        view_layer.objects.active = obj
        ctx = SimpleNamespace(light=bpy.context.object.data if bpy.context.object.type == "LIGHT" else None)
        assert panels.OMNIWARP_PT_light.poll(ctx)
        view_layer.objects.active = mesh_obj
        ctx = SimpleNamespace(light=bpy.context.object.data if bpy.context.object.type == "LIGHT" else None)
        assert not panels.OMNIWARP_PT_light.poll(ctx)
    finally:
        view_layer.objects.active = previous
        bpy.data.objects.remove(obj)
        bpy.data.objects.remove(mesh_obj)
        bpy.data.meshes.remove(mesh)


LIGHT_PANEL_PROPS = ["emission", "parameterization", "warp", "resolution", "exact",
                     "bias_constant", "bias_slope", "bias_normal", "cull"]


def test_light_panel_draw(make_light) -> None:
    light = make_light("SPOT", 45.0)
    ctx = SimpleNamespace(light=light, scene=bpy.context.scene)
    assert draw_panel(panels.OMNIWARP_PT_light, ctx, header=True).props() == ["enabled"]
    layout = draw_panel(panels.OMNIWARP_PT_light, ctx)
    assert layout.use_property_split
    assert layout.props() == LIGHT_PANEL_PROPS
    labels = " | ".join(layout.labels())
    assert "Treated as: Spot cone" in labels and "Bias" in labels
    assert "179" not in labels  # AUTO on a narrow spot shadows its cone only
    assert layout.layout_of("warp").active is False and "PSM takes no warp" in labels
    assert ("box",) in layout.record

    light.omniwarp.emission = "OMNI"  # explicitly all directions: the note says so
    layout = draw_panel(panels.OMNIWARP_PT_light, ctx)
    labels = " | ".join(layout.labels())
    assert "179" in labels and "Treated as" not in labels
    assert layout.layout_of("warp").active is True and "takes no warp" not in labels

    wide = make_light("SPOT", 180.0)
    labels = draw_panel(panels.OMNIWARP_PT_light, SimpleNamespace(light=wide)).labels()
    assert any("Hemispherical" in text for text in labels)
    wide.omniwarp.emission = "OMNI"
    labels = draw_panel(panels.OMNIWARP_PT_light, SimpleNamespace(light=wide)).labels()
    assert not any("Treated as" in text for text in labels)
    assert not any("179" in text for text in labels)  # a wide spot is no narrow one


@pytest.mark.parametrize(("parameterization", "greyed"), [
    ("DPSM", False), ("CUBE", False), ("IPSM", False), ("UNFOLD", True)])
def test_light_panel_greys_out_warp(make_light, parameterization: str, greyed: bool) -> None:
    light = make_light("POINT")
    light.omniwarp.parameterization = parameterization
    layout = draw_panel(panels.OMNIWARP_PT_light, SimpleNamespace(light=light))
    assert layout.layout_of("warp").active is not greyed
    assert any("takes no warp" in text for text in layout.labels()) is greyed


@pytest.mark.parametrize("value", [float("nan"), float("inf")])
def test_light_panel_names_a_bias_that_cannot_be_drawn(make_light, value: float) -> None:
    """A NaN or infinite bias set from Python (Blender keeps NaN, stores inf as FLT_MAX)
    is named in an alert box of the light panel; a finite one shows no alert."""
    light = make_light("POINT")
    labels = " | ".join(draw_panel(panels.OMNIWARP_PT_light, SimpleNamespace(light=light)).labels())
    assert "Cannot be drawn" not in labels
    light.omniwarp.bias_slope = value
    labels = " | ".join(draw_panel(panels.OMNIWARP_PT_light, SimpleNamespace(light=light)).labels())
    assert "Cannot be drawn, preview paused" in labels and "bias slope" in labels
    with pytest.raises(InputError, match="bias slope"):
        properties.shadow_settings_for(light)


def test_light_panel_shows_the_soft_settings_of_a_sized_point_light(make_light) -> None:
    light = make_light("POINT")
    light.shadow_soft_size = 0.25
    assert panels.OMNIWARP_PT_light and draw_panel(panels.OMNIWARP_PT_light, SimpleNamespace(light=light)).props()[-3:] \
        == ["light_samples", "search_samples", "cull"]
    light.omniwarp.light_samples, light.omniwarp.search_samples = 48, 4
    settings = properties.shadow_settings_for(light)
    assert (settings.light_samples, settings.search_samples) == (48, 4)
    light.shadow_soft_size = 0.0  # hard: nothing to filter, nothing shown
    assert "light_samples" not in draw_panel(panels.OMNIWARP_PT_light, SimpleNamespace(light=light)).props()
    # A sized spot and a sun with an angle are softened on their own maps too.
    spot, sun = make_light("SPOT"), make_light("SUN")
    spot.spot_size, spot.shadow_soft_size, sun.angle = 1.0, 0.2, 0.1
    for sized in (spot, sun):
        assert "light_samples" in draw_panel(panels.OMNIWARP_PT_light, SimpleNamespace(light=sized)).props()


def test_light_panel_draw_sun(make_light) -> None:
    sun = make_light("SUN")
    # Blender's new sun is 0.53 degrees across: a sized light, whose soft settings show.
    assert sun.angle > 0.0
    assert draw_panel(panels.OMNIWARP_PT_light, SimpleNamespace(light=sun)).props()[-3:] \
        == ["light_samples", "search_samples", "cull"]
    sun.angle = 0.0
    layout = draw_panel(panels.OMNIWARP_PT_light, SimpleNamespace(light=sun))
    assert layout.props() == LIGHT_PANEL_PROPS[1:]  # no emission choice for a sun
    labels = " | ".join(layout.labels())
    assert "Treated as: Sun (parallel)" in labels
    assert layout.layout_of("warp").active is False
    # Only before Blender 5.0 does the field show the unfitting default (DPSM) as blank.
    assert ("Stored method does not fit this light: using PSM" in labels) is not properties._HAS_GET_TRANSFORM
    sun.omniwarp.parameterization = "SM"
    labels = " | ".join(draw_panel(panels.OMNIWARP_PT_light, SimpleNamespace(light=sun)).labels())
    assert "Stored method" not in labels and "SM takes no warp" in labels


def test_viewport_panel_draw_without_lights(registered) -> None:
    scene = bpy.context.scene
    for obj in scene.objects:
        if obj.type == "LIGHT":
            assert not obj.data.omniwarp.enabled  # fresh registration: all off
    layout = draw_panel(panels.OMNIWARP_PT_viewport, SimpleNamespace(scene=scene))
    assert layout.use_property_split
    assert layout.props() == ["preview_enabled", "shadow_strength", "camera_resolution_scale", "throttle_ms"]
    assert any("No light has OmniWarp enabled" in text for text in layout.labels())


def test_viewport_panel_lists_enabled_lights(light_object) -> None:
    scene = bpy.context.scene
    shown = light_object("omniwarp_test_shown")
    shown.data.omniwarp.parameterization = "CUBE"
    shown.data.omniwarp.warp = "NOTW"
    shown.data.omniwarp.resolution = 512
    light_object("omniwarp_test_hidden", enabled=False)
    light_object("omniwarp_test_area", kind="AREA")  # enabled: a sized hemispherical light
    sun = light_object("omniwarp_test_sun", kind="SUN")
    sun.data.omniwarp.warp = "NOTW"  # stored, but psm takes no warp
    assert [o.name for o in panels.enabled_light_objects(scene)] == ["omniwarp_test_area", "omniwarp_test_shown",
                                                                      "omniwarp_test_sun"]
    labels = draw_panel(panels.OMNIWARP_PT_viewport, SimpleNamespace(scene=scene)).labels()
    assert "omniwarp_test_shown" in labels and "omniwarp_test_sun" in labels and "omniwarp_test_area" in labels
    assert "CUBE + NOTW, 512 px, omni" in labels
    assert "PSM, 1024 px, sun" in labels
    assert any(text.endswith("px, hemi") for text in labels)  # the area light
    assert not any("hidden" in text for text in labels)
    assert not any("No light" in text for text in labels)


def test_overlay_panel_draw(registered) -> None:
    ctx = SimpleNamespace(scene=bpy.context.scene)
    assert panels.OMNIWARP_PT_overlay.bl_parent_id == panels.OMNIWARP_PT_viewport.bl_idname
    assert panels.OMNIWARP_PT_viewport.bl_category == "OmniWarp"
    assert panels.OMNIWARP_PT_viewport.bl_label == "Shadow preview"
    assert draw_panel(panels.OMNIWARP_PT_overlay, ctx, header=True).props() == ["overlay_enabled"]
    layout = draw_panel(panels.OMNIWARP_PT_overlay, ctx)
    assert layout.props() == ["overlay_maps", "overlay_size", "overlay_corner", "overlay_stats"]


def test_light_settings_survive_unregister_and_register(no_runtime, recorder: ViewportRecorder) -> None:
    """The stored choices live in the .blend data, so re-registering (an extension update) finds them."""
    registration.unregister()
    registration.register()
    point, sun = bpy.data.lights.new("omniwarp_keep_point", "POINT"), bpy.data.lights.new("omniwarp_keep_sun", "SUN")
    try:
        point.omniwarp.parameterization, point.omniwarp.warp = "UNFOLD", "RTW"
        sun.omniwarp.parameterization, sun.omniwarp.resolution = "SM", 2048
        registration.unregister()
        assert not hasattr(point, "omniwarp")
        registration.register()
        assert (point.omniwarp.parameterization, point.omniwarp.warp) == ("UNFOLD", "RTW")
        assert (sun.omniwarp.parameterization, sun.omniwarp.resolution) == ("SM", 2048)
        assert properties.shadow_settings_for(point).warp == "none"
        assert properties.shadow_settings_for(sun).parameterization == "sm"
    finally:
        bpy.data.lights.remove(point)
        bpy.data.lights.remove(sun)
        registration.unregister()


def test_unregister_removes_pointers(no_runtime) -> None:
    registration.unregister()
    registration.register()
    registration.unregister()
    assert not hasattr(bpy.types.Light, "omniwarp")
    assert not hasattr(bpy.types.Scene, "omniwarp")
    light = bpy.data.lights.new("omniwarp_after", "POINT")
    try:
        assert not hasattr(light, "omniwarp")
    finally:
        bpy.data.lights.remove(light)


@pytest.mark.parametrize("kind,spot_deg", [("SPOT", 45.0), ("SUN", None)])
def test_exact_runs_over_a_spot_or_sun_map_and_is_kept_from_psm(make_light, kind, spot_deg) -> None:
    """A spot narrower than 179 degrees, or a sun, gets a projective map: its plain map (SM)
    takes the exact pass (the `exact` method), PSM does not, which keeps the stored choice
    but does not use it."""
    light = make_light(kind, spot_deg)
    light.omniwarp.exact = True
    light.omniwarp.parameterization = "SM"
    settings = properties.shadow_settings_for(light)
    assert (settings.parameterization, settings.exact) == ("sm", True)
    assert method_registry.label_for(settings.parameterization, settings.warp, exact=settings.exact) == "exact"
    light.omniwarp.parameterization = "PSM"
    settings = properties.shadow_settings_for(light)
    assert (settings.parameterization, settings.exact) == ("psm", False)
    assert light.omniwarp.exact is True
