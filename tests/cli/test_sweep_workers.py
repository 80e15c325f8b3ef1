"""A worker's part in a cluster run (addon/cluster.py's RunPlugin), without a cluster: Dask's
statistical profiler is stopped before the first job and started again at the end, after
the worker has let go of what it holds. The runs themselves are in test_sweeps.py."""
from __future__ import annotations

from types import SimpleNamespace

import pytest

pytest.importorskip("distributed", reason="the cluster runs need the dask extra (scripts/setup_env.sh installs it)")

from addon import cluster  # noqa: E402

pytestmark = pytest.mark.dask


class _Callback:
    """A stand-in for tornado's PeriodicCallback."""

    def __init__(self, running: bool) -> None:
        self.running = running

    def is_running(self) -> bool:
        return self.running

    def start(self) -> None:
        self.running = True

    def stop(self) -> None:
        self.running = False


def test_the_profiler_is_off_while_a_run_lasts(monkeypatch):
    """A profile sample holds the frames of the thread running a job; one taken as a Cycles
    render ends outlives Blender's free of the engine, whose __del__ then prints a traceback."""
    callbacks = {"profile": _Callback(True), "profile-cycle": _Callback(True), "heartbeat": _Callback(True)}
    worker = SimpleNamespace(periodic_callbacks=callbacks)
    released = []
    monkeypatch.setattr(cluster, "release_worker", lambda: released.append(True))
    plugin = cluster.RunPlugin()
    plugin.setup(worker)
    assert not callbacks["profile"].running and not callbacks["profile-cycle"].running
    assert callbacks["heartbeat"].running
    plugin.teardown(worker)
    assert released == [True]
    assert all(callback.running for callback in callbacks.values())


def test_a_profiler_that_was_off_stays_off():
    callbacks = {"profile": _Callback(False)}  # distributed.worker.profile.enabled: False has no "profile-cycle"
    worker = SimpleNamespace(periodic_callbacks=callbacks)
    plugin = cluster.RunPlugin()
    plugin.setup(worker)
    plugin.teardown(worker)
    assert not callbacks["profile"].running


def test_release_worker_lets_go_of_the_pipelines(monkeypatch):
    released = []
    pipeline = SimpleNamespace(backend=SimpleNamespace(release=lambda: released.append(True)))
    monkeypatch.setattr(cluster, "_PIPELINES", {1: pipeline})
    cluster.release_worker()
    assert released == [True] and cluster._PIPELINES == {}
