"""Named exceptions shared by every layer.

Each carries a message meant for the user: it names the input at fault and what
would fix it. The CLI turns them into a non-zero exit with that message.
"""
from __future__ import annotations

import sys


class OmniWarpError(Exception):
    """Base class of every error OmniWarp raises on purpose."""


class InputError(OmniWarpError, ValueError):
    """Bad user input: an unknown name, a bad number, a missing file."""


class PresetError(InputError):
    """An unknown preset, or a preset module that does not follow the contract."""


class GeometryError(OmniWarpError):
    """Geometry that cannot be processed (e.g. nothing finite left to draw)."""


class BackendError(OmniWarpError):
    """A GPU backend failed to start, compile a shader or read back."""


class ReferenceCaptureError(OmniWarpError):
    """The Cycles reference could not be rendered, read or loaded from cache."""


# Exit codes of the commands (omniwarp, and its child processes): bad input, other failure.
EXIT_BAD_INPUT = 2
EXIT_FAILURE = 1


def report_error(program: str, exc: OmniWarpError) -> int:
    """Print a command's one-line error on stderr and return its exit code."""
    if isinstance(exc, InputError):
        print(f"{program}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    print(f"{program}: failed: {exc}", file=sys.stderr)
    return EXIT_FAILURE


def child_stderr_tail(text: str, limit: int = 2000) -> str:
    """The end of a child process's stderr for an error message, without Mesa's
    harmless EGL_BAD_MATCH lines."""
    return "\n".join(line for line in text.splitlines() if "EGL_BAD" not in line)[-limit:]
