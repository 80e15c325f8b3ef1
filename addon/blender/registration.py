"""Registers the extension with Blender, in one fixed order.

`register()` does three steps, and `unregister()` undoes them in exactly the
reverse order:

1. the bpy classes in `CLASSES` (PropertyGroups first, then panels), then
   those of the comparison tool in `TOOL_CLASSES`;
2. the namespaced settings pointers `bpy.types.Light.omniwarp` and
   `bpy.types.Scene.omniwarp` (see `POINTERS`), then
   `bpy.types.Scene.omniwarp_compare` (see `TOOL_POINTERS`);
3. the runtime modules in `RUNTIME_MODULES` (depsgraph handlers, viewport draw
   handlers and timers), each asked to `register()`.

Order matters: a PropertyGroup must be registered before anything that points
at it, and panels after the operators they draw. Add new classes to `CLASSES`
in dependency order; `unregister()` walks it backwards.
"""
from __future__ import annotations

import logging
from types import ModuleType

import bpy

from . import compare_job, compare_ops, compare_props, compare_ui, panels, properties, scene_cache, viewport

log = logging.getLogger(__name__)

CLASSES: tuple[type, ...] = (
    properties.OMNIWARP_PG_light,
    properties.OMNIWARP_PG_scene,
    panels.OMNIWARP_PT_light,
    panels.OMNIWARP_PT_viewport,
    panels.OMNIWARP_PT_overlay,
)

# (owner type, attribute, PropertyGroup): one namespaced pointer per owner.
POINTERS: tuple[tuple[type, str, type], ...] = (
    (bpy.types.Light, "omniwarp", properties.OMNIWARP_PG_light),
    (bpy.types.Scene, "omniwarp", properties.OMNIWARP_PG_scene),
)

# The comparison tool of the sidebar tab (compare_*.py), registered after
# CLASSES: its PropertyGroups (the row before the group holding the rows), its
# operators, the UI list, then the panel that draws them.
TOOL_CLASSES: tuple[type, ...] = (
    compare_props.OMNIWARP_PG_result_row,
    compare_props.OMNIWARP_PG_comparison,
    compare_ops.OMNIWARP_OT_build_preset,
    compare_ops.OMNIWARP_OT_compare,
    compare_ops.OMNIWARP_OT_export_results,
    compare_ui.OMNIWARP_UL_results,
    compare_ui.OMNIWARP_PT_compare,
)

# Its one namespaced pointer, added after POINTERS.
TOOL_POINTERS: tuple[tuple[type, str, type], ...] = (
    (bpy.types.Scene, "omniwarp_compare", compare_props.OMNIWARP_PG_comparison),
)

# Sibling modules with their own register()/unregister(), called in this order
# (and in reverse on unregister). Tests may set this to () to run without them.
RUNTIME_MODULES: tuple[ModuleType, ...] = (scene_cache, viewport)


def _all_classes() -> tuple[type, ...]:
    """Every class, in registration order."""
    return CLASSES + TOOL_CLASSES


def _all_pointers() -> tuple[tuple[type, str, type], ...]:
    """Every settings pointer, in the order they are added."""
    return POINTERS + TOOL_POINTERS


def _register_classes(done: list[type]) -> None:
    for cls in _all_classes():
        bpy.utils.register_class(cls)
        done.append(cls)


def _add_pointers(done: list[tuple[type, str]]) -> None:
    for owner, attr, group in _all_pointers():
        setattr(owner, attr, bpy.props.PointerProperty(type=group))
        done.append((owner, attr))


def _register_runtime(done: list[ModuleType]) -> None:
    for module in RUNTIME_MODULES:
        module.register()
        done.append(module)


def _remove_pointer(owner: type, attr: str) -> bool:
    """Delete `owner.attr` if it is there; True when something was removed."""
    if not hasattr(owner, attr):
        return False
    delattr(owner, attr)
    return True


def register() -> None:
    """Register classes, then the settings pointers, then the runtime modules.

    If a step fails, everything done so far is undone in reverse order and the
    error is re-raised, so a failed enable leaves Blender clean.
    """
    classes: list[type] = []
    pointers: list[tuple[type, str]] = []
    runtime: list[ModuleType] = []
    try:
        _register_classes(classes)
        _add_pointers(pointers)
        _register_runtime(runtime)
    except Exception:
        log.exception(
            "registering OmniWarp failed after %d classes, %d pointers, %d runtime modules; rolling back",
            len(classes), len(pointers), len(runtime),
        )
        for module in reversed(runtime):
            module.unregister()
        for owner, attr in reversed(pointers):
            _remove_pointer(owner, attr)
        for cls in reversed(classes):
            bpy.utils.unregister_class(cls)
        raise
    log.debug("registered %d classes, %d pointers, %d runtime modules", len(classes), len(pointers), len(runtime))


def unregister() -> None:
    """Undo `register()` in reverse: runtime modules, pointers, then classes.

    Safe to call when nothing (or only part) is registered: a missing pointer or
    an unregistered class is skipped with a log line instead of stopping the rest
    (the runtime modules' own unregister is idempotent).
    """
    modules = 0
    for module in reversed(RUNTIME_MODULES):
        module.unregister()
        modules += 1

    pointers = 0
    for owner, attr, _group in reversed(_all_pointers()):
        if _remove_pointer(owner, attr):
            pointers += 1
        else:
            log.debug("%s.%s was not registered; skipping", owner.__name__, attr)

    compare_job.free_state()  # a running comparison's GPU objects, its rows, the preset caches
    count = 0
    for cls in reversed(_all_classes()):
        try:
            bpy.utils.unregister_class(cls)
            count += 1
        except RuntimeError:
            log.warning("%s was not registered; skipping", cls.__name__)
    log.debug("unregistered %d runtime modules, %d pointers, %d classes", modules, pointers, count)
