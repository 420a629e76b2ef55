"""Recorded stretches of motion: events of several cycles, and exact states between them.

Used by :mod:`tasks.trajectory` and by the design pass (:mod:`tasks.kernel.design`).
"""

from __future__ import annotations

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
    ETAD_OFF,
    N_STATS,
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


@njit(cache=True)
def sample_states(ctx, work, rec, taus):
    """States ``(x, x')`` at the absolute times ``taus`` (ascending) from the records.

    Each phase's recorded start is projected onto its modal coordinates once, for
    all the times that fall in it (the same values as projecting it per time)."""
    n = (rec.shape[1] - REC_X) // 2
    beta = ctx[CTX_BETA]
    out = np.empty((taus.shape[0], 2 * n))
    x = np.empty(n)
    xd = np.empty(n)
    eta, etad, eta_s, etad_s, q, _ = work
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
            for k in range(n):
                x[k] = rec[j, REC_X + k]
                xd[k] = rec[j, REC_X + n + k]
            if mode == 0:
                d0 = start_stick_in(ctx, x, xd, tau0, beta, q)
            else:
                _start_slip(
                    ctx[CTX_SEG_SLIP],
                    ctx[CTX_SC],
                    x,
                    xd,
                    tau0,
                    float(mode),
                    0.0,
                    beta,
                    ctx[CTX_F_R2],
                    ctx[CTX_PHI_T_GAMMA],
                )
        if mode == 0:
            seg = ctx[CTX_SEG_STICK]
            evaluate(seg, ctx[CTX_SC], tau - tau0, eta_s, etad_s)
            _stick_state(
                ctx[CTX_PHI_S], ctx[CTX_T], ctx[CTX_W], d0, eta_s, etad_s, q, x, xd, seg[ETAD_OFF]
            )
        else:
            seg = ctx[CTX_SEG_SLIP]
            evaluate(seg, ctx[CTX_SC], tau - tau0, eta, etad)
            _slip_state(ctx[CTX_PHI], eta, etad, x, xd, seg[ETAD_OFF])
        out[i, :n] = x
        out[i, n:] = xd
    return out
