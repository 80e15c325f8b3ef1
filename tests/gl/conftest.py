"""GL fixtures: one standalone moderngl context per test session.

These tests need Mesa EGL (CI installs it). A missing context is a failure, not a
skip: the shaders are the product.
"""
from __future__ import annotations

import pytest

from addon.render.moderngl_backend import ModernGLBackend


@pytest.fixture(scope="session")
def gl_backend():
    backend = ModernGLBackend()
    yield backend
    backend.release()
