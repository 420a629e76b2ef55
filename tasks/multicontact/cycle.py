"""One excitation cycle of a scene with several contacts, event by event.

A phase is a stuck set ``S`` and the slip signs of the other contacts
(docs/contacts.md 2). It is propagated in closed form with the single-contact
kernel's modal solution (:func:`tasks.kernel.propagation.evaluate`): every
contact gets its own *observable* on the same modal state, its force ``g_c``
(stuck, event function ``beta_c - |g_c|``) or its velocity ``b_c . x'``
(sliding with sign ``s_c``, event function ``s_c b_c . x'``), and the first
zero of each is found by the kernel's complete event search
(:func:`tasks.kernel.events.next_event`). The earliest is the next event;
events of other contacts within ``2 event_tol`` of it coincide with it. The
set after the event is decided by :func:`tasks.multicontact.decide.decide`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.kernel.events import DIP_STACK, never_unsticks, next_event
from tasks.kernel.layout import (
    ALPHA,
    BETA,
    COS_TAU0,
    DAMP,
    DAMPED,
    DELTA,
    ETA0,
    ETAD0,
    ETAD_OFF,
    EVALS,
    KIND,
    KIND_SLIP,
    KIND_STICK,
    LOAD_CONST,
    LOAD_COS,
    N_ROWS,
    N_SCALARS,
    OBS0,
    OBS_COS,
    OMEGA,
    SIGN,
    SIN_TAU0,
    TAU0,
    WORK_CAP,
)
from tasks.kernel.phases import STICK_RTOL
from tasks.kernel.propagation import evaluate
from tasks.multicontact import viscous
from tasks.multicontact.decide import decide
from tasks.multicontact.layout import (
    CS_DMAX,
    CS_DMIN,
    CS_FORCE_MAX,
    CS_ORBIT_ERROR,
    CS_REVERSALS,
    CS_SLIP,
    CS_STICK_START,
    CS_STOPS,
    CS_STUCK_TIME,
    CS_VEL_ERROR,
    CX_ACTIVE,
    CX_B,
    CX_BETAS,
    CX_BX,
    CX_COMPLIANCE,
    CX_H,
    CX_HKX,
    CX_HP,
    CX_K,
    CX_LOAD_COS,
    CX_MAX_EVENTS,
    CX_OMEGA,
    CX_R2,
    CX_SIZE,
    CX_STEP,
    CX_STICK_MIN,
    CX_TOL,
    CX_W,
    CX_X,
    CX_XTG,
    GS_EVENTS,
    GS_FOREVER,
    GS_STATUS,
    GS_VISCOUS,
    GS_WORK,
    N_GST,
)
from tasks.regimes import EVENT_LIMIT, NUMERICAL_FAILURE, WORK_LIMIT

#: Points per phase where the final orbit's forces and velocities are checked.
ORBIT_SAMPLES = 16


@njit(cache=True)
def _col_dot(B, c, x):
    acc = 0.0
    for i in range(x.shape[0]):
        acc += B[i, c] * x[i]
    return acc


@njit(cache=True)
def start_phase(x, xd, tau, stuck, signs, zeroed, ctx, segs, scs, d, eta0, etad0):
    """Fill ``segs[c], scs[c]`` for every active contact c: the phase of stuck set
    ``stuck`` with slip signs ``signs`` from the state ``(x, x')`` at ``tau``.

    ``d`` receives the frozen ``b_c . x`` of the stuck contacts; contacts flagged
    in ``zeroed`` start sliding from zero velocity (right after an event)."""
    B = ctx[CX_B]
    K = ctx[CX_K]
    betas = ctx[CX_BETAS]
    active = ctx[CX_ACTIVE]
    m = ctx[CX_SIZE][stuck]
    X = ctx[CX_X][stuck]
    XtG = ctx[CX_XTG][stuck]
    W = ctx[CX_W][stuck]
    H = ctx[CX_H][stuck]
    HKX = ctx[CX_HKX][stuck]
    BX = ctx[CX_BX][stuck]
    r2 = ctx[CX_R2]
    n = x.shape[0]
    k = B.shape[1]
    xr = x.copy()
    for c in range(k):
        if (stuck >> c) & 1:
            d[c] = _col_dot(B, c, x)
            for i in range(n):
                xr[i] -= W[i, c] * d[c]
    # constant physical load: -K W d - sum_sliding beta_c s_c b_c
    fconst = np.zeros(n)
    for i in range(n):
        acc = 0.0
        for c in range(k):
            if (stuck >> c) & 1:
                for j in range(n):
                    acc -= K[i, j] * W[j, c] * d[c]
            elif (active >> c) & 1:
                acc -= betas[c] * signs[c] * B[i, c]
        fconst[i] = acc
    for a in range(m):
        e = 0.0
        ed = 0.0
        lc = 0.0
        for i in range(n):
            e += XtG[a, i] * xr[i]
            ed += XtG[a, i] * xd[i]
            lc += X[i, a] * fconst[i]
        eta0[a] = e
        etad0[a] = ed
        segs[0, LOAD_CONST, a] = lc / r2
    ctau = math.cos(tau)
    stau = math.sin(tau)
    for c in range(k):
        if not (active >> c) & 1:
            continue
        seg = segs[c]
        sc = scs[c]
        for a in range(m):
            seg[OMEGA, a] = ctx[CX_OMEGA][stuck, a]
            seg[ETA0, a] = eta0[a]
            seg[ETAD0, a] = etad0[a]
            seg[LOAD_COS, a] = ctx[CX_LOAD_COS][stuck, a]
            seg[LOAD_CONST, a] = segs[0, LOAD_CONST, a]
        sc[TAU0] = tau
        sc[COS_TAU0] = ctau
        sc[SIN_TAU0] = stau
        if (stuck >> c) & 1:
            g = ctx[CX_HP][stuck, c] * ctau
            for i in range(n):
                g += H[c, i] * fconst[i]
            for a in range(m):
                seg[ALPHA, a] = -HKX[c, a]
                seg[DELTA, a] = 0.0
                g += seg[ALPHA, a] * eta0[a]
            sc[OBS_COS] = ctx[CX_HP][stuck, c]
            sc[OBS0] = g
            sc[KIND] = KIND_STICK
            sc[SIGN] = 0.0
            sc[BETA] = betas[c] * (1.0 + STICK_RTOL)
        else:
            v = 0.0
            for a in range(m):
                seg[ALPHA, a] = 0.0
                seg[DELTA, a] = BX[c, a]
                v += BX[c, a] * etad0[a]
            sc[OBS_COS] = 0.0
            sc[OBS0] = 0.0 if zeroed[c] else v
            sc[KIND] = KIND_SLIP
            sc[SIGN] = signs[c]
            sc[BETA] = betas[c]
    D = ctx[CX_COMPLIANCE]
    if D.shape[0] > k:  # damped (docs/contacts.md 7)
        viscous.damp_phase(D, n, k, stuck, active, m, etad0, segs, scs)
        if viscous.is_general(D, n, k, stuck):  # C couples the set's modes: pairs
            viscous.general_phase(ctx, stuck, zeroed, x, xd, d, fconst, segs, scs, eta0, etad0)
    return m


@njit(cache=True)
def _viscous(ctx, stuck, seg, sc, t, off):
    """The viscous work of a damped phase of length ``t`` (docs/contacts.md 7): modal
    (``X_S^T C X_S`` diagonal) or on the damped pairs."""
    D = ctx[CX_COMPLIANCE]
    n, k = ctx[CX_B].shape
    if viscous.is_general(D, n, k, stuck):
        return viscous.general_work(ctx, stuck, seg, sc, t, off)
    return viscous.viscous_work(seg, sc, t, viscous.cdiag_row(D, n, k, stuck), D[k])


@njit(cache=True)
def _state(ctx, stuck, d, eta, etad, x, xd):
    """``x = X_S eta + W_S d``, ``x' = X_S eta'``."""
    X = ctx[CX_X][stuck]
    W = ctx[CX_W][stuck]
    m = ctx[CX_SIZE][stuck]
    n = x.shape[0]
    k = d.shape[0]
    for i in range(n):
        acc = 0.0
        accd = 0.0
        for a in range(m):
            acc += X[i, a] * eta[a]
            accd += X[i, a] * etad[a]
        for c in range(k):
            if (stuck >> c) & 1:
                acc += W[i, c] * d[c]
        x[i] = acc
        xd[i] = accd


@njit(cache=True)
def _sample_phase(segs, scs, stuck, t, cst, active, eta, etad):
    """Largest |g| of the stuck contacts and the worst orbit error at interior
    points of a phase: ``|g_c| - beta_c`` (stuck) or ``-s_c v_c`` (sliding),
    relative to beta_c (the orbit check, docs/contacts.md 4)."""
    k = cst.shape[0]
    for j in range(1, ORBIT_SAMPLES):
        tj = t * j / ORBIT_SAMPLES
        for c in range(k):
            if not (active >> c) & 1:
                continue
            y, _ = evaluate(segs[c], scs[c], tj, eta, etad)
            if (stuck >> c) & 1:
                if abs(y) > cst[c, CS_FORCE_MAX]:
                    cst[c, CS_FORCE_MAX] = abs(y)
                err = (abs(y) - scs[c][BETA]) / max(scs[c][BETA], 1e-300)
                if err > cst[c, CS_ORBIT_ERROR]:
                    cst[c, CS_ORBIT_ERROR] = err
            else:  # a velocity against the slip sign (velocity units)
                err = -scs[c][SIGN] * y
                if err > cst[c, CS_VEL_ERROR]:
                    cst[c, CS_VEL_ERROR] = err


@njit(cache=True)
def _record(rec, rec_n, tau, stuck, signs, x, xd):
    """Append a phase start ``(tau, stuck, signs..., x..., x'...)`` to ``rec`` (if room)."""
    i = rec_n[0]
    if i >= rec.shape[0]:
        return
    k = signs.shape[0]
    n = x.shape[0]
    rec[i, 0] = tau
    rec[i, 1] = stuck
    for c in range(k):
        rec[i, 2 + c] = signs[c]
    for j in range(n):
        rec[i, 2 + k + j] = x[j]
        rec[i, 2 + k + n + j] = xd[j]
    rec_n[0] = i + 1


@njit(cache=True)
def run_cycle(x, xd, stuck, signs, cst, gst, ctx, tau_start, tau_end, max_work, check, rec, rec_n):
    """Advance ``(x, x', stuck, signs)`` from ``tau_start`` to ``tau_end``.

    Fills the per-contact statistics ``cst`` (stops ending here of more than
    ``stick_min``, reversals, stuck time, range of ``b_c . x``, slip distance,
    largest stuck force; ``CS_STICK_START`` carries each stuck contact's stick
    start over cycles) and the global ``gst`` (events, status, stuck for ever,
    work). ``check`` samples every phase for the orbit check and the force
    amplitude. Every phase start is appended to ``rec`` (``rec_n[0]`` counts
    them; a buffer of 0 rows records nothing), and the end state last.
    Returns the new stuck set (signs updated in place).
    """
    B = ctx[CX_B]
    active = ctx[CX_ACTIVE]
    betas = ctx[CX_BETAS]
    tol = ctx[CX_TOL]
    stick_min = ctx[CX_STICK_MIN]
    n = x.shape[0]
    k = B.shape[1]
    for i in range(N_GST):
        gst[i] = 0.0
    for c in range(k):
        start = cst[c, CS_STICK_START]
        for j in range(cst.shape[1]):
            cst[c, j] = 0.0
        cst[c, CS_STICK_START] = start
        dc = _col_dot(B, c, x)
        cst[c, CS_DMIN] = dc
        cst[c, CS_DMAX] = dc
        cst[c, CS_ORBIT_ERROR] = -np.inf
        cst[c, CS_VEL_ERROR] = -np.inf
    d = np.zeros(k)
    eta = np.zeros(n)
    etad = np.zeros(n)
    eta0 = np.zeros(n)
    etad0 = np.zeros(n)
    zeroed = np.zeros(k, dtype=np.bool_)
    new_signs = np.zeros(k)
    t_found = np.empty(k)
    d_start = np.empty(k)
    stack = np.empty((DIP_STACK, 6))  # next_event's bisection stack
    tau = tau_start
    events = 0
    work = 0.0
    while True:
        remaining = tau_end - tau
        if remaining <= tol:
            break
        _record(rec, rec_n, tau, stuck, signs, x, xd)
        m = ctx[CX_SIZE][stuck]
        segs = np.zeros((k, N_ROWS, m))
        scs = np.zeros((k, N_SCALARS))
        start_phase(x, xd, tau, stuck, signs, zeroed, ctx, segs, scs, d, eta0, etad0)
        om_max = 1.0
        for a in range(m):
            om_max = max(om_max, ctx[CX_OMEGA][stuck, a])
        h = ctx[CX_STEP] * math.pi / om_max
        for c in range(k):
            d_start[c] = _col_dot(B, c, x)
        forever = stuck == active and active != 0
        if forever:
            for c in range(k):
                if (active >> c) & 1 and not never_unsticks(segs[c], scs[c]):
                    forever = False
        best = remaining
        found_any = False
        first = -1
        for c in range(k):
            t_found[c] = np.inf
            if not (active >> c) & 1:
                continue
            if first < 0:
                first = c
            if forever:
                continue
            scs[c, WORK_CAP] = max_work - work
            t_end = min(remaining, best + 2.0 * tol)
            t, found = next_event(segs[c], scs[c], t_end, h, tol, eta, etad, stack)
            work += scs[c, EVALS]
            if found:
                t_found[c] = t
                if t < best:
                    best = t
                found_any = True
            elif work > max_work:
                break
        if forever:
            gst[GS_FOREVER] = 1.0
        t = best
        if first >= 0:
            evaluate(segs[first], scs[first], t, eta, etad)
        else:  # no active contact: the linear structure alone
            seg = np.zeros((N_ROWS, m))
            sc = np.zeros(N_SCALARS)
            for a in range(m):
                seg[OMEGA, a] = ctx[CX_OMEGA][stuck, a]
                seg[ETA0, a] = eta0[a]
                seg[ETAD0, a] = etad0[a]
                seg[LOAD_COS, a] = ctx[CX_LOAD_COS][stuck, a]
                seg[LOAD_CONST, a] = segs[0, LOAD_CONST, a]
            sc[COS_TAU0] = math.cos(tau)
            sc[SIN_TAU0] = math.sin(tau)
            D = ctx[CX_COMPLIANCE]
            if D.shape[0] > k:  # damped: the structure's own modes and rates
                for a in range(m):
                    seg[DAMP, a] = viscous.sigma(D, n, k, stuck, a)
                sc[DAMPED] = 1.0
            evaluate(seg, sc, t, eta, etad)
            if check and D.shape[0] > k:
                gst[GS_VISCOUS] += _viscous(ctx, stuck, seg, sc, t, segs[0, ETAD_OFF])
                evaluate(seg, sc, t, eta, etad)
        if check and first >= 0:
            _sample_phase(segs, scs, stuck, t, cst, active, eta0, etad0)
            if ctx[CX_COMPLIANCE].shape[0] > k:
                off = segs[0, ETAD_OFF]
                gst[GS_VISCOUS] += _viscous(ctx, stuck, segs[first], scs[first], t, off)
            evaluate(segs[first], scs[first], t, eta, etad)
        D = ctx[CX_COMPLIANCE]
        if D.shape[0] > k and viscous.is_general(D, n, k, stuck):
            viscous.general_state(ctx, stuck, d, eta, etad, segs[0, ETAD_OFF], x, xd)
        else:
            _state(ctx, stuck, d, eta, etad, x, xd)
        for c in range(k):
            dc = _col_dot(B, c, x)
            if (stuck >> c) & 1:
                cst[c, CS_STUCK_TIME] += t
            else:
                cst[c, CS_SLIP] += abs(dc - d_start[c])
                if (active >> c) & 1 and betas[c] > cst[c, CS_FORCE_MAX]:
                    cst[c, CS_FORCE_MAX] = betas[c]
            cst[c, CS_DMIN] = min(cst[c, CS_DMIN], dc)
            cst[c, CS_DMAX] = max(cst[c, CS_DMAX], dc)
        if work > max_work:
            gst[GS_STATUS] = WORK_LIMIT
            break
        if not found_any:
            break
        # the event: candidates are the stuck contacts and those whose event coincides
        cand = stuck
        for c in range(k):
            if t_found[c] <= best + 2.0 * tol:
                cand |= 1 << c
        old = signs.copy()
        for c in range(k):
            if (cand >> c) & 1:
                signs[c] = 0.0
        if ctx[CX_COMPLIANCE].shape[0] > k:  # damped: the viscous force in the decision
            xe = viscous.effective(ctx[CX_COMPLIANCE], k, x, xd)
            new_stuck, _ = decide(xe, tau + t, cand, signs, ctx, new_signs)
        else:
            new_stuck, _ = decide(x, tau + t, cand, signs, ctx, new_signs)
        tau += t
        for c in range(k):
            if not (active >> c) & 1:
                signs[c] = 0.0
                continue
            was = (stuck >> c) & 1
            now = (new_stuck >> c) & 1
            signs[c] = new_signs[c]
            zeroed[c] = bool((cand >> c) & 1) and not now
            if was and not now:
                if tau - cst[c, CS_STICK_START] > stick_min:
                    cst[c, CS_STOPS] += 1.0
            elif now and not was:
                cst[c, CS_STICK_START] = tau
            elif not now and old[c] != 0.0 and signs[c] != old[c]:
                cst[c, CS_REVERSALS] += 1.0
        stuck = new_stuck
        events += 1
        if events > ctx[CX_MAX_EVENTS]:
            gst[GS_STATUS] = EVENT_LIMIT
            break
    _record(rec, rec_n, tau_end, stuck, signs, x, xd)
    gst[GS_EVENTS] = events
    gst[GS_WORK] = work
    for i in range(n):
        if not (math.isfinite(x[i]) and math.isfinite(xd[i])):
            gst[GS_STATUS] = NUMERICAL_FAILURE
    return stuck
