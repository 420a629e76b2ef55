"""A warm start's seed extrapolated from two solved neighbours on a line (a secant predictor).

Near a resonance of the held system a Floquet multiplier of the stick-slip
orbit approaches 1 (critical slowing down): the fixed point of the Poincare
map moves fast with (r, beta), the neighbour's orbit is too far for Newton's
method (the step crosses a change of the event pattern, or exceeds the trust
region), and the held start then needs hundreds to thousands of periods. The
fixed point still moves smoothly along a grid line: two solved points ``j``
and ``k`` on the line through the point ``i``, ``j`` between them, give the
secant prediction ``X_i = X_j + t (X_j - X_k)`` with ``t = |p_i - p_j| /
|p_j - p_k|``, second-order accurate where the copied seed ``X_j`` is first.

The prediction is only a seed: :func:`tasks.kernel.point.warm_point` accepts
the orbit it leads to by the same tests as any warm start, so neither the
labels nor (after the polish) the other fields depend on it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.kernel.context import _context
from tasks.kernel.cycle import _advance
from tasks.kernel.layout import LEAF, N_STATS, ST_STATUS, STATUS_OK, TWO_PI

#: Largest extrapolation ``t`` (the point at most this many times as far from ``j``
#: as ``k`` is), and the collinearity the three points must meet (sine of the angle).
SECANT_REACH = 2.0
SECANT_SINE = 1e-9


@njit(cache=True)
def _along(r, beta, i, j, k):
    """``t`` with ``p_i - p_j = t (p_j - p_k)`` in the (r, beta) plane, or 0.0 where
    the three points are not on one line with ``j`` between ``i`` and ``k`` (or
    ``t`` exceeds ``SECANT_REACH``)."""
    ar = r[i] - r[j]
    ab = beta[i] - beta[j]
    br = r[j] - r[k]
    bb = beta[j] - beta[k]
    nb = br * br + bb * bb
    na = ar * ar + ab * ab
    if nb == 0.0 or na == 0.0:
        return 0.0
    if abs(ar * bb - ab * br) > SECANT_SINE * math.sqrt(na * nb):
        return 0.0
    t = (ar * br + ab * bb) / nb
    if not 0.0 < t <= SECANT_REACH:
        return 0.0
    return t


@njit(**LEAF)
def _candidate(seeds, idx, c):
    """The ``c``-th point that may continue a line to point ``idx``: the point before it
    in the call (``c = 0``: along a grid line or a trace in the call's order), then
    its candidate seeds (row ``idx`` of ``seeds``, nearest first); -1 where none."""
    if c == 0:
        return idx - 1
    j = seeds[idx, c - 1]
    return -1 if j == idx - 1 else j


@njit(cache=True)
def secant_seed(r, beta, i, nth, seeds, seedable, final, scene, settings, pred):
    """The ``nth`` (0, 1, ...) secant prediction of point ``i``'s orbit (into ``pred``).

    The pairs ``(j, k)`` are taken in order: ``j`` each point that may continue a
    line to ``i`` (:func:`_candidate`: the point before it in the call, then its
    candidate seeds of :func:`tasks.seeds.warm_seeds`) that is a solved moving
    period-1 orbit (``seedable``), ``k`` the first such point for ``j`` that lies
    on the line through ``i`` and ``j`` beyond ``j`` (:func:`_along`). ``final``
    rows are (section state, phase, section phase); where ``k``'s section
    differs from ``j``'s, ``k``'s orbit is carried to ``j``'s section (a part of
    a period of ``k``'s own motion); the state there must lie in the same kind
    of phase (stuck or sliding) as ``j``'s.

    Returns True where ``pred`` holds a prediction (phase and section of ``j``).
    """
    found = 0
    for a in range(seeds.shape[1] + 1):
        j = _candidate(seeds, i, a)
        if not (0 <= j < i and seedable[j]):
            continue
        for c in range(seeds.shape[1] + 1):
            k = _candidate(seeds, j, c)
            if not (0 <= k < j and seedable[k]):
                continue
            t = _along(r, beta, i, j, k)
            if t == 0.0:
                continue
            if found < nth:
                found += 1
                break
            return _predict(r, beta, j, k, t, final, scene, settings, pred)
    return False


@njit(cache=True)
def _predict(r, beta, j, k, t, final, scene, settings, pred):
    """``pred = X_j + t (X_j - X_k)`` at ``j``'s section (:func:`secant_seed`)."""
    n = (final.shape[1] - 2) // 2
    mode_j = int(final[j, 2 * n])
    theta = final[j, 2 * n + 1]
    Xk = final[k, : 2 * n].copy()
    theta_k = final[k, 2 * n + 1]
    mode_k = int(final[k, 2 * n])
    if theta_k != theta:
        # k's orbit carried from its section to j's (its own motion: its context)
        ctx, work, _, _, _ = _context(r[k], beta[k], scene, settings)
        target = theta if theta > theta_k else theta + TWO_PI
        stats = np.zeros(N_STATS)
        Xk, mode_k, _ = _advance(Xk, mode_k, theta_k, stats, ctx, work, theta_k, target)
        if stats[ST_STATUS] != STATUS_OK:
            return False
    if (mode_k == 0) != (mode_j == 0):
        return False
    for q in range(2 * n):
        pred[q] = final[j, q] + t * (final[j, q] - Xk[q])
    pred[2 * n] = mode_j
    pred[2 * n + 1] = theta
    return True
