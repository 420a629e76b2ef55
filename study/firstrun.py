"""First run on a machine: compile the simulator once, in the client, and say so.

Without this, every worker process of a new ``LocalCluster`` would compile
:mod:`tasks.kernel` at the same time (minutes on a loaded machine, with no
output), and the progress display would count that time as computing. The
client compiles it once, before the workers start; they load it from numba's
on-disk cache (:mod:`tasks.numba_cache`).
"""

from __future__ import annotations

from typing import TextIO


def compile_once(stream: TextIO) -> float:
    """Compile the simulator unless it is cached; announce it. Returns the seconds spent."""
    from tasks import numba_cache

    if numba_cache.is_compiled():
        return 0.0
    print(numba_cache.compile_message("study"), file=stream, flush=True)
    seconds = numba_cache.compile_simulator()
    print(f"study: compiled in {seconds:.0f} s", file=stream, flush=True)
    return seconds
