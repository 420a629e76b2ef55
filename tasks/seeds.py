"""Warm starts along a map: which already solved points may seed each point's search.

A point's steady-state search can start from the converged orbit of a point
solved before it in the same call (:func:`tasks.kernel.batch.run_points_seeded`),
if the two orbits are close enough for a few Newton steps on the Poincare map to
follow one to the other. How far an orbit moves is measured in two scaled
coordinates: the phase the fastest free mode turns through in one period of the
excitation, ``2 pi sqrt(lambda_max) / r`` (Eq. 7: its frequency relative to the
excitation is ``sqrt(lambda_max) / r``), in units of ``WARM_PHASE`` radians, and
``ln beta`` in units of ``WARM_STEP``. Two points are neighbours when both
coordinates differ by at most 1.

The seeds change how fast a point settles, never what it settles to: the labels
are those of the held start (docs/theory.md 3, "One regime per point") and the
orbit is polished to the fixed point of its map, so the other fields agree
whatever seeded the search (``tasks.kernel.point``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy.spatial import cKDTree

from tasks.kernel.layout import OUT_ASYMPTOTIC, OUT_CONVERGED, OUT_PERIOD, OUT_REGIME
from tasks.regimes import CONTINUOUS, STICK_SLIP

#: Largest difference in the fastest mode's phase over one period (radians), and in
#: ``ln beta``, between a point and a neighbour that seeds it.
WARM_PHASE = 1.0
WARM_STEP = 0.2
#: Candidate seeds kept per point (nearest first): the kernel takes the first
#: that converged to a moving period-1 orbit.
CANDIDATES = 4
#: Nearest points looked at per point (before and after it in the call).
_LOOK = 12
#: Reach (in the units of :func:`warm_coordinates`) and candidate seeds per point of
#: :func:`tasks.classifier.classify_given`, whose points (an adaptive map's new
#: points) lie up to a coarse step (16 grid steps) from the solved points that
#: seed them: a failed warm start costs one or two periods, the held start it
#: saves up to hundreds (benchmarks/bench_refine_seeded.py).
GIVEN_REACH = 4.0
GIVEN_CANDIDATES = 8


def warm_coordinates(r: np.ndarray, beta: np.ndarray, lambda_max: float) -> np.ndarray:
    """``(n, 2)`` scaled coordinates of the points: fastest-mode phase over one period
    in units of ``WARM_PHASE``, ``ln beta`` in units of ``WARM_STEP``."""
    phase = 2.0 * math.pi * math.sqrt(max(lambda_max, 0.0)) / r / WARM_PHASE
    with np.errstate(divide="ignore"):
        log_beta = np.log(beta) / WARM_STEP
    return np.stack([phase, log_beta], axis=1)


def warm_seeds(
    r: np.ndarray,
    beta: np.ndarray,
    lambda_max: float,
    given_r: np.ndarray | None = None,
    given_beta: np.ndarray | None = None,
    reach: float = 1.0,
    candidates: int = CANDIDATES,
) -> np.ndarray:
    """Candidate seeds of every point: ``(n, candidates)`` indices of earlier points.

    Row ``i`` lists the points before ``i`` (index below ``i``) within distance
    ``reach`` in the scaled coordinates of :func:`warm_coordinates` (the larger of
    the two differences), nearest first, padded with -1. Points at ``beta = 0`` neither
    seed nor are seeded (linear, no search). ``lambda_max`` is the largest
    eigenvalue of the sliding system (``scene_modes(...).kernel_args()[5][-1]``).

    ``given_r``, ``given_beta``: points solved outside the call (moving period-1
    orbits, e.g. the corners of an adaptive map's cells) that may seed any point
    of the call, ranked with the earlier points by distance; given point ``k``
    is listed as ``-2 - k`` (:func:`tasks.kernel.batch.run_points_given`).
    """
    r = np.asarray(r, dtype=np.float64).ravel()
    beta = np.asarray(beta, dtype=np.float64).ravel()
    n = r.size
    seeds = np.full((n, candidates), -1, dtype=np.int64)
    live = np.flatnonzero(beta > 0.0)
    m = 0 if given_r is None else np.asarray(given_r).size
    if live.size < (2 if m == 0 else 1):
        return seeds
    coords = warm_coordinates(r[live], beta[live], lambda_max)
    index = live
    if m:
        g_r = np.asarray(given_r, dtype=np.float64).ravel()
        g_beta = np.asarray(given_beta, dtype=np.float64).ravel()
        coords = np.concatenate([coords, warm_coordinates(g_r, g_beta, lambda_max)])
        index = np.concatenate([live, -2 - np.arange(m)])  # given: -2 - k
    k = min(_LOOK + min(m, candidates), index.size)
    dist, near = cKDTree(coords).query(coords[: live.size], k=k, p=np.inf)
    dist, near = dist.reshape(live.size, k), near.reshape(live.size, k)
    index = index[near]  # the neighbours' indices in the call (or given), nearest first
    earlier = (index >= 0) & (index < live[:, None])
    ok = (dist <= reach) & (earlier | (index <= -2))
    taken = first_true(ok, index, candidates)  # kept, nearest first
    seeds[live, : taken.shape[1]] = taken
    return seeds


def first_true(ok: np.ndarray, values: np.ndarray, k: int) -> np.ndarray:
    """The first ``k`` entries of each row of ``values`` where ``ok`` holds, in their order,
    padded with -1: ``(rows, min(k, columns))``. The stable argsort of ``~ok`` taken
    without sorting (a row's rank of each kept entry from a cumulative sum)."""
    rows, cols = ok.shape
    k = min(int(k), cols)
    out = np.full((rows, k), -1, dtype=np.int64)
    rank = np.cumsum(ok, axis=1) - 1
    put = ok & (rank < k)
    out[np.nonzero(put)[0], rank[put]] = values[put]
    return out


def can_seed(out: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """Which points' orbits can seed a neighbour: verified moving period-1 orbits at
    ``beta > 0`` (``out``: the kernel's ``(n, N_OUT)`` results; the kernel's own
    test, ``tasks.kernel.point._seeds_next``)."""
    regime = out[:, OUT_REGIME]
    return (
        (out[:, OUT_CONVERGED] == 1.0)
        & (out[:, OUT_PERIOD] == 1.0)
        & (out[:, OUT_ASYMPTOTIC] == 0.0)
        & ((regime == STICK_SLIP) | (regime == CONTINUOUS))
        & (np.asarray(beta) > 0.0)
    )


def grid_offsets(reach: int) -> np.ndarray:
    """``(m, 2)`` grid offsets ``(di, dj)`` at which an adaptive map's solved points
    are looked for around a new point, nearest first: every combination of 0 and
    the powers of two up to ``reach`` (the coarse step) along each axis and either
    sign, where the corners of the cells the refinement splits lie."""
    steps = [0]
    d = 1
    while d <= max(1, reach):
        steps += [d, -d]
        d *= 2
    off = np.array([(a, b) for a in steps for b in steps if a or b], dtype=np.int64)
    size = np.abs(off)
    order = np.lexsort((size.sum(axis=1), size.max(axis=1)))
    return off[order]


def grid_neighbours(
    idx: np.ndarray, shape: tuple[int, int], row: np.ndarray, offsets: np.ndarray, k: int
) -> np.ndarray:
    """The ``k`` nearest solved points of each grid point: ``(len(idx), k)`` rows of
    ``row`` (-1 padding).

    ``idx`` are flat indices on a grid of ``shape``; ``row`` maps every flat index
    to the row of its solved orbit (-1: none); ``offsets`` from :func:`grid_offsets`,
    nearest first."""
    idx = np.ascontiguousarray(idx, dtype=np.int64).ravel()
    offsets = np.ascontiguousarray(offsets, dtype=np.int64)
    k = min(int(k), offsets.shape[0])
    return _grid_neighbours(idx, int(shape[0]), int(shape[1]), row, offsets, k)


@njit(cache=True, nogil=True)
def _grid_neighbours(idx, n_r, n_b, row, offsets, k):  # pragma: no cover - compiled
    """:func:`grid_neighbours`, point by point: the offsets in order until ``k`` are found
    (a numpy pass over every offset of every point cost a tile's round as much as the
    neighbour search of its seeds)."""
    out = np.full((idx.size, k), -1, dtype=np.int64)
    for p in range(idx.size):
        i, j = idx[p] // n_b, idx[p] % n_b
        n = 0
        for o in range(offsets.shape[0]):
            ii, jj = i + offsets[o, 0], j + offsets[o, 1]
            if 0 <= ii < n_r and 0 <= jj < n_b and row[ii * n_b + jj] >= 0:
                out[p, n] = row[ii * n_b + jj]
                n += 1
                if n == k:
                    break
    return out
