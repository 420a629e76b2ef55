"""Running a study on Dask: submit chunks, persist results as they finish, assemble.

The client submits at most a window of chunks at a time (a few per worker
thread, resized as workers come and go) and refills it from ``as_completed``,
so neither the client nor the scheduler ever holds the whole study. Workers
return numpy arrays and never write files; the client writes each finished
chunk atomically into the work folder (``OUT.nc.work/``, :mod:`study.store`)
before counting it done. A rerun skips every chunk already on disk (resume); a
killed worker costs only the tasks it was running or holding, which the
scheduler reruns elsewhere; tasks that raise are retried (``retries``). After
the last chunk the result file is assembled (:mod:`study.netcdf`), written
atomically, and only then is the work folder removed.

Where the computing happens:

* default: a ``LocalCluster`` on this machine (one single-threaded worker
  process per core, 127.0.0.1 only);
* ``scheduler=ADDRESS`` / ``scheduler_file=FILE`` (CLI ``--scheduler``,
  ``--scheduler-file``): any running Dask scheduler, e.g. one started by
  dask-jobqueue on an HPC batch system. The recipe for SLURM (and other batch
  systems) is in ``examples/hpc_slurm.md``.
"""

from __future__ import annotations

import logging
import os
import sys
import time
from collections.abc import Iterator
from concurrent.futures import CancelledError
from contextlib import contextmanager, nullcontext, suppress
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from distributed.diagnostics.plugin import WorkerPlugin

from study.chunks import Chunk, ScenePlan, plan
from study.compute import compute_chunk
from study.connect import DEFAULT_SCHEDULER_TIMEOUT, call_within, check_timeout
from study.connect import connect as connect_scheduler
from study.cost import CostTracker
from study.definition import Study
from study.errors import StudyError, StudyFailed, StudyInterrupted
from study.firstrun import compile_once
from study.preflight import check_run, older_result_note
from study.progress import Progress
from study.store import WorkDir, temporary_outputs
from study.verify import chunk_shape
from study.watchdog import (
    ASK_TIMEOUT,
    DEFAULT_WORKER_TIMEOUT,
    Watchdog,
    quiet_dask_logs,
    start_deferring_sigint,
    watched_batches,
    watched_gather,
)

#: Chunks kept in flight per worker thread (at least ``MIN_WINDOW`` in all).
WINDOW_PER_THREAD = 4
MIN_WINDOW = 16
#: Seconds between two looks at the number of worker threads (window size).
WINDOW_REFRESH = 5.0


@dataclass
class RunSummary:
    """What a run did (also printed by the CLI)."""

    output: Path
    n_points: int
    n_chunks: int
    reused: int
    computed: int
    wall_seconds: float
    compute_seconds: float
    #: Wall seconds from the first submitted chunk to the last saved one
    #: (no cluster start-up, no file assembly).
    compute_wall_seconds: float = 0.0
    #: Wall seconds spent assembling the result file.
    write_seconds: float = 0.0


def default_workers() -> int:
    """Cores available to this process."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


class IgnoreSigint(WorkerPlugin):
    """Worker plugin: a local worker process ignores SIGINT.

    Ctrl-C in a terminal reaches every process of the foreground group, the
    LocalCluster's worker processes included; they would die printing
    tracebacks while the client is still cancelling. The client handles
    Ctrl-C and then stops its own cluster. Registered only on the LocalCluster
    that :func:`connect` starts, never on a shared cluster.
    """

    name = "study-ignore-sigint"
    idempotent = True

    def setup(self, worker) -> None:
        import signal
        import threading

        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, signal.SIG_IGN)


def dashboard_note(client, local: bool) -> str:
    """``dashboard LINK`` (with a hint when bokeh is missing), or ``no dashboard``."""
    try:
        link = client.dashboard_link
    except (KeyError, AttributeError, TypeError):  # the scheduler runs without one
        link = None
    if not link:
        return "no dashboard"
    if local:
        try:
            import bokeh  # noqa: F401
        except ImportError:
            return f"dashboard {link} (its plots need bokeh>=3.1: pip install bokeh)"
    return f"dashboard {link}"


@contextmanager
def connect(
    client=None,
    scheduler: str | None = None,
    scheduler_file: str | None = None,
    workers: int | None = None,
    stream: TextIO = sys.stderr,
    scheduler_timeout: float = DEFAULT_SCHEDULER_TIMEOUT,
    worker_timeout: float = DEFAULT_WORKER_TIMEOUT,
):
    """A Dask client: the one given, a running scheduler, or a new LocalCluster.

    The LocalCluster has one single-threaded worker process per core (the
    numerics hold the GIL) and listens on 127.0.0.1 only. With a running
    scheduler, ``workers`` means: wait until that many workers are connected.
    A client that is given is neither changed nor closed.
    """
    if client is not None:
        yield client
        return
    from distributed import Client, LocalCluster

    cluster = None
    if scheduler or scheduler_file:
        where = scheduler or scheduler_file
        client = connect_scheduler(scheduler, scheduler_file, scheduler_timeout)  # bounded
        try:
            n = len(call_within(scheduler_timeout, client.nthreads))
            print(
                f"study: connected to {client.scheduler.address} ({n} workers), "
                f"{dashboard_note(client, local=False)}",
                file=stream,
            )
            if workers and n < workers:
                print(f"study: waiting for {workers} workers", file=stream)
                try:  # bounded: workers that never come, a scheduler that stops answering
                    call_within(
                        worker_timeout + scheduler_timeout, client.wait_for_workers, workers
                    )
                except TimeoutError:
                    raise StudyFailed(
                        f"{workers} workers did not connect to {where} within "
                        f"{worker_timeout:g} s (--worker-timeout); nothing was computed"
                    ) from None
            elif not n:
                print("study: no workers yet; tasks wait until workers connect", file=stream)
        except BaseException as exc:
            with suppress(TimeoutError):
                call_within(2 * scheduler_timeout, client.close)
            if isinstance(exc, TimeoutError):  # call_within's: the scheduler went silent
                raise StudyFailed(
                    f"the scheduler {where} stopped answering after the connection "
                    f"({scheduler_timeout:g} s, --scheduler-timeout); nothing was computed"
                ) from None
            raise
    else:
        n = workers or default_workers()
        cluster = start_deferring_sigint(  # Ctrl-C during the start: one line (study.watchdog)
            lambda: LocalCluster(
                n_workers=n,
                threads_per_worker=1,
                processes=True,
                host="127.0.0.1",
                dashboard_address="127.0.0.1:0",
                # workers' own logs: a worker that outlives the scheduler at Ctrl-C
                # logs heartbeat tracebacks; the run reports failures itself
                silence_logs=logging.CRITICAL,
            )
        )
        try:
            client = Client(cluster)
            client.register_plugin(IgnoreSigint())
            print(
                f"study: local cluster with {n} workers, {dashboard_note(client, local=True)}",
                file=stream,
            )
        except BaseException as exc:
            if client is not None:
                client.close()
            cluster.close()
            if isinstance(exc, OSError):  # e.g. a worker killed while it started: one line
                raise StudyFailed(
                    f"the local cluster failed while starting: {type(exc).__name__}; "
                    "nothing was computed, rerun to try again"
                ) from None
            raise
    try:
        yield client
    finally:  # bounded: the scheduler or the workers may have stopped answering
        with suppress(TimeoutError):
            call_within(2 * scheduler_timeout, client.close)
            if cluster is not None:
                call_within(2 * scheduler_timeout, cluster.close)


def _check_runnable(study: Study, output: Path, overwrite: bool = False) -> None:
    if not output.parent.is_dir():
        raise StudyError("-o", f"output directory does not exist: {output.parent}")
    if output.is_dir():
        raise StudyError("-o", f"output is a directory: {output}")
    if output.exists() and not overwrite:  # written atomically: it exists only when complete
        raise StudyError(
            "-o", f"{output} is complete already; --overwrite computes it again and replaces it"
        )


def run_study(
    study: Study,
    output: str | os.PathLike | None = None,
    *,
    client=None,
    scheduler: str | None = None,
    scheduler_file: str | None = None,
    workers: int | None = None,
    retries: int = 3,
    progress: bool = True,
    command: str | None = None,
    stream: TextIO | None = None,
    overwrite: bool = False,
    worker_timeout: float = DEFAULT_WORKER_TIMEOUT,
    scheduler_timeout: float = DEFAULT_SCHEDULER_TIMEOUT,
) -> RunSummary:
    """Compute every missing chunk of ``study`` and write the result to ``output``.

    Parameters
    ----------
    study : Study
        A validated study.
    output : path, optional
        The netCDF file to write; chunks are kept in ``output + ".work"``.
        Without it nothing is written: the chunks are kept in memory and the
        labelled result is returned (an ``xarray.DataTree`` laid out as the
        file would be: one scene at the root, several as children).
    client : distributed.Client, optional
        Use this client (it is not closed). Otherwise connect to ``scheduler``
        (an address) or ``scheduler_file``, or start a LocalCluster with
        ``workers`` processes (default: one per core).
    retries : int
        Times a task that raised is retried before the run fails (0..100).
    overwrite : bool
        Compute and replace an ``output`` that exists (complete) already;
        without it such a run is refused.
    worker_timeout : float
        Seconds without any live worker (none connected, or all stopped answering)
        before the run stops with ``StudyFailed`` (:mod:`study.watchdog`).
    scheduler_timeout : float
        Seconds a scheduler may take to answer, at connection (``StudyError``)
        and during the run (``StudyFailed``) (:mod:`study.connect`).

    Raises
    ------
    StudyError
        Bad output path, an existing output without ``overwrite``,
        unreachable scheduler, a run of the same output already in progress,
        or an unavailable feature (nothing is written).
    StudyInterrupted
        Ctrl-C (KeyboardInterrupt): finished chunks stay in the work folder,
        no result file.
    StudyFailed
        A chunk failed on every retry, or the scheduler cancelled it.

    Returns
    -------
    RunSummary or xarray.DataTree
        What the run did (with ``output``), or the result (without).
    """
    if not isinstance(study, Study):
        raise TypeError(
            f"study: must be a Study (Study.from_toml(path)), got a {type(study).__name__}"
        )
    check_timeout(scheduler_timeout, "--scheduler-timeout")
    stream = stream if stream is not None else sys.stderr
    t0 = time.perf_counter()
    in_memory = output is None
    check_run(output, client, scheduler, scheduler_file, workers, retries, worker_timeout)
    plans = plan(study)
    adaptive = [p for p in plans if p.kind == "adaptive"]  # refinement waves (study.adaptive)
    if in_memory:
        from study.memory import MemoryWork

        work = MemoryWork()
    else:
        output = Path(output)
        _check_runnable(study, output, overwrite)
        work = WorkDir(output)
    if not work.lock():
        raise StudyError(
            "-o", f"another run is writing {output} (its work folder {work.path} is locked)"
        )
    finished = False
    saved = [0]  # chunks on disk for this study: reused + computed so far
    n_chunks = 0
    try:
        stale = work.clean()
        for p in [] if in_memory else temporary_outputs(output):
            p.unlink(missing_ok=True)
            stale += 1
        reused = reused_points = discarded = 0
        for p in plans:
            if p.kind == "adaptive":
                continue
            for c in p.chunks():
                n_chunks += 1
                if work.has(c.scene, c.key):
                    why = work.discard_if_bad(c.scene, c.key, chunk_shape(p.kind, c.rows, c.cols))
                    if why:  # verified, not trusted (study.verify)
                        discarded += 1
                        path = work.chunk_path(c.scene, c.key)
                        print(f"study: discarded {path}: {why}; computing it again", file=stream)
                        continue
                    reused += 1
                    reused_points += c.n_points
        saved[0] = reused
        missing = n_chunks - reused
        n_points = study.n_points
        print(
            f"study: {study.name}: {n_points:,} points in {n_chunks:,} chunks; "
            f"reusing {reused:,} chunks from {work.path}, computing {missing:,}"
            + (f" (deleted {stale} partial files of a killed run)" if stale else ""),
            file=stream,
        )
        compute_seconds = compute_wall = 0.0
        if adaptive:
            from study.adaptive import missing_planes, run_adaptive

            adaptive = [p for p in adaptive if missing_planes(p, work)]
        if missing or adaptive:
            bar = Progress(n_points, reused_points, stream=stream, enabled=progress)
            bar.tracker = cost_tracker(plans, work)  # learns each scene's cost (study.cost)
            bar.eta_seconds = bar.tracker.eta
            if client is None and not (scheduler or scheduler_file):
                compile_once(stream)  # before the local workers start: they load it from cache
            quiet = quiet_dask_logs() if client is None else nullcontext()
            kw = {"scheduler_timeout": scheduler_timeout, "worker_timeout": worker_timeout}
            with quiet, connect(client, scheduler, scheduler_file, workers, stream, **kw) as c:
                bar.start()
                t1 = time.perf_counter()
                dog = Watchdog(
                    c,
                    worker_timeout,
                    local=client is None and not (scheduler or scheduler_file),
                    where=str(work.path),
                    stream=stream,
                    scheduler_timeout=scheduler_timeout,
                )
                if missing:
                    grid = [p for p in plans if p.kind != "adaptive"]
                    compute_seconds = _compute(c, grid, work, bar, retries, saved, watchdog=dog)
                for p in adaptive:
                    run_adaptive(c, p, work, retries, stream, progress, saved, bar, watchdog=dog)
                compute_wall = time.perf_counter() - t1
            bar.close()
        from study.netcdf import result_tree, write_result

        t2 = time.perf_counter()
        if in_memory:
            tree = result_tree(study, plans, work)
        else:
            write_result(study, plans, work, output, command)
        write_seconds = time.perf_counter() - t2
        finished = True
    except KeyboardInterrupt:
        raise StudyInterrupted(
            f"interrupted: {saved[0]:,} of {n_chunks:,} chunks are saved in {work.path}; "
            f"{older_result_note(output)}; rerun the same command to resume"
        ) from None
    finally:
        if finished or not work.count():
            work.remove()  # done, or nothing worth keeping
        else:
            work.unlock()
    wall = time.perf_counter() - t0
    computed = saved[0] - reused  # chunks whose results arrived and were saved by this run
    if in_memory:
        print(f"study: computed {n_points:,} points in memory in {wall:.1f} s", file=stream)
        return tree
    print(
        f"study: wrote {output} ({n_points:,} points; {computed:,} chunks computed, "
        f"{reused:,} reused) in {wall:.1f} s",
        file=stream,
    )
    return RunSummary(
        output,
        n_points,
        n_chunks,
        reused,
        computed,
        wall,
        compute_seconds,
        compute_wall,
        write_seconds,
    )


def cost_tracker(plans: list[ScenePlan], work: WorkDir) -> CostTracker:
    """A :class:`study.cost.CostTracker` of the chunks still missing from ``work``."""
    estimates = {}
    for p in plans:
        missing = sum(c.n_points for c in p.chunks() if not work.has(c.scene, c.key))
        per = p.est_seconds / max(1, p.spec.n_points)
        estimates[p.spec.name] = (missing, per)
    return CostTracker(estimates)


def _pending(plans: list[ScenePlan], work: WorkDir) -> Iterator[tuple[ScenePlan, dict, Chunk]]:
    for p in plans:
        axes = p.axes()
        for c in p.chunks():
            if not work.has(c.scene, c.key):
                yield p, axes, c


def _failure(chunk: Chunk, exc: BaseException, retries: int, work: WorkDir) -> StudyFailed:
    from distributed import KilledWorker
    from distributed.comm.core import CommClosedError

    if isinstance(exc, CancelledError):
        why = "was cancelled by the scheduler (restarted, or the connection to it was lost)"
    elif isinstance(exc, CommClosedError | ConnectionError):
        why = "could not be fetched: the connection to the scheduler was lost"
    elif isinstance(exc, KilledWorker):
        why = f"killed every worker that ran it: {exc}"
    else:
        why = f"failed after {retries} retries: {type(exc).__name__}: {exc}"
    msg = (
        f"chunk {chunk.key} of scene {chunk.scene} {why}; "
        f"finished chunks are kept in {work.path}, rerun to resume"
    )
    return StudyFailed(" ".join(msg.split()))


def _compute(
    client,
    plans,
    work: WorkDir,
    bar: Progress,
    retries: int,
    saved: list[int],
    watchdog: Watchdog | None = None,
) -> float:
    """Submit the missing chunks through a sliding window; persist each as it finishes.

    ``saved[0]`` counts the chunks on disk (for the message of an interrupted
    run). Returns the compute seconds the finished chunks report.
    """
    from distributed import as_completed

    todo = _pending(plans, work)
    inflight: dict[str, tuple[object, Chunk]] = {}  # future key -> (future, chunk)
    futures = as_completed()
    compute_seconds = 0.0
    window = MIN_WINDOW
    next_look = 0.0

    def fill() -> None:
        nonlocal window, next_look
        now = time.monotonic()
        if now >= next_look:  # workers come and go (adaptive clusters, lost workers)
            try:
                threads = sum(call_within(ASK_TIMEOUT, client.nthreads).values())
            except (OSError, TimeoutError):  # unreachable or silent: the watchdog decides
                threads = 0
            window = max(MIN_WINDOW, WINDOW_PER_THREAD * threads)
            next_look = now + WINDOW_REFRESH
        batch: list[tuple[ScenePlan, dict, Chunk]] = []
        while len(inflight) + len(batch) < window:
            item = next(todo, None)
            if item is None:
                break
            batch.append(item)
        if not batch:
            return
        new = client.map(
            compute_chunk,
            [p.task(c, axes) for p, axes, c in batch],
            key=[f"study-{c.key}" for _, _, c in batch],
            retries=retries,
            pure=False,
        )
        for fut, (_, _, chunk) in zip(new, batch, strict=True):
            inflight[fut.key] = (fut, chunk)
        futures.update(new)

    try:
        fill()
        for done in watched_batches(futures, watchdog):
            try:  # one round trip for the whole batch
                results = watched_gather(client, done, watchdog)
            except BaseException as exc:
                if isinstance(exc, KeyboardInterrupt):
                    raise
                results = None
            for i, fut in enumerate(done):
                _, chunk = inflight[fut.key]
                if results is None:
                    try:
                        arrays = watched_gather(client, [fut], watchdog)[0]
                    except (KeyboardInterrupt, StudyFailed):  # StudyFailed: the watchdog's
                        raise
                    except BaseException as exc:  # CancelledError is not an Exception
                        raise _failure(chunk, exc, retries, work) from None
                else:
                    arrays = results[i]
                work.save(chunk.scene, chunk.key, arrays)
                del inflight[fut.key]
                fut.release()
                saved[0] += 1
                compute_seconds += float(arrays["seconds"])
                bar.update(chunk.n_points)
                if getattr(bar, "tracker", None) is not None:
                    bar.tracker.record(chunk.scene, chunk.n_points, float(arrays["seconds"]))
            fill()
    except BaseException:
        with suppress(TimeoutError):  # bounded: the scheduler may be the one that went silent
            call_within(ASK_TIMEOUT, client.cancel, [f for f, _ in inflight.values()])
        raise
    if inflight:  # as_completed ended with chunks unaccounted for: never silently
        chunk = next(iter(inflight.values()))[1]
        raise StudyFailed(f"chunk {chunk.key} of scene {chunk.scene} never completed")
    return compute_seconds
