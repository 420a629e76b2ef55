"""First run on a machine: compile the simulators a study needs once, in the client,
and say so.

Without this, every worker process of a new ``LocalCluster`` would compile the
simulator at the same time (minutes on a loaded machine, with no output), and
the progress display would count that time as computing. The client compiles
each simulator the study's scenes need (:func:`kernels_for`: the one-contact
kernel :mod:`tasks.kernel`, the several-contact one of :mod:`tasks.multicontact`,
or both) once, before the workers start; they load it from numba's on-disk
cache (:mod:`tasks.numba_cache`).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TextIO


def kernels_for(plans: Iterable, work=None) -> tuple[str, ...]:
    """The simulators (names of :data:`tasks.numba_cache.KERNELS`) the scene plans
    ``plans`` (:class:`study.plans.ScenePlan`) compute with, in the order of the
    plans; with ``work`` (the work folder) only those of plans with points missing."""
    from study import contacts
    from tasks import numba_cache

    out: list[str] = []
    for p in plans:
        if work is not None and not p.missing_points(work):
            continue
        multi = contacts.is_multi(p.spec.structure)
        name = numba_cache.SEVERAL_CONTACTS if multi else numba_cache.ONE_CONTACT
        if name not in out:
            out.append(name)
    return tuple(out)


def compile_once(stream: TextIO, kernels: Iterable[str] = ("kernel",)) -> float:
    """Compile each simulator of ``kernels`` unless it is cached, announcing each in
    one line before its compile and its seconds after. Returns the seconds spent."""
    from tasks import numba_cache

    seconds = 0.0
    for name in kernels:
        if numba_cache.compiled(name):
            continue
        print(numba_cache.compile_message("study", name), file=stream, flush=True)
        if name == numba_cache.ONE_CONTACT:  # as callers (and tests) replace it
            spent = numba_cache.compile_simulator()
        else:
            spent = numba_cache.compile_simulator(name)
        print(f"study: compiled in {spent:.0f} s", file=stream, flush=True)
        seconds += spent
    return seconds
