"""Recorded stretches of motion: events of several cycles, and exact states between them.

Used by :mod:`tasks.trajectory` and by the design pass (:mod:`tasks.kernel.design`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.kernel.context import _context
from tasks.kernel.cycle import replay_cycles
from tasks.kernel.layout import (
    CTX_BETA,
    CTX_F_R2,
    CTX_PHI,
    CTX_PHI_S,
    CTX_PHI_T_GAMMA,
    CTX_SC,
    CTX_SEG_SLIP,
    CTX_SEG_STICK,
    CTX_T,
    CTX_W,
    DAMP,
    ETAD_OFF,
    LEAF,
    LOAD_CONST,
    LOAD_COS,
    N_STATS,
    OMEGA,
    REC_MODE,
    REC_TAU,
    REC_X,
    ST_STATUS,
)
from tasks.kernel.phases import _slip_state, _start_slip, _stick_state, start_stick_in
from tasks.kernel.propagation import evaluate


@njit(cache=True)
def trace_cycles(r, beta, scene, settings, X0, mode0, theta, n_cycles, max_records):
    """Simulate ``n_cycles`` periods from ``(X0, mode0)`` at ``tau = theta``, recording events.

    ``mode0`` < -1 means: the held initial condition of :func:`_context` (at
    ``tau = 0``). Times in the records are absolute (``theta + 2 pi k`` starts
    period k). Returns ``(records, n_records, X, mode, status)``.
    """
    ctx, work, Xh, mode_h, ic_used = _context(r, beta, scene, settings)
    if mode0 < -1:
        X = Xh
        mode = mode_h
        theta = 0.0
    else:
        X = X0.copy()
        mode = mode0
    n = X.shape[0] // 2
    rec = np.zeros((max_records, REC_X + 2 * n))
    rec_n = np.zeros(1, dtype=np.int64)
    stats = np.zeros(N_STATS)
    x = X[:n].copy()
    xd = X[n:].copy()
    mode, _ = replay_cycles(x, xd, mode, theta, n_cycles, stats, ctx, work, rec, rec_n)
    status = stats[ST_STATUS]
    out = np.empty(2 * n)
    out[:n] = x
    out[n:] = xd
    return rec, rec_n[0], out, mode, status


@njit(**LEAF)
def phase_start(ctx, work, rec, j, x, xd):
    """Set the phase of record row ``j`` (its modal start in the phase's ``seg`` and
    ``sc``, :mod:`tasks.kernel.phases`) from its recorded state; returns d0 (stick)."""
    n = x.shape[0]
    for k in range(n):
        x[k] = rec[j, REC_X + k]
        xd[k] = rec[j, REC_X + n + k]
    mode = int(rec[j, REC_MODE])
    if mode == 0:
        return start_stick_in(ctx, x, xd, rec[j, REC_TAU], ctx[CTX_BETA], work[4])
    _start_slip(
        ctx[CTX_SEG_SLIP],
        ctx[CTX_SC],
        x,
        xd,
        rec[j, REC_TAU],
        float(mode),
        0.0,
        ctx[CTX_BETA],
        ctx[CTX_F_R2],
        ctx[CTX_PHI_T_GAMMA],
    )
    return 0.0


@njit(**LEAF)
def modal_to_state(stick, d0, eta, etad, x, xd, phi, phi_s, T, w, q, off):
    """``(x, x')`` of a phase's modal state ``(eta, eta')``: a stick phase (contact
    displacement ``d0``; ``phi_s``, ``T``, ``w``, scratch ``q``) or a slip phase
    (``phi``); ``off`` the phase's row ETAD_OFF. With ``d0 = 0`` it maps modal
    accelerations and jerks to physical ones (not for general damping, whose pairs
    carry an offset). The arrays are the context's (:func:`phase_maps`)."""
    if stick:
        _stick_state(phi_s, T, w, d0, eta, etad, q, x, xd, off)
    else:
        _slip_state(phi, eta, etad, x, xd, off)


@njit(cache=True)
def sample_states(ctx, work, rec, taus):
    """States ``(x, x')`` at the absolute times ``taus`` (ascending) from the records.

    Each phase's recorded start is projected onto its modal coordinates once, for
    all the times that fall in it (the same values as projecting it per time)."""
    n = (rec.shape[1] - REC_X) // 2
    return sample_motion(ctx, work, rec, taus, np.empty((0, 2 * n)))


@njit(cache=True)
def sample_motion(ctx, work, rec, taus, derivs):
    """:func:`sample_states`; if ``derivs`` has a row per time, also writes there the
    accelerations and jerks ``(x'', x''')``: modal ``eta'' = a cos tau + c -
    2 sigma eta' - Omega^2 eta`` (Eq. (1) of :mod:`tasks.kernel.propagation`, Eq. 4.1
    damped) and its derivative, mapped as velocities are (not for general damping)."""
    n = (rec.shape[1] - REC_X) // 2
    out = np.empty((taus.shape[0], 2 * n))
    x = np.empty(n)
    xd = np.empty(n)
    eta, etad, eta_s, etad_s, q, _ = work
    with_derivs = derivs.shape[0] == taus.shape[0]
    phi, phi_s, T, w = ctx[CTX_PHI], ctx[CTX_PHI_S], ctx[CTX_T], ctx[CTX_W]
    off_slip = ctx[CTX_SEG_SLIP][ETAD_OFF]
    off_stick = ctx[CTX_SEG_STICK][ETAD_OFF]
    etadd = np.empty(n)
    etaddd = np.empty(n)
    j = 0
    started = -1  # the phase (record row) whose start is set in seg, sc
    d0 = 0.0
    for i in range(taus.shape[0]):
        tau = taus[i]
        while j + 1 < rec.shape[0] - 1 and rec[j + 1, REC_TAU] <= tau:
            j += 1
        tau0 = rec[j, REC_TAU]
        mode = int(rec[j, REC_MODE])
        if j != started:  # a new phase: project its recorded start once
            started = j
            d0 = phase_start(ctx, work, rec, j, x, xd)
        if mode == 0:
            seg = ctx[CTX_SEG_STICK]
            e, ed, off = eta_s, etad_s, off_stick
        else:
            seg = ctx[CTX_SEG_SLIP]
            e, ed, off = eta, etad, off_slip
        evaluate(seg, ctx[CTX_SC], tau - tau0, e, ed)
        modal_to_state(mode == 0, d0, e, ed, x, xd, phi, phi_s, T, w, q, off)
        out[i, :n] = x
        out[i, n:] = xd
        if with_derivs:
            m = e.shape[0]
            ct = math.cos(tau)
            st = math.sin(tau)
            for k in range(m):
                w2 = seg[OMEGA, k] ** 2
                sigma2 = 2.0 * seg[DAMP, k]
                etadd[k] = seg[LOAD_COS, k] * ct + seg[LOAD_CONST, k] - sigma2 * ed[k] - w2 * e[k]
                etaddd[k] = -seg[LOAD_COS, k] * st - sigma2 * etadd[k] - w2 * ed[k]
            modal_to_state(mode == 0, 0.0, etadd[:m], etaddd[:m], x, xd, phi, phi_s, T, w, q, off)
            derivs[i, :n] = x
            derivs[i, n:] = xd
    return out
