"""Cost model: estimated seconds of ``tasks.classify`` work per point.

Used to size tasks (about ``task_seconds`` of work each, 0.1-2 s, not one task
per point) and to print time estimates (``study plan``). The model is

    seconds_per_point = BASE_SECONDS[fidelity] * (1 + DOF_SLOPE * (dof - 1)) * factor
    factor = (1 + CONTACT_SLOPE * (contacts - 1)) * (1 + slope * max(0, rate - CHAIN_MODE_RATE))

with ``rate`` the mean over the scene's r values of ``sqrt(lambda_max) / r``
(:func:`mode_rate`: how many turns the fastest free mode makes per excitation
period, which sets the number of event-search brackets per period). A chain has
``rate`` 1.8-4, a reduced beam 35-90 (its fixed-interface modes), hence the
factor of scenes given by matrices or beams; several contacts run the
multi-contact simulator (:mod:`tasks.multicontact`), hence ``CONTACT_SLOPE``;
``slope`` is ``MODE_SLOPE`` for one contact, ``MULTI_MODE_SLOPE`` for several.

Measured with ``benchmarks/bench_scheduling.py``: on a 2-worker LocalCluster the
scheduling overhead is about 2-5 % with tasks of 0.3-1.5 s and 12-14 % with
tasks of 0.1 s, hence the target of ``[study] task_seconds`` = 0.5 s.

How the constants are calibrated (``benchmarks/bench_plan.py``): whole chunks
of the real plans of the example studies (quickstart, Figs. 3, 4, 10a, 10b, 14,
17, the cantilever, two contacts on a 2DOF and a 3DOF chain and on a beam: every
regime of the maps, as in a run), a few per scene, computed by
``study.compute.compute_chunk`` and timed in CPU seconds; the constants below
are fitted to the measured seconds per point (every example scene within
2.3x), and two scenes not among the examples check the fit. :func:`wall_seconds`
adds the start-up (:data:`STARTUP_SECONDS`, measured by ``bench_plan.py --startup``) and
the scheduling overhead.

Task sizes must not change between a run and its resume (they define the chunk
keys), so they always use these fixed constants (with :func:`spec_factor`, a pure
function of the study) or ``[study] chunk_points``.
:func:`calibrate` measures the real cost on the local machine for estimates
only (``study plan --calibrate``); put a measured value in ``BASE_SECONDS`` to re-tune.
"""

from __future__ import annotations

import time

import numpy as np

from tasks.fidelity import Settings
from tasks.scene import Scene

#: CPU seconds per point of a 1-DOF chain with one contact for each preset.
#: Fitted to ``benchmarks/bench_plan.py`` (whole chunks of the example studies,
#: balanced preset): measured 0.105 ms (1 DOF, Fig. 3); 2 DOF 0.17-0.25 ms (ground
#: contact, Fig. 4, quickstart), 0.08-0.10 ms (base contact, Fig. 14), 0.07-0.09 ms
#: (contact between the masses, Fig. 17); 0.19-0.31 ms (5 DOF, Figs. 10a, 10b).
#: The fast preset measured 0.93 times balanced (a 2DOF chain, 240 points); exact
#: keeps its earlier ratio to balanced (1.15). Points near a resonance or a
#: boundary cost more, no-motion points far less.
BASE_SECONDS: dict[str, float] = {"fast": 0.93e-4, "balanced": 1.0e-4, "exact": 1.15e-4}
#: Relative extra cost per additional degree of freedom (fit above: 2 DOF 0.12 ms,
#: 5 DOF 0.18 ms per point).
DOF_SLOPE = 0.2
#: Relative extra cost per additional contact (several contacts run
#: :mod:`tasks.multicontact`). Fitted to ``bench_plan.py``: 2 contacts on a 2DOF
#: and a 3DOF chain (fast preset) cost 6.3 and 9.3 times one contact.
CONTACT_SLOPE = 6.6
#: The fastest mode's :func:`mode_rate` up to which a scene costs what a chain
#: costs (chains of the examples: 1.8-4.0).
CHAIN_MODE_RATE = 4.0
#: Relative extra cost per unit of :func:`mode_rate` above ``CHAIN_MODE_RATE``,
#: one contact: the cantilever example (rate 35) costs 20-32 times a 5DOF chain.
MODE_SLOPE = 0.78
#: The same for several contacts (their simulator's brackets grow more slowly
#: with the fastest mode): the beam with two contacts (rate 87) costs 5.7 times a
#: chain of two contacts.
MULTI_MODE_SLOPE = 0.057
#: Wall seconds to start a local cluster of single-threaded workers and load the
#: compiled kernels in them (``bench_plan.py --startup``: 4.5-4.6 s, 2 workers).
STARTUP_SECONDS = 4.5
#: Wall seconds before and after the compute of a small study computed in threads
#: of the run's own process (:func:`study.drive.local_threads`): imports, loading
#: the compiled kernel, writing the result (``bench_example.py``, the Fig. 4
#: example, its in-process Dask worker included: 0.75 s before, 0.6 s after).
IN_PROCESS_STARTUP_SECONDS = 1.4
#: Scheduling overhead of tasks of about ``task_seconds`` (bench_scheduling.py: 2-5 %).
SCHEDULING_OVERHEAD = 0.05
#: Shortest task the sizing aims at, in seconds: below ~0.1 s the fixed cost of
#: a Dask task (scheduling, transfer, the client's save) is no longer small.
MIN_TASK_SECONDS = 0.1
#: A scene is cut into at least this many tasks when that keeps tasks above
#: ``MIN_TASK_SECONDS``, so small studies still use every worker.
MIN_TASKS_PER_SCENE = 16
#: Classifications per r value when a boundary is traced (``mode = "trace"``):
#: a scan plus bisection for each of the two boundaries.
TRACE_POINTS_PER_R = 40


def mode_rate(scene, r: np.ndarray) -> float:
    """Mean over ``r`` of ``sqrt(lambda_max) / r``: the phase the fastest free mode
    turns through per excitation period, over 2 pi.

    ``lambda_max`` is the largest eigenvalue of ``(K, M)`` at ``r = 1`` (Eqs. 68-69,
    Eq. 1.1 for a structure). The event search scans each period in brackets a
    fraction of that mode's half-period long, so the brackets per period grow
    with it: about 1.6-4 for a chain, 35-90 for the example beams.
    """
    from scipy.linalg import eigh

    lam = eigh(scene.stiffness_matrix(), scene.mass_matrix(1.0), eigvals_only=True)
    r = np.asarray(r, dtype=float)
    return float(np.mean(np.sqrt(max(float(lam[-1]), 0.0)) / r)) if r.size else 0.0


def scene_factor(scene, r: np.ndarray) -> float:
    """Cost of a point of ``scene`` over the r values ``r``, relative to a chain with
    one contact of the same DOF count and fidelity.

    ``(1 + CONTACT_SLOPE * (n - 1))`` for ``n`` contacts (:mod:`tasks.multicontact`),
    times ``(1 + slope * max(0, mode_rate - CHAIN_MODE_RATE))`` for the fastest
    mode (:func:`mode_rate`; ``slope`` is ``MODE_SLOPE`` for one contact,
    ``MULTI_MODE_SLOPE`` for several). A pure function of the scene and its r values.
    """
    n = int(getattr(scene, "n_contacts", 1))
    slope = MODE_SLOPE if n == 1 else MULTI_MODE_SLOPE
    modes = 1.0 + slope * max(0.0, mode_rate(scene, r) - CHAIN_MODE_RATE)
    return (1.0 + CONTACT_SLOPE * (n - 1)) * modes


def spec_factor(spec) -> float:
    """:func:`scene_factor` of a study scene (``study.definition.SceneSpec``): its
    first scene of the sweeps, over its r axis (or its points' r)."""
    r = spec.r.values_array() if spec.r is not None else np.asarray(spec.points.r)
    return scene_factor(spec.base_scene, r)


def seconds_per_point(dof: int, fidelity: str, factor: float = 1.0) -> float:
    """Estimated compute seconds for one (r, beta) point; ``factor``: :func:`scene_factor`."""
    return BASE_SECONDS[fidelity] * (1.0 + DOF_SLOPE * (dof - 1)) * factor


def wall_seconds(
    cpu_seconds: float, workers: int, local: bool = True, in_process: bool = False
) -> float:
    """Estimated wall seconds of a run: start-up (a local cluster's, or the imports of
    a run computed in ``workers`` threads of its own process, ``in_process``), then
    the CPU seconds shared by ``workers`` with the scheduling overhead."""
    if in_process:
        startup = IN_PROCESS_STARTUP_SECONDS
    else:
        startup = STARTUP_SECONDS if local else 0.0
    return startup + cpu_seconds / max(1, workers) * (1.0 + SCHEDULING_OVERHEAD)


def points_per_task(dof: int, fidelity: str, task_seconds: float, factor: float = 1.0) -> int:
    """Points in one task so that it takes about ``task_seconds``."""
    return max(1, int(round(task_seconds / seconds_per_point(dof, fidelity, factor))))


def chunk_target(
    dof: int, fidelity: str, task_seconds: float, n_points: int, factor: float = 1.0
) -> int:
    """Points per task of a scene of ``n_points``: ``task_seconds`` of work each, but
    at least ``MIN_TASKS_PER_SCENE`` tasks as long as each keeps ``MIN_TASK_SECONDS``.

    Depends on the study only (never on the cluster), so chunk keys are stable.
    """
    target = points_per_task(dof, fidelity, task_seconds, factor)
    floor = points_per_task(dof, fidelity, min(MIN_TASK_SECONDS, task_seconds), factor)
    spread = -(-n_points // MIN_TASKS_PER_SCENE)  # ceil
    return max(1, min(target, max(floor, spread)))


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


class CostTracker:
    """Learns the cost of each scene from its finished tasks; gives the ETA of a run.

    The cost model above sizes the tasks (it must not change between a run and
    its resume: task sizes define the chunk keys). What a task really costs is
    learnt as tasks finish: per scene, the compute seconds per point of its
    finished chunks; for a scene without a finished chunk yet, the model's
    estimate scaled by what the finished scenes cost against their estimates
    (the machine's speed). The remaining compute seconds are divided by the
    parallelism observed (compute seconds finished per wall second), so a slow
    scene (e.g. 20 DOF, 50 times the estimate) neither hides behind the rate of
    the fast ones nor makes the first ETA absurd.

    Parameters
    ----------
    estimates : dict
        Scene name -> (points still to compute, model seconds per point).
    clock : callable
        Wall clock (``time.monotonic``).
    """

    def __init__(self, estimates: dict[str, tuple[int, float]], clock=time.monotonic) -> None:
        self.remaining = {k: int(n) for k, (n, _) in estimates.items()}
        self.model = {k: float(s) for k, (_, s) in estimates.items()}
        self.points: dict[str, int] = {}
        self.seconds: dict[str, float] = {}
        self.clock = clock
        self.t0 = clock()

    def record(self, scene: str, n_points: int, seconds: float) -> None:
        """One finished chunk of ``scene``: ``n_points`` in ``seconds`` of compute."""
        self.remaining[scene] = max(0, self.remaining.get(scene, 0) - n_points)
        self.points[scene] = self.points.get(scene, 0) + n_points
        self.seconds[scene] = self.seconds.get(scene, 0.0) + max(0.0, float(seconds))

    def per_point(self, scene: str) -> float:
        """Learnt seconds per point of ``scene`` (the scaled model before its first chunk)."""
        if self.points.get(scene):
            return self.seconds[scene] / self.points[scene]
        done = [k for k in self.points if self.points[k]]
        model_done = sum(self.model.get(k, 0.0) * self.points[k] for k in done)
        speed = sum(self.seconds[k] for k in done) / model_done if model_done > 0 else 1.0
        return self.model.get(scene, 0.0) * speed

    def eta(self) -> float | None:
        """Wall seconds left, or None before the first finished chunk."""
        spent = sum(self.seconds.values())
        if spent <= 0.0:
            return None
        wall = max(self.clock() - self.t0, 1e-9)
        parallel = max(1.0, spent / wall)
        left = sum(n * self.per_point(k) for k, n in self.remaining.items())
        return left / parallel
