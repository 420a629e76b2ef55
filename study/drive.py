"""Driving plans on Dask: one loop for every scene kind.

Every plan (:mod:`study.chunks`) hands out its units of work through
:meth:`~study.chunks.ScenePlan.next_unit`. The client keeps at most a window of
units in flight (a few per worker thread, resized as workers come and go),
refilled from ``as_completed``, so neither the client nor the scheduler ever
holds the whole study. Workers return numpy arrays and never write files; the
client queues each result for saving in the work folder (:mod:`study.saving`: a
background writer, atomic files of :mod:`study.store`), once, with what its unit
adds (``saved_with``: the indices of an adaptive point list), and hands it to its
plan (:meth:`~study.chunks.ScenePlan.accept`), which may then have more units to
give (new points of an adaptive plane). Whatever stops the loop (Ctrl-C, a
failed unit), every arrived result is written before the run ends. A
killed worker costs only the tasks it was running or holding, which the
scheduler reruns elsewhere; tasks that raise are retried (``retries``).
"""

from __future__ import annotations

import time
from concurrent.futures import CancelledError
from contextlib import suppress
from dataclasses import dataclass

from study.compute import TRANSIENT, compute_chunk
from study.connect import call_within
from study.errors import StudyFailed
from study.plans import WAIT, ScenePlan
from study.progress import Progress
from study.saving import Saver
from study.store import WorkDir
from study.watchdog import ASK_TIMEOUT, Watchdog, watched_batches, watched_gather

#: Units kept in flight per worker thread (at least ``MIN_WINDOW`` in all).
WINDOW_PER_THREAD = 4
MIN_WINDOW = 16
#: Seconds between two looks at the number of worker threads (window size).
WINDOW_REFRESH = 5.0
#: Largest planned compute, in CPU seconds per core, done by threads of the client's
#: process instead of worker processes (a minute of wall time: beyond it the start-up
#: of the processes, :data:`study.cost.STARTUP_SECONDS`, is small, and a crash of one
#: worker costs one worker, not the run).
IN_PROCESS_SECONDS = 60.0


def local_threads(plans: list[ScenePlan], work, cores: int) -> int:
    """Threads of the client's process that compute the missing work of ``plans`` on
    this machine, or 0 when worker processes pay (one per core, :func:`study.run.connect`).

    The single-contact simulator releases the GIL (``tasks.kernel.run_points``,
    ``orbit_designs``), so ``cores`` threads compute as fast as ``cores`` processes
    without their start-up: threads while the planned compute is at most
    :data:`IN_PROCESS_SECONDS` per core. The several-contact simulator holds the
    GIL: one thread, and only while the processes' start-up would cost more than
    they save.
    """
    from study import contacts
    from study.cost import STARTUP_SECONDS

    cpu = sum(p.est_seconds * p.missing_points(work) / max(1, p.spec.n_points) for p in plans)
    if cores <= 1:
        return 1
    if any(contacts.is_multi(p.spec.structure) for p in plans):  # holds the GIL
        return 1 if cpu * (1 - 1 / cores) < STARTUP_SECONDS else 0
    return cores if cpu / cores <= IN_PROCESS_SECONDS else 0


@dataclass
class Driven:
    """What :func:`drive` did: units saved and their compute seconds."""

    saved: int = 0
    compute_seconds: float = 0.0
    here: int = 0  #: units computed in the client's thread (:meth:`_Window.here`)


def _failure(unit, exc: BaseException, retries: int, where: str) -> StudyFailed:
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
        f"chunk {unit.key} of scene {unit.scene} {why}; "
        f"finished chunks are kept in {where}, rerun to resume"
    )
    return StudyFailed(" ".join(msg.split()))


class _Window:
    """Units in flight, the plans still handing out units, and the progress."""

    def __init__(self, client, plans, work, bar: Progress, retries: int, done: Driven):
        from distributed import as_completed

        self.client, self.work, self.bar, self.retries, self.done = (
            client,
            work,
            bar,
            retries,
            done,
        )
        self.active = list(plans)
        self.plans = list(plans)
        self.inflight: dict[str, tuple[object, ScenePlan, object]] = {}
        self.futures = as_completed()
        self.size = MIN_WINDOW
        self.next_look = 0.0
        self.shown = sum(p.finished_points for p in plans)
        self.again: set[str] = set()  # units submitted a second time after a cancel
        self.saver = Saver(work, done, background=isinstance(work, WorkDir))

    def _resize(self) -> None:
        now = time.monotonic()
        if now < self.next_look:  # workers come and go (adaptive clusters, lost workers)
            return
        try:
            threads = sum(call_within(ASK_TIMEOUT, self.client.nthreads).values())
        except (OSError, TimeoutError):  # unreachable or silent: the watchdog decides
            threads = 0
        self.size = max(MIN_WINDOW, WINDOW_PER_THREAD * threads)
        self.next_look = now + WINDOW_REFRESH
        for p in self.plans:
            p.worker_threads = threads

    def fill(self) -> None:
        """Submit units until the window is full or every plan waits or is done. The
        worker threads are looked at after the units are submitted (a round trip: they
        compute meanwhile), and the window filled again if it grew (a first look); first
        when a plan cuts its first units by them (adaptive tiles, :mod:`study.tiles`)."""
        if not self.next_look and any(getattr(p, "tiles", False) is True for p in self.active):
            self._resize()
        while True:
            size = self.size
            batch: list[tuple[ScenePlan, object]] = []
            for p in list(self.active):
                while len(self.inflight) + len(batch) < self.size:
                    unit = p.next_unit(self.work)
                    if unit is None:
                        self.active.remove(p)
                        break
                    if unit is WAIT:
                        break
                    if not self.here(p, unit):
                        batch.append((p, unit))
            self.progress()
            self.submit(batch)
            self._resize()
            if self.size <= size or not self.active:
                return

    def here(self, p: ScenePlan, unit) -> bool:
        """Compute a unit the plan says is cheaper here than a round trip through the
        cluster (``compute_here``: a few points of an adaptive plane, which its
        refinement waits for); True once its result is handed over. A unit that raises
        here goes to the cluster (its retries, its one-line failure)."""
        ask = getattr(p, "compute_here", None)
        if ask is None or not ask(unit):
            return False
        try:
            arrays = compute_chunk(p.task(unit))
        except Exception:  # noqa: BLE001 - the cluster computes it, and reports
            return False
        self.done.here += 1
        self.take(p, unit, arrays)
        return True

    def submit(self, batch: list[tuple[ScenePlan, object]], suffix: str = "") -> None:
        if not batch:
            return
        new = self.client.map(
            compute_chunk,
            [p.task(u) for p, u in batch],
            key=[f"study-{u.key}{suffix}" for _, u in batch],
            retries=self.retries,
            pure=False,
        )
        for fut, (p, u) in zip(new, batch, strict=True):
            self.inflight[fut.key] = (fut, p, u)
        self.futures.update(new)

    def progress(self) -> None:
        total = sum(p.finished_points for p in self.plans)
        if total > self.shown:
            self.bar.update(total - self.shown)
            self.shown = total

    def arrived(self, fut, arrays) -> None:
        """Queue one result for saving (:mod:`study.saving`), hand it to its plan, count it."""
        _, p, unit = self.inflight.pop(fut.key)
        fut.release()
        self.take(p, unit, arrays)

    def take(self, p: ScenePlan, unit, arrays) -> None:
        """Queue a unit's result for saving, hand it to its plan, count it."""
        extra = getattr(unit, "saved_with", None)  # e.g. an adaptive point list's indices
        saved = {k: v for k, v in arrays.items() if k not in TRANSIENT}  # for the plan only
        self.saver.put(p, unit, saved if extra is None else saved | extra)
        seconds = float(arrays["seconds"])
        self.done.compute_seconds += seconds
        before = p.finished_points
        p.accept(unit, arrays, self.work)
        tracker = getattr(self.bar, "tracker", None)
        if tracker is not None:
            tracker.record(unit.scene, p.finished_points - before, seconds)

    def fetch_one(self, fut, watchdog):
        try:
            return watched_gather(self.client, [fut], watchdog)[0]
        except (KeyboardInterrupt, StudyFailed):  # StudyFailed: the watchdog's
            raise
        except BaseException as exc:  # CancelledError is not an Exception
            _, p, unit = self.inflight[fut.key]
            if isinstance(exc, CancelledError) and unit.key not in self.again:
                # a key cancelled by an earlier run on this client can still be
                # cancelling when this run submits it: once more, under another key
                self.again.add(unit.key)
                del self.inflight[fut.key]
                self.submit([(p, unit)], suffix="-again")
                return None
            raise _failure(unit, exc, self.retries, str(self.work.path)) from None


def drive(
    client,
    plans: list[ScenePlan],
    work,
    bar: Progress,
    retries: int,
    done: Driven,
    watchdog: Watchdog | None = None,
) -> Driven:
    """Compute every missing unit of ``plans`` (after their ``prepare``), saving each.

    ``done`` is updated as results are saved (so an interrupted run can say
    how much it kept).
    """
    win = _Window(client, plans, work, bar, retries, done)
    try:
        _drive(win, client, watchdog)
    except BaseException:  # every arrived result is written, whatever stopped the loop;
        with suppress(Exception):  # the loop's own exception is the one to report
            win.saver.close()
        raise
    win.saver.close()
    if win.inflight or win.active:  # as_completed ended with work unaccounted for
        p = (win.active or [None])[0]
        unit = next(iter(win.inflight.values()))[2] if win.inflight else None
        what = f"chunk {unit.key}" if unit else "a unit"
        raise StudyFailed(f"{what} of scene {unit.scene if unit else p.spec.name} never completed")
    return done


def _drive(win: _Window, client, watchdog: Watchdog | None) -> None:
    """The loop: submit, wait for a batch of results, hand them over, submit more."""
    try:
        win.fill()
        for batch in watched_batches(win.futures, watchdog):
            try:  # one round trip for the whole batch
                results = watched_gather(client, batch, watchdog)
            except KeyboardInterrupt:
                raise
            except BaseException:  # one of them failed: fetch one by one to name it
                results = [win.fetch_one(fut, watchdog) for fut in batch]
            for fut, arrays in zip(batch, results, strict=True):
                if arrays is not None:  # None: submitted again (_Window.fetch_one)
                    win.arrived(fut, arrays)
            win.fill()
    except BaseException:
        # bounded: the scheduler may be the one that went silent, or the client closed
        with suppress(TimeoutError, Exception):
            call_within(ASK_TIMEOUT, client.cancel, [f for f, _, _ in win.inflight.values()])
        raise
