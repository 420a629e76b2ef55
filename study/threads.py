"""Computing a small study in threads of this process, without Dask.

A study whose planned compute is short (:func:`study.drive.local_threads`) is
computed by a pool of threads of the client's own process: the single-contact
simulator releases the GIL, so ``n`` threads compute as fast as ``n`` worker
processes, without their start-up, without a scheduler, and without importing
``distributed`` (half a second) or sending each result through a socket.

:class:`ThreadClient` is the part of a ``distributed.Client`` that
:func:`study.drive.drive` uses (``map`` with keys and retries, ``gather``,
``cancel``, ``nthreads``, ``as_completed``), on a
:class:`concurrent.futures.ThreadPoolExecutor`. Nothing can be lost here but the
process itself, so no watchdog looks at it; a task that raises is retried
``retries`` times, as Dask would.
"""

from __future__ import annotations

import queue
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor

#: Seconds between two looks for Ctrl-C while the client waits for a result.
POLL = 0.2


class ThreadFuture:
    """A submitted task: its ``key`` and its :class:`concurrent.futures.Future`."""

    def __init__(self, key: str, future: Future) -> None:
        self.key = key
        self.future = future

    def result(self):
        while True:  # a bounded wait at a time: Ctrl-C reaches the waiting thread
            try:
                return self.future.result(timeout=POLL)
            except TimeoutError:
                continue

    def done(self) -> bool:
        return self.future.done()

    def cancel(self) -> bool:
        return self.future.cancel()

    def release(self) -> None:
        """Nothing to release (Dask's futures free the result on the cluster)."""


class Completed:
    """``distributed.as_completed`` for :class:`ThreadFuture`: futures in the order they
    finish, in batches of every one finished by then."""

    def __init__(self) -> None:
        self._done: queue.SimpleQueue[ThreadFuture] = queue.SimpleQueue()
        self._pending = 0

    def update(self, futures: list[ThreadFuture]) -> None:
        for fut in futures:
            self._pending += 1
            fut.future.add_done_callback(lambda _, fut=fut: self._done.put(fut))

    def batches(self) -> Iterator[list[ThreadFuture]]:
        while self._pending:
            try:
                first = self._done.get(timeout=POLL)  # bounded: Ctrl-C is seen
            except queue.Empty:
                continue
            batch = [first]
            while True:
                try:
                    batch.append(self._done.get_nowait())
                except queue.Empty:
                    break
            self._pending -= len(batch)
            yield batch


class ThreadClient:
    """Tasks on ``n_threads`` threads of this process, with the calls of
    ``distributed.Client`` that :mod:`study.drive` makes."""

    status = "running"

    def __init__(self, n_threads: int) -> None:
        self.n_threads = max(1, int(n_threads))
        self.pool = ThreadPoolExecutor(self.n_threads, thread_name_prefix="study-compute")

    def map(
        self, fn: Callable, tasks: list, key: list[str], retries: int = 0, pure: bool = False
    ) -> list[ThreadFuture]:
        return [
            ThreadFuture(k, self.pool.submit(_with_retries, fn, t, retries))
            for t, k in zip(tasks, key, strict=True)
        ]

    def gather(self, futures: list[ThreadFuture]) -> list:
        return [f.result() for f in futures]

    def cancel(self, futures: list[ThreadFuture]) -> None:
        for f in futures:
            f.cancel()

    def nthreads(self) -> dict[str, int]:
        return {"threads": self.n_threads}

    @staticmethod
    def as_completed() -> Completed:
        return Completed()

    def close(self) -> None:
        """Cancel what has not started; tasks running finish their call (they cannot be
        interrupted inside the simulator), without the client waiting for them."""
        self.pool.shutdown(wait=False, cancel_futures=True)


def _with_retries(fn: Callable, task, retries: int):
    for attempt in range(retries + 1):
        try:
            return fn(task)
        except Exception:
            if attempt == retries:
                raise
    raise AssertionError("unreachable")  # pragma: no cover
