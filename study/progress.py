"""Progress display on the client (stderr): points done, rate, ETA. No tqdm.

Driven by the client's ``as_completed`` loop (points whose results reached the
client and were saved), so it works the same for a local cluster and a remote
scheduler and never counts a point that could still be lost. Updates are
throttled: at most every 0.5 s on a terminal (redrawn in place), every 10 s
otherwise (one line each, for logs).

The rate and ETA are measured from the first finished chunk on, so worker
start-up, loading (or, on a remote cluster, compiling) the simulator and
the first chunk's latency never count as computing: until a second batch of
points has arrived the ETA is ``?``.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    h, rest = divmod(seconds, 3600)
    m, s = divmod(rest, 60)
    return f"{h:d}:{m:02d}:{s:02d}"


class Progress:
    """Throttled progress line for ``total`` points, ``done`` of them already on disk."""

    def __init__(
        self,
        total: int,
        done: int = 0,
        stream: TextIO | None = None,
        interval: float | None = None,
        enabled: bool = True,
    ) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.interval = interval if interval is not None else (0.5 if self.tty else 10.0)
        self.total = total
        self.done = done
        self.new = 0
        self.enabled = enabled
        self.t0 = time.monotonic()
        self.last = self.t0
        #: Time and points of the first update (the rate is measured from there)
        #: and time of the latest (so cluster shutdown never lowers the final rate).
        self.first: tuple[float, int] | None = None
        self.latest = self.t0
        #: Seconds left as learnt by a :class:`study.cost.CostTracker` (None: from the rate).
        self.eta_seconds = None
        #: Points done at the last line shown (the final line is not repeated).
        self.shown = -1

    def start(self) -> None:
        """Start the clock now (after the cluster is up), so the rate counts computing only."""
        self.t0 = self.last = time.monotonic()
        self.first = None
        tracker = getattr(self, "tracker", None)
        if tracker is not None:
            tracker.t0 = tracker.clock()

    def rate(self) -> float:
        """Points per second from the first to the last finished chunk (0 while unknown)."""
        if self.first is None:
            return 0.0
        t1, n1 = self.first
        seconds = self.latest - t1
        return (self.new - n1) / seconds if seconds > 0 and self.new > n1 else 0.0

    def update(self, n: int) -> None:
        self.done += n
        self.new += n
        now = self.latest = time.monotonic()
        if self.first is None:
            self.first = (now, self.new)
        if self.enabled and now - self.last >= self.interval:
            self.last = now
            self._emit(self.line(now), final=False)

    def line(self, now: float | None = None) -> str:
        now = now or time.monotonic()
        elapsed = max(now - self.t0, 1e-9)
        steady = self.rate()
        rate = steady or self.new / elapsed
        pct = 100.0 * self.done / self.total if self.total else 100.0
        learnt = self.eta_seconds() if self.eta_seconds is not None else None
        if learnt is not None:  # per-scene costs learnt from finished tasks (study.cost)
            eta = _clock(learnt)
        else:
            eta = _clock((self.total - self.done) / steady) if steady > 0 else "?"
        return (
            f"{self.done:,}/{self.total:,} points ({pct:5.1f}%) | {rate:,.0f} points/s | "
            f"elapsed {_clock(elapsed)} | ETA {eta}"
        )

    def close(self) -> None:
        """The final line (on a log, not again if the last line shown said the same)."""
        if self.enabled and (self.tty or self.shown != self.done):
            self._emit(self.line(), final=True)

    def _emit(self, text: str, final: bool) -> None:
        self.shown = self.done
        if self.tty:
            self.stream.write("\r\x1b[K" + text + ("\n" if final else ""))
        else:
            self.stream.write(text + "\n")
        self.stream.flush()
