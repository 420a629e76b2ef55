"""How an adaptive plane hands out its ready points (study.adaptive) and how the client
waits for results (study.watchdog.watched_batches): equal point lists, short lists
computed by the client while a worker thread is free, no missed wake-up."""

from __future__ import annotations

import threading
import time
from types import SimpleNamespace

import numpy as np
import pytest

from study import Study
from study.adaptive import LOCAL_POINTS, LOCAL_POINTS_IDLE, MIN_LIST, PARTIAL_BELOW
from study.chunks import plan
from study.watchdog import watched_batches

STUDY = """
[study]
name = "lists"
fidelity = "fast"

[[scene]]
name = "s"
contact = "ground"
dof = 2
mode = "adaptive"
r = {start = 0.1, stop = 2.4, num = 400}
beta = {start = 0.0, stop = 1.5, num = 200}
"""


def _plan(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(STUDY, encoding="utf-8")
    return plan(Study.from_toml(path))[0]


def _cut(p, n: int) -> list[int]:
    """The lengths of the lists ``n`` ready points are handed out as (while few lists are
    in flight, as ``AdaptivePlan._next_of`` hands them out)."""
    pl = SimpleNamespace(todo=np.arange(n), cut=0)
    sizes = []
    while pl.todo.size:
        size = p._list_size(pl)
        sizes.append(min(size, pl.todo.size))
        pl.todo = pl.todo[size:]
    return sizes


@pytest.mark.parametrize("n", [2016, 1000, 700, 300, 5000])
def test_ready_points_are_cut_into_equal_lists(tmp_path, n):
    p = _plan(tmp_path)
    target = p.block[0]
    sizes = _cut(p, n)
    assert sum(sizes) == n
    assert max(sizes) <= max(target, MIN_LIST)
    body = sizes[:-1] or sizes
    assert max(body) - min(body) <= 1 and sizes[-1] <= sizes[0]  # equal but the remainder
    # enough lists for PARTIAL_BELOW in flight, as long as each keeps MIN_LIST points
    assert len(sizes) >= min(PARTIAL_BELOW, -(-n // MIN_LIST))
    if n >= PARTIAL_BELOW * MIN_LIST:  # no short remainder left over for a later round
        assert sizes[-1] > sizes[0] // 2


def _here(p, n_points: int, others: int, threads: int, seconds_per_point: float) -> bool:
    pl = SimpleNamespace(
        outstanding=set(range(others + 1)), cost=[seconds_per_point * 1000, 1000], here=0
    )
    p._active = {(): pl}
    p._here = True  # the simulator counts as cached (numba_cache.is_compiled)
    p.worker_threads = threads
    return p.compute_here(SimpleNamespace(n_points=n_points, sweep=()))


def test_the_client_computes_short_lists_while_a_worker_thread_is_free(tmp_path):
    p = _plan(tmp_path)
    cheap = 1e-4  # seconds per point: 64 points cost 6.4 ms, less than a round trip
    assert _here(p, LOCAL_POINTS, others=5, threads=2, seconds_per_point=cheap)  # always
    assert _here(p, LOCAL_POINTS_IDLE, others=1, threads=2, seconds_per_point=cheap)
    assert not _here(p, LOCAL_POINTS_IDLE, others=2, threads=2, seconds_per_point=cheap)
    assert not _here(p, LOCAL_POINTS_IDLE + 1, others=0, threads=2, seconds_per_point=cheap)
    # costly points: only as many as a round trip's worth (and never fewer than LOCAL_POINTS)
    assert not _here(p, 40, others=0, threads=2, seconds_per_point=1e-3)
    assert _here(p, LOCAL_POINTS, others=0, threads=2, seconds_per_point=1e-3)
    p.local_points = 0  # none at all
    assert not _here(p, 1, others=0, threads=2, seconds_per_point=cheap)


class _Futures:
    """An ``as_completed`` whose result arrives (and is notified) right after the loop's
    first look finds none: between that look and the wait."""

    def __init__(self) -> None:
        self.thread_condition = threading.Condition()
        self.ready = False
        self.looks = 0

    def has_ready(self) -> bool:
        self.looks += 1
        ready = self.ready
        if self.looks == 1:  # the first look: nothing yet, and then the result comes
            threading.Thread(target=self._arrive).start()
            time.sleep(0.2)  # it has arrived and notified before the loop waits
        return ready

    def _arrive(self) -> None:
        with self.thread_condition:
            self.ready = True
            self.thread_condition.notify_all()

    def is_empty(self) -> bool:
        return False

    def next_batch(self, block: bool = False) -> list:
        self.ready = False
        return ["result"]


def test_a_result_arriving_before_the_wait_is_not_missed():
    watchdog = SimpleNamespace(check=lambda: None)
    t0 = time.monotonic()
    batch = next(watched_batches(_Futures(), watchdog, poll=30.0))
    assert batch == ["result"]
    assert time.monotonic() - t0 < 10.0  # not the 30 s of a missed notice
