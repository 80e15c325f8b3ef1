"""What the settings and the scene cache tell the viewport preview, without importing it.

Property callbacks, the panels and the depsgraph handler sit below the viewport in the
import graph: they call `notify` here, and the viewport listens once registered
(`viewport.register` calls `listen`). With no listener (the viewport not registered, or
a test without it) a notification does nothing. `redraw_3d_views` is the one thing they
all do to Blender's windows.
"""
from __future__ import annotations

import logging
from collections.abc import Callable

import bpy

log = logging.getLogger(__name__)

# The viewport's answers: "request_update" (reason), "set_preview_enabled" (context,
# enabled) and "last_error" (), each with one listener.
_LISTENERS: dict[str, Callable] = {}


def listen(event: str, callback: Callable) -> None:
    """Make `callback` the listener of `event` (the viewport does, on register)."""
    _LISTENERS[event] = callback


def forget(event: str) -> None:
    """Drop the listener of `event` (on unregister)."""
    _LISTENERS.pop(event, None)


def notify(event: str, *args, default=None):
    """Call the listener of `event` with `args` and return its answer; `default` without one."""
    callback = _LISTENERS.get(event)
    if callback is None:
        log.debug("no listener for %s", event)
        return default
    return callback(*args)


def redraw_3d_views() -> None:
    """Redraw every 3D view of every window."""
    wm = bpy.context.window_manager
    if wm is None:
        return
    for window in wm.windows:
        for area in window.screen.areas:
            if area.type == "VIEW_3D":
                area.tag_redraw()
