"""One excitation cycle (or part of one), event by event.

:func:`run_cycle` alternates slip and stick phases (:mod:`tasks.kernel.phases`),
each propagated in closed form and ended at its first event
(:mod:`tasks.kernel.events`), and gathers the statistics the steady-state
tests need (stops, reversals, stuck time, contact displacement range); it can
record every event (:mod:`tasks.kernel.records`, :mod:`tasks.trajectory`).
:func:`_cycle` is the Poincare map: one period ``2 pi`` from the section
``tau = theta``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.kernel.events import never_unsticks, next_event
from tasks.kernel.layout import (
    DAMPED,
    ETAD_OFF,
    EV_END,
    EV_GRAZE,
    EV_REVERSAL,
    EV_SECTION,
    EV_STOP,
    EV_UNSTICK,
    EVALS,
    LAST_T,
    LAST_Y,
    LEAF,
    N_STATS,
    REC_G,
    REC_KIND,
    REC_MODE,
    REC_TAU,
    REC_X,
    ST_DMAX,
    ST_DMIN,
    ST_EVENTS,
    ST_FOREVER,
    ST_LONGEST,
    ST_MID,
    ST_REVERSALS,
    ST_STATUS,
    ST_STOPS,
    ST_STUCK_TIME,
    STATUS_OK,
    TWO_PI,
)
from tasks.kernel.phases import (
    _contact_force,
    _dot,
    _slip_state,
    _start_slip,
    _start_stick,
    _stick_state,
)
from tasks.kernel.propagation import evaluate
from tasks.regimes import EVENT_LIMIT, NUMERICAL_FAILURE, WORK_LIMIT

# Work units (``sc[EVALS]``, mode evaluations) charged per event and per N^2:
# the bookkeeping of an event (state projections, contact force) is O(N^2).
EVENT_WORK = 4.0


@njit(**LEAF)
def _record(rec, rec_n, tau, kind, mode, g, x, xd):
    """Append one event to the record buffer (if there is room)."""
    k = rec_n[0]
    if k >= rec.shape[0]:
        return
    n = x.shape[0]
    rec[k, REC_TAU] = tau
    rec[k, REC_KIND] = kind
    rec[k, REC_MODE] = mode
    rec[k, REC_G] = g
    for i in range(n):
        rec[k, REC_X + i] = x[i]
        rec[k, REC_X + n + i] = xd[i]
    rec_n[0] = k + 1


@njit(**LEAF)
def run_cycle(x, xd, mode, stick_start, stats, ctx, work, rec, rec_n, tau_start, tau_end):
    """Advance ``(x, x', mode)`` from ``tau_start`` to ``tau_end`` (one period, or part).

    ``mode`` is +1 / -1 (sliding with that sign) or 0 (stuck). ``stick_start``
    is the time the current stick phase began (same time frame; earlier than
    ``tau_start`` if it began before). Fills ``stats`` (stops of duration above
    ``stick_min`` ending in this run, reversals, stuck time, min / max of the
    contact displacement ``b . x``, whether the contact provably stays stuck for
    ever, events, status, and the middle ``ST_MID`` of the longest phase, the
    best place for a Poincare section). Returns ``(mode, stick_start)``.

    If ``rec`` has rows, every phase boundary is appended to it (``rec_n[0]``
    counts them): the cycle start, each event with the state at the event and
    the phase that follows it, and the cycle end (columns ``REC_*``).
    """
    (
        seg_slip,
        seg_stick,
        sc,
        beta,
        p,
        K,
        b,
        w,
        T,
        phi,
        phi_t_gamma,
        phi_s,
        phi_s_t_gamma_s,
        proj,
        f_r2,
        dstat_r2,
        g_load,
        g_cos,
        g_d0,
        h_slip,
        h_stick,
        tol,
        stick_min,
        max_events,
        max_work,
        g_c,
    ) = ctx
    eta, etad, eta_s, etad_s, q, stack = work
    for i in range(N_STATS):
        stats[i] = 0.0
    d = _dot(b, x)
    stats[ST_DMIN] = d
    stats[ST_DMAX] = d
    tau = tau_start
    v0 = _dot(b, xd)
    events = 0
    if rec.shape[0]:
        g = _contact_force(p, math.cos(tau), K, x, g_load)
        if sc[DAMPED] != 0.0:
            g -= _dot(g_c, xd)
        _record(rec, rec_n, tau, EV_SECTION, mode, g, x, xd)
    while True:
        remaining = tau_end - tau
        if remaining <= tol:  # an event right at the end of the run
            break
        if mode == 0:
            d0 = _start_stick(
                seg_stick,
                sc,
                x,
                xd,
                tau,
                beta,
                b,
                w,
                proj,
                phi_s_t_gamma_s,
                dstat_r2,
                g_cos,
                g_d0,
                q,
            )
            sc[LAST_T] = np.nan
            if never_unsticks(seg_stick, sc):
                stats[ST_FOREVER] = 1.0
                t, found = remaining, False
            else:
                t, found = next_event(seg_stick, sc, remaining, h_stick, tol, eta_s, etad_s, stack)
            if sc[LAST_T] == t:  # the search's last evaluation: the state is at t already
                g = sc[LAST_Y]
            else:
                g, _ = evaluate(seg_stick, sc, t, eta_s, etad_s)
            _stick_state(phi_s, T, w, d0, eta_s, etad_s, q, x, xd, seg_stick[ETAD_OFF])
            stats[ST_STUCK_TIME] += t
            if t > stats[ST_LONGEST]:
                stats[ST_LONGEST] = t
                stats[ST_MID] = tau + 0.5 * t
            if not found:
                break
            if tau + t - stick_start > stick_min:
                stats[ST_STOPS] += 1.0
            mode = 1 if g > 0.0 else -1
            v0 = 0.0
            kind = EV_UNSTICK
        else:
            s = float(mode)
            _start_slip(seg_slip, sc, x, xd, tau, s, v0, beta, f_r2, phi_t_gamma)
            sc[LAST_T] = np.nan
            t, found = next_event(seg_slip, sc, remaining, h_slip, tol, eta, etad, stack)
            if sc[LAST_T] != t:  # (else the search's last evaluation left the state at t)
                evaluate(seg_slip, sc, t, eta, etad)
            _slip_state(phi, eta, etad, x, xd, seg_slip[ETAD_OFF])
            if t > stats[ST_LONGEST]:
                stats[ST_LONGEST] = t
                stats[ST_MID] = tau + 0.5 * t
            d = _dot(b, x)
            if d < stats[ST_DMIN]:
                stats[ST_DMIN] = d
            if d > stats[ST_DMAX]:
                stats[ST_DMAX] = d
            if not found:
                break
            g = _contact_force(p, math.cos(tau + t), K, x, g_load)
            if sc[DAMPED] != 0.0:  # viscous part: -r g_load . C x'
                g -= _dot(g_c, xd)
            if abs(g) <= beta:
                mode = 0
                stick_start = tau + t
                kind = EV_STOP
            elif (g > 0.0) != (s > 0.0):
                mode = -mode
                stats[ST_REVERSALS] += 1.0
                kind = EV_REVERSAL
            else:
                kind = EV_GRAZE
            v0 = 0.0
        tau += t
        _record(rec, rec_n, tau, kind, mode, g, x, xd)
        events += 1
        sc[EVALS] += EVENT_WORK * x.shape[0] * x.shape[0]
        if events > max_events:
            stats[ST_STATUS] = EVENT_LIMIT
            break
        if sc[EVALS] > max_work:
            stats[ST_STATUS] = WORK_LIMIT
            break
    stats[ST_EVENTS] = events
    if sc[EVALS] > max_work and stats[ST_STATUS] == STATUS_OK:
        stats[ST_STATUS] = WORK_LIMIT
    for i in range(x.shape[0]):
        if not (math.isfinite(x[i]) and math.isfinite(xd[i])):
            stats[ST_STATUS] = NUMERICAL_FAILURE
    if rec.shape[0]:
        g = _contact_force(p, math.cos(tau_end), K, x, g_load)
        if sc[DAMPED] != 0.0:
            g -= _dot(g_c, xd)
        _record(rec, rec_n, tau_end, EV_END, mode, g, x, xd)
    return mode, stick_start


@njit(**LEAF)
def _max_abs(v):
    acc = 0.0
    for i in range(v.shape[0]):
        a = abs(v[i])
        if a > acc:
            acc = a
    return acc


@njit(**LEAF)
def _max_abs_diff(a, b):
    acc = 0.0
    for i in range(a.shape[0]):
        d = abs(a[i] - b[i])
        if d > acc:
            acc = d
    return acc


@njit(**LEAF)
def replay_cycles(x, xd, mode, theta, n_cycles, stats, ctx, work, rec, rec_n):
    """Run ``n_cycles`` excitation cycles from ``(x, x')`` (updated in place) at
    ``tau = theta``, recording every event in ``rec`` (:func:`run_cycle`).

    Stops at the first cycle whose status is not ``STATUS_OK`` (``stats``
    says why). Returns the phase and the stick start at the end.
    """
    stick_start = theta
    for k in range(n_cycles):
        t0 = theta + TWO_PI * k
        mode, stick_start = run_cycle(
            x, xd, mode, stick_start, stats, ctx, work, rec, rec_n, t0, t0 + TWO_PI
        )
        if stats[ST_STATUS] != STATUS_OK:
            break
    return mode, stick_start


@njit(cache=True)
def _advance(X, mode, stick_start, stats, ctx, work, tau_start, tau_end):
    """``X = (x, x')`` at ``tau_start`` -> state at ``tau_end``; returns the new state."""
    n = X.shape[0] // 2
    out = X.copy()  # advanced in place through its two halves (views)
    no_count = np.zeros(1, dtype=np.int64)
    mode, stick_start = run_cycle(
        out[:n],
        out[n:],
        mode,
        stick_start,
        stats,
        ctx,
        work,
        work[5][:0],
        no_count,
        tau_start,
        tau_end,
    )
    return out, mode, stick_start


@njit(cache=True)
def _cycle(X, mode, stick_start, stats, ctx, work, theta):
    """One period from the section state ``X = (x, x')`` at ``tau = theta``.

    Returns the new section state, its phase and the stick start shifted by one
    period (so that it stays relative to the section).
    """
    X1, mode, stick_start = _advance(X, mode, stick_start, stats, ctx, work, theta, theta + TWO_PI)
    return X1, mode, stick_start - TWO_PI
