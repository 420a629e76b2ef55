"""The settling rule of a creep in progress with several contacts (docs/contacts.md 4).

A contact stuck at two sections whose slips in between went one way *drifts*: no
periodic orbit does that (its slips sum to zero over a period), so such a cycle is
no steady state. A set H of contacts *creeps* when, for ``CREEP_WINDOW`` consecutive
cycles, every contact of H is stuck at the section, slips less than ``CREEP_SLIP_RTOL
beta_c c_c`` per cycle, one way, and drifted in the last cycle (:func:`update`). Two
cases:

* every contact with friction creeps, all stuck: the single-contact rule per contact
  (:func:`tasks.kernel.creep.creep_settled`: most cycles of the window without an
  event, or every contact drifting one way through it, and the stuck section's force
  bound at most ``(1 + CREEP_FORCE_RTOL) beta_c`` for every contact;
  :func:`all_stuck_settled`; measured at a shifted section where every contact is
  stuck when one slides at ``tau = 2 pi n``: :mod:`tasks.multicontact.shifted`);
* others move: the motion is continued with H held (:func:`held_context`) to its
  periodic orbit; H reaches no motion when each held contact's force swings by at
  most ``2 (1 - CREEP_FORCE_RTOL) beta_c`` over that period (:func:`swing_certified`):
  that orbit shifted by a static load at H is a motion holding H with a margin, and
  the energy of the difference bounds the slip of H for ever.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from tasks.kernel.events import stick_force_bound
from tasks.kernel.layout import N_ROWS, N_SCALARS, TWO_PI
from tasks.kernel.propagation import evaluate
from tasks.multicontact.cycle import run_cycle, start_phase
from tasks.multicontact.layout import (
    CS_DMAX,
    CS_DMIN,
    CS_SLIP,
    CX_ACTIVE,
    CX_B,
    CX_BETAS,
    CX_BX,
    CX_COMPLIANCE,
    CX_GINV,
    CX_MAX_EVENTS,
    CX_OMEGA,
    CX_R2,
    CX_SIZE,
    GS_STATUS,
    N_CST,
    N_GST,
)
from tasks.regimes import CREEP_FORCE_RTOL, CREEP_SLIP_RTOL, CREEP_WINDOW, SLIP_RTOL

#: Friction limit of a held contact, relative to its own (it never unsticks).
HELD_SCALE = 1e12
#: Samples of a phase for the force swing of a held contact (its relative error on
#: a harmonic is about (pi / 64)^2 / 2 = 1.2e-3 of a phase-long half-wave, below
#: ``CREEP_FORCE_RTOL`` of the swing on the phases of a period).
SWING_SAMPLES = 256


@njit(cache=True)
def creep_compliance(ctx, c):
    """The compliance contact ``c`` sees at the excitation frequency, for the creep
    threshold (as :func:`tasks.kernel.creep.creep_threshold`, docs/contacts.md 4): in
    the modes of the structure with no contact stuck (set 0),
    ``sum_a (b_c . psi_a)^2 / max(lambda_a, r^2)``; a damped scene takes
    ``min(b_c^T K^-1 b_c, b_c^T G^-1 b_c / r^2)`` (its set 0 may have no real modes).
    The static ``b_c^T K^-1 b_c`` alone overstates it by ``r^2 / lambda`` above the
    natural frequencies."""
    B = ctx[CX_B]
    k = B.shape[1]
    comp = ctx[CX_COMPLIANCE]
    r2 = ctx[CX_R2]
    if comp.shape[0] == k:
        BX = ctx[CX_BX]
        om = ctx[CX_OMEGA]
        acc = 0.0
        for a in range(ctx[CX_SIZE][0]):
            acc += BX[0, c, a] * BX[0, c, a] / (r2 * max(om[0, a] * om[0, a], 1.0))
        return min(acc, comp[c])
    Ginv = ctx[CX_GINV]
    n = B.shape[0]
    inertial = 0.0
    for i in range(n):
        for j in range(n):
            inertial += B[i, c] * Ginv[i, j] * B[j, c]
    return min(comp[c], inertial / r2)


@njit(cache=True)
def update(X_old, X_new, stuck, tot, ctx, runs, drift, refused):
    """Count, per contact, the consecutive creeping cycles ending at ``X_new``.

    A contact stuck at both sections whose slips in the cycle went one way only
    (``|b_c . (x_new - x_old)|`` equals its slip distance, 1e-3 relative) and half of
    whose slip reaches the creep threshold ``SLIP_RTOL beta_c c_c`` (``c_c``:
    :func:`creep_compliance`) *drifts*:
    ``runs[c, 2]`` is the drift's sign (else 0); the cycle is no steady state,
    whatever the section's tolerance. A cycle *creeps* for c when c is stuck at its
    end, its slip amplitude (half the range of ``b_c . x``) is below
    ``CREEP_SLIP_RTOL beta_c c_c`` and its slips, if any, went one way, that of the
    run so far (``drift[c]``); ``runs[c, 0]`` counts those cycles, ``runs[c, 1]``
    the ones that slipped. Returns the contacts that crept for ``CREEP_WINDOW``
    cycles and drifted in the last one (a creep in progress), except ``refused``."""
    B = ctx[CX_B]
    betas = ctx[CX_BETAS]
    active = ctx[CX_ACTIVE]
    n = B.shape[0]
    held = 0
    for c in range(B.shape[1]):
        runs[c, 2] = 0
        if not (active >> c) & 1:
            continue
        comp_c = creep_compliance(ctx, c)
        amp = 0.5 * (tot[c, CS_DMAX] - tot[c, CS_DMIN])
        slip = tot[c, CS_SLIP]
        dd = 0.0
        for i in range(n):
            dd += B[i, c] * (X_new[i] - X_old[i])
        one_way = abs(dd) >= (1.0 - 1e-3) * slip
        sign = 0.0
        if slip > 0.0:
            sign = 1.0 if dd > 0.0 else -1.0
        at_rest = (stuck >> c) & 1
        if at_rest and one_way and 0.5 * slip >= SLIP_RTOL * betas[c] * comp_c:
            runs[c, 2] = 1 if dd > 0.0 else -1
        ok = (
            at_rest
            and amp < CREEP_SLIP_RTOL * betas[c] * comp_c
            and one_way
            and sign * drift[c] >= 0.0
        )
        if ok:
            runs[c, 0] += 1
            if slip > 0.0:
                runs[c, 1] += 1
                drift[c] = sign
        else:
            runs[c, 0] = 0
            runs[c, 1] = 0
            drift[c] = 0.0
        if ok and runs[c, 0] >= CREEP_WINDOW and runs[c, 2] != 0:
            held |= 1 << c
    return held & ~refused


@njit(cache=True)
def creeping(runs, refused):
    """A contact not ``refused`` slipped in its current creep run (``runs[c, 1]``)."""
    for c in range(runs.shape[0]):
        if runs[c, 1] > 0 and not (refused >> c) & 1:
            return True
    return False


@njit(cache=True)
def all_stuck_settled(X, stuck, signs, ctx, tau):
    """Every contact with friction stuck at the section ``tau`` and its stick force bound
    (:func:`tasks.kernel.events.stick_force_bound`) at most ``(1 + CREEP_FORCE_RTOL)
    beta_c``: the single-contact rule (:func:`tasks.kernel.creep.creep_settled`) for
    each contact of the stuck structure."""
    active = ctx[CX_ACTIVE]
    if stuck != active:
        return False
    n = X.shape[0] // 2
    k = signs.shape[0]
    segs = np.zeros((k, N_ROWS, ctx[CX_SIZE][stuck]))
    scs = np.zeros((k, N_SCALARS))
    d = np.zeros(k)
    eta0 = np.zeros(n)
    etad0 = np.zeros(n)
    zeroed = np.zeros(k, dtype=np.bool_)
    x = X[:n].copy()
    start_phase(x, X[n:].copy(), tau, stuck, signs, zeroed, ctx, segs, scs, d, eta0, etad0)
    betas = ctx[CX_BETAS]
    for c in range(k):
        if (active >> c) & 1:
            bound = stick_force_bound(segs[c], scs[c])
            if not (np.isfinite(bound) and bound <= betas[c] * (1.0 + CREEP_FORCE_RTOL)):
                return False
    return True


assert CX_BETAS == 5 and CX_COMPLIANCE == 22  # the literal indices of held_context


@njit(cache=True)
def held_context(ctx, held):
    """``ctx`` with the contacts of ``held`` given the friction limit ``HELD_SCALE
    beta_c``: they stay stuck, the others run as before."""
    betas = ctx[CX_BETAS].copy()
    for c in range(betas.shape[0]):
        if (held >> c) & 1:
            betas[c] *= HELD_SCALE
    # CX_BETAS == 5 (tasks.multicontact.layout): numba needs literal tuple indices
    return (
        ctx[0], ctx[1], ctx[2], ctx[3], ctx[4], betas, ctx[6], ctx[7], ctx[8], ctx[9],
        ctx[10], ctx[11], ctx[12], ctx[13], ctx[14], ctx[15], ctx[16], ctx[17], ctx[18],
        ctx[19], ctx[20], ctx[21], ctx[22],
    )  # fmt: skip


@njit(cache=True)
def swing_certified(X, stuck, signs, ctx, held, betas, period, max_work):
    """Over ``period`` cycles from the section (``ctx`` holding ``held``), the force
    of every held contact c stays in a band of width at most ``2 (1 -
    CREEP_FORCE_RTOL) beta_c`` (``betas``: the contacts' own limits), sampled at
    ``SWING_SAMPLES`` points of every phase (docs/contacts.md 4)."""
    n = X.shape[0] // 2
    k = signs.shape[0]
    rows = int(min(4.0 * ctx[CX_MAX_EVENTS] * period + 2.0, 1e6))
    rec = np.zeros((rows, 2 + k + 2 * n))
    rec_n = np.zeros(1, dtype=np.int64)
    cst = np.zeros((k, N_CST))
    gst = np.zeros(N_GST)
    x = X[:n].copy()
    xd = X[n:].copy()
    s = signs.copy()
    st = stuck
    for _ in range(period):
        st = run_cycle(x, xd, st, s, cst, gst, ctx, 0.0, TWO_PI, max_work, False, rec, rec_n)
        if gst[GS_STATUS] != 0.0:
            return False
    count = rec_n[0]
    if count >= rows:
        return False
    gmin = np.full(k, np.inf)
    gmax = np.full(k, -np.inf)
    scs = np.zeros((k, N_SCALARS))
    d = np.zeros(k)
    eta0 = np.zeros(n)
    etad0 = np.zeros(n)
    eta = np.zeros(n)
    etad = np.zeros(n)
    zeroed = np.zeros(k, dtype=np.bool_)
    for j in range(count - 1):
        tau = rec[j, 0]
        t = rec[j + 1, 0] - tau  # <= 0 from a cycle's end row to the next start
        S = int(rec[j, 1])
        if t <= 0.0 or (S & held) == 0:
            continue
        segs = np.zeros((k, N_ROWS, ctx[CX_SIZE][S]))
        sg = rec[j, 2 : 2 + k].copy()
        xs = rec[j, 2 + k : 2 + k + n].copy()
        xds = rec[j, 2 + k + n :].copy()
        start_phase(xs, xds, tau, S, sg, zeroed, ctx, segs, scs, d, eta0, etad0)
        for c in range(k):
            if not (held >> c) & 1 or not (S >> c) & 1:
                continue
            for i in range(SWING_SAMPLES + 1):
                y, _ = evaluate(segs[c], scs[c], t * i / SWING_SAMPLES, eta, etad)
                gmin[c] = min(gmin[c], y)
                gmax[c] = max(gmax[c], y)
    for c in range(k):
        if (held >> c) & 1:
            if not gmax[c] - gmin[c] <= 2.0 * (1.0 - CREEP_FORCE_RTOL) * betas[c]:
                return False
    return True
