"""A run never waits silently: the client's wait for results is watched.

:func:`watched_batches` replaces ``as_completed.batches()`` in the client's
loop (:func:`study.run._compute`). While no result is ready it looks, once a
second, at the cluster through :class:`Watchdog`, asking the scheduler for its
workers with a bounded wait (:data:`ASK_TIMEOUT`):

* the scheduler: a client that is no longer connected, or a scheduler that does
  not answer (stopped with SIGSTOP, hung, unreachable), for ``scheduler_timeout``
  seconds (CLI ``--scheduler-timeout``, default
  :data:`study.connect.DEFAULT_SCHEDULER_TIMEOUT`, 30 s) stops the run: "lost the
  scheduler ..." or "the scheduler ... did not answer for ... s";
* the workers: no live worker for ``worker_timeout`` seconds (CLI
  ``--worker-timeout``, default :data:`DEFAULT_WORKER_TIMEOUT`, 300 s) stops the
  run. A worker is live while its heartbeat to the scheduler moves on
  (``last_seen`` changes between two looks): none connected, or every one
  stopped (SIGSTOP), hung or cut off, counts as none. On a local cluster no
  worker is left when the worker processes died and their managers (nannies)
  gave up restarting them; the message says so.

Either ends in :class:`~study.errors.StudyFailed` (one line, exit 1) about
one second after its timeout (a look never waits past the scheduler timeout);
the run then cancels its tasks and closes the connection, each bounded
(:data:`ASK_TIMEOUT`, twice the scheduler timeout); every finished chunk is
already saved in the work folder, so a rerun resumes. A worker runs one numba
call of a chunk with the GIL held, which can delay its heartbeat: keep
``--worker-timeout`` well above the longest single call (the default is ample).
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

from study.connect import DEFAULT_SCHEDULER_TIMEOUT
from study.errors import StudyFailed

#: Default of ``--worker-timeout``: seconds without any live worker before a run stops.
DEFAULT_WORKER_TIMEOUT = 300.0
#: Former name of the default scheduler timeout (seconds without the scheduler).
SCHEDULER_GRACE = DEFAULT_SCHEDULER_TIMEOUT
#: Longest wait, in seconds, for one answer of the scheduler to the watchdog.
ASK_TIMEOUT = 5.0
#: Seconds every worker may stay silent before the run says it is waiting.
SILENCE_NOTICE = 10.0
#: Seconds between two looks at the cluster.
LOOK_INTERVAL = 1.0


#: Loggers silenced by :func:`quiet_dask_logs`.
DASK_LOGGERS = ("distributed", "tornado", "asyncio")


@contextmanager
def quiet_dask_logs(level: int = logging.CRITICAL) -> Iterator[None]:
    """Raise the level of Dask's (and its event loop's) loggers to ``level`` for a while.

    ``distributed`` is imported first: its import configures its loggers (level
    ``info`` for ``distributed``, a handler on stderr), which would undo a level
    raised before it.
    """
    import distributed  # noqa: F401  (every run that quiets the logs connects through it)

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
        scheduler_timeout: float = DEFAULT_SCHEDULER_TIMEOUT,
    ) -> None:
        self.client = client
        self.worker_timeout = float(worker_timeout)
        self.scheduler_timeout = float(scheduler_timeout)
        self.local = local
        self.where = where
        self.stream = stream
        self.clock = clock
        self._next_look = 0.0
        self._lost_since: float | None = None  # start of the first look without an answer
        self._idle_since: float | None = None
        self._alive_at: float | None = None
        self._beats: dict[str, object] = {}
        self._last_info: object = None
        self._asking: _Ask | None = None
        self._announced = False

    def _fail(self, why: str) -> StudyFailed:
        return StudyFailed(f"{why}; finished chunks are kept in {self.where}, rerun to resume")

    def _say(self, text: str) -> None:
        """One line on the stream, once per run (below a progress line on a terminal)."""
        if self.stream is None or self._announced:
            return
        self._announced = True
        tty = bool(getattr(self.stream, "isatty", lambda: False)())
        print(("\n" if tty else "") + f"study: {text}", file=self.stream, flush=True)

    def ask(self, wait: float = ASK_TIMEOUT) -> dict | None:
        """The scheduler's fresh answer (its identity, every worker), or None.

        None when the client is not connected, or the scheduler has not answered
        within ``wait`` seconds (the question stays pending: the next look waits
        for the same answer, never a second thread).
        """
        if self.client.status != "running":
            return None
        if self._asking is None or self._asking.done.is_set():
            self._asking = _Ask(self.client)
        info = self._asking.result(wait)
        if info is None or info is self._last_info:  # distributed keeps a stale copy
            return None
        self._last_info = info
        return info

    def n_workers(self) -> int | None:
        """Workers connected to the scheduler, or None when it does not answer."""
        info = self.ask()
        return None if info is None else _count(info)

    def _moved(self, info: dict) -> bool:
        """Whether any worker's heartbeat moved on since the last look (or cannot be told)."""
        workers = info.get("workers") or {}
        beats = {a: w.get("last_seen") if isinstance(w, dict) else None for a, w in workers.items()}
        moved = len(beats) < _count(info) or any(
            seen is None or a not in self._beats or self._beats[a] != seen
            for a, seen in beats.items()
        )
        self._beats = beats
        return moved

    def check(self) -> None:
        """Look at the cluster (at most once per :data:`LOOK_INTERVAL`); raise if it is lost."""
        now = self.clock()
        if now < self._next_look:
            return
        self._next_look = now + LOOK_INTERVAL
        start = now
        left = self.scheduler_timeout
        if self._lost_since is not None:  # never wait past the scheduler timeout
            left -= now - self._lost_since
        info = self.ask(min(ASK_TIMEOUT, max(0.05, left)))
        now = max(now, self.clock())
        address = getattr(getattr(self.client, "scheduler", None), "address", "?")
        if info is None:
            self._lost_since = self._lost_since if self._lost_since is not None else start
            silent = now - self._lost_since
            if silent >= self.scheduler_timeout:
                if self.client.status != "running":
                    why = f"lost the scheduler {address}: no connection for {silent:.0f} s "
                    why += "(killed, or the network is down)"
                else:
                    why = f"the scheduler {address} did not answer for {silent:.0f} s "
                    why += "(stopped, hung or overloaded; --scheduler-timeout)"
                raise self._fail(why)
            return
        self._lost_since = None
        n = _count(info)
        if n > 0:
            self._idle_since = None
            if self._moved(info) or self._alive_at is None:
                self._alive_at = now
            silent = now - self._alive_at
            if silent >= min(SILENCE_NOTICE, self.worker_timeout / 2):
                self._say(
                    f"no worker has answered for {silent:.0f} s; waiting up to "
                    f"{self.worker_timeout:g} s (--worker-timeout)"
                )
            if silent >= self.worker_timeout:
                raise self._fail(
                    f"every worker ({n}) stopped answering: no heartbeat for {silent:.0f} s "
                    "(stopped, hung or cut off; --worker-timeout)"
                )
            return
        self._beats = {}
        if self._idle_since is None:
            self._idle_since = now
            self._say(
                f"no worker is connected; waiting up to {self.worker_timeout:g} s "
                "(--worker-timeout)"
            )
        if now - self._idle_since >= self.worker_timeout:
            why = (
                "the local cluster lost every worker process and did not restart them"
                if self.local
                else "no worker connected to the scheduler"
            )
            raise self._fail(f"{why} for {now - self._idle_since:.0f} s (--worker-timeout)")


def _count(info: dict) -> int:
    n = info.get("n_workers")
    return len(info.get("workers") or {}) if n is None else int(n)


class _Ask:
    """One question to the scheduler (``scheduler_info`` of every worker) in a daemon thread."""

    def __init__(self, client) -> None:
        self.done = threading.Event()
        self.answer: dict | None = None
        threading.Thread(target=self._run, args=(client,), name="study-watch", daemon=True).start()

    def _run(self, client) -> None:
        try:
            self.answer = client.scheduler_info(n_workers=-1)
        except Exception:  # noqa: BLE001 - any failure to ask means: no answer now
            self.answer = None
        finally:
            self.done.set()

    def result(self, timeout: float) -> dict | None:
        return self.answer if self.done.wait(timeout) else None


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
            with condition:  # asked under the lock the notice is sent under: none is missed
                if not futures.has_ready():
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
