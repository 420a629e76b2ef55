"""A run never waits silently: the client's wait for results is watched.

:func:`watched_batches` replaces ``as_completed.batches()`` in the client's
loop (:func:`study.run._compute`). While no result is ready it looks, once a
second, at the cluster through :class:`Watchdog`:

* the scheduler: a client that is no longer connected for
  :data:`SCHEDULER_GRACE` seconds (the scheduler was killed, the network is
  gone) stops the run: "lost the scheduler ...";
* the workers: no worker connected for ``worker_timeout`` seconds (CLI
  ``--worker-timeout``, default :data:`DEFAULT_WORKER_TIMEOUT`) stops the run:
  "no worker for ... s". On a local cluster this happens when the worker
  processes died and their managers (nannies) gave up restarting them; the
  message says so.

Either ends in :class:`~study.errors.StudyFailed` (one line, exit 1); every
finished chunk is already saved in the work folder, so a rerun resumes.
:func:`quiet_dask_logs` keeps Dask's own error logs (the tracebacks of a lost
connection, ``CommClosedError``, of a cluster start interrupted by Ctrl-C) off
the terminal while this process owns the cluster or its connection: the run
reports what happened in one line.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TextIO

from study.errors import StudyFailed

#: Default of ``--worker-timeout``: seconds without any worker before a run stops.
DEFAULT_WORKER_TIMEOUT = 300.0
#: Seconds the client may stay disconnected from its scheduler before the run stops.
SCHEDULER_GRACE = 20.0
#: Seconds between two looks at the cluster.
LOOK_INTERVAL = 1.0


#: Loggers silenced by :func:`quiet_dask_logs`.
DASK_LOGGERS = ("distributed", "tornado", "asyncio")


@contextmanager
def quiet_dask_logs(level: int = logging.CRITICAL) -> Iterator[None]:
    """Raise the level of Dask's (and its event loop's) loggers to ``level`` for a while."""
    previous = {}
    for name in DASK_LOGGERS:
        previous[name] = logging.getLogger(name).level
        logging.getLogger(name).setLevel(level)
    children = [
        logging.getLogger(name)
        for name in list(logging.root.manager.loggerDict)
        if name.startswith("distributed.")
    ]
    previous_children = {lg.name: lg.level for lg in children}
    for lg in children:
        lg.setLevel(level)
    try:
        yield
    finally:
        for name, lvl in {**previous, **previous_children}.items():
            logging.getLogger(name).setLevel(lvl)


class Watchdog:
    """Raises :class:`StudyFailed` when the scheduler is lost or no worker is left for long.

    Parameters
    ----------
    client : distributed.Client
    worker_timeout : float
        Seconds without any connected worker before the run stops.
    local : bool
        The cluster is the LocalCluster this run started (changes the message).
    where : str
        Where finished chunks are kept (for the message).
    """

    def __init__(
        self,
        client,
        worker_timeout: float = DEFAULT_WORKER_TIMEOUT,
        *,
        local: bool = False,
        where: str = "the work folder",
        stream: TextIO | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.client = client
        self.worker_timeout = float(worker_timeout)
        self.local = local
        self.where = where
        self.stream = stream
        self.clock = clock
        self._next_look = 0.0
        self._lost_since: float | None = None
        self._idle_since: float | None = None
        self._announced = False

    def _fail(self, why: str) -> StudyFailed:
        return StudyFailed(f"{why}; finished chunks are kept in {self.where}, rerun to resume")

    def n_workers(self) -> int | None:
        """Workers connected to the scheduler, or None when it cannot be asked."""
        if self.client.status != "running":
            return None
        try:
            info = self.client.scheduler_info(n_workers=0)
        except Exception:  # noqa: BLE001 - any failure to ask means: not reachable now
            return None
        n = info.get("n_workers")
        return len(info.get("workers", {})) if n is None else int(n)

    def check(self) -> None:
        """Look at the cluster (at most once per :data:`LOOK_INTERVAL`); raise if it is lost."""
        now = self.clock()
        if now < self._next_look:
            return
        self._next_look = now + LOOK_INTERVAL
        n = self.n_workers()
        if n is None:
            self._lost_since = self._lost_since if self._lost_since is not None else now
            if now - self._lost_since >= SCHEDULER_GRACE:
                address = getattr(getattr(self.client, "scheduler", None), "address", "?")
                raise self._fail(
                    f"lost the scheduler {address}: no connection for "
                    f"{now - self._lost_since:.0f} s (killed, or the network is down)"
                )
            return
        self._lost_since = None
        if n > 0:
            self._idle_since = None
            return
        if self._idle_since is None:
            self._idle_since = now
            if self.stream is not None and not self._announced:  # once per run
                self._announced = True
                tty = bool(getattr(self.stream, "isatty", lambda: False)())
                print(
                    ("\n" if tty else "")  # below the progress line
                    + f"study: no worker is connected; waiting up to {self.worker_timeout:g} s "
                    "(--worker-timeout)",
                    file=self.stream,
                    flush=True,
                )
        if now - self._idle_since >= self.worker_timeout:
            why = (
                "the local cluster lost every worker process and did not restart them"
                if self.local
                else "no worker connected to the scheduler"
            )
            raise self._fail(f"{why} for {now - self._idle_since:.0f} s (--worker-timeout)")


def watched_batches(futures, watchdog: Watchdog | None, poll: float = 0.1) -> Iterator[list]:
    """``futures.batches()`` of a ``distributed.as_completed``, watched while waiting."""
    if watchdog is None:
        yield from futures.batches()
        return
    condition = getattr(futures, "thread_condition", None)
    while True:
        if futures.has_ready():
            yield futures.next_batch(block=False)
            continue
        if futures.is_empty():
            return
        watchdog.check()
        if condition is not None:
            with condition:
                condition.wait(timeout=poll)
        else:
            time.sleep(poll)


def watched_gather(client, futures: list, watchdog: Watchdog | None, poll: float = 0.2) -> list:
    """``client.gather(futures)``, watched: a result held by a worker that died before it
    was fetched waits for a recomputation, which never comes if no worker is left."""
    if watchdog is None:
        return client.gather(futures)
    box: dict[str, object] = {}
    done = threading.Event()

    def fetch() -> None:
        try:
            box["value"] = client.gather(futures)
        except BaseException as exc:  # noqa: BLE001 - handed to the waiting thread
            box["error"] = exc
        finally:
            done.set()

    threading.Thread(target=fetch, name="study-gather", daemon=True).start()
    while not done.wait(poll):
        watchdog.check()
    if "error" in box:
        raise box["error"]
    return box["value"]


def _start(factory: Callable[[], object]) -> object:
    """``factory()``; a cluster that fails to start is one line (``StudyFailed``)."""
    try:
        with quiet_dask_logs():
            return factory()
    except Exception as exc:  # noqa: BLE001 - e.g. a worker process killed while starting
        text = str(exc).splitlines()[0] if str(exc) else ""
        raise StudyFailed(
            f"the local cluster did not start: {type(exc).__name__}: {text}; "
            "nothing was computed, rerun to try again"
        ) from None


def start_deferring_sigint(factory: Callable[[], object]) -> object:
    """Run ``factory()`` (start a LocalCluster) with Ctrl-C held back until it returns.

    SIGINT is blocked in this thread while the cluster starts; the threads and the
    worker processes started meanwhile inherit the block, so a Ctrl-C in the
    terminal can neither kill a worker process half-way through its start (Dask's
    tracebacks) nor reach the workers later (the client stops them). The Ctrl-C
    is delivered when the start is over: the cluster is closed and
    ``KeyboardInterrupt`` raised, which the run reports in one line.
    """
    import signal

    if threading.current_thread() is not threading.main_thread() or not hasattr(
        signal, "pthread_sigmask"
    ):
        return _start(factory)
    try:  # start it first: starting it later would unblock SIGINT in the spawning thread
        from multiprocessing import resource_tracker

        resource_tracker.ensure_running()
    except (ImportError, OSError):
        pass
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        cluster = _start(factory)
    except BaseException:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)
        raise
    try:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)  # a held-back Ctrl-C arrives here
        time.sleep(0)  # let its handler run inside this try
    except KeyboardInterrupt:
        with quiet_dask_logs():
            cluster.close()
        raise
    return cluster
