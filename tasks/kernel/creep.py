"""The creep rule: slips too small to be motion, and no motion reached asymptotically.

A stick-slip orbit whose slip amplitude is below :func:`creep_threshold` is
no motion (``SLIP_RTOL`` of :mod:`tasks.regimes`, docs/theory.md 3, creep); a
stuck section from which the contact force can exceed beta only marginally
(:func:`creep_settled`) ends a creep towards the stuck set.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.kernel.events import stick_force_bound
from tasks.kernel.layout import (
    COMPLIANCE,
    CTX_B,
    CTX_BETA,
    CTX_K,
    CTX_PHI,
    CTX_SC,
    CTX_SEG_SLIP,
    CTX_SEG_STICK,
    OMEGA,
    OUT_AMP,
    OUT_ASYMPTOTIC,
    OUT_CONVERGED,
    OUT_CYCLES,
    OUT_IC,
    OUT_PERIOD,
    OUT_REGIME,
    OUT_STICK,
    OUT_STOPS,
    ST_DMAX,
    ST_DMIN,
    ST_STUCK_TIME,
    TWO_PI,
)
from tasks.kernel.linsolve import _solve
from tasks.kernel.phases import _dot, start_stick_in
from tasks.regimes import CREEP_FORCE_RTOL, NO_MOTION, SLIP_RTOL, STICK_SLIP


@njit(cache=True)
def creep_threshold(ctx, beta, r):
    """Slip amplitude below which a slip is not motion: ``SLIP_RTOL * beta * c``.

    ``c`` is the compliance the contact sees at the excitation frequency, so
    ``beta c`` is the deflection the friction force produces at the contact. A
    slip of amplitude ``a`` changes the force at the contact by about ``a / c``;
    below the threshold that is less than ``SLIP_RTOL`` of the friction force,
    i.e. indistinguishable from holding with a friction ratio changed by one part
    in ``1 / SLIP_RTOL`` (docs/theory.md 3, creep). In the modes of the sliding
    system (``lambda_i``, ``psi_i``, Eq. 40), each mode answers with its spring
    below its natural frequency and with its inertia above it::

        c = sum_i (b . psi_i)^2 / max(lambda_i, r^2),

    the static compliance ``b^T K^-1 b`` where every mode is faster than the
    excitation (``r^2 <= lambda_1``), the inertial ``b^T Gamma^-1 b / r^2`` where
    every mode is slower. (The static compliance alone overstates the threshold
    by ``r^2 / lambda`` above the natural frequencies and took genuine stick-slip
    well below the motion bound for no motion.) A structure whose damping is not
    proportional runs on damped pairs, which have no real modes: ``c`` is the same
    sum over the undamped modes of ``(K, Gamma)``, computed once per point
    (:func:`tasks.kernel.context._undamped_scales`, entry ``COMPLIANCE`` of the
    context's scalars). It kept the static compliance, which overstated the threshold
    by up to ``r^2 / lambda`` too: genuine stick-slip 1 % below the motion bound of a
    chain with a dashpot (r = 232, above every mode) was labelled no motion.
    """
    b = ctx[CTX_B]
    phi = ctx[CTX_PHI]
    n = b.shape[0]
    if phi.shape[0] != n:
        return SLIP_RTOL * beta * ctx[CTX_SC][COMPLIANCE]
    static = abs(_dot(b, _solve(ctx[CTX_K], b)))
    r2 = r * r
    seg = ctx[CTX_SEG_SLIP]
    c = 0.0
    for k in range(n):
        bk = 0.0
        for i in range(n):
            bk += b[i] * phi[i, k]
        lam = seg[OMEGA, k] * seg[OMEGA, k] * r2
        c += bk * bk / max(lam, r2)
    return SLIP_RTOL * beta * min(c, static)


@njit(cache=True)
def creep_settled(X, ctx, theta):
    """A stuck section state from which ``|g|`` can exceed beta by at most
    ``CREEP_FORCE_RTOL * beta``: whatever slips remain are driven by a force
    excess of that order, and their amplitude (about excess^2 in units of the
    static deflection, measured near the motion bound) stays below the creep
    threshold; the limit is no motion."""
    n = X.shape[0] // 2
    seg = ctx[CTX_SEG_STICK]
    sc = ctx[CTX_SC]
    beta = ctx[CTX_BETA]
    work = np.zeros(2 * seg.shape[1])
    start_stick_in(ctx, X[:n].copy(), X[n:].copy(), theta, beta, work)
    bound = stick_force_bound(seg, sc)
    return math.isfinite(bound) and bound <= beta * (1.0 + CREEP_FORCE_RTOL)


@njit(cache=True)
def _creep_limit(out, slip_tol):
    """A converged stick-slip orbit whose slip is below the creep threshold is
    no motion (reached asymptotically; the measured slip stays in ``out``). A
    converged orbit stuck for its whole period that was found by iterating or
    shooting (not certified stuck for ever in a cycle of the trajectory) ends a
    creep too: no motion reached asymptotically."""
    if out[OUT_REGIME] == STICK_SLIP and out[OUT_AMP] < slip_tol:
        out[OUT_REGIME] = NO_MOTION
        out[OUT_STOPS] = 0.0
        out[OUT_ASYMPTOTIC] = 1.0
    elif out[OUT_REGIME] == NO_MOTION:
        out[OUT_ASYMPTOTIC] = 1.0


@njit(cache=True)
def _asymptotic_no_motion(out, stats, cycles, ic_used):
    """No motion reached asymptotically (:func:`creep_settled`): the last cycle's
    slip amplitude and stick fraction are kept as diagnostics."""
    out[OUT_REGIME] = NO_MOTION
    out[OUT_CONVERGED] = 1.0
    out[OUT_CYCLES] = cycles
    out[OUT_STOPS] = 0.0
    out[OUT_AMP] = 0.5 * (stats[ST_DMAX] - stats[ST_DMIN])
    out[OUT_STICK] = stats[ST_STUCK_TIME] / TWO_PI
    out[OUT_PERIOD] = 1.0
    out[OUT_IC] = ic_used
    out[OUT_ASYMPTOTIC] = 1.0
