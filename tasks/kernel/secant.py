"""A warm start's seed from two solved points on a line through the point (a secant predictor).

Near a resonance of the held system a Floquet multiplier of the stick-slip
orbit approaches 1 (critical slowing down): the fixed point of the Poincare
map moves fast with (r, beta), the neighbour's orbit is too far for Newton's
method (the step crosses a change of the event pattern, or exceeds the trust
region), and the held start then needs hundreds to thousands of periods. The
fixed point still moves smoothly along a line of points: two solved points
``j`` and ``k`` on the line through the point ``i`` give the secant prediction
``X_i = X_j + t (X_j - X_k)``, with ``p_i - p_j = t (p_j - p_k)`` in the (r,
beta) plane: an extrapolation (``0 < t <= SECANT_REACH``, ``j`` between ``i``
and ``k``) or an interpolation (``-1 < t < 0``, ``i`` between them: e.g. the
midpoint of a cell's edge between two solved corners), second-order accurate
where the copied seed ``X_j`` is first.

A point is named by an index ``q``: ``q >= 0`` a point of the call (``r[q]``,
``beta[q]``, ``final[q]``), ``q <= -2`` row ``-2 - q`` of ``given`` (a moving
period-1 orbit solved outside the call: ``final`` row, then its r and beta,
:func:`tasks.kernel.batch.run_points_given`).

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
#: What :func:`_candidate` returns past the last candidate (no point's name: -2 is
#: given row 0).
PAST_END = -(1 << 62)


@njit(**LEAF)
def _where(q, r, beta, given, n):
    """``(r, beta)`` of the point ``q`` (of the call, or given: module docstring)."""
    if q >= 0:
        return r[q], beta[q]
    return given[-2 - q, 2 * n + 2], given[-2 - q, 2 * n + 3]


@njit(**LEAF)
def _solved(q, i, seedable, given):
    """Whether ``q`` names a solved moving period-1 orbit: an earlier point of the call
    that can seed, or a given one."""
    if q >= 0:
        return q < i and seedable[q]
    return q <= -2 and -2 - q < given.shape[0]


@njit(cache=True)
def _along(ri, bi, rj, bj, rk, bk):
    """``t`` with ``p_i - p_j = t (p_j - p_k)`` in the (r, beta) plane, or 0.0 where
    the three points are not on one line, or ``t`` is outside ``(-1, 0)`` and
    ``(0, SECANT_REACH]`` (module docstring)."""
    ar = ri - rj
    ab = bi - bj
    br = rj - rk
    bb = bj - bk
    nb = br * br + bb * bb
    na = ar * ar + ab * ab
    if nb == 0.0 or na == 0.0:
        return 0.0
    if abs(ar * bb - ab * br) > SECANT_SINE * math.sqrt(na * nb):
        return 0.0
    t = (ar * br + ab * bb) / nb
    if not (-1.0 < t < 0.0 or 0.0 < t <= SECANT_REACH):
        return 0.0
    return t


@njit(**LEAF)
def _candidate(seeds, i, q, c):
    """The ``c``-th point that may lie on a line with ``i`` and ``q`` (``q = i``: the
    candidates of the pair's first point): the point before ``q`` in the call
    (``c = 0``: along a grid line or a trace in the call's order), then ``q``'s
    candidate seeds (row ``q`` of ``seeds``, nearest first, given points among
    them), then ``i``'s; for a given ``q`` the point before ``i`` and ``i``'s
    candidates. -1 where none, ``PAST_END`` past the end."""
    m = seeds.shape[1]
    row = q if q >= 0 else i
    if c == 0:
        return row - 1 if row >= 1 else -1
    if c <= m:
        return seeds[row, c - 1]
    if q != i and q >= 0 and c <= 2 * m:
        return seeds[i, c - 1 - m]
    return PAST_END


@njit(cache=True)
def secant_seed(r, beta, i, nth, seeds, seedable, final, given, scene, settings, pred, between):
    """The ``nth`` (0, 1, ...) secant prediction of point ``i``'s orbit (into ``pred``).

    The pairs ``(j, k)`` are taken in order: ``j`` each point that may lie on a
    line with ``i`` (:func:`_candidate`: the point before it in the call, then its
    candidate seeds of :func:`tasks.seeds.warm_seeds`) that is a solved moving
    period-1 orbit (:func:`_solved`), ``k`` the first such point for ``j`` on the
    line through ``i`` and ``j`` (:func:`_along`). Where ``k``'s section differs
    from ``j``'s, ``k``'s orbit is carried to ``j``'s section (a part of a period
    of ``k``'s own motion); the state there must lie in the same kind of phase
    (stuck or sliding) as ``j``'s. With ``between`` only interpolations count
    (``i`` between ``j`` and ``k``: ``t < 0``, error of order ``h^2`` where the
    copied seed's is of order ``h``; :func:`tasks.kernel.batch.run_points_given`
    tries the first of them before any copied seed).

    Returns True where ``pred`` holds a prediction (phase and section of ``j``).
    """
    n = (final.shape[1] - 2) // 2
    found = 0
    ri, bi = r[i], beta[i]
    for a in range(seeds.shape[1] + 1):
        j = _candidate(seeds, i, i, a)
        if not _solved(j, i, seedable, given):
            continue
        rj, bj = _where(j, r, beta, given, n)
        for c in range(2 * seeds.shape[1] + 1):
            k = _candidate(seeds, i, j, c)
            if k == PAST_END:
                break
            if k == j or not _solved(k, i, seedable, given):
                continue
            rk, bk = _where(k, r, beta, given, n)
            t = _along(ri, bi, rj, bj, rk, bk)
            if t == 0.0 or (between and t > 0.0):
                continue
            if found < nth:
                found += 1
                break
            Xj = final[j] if j >= 0 else given[-2 - j, : 2 * n + 2]
            Xk = final[k] if k >= 0 else given[-2 - k, : 2 * n + 2]
            return _predict(rk, bk, Xj, Xk, t, scene, settings, pred)
    return False


@njit(cache=True)
def _predict(rk, bk, Xj, Xk, t, scene, settings, pred):
    """``pred = X_j + t (X_j - X_k)`` at ``j``'s section (:func:`secant_seed`); ``Xj``,
    ``Xk``: ``final`` rows, ``(rk, bk)`` the point of ``Xk``."""
    n = (Xj.shape[0] - 2) // 2
    mode_j = int(Xj[2 * n])
    theta = Xj[2 * n + 1]
    Xs = Xk[: 2 * n].copy()
    theta_k = Xk[2 * n + 1]
    mode_k = int(Xk[2 * n])
    if theta_k != theta:
        # k's orbit carried from its section to j's (its own motion: its context)
        ctx, work, _, _, _ = _context(rk, bk, scene, settings)
        target = theta if theta > theta_k else theta + TWO_PI
        stats = np.zeros(N_STATS)
        Xs, mode_k, _ = _advance(Xs, mode_k, theta_k, stats, ctx, work, theta_k, target)
        if stats[ST_STATUS] != STATUS_OK:
            return False
    if (mode_k == 0) != (mode_j == 0):
        return False
    for q in range(2 * n):
        pred[q] = Xj[q] + t * (Xj[q] - Xs[q])
    pred[2 * n] = mode_j
    pred[2 * n + 1] = theta
    return True
