"""Output folders written all at once: a run writes into a staging folder beside its
`--out` folder and moves its files into place only when it has finished.

A failed or interrupted run leaves the previous results as they were; a finished run
replaces each of its outputs (a folder such as `images/` as a whole, so no image of an
earlier run stays behind). The staging folder lies in the same parent (or, for a
folder that does not exist yet, in its nearest existing ancestor), so every move is a
rename on one file system.
"""
from __future__ import annotations

import json
import logging
import os
import shutil
from collections.abc import Iterable
from contextlib import AbstractContextManager
from pathlib import Path

from . import interrupt
from .errors import InputError

log = logging.getLogger(__name__)

STAGING_PREFIX = ".omniwarp-staging-"


def _writable(path: Path) -> bool:
    return os.access(path, os.W_OK | os.X_OK)


def check_output_dir(path: str | os.PathLike, option: str = "--out") -> Path:
    """The absolute output folder, after checking that a run can write it.

    InputError (one line) when it is a file, lies under a file, or is in a folder
    without write permission. Nothing is created.
    """
    target = Path(os.path.abspath(os.fspath(path)))
    if target.exists() and not target.is_dir():
        raise InputError(f"{option} {path}: that is a file, not a folder; give a folder path")
    if target.is_dir():
        if not _writable(target):
            raise InputError(f"{option} {path}: no write permission in {target}; choose a writable folder")
        return target
    anchor = target.parent
    while not anchor.exists():
        anchor = anchor.parent
    if not anchor.is_dir():
        raise InputError(f"{option} {path}: {anchor} is a file, so no folder can be made under it")
    if not _writable(anchor):
        raise InputError(f"{option} {path}: no write permission in {anchor} to create it; choose a writable folder")
    return target


def _staging_parent(target: Path) -> Path:
    """Where the staging folder goes: beside the target when possible (same parent)."""
    if target.is_dir():
        return target.parent if _writable(target.parent) else target
    anchor = target.parent
    while not anchor.exists():
        anchor = anchor.parent
    return anchor


class StagedOutput:
    """`with StagedOutput(out, replaces=("images",)) as stage:` write into `stage.path`,
    then `stage.commit()`; leaving the block removes whatever was not moved.

    `replaces` names outputs of earlier runs that a finished run removes when it does
    not write them again (e.g. `images/` after a run with --no-images).
    """

    def __init__(self, target: str | os.PathLike, replaces: Iterable[str] = (), option: str = "--out") -> None:
        self.target = check_output_dir(target, option)
        self.option = option
        self.replaces = tuple(replaces)
        self._dir: AbstractContextManager[Path] | None = None
        self.path: Path | None = None
        self.committed = False

    def __enter__(self) -> "StagedOutput":
        parent = _staging_parent(self.target)
        try:
            self._dir = interrupt.temporary_dir(STAGING_PREFIX + self.target.name + "-", parent)
            self.path = self._dir.__enter__()
        except OSError as exc:
            raise InputError(f"{self.option} {self.target}: cannot write in {parent} ({exc.strerror or exc}); "
                             "choose a writable folder") from None
        return self

    def __exit__(self, *exc_info) -> None:
        if self._dir is not None:
            self._dir.__exit__(*exc_info)
            self._dir = None

    def commit(self) -> list[Path]:
        """Move every staged entry into the target folder; return the final paths.

        Interrupts wait until the moves are done (`interrupt.deferred`).
        """
        if self.path is None:
            raise RuntimeError("commit() outside the with block")
        with interrupt.deferred():
            self.target.mkdir(parents=True, exist_ok=True)
            moved = []
            names = sorted(entry.name for entry in self.path.iterdir())
            for name in names:
                moved.append(self._move(self.path / name, self.target / name))
            for name in self.replaces:
                stale = self.target / name
                if name not in names and (stale.exists() or stale.is_symlink()):
                    log.info("removing %s of an earlier run (this run wrote none)", stale)
                    self._discard(stale)
            self.committed = True
        return moved

    def _move(self, source: Path, dest: Path) -> Path:
        if source.is_dir() and (dest.exists() or dest.is_symlink()):
            # A folder is replaced as a whole: the old one is renamed aside first.
            self._discard(dest)
        os.replace(source, dest)
        return dest

    def _discard(self, path: Path) -> None:
        """Remove an old output: renamed into the staging folder (atomic), then deleted."""
        assert self.path is not None
        aside = self.path / f".old-{path.name}"
        os.replace(path, aside)
        if aside.is_dir() and not aside.is_symlink():
            shutil.rmtree(aside, ignore_errors=True)
        else:
            aside.unlink(missing_ok=True)


PARTIAL_NAME = "results.partial.json"


class FinishedRows:
    """The rows a run has finished so far, kept beside its results as they finish.

    Each finished row rewrites `OUT/results.partial.json` whole (a temporary file renamed
    over it, so a reader sees the rows before or after, never half a file). A run that is
    interrupted or fails keeps them there; its earlier `results.json` stays as it was.
    `discard()`, once the run's outputs are in place, removes the file.
    """

    def __init__(self, out_dir: Path) -> None:
        self.path = Path(out_dir) / PARTIAL_NAME
        self.rows: list[dict] = []

    def add(self, row: dict) -> None:
        self.rows.append(row)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        temporary = self.path.with_name(f".{PARTIAL_NAME}.{os.getpid()}.tmp")
        interrupt.register_temporary(temporary)
        with interrupt.deferred():  # the rename must not be cut from the write
            temporary.write_text(json.dumps(self.rows, indent=1), encoding="utf-8")
            os.replace(temporary, self.path)
        count = len(self.rows)
        interrupt.set_kept(f"{count} finished row{'s' if count != 1 else ''} kept in {self.path}")

    def discard(self) -> None:
        interrupt.set_kept("")
        if self.rows:
            try:
                self.path.unlink(missing_ok=True)
            except OSError as exc:
                log.warning("could not remove %s: %s", self.path, exc)
