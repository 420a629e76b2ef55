"""Steady states by Newton's method on the Poincare map (shooting).

Slow continuous transients (a Floquet multiplier near 1) are settled by
solving ``P(X) - X = 0`` for the section state ``X = (x, x')``: :func:`_shoot`
(difference Jacobian, then Broyden updates) and, for points where that
fails, :func:`newton_settle` (a fresh Jacobian every step) from one or more
sections of the period (:func:`settle_at_phases`). A fixed point is accepted
only if its residual is small and it is not unstable: shooting must find the
attractor the point's own trajectory reaches, not any periodic orbit.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.kernel.cycle import _advance, _cycle, _max_abs
from tasks.kernel.layout import (
    CTX_B,
    CTX_BETA,
    CTX_P,
    CTX_PROJ,
    CTX_T,
    CTX_W,
    N_STATS,
    ST_FOREVER,
    ST_STATUS,
    STATUS_OK,
    TWO_PI,
)
from tasks.kernel.phases import _dot
from tasks.kernel.starts import start_phase

# Sections a slow point's Newton settle tries (:func:`settle_at_phases`).
SETTLE_PHASES = 4
SETTLE_CYCLES = 150


@njit(cache=True)
def _reduce(X, mode, b, w, proj):
    """Coordinates of the section state in its phase: ``(x, x')`` while sliding,
    ``(d0, q, q')`` while stuck (the contact frozen: ``x = T q + d0 w``, ``x' = T q'``)."""
    if mode != 0:
        return X.copy()
    n = X.shape[0] // 2
    m = proj.shape[0]
    y = np.empty(2 * m + 1)
    d0 = _dot(b, X[:n])
    y[0] = d0
    for i in range(m):
        acc = 0.0
        accd = 0.0
        for j in range(n):
            acc += proj[i, j] * (X[j] - d0 * w[j])
            accd += proj[i, j] * X[n + j]
        y[1 + i] = acc
        y[1 + m + i] = accd
    return y


@njit(cache=True)
def _expand(y, mode, n, w, T):
    """Inverse of :func:`_reduce`."""
    if mode != 0:
        return y.copy()
    m = T.shape[1]
    X = np.zeros(2 * n)
    for j in range(n):
        acc = y[0] * w[j]
        accd = 0.0
        for i in range(m):
            acc += T[j, i] * y[1 + i]
            accd += T[j, i] * y[1 + m + i]
        X[j] = acc
        X[n + j] = accd
    return X


@njit(cache=True)
def _phase_of(X, mode, b):
    """Phase a section state starts in: stuck stays stuck; a sliding state slides
    with the sign of its contact velocity (the flow is continuous across a
    reversal, so both signs belong to one chart)."""
    if mode == 0:
        return 0
    n = X.shape[0] // 2
    v = _dot(b, X[n:])
    if v > 0.0:
        return 1
    if v < 0.0:
        return -1
    return mode


@njit(cache=True)
def _same_chart(mode_a, mode_b):
    return (mode_a == 0) == (mode_b == 0)


@njit(cache=True)
def _fd_jacobian(y0, y1, mode, ctx, work, scale, J, theta):
    """``J = dP/dy - I`` by forward differences (one period per column).

    Returns the periods used, or -1 if a perturbed period left the chart.
    """
    n = ctx[CTX_P].shape[0]
    b = ctx[CTX_B]
    w = ctx[CTX_W]
    T = ctx[CTX_T]
    proj = ctx[CTX_PROJ]
    dim = y0.shape[0]
    probe = np.empty(N_STATS)
    for k in range(dim):
        hk = 1e-7 * max(abs(y0[k]), 1e-3 * scale)
        yp = y0.copy()
        yp[k] += hk
        Xp = _expand(yp, mode, n, w, T)
        Pk, mk, _ = _cycle(Xp, _phase_of(Xp, mode, b), theta, probe, ctx, work, theta)
        if not _same_chart(mk, mode) or probe[ST_STATUS] != STATUS_OK:
            return -1
        yk = _reduce(Pk, mode, b, w, proj)
        for i in range(dim):
            J[i, k] = (yk[i] - y1[i]) / hk
        J[k, k] -= 1.0
    return dim


@njit(cache=True)
def _shoot(X0, mode, stats, ctx, work, rtol, floor, max_newton, theta):
    """Newton's method on the Poincare map ``P(X) - X = 0`` (shooting).

    Works in the coordinates of the phase the section falls in
    (:func:`_reduce`); the section must fall in the same kind of phase (stuck
    or sliding) before and after the period. The Jacobian is built once by
    forward differences (one period per column) and then updated by Broyden's
    rank-one formula (one period per iteration). A fixed point is accepted only
    if its residual is below ``rtol`` of the motion (or of ``floor``, the static
    response) and it is not unstable (spectral radius of ``dP/dy`` at most
    1 + 1e-6): shooting must find the attractor, not any periodic orbit.

    Returns ``(success, X, cycles_used)``; on success ``stats`` holds the
    statistics of the verified period ``X -> P(X)``.
    """
    n = X0.shape[0] // 2
    b = ctx[CTX_B]
    w = ctx[CTX_W]
    T = ctx[CTX_T]
    proj = ctx[CTX_PROJ]
    cycles = 0
    y0 = _reduce(X0, mode, b, w, proj)
    X0 = _expand(y0, mode, n, w, T)
    X1, m1, _ = _cycle(X0, _phase_of(X0, mode, b), theta, stats, ctx, work, theta)
    cycles += 1
    if not _same_chart(m1, mode) or stats[ST_STATUS] != STATUS_OK or stats[ST_FOREVER] > 0.0:
        return False, X0, cycles
    y1 = _reduce(X1, mode, b, w, proj)
    dim = y0.shape[0]
    J = np.empty((dim, dim))
    scale = max(_max_abs(X1), 1e-300)
    used = _fd_jacobian(y0, y1, mode, ctx, work, scale, J, theta)
    if used < 0:
        return False, X0, cycles + dim
    cycles += used
    if not np.all(np.isfinite(J)):
        return False, X0, cycles
    fresh = True
    for _ in range(max_newton):
        R = y1 - y0
        scale = max(_max_abs(X1), 1e-300)
        res = _max_abs(R)
        if res <= rtol * max(scale, floor):
            dP = J.copy()
            for i in range(dim):
                dP[i, i] += 1.0
            radius = np.max(np.abs(np.linalg.eigvals(dP.astype(np.complex128))))
            return radius <= 1.0 + 1e-6, X0, cycles
        try:
            step = np.linalg.solve(J, -R)
        except Exception:  # singular: no isolated fixed point (e.g. resonance)
            return False, X0, cycles
        # trust region: a fixed point far beyond the current motion is not a
        # settled transient but a (near-)singular map, e.g. resonant growth
        if not np.all(np.isfinite(step)) or _max_abs(step) > 10.0 * scale:
            return False, X0, cycles
        lam = 1.0
        accepted = False
        for _ls in range(5):
            yn = y0 + lam * step
            Xn = _expand(yn, mode, n, w, T)
            X1n, mn, _ = _cycle(Xn, _phase_of(Xn, mode, b), theta, stats, ctx, work, theta)
            cycles += 1
            if _same_chart(mn, mode) and stats[ST_STATUS] == STATUS_OK and stats[ST_FOREVER] == 0.0:
                y1n = _reduce(X1n, mode, b, w, proj)
                Rn = y1n - yn
                if _max_abs(Rn) < res:
                    # Broyden: J += ((Rn - R) - J s) s^T / (s . s), s = yn - y0
                    sv = yn - y0
                    ss = _dot(sv, sv)
                    if ss > 0.0:
                        u = (Rn - R) - J @ sv
                        for i in range(dim):
                            for k in range(dim):
                                J[i, k] += u[i] * sv[k] / ss
                    y0 = yn
                    y1 = y1n
                    X0 = Xn
                    X1 = X1n
                    accepted = True
                    fresh = False
                    break
            lam *= 0.5
        if not accepted:
            if fresh:
                return False, X0, cycles
            # the updated Jacobian went stale: rebuild it once here
            used = _fd_jacobian(y0, y1, mode, ctx, work, scale, J, theta)
            if used < 0:
                return False, X0, cycles + dim
            cycles += used
            fresh = True
    return False, X0, cycles


@njit(cache=True)
def newton_settle(X0, mode, stats, ctx, work, rtol, floor, max_iter, theta):
    """Newton's method on the Poincare map with a fresh Jacobian at every step.

    The fallback for slow points (a Floquet multiplier near 1, e.g. next to an
    antiresonance, where the held system is nearly resonant and the free mode
    beats with the excitation over thousands of periods), where the
    Broyden-updated shooting of :func:`_shoot` fails its line search. Works in
    the chart of ``mode`` (:func:`_reduce`); an iterate may leave the chart for a
    step (its image is projected back), but the fixed point must lie in it. A
    fixed point is accepted only if its residual is below ``rtol`` of the motion
    (or of ``floor``) and it is not unstable (spectral radius of the Jacobian at
    the fixed point at most 1 + 1e-6), so it is an attractor, reached from the
    point's own trajectory. Costs ``dim + 1`` periods per step.

    Returns ``(success, X, cycles_used)``; on success ``stats`` holds the
    statistics of the verified period ``X -> P(X)``.
    """
    n = X0.shape[0] // 2
    b = ctx[CTX_B]
    w = ctx[CTX_W]
    T = ctx[CTX_T]
    proj = ctx[CTX_PROJ]
    y = _reduce(X0, mode, b, w, proj)
    dim = y.shape[0]
    J = np.empty((dim, dim))
    cycles = 0
    for _ in range(max_iter):
        X = _expand(y, mode, n, w, T)
        P, m1, _s = _cycle(X, _phase_of(X, mode, b), theta, stats, ctx, work, theta)
        cycles += 1
        if stats[ST_STATUS] != STATUS_OK or stats[ST_FOREVER] > 0.0:
            return False, X, cycles
        y1 = _reduce(P, mode, b, w, proj)
        R = y1 - y
        scale = max(_max_abs(P), 1e-300)
        used = _fd_jacobian(y, y1, mode, ctx, work, scale, J, theta)
        if used < 0 or not np.all(np.isfinite(J)):
            return False, X, cycles + dim
        cycles += used
        if _max_abs(R) <= rtol * max(scale, floor) and _same_chart(m1, mode):
            dP = J.copy()
            for i in range(dim):
                dP[i, i] += 1.0
            radius = np.max(np.abs(np.linalg.eigvals(dP.astype(np.complex128))))
            if radius > 1.0 + 1e-6:
                return False, X, cycles
            _cycle(X, _phase_of(X, mode, b), theta, stats, ctx, work, theta)
            return True, X, cycles + 1
        try:
            step = np.linalg.solve(J, -R)
        except Exception:  # singular: no isolated fixed point
            return False, X, cycles
        if not np.all(np.isfinite(step)) or _max_abs(step) > 100.0 * max(scale, floor):
            return False, X, cycles
        y = y + step
    return False, _expand(y, mode, n, w, T), cycles


@njit(cache=True)
def settle_at_phases(X, mode, stick_start, stats, ctx, work, rtol, floor, theta, n_phases):
    """:func:`newton_settle` from the section at ``theta`` (up to 30 steps), then
    from ``n_phases - 1`` sections moved by ``1 / n_phases`` of the period each
    (about ``SETTLE_CYCLES`` periods each, i.e. 30 Newton steps for 2 DOF and 13
    for 5 DOF). Used with one phase for the slow-point settles of the iteration
    and with ``SETTLE_PHASES`` as the last resort when ``max_cycles`` is spent.

    The Poincare map of a slow point can be smooth at one phase and cut by an
    event (a stop or a reversal that moves with the iterate) at another, where
    Newton's method with difference Jacobians stalls. The trajectory is carried
    to each new section (one part of a period); the fixed point is accepted with
    the same conditions (residual, not unstable) at whichever section finds it.

    Returns ``(success, X, mode, theta, cycles_used)``: the fixed point, its phase
    and its section; on success ``stats`` holds the statistics of the verified
    period.
    """
    used_total = 0
    Xa = X
    mode_a = mode
    start_a = stick_start
    theta_a = theta
    for j in range(n_phases):
        if j > 0:
            target = theta_a + TWO_PI / n_phases
            Xa, mode_a, start_a = _advance(Xa, mode_a, start_a, stats, ctx, work, theta_a, target)
            if stats[ST_STATUS] != STATUS_OK:
                break
            theta_a = target - TWO_PI * math.floor(target / TWO_PI)
            start_a -= target - theta_a
        # the extra sections get about SETTLE_CYCLES periods each (dim + 1 per step)
        steps = 30 if j == 0 else max(4, SETTLE_CYCLES // (X.shape[0] + 1))
        ok, Xs, used = newton_settle(Xa, mode_a, stats, ctx, work, rtol, floor, steps, theta_a)
        used_total += used
        if ok:
            mode_s = start_phase(Xs, ctx[CTX_BETA], ctx, theta_a) if mode_a != 0 else 0
            return True, Xs, mode_s, theta_a, used_total
    return False, X, mode, theta, used_total
