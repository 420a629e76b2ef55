"""Many points classified in order, each seeded by the solved points near it (warm starts).

:func:`run_points_given` runs the search of :mod:`tasks.kernel.point` on every
point of a call: a warm start (:func:`tasks.kernel.point.warm_point`) from the
best seeds first (:func:`_warm_tries`: a secant prediction from two solved
points, the nearest copied orbit, more secant predictions, other candidates),
the held start (:func:`tasks.kernel.point.simulate_point`) where none settles
the point, the polish, the orbit check and the design pass.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from tasks.kernel.design import DESIGN_SCALARS, point_design
from tasks.kernel.layout import N_OUT, OUT_CONVERGED, OUT_CYCLES, REC_X
from tasks.kernel.orbit import _check_orbit
from tasks.kernel.point import _seeds_next, polish_point, simulate_point, warm_point
from tasks.kernel.secant import secant_seed
from tasks.kernel.shooting import REC_ROWS

# Secant predictions (:mod:`tasks.kernel.secant`) a point tries where its copied
# seed failed, before the held start.
SECANT_TRIES = 2
# Copied orbits of further candidate seeds a point of an adaptive map tries where
# the first copied seed and the secant predictions failed (:func:`_warm_tries`),
# before the held start (``alt_tries`` of :func:`run_points_given`; none in a dense
# grid, whose chain of neighbours one step apart rarely needs them: there they
# cost more periods than they save, benchmarks/bench_refine_seeded.py).
ALT_TRIES = 5


@njit(cache=True)
def _seed_row(q, final, given):
    """The ``final`` row of a solved point ``q`` (of the call, or given: ``-2 - k``)."""
    n2 = final.shape[1]
    return final[q] if q >= 0 else given[-2 - q, :n2]


@njit(cache=True)
def _warm_tries(
    r, beta, i, scene, settings, out, final, seeds, seedable, given, first, alt_tries, keep, kept
):
    """The warm starts of point ``i`` (:func:`run_points_given`), best seed first, until
    one is accepted. Returns ``(accepted, periods spent)``.

    In order: the interpolation between two solved points on a line through the
    point (:func:`tasks.kernel.secant.secant_seed` with ``between``: the midpoint
    of a cell's edge, a cell's centre on a diagonal; error of order ``h^2``, where
    the copied orbit's is of order ``h``), or where there is none the first secant
    extrapolation (e.g. along a grid column from the two points before it), the
    copied orbit of the nearest candidate (``first``: a point of the call, or
    ``-2 - k``: given row ``k``), up to ``SECANT_TRIES``
    secant predictions, then the copied orbits of up to ``alt_tries`` other
    candidates (nearest first: where the point lies across a change of regime or
    stops from its nearest neighbour, one on its own side). A warm start that is
    not tried (``warm_point`` returns no periods: the held start decides such
    points) ends the tries.
    """
    n2 = final.shape[1]
    pred = np.empty(n2)
    tried = np.empty((1 + SECANT_TRIES, n2))
    n_tried = 0
    spent = 0
    if secant_seed(
        r, beta, i, 0, seeds, seedable, final, given, scene, settings, pred, True
    ) or secant_seed(r, beta, i, 0, seeds, seedable, final, given, scene, settings, pred, False):
        # a prediction from two solved points before any copied orbit
        accepted, used = warm_point(
            r[i], beta[i], scene, settings, out[i], final[i], pred, keep, kept
        )
        if accepted or used == 0:
            return accepted, used
        spent += used
        tried[n_tried] = pred
        n_tried += 1
    # the copied orbit of the nearest candidate
    q0 = first
    accepted, used = warm_point(
        r[i], beta[i], scene, settings, out[i], final[i], _seed_row(q0, final, given), keep, kept
    )
    spent += used
    if accepted or used == 0:
        return accepted, spent
    # secant predictions along lines (secant.py), those not tried yet
    secants = 0
    for nth in range(SECANT_TRIES + 1):
        if secants == SECANT_TRIES or not secant_seed(
            r, beta, i, nth, seeds, seedable, final, given, scene, settings, pred, False
        ):
            break
        if _among(pred, tried, n_tried):
            continue
        secants += 1
        accepted, used = warm_point(
            r[i], beta[i], scene, settings, out[i], final[i], pred, keep, kept
        )
        spent += used
        if accepted:
            return True, spent
        tried[n_tried] = pred
        n_tried += 1
    # the copied orbits of the other candidates, nearest first
    alts = 0
    for c in range(seeds.shape[1]):
        q = seeds[i, c]
        if alts == alt_tries:
            break
        if q == q0 or not (0 <= q < i and seedable[q] or q <= -2 and -2 - q < given.shape[0]):
            continue
        seed = _seed_row(q, final, given)
        if _same_row(seed, _seed_row(q0, final, given)):
            continue
        alts += 1
        accepted, used = warm_point(
            r[i], beta[i], scene, settings, out[i], final[i], seed, keep, kept
        )
        spent += used
        if accepted:
            return True, spent
    return False, spent


@njit(cache=True)
def _same_row(a, b):
    """Whether two seeds are equal (the same orbit: trying it again would repeat it)."""
    for q in range(a.shape[0]):
        if a[q] != b[q]:
            return False
    return True


@njit(cache=True)
def _among(a, rows, m):
    """Whether ``a`` equals one of the first ``m`` rows of ``rows``."""
    for k in range(m):
        if _same_row(a, rows[k]):
            return True
    return False


def run_points(r, beta, scene, settings):
    """Classify every point ``(r[i], beta[i])`` (:func:`run_points_design` without
    the design pass). Returns ``(out, final)``.

    Plain Python, as :func:`run_points_design` and :func:`run_points_seeded`: each
    fills in the arguments it leaves out and calls the one compiled entry point,
    :func:`run_points_given`, with the argument types :func:`tasks.classify` gives it.
    Compiled, each would be one more copy of the whole kernel to compile (numba
    optimises a function together with everything it calls), and its constant
    arguments (``0``) would compile :func:`run_points_given` once more for them.
    """
    out, final, _ = run_points_design(r, beta, scene, settings, 0)
    return out, final


def run_points_design(r, beta, scene, settings, samples):
    """Classify every point ``(r[i], beta[i])`` from the held start (no seeds:
    :func:`run_points_seeded`), and with ``samples > 0`` compute the design
    quantities of its orbit. Returns ``(out, final, design)``."""
    seeds = np.full((r.shape[0], 0), -1, dtype=np.int64)
    return run_points_seeded(r, beta, scene, settings, samples, seeds)


def run_points_seeded(r, beta, scene, settings, samples, seeds):
    """:func:`run_points_given` with no given seeds: ``seeds`` lists earlier points of
    the call only. Returns ``(out, final, design)``."""
    given = np.empty((0, 2 * scene[0].shape[0] + 4))
    return run_points_given(r, beta, scene, settings, int(samples), seeds, given, 0)


@njit(cache=True, nogil=True)
def run_points_given(r, beta, scene, settings, samples, seeds, given, alt_tries):
    """Classify every point ``(r[i], beta[i])`` in order, warm-started where
    ``seeds`` says, and with ``samples > 0`` compute the design quantities of
    its orbit.

    With ``settings[12]`` (``warm``, :mod:`tasks.fidelity`), row ``i`` of
    ``seeds`` lists earlier points (indices below ``i``, nearest first, -1
    padding; :func:`tasks.seeds.warm_seeds`) whose orbit may seed point ``i``:
    the first of them that converged to a moving period-1 orbit seeds a warm
    start (:func:`warm_point`). An entry ``-2 - k`` names row ``k`` of ``given``
    instead: the ``final`` row (section state, phase, section phase) of a moving
    period-1 orbit solved outside the call (e.g. a corner of an adaptive map's
    cell, :mod:`tasks.seeds`), then its r and beta (``2 n + 4`` columns), which
    seeds the point as an earlier point would.
    Before that copied orbit, a prediction from two solved points (of the call
    or given) on a line through the point seeds it (the interpolation where the
    point lies between them, else an extrapolation), and after it up to
    ``SECANT_TRIES`` more such secant predictions
    (:func:`tasks.kernel.secant.secant_seed`: second-order accurate where the
    copied orbit is first-order; the fixed point moves fast but smoothly near a
    resonance of the held system, where the copied orbit is too far for
    Newton's method and the held start needs hundreds of periods), then the
    copied orbits of up to ``alt_tries`` other candidates (:func:`_warm_tries`;
    :data:`ALT_TRIES` for an adaptive map's point lists, 0 elsewhere).
    A point the warm start does not settle, or whose orbit then fails the orbit
    invariant, is classified from the held start (:func:`simulate_point`)
    exactly as without warm starts, and its period-1 motion is then polished
    (:func:`polish_point`) as the warm start's is: every moving period-1 orbit
    is the fixed point of its map to ``POLISH_RTOL``, so the fields do not
    depend on which point seeded which (and the labels never do:
    :func:`warm_point`). The warm start's periods are counted in ``cycles``
    (the one field that depends on the seeds); ``initial_condition`` stays the
    held start, the reference the steady state is the limit of. Without
    ``warm`` the seeds are ignored and nothing is polished.

    The design quantities (:func:`tasks.kernel.design.orbit_design_recorded`,
    ``samples`` per cycle at least) are computed from the records of the orbit
    check (:func:`tasks.kernel.orbit._check_orbit`): the orbit is replayed once
    for both.

    Returns ``(out, final, design)``: ``out`` is ``(n_points, N_OUT)`` (columns
    ``OUT_*``), ``final`` the last section state and phase of each point,
    ``design`` the ``(n_points, 2 n + 3)`` design quantities (NaN where the point
    has no steady state; no rows when ``samples`` is 0).
    """
    n = scene[0].shape[0]
    out = np.empty((r.shape[0], N_OUT))
    final = np.empty((r.shape[0], 2 * n + 2))
    design = np.full((r.shape[0] if samples > 0 else 0, 2 * n + DESIGN_SCALARS), np.nan)
    warm = settings[12]
    keep = np.empty((REC_ROWS, REC_X + 2 * n))  # a shot's verified period, for the check
    kept = np.zeros(1, dtype=np.int64)
    seedable = np.zeros(r.shape[0], dtype=np.bool_)
    for i in range(r.shape[0]):
        accepted = False
        spent = 0
        rec = np.zeros((0, REC_X + 2 * n))
        nr = 0
        source = -1
        outside = -1
        if warm:
            for c in range(seeds.shape[1]):
                j = seeds[i, c]
                if 0 <= j < i and seedable[j]:
                    source = j
                    break
                if j <= -2 and -2 - j < given.shape[0]:
                    outside = -2 - j
                    break
        if source >= 0 or outside >= 0:
            first = source if source >= 0 else -2 - outside
            accepted, spent = _warm_tries(
                r,
                beta,
                i,
                scene,
                settings,
                out,
                final,
                seeds,
                seedable,
                given,
                first,
                alt_tries,
                keep,
                kept,
            )
            if accepted:
                out[i, OUT_CYCLES] = spent
                rec, nr = _check_orbit(
                    r[i], beta[i], scene, settings, out[i], final[i], keep, kept[0]
                )
                accepted = out[i, OUT_CONVERGED] == 1.0
        if not accepted:
            simulate_point(r[i], beta[i], scene, settings, out[i], final[i], keep, kept)
            if warm and beta[i] > 0.0 and _seeds_next(out[i]):  # (beta = 0: closed form)
                polish_point(r[i], beta[i], scene, settings, out[i], final[i], keep, kept)
            rec, nr = _check_orbit(r[i], beta[i], scene, settings, out[i], final[i], keep, kept[0])
            out[i, OUT_CYCLES] += spent
        if samples > 0:
            point_design(
                r[i], beta[i], scene, settings, out[i], final[i], samples, design[i], rec, nr
            )
        seedable[i] = warm and beta[i] > 0.0 and _seeds_next(out[i])
    return out, final, design
