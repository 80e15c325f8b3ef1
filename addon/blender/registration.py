"""Registers the extension's bpy classes with Blender, in one fixed order.

Order matters: a PropertyGroup must be registered before anything that points
at it, and panels after the operators they draw. Add new classes to `CLASSES`
in dependency order; `unregister()` walks it backwards.
"""
from __future__ import annotations

import logging

import bpy

log = logging.getLogger(__name__)

CLASSES: tuple[type, ...] = ()


def register() -> None:
    """Register every class in `CLASSES`, in order.

    If one fails, the classes registered so far are unregistered again and the
    error is re-raised, so a failed enable leaves Blender clean.
    """
    done: list[type] = []
    try:
        for cls in CLASSES:
            bpy.utils.register_class(cls)
            done.append(cls)
    except Exception:
        log.exception("registering %s failed; rolling back", CLASSES[len(done)].__name__)
        for cls in reversed(done):
            bpy.utils.unregister_class(cls)
        raise
    log.debug("registered %d classes", len(done))


def unregister() -> None:
    """Unregister every class in `CLASSES`, in reverse order.

    Classes that are not registered (e.g. after a failed register) are skipped
    with a warning instead of stopping the rest.
    """
    count = 0
    for cls in reversed(CLASSES):
        try:
            bpy.utils.unregister_class(cls)
            count += 1
        except RuntimeError:
            log.warning("%s was not registered; skipping", cls.__name__)
    log.debug("unregistered %d classes", count)
