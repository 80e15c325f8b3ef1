"""Named exceptions shared by every layer, and the exit contract of the commands.

Each exception carries a message meant for the user: it names the input at fault and
what would fix it. The commands (`omniwarp`, and its child processes) exit with:

    0    done
    2    bad input or environment: every OmniWarpError, as ONE line on stderr
    130  interrupted (Ctrl-C or SIGTERM): one line; temporaries removed
    1    a bug only: anything else, with its traceback, to be reported
"""
from __future__ import annotations

import sys


class OmniWarpError(Exception):
    """Base class of every error OmniWarp raises on purpose."""


class InputError(OmniWarpError, ValueError):
    """Bad user input: an unknown name, a bad number, a missing file."""


class PresetError(InputError):
    """An unknown preset, or a preset module that does not follow the contract."""


class BackendError(OmniWarpError):
    """A GPU backend failed to start, compile a shader or read back."""


class ReferenceCaptureError(OmniWarpError):
    """The Cycles reference could not be rendered, read or loaded from cache."""


class ChildProcessCrash(Exception):
    """A child process (the EEVEE renderer, the preview) ended without its one-line
    error: a bug, reported with the child's traceback. Not an OmniWarpError on purpose."""


class Interrupted(KeyboardInterrupt):
    """Ctrl-C (SIGINT) or SIGTERM reached a command (`core/interrupt.py`).

    A KeyboardInterrupt, so that no `except Exception` on the way swallows it; the
    message says where the run stopped, `signum` which signal stopped it.
    """

    def __init__(self, message: str = "", signum: int = 2) -> None:
        super().__init__(message)
        self.signum = signum


EXIT_OK = 0
EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130  # 128 + SIGINT, what a shell reports for Ctrl-C
EXIT_TERMINATED = 143  # 128 + SIGTERM, what a shell reports for `kill`
EXIT_BUG = 1

# The contract as the commands' --help and the README state it.
EXIT_CONTRACT = ("exit status: 0 done; 2 bad input or environment (one line on stderr names the problem "
                 "and what to do); 130 interrupted (Ctrl-C; 143 for SIGTERM; temporaries removed, earlier results "
                 "untouched); "
                 "1 a bug (with its traceback, please report it)")


def one_line(text: str) -> str:
    """A message on one line: its lines joined with '; ' (the contract allows one line)."""
    return "; ".join(part.strip() for part in str(text).splitlines() if part.strip())


def report_error(program: str, exc: OmniWarpError) -> int:
    """Print a command's one-line error on stderr and return its exit code (2)."""
    print(f"{program}: error: {one_line(str(exc))}", file=sys.stderr, flush=True)
    return EXIT_BAD_INPUT


def report_interrupt(program: str, exc: BaseException, kept: str = "") -> int:
    """Print the one line of an interrupted command and return its exit code: 128 plus the
    signal's number, as a shell reports a process the signal ended (130 SIGINT, 143 SIGTERM).
    `kept` says what the run keeps (its finished rows), if anything."""
    where = one_line(str(exc)) if isinstance(exc, Interrupted) and str(exc) else "interrupted"
    kept_text = f"; {kept}" if kept else ""
    print(f"{program}: {where}{kept_text}; temporary files removed, earlier results untouched", file=sys.stderr,
          flush=True)
    return 128 + exc.signum if isinstance(exc, Interrupted) else EXIT_INTERRUPTED


def child_stderr_tail(text: str, limit: int = 2000) -> str:
    """The end of a child process's stderr for an error message, without Mesa's
    harmless EGL_BAD_MATCH lines."""
    return "\n".join(line for line in text.splitlines() if "EGL_BAD" not in line)[-limit:]


def child_error_line(text: str) -> str | None:
    """The one-line message of a child that exited with EXIT_BAD_INPUT: its last line
    of the form 'PROGRAM: error: MESSAGE' gives MESSAGE; None when there is none."""
    for line in reversed(text.splitlines()):
        head, sep, message = line.partition(": error: ")
        if sep and message.strip() and head.strip().startswith("omniwarp"):
            return message.strip()
    return None
