"""GL entry points moderngl does not give as the pipeline needs them, called through ctypes on
the context moderngl made current (EGL's eglGetProcAddress finds them).

* `finish`: glFinish without the GIL. moderngl holds the GIL in every call, so a wait on
  minutes of queued GPU work kept the signal watchdog (core/interrupt.py) from running;
  a ctypes call lets the GIL go while it blocks.
* time-elapsed queries read as 64 bits. moderngl 5.13 reads them into a 32-bit unsigned
  (`glGetQueryObjectuiv`): a stage of more than 2^32 ns, 4,295 ms, wrapped around, so frames
  of 40 to 254 s all reported about 4,300 GPU ms.

Everything is resolved once, on first use; where EGL or a call is missing, `GL_CALLS` is
None and the moderngl device falls back to moderngl's own calls.
"""
from __future__ import annotations

import ctypes
import logging
from dataclasses import dataclass
from typing import Any

log = logging.getLogger(__name__)

GL_TIME_ELAPSED = 0x88BF
GL_QUERY_RESULT = 0x8866


@dataclass(frozen=True)
class GLCalls:
    """The resolved entry points."""

    finish: Any
    gen_queries: Any
    delete_queries: Any
    begin_query: Any
    end_query: Any
    query_result_u64: Any

    def new_timer(self) -> int:
        """A new query object's name."""
        name = ctypes.c_uint(0)
        self.gen_queries(1, ctypes.byref(name))
        return int(name.value)

    def delete(self, name: int) -> None:
        self.delete_queries(1, ctypes.byref(ctypes.c_uint(name)))

    def begin_timer(self, name: int) -> None:
        self.begin_query(GL_TIME_ELAPSED, name)

    def end_timer(self) -> None:
        self.end_query(GL_TIME_ELAPSED)

    def elapsed_ns(self, name: int) -> int:
        """The query's result, 64 bits; waits (without the GIL) until the GPU has it."""
        value = ctypes.c_uint64(0)
        self.query_result_u64(name, GL_QUERY_RESULT, ctypes.byref(value))
        return int(value.value)


_SIGNATURES = {
    "glFinish": (None,),
    "glGenQueries": (None, ctypes.c_int, ctypes.POINTER(ctypes.c_uint)),
    "glDeleteQueries": (None, ctypes.c_int, ctypes.POINTER(ctypes.c_uint)),
    "glBeginQuery": (None, ctypes.c_uint, ctypes.c_uint),
    "glEndQuery": (None, ctypes.c_uint),
    "glGetQueryObjectui64v": (None, ctypes.c_uint, ctypes.c_uint, ctypes.POINTER(ctypes.c_uint64)),
}
_UNRESOLVED = object()
_RESOLVED: Any = _UNRESOLVED


def gl_calls() -> GLCalls | None:
    """The entry points (resolved on the first call), or None where EGL cannot give them."""
    global _RESOLVED
    if _RESOLVED is _UNRESOLVED:
        _RESOLVED = None
        try:
            egl = ctypes.CDLL("libEGL.so.1")
            egl.eglGetProcAddress.restype = ctypes.c_void_p
            egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
            found = {}
            for name, (restype, *argtypes) in _SIGNATURES.items():
                address = egl.eglGetProcAddress(name.encode())
                if not address:
                    raise AttributeError(f"eglGetProcAddress has no {name}")
                found[name] = ctypes.CFUNCTYPE(restype, *argtypes)(address)
            _RESOLVED = GLCalls(found["glFinish"], found["glGenQueries"], found["glDeleteQueries"],
                                found["glBeginQuery"], found["glEndQuery"], found["glGetQueryObjectui64v"])
        except (OSError, AttributeError) as exc:
            log.debug("GL calls through ctypes unavailable (%s): moderngl's own are used", exc)
    return _RESOLVED
