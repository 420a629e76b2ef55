"""Steady state of one point with several contacts, and many points (docs/contacts.md 4).

From the held start or rest (:mod:`tasks.multicontact.starts`), excitation cycles run
from the section ``tau = 2 pi n`` (:mod:`tasks.multicontact.section`) until it repeats
with the same stuck set and slip signs (period 1 or 2; Newton on the Poincare map for
slow transients), every contact provably stays stuck, or the creep rule settles it
(:mod:`tasks.multicontact.creep`; at a shifted section where every contact is stuck
when some contact's creep straddles this one, :mod:`tasks.multicontact.shifted`); the
converged period is run once more with the orbit check and the design quantities
(:mod:`tasks.multicontact.fields`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from tasks.kernel.layout import TWO_PI
from tasks.multicontact import creep, shifted, viscous
from tasks.multicontact.cycle import run_cycle
from tasks.multicontact.fields import finish, settle, undetermined
from tasks.multicontact.held import held_margins, held_response
from tasks.multicontact.layout import (
    CS_DMAX,
    CS_DMIN,
    CS_STICK_START,
    CX_ACTIVE,
    CX_BETAS,
    CX_COMPLIANCE,
    CX_K,
    CX_P,
    GS_EVENTS,
    GS_FOREVER,
    GS_STATUS,
    GS_WORK,
    N_CST,
    N_GST,
    N_OC,
    N_OG,
    OG_ASYMPTOTIC,
    OG_PERIOD,
)
from tasks.multicontact.section import SHOOT_EVERY, max_abs, newton, polish, run_period
from tasks.multicontact.starts import start_state
from tasks.regimes import (
    CREEP_SLIP_RTOL,
    CREEP_WINDOW,
    IC_HELD,
    NOT_CONVERGED,
    UNBOUNDED,
)

#: The creep rule's result under the name the tests call (:func:`fields.settle`).
_settle = settle


@njit(cache=True)
def point_context(r, beta, args, settings):
    """The per-point context tuple (entries ``CX_*`` of :mod:`tasks.multicontact.layout`)."""
    (G, Ginv, K, p0, scales, B, ratio, compliance, size, lam, X, XtG, W, H, HKX, BX) = args[:16]
    C, cdiag, HCX, KinvC = args[16], args[17], args[18], args[19]
    general, Tset, Lset, Vset, Wo, damped = args[20:26]
    event_tol = settings[0]
    step_fraction = settings[1]
    max_events = settings[7]
    r2 = r * r
    p = p0 * r2 if scales else p0.copy()
    n = p.shape[0]
    k = B.shape[1]
    n_sets = size.shape[0]
    betas = ratio * beta
    active = 0
    for c in range(k):
        if betas[c] > 0.0:
            active |= 1 << c
    omega = np.zeros((n_sets, n))
    load_cos = np.zeros((n_sets, n))
    hp = np.zeros((n_sets, k))
    om_max = 1.0
    for S in range(n_sets):
        for a in range(size[S]):
            omega[S, a] = math.sqrt(max(lam[S, a], 0.0)) / r
            om_max = max(om_max, omega[S, a])
            acc = 0.0
            for i in range(n):
                acc += X[S, i, a] * p[i]
            load_cos[S, a] = acc / r2
        for c in range(k):
            acc = 0.0
            for i in range(n):
                acc += H[S, c, i] * p[i]
            hp[S, c] = acc
    events = max(float(max_events), min(8.0 * om_max, 1e9))
    if damped:  # the damping data after the compliances (tasks.multicontact.viscous)
        compliance = viscous.pack(
            compliance, r, C, cdiag, HCX, KinvC, general, Tset, Lset, Vset, Wo
        )
    return (
        G,
        Ginv,
        K,
        p,
        B,
        betas,
        active,
        size,
        X,
        XtG,
        W,
        H,
        HKX,
        BX,
        omega,
        load_cos,
        hp,
        r2,
        step_fraction,
        event_tol,
        1e3 * event_tol,
        events,
        compliance,
    )


@njit(cache=True)
def simulate_point(r, beta, args, settings, out_g, out_c):
    """Steady state of one point: fills ``out_g`` (``OG_*``) and ``out_c`` (``OC_*``,
    one row per contact). Returns the section state ``(X, stuck, signs, held)`` of
    the steady state found (of the last cycle run where none was found), ``held``
    the contacts the creep rule held (:func:`tasks.multicontact.creep.held_context`)
    in the run that found it (0: none): its orbit is that of ``ctx`` holding them."""
    section_rtol = settings[2]
    max_cycles = settings[3]
    min_cycles = settings[4]
    shooting = settings[5]
    shooting_after = settings[6]
    growth_factor = settings[8]
    ic = settings[9]
    max_work = settings[10]
    ctx = point_context(r, beta, args, settings)
    k = ctx[CX_BETAS].shape[0]
    out_g[OG_ASYMPTOTIC] = 0.0
    X, stuck, signs, used = start_state(ctx, ic, r, beta, int(settings[11]))
    margins = np.zeros(k)
    if ctx[CX_ACTIVE] == 0:  # no friction anywhere: linear, continuous unless resonant
        Xf, exists = held_response(ctx, 0)
        if not exists:
            undetermined(out_g, out_c, UNBOUNDED, 0, used)
            return X, stuck, signs, 0
        finish(Xf, 0, np.zeros(k), ctx, 1, 0, used, out_g, out_c, max_work)
        return Xf, 0, np.zeros(k), 0
    if used != IC_HELD and held_margins(ctx, margins):
        Xh, _ = held_response(ctx, ctx[CX_ACTIVE])
        finish(Xh, ctx[CX_ACTIVE], np.zeros(k), ctx, 1, 0, used, out_g, out_c, max_work)
        out_g[OG_ASYMPTOTIC] = 1.0
        return Xh, ctx[CX_ACTIVE], np.zeros(k), 0
    cst = np.zeros((k, N_CST))
    gst = np.zeros(N_GST)
    for c in range(k):
        cst[c, CS_STICK_START] = -1e300 if (stuck >> c) & 1 else 0.0
    ref = max(max_abs(X), max_abs(np.linalg.solve(ctx[CX_K], ctx[CX_P])), 1e-300)
    X1 = X.copy()
    X2 = X.copy()
    st1 = stuck
    st2 = stuck
    sg1 = signs.copy()
    sg2 = signs.copy()
    cycles = 0
    work = 0.0
    next_shot = shooting_after
    # the creep rule (tasks.multicontact.creep): per-contact runs, the stuck
    # structure's window (as one contact's), the contacts it holds, their last slips
    runs = np.zeros((k, 3), dtype=np.int64)
    prev_drift = np.zeros(k, dtype=np.int64)
    drift = np.zeros(k)
    small_run = 0
    quiet_run = 0
    held = 0
    refused = 0  # creeps the cycle at hand did not certify
    betas = ctx[CX_BETAS]
    amps = np.zeros(k)
    period = 0  # of the steady state found
    while cycles < max_cycles:
        s_before = signs.copy()
        st_before = stuck
        Xn, stuck, tot = run_period(X, stuck, signs, cst, gst, ctx, 1, max_work - work, False)
        cycles += 1
        work += gst[GS_WORK]
        if gst[GS_STATUS] != 0.0:
            undetermined(out_g, out_c, gst[GS_STATUS], cycles, used)
            return X, stuck, signs, held
        if gst[GS_FOREVER] > 0.0:  # every contact stuck for ever: no motion
            stuck = st_before
            signs = s_before
            period = 1
            break
        if held == 0:
            small = True
            for c in range(k):
                amps[c] = 0.5 * (tot[c, CS_DMAX] - tot[c, CS_DMIN])
                if (ctx[CX_ACTIVE] >> c) & 1:
                    small &= amps[c] < CREEP_SLIP_RTOL * betas[c] * ctx[CX_COMPLIANCE][c]
            small_run = small_run + 1 if small else 0
            quiet_run = (
                quiet_run + 1 if small and gst[GS_EVENTS] == 0.0 else (quiet_run if small else 0)
            )
            prev_drift[:] = runs[:, 2]
            held = creep.update(X, Xn, stuck, tot, ctx, runs, drift, refused)
            # most of the window without an event, or every contact drifting one way
            # through it (a creep in progress at each: no orbit of any period)
            if (
                small_run >= CREEP_WINDOW
                and (2 * quiet_run > small_run or held == ctx[CX_ACTIVE])
                and creep.all_stuck_settled(Xn, stuck, signs, ctx, 0.0)
            ):  # the stuck structure settles as one contact does: hold it, finish
                hctx = creep.held_context(ctx, ctx[CX_ACTIVE])
                finish(Xn, stuck, signs, hctx, 1, cycles, used, out_g, out_c, max_work)
                settle(
                    Xn, stuck, signs, hctx, -1, betas, 1, cycles, used, out_g, out_c, amps, max_work
                )
                return Xn, stuck, signs, ctx[CX_ACTIVE]
            if small_run >= CREEP_WINDOW and stuck != ctx[CX_ACTIVE]:
                # every contact's slips small, some contact sliding at the section: the
                # stuck structure's rule at a section where every contact is stuck
                code, X, stuck, signs, used_cycles, status, used_work = shifted.settle_shifted(
                    Xn, stuck, signs, ctx, max_cycles - cycles, max_work - work, amps
                )
                cycles += used_cycles
                work += used_work
                if code == shifted.SHIFT_FAULT:
                    undetermined(out_g, out_c, status, cycles, used)
                    return X, stuck, signs, 0
                if code == shifted.SHIFT_SETTLED:
                    hctx = creep.held_context(ctx, ctx[CX_ACTIVE])
                    finish(X, stuck, signs, hctx, 1, cycles, used, out_g, out_c, max_work)
                    settle(
                        X, stuck, signs, hctx, -1, betas, 1, cycles, used, out_g, out_c, amps,
                        max_work,
                    )  # fmt: skip
                    return X, stuck, signs, ctx[CX_ACTIVE]
                # no creep there: the iteration goes on from the section, afresh
                for c in range(k):
                    cst[c, CS_STICK_START] = -1e300 if (stuck >> c) & 1 else 0.0
                runs[:, :] = 0
                prev_drift[:] = 0
                drift[:] = 0.0
                small_run = 0
                quiet_run = 0
                X1 = X + 1e300
                X2 = X1
                continue
            if held == ctx[CX_ACTIVE]:
                held = 0  # every contact creeps: the stuck structure's window decides
            if held != 0 and not creep.swing_certified(
                Xn, stuck, signs, creep.held_context(ctx, held), held, betas, 1, max_work
            ):  # not certified on the cycle at hand: the creep keeps running as it is
                refused |= held
                held = 0
            if held != 0:  # others move: continue with the creeping contacts held
                ctx = creep.held_context(ctx, held)
                runs[:, 2] = 0
                prev_drift[:] = 0
                X1 = Xn + 1e300
                X2 = X1
                next_shot = cycles + shooting_after
                X = Xn
                continue
        X2 = X1
        st2 = st1
        sg2 = sg1
        X1 = X
        st1 = st_before
        sg1 = s_before
        X = Xn
        scale = max(max_abs(X), 1e-300)
        if scale > growth_factor * ref:
            undetermined(out_g, out_c, UNBOUNDED, cycles, used)
            return X, stuck, signs, held
        # a contact drifting one way (creep.update) over the period: no steady state,
        # whatever the tolerance
        drifts = np.any(runs[:, 2] != 0)
        drifts2 = np.any((runs[:, 2] != 0) & (runs[:, 2] == prev_drift))
        if cycles >= min_cycles:
            if stuck == st1 and not drifts and np.all(signs == sg1):
                if max_abs(X - X1) <= section_rtol * scale:
                    period = 1
                    break
            if stuck == st2 and not drifts2 and np.all(signs == sg2):
                if max_abs(X - X2) <= section_rtol * scale:
                    period = 2
                    break
        # a contact creeping in one direction: no fixed point on this branch (its
        # relative displacement drifts), Newton would only spend the cycles it needs
        if shooting and cycles >= next_shot and not creep.creeping(runs, refused):
            Xs, used_cycles, ok = newton(
                X.copy(), stuck, signs.copy(), cst.copy(), gst, ctx, max_work, section_rtol
            )
            cycles += used_cycles
            next_shot = cycles + SHOOT_EVERY  # 20 cycles of iteration between attempts
            gst[GS_STATUS] = 0.0
            if ok:
                X = Xs
                X1 = Xs + 1e300  # the plain test must see the fixed point repeat
                X2 = X1
    if period == 0:
        undetermined(out_g, out_c, NOT_CONVERGED, cycles, used)
        return X, stuck, signs, held
    if gst[GS_FOREVER] == 0.0:
        X = polish(X, stuck, signs, ctx, period, max_work)
    finish(X, stuck, signs, ctx, period, cycles, used, out_g, out_c, max_work)
    settle(X, stuck, signs, ctx, held, betas, period, cycles, used, out_g, out_c, amps, max_work)
    return X, stuck, signs, held


@njit(cache=True, parallel=False)
def run_points(r, beta, args, settings):
    """Every point: ``(out_g (n, N_OG), out_c (n, k, N_OC))``."""
    npts = r.shape[0]
    k = args[5].shape[1]
    out_g = np.zeros((npts, N_OG))
    out_c = np.zeros((npts, k, N_OC))
    for i in prange(npts):
        simulate_point(r[i], beta[i], args, settings, out_g[i], out_c[i])
    return out_g, out_c


@njit(cache=True)
def record_orbit(r, beta, args, settings, max_rows):
    """The steady state of one point and its last period, phase by phase:
    ``(out_g, out_c, rec, rows)``, ``rec`` rows ``(tau, stuck, signs, x, x')`` at
    every phase start of the period (and its end), for tests and figures. The period
    is the accepted orbit's: run with the contacts the creep rule held held
    (docs/contacts.md 4), as :func:`simulate_point` found it."""
    k = args[5].shape[1]
    n = args[3].shape[0]
    out_g = np.zeros(N_OG)
    out_c = np.zeros((k, N_OC))
    X, stuck, signs, held = simulate_point(r, beta, args, settings, out_g, out_c)
    ctx = point_context(r, beta, args, settings)
    if held != 0:  # the orbit accepted: with the creeping contacts held
        ctx = creep.held_context(ctx, held)
    rec = np.zeros((max_rows, 2 + k + 2 * n))
    period = max(int(out_g[OG_PERIOD]), 1)
    cst = np.zeros((k, N_CST))
    gst = np.zeros(N_GST)
    rec_n = np.zeros(1, dtype=np.int64)
    x = X[:n].copy()
    xd = X[n:].copy()
    s = signs.copy()
    for _ in range(period):
        stuck = run_cycle(
            x, xd, stuck, s, cst, gst, ctx, 0.0, TWO_PI, settings[10], False, rec, rec_n
        )
    return out_g, out_c, rec, rec_n[0]
