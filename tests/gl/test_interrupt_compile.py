"""A Ctrl-C that arrives while moderngl compiles a program is raised only after the
compile returns: the Python handler raising inside the compile segfaulted `compare`."""
from __future__ import annotations

import os
import signal

import pytest

from addon.core import interrupt
from addon.core.errors import Interrupted
from addon.render.backends.moderngl.backend import ModernGLBackend
from addon.render.shaders import SAMPLE_STATS_PROGRAM

pytestmark = pytest.mark.gl


def test_a_signal_during_a_compile_is_raised_after_it():
    backend = ModernGLBackend()
    real = backend.ctx.compute_shader
    finished = []

    def compile_after_a_signal(source):
        os.kill(os.getpid(), signal.SIGINT)
        # The Python handler runs at one of the next bytecodes: here, inside the compile call.
        total = sum(range(10_000))
        program = real(source)
        finished.append(total)
        return program

    backend.ctx.compute_shader = compile_after_a_signal
    try:
        with interrupt.handling():
            with pytest.raises(Interrupted):
                backend.program(SAMPLE_STATS_PROGRAM)
        assert finished, "the interruption cut the compile in two"
        assert SAMPLE_STATS_PROGRAM.name in backend._programs  # built once, kept
    finally:
        del backend.ctx.compute_shader
        backend.release()
