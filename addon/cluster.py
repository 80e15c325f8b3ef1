"""The jobs of `compare` on Dask distributed (`--workers N`, `--scheduler ADDRESS`), docs/sweeps.md.

Imported only when one of those flags is given: without them no Dask is imported. Each
job is `shots.run_job` on a worker; a worker process holds one GL context (one
pipeline, made on its first job) and one bpy, and runs one job at a time (one thread).
A worker sends back its rows, its images as bytes and, unless the workers share the
cache folder (`--cache-dir`), the reference it rendered, which goes into the client's
cache. A lost worker's job is run again on another by Dask's own rescheduling; a job
that fails on bad input ends the run with its one line; Ctrl-C cancels the futures.

While a run lasts, each worker's statistical profiler is off (`RunPlugin`): it samples
the frames of the thread running a job every 10 ms, and a sample held as a Cycles render
ends keeps Cycles' engine object alive after Blender has freed it; when the sample is
dropped, the engine's `__del__` (addons_core/cycles/__init__.py) runs on the freed struct
and prints a ReferenceError traceback. At the end of a run a worker releases its GL
contexts and collects what it still holds of bpy's, while its modules are loaded.
"""
from __future__ import annotations

import gc
import logging
import os
import sys
import tempfile
import threading
import time
import uuid
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import dask
from distributed import Client, Future, LocalCluster, Worker, get_worker
from distributed.diagnostics.plugin import WorkerPlugin

from .compare import CompareOptions, Progress, check_some_fit, row_finished
from .core import interrupt
from .core.errors import OmniWarpError
from .render.pipeline import ShadowPipeline
from .core.rows import Row
from .shots import Job, run_job

log = logging.getLogger(__name__)

CONNECT_TIMEOUT_S = 10
POLL_S = 0.1  # how often the client looks at its futures: short, so Ctrl-C is served at once
# One pipeline per worker thread: a GL context is current in the thread that made it.
_PIPELINES: dict[int, ShadowPipeline] = {}
# The worker's periodic callbacks of Dask's statistical profiler (distributed.worker.profile).
PROFILER_CALLBACKS = ("profile", "profile-cycle")


class ClusterError(OmniWarpError):
    """The cluster could not be reached or started, or it lost a job for good."""


@dataclass
class RemoteResult:
    """A job's result as it crosses the network: rows, image bytes, a fresh reference."""

    rows: list[Row]
    skipped: list[str]
    images: dict[str, bytes] = field(default_factory=dict)
    reference: tuple[str, bytes] | None = None  # (cache file name, its bytes)
    worker: str = ""


def _worker_pipeline() -> ShadowPipeline:
    """This worker thread's pipeline, made on its first job and kept for the next."""
    from .render.backends.moderngl.backend import ModernGLBackend

    key = threading.get_ident()
    if key not in _PIPELINES:
        _PIPELINES[key] = ShadowPipeline(ModernGLBackend())
    return _PIPELINES[key]


class RunPlugin(WorkerPlugin):
    """A worker's part in one run: its profiler stopped from before the first job (see the
    module docstring) and started again at the end, after the worker has released what it
    holds (`release_worker`). Registered per run; a worker that joins later gets it too."""

    def __init__(self) -> None:
        self.stopped: list[str] = []

    def setup(self, worker: Worker) -> None:
        callbacks = worker.periodic_callbacks
        self.stopped = [name for name in PROFILER_CALLBACKS if name in callbacks and callbacks[name].is_running()]
        for name in self.stopped:
            callbacks[name].stop()

    def teardown(self, worker: Worker) -> None:
        release_worker()
        for name in self.stopped:  # a closing worker stops them again right after
            worker.periodic_callbacks[name].start()
        self.stopped = []


def remote_job(job: Job, options: CompareOptions, cache_dir: str | None, send_reference: bool) -> RemoteResult:
    """`shots.run_job` on a worker: its images are written to a temporary folder there and
    sent back as bytes, since the worker may see another file system than the client."""
    _drop_blender_paths()
    with tempfile.TemporaryDirectory(prefix="omniwarp_job_") as tmp, open(os.devnull, "w") as quiet:
        image_dir = Path(tmp) / "images" if options.write_images else None
        # The client shows progress per job; the worker's own row counter would only interleave.
        result = run_job(job, options, _worker_pipeline(), image_dir, Progress(1, stream=quiet), cache_dir,
                         say=lambda message: log.info("%s: %s", job.describe(), message))
        images = ({p.name: p.read_bytes() for p in sorted(image_dir.iterdir())}
                  if image_dir is not None and image_dir.is_dir() else {})
    reference = None
    if send_reference and result.rendered is not None and result.rendered.is_file():
        reference = (result.rendered.name, result.rendered.read_bytes())
    return RemoteResult(result.rows, result.skipped, images, reference, get_worker().address)


def _drop_blender_paths() -> None:
    """Before bpy is imported in a worker: drop the folders inside the bpy package from
    sys.path. A local worker is spawned with the client's sys.path, to which the client's
    own bpy added its scripts folders; `import bpy` would then find scripts/modules/bpy
    (Blender's Python half, without `_bpy`) before the module itself."""
    if "bpy" in sys.modules:
        return
    roots = [os.path.join(entry, "bpy") + os.sep for entry in sys.path if entry and _holds_bpy_module(entry)]
    sys.path[:] = [entry for entry in sys.path if not any(entry.startswith(root) for root in roots)]


def _holds_bpy_module(folder: str) -> bool:
    """Whether `folder` holds the bpy extension module (bpy/__init__.so, not a .py package)."""
    try:
        return any(name.startswith("__init__.") and name.endswith((".so", ".pyd"))
                   for name in os.listdir(os.path.join(folder, "bpy")))
    except OSError:
        return False


def run_jobs(jobs: Sequence[Job], options: CompareOptions, image_dir: Path | None, *, workers: int | None = None,
             scheduler: str | None = None, cache_dir: str | None = None) -> list[Row]:
    """Every job on a Dask cluster: a LocalCluster of `workers` processes, or the one at
    `scheduler`. The rows come back in job order, as the serial run gives them."""
    # Dask's own scratch folders (the scheduler's, the nannies') go under ours too.
    with interrupt.temporary_dir("omniwarp_dask_") as tmp, dask.config.set({"temporary-directory": str(tmp)}):
        cluster: LocalCluster | None = None
        client: Client | None = None
        plugin: str | None = None
        futures: list[Future] = []
        try:
            with interrupt.deferred():  # a Ctrl-C during the start must not orphan the workers
                cluster, client = _connect(workers, scheduler, tmp)
            _say(f"running {len(jobs)} jobs on {_describe(client, scheduler)}")
            # No --cache-dir: each worker caches its references where it is, and a reference a
            # worker rendered comes back into this machine's cache too.
            send = cache_dir is None
            run = uuid.uuid4().hex[:8]
            plugin = f"omniwarp-{run}"
            # A Ctrl-C inside one of Dask's blocking calls can reach its event loop half done
            # (distributed's sync() then prints a NameError traceback): it is raised after them.
            with interrupt.deferred():
                client.register_plugin(RunPlugin(), name=plugin)
                futures = [client.submit(remote_job, job, options, cache_dir, send, key=f"omniwarp-{run}-{i}",
                                         pure=False) for i, job in enumerate(jobs)]
            results = _gather(jobs, futures, image_dir, cache_dir)
        except BaseException:
            # Bad input, Ctrl-C or a bug: nothing more runs for this run.
            if client is not None and futures:
                with interrupt.deferred():
                    _cancel(client, futures)
            raise
        finally:
            with interrupt.deferred():  # the workers go before the temporaries do
                _close(client, cluster, plugin)
    rows = [row for result in results for row in result.rows]
    check_some_fit(rows, [entry for result in results for entry in result.skipped])
    return rows


def _connect(workers: int | None, scheduler: str | None, tmp: Path) -> tuple[LocalCluster | None, Client]:
    """A client of the cluster at `scheduler`, or of a new LocalCluster of `workers` processes."""
    verbose = logging.getLogger("omniwarp").isEnabledFor(logging.INFO)
    if not verbose:
        # Dask logs every worker's start and stop at INFO, and a heartbeat cut short by the
        # close as an error; without -v stderr keeps the run's own lines. A job's failure
        # comes back through its future either way.
        logging.getLogger("distributed").setLevel(logging.CRITICAL)
    if scheduler is not None:
        try:
            return None, Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError) as exc:
            raise ClusterError(f"--scheduler {scheduler}: no Dask scheduler answered ({exc}); start one with "
                               "`dask scheduler` and its workers with `dask worker ADDRESS`") from None
    # One thread per worker process: one GL context and one bpy each. Their temporaries
    # (Dask's spill folder, Blender's session folder) go under ours, so nothing stays behind.
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                           local_directory=str(tmp), env={"TMPDIR": str(tmp)},
                           silence_logs=logging.INFO if verbose else logging.CRITICAL)
    return cluster, Client(cluster)


def _describe(client: Client, scheduler: str | None) -> str:
    count = len(client.scheduler_info().get("workers", {}))
    where = scheduler if scheduler is not None else "a local cluster"
    return f"{where} ({count} worker{'s' if count != 1 else ''})"


def _gather(jobs: Sequence[Job], futures: list[Future], image_dir: Path | None,
            cache_dir: str | None) -> list[RemoteResult]:
    """Wait for every future (polling, so a signal is served at once), write each job's
    images as it finishes, and say jobs done of total with the time left."""
    results: list[RemoteResult | None] = [None] * len(futures)
    pending = dict(enumerate(futures))
    start = time.perf_counter()
    done = 0
    while pending:
        finished = [i for i, future in pending.items() if future.done()]
        if not finished:
            interrupt.check()
            time.sleep(POLL_S)
            continue
        for i in finished:
            future = pending.pop(i)
            results[i] = _result(jobs[i], future)
            _keep(results[i], image_dir, cache_dir)
            for row in results[i].rows:  # kept as they come (results.partial.json), in finishing order
                row_finished(row)
            done += 1
            elapsed = time.perf_counter() - start
            left = elapsed / done * (len(futures) - done)
            _say(f"[{done}/{len(futures)} jobs] {jobs[i].describe()} done on {results[i].worker} "
                 f"({elapsed:.0f}s elapsed, ~{left:.0f}s left)")
    return results  # type: ignore[return-value]


def _result(job: Job, future: Future) -> RemoteResult:
    """A finished future's result; its error as raised (bad input stays one line)."""
    if future.status == "error":
        exc = future.exception()
        if isinstance(exc, OmniWarpError):
            raise exc
        if type(exc).__name__ == "KilledWorker":
            raise ClusterError(f"job {job.describe()} was lost with every worker that ran it ({exc}); "
                               "see the workers' logs") from None
        raise exc  # a bug: shown with its traceback by the command
    if future.status == "cancelled":
        raise ClusterError(f"job {job.describe()} was cancelled by the cluster")
    return future.result()


def _keep(result: RemoteResult, image_dir: Path | None, cache_dir: str | None) -> None:
    """A job's images into the run's staging folder; a fresh reference into this cache."""
    if image_dir is not None and result.images:
        image_dir.mkdir(parents=True, exist_ok=True)
        for name, data in result.images.items():
            (image_dir / Path(name).name).write_bytes(data)
    if result.reference is not None:
        from .reference.cache import cache_dir_path

        folder = cache_dir_path(cache_dir)
        target = folder / Path(result.reference[0]).name
        if not target.exists():  # a worker on this machine may have written it already
            try:
                folder.mkdir(parents=True, exist_ok=True)
                part = target.with_name(f".{target.name}.{os.getpid()}.part")
                part.write_bytes(result.reference[1])
                os.replace(part, target)  # atomic, like every cache write
            except OSError as exc:
                log.warning("could not keep the reference %s in %s: %s", target.name, folder, exc)


def _cancel(client: Client, futures: list[Future]) -> None:
    try:
        client.cancel(futures, force=True)
    except (OSError, TimeoutError, RuntimeError) as exc:  # the cluster may be gone already
        log.info("cancelling the futures: %s", exc)


def release_worker() -> None:
    """On a worker at the end of a run: release its GL contexts, and collect the garbage now,
    while Blender's Python modules are loaded: a bpy object in a reference cycle is then
    finalized by a working interpreter, not during the worker's interpreter shutdown."""
    while _PIPELINES:
        _, pipeline = _PIPELINES.popitem()
        pipeline.backend.release()
    if "bpy" in sys.modules:
        gc.collect()


def _close(client: Client | None, cluster: LocalCluster | None, plugin: str | None) -> None:
    """Close the client, then the local cluster and its worker processes (an external
    cluster stays up: it is not ours, but each worker ends its part in the run first:
    `RunPlugin.teardown`)."""
    if client is not None and plugin is not None:
        try:
            client.unregister_worker_plugin(plugin)
        except (OSError, TimeoutError, RuntimeError, ValueError) as exc:
            log.info("ending the workers' part in the run: %s", exc)
    for what, thing in (("client", client), ("cluster", cluster)):
        if thing is None:
            continue
        try:
            thing.close()
        except (OSError, TimeoutError, RuntimeError) as exc:
            log.warning("closing the Dask %s: %s", what, exc)


def _say(message: str) -> None:
    print(message, file=sys.stderr, flush=True)
