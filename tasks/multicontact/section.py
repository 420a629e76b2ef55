"""The Poincare section ``tau = 2 pi n`` of a point with several contacts
(docs/contacts.md 4): cycles run from it, Newton's method on its map for slow
transients, and the polish of a converged section state."""

from __future__ import annotations

import numpy as np
from numba import njit

from tasks.kernel.layout import TWO_PI
from tasks.multicontact.cycle import run_cycle
from tasks.multicontact.layout import (
    CS_DMAX,
    CS_DMIN,
    CS_FORCE_MAX,
    CS_ORBIT_ERROR,
    CS_STICK_START,
    CS_VEL_ERROR,
    CX_ACTIVE,
    CX_B,
    GS_STATUS,
    GS_VISCOUS,
    N_CST,
    N_GST,
)

#: Newton iterations per shooting attempt, and cycles between attempts.
NEWTON_ITERATIONS = 8
SHOOT_EVERY = 20
#: The polish of a converged section (:func:`polish`): residual sought (relative to
#: the section state), difference step of its Jacobian, chord steps at most.
POLISH_RTOL = 1e-14
POLISH_STEP = 1e-7
POLISH_STEPS = 4


@njit(cache=True)
def run_period(X, stuck, signs, cst, gst, ctx, n_cycles, max_work, check):
    """Run ``n_cycles`` cycles from the section; returns the new state, set and
    the per-contact statistics summed (ranges merged) over them."""
    n = X.shape[0] // 2
    k = signs.shape[0]
    x = X[:n].copy()
    xd = X[n:].copy()
    total = np.zeros((k, N_CST))
    rec_n = np.zeros(1, dtype=np.int64)
    buf = np.zeros((0, 2 + k + 2 * n))
    viscous = 0.0
    for cyc in range(n_cycles):
        stuck = run_cycle(
            x, xd, stuck, signs, cst, gst, ctx, 0.0, TWO_PI, max_work, check, buf, rec_n
        )
        viscous += gst[GS_VISCOUS]
        gst[GS_VISCOUS] = viscous
        for c in range(k):
            cst[c, CS_STICK_START] -= TWO_PI
            for j in range(N_CST):
                if cyc == 0:
                    total[c, j] = cst[c, j]
                elif j == CS_DMIN:
                    total[c, j] = min(total[c, j], cst[c, j])
                elif j == CS_DMAX or j == CS_FORCE_MAX or j == CS_ORBIT_ERROR or j == CS_VEL_ERROR:
                    total[c, j] = max(total[c, j], cst[c, j])
                elif j != CS_STICK_START:
                    total[c, j] += cst[c, j]
        if gst[GS_STATUS] != 0.0:
            break
    out = np.empty(2 * n)
    out[:n] = x
    out[n:] = xd
    return out, stuck, total


@njit(cache=True)
def max_abs(v):
    acc = 0.0
    for i in range(v.shape[0]):
        acc = max(acc, abs(v[i]))
    return acc


@njit(cache=True)
def _signs_hold(X, stuck, signs, ctx):
    """Every sliding contact at the section moves in its slip direction (or has
    zero velocity to rounding): a section state the map ``P`` is defined at."""
    B = ctx[CX_B]
    n = X.shape[0] // 2
    vmax = 1e-300
    for i in range(n):
        vmax = max(vmax, abs(X[n + i]))
    for c in range(signs.shape[0]):
        if (ctx[CX_ACTIVE] >> c) & 1 and not (stuck >> c) & 1:
            v = 0.0
            for i in range(n):
                v += B[i, c] * X[n + i]
            if signs[c] * v < -1e-9 * vmax:
                return False
    return True


@njit(cache=True)
def newton(X, stuck, signs, cst, gst, ctx, max_work, tol):
    """Newton's method on the Poincare map ``P(X) - X = 0`` (finite-difference
    Jacobian, the section's stuck set and signs kept). A fixed point is accepted
    only where the section's slip signs hold and it attracts (spectral radius of
    ``dP/dX`` at most 1 + 1e-6, as for one contact). Returns ``(X, cycles, ok)``."""
    n2 = X.shape[0]
    cycles = 0
    J = np.zeros((n2, n2))
    have_j = False
    for _ in range(NEWTON_ITERATIONS):
        if not _signs_hold(X, stuck, signs, ctx):
            return X, cycles, False
        s0 = signs.copy()
        P0, _, _ = run_period(X, stuck, s0, cst, gst, ctx, 1, max_work, False)
        cycles += 1
        if gst[GS_STATUS] != 0.0:
            return X, cycles, False
        F0 = P0 - X
        scale = max(max_abs(X), 1e-300)
        if max_abs(F0) <= tol * scale:
            if not have_j:
                return X, cycles, True
            A = J.astype(np.complex128)
            for i in range(n2):
                A[i, i] += 1.0
            rho = np.max(np.abs(np.linalg.eigvals(A)))
            return X, cycles, rho <= 1.0 + 1e-6
        h = 1e-7 * scale
        for i in range(n2):
            Xp = X.copy()
            Xp[i] += h
            s1 = signs.copy()
            Pi, _, _ = run_period(Xp, stuck, s1, cst, gst, ctx, 1, max_work, False)
            cycles += 1
            if gst[GS_STATUS] != 0.0:
                return X, cycles, False
            for j in range(n2):
                J[j, i] = (Pi[j] - P0[j]) / h
            J[i, i] -= 1.0
        have_j = True
        # least squares: a stuck coordinate's displacement is carried over
        # unchanged (a zero column of J - I), the step leaves it alone
        dX = np.linalg.lstsq(J, -F0)[0]
        if not np.all(np.isfinite(dX)):
            return X, cycles, False
        X = X + dX
    return X, cycles, False


@njit(cache=True)
def map_period(X, stuck, signs, ctx, period, max_work):
    """``(P^period(X), same)``: ``same`` when the period ran without a fault and
    ended in the section's stuck set and slip signs (the branch of the map)."""
    k = signs.shape[0]
    cst = np.zeros((k, N_CST))
    gst = np.zeros(N_GST)
    s = signs.copy()
    PX, st, _ = run_period(X, stuck, s, cst, gst, ctx, period, max_work, False)
    same = gst[GS_STATUS] == 0.0 and st == stuck and np.all(s == signs)
    return PX, same


@njit(cache=True)
def polish(X, stuck, signs, ctx, period, max_work):
    """The fixed point of ``P^period`` next to a converged section state ``X``,
    to ``POLISH_RTOL`` (docs/contacts.md 4).

    The plain iteration stops when two sections agree to ``section_rtol``; the
    fixed point is then that close but no closer (slow points: further). A
    chord Newton step (Jacobian of ``P^period - I`` by forward differences,
    once; least squares, so a contact stuck through the period keeps its
    position) is repeated while it shrinks the residual, at most
    ``POLISH_STEPS`` times. The section's stuck set and signs must hold for
    every evaluation; else (or if nothing shrinks) ``X`` is returned as it came.
    """
    n2 = X.shape[0]
    P0, same = map_period(X, stuck, signs, ctx, period, max_work)
    if not same:
        return X
    F = P0 - X
    scale = max(max_abs(X), 1e-300)
    res = max_abs(F)
    if res <= POLISH_RTOL * scale:
        return X
    J = np.zeros((n2, n2))
    h = POLISH_STEP * scale
    for i in range(n2):
        Xp = X.copy()
        Xp[i] += h
        Pi, same = map_period(Xp, stuck, signs, ctx, period, max_work)
        if not same:
            return X
        for j in range(n2):
            J[j, i] = (Pi[j] - P0[j]) / h
        J[i, i] -= 1.0
    best = X
    for _ in range(POLISH_STEPS):
        dX = np.linalg.lstsq(J, -F)[0]
        if not np.all(np.isfinite(dX)):
            break
        Xn = best + dX
        Pn, same = map_period(Xn, stuck, signs, ctx, period, max_work)
        if not same:
            break
        Fn = Pn - Xn
        rn = max_abs(Fn)
        if rn >= res:
            break
        best = Xn
        F = Fn
        res = rn
        if res <= POLISH_RTOL * scale:
            break
    return best
