"""Warm starts along a map: which already solved points may seed each point's search.

A point's steady-state search can start from the converged orbit of a point
solved before it in the same call (:func:`tasks.kernel.point.run_points_seeded`),
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
from scipy.spatial import cKDTree

#: Largest difference in the fastest mode's phase over one period (radians), and in
#: ``ln beta``, between a point and a neighbour that seeds it.
WARM_PHASE = 1.0
WARM_STEP = 0.2
#: Candidate seeds kept per point (nearest first): the kernel takes the first
#: that converged to a moving period-1 orbit.
CANDIDATES = 4
#: Nearest points looked at per point (before and after it in the call).
_LOOK = 12


def warm_coordinates(r: np.ndarray, beta: np.ndarray, lambda_max: float) -> np.ndarray:
    """``(n, 2)`` scaled coordinates of the points: fastest-mode phase over one period
    in units of ``WARM_PHASE``, ``ln beta`` in units of ``WARM_STEP``."""
    phase = 2.0 * math.pi * math.sqrt(max(lambda_max, 0.0)) / r / WARM_PHASE
    with np.errstate(divide="ignore"):
        log_beta = np.log(beta) / WARM_STEP
    return np.stack([phase, log_beta], axis=1)


def warm_seeds(r: np.ndarray, beta: np.ndarray, lambda_max: float) -> np.ndarray:
    """Candidate seeds of every point: ``(n, CANDIDATES)`` indices of earlier points.

    Row ``i`` lists the points before ``i`` (index below ``i``) within distance 1
    in the scaled coordinates of :func:`warm_coordinates` (the larger of the two
    differences), nearest first, padded with -1. Points at ``beta = 0`` neither
    seed nor are seeded (linear, no search). ``lambda_max`` is the largest
    eigenvalue of the sliding system (``scene_modes(...).kernel_args()[5][-1]``).
    """
    r = np.asarray(r, dtype=np.float64).ravel()
    beta = np.asarray(beta, dtype=np.float64).ravel()
    n = r.size
    seeds = np.full((n, CANDIDATES), -1, dtype=np.int64)
    live = np.flatnonzero(beta > 0.0)
    if live.size < 2:
        return seeds
    coords = warm_coordinates(r[live], beta[live], lambda_max)
    k = min(_LOOK, live.size)
    dist, near = cKDTree(coords).query(coords, k=k, p=np.inf)
    dist, near = dist.reshape(live.size, k), near.reshape(live.size, k)
    index = live[near]  # the neighbours' indices in the call, nearest first
    ok = (dist <= 1.0) & (index < live[:, None])
    first = np.argsort(~ok, axis=1, kind="stable")[:, :CANDIDATES]  # kept, nearest first
    taken = np.where(np.take_along_axis(ok, first, 1), np.take_along_axis(index, first, 1), -1)
    seeds[live, : taken.shape[1]] = taken
    return seeds
