"""Cost model: estimated seconds of ``tasks.classify`` work per point.

Used to size tasks (about ``task_seconds`` of work each, 0.1-2 s, not one task
per point) and to print time estimates (``study plan``). The model is

    seconds_per_point = BASE[fidelity] * (1 + DOF_SLOPE * (dof - 1))

Task sizes must not change between a run and its resume (they define the chunk
keys), so they always use these fixed constants or ``[study] chunk_points``.
:func:`calibrate` measures the real cost on the local machine for estimates
only (``study plan --calibrate``); put a measured value in ``BASE`` to re-tune.
"""

from __future__ import annotations

import time

import numpy as np

from tasks.fidelity import Settings
from tasks.scene import Scene

#: Seconds per point of a 1-DOF scene for each preset (measured with
#: benchmarks/bench_scheduling.py on one core; typical maps mix all regimes).
BASE_SECONDS: dict[str, float] = {"fast": 2.5e-4, "balanced": 1.0e-3, "exact": 4.0e-3}
#: Relative extra cost per additional degree of freedom.
DOF_SLOPE = 0.5
#: Classifications per r value when a boundary is traced (``mode = "trace"``):
#: a scan plus bisection for each of the two boundaries.
TRACE_POINTS_PER_R = 40


def seconds_per_point(dof: int, fidelity: str) -> float:
    """Estimated compute seconds for one (r, beta) point."""
    return BASE_SECONDS[fidelity] * (1.0 + DOF_SLOPE * (dof - 1))


def points_per_task(dof: int, fidelity: str, task_seconds: float) -> int:
    """Points in one task so that it takes about ``task_seconds``."""
    return max(1, int(round(task_seconds / seconds_per_point(dof, fidelity))))


def calibrate(
    scene: Scene,
    settings: Settings,
    r: np.ndarray,
    beta: np.ndarray,
    n: int = 200,
    seed: int = 0,
) -> float:
    """Measure seconds per point of ``tasks.classify`` on ``n`` random points of a grid.

    The first call compiles the kernels, so a warm-up point is run first and
    not timed.
    """
    from tasks import classify

    rng = np.random.default_rng(seed)
    rs = rng.choice(np.asarray(r, dtype=float), n)
    bs = rng.choice(np.asarray(beta, dtype=float), n)
    fields = settings.to_dict()
    classify(scene, rs[:1], bs[:1], **fields)
    t0 = time.perf_counter()
    classify(scene, rs, bs, **fields)
    return (time.perf_counter() - t0) / n
