"""Running a study: plans, the cluster, the work folder, the result file.

:func:`run_study` drives every scene kind the same way: the study becomes one
plan per scene (:mod:`study.chunks`), each plan verifies what the work folder
(``OUT.nc.work/``, :mod:`study.store`) holds already, the missing units of work
are computed on Dask (:mod:`study.drive`), and the result file is assembled
(:mod:`study.netcdf`), written atomically; only then is the work folder
removed. A rerun reuses every verified unit (resume).

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
import threading
import time
from contextlib import contextmanager, nullcontext, suppress
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from study.chunks import ScenePlan, plan
from study.connect import DEFAULT_SCHEDULER_TIMEOUT, call_within, check_timeout
from study.connect import connect as connect_scheduler
from study.cost import CostTracker
from study.definition import Study
from study.drive import Driven, drive, local_threads
from study.errors import StudyError, StudyFailed, StudyInterrupted
from study.firstrun import compile_once, kernels_for
from study.preflight import check_run, default_workers, older_result_note
from study.progress import Progress
from study.store import WorkDir, os_cause, temporary_outputs
from study.watchdog import (
    DEFAULT_WORKER_TIMEOUT,
    Watchdog,
    quiet_dask_logs,
    start_deferring_sigint,
)

__all__ = ["RunSummary", "connect", "default_workers", "run_study"]


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


def ignore_sigint_plugin():
    """A worker plugin: a local worker process ignores SIGINT.

    Ctrl-C in a terminal reaches every process of the foreground group, the
    LocalCluster's worker processes included; they would die printing
    tracebacks while the client is still cancelling. The client handles
    Ctrl-C and then stops its own cluster. Registered only on the LocalCluster
    that :func:`connect` starts, never on a shared cluster. (Made on demand:
    ``distributed`` is imported only by runs that use it.)
    """
    from distributed.diagnostics.plugin import WorkerPlugin

    class IgnoreSigint(WorkerPlugin):
        name = "study-ignore-sigint"
        idempotent = True

        def setup(self, worker) -> None:
            import signal
            import threading

            if threading.current_thread() is threading.main_thread():
                signal.signal(signal.SIGINT, signal.SIG_IGN)

    return IgnoreSigint()


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
    in_process: int = 0,
):
    """A Dask client: the one given, a running scheduler, or a new LocalCluster.

    The LocalCluster has one single-threaded worker process per core and
    listens on 127.0.0.1 only; with ``in_process`` threads, one worker of that
    many threads in this process instead (no process to start: for studies
    whose planned compute is short, :func:`study.drive.local_threads`). With a running
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
        n = 1 if in_process else workers or default_workers()
        cluster = start_deferring_sigint(  # Ctrl-C during the start: one line (study.watchdog)
            lambda: LocalCluster(
                n_workers=n,
                threads_per_worker=max(1, in_process),
                processes=not in_process,
                # tcp:// for a cluster in this process too: inproc:// opens a port on
                # every interface beside it
                protocol="tcp://",
                host="127.0.0.1",
                dashboard_address="127.0.0.1:0",
                # workers' own logs: a worker that outlives the scheduler at Ctrl-C
                # logs heartbeat tracebacks; the run reports failures itself
                silence_logs=logging.CRITICAL,
            )
        )
        try:
            client = Client(cluster)
            client.register_plugin(ignore_sigint_plugin())
            what = (
                "a small study: computing in this process (no worker processes to wait "
                f"for), {in_process} thread{'s' if in_process > 1 else ''}"
                if in_process
                else f"local cluster with {n} workers"
            )
            print(f"study: {what}, {dashboard_note(client, local=True)}", file=stream)
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
    """Compute every missing unit of ``study`` and write the result to ``output``.

    Parameters
    ----------
    study : Study
        A validated study.
    output : path, optional
        The netCDF file to write; units are kept in ``output + ".work"``.
        Without it nothing is written: the units are kept in memory and the
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
        Ctrl-C (KeyboardInterrupt): finished units stay in the work folder,
        no result file.
    StudyFailed
        A unit failed on every retry, the scheduler cancelled it, or the
        operating system refused a write (one line naming the path).

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
    check_run(output, client, scheduler, scheduler_file, workers, retries, worker_timeout)
    plans = plan(study)
    work = _work(study, output, overwrite, stream)
    done, survey, finished = Driven(), None, False
    try:
        survey = _survey(study, plans, work, output, stream)
        if survey.missing:
            where = (client, scheduler, scheduler_file, workers)
            timeouts = (worker_timeout, scheduler_timeout)
            timing = _compute(plans, work, where, retries, progress, timeouts, done, stream)
        else:
            timing = (0.0, 0.0)
        t2 = time.perf_counter()
        result = _assemble(study, plans, work, output, command)
        write_seconds = time.perf_counter() - t2
        finished = True
    except KeyboardInterrupt:
        raise StudyInterrupted(_interrupted(work, output, done, survey)) from None
    except OSError as exc:  # the OS refused the work folder: one line, nothing lost
        where = exc.filename or work.path
        raise StudyFailed(
            f"cannot use {where}: {os_cause(exc)}; {older_result_note(output)}"
        ) from None
    finally:
        if not finished:
            _keep(plans, work)
        _release(work, finished)
    wall = time.perf_counter() - t0
    if output is None:
        print(f"study: computed {study.n_points:,} points in memory in {wall:.1f} s", file=stream)
        return result
    print(
        f"study: wrote {output} ({study.n_points:,} points; {done.saved:,} chunks computed, "
        f"{survey.reused:,} reused) in {wall:.1f} s",
        file=stream,
    )
    return RunSummary(
        Path(output),
        study.n_points,
        survey.units,
        survey.reused,
        done.saved,
        wall,
        done.compute_seconds,
        timing[1],
        write_seconds,
    )


@dataclass
class Survey:
    """What the work folder holds for a study's plans (after their ``prepare``)."""

    units: int
    reused: int
    missing: bool
    #: Every unit is known ahead (no adaptive scene).
    fixed: bool = True


def _work(study: Study, output, overwrite: bool, stream: TextIO):
    """The locked work folder of ``output`` (in memory without one)."""

    def report(line: str) -> None:
        print(line, file=stream)

    if output is None:
        from study.memory import MemoryWork

        return MemoryWork(report)
    output = Path(output)
    _check_runnable(study, output, overwrite)
    work = WorkDir(output, report)
    try:
        locked = work.lock()
    except OSError as exc:
        raise StudyError("-o", f"cannot lock {work.lock_path}: {os_cause(exc)}") from None
    if not locked:
        raise StudyError(
            "-o", f"another run is writing {output} (its work folder {work.path} is locked)"
        )
    return work


def _survey(study: Study, plans: list[ScenePlan], work, output, stream: TextIO) -> Survey:
    """Clean and verify the work folder; say in one line what is reused and what is computed."""
    stale = work.scan([p.spec.name for p in plans])
    for p in [] if output is None else temporary_outputs(output):
        p.unlink(missing_ok=True)
        stale += 1
    by_noun: dict[str, list[int]] = {}
    for p in plans:
        p.stream = stream
        n, reused, _ = p.prepare(work)
        counts = by_noun.setdefault(p.unit_noun, [0, 0])
        counts[0] += n
        counts[1] += reused
    parts = [
        f"{n:,} {noun}; reusing {reused:,} {noun} from {work.path}, computing {n - reused:,}"
        for noun, (n, reused) in by_noun.items()
    ]
    print(
        f"study: {study.name}: {study.n_points:,} points in "
        + "; ".join(parts)
        + (f" (deleted {stale} partial files of a killed run)" if stale else ""),
        file=stream,
    )
    units = sum(n for n, _ in by_noun.values())
    reused = sum(r for _, r in by_noun.values())
    missing = any(p.missing_points(work) for p in plans)
    return Survey(units, reused, missing, set(by_noun) == {"chunks"})


def _compute(plans, work, where, retries, progress, timeouts, done, stream):
    """Compute every missing unit on the cluster; (compute seconds, compute wall seconds)."""
    client, scheduler, scheduler_file, workers = where
    worker_timeout, scheduler_timeout = timeouts
    local = client is None and not (scheduler or scheduler_file)
    total = sum(p.spec.n_points for p in plans)
    bar = Progress(total, sum(p.finished_points for p in plans), stream=stream, enabled=progress)
    bar.tracker = CostTracker(  # learns each scene's cost (study.cost)
        {
            p.spec.name: (p.missing_points(work), p.est_seconds / max(1, p.spec.n_points))
            for p in plans
        }
    )
    bar.eta_seconds = bar.tracker.eta
    in_process = local_threads(plans, work, default_workers()) if local and workers is None else 0
    if local:
        # before the local workers start: they load what the scenes need from cache
        compile_once(stream, kernels_for(plans, work))
    quiet = quiet_dask_logs() if client is None else nullcontext()
    kw = {
        "scheduler_timeout": scheduler_timeout,
        "worker_timeout": worker_timeout,
        "in_process": in_process,
    }
    with quiet, connect(client, scheduler, scheduler_file, workers, stream, **kw) as c:
        bar.start()
        t1 = time.perf_counter()
        if in_process:  # the result's modules, imported while the threads compute
            threading.Thread(target=_import_writer, name="study-import", daemon=True).start()
        dog = Watchdog(
            c,
            worker_timeout,
            local=local,
            where=str(work.path),
            stream=stream,
            scheduler_timeout=scheduler_timeout,
        )
        drive(c, plans, work, bar, retries, done, watchdog=dog)
        wall = time.perf_counter() - t1
    bar.close()
    return done.compute_seconds, wall


def _import_writer() -> None:
    """Import what assembling the result needs (xarray, netCDF4, and dask.array, which
    xarray imports at its first variable when dask is installed: about a second)
    while a study computes in threads of this process, instead of after it. None of
    these is imported by the client's thread meanwhile."""
    with suppress(Exception):  # the imports where they are used report any error
        import numpy as np
        import xarray as xr

        import study.netcdf  # noqa: F401

        xr.Variable("x", np.zeros(1))  # xarray's look for dask arrays imports dask


def _assemble(study: Study, plans: list[ScenePlan], work, output, command: str | None):
    """The result: written atomically to ``output``, or in memory without one."""
    from study.netcdf import result_tree, write_result

    if output is None:
        return result_tree(study, plans, work)
    return write_result(study, plans, work, Path(output), command)


def _interrupted(work, output, done: Driven, survey: Survey | None) -> str:
    """The line of an interrupted run: what is kept where, and what the output still is."""
    older = older_result_note(output) if output is not None else "nothing was written"
    kept = (survey.reused if survey else 0) + done.saved
    if output is None or not kept:  # the work folder is removed: never name it
        return f"interrupted: no chunk was saved yet; {older}"
    of = f" of {survey.units:,}" if survey.fixed else ""  # adaptive units are not known ahead
    return (
        f"interrupted: {kept:,}{of} chunks are saved in {work.path}; "
        f"{older}; rerun the same command to resume"
    )


def _keep(plans: list[ScenePlan], work) -> None:
    """Save what a plan holds in memory only (an adaptive scene's last plane,
    ``keep``) when the run stops before its result file is written; its point lists
    are saved, so a failure here loses no simulated point."""
    for p in plans:
        keep = getattr(p, "keep", None)
        if keep is not None:
            with suppress(BaseException):  # the run's own exception is the one to report
                keep(work)


def _release(work, finished: bool) -> None:
    """Remove the work folder when done or empty; else keep it for a rerun."""
    if finished or not work.count():
        work.remove()  # done, or nothing worth keeping
    else:
        work.unlock()
