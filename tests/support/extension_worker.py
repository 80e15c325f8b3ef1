"""Child-process side of tests/blender/test_packaging.py: one bpy session per task.

    python tests/support/extension_worker.py install ZIP
    python tests/support/extension_worker.py save BLEND
    python tests/support/extension_worker.py reopen BLEND

Each task prints one line `OMNIWARP_REPORT <json>` (bpy prints its own lines to
stdout too, hence the marker); the test asserts on that report.

bpy state must not leak between tasks or into pytest, and nothing may be
installed into the real ~/.config/blender: the caller sets
BLENDER_USER_RESOURCES to a temporary folder (Blender then puts config/,
scripts/, extensions/ and datafiles/ under it), and every task refuses to run
unless bpy really reports its user folders under that path.
"""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[2]
REPORT_MARKER = "OMNIWARP_REPORT "
EXT_ID = "omniwarp_shadows"
REPO_MODULE = "user_default"  # the "User Default" repository every Blender has
ADDON_MODULE = f"bl_ext.{REPO_MODULE}.{EXT_ID}"
# The other user-folder variables override BLENDER_USER_RESOURCES when set.
USER_DIR_OVERRIDES = ("BLENDER_USER_CONFIG", "BLENDER_USER_SCRIPTS", "BLENDER_USER_EXTENSIONS",
                      "BLENDER_USER_DATAFILES")

# Non-default settings for the round trip. Properties not listed here get a
# generated non-default value (see `_non_default`), so a setting added later is
# covered without editing this file.
LIGHT_VALUES: dict[str, Any] = {
    "enabled": True,
    "emission": "HEMI",
    "parameterization": "CUBE",
    "warp": "NOTW",
    "resolution": 2048,
    "bias_constant": 1.25,
    "bias_slope": 0.5,
    "bias_normal": 2.0,
    "cull": False,
}
# A second light covers the other enum items.
# parameterization is a dynamic enum (items per light type), so the worker cannot pick a
# non-default value from the class; name one a point-treated spot takes.
SPOT_VALUES: dict[str, Any] = {"emission": "OMNI", "parameterization": "IPSM", "warp": "RTW", "resolution": 512}
SCENE_VALUES: dict[str, Any] = {
    "preview_enabled": True,
    "shadow_strength": 0.25,
    "overlay_enabled": False,
    "overlay_maps": {"COUNT"},
    "overlay_size": 300,
    "overlay_corner": "TOP_RIGHT",
    "overlay_stats": False,
    "camera_resolution_scale": 0.75,
    "throttle_ms": 40,
}
LIGHT_NAMES = ("OmniWarp Point", "OmniWarp Spot")


# ---------------------------------------------------------------------------
# isolation
# ---------------------------------------------------------------------------
def _user_root() -> Path:
    """The temporary user-resources folder; exits when the caller did not isolate us."""
    root = os.environ.get("BLENDER_USER_RESOURCES")
    overrides = [name for name in USER_DIR_OVERRIDES if os.environ.get(name)]
    if not root or overrides:
        sys.exit(f"extension_worker: refusing to run: set BLENDER_USER_RESOURCES to a temporary folder "
                 f"and unset {overrides or 'the other BLENDER_USER_* variables'}")
    return Path(root).resolve()


def _check_isolated(root: Path) -> dict[str, str]:
    """bpy's user folders; exits unless all of them lie under `root`."""
    import bpy

    paths = {kind: bpy.utils.user_resource(kind) for kind in ("CONFIG", "SCRIPTS", "EXTENSIONS", "DATAFILES")}
    outside = {k: p for k, p in paths.items() if not Path(p).resolve().is_relative_to(root)}
    if outside:
        sys.exit(f"extension_worker: refusing to run: bpy ignores BLENDER_USER_RESOURCES={root} for {outside}")
    return paths


def _report(data: dict[str, Any]) -> None:
    print(REPORT_MARKER + json.dumps(data, sort_keys=True), flush=True)


# ---------------------------------------------------------------------------
# reading and writing PropertyGroups generically
# ---------------------------------------------------------------------------
def _settings_props(group) -> list:
    """RNA properties of a settings PropertyGroup, without `rna_type` and the built-in `name`."""
    return [p for p in group.bl_rna.properties if p.identifier not in ("rna_type", "name")]


def _jsonable(value: Any) -> Any:
    if isinstance(value, set):
        return sorted(value)
    if isinstance(value, float):
        return float(value)
    return value


def _read(group) -> dict[str, Any]:
    """Every setting of a PropertyGroup instance, JSON-ready (enum flags as sorted lists)."""
    return {p.identifier: _jsonable(getattr(group, p.identifier)) for p in _settings_props(group)}


def _default(prop) -> Any:
    if prop.type == "ENUM":
        return set(prop.default_flag) if prop.is_enum_flag else prop.default
    return prop.default


def _non_default(prop) -> Any:
    """A valid value that differs from the property's default."""
    default = _default(prop)
    if prop.type == "BOOLEAN":
        return not default
    if prop.type == "ENUM":
        ids = [item.identifier for item in prop.enum_items]
        if prop.is_enum_flag:
            return {ids[0]} if {ids[0]} != default else {ids[-1]}
        return next(i for i in ids if i != default)
    if prop.type in ("INT", "FLOAT"):
        step = 1 if prop.type == "INT" else 0.25
        high = min(prop.hard_max, getattr(prop, "soft_max", prop.hard_max))
        return default + step if default + step <= high else default - step
    if prop.type == "STRING":
        return "omniwarp round trip"
    raise TypeError(f"no generated value for {prop.identifier} ({prop.type})")


def _apply(group, explicit: dict[str, Any]) -> tuple[dict[str, Any], list[str], list[str]]:
    """Set every setting to a non-default value: `explicit` first, generated for the rest.

    Returns (what was asked for, names that got generated values, names whose
    asked value equals the default, which would make a round trip meaningless).
    """
    wanted: dict[str, Any] = {}
    generated: list[str] = []
    same_as_default: list[str] = []
    for prop in _settings_props(group):
        name = prop.identifier
        if name in explicit:
            value = explicit[name]
        else:
            value = _non_default(prop)
            generated.append(name)
        if value == _default(prop):
            same_as_default.append(name)
        setattr(group, name, value)
        wanted[name] = _jsonable(value)
    return wanted, generated, same_as_default


# ---------------------------------------------------------------------------
# install: the built zip, through Blender's own "Install from Disk" operator
# ---------------------------------------------------------------------------
def ext_handlers() -> list[str]:
    """`bpy.app.handlers` callbacks that belong to the installed extension."""
    import bpy

    found = []
    for name in dir(bpy.app.handlers):
        handlers = getattr(bpy.app.handlers, name)
        if isinstance(handlers, list):
            found += [f"{name}:{fn.__qualname__}" for fn in handlers
                      if getattr(fn, "__module__", "").startswith(ADDON_MODULE)]
    return found


def _state() -> dict[str, Any]:
    """What the test needs to know about the add-on's registration right now."""
    import bpy

    return {
        "enabled": ADDON_MODULE in bpy.context.preferences.addons,
        # What "enabled" was looked up in, shown by tests/support/checks.py when it fails.
        "enabled_values": {"addons": sorted(bpy.context.preferences.addons.keys())},
        "light_pointer": hasattr(bpy.types.Light, "omniwarp"),
        "scene_pointer": hasattr(bpy.types.Scene, "omniwarp"),
        "light_panel": hasattr(bpy.types, "OMNIWARP_PT_light"),
        "handlers": ext_handlers(),
    }


def _listing(folder: Path) -> list[str] | None:
    """The names in a folder, None if it does not exist (values behind a failed check)."""
    return sorted(p.name for p in folder.iterdir()) if folder.is_dir() else None


def install(zip_path: str) -> None:
    """Install + enable the zip, use the settings, disable, re-enable, disable."""
    root = _user_root()
    import bpy
    import addon_utils  # importable only once bpy is

    report: dict[str, Any] = {"user_paths": _check_isolated(root), "user_root": str(root)}
    repo = next((r for r in bpy.context.preferences.extensions.repos if r.module == REPO_MODULE), None)
    if repo is None:
        # A fresh user config always has it; create it the way Preferences does if not.
        repo = bpy.context.preferences.extensions.repos.new(name="User Default", module=REPO_MODULE)
    report["repo_directory"] = repo.directory

    # The same operator as Preferences > Get Extensions > Install from Disk. In
    # background mode the extension operators refuse online steps (sync,
    # install from a URL) unless online access is allowed, but installing a local
    # file needs none, so this is the real user route, not a stand-in.
    report["install_result"] = sorted(bpy.ops.extensions.package_install_files(
        filepath=str(Path(zip_path).resolve()), repo=REPO_MODULE, enable_on_install=True))
    module = sys.modules.get(ADDON_MODULE)
    report["module_file"] = getattr(module, "__file__", None)
    installed = Path(repo.directory) / EXT_ID
    report["installed_manifest"] = (installed / "blender_manifest.toml").is_file()
    report["installed_manifest_values"] = {"folder": str(installed), "files": _listing(installed),
                                           "repository": _listing(installed.parent)}
    report["after_install"] = _state()

    # Use the settings on a new light: they must behave like any RNA property.
    light = bpy.data.lights.new(LIGHT_NAMES[0], "POINT")
    light.omniwarp.parameterization = "CUBE"
    light.omniwarp.warp = "NOTW"
    light.omniwarp.resolution = 2048
    report["light_readback"] = _read(light.omniwarp)
    try:
        light.omniwarp.resolution = 100_000  # RNA clamps ints to [min, max]
        report["resolution_clamped"] = light.omniwarp.resolution
    except (TypeError, ValueError) as err:
        report["resolution_clamped"] = f"rejected: {err}"
    light.omniwarp.resolution = 2048

    report["disable_result"] = sorted(bpy.ops.preferences.addon_disable(module=ADDON_MODULE))
    report["after_disable"] = _state()

    # Enabling again must work after a disable (unregister left nothing behind),
    # and the light's stored settings come back with the pointer.
    addon_utils.enable(ADDON_MODULE, default_set=True, handle_error=None)
    report["after_reenable"] = _state()
    report["light_after_reenable"] = _read(light.omniwarp) if report["after_reenable"]["light_pointer"] else None
    bpy.ops.preferences.addon_disable(module=ADDON_MODULE)
    report["after_second_disable"] = _state()
    _report(report)


# ---------------------------------------------------------------------------
# save / reopen: the settings survive a .blend round trip
# ---------------------------------------------------------------------------
def _register_from_repo():
    """Register the add-on straight from this checkout (not installed)."""
    if str(REPO) not in sys.path:
        sys.path.insert(0, str(REPO))
    from addon.blender import registration

    registration.register()
    return registration


def _repo_handlers() -> list[str]:
    """`bpy.app.handlers` callbacks from the checkout's `addon` package."""
    import bpy

    found = []
    for name in dir(bpy.app.handlers):
        handlers = getattr(bpy.app.handlers, name)
        if isinstance(handlers, list):
            found += [f"{name}:{fn.__qualname__}" for fn in handlers
                      if getattr(fn, "__module__", "").startswith("addon.")]
    return sorted(found)


def _read_file_settings() -> dict[str, Any]:
    """Settings of the named lights and of every scene, as the current file holds them."""
    import bpy

    return {
        "lights": {n: _read(bpy.data.lights[n].omniwarp) for n in LIGHT_NAMES if n in bpy.data.lights},
        "scenes": {s.name: _read(s.omniwarp) for s in bpy.data.scenes},
    }


def save(blend: str) -> None:
    """Register from the repo, set non-default settings, save, load other files, reopen."""
    root = _user_root()
    import bpy

    report: dict[str, Any] = {"user_paths": _check_isolated(root)}
    registration = _register_from_repo()
    report["handlers_registered"] = _repo_handlers()

    scene = bpy.context.scene
    wanted: dict[str, Any] = {"lights": {}, "scenes": {}}
    generated: list[str] = []
    same: list[str] = []
    for name, kind, values in ((LIGHT_NAMES[0], "POINT", LIGHT_VALUES), (LIGHT_NAMES[1], "SPOT", SPOT_VALUES)):
        light = bpy.data.lights.new(name, kind)
        scene.collection.objects.link(bpy.data.objects.new(name, light))
        wanted["lights"][name], gen, sam = _apply(light.omniwarp, values)
        generated += [f"{name}.{g}" for g in gen]
        same += [f"{name}.{s}" for s in sam]
    wanted["scenes"][scene.name], gen, sam = _apply(scene.omniwarp, SCENE_VALUES)
    generated += [f"{scene.name}.{g}" for g in gen]
    same += [f"{scene.name}.{s}" for s in sam]
    report.update(wanted=wanted, generated=generated, same_as_default=same)
    report["before_save"] = _read_file_settings()

    bpy.ops.wm.save_as_mainfile(filepath=blend)
    # Load something else, so the values must come from the file.
    bpy.ops.wm.read_homefile(use_empty=True)
    report["after_homefile"] = {
        "lights": [lt.name for lt in bpy.data.lights],
        "light_pointer": hasattr(bpy.types.Light, "omniwarp"),
        "scene_settings": {s.name: _read(s.omniwarp) for s in bpy.data.scenes},
        "scene_defaults": {p.identifier: _jsonable(_default(p)) for p in _settings_props(bpy.data.scenes[0].omniwarp)},
    }
    bpy.ops.wm.open_mainfile(filepath=blend)
    report["after_reopen"] = _read_file_settings()
    report["pointers_after_reopen"] = {
        "light": hasattr(bpy.types.Light, "omniwarp"), "scene": hasattr(bpy.types.Scene, "omniwarp"),
    }
    report["handlers_after_reopen"] = _repo_handlers()
    registration.unregister()
    _report(report)


def _stored_raw(id_block) -> dict[str, Any] | None:
    """The `omniwarp` group as raw ID properties, readable without the add-on.

    Blender 5 keeps bpy.props values apart from user custom properties, as
    "system properties" (`bl_system_properties_get()`); older versions kept them
    in the custom properties (`id_block["omniwarp"]`).
    """
    if hasattr(id_block, "bl_system_properties_get"):
        group = id_block.bl_system_properties_get()
        stored = group.get("omniwarp") if group is not None else None
    else:
        stored = id_block.get("omniwarp")
    return stored.to_dict() if stored is not None else None


def reopen(blend: str) -> None:
    """Open the .blend without the add-on, then register it and read the settings."""
    root = _user_root()
    import bpy

    report: dict[str, Any] = {"user_paths": _check_isolated(root)}
    report["pointer_before"] = hasattr(bpy.types.Light, "omniwarp")
    report["open_result"] = sorted(bpy.ops.wm.open_mainfile(filepath=blend))
    report["lights"] = sorted(lt.name for lt in bpy.data.lights)
    report["raw_unregistered"] = {
        "lights": {n: _stored_raw(bpy.data.lights[n]) for n in LIGHT_NAMES if n in bpy.data.lights},
        "scenes": {s.name: _stored_raw(s) for s in bpy.data.scenes},
    }
    registration = _register_from_repo()
    report["after_register"] = _read_file_settings()
    registration.unregister()
    _report(report)


TASKS = {"install": install, "save": save, "reopen": reopen}

if __name__ == "__main__":
    if len(sys.argv) != 3 or sys.argv[1] not in TASKS:
        sys.exit(f"usage: {Path(__file__).name} {{{'|'.join(TASKS)}}} PATH")
    TASKS[sys.argv[1]](sys.argv[2])
