"""The all-stuck creep measured at a shifted section (docs/contacts.md 4).

The stuck structure's creep rule (:mod:`tasks.multicontact.creep`) measures every
contact's drift, and the stuck section's force bound, at the section ``tau = 2 pi
n``. A creep whose slip straddles that section (a contact sliding there) is never
stuck at it, so the rule does not see it. Here the same rule runs at a section
``tau_s + 2 pi n`` placed in the middle of the longest phase of a cycle in which
every contact with friction is stuck: the contacts' stuck offsets, their drift from
cycle to cycle and the force bound are then measured where every contact is stuck,
whatever the slip's phase. The evidence asked for is the same (``CREEP_WINDOW``
cycles of slips below ``CREEP_SLIP_RTOL beta_c c_c``, one way, every contact stuck
at the section, most cycles without an event or every contact drifting through the
window, and the stuck section's force bound at most ``(1 + CREEP_FORCE_RTOL)
beta_c``); a contact whose cycle at the shifted section is no creep (it slips both
ways, or more) ends the attempt, and the iteration at ``tau = 2 pi n`` goes on.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from tasks.kernel.layout import TWO_PI
from tasks.multicontact import creep
from tasks.multicontact.cycle import run_cycle
from tasks.multicontact.layout import (
    CS_DMAX,
    CS_DMIN,
    CS_STICK_START,
    CX_ACTIVE,
    CX_BETAS,
    CX_COMPLIANCE,
    CX_MAX_EVENTS,
    GS_EVENTS,
    GS_FOREVER,
    GS_STATUS,
    GS_WORK,
    N_CST,
    N_GST,
)
from tasks.regimes import CREEP_SLIP_RTOL, CREEP_WINDOW

#: Outcomes of :func:`settle_shifted`.
SHIFT_SETTLED = 1
SHIFT_NONE = 0
SHIFT_FAULT = -1


@njit(cache=True)
def stuck_phase(X, stuck, signs, ctx, max_work):
    """One cycle from the section state ``X``, recorded: the middle ``tau_s`` of its
    longest phase with every contact with friction stuck, and the state there.
    Returns ``(tau_s, Xs, signs_s, work, ok)``; ``ok`` is False when no phase of
    the cycle has every contact stuck (or the cycle faulted)."""
    n = X.shape[0] // 2
    k = signs.shape[0]
    active = ctx[CX_ACTIVE]
    rows = int(min(4.0 * ctx[CX_MAX_EVENTS] + 2.0, 1e6))
    rec = np.zeros((rows, 2 + k + 2 * n))
    rec_n = np.zeros(1, dtype=np.int64)
    cst = np.zeros((k, N_CST))
    gst = np.zeros(N_GST)
    x = X[:n].copy()
    xd = X[n:].copy()
    s = signs.copy()
    run_cycle(x, xd, stuck, s, cst, gst, ctx, 0.0, TWO_PI, max_work, False, rec, rec_n)
    work = gst[GS_WORK]
    Xs = X.copy()
    count = rec_n[0]
    if gst[GS_STATUS] != 0.0 or count >= rows:
        return 0.0, Xs, s, work, False
    best = -1
    longest = 0.0
    for j in range(count - 1):
        t = rec[j + 1, 0] - rec[j, 0]
        if int(rec[j, 1]) == active and t > longest:
            best = j
            longest = t
    if best < 0:
        return 0.0, Xs, s, work, False
    tau0 = rec[best, 0]
    tau_s = tau0 + 0.5 * longest
    x = rec[best, 2 + k : 2 + k + n].copy()
    xd = rec[best, 2 + k + n :].copy()
    s = rec[best, 2 : 2 + k].copy()
    buf = np.zeros((0, 2 + k + 2 * n))
    st = run_cycle(x, xd, active, s, cst, gst, ctx, tau0, tau_s, max_work, False, buf, rec_n)
    work += gst[GS_WORK]
    if gst[GS_STATUS] != 0.0 or st != active:
        return 0.0, Xs, s, work, False
    Xs[:n] = x
    Xs[n:] = xd
    return tau_s, Xs, s, work, True


@njit(cache=True)
def _advance(X, stuck, signs, ctx, tau_a, tau_b, max_work):
    """``(X, stuck)`` advanced from ``tau_a`` to ``tau_b`` (signs in place), and the
    run's status."""
    n = X.shape[0] // 2
    k = signs.shape[0]
    cst = np.zeros((k, N_CST))
    gst = np.zeros(N_GST)
    buf = np.zeros((0, 2 + k + 2 * n))
    rec_n = np.zeros(1, dtype=np.int64)
    x = X[:n].copy()
    xd = X[n:].copy()
    st = run_cycle(x, xd, stuck, signs, cst, gst, ctx, tau_a, tau_b, max_work, False, buf, rec_n)
    out = np.empty(2 * n)
    out[:n] = x
    out[n:] = xd
    return out, st, gst[GS_STATUS]


@njit(cache=True)
def settle_shifted(X, stuck, signs, ctx, max_cycles, max_work, amps):
    """The stuck structure's creep rule at a shifted section, from the section state
    ``(X, stuck, signs)`` at ``tau = 0``, for at most ``max_cycles`` cycles.

    Returns ``(code, X0, stuck0, signs0, cycles, status, work)``. ``SHIFT_SETTLED``: every contact
    crept at the shifted section and its stuck state there passes
    :func:`tasks.multicontact.creep.all_stuck_settled`; ``X0`` is the next section
    state at ``tau = 2 pi n`` of the structure with every contact held
    (:func:`tasks.multicontact.creep.held_context`), ``amps`` the slip amplitudes
    of the last creeping cycle. ``SHIFT_NONE``: no creep there (or the cycles ran
    out); ``(X0, stuck0, signs0)`` is the state at the next ``tau = 2 pi n``, from
    which the iteration goes on. ``SHIFT_FAULT``: a run faulted (work or event
    limit, or a non-finite state; ``status`` its code)."""
    k = signs.shape[0]
    active = ctx[CX_ACTIVE]
    betas = ctx[CX_BETAS]
    tau_s, Xs, s, work, ok = stuck_phase(X, stuck, signs, ctx, max_work)
    cycles = 1
    if not ok:  # the recorded cycle: run it again unrecorded for its end state
        s = signs.copy()
        X0, st0, status = _advance(X, stuck, s, ctx, 0.0, TWO_PI, max_work)
        code = SHIFT_FAULT if status != 0.0 else SHIFT_NONE
        return code, X0, st0, s, cycles, status, work
    n = X.shape[0] // 2
    runs = np.zeros((k, 3), dtype=np.int64)
    drift = np.zeros(k)
    cst = np.zeros((k, N_CST))
    gst = np.zeros(N_GST)
    buf = np.zeros((0, 2 + k + 2 * n))
    rec_n = np.zeros(1, dtype=np.int64)
    st = active
    small_run = 0
    quiet_run = 0
    for c in range(k):
        cst[c, CS_STICK_START] = -1e300
    while cycles < max_cycles:
        x = Xs[:n].copy()
        xd = Xs[n:].copy()
        st = run_cycle(
            x, xd, st, s, cst, gst, ctx, tau_s, tau_s + TWO_PI, max_work - work, False, buf, rec_n
        )
        cycles += 1
        work += gst[GS_WORK]
        if gst[GS_STATUS] != 0.0:
            return SHIFT_FAULT, Xs, st, s, cycles, gst[GS_STATUS], work
        for c in range(k):
            cst[c, CS_STICK_START] -= TWO_PI
        Xn = np.empty(2 * n)
        Xn[:n] = x
        Xn[n:] = xd
        small = gst[GS_FOREVER] == 0.0
        for c in range(k):
            amps[c] = 0.5 * (cst[c, CS_DMAX] - cst[c, CS_DMIN])
            if (active >> c) & 1:
                small &= amps[c] < CREEP_SLIP_RTOL * betas[c] * ctx[CX_COMPLIANCE][c]
        held = creep.update(Xs, Xn, st, cst, ctx, runs, drift, 0)
        Xs = Xn
        creeps = small
        for c in range(k):
            if (active >> c) & 1 and runs[c, 0] == 0:
                creeps = False  # no creep at this contact: not this rule's case
        if not creeps:
            break
        small_run += 1
        quiet_run += 1 if gst[GS_EVENTS] == 0.0 else 0
        if (
            small_run >= CREEP_WINDOW
            and (2 * quiet_run > small_run or held == active)
            and creep.all_stuck_settled(Xs, st, s, ctx, tau_s)
        ):
            hctx = creep.held_context(ctx, active)
            X0, st0, status = _advance(Xs, st, s, hctx, tau_s, TWO_PI, max_work)
            if status != 0.0:
                return SHIFT_FAULT, X0, st0, s, cycles, status, work
            return SHIFT_SETTLED, X0, st0, s, cycles, status, work
    X0, st0, status = _advance(Xs, st, s, ctx, tau_s, TWO_PI, max_work)
    code = SHIFT_FAULT if status != 0.0 else SHIFT_NONE
    return code, X0, st0, s, cycles, status, work  # the advance ends the last cycle
