"""Running a study on Dask: submit chunks, persist results as they finish, assemble.

The client submits at most a window of chunks at a time (a few per worker
thread) and refills it from ``as_completed``, so neither the client nor the
scheduler ever holds the whole study. Workers return numpy arrays; the client
writes each finished chunk atomically into the work folder (``OUT.nc.work/``)
before asking for more. A rerun skips every chunk already on disk (resume); a
killed worker costs only its running tasks, which the scheduler reruns; tasks
that raise are retried (``retries``). After the last chunk the result file is
assembled (:mod:`study.netcdf`) and the work folder removed.
"""

from __future__ import annotations

import logging
import os
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from study import trace
from study.chunks import Chunk, ScenePlan, plan
from study.compute import compute_chunk
from study.definition import Study
from study.errors import StudyError, StudyFailed, StudyInterrupted
from study.progress import Progress
from study.store import WorkDir


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


def default_workers() -> int:
    """Cores available to this process."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


@contextmanager
def connect(
    client=None,
    scheduler: str | None = None,
    scheduler_file: str | None = None,
    workers: int | None = None,
    stream: TextIO = sys.stderr,
):
    """A Dask client: the one given, a running scheduler, or a new LocalCluster.

    The LocalCluster has one single-threaded worker process per core (the
    numerics hold the GIL) and listens on 127.0.0.1 only.
    """
    if client is not None:
        yield client
        return
    from distributed import Client, LocalCluster

    cluster = None
    if scheduler or scheduler_file:
        kw = {"address": scheduler} if scheduler else {"scheduler_file": scheduler_file}
        try:
            client = Client(**kw, timeout="30s")
        except (OSError, TimeoutError, ValueError) as exc:
            where = scheduler or scheduler_file
            flag = "--scheduler" if scheduler else "--scheduler-file"
            raise StudyError(flag, f"cannot connect to {where}: {exc}") from None
        if workers:
            client.wait_for_workers(workers)
        print(
            f"study: connected to {client.scheduler.address} "
            f"({len(client.scheduler_info()['workers'])} workers)",
            file=stream,
        )
    else:
        n = workers or default_workers()
        cluster = LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address="127.0.0.1:0",
            silence_logs=logging.ERROR,
        )
        client = Client(cluster)
        print(
            f"study: local cluster with {n} workers, dashboard {client.dashboard_link}", file=stream
        )
    try:
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _check_runnable(study: Study, output: Path) -> None:
    if not output.parent.is_dir():
        raise StudyError("-o", f"output directory does not exist: {output.parent}")
    if output.is_dir():
        raise StudyError("-o", f"output is a directory: {output}")
    for i, s in enumerate(study.scenes):
        if s.mode == "trace" and not trace.available():
            raise StudyError(
                f"scene[{i}].mode",
                "'trace' needs tasks.trace_boundaries, which is not available in this version",
                study.source,
            )


def run_study(
    study: Study,
    output: str | os.PathLike,
    *,
    client=None,
    scheduler: str | None = None,
    scheduler_file: str | None = None,
    workers: int | None = None,
    retries: int = 3,
    progress: bool = True,
    command: str | None = None,
    stream: TextIO | None = None,
) -> RunSummary:
    """Compute every missing chunk of ``study`` and write the result to ``output``.

    Parameters
    ----------
    study : Study
        A validated study.
    output : path
        The netCDF file to write; chunks are kept in ``output + ".work"``.
    client : distributed.Client, optional
        Use this client (it is not closed). Otherwise connect to ``scheduler``
        (an address) or ``scheduler_file``, or start a LocalCluster with
        ``workers`` processes (default: one per core).
    retries : int
        Times a task that raised is retried before the run fails.

    Raises
    ------
    StudyError
        Bad output path or an unavailable feature (nothing is written).
    StudyInterrupted
        Ctrl-C: finished chunks stay in the work folder, no result file.
    StudyFailed
        A chunk failed on every retry.
    """
    stream = stream if stream is not None else sys.stderr
    t0 = time.perf_counter()
    output = Path(output)
    _check_runnable(study, output)
    plans = plan(study)
    work = WorkDir(output)
    n_chunks = reused = reused_points = 0
    for p in plans:
        for c in p.chunks():
            n_chunks += 1
            if work.has(c.scene, c.key):
                reused += 1
                reused_points += c.n_points
    missing = n_chunks - reused
    n_points = study.n_points
    print(
        f"study: {study.name}: {n_points:,} points in {n_chunks:,} chunks; "
        f"reusing {reused:,} chunks from {work.path}, computing {missing:,}",
        file=stream,
    )
    compute_seconds = 0.0
    if missing:
        bar = Progress(n_points, reused_points, stream=stream, enabled=progress)
        with connect(client, scheduler, scheduler_file, workers, stream) as c:
            compute_seconds = _compute(c, plans, work, bar, retries, n_chunks)
        bar.close()
    from study.netcdf import write_result

    write_result(study, plans, work, output, command)
    work.remove()
    wall = time.perf_counter() - t0
    print(
        f"study: wrote {output} ({n_points:,} points; {missing:,} chunks computed, "
        f"{reused:,} reused) in {wall:.1f} s",
        file=stream,
    )
    return RunSummary(output, n_points, n_chunks, reused, missing, wall, compute_seconds)


def _pending(plans: list[ScenePlan], work: WorkDir) -> Iterator[tuple[ScenePlan, dict, Chunk]]:
    for p in plans:
        axes = p.axes()
        for c in p.chunks():
            if not work.has(c.scene, c.key):
                yield p, axes, c


def _compute(client, plans, work: WorkDir, bar: Progress, retries: int, n_chunks: int) -> float:
    """Submit the missing chunks through a sliding window; persist each as it finishes."""
    from distributed import as_completed

    threads = sum(client.nthreads().values()) or 1
    window = max(16, 4 * threads)
    todo = _pending(plans, work)
    meta: dict[str, Chunk] = {}
    futures = as_completed()
    compute_seconds = 0.0

    def submit_next() -> bool:
        item = next(todo, None)
        if item is None:
            return False
        p, axes, chunk = item
        fut = client.submit(
            compute_chunk, p.task(chunk, axes), key=f"study-{chunk.key}", retries=retries
        )
        meta[fut.key] = chunk
        futures.add(fut)
        return True

    try:
        for _ in range(window):
            if not submit_next():
                break
        for fut in futures:
            chunk = meta.pop(fut.key)
            if fut.status != "finished":
                exc = fut.exception()
                raise StudyFailed(
                    f"chunk {chunk.key} of scene {chunk.scene} failed after {retries} retries: "
                    f"{exc!r}; finished chunks are kept in {work.path}, rerun to resume"
                )
            arrays = fut.result()
            fut.release()
            work.save(chunk.scene, chunk.key, arrays)
            compute_seconds += float(arrays["seconds"])
            bar.update(chunk.n_points)
            submit_next()
    except KeyboardInterrupt:
        done = work.count()
        client.cancel(list(futures.futures))
        raise StudyInterrupted(
            f"interrupted: {done:,} of {n_chunks:,} chunks are saved in {work.path}; "
            "rerun the same command to resume"
        ) from None
    return compute_seconds
