"""Event location: the first zero of a phase's event function, and stick phases that never end.

The event function ``F`` of a phase (:mod:`tasks.kernel.propagation`) is ``s y``
while sliding with sign ``s`` (a stop when the contact velocity reaches 0) and
``beta - |g|`` while stuck (unsticking when the contact force reaches the
friction limit; Eqs. 11, 12, 79, 103). :func:`next_event` finds its *first*
zero completely: every part of the phase is either proved free of zeros by a
certificate built on bounds of ``|F'|`` and ``|F''|``
(:func:`tasks.kernel.propagation.derivative_bounds`) or searched down to the
event tolerance, so no stop, reversal or unsticking is skipped however briefly
the function dips. :func:`never_unsticks` proves that a stick phase lasts for
ever (the no-motion steady state, docs/theory.md 4.2).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.kernel.damping import stick_force_bound_damped
from tasks.kernel.layout import (
    ALPHA,
    BETA,
    COS_TAU0,
    DAMPED,
    ETA0,
    ETAD0,
    EVALS,
    KIND,
    KIND_SLIP,
    KIND_STICK,
    LAST_T,
    LAST_Y,
    LEAF,
    LOAD_CONST,
    LOAD_COS,
    OBS0,
    OBS_COS,
    OMEGA,
    SIGN,
    SIN_TAU0,
    WORK_CAP,
)
from tasks.kernel.propagation import derivative_bounds, evaluate, evaluate_start, start_taylor

# Rows of the bisection stack of :func:`_dip` (``work[5]`` of a point's context):
# brackets still to search, at most one per halving level.
DIP_STACK = 128


@njit(**LEAF)
def _no_zero_between(fa, da, fb, db, h, curvature, slope=np.inf):
    """Certificate that F > 0 on ``(a, a + h)`` from its values and slopes at both
    ends, ``|F''| <= curvature`` and ``|F'| <= slope``: the lower bounds
    ``fa + da u - c u^2 / 2`` and ``fa - slope u`` from the left end, and their
    mirror images from the right end, are positive on intervals that together
    cover the bracket. ``fa`` or ``fb`` may be 0 (a phase start at an event);
    values below 0 (rounding at such a start) count as 0."""
    fa = max(fa, 0.0)
    fb = max(fb, 0.0)
    if curvature <= 0.0:
        return fa > 0.0 or fb > 0.0 or (da > 0.0 and db < 0.0)
    ua = (da + math.sqrt(da * da + 2.0 * curvature * fa)) / curvature
    wb = (-db + math.sqrt(db * db + 2.0 * curvature * fb)) / curvature
    if slope > 0.0 and slope < np.inf:
        ua = max(ua, fa / slope)
        wb = max(wb, fb / slope)
    return ua + wb >= h


@njit(**LEAF)
def stick_force_bound(seg, sc):
    """``|G0| + |H| + sum_k |alpha_k| A_free,k``: the largest ``|g|`` a stick phase
    can ever reach (the bound of :func:`never_unsticks`; tight when the free
    frequencies are incommensurate with the excitation and each other; ``H`` a phasor
    with the free vibration of an unloaded mode at the excitation's frequency,
    docs/theory.md 3, the absorber). A damped scene takes
    :func:`tasks.kernel.damping.stick_force_bound_damped`."""
    if sc[DAMPED] != 0.0:
        return stick_force_bound_damped(seg, sc)
    harmonic = sc[OBS_COS]
    in_phase = 0.0  # sin tau part of g: free modes at the excitation's frequency
    free_sum = 0.0
    # sc[OBS0] is g at tau0; rebuild the constant part from the modal split.
    const = sc[OBS0] - sc[OBS_COS] * sc[COS_TAU0]
    for k in range(seg.shape[1]):
        w = seg[OMEGA, k]
        den = w * w - 1.0
        if den == 0.0:
            if seg[LOAD_COS, k] != 0.0:  # resonant and loaded: grows without bound
                return np.inf
            # an unloaded mode at the excitation's frequency (tasks.kernel.context,
            # RESONANT_RTOL): its free vibration d cos(tau - tau0) + e sin(tau - tau0)
            # is a harmonic of g, added to H as a phasor (docs/theory.md 3, the
            # absorber's held state)
            static = seg[LOAD_CONST, k]
            d = seg[ETA0, k] - static
            e = seg[ETAD0, k]
            alpha = seg[ALPHA, k]
            const -= alpha * d
            harmonic += alpha * (d * sc[COS_TAU0] - e * sc[SIN_TAU0])
            in_phase += alpha * (d * sc[SIN_TAU0] + e * sc[COS_TAU0])
            continue
        pk = seg[LOAD_COS, k] / den
        static = seg[LOAD_CONST, k] / (w * w)
        d = seg[ETA0, k] - static - pk * sc[COS_TAU0]
        e = (seg[ETAD0, k] + pk * sc[SIN_TAU0]) / w
        alpha = seg[ALPHA, k]
        # g(tau0) contains alpha * eta0 = alpha * (static + P cos tau0 + d)
        const -= alpha * (pk * sc[COS_TAU0] + d)
        harmonic += alpha * pk
        free_sum += abs(alpha) * math.hypot(d, e)
    return abs(const) + math.hypot(harmonic, in_phase) + free_sum


@njit(**LEAF)
def never_unsticks(seg, sc):
    """Certificate that a stick phase lasts for ever (docs/theory.md 4.2, held contact).

    While stuck, ``g = G0 + H cos(tau) + free modes``; if
    ``|G0| + |H| + sum_k |alpha_k| A_free,k <= beta`` (:func:`stick_force_bound`)
    then ``|g| <= beta`` at every future time, whatever the phases of the free modes.
    """
    total = stick_force_bound(seg, sc)
    # |g| <= beta sticks (Eq. 3, sgn in [-1, 1]): the bound itself is no motion
    # (Tables 1-3: beta >= bound); 1e-12 absorbs the rounding of the modal sums.
    return math.isfinite(total) and total <= sc[BETA] * (1.0 + 1e-12)


@njit(**LEAF)
def _solve_bracket(seg, sc, lo, hi, f_lo, d_lo, y_lo, dy_lo, f_hi, d_hi, tol, eta, etad):
    """Safeguarded Newton on F in a sign-changing bracket, to ``hi - lo <= tol``.

    ``F(lo) > 0 >= F(hi)``; ``d_lo``, ``d_hi`` are F' there and ``y_lo``,
    ``dy_lo`` the observable at ``lo``. Newton steps from the last point use the
    F' every evaluation gives anyway; a step that leaves the bracket or does not
    halve the step before it is replaced by bisection, and once the Newton
    correction is below ``0.9 tol`` the next point is placed ``0.99 tol`` from the
    last one, past the root estimate, to close the bracket. Returns
    ``(lo, hi, y_lo, dy_lo)``: ``hi - lo <= tol``, ``F(lo) > 0 >= F(hi)`` and the
    observable at the final ``lo``.
    """
    # start from the end with the smaller |F| (Newton), else the secant point
    if -f_hi < f_lo:
        t = hi - f_hi / d_hi if d_hi != 0.0 else np.nan
    else:
        t = lo - f_lo / d_lo if d_lo != 0.0 else np.nan
    if not (lo < t < hi):
        t = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
    step_old = hi - lo
    step = step_old
    for _ in range(200):
        if hi - lo <= tol or f_hi == 0.0:
            break
        if not (lo < t < hi):
            t = 0.5 * (lo + hi)
        y, dy = _observe(seg, sc, t, eta, etad)
        f, df = _event_value(sc, y, dy)
        if f > 0.0:
            lo = t
            y_lo = y
            dy_lo = dy
        else:
            hi = t
            f_hi = f
        if hi - lo <= tol or f == 0.0:
            break
        step_old = step
        tn = t - f / df if df != 0.0 else np.nan
        if abs(tn - t) < 0.9 * tol:
            # converged: close the bracket with a point just past the root
            tn = t + 0.99 * tol if f > 0.0 else t - 0.99 * tol
        elif not (lo < tn < hi) or abs(tn - t) > 0.5 * abs(step_old):
            tn = 0.5 * (lo + hi)  # bisection: Newton left the bracket or stalled
        step = tn - t
        t = tn
    return lo, hi, y_lo, dy_lo


@njit(**LEAF)
def _observe(seg, sc, t, eta, etad):
    """``(y, y')`` of the phase's observable at t, counting the work in ``sc[EVALS]``;
    ``eta, etad`` then hold the state at t (``sc[LAST_T]``, ``sc[LAST_Y]``: t and y)."""
    sc[EVALS] += 1.0 + seg.shape[1]
    y, dy = evaluate(seg, sc, t, eta, etad)
    sc[LAST_T] = t
    sc[LAST_Y] = y
    return y, dy


@njit(**LEAF)
def _observe_start(seg, sc, eta, etad):
    """:func:`_observe` at the phase start (:func:`evaluate_start`, the same values)."""
    sc[EVALS] += 1.0 + seg.shape[1]
    y, dy = evaluate_start(seg, sc, eta, etad)
    sc[LAST_T] = 0.0
    sc[LAST_Y] = y
    return y, dy


@njit(**LEAF)
def _event_value(sc, y, dy):
    """``(F, F')`` from the observable: ``s y`` sliding, ``beta - |y|`` stuck."""
    if sc[KIND] == KIND_SLIP:
        return sc[SIGN] * y, sc[SIGN] * dy
    if y >= 0.0:
        return sc[BETA] - y, -dy
    return sc[BETA] + y, dy


@njit(**LEAF)
def _clear(sc, ya, dya, yb, dyb, h, curvature, slope):
    """Certificate that the event function stays positive on ``(a, a + h)``.

    Sliding: on ``F = s y``. Stuck: ``F = beta - |y|`` is the smaller of the two
    smooth branches ``beta - y`` and ``beta + y``; both must be certified (a
    bound of one branch says nothing about the other once ``y`` changes sign
    inside the bracket).
    """
    if sc[KIND] == KIND_SLIP:
        s = sc[SIGN]
        return _no_zero_between(s * ya, s * dya, s * yb, s * dyb, h, curvature, slope)
    beta = sc[BETA]
    return _no_zero_between(
        beta - ya, -dya, beta - yb, -dyb, h, curvature, slope
    ) and _no_zero_between(beta + ya, dya, beta + yb, dyb, h, curvature, slope)


@njit(**LEAF)
def _clear_ahead(sc, y, dy, curvature):
    """How far ahead of a point the event function provably stays positive:
    ``u`` with ``F + F' u - curvature u^2 / 2 > 0`` before it, on ``F = s y``
    sliding and on both smooth branches ``beta -+ y`` stuck (:func:`_clear`)."""
    if sc[KIND] == KIND_SLIP:
        f = sc[SIGN] * y
        d = sc[SIGN] * dy
        return (d + math.sqrt(d * d + 2.0 * curvature * f)) / curvature
    beta = sc[BETA]
    up = (-dy + math.sqrt(dy * dy + 2.0 * curvature * (beta - y))) / curvature
    down = (dy + math.sqrt(dy * dy + 2.0 * curvature * (beta + y))) / curvature
    return min(up, down)


@njit(**LEAF)
def _out_of_work(sc):
    return sc[EVALS] > sc[WORK_CAP]


@njit(**LEAF)
def _dip(
    seg, sc, ta, tb, ya, dya, yb, dyb, curvature, slope, tol, skip_graze, floor, eta, etad, stack
):
    """Search ``(ta, tb)`` (F > 0 at both ends) for the first point where F <= 0.

    Bisects the parts of the bracket the certificate (:func:`_clear`) cannot
    clear, left to right, so everything left of the returned bracket is
    cleared. Returns ``(lo, hi, kind)``: kind 0 = no zero, 1 = a sign change
    in ``(lo, hi]`` (F(lo) > 0 >= F(hi)), 2 = a touching zero at ``hi`` (a piece
    of width ``tol`` that cannot be cleared while F stays positive at every
    point tried: F comes within ``curvature tol^2 / 8`` of zero), 3 = the
    point's work budget ran out. Stick phases (and ``skip_graze``) step over
    touching zeros: ``|g| = beta`` still sticks. Values ``F > -floor`` count
    as positive (``floor`` > 0 only next to a phase start, where F starts at a
    zero known to rounding). Also returns the observable ``(y, y')`` at ``lo``
    and ``hi`` (kind 1; at ``hi`` not evaluated, NaN, for kinds 2 and 3).
    """
    if _clear(sc, ya, dya, yb, dyb, tb - ta, curvature, slope):
        return ta, tb, 0, ya, dya, yb, dyb  # the common case: no stack needed
    # the brackets still to search: rows (a, b, y(a), y'(a), y(b), y'(b))
    stack[0, 0] = ta
    stack[0, 1] = tb
    stack[0, 2] = ya
    stack[0, 3] = dya
    stack[0, 4] = yb
    stack[0, 5] = dyb
    top = 1
    skip = skip_graze or sc[KIND] == KIND_STICK
    while top > 0:
        top -= 1
        a = stack[top, 0]
        b = stack[top, 1]
        y_a = stack[top, 2]
        d_a = stack[top, 3]
        y_b = stack[top, 4]
        d_b = stack[top, 5]
        if _clear(sc, y_a, d_a, y_b, d_b, b - a, curvature, slope):
            continue
        m = 0.5 * (a + b)
        if b - a <= tol or not (a < m < b) or top >= DIP_STACK - 2:
            if skip:
                continue
            return a, m, 2, y_a, d_a, np.nan, np.nan
        if _out_of_work(sc):
            return a, b, 3, y_a, d_a, np.nan, np.nan
        y_m, d_m = _observe(seg, sc, m, eta, etad)
        f_m, _ = _event_value(sc, y_m, d_m)
        if f_m <= -floor:
            return a, m, 1, y_a, d_a, y_m, d_m
        # right half first on the stack, so the left half is searched first
        stack[top, 0] = m
        stack[top, 1] = b
        stack[top, 2] = y_m
        stack[top, 3] = d_m
        stack[top, 4] = y_b
        stack[top, 5] = d_b
        top += 1
        stack[top, 0] = a
        stack[top, 1] = m
        stack[top, 2] = y_a
        stack[top, 3] = d_a
        stack[top, 4] = y_m
        stack[top, 5] = d_m
        top += 1
    return ta, tb, 0, ya, dya, yb, dyb


@njit(**LEAF)
def _first_zero(seg, sc, lo, hi, y_lo, dy_lo, y_hi, dy_hi, curvature, slope, tol, eta, etad, stack):
    """The first zero of F in ``(lo, hi]`` (F(lo) > 0 >= F(hi), no zero before lo).

    ``(y_lo, dy_lo)``, ``(y_hi, dy_hi)`` are the observable at both ends (already
    evaluated by the caller). Solves the bracket (:func:`_solve_bracket`), then
    proves with :func:`_dip` that F has no zero between ``lo`` and the root found;
    if it has, the search moves to the earlier sign change (or touching zero).
    Returns ``(t, ok)``, ``t`` on the far side of the first zero; ``ok`` is False
    if the work budget ran out.
    """
    while True:
        f_lo, d_lo = _event_value(sc, y_lo, dy_lo)
        f_hi, d_hi = _event_value(sc, y_hi, dy_hi)
        if not f_lo > 0.0:  # rounding at the bracket's end: take it as the zero
            return lo, True
        r_lo, r_hi, y_r, dy_r = _solve_bracket(
            seg, sc, lo, hi, f_lo, d_lo, y_lo, dy_lo, f_hi, d_hi, tol, eta, etad
        )
        if r_lo <= lo:
            return r_hi, True
        if _clear(sc, y_lo, dy_lo, y_r, dy_r, r_lo - lo, curvature, slope):
            return r_hi, True  # (_dip's own first test, without the call)
        a, b, kind, y_lo, dy_lo, y_hi, dy_hi = _dip(
            seg,
            sc,
            lo,
            r_lo,
            y_lo,
            dy_lo,
            y_r,
            dy_r,
            curvature,
            slope,
            tol,
            False,
            0.0,
            eta,
            etad,
            stack,
        )
        if kind == 0:
            return r_hi, True
        if kind == 2:
            return b, True
        if kind == 3:
            return r_hi, False
        lo = a
        hi = b


@njit(**LEAF)
def _taylor_clear(seg, sc, y0, f0, d0, floor, t_max):
    """Length ``T <= t_max`` of the start ``(0, T]`` of a phase proved to keep
    ``F > -floor`` by the Taylor bound ``F(t) >= F(0) + F'(0) t + F''(0) t^2 / 2 -
    max|F'''| t^3 / 6`` (:func:`tasks.kernel.propagation.start_taylor`); 0 if it
    proves nothing (``F''(0)`` not positive beyond its rounding, or a damped scene).

    With ``T <= 3 F''(0) / (2 max|F'''|)`` the last two terms are at least
    ``q t^2``, ``q = F''(0) / 2 - max|F'''| T / 6 > 0``, and the quadratic
    ``F(0) + floor + F'(0) t + q t^2`` is positive for t > 0 when ``F'(0) >= 0``
    or when its minimum ``F(0) + floor - F'(0)^2 / (4 q)`` is.
    """
    y2, bound, scale = start_taylor(seg, sc, t_max)
    if sc[KIND] == KIND_SLIP:
        f2 = sc[SIGN] * y2
    else:
        f2 = -y2 if y0 >= 0.0 else y2
    f2 -= 1e-12 * scale  # rounding of the terms of F''(0)
    if not (f2 > 0.0 and bound < np.inf):
        return 0.0
    t_clear = t_max if bound == 0.0 else min(t_max, 1.5 * f2 / bound)
    q = 0.5 * f2 - bound * t_clear / 6.0
    base = f0 + floor
    if not (q > 0.0 and base >= 0.0):
        return 0.0
    if d0 >= 0.0 or base > d0 * d0 / (4.0 * q):
        return t_clear
    return 0.0


@njit(**LEAF)
def next_event(seg, sc, t_end, h, tol, eta, etad, stack):
    """First time ``t`` in ``(0, t_end]`` where the event function ``F`` reaches 0.

    ``F > 0`` just after the phase start (it may start at 0, right after an
    event). Complete: every part of ``(0, t_end]`` is either proved free of
    zeros or searched down to ``tol``. The interval is scanned in brackets no
    longer than ``h`` (a fraction of the shortest modal half-period), or longer
    where ``F / max|F'|`` proves them free of zeros. A bracket that ends with
    ``F <= 0`` is solved for its *first* zero (:func:`_first_zero`); one that
    does not is cleared by the certificate of :func:`_clear` (bounds of
    :func:`derivative_bounds` on ``|F'|`` and ``|F''|`` covering every term, both
    branches of ``beta - |g|`` in stick phases) or else bisected where it
    cannot be cleared (:func:`_dip`), which finds pairs of zeros and grazing
    zeros however close together. The point's work budget (``sc[WORK_CAP]``)
    bounds the search.

    Returns ``(t, found)``; ``t`` is on the far side of the zero (F <= 0), or at
    a touching zero. If the work budget ran out, ``(t, False)`` with
    ``sc[EVALS] > sc[WORK_CAP]``.
    """
    y0, dy0 = _observe_start(seg, sc, eta, etad)
    f0, d0 = _event_value(sc, y0, dy0)
    slope, curvature = derivative_bounds(seg, sc, t_end)
    ta = 0.0
    ya = y0
    dya = dy0
    if not f0 > 0.0:
        # phase start at an event (F(0) = 0): step off it to a point where
        # F > 0 (a zero closer than h / 64 to the start is taken as immediate).
        # F(0) is 0 only to rounding: next to the start, values above -noise
        # count as positive (else a tangential event repeats in zero time).
        t1 = min(h / 64.0, t_end)
        y1, dy1 = _observe(seg, sc, t1, eta, etad)
        f1, _ = _event_value(sc, y1, dy1)
        noise = 1e-12 * (abs(y0) + (sc[BETA] if sc[KIND] == KIND_STICK else 0.0) + slope * t1)
        if not noise < np.inf:
            noise = 0.0
        if f1 > -noise:
            # (0, t1) is cleared from F(0) = 0 and F'(0) > 0 (or from the Taylor
            # bound where F'(0) = 0 too), or searched
            t_clear = _taylor_clear(seg, sc, y0, f0, d0, noise, t1)
            lo, hi, kind = t_clear, t1, 0
            y_lo, dy_lo, y_hi, dy_hi = y1, dy1, y1, dy1
            if t_clear < t1:
                y_c, dy_c = y0, dy0
                if t_clear > 0.0:
                    y_c, dy_c = _observe(seg, sc, t_clear, eta, etad)
                lo, hi, kind, y_lo, dy_lo, y_hi, dy_hi = _dip(
                    seg,
                    sc,
                    t_clear,
                    t1,
                    y_c,
                    dy_c,
                    y1,
                    dy1,
                    curvature,
                    slope,
                    tol,
                    True,
                    noise,
                    eta,
                    etad,
                    stack,
                )
            if kind == 3:
                return t1, False
            if kind == 1 and lo > 0.0:
                return _first_zero(
                    seg,
                    sc,
                    lo,
                    hi,
                    y_lo,
                    dy_lo,
                    y_hi,
                    dy_hi,
                    curvature,
                    slope,
                    tol,
                    eta,
                    etad,
                    stack,
                )
            if kind == 1:
                t1 = hi
                y1 = y_hi
                dy1 = dy_hi
                f1 = -np.inf
        if not f1 > -noise:
            tm = t1
            for _ in range(60):
                tm = 0.5 * tm
                ym, dym = _observe(seg, sc, tm, eta, etad)
                fm, _ = _event_value(sc, ym, dym)
                if fm > 0.0:
                    return _first_zero(
                        seg, sc, tm, t1, ym, dym, y1, dy1, curvature, slope, tol, eta, etad, stack
                    )
            return tm, True
        ta = t1
        ya = y1
        dya = dy1
    fa, _ = _event_value(sc, ya, dya)
    while ta < t_end:
        if _out_of_work(sc):
            return ta, False
        step = h
        certified = False
        if slope < np.inf:
            # F > 0 on [ta, ta + safe): from |F'| <= slope, or from the curvature
            # bound F(ta + u) >= F(ta) + F'(ta) u - curvature u^2 / 2
            safe = fa / slope if slope > 0.0 else t_end - ta
            if curvature > 0.0 and fa > 0.0:
                safe = max(safe, _clear_ahead(sc, ya, dya, curvature))
            if safe > step:
                step = safe
                certified = True
        tb = min(ta + step, t_end)
        if not tb > ta:  # the step no longer advances time: out of budget
            sc[EVALS] = sc[WORK_CAP] + 1.0
            return ta, False
        yb, dyb = _observe(seg, sc, tb, eta, etad)
        fb, _ = _event_value(sc, yb, dyb)
        if fb <= 0.0:
            return _first_zero(
                seg, sc, ta, tb, ya, dya, yb, dyb, curvature, slope, tol, eta, etad, stack
            )
        # (the certificate first: the common case needs no call of _dip)
        if not certified and not _clear(sc, ya, dya, yb, dyb, tb - ta, curvature, slope):
            lo, hi, kind, y_lo, dy_lo, y_hi, dy_hi = _dip(
                seg,
                sc,
                ta,
                tb,
                ya,
                dya,
                yb,
                dyb,
                curvature,
                slope,
                tol,
                False,
                0.0,
                eta,
                etad,
                stack,
            )
            if kind == 2:  # the contact velocity touches zero: a stop if it can stick
                return hi, True
            if kind == 1:
                return _first_zero(
                    seg,
                    sc,
                    lo,
                    hi,
                    y_lo,
                    dy_lo,
                    y_hi,
                    dy_hi,
                    curvature,
                    slope,
                    tol,
                    eta,
                    etad,
                    stack,
                )
            if kind == 3:
                return tb, False
        ta = tb
        ya = yb
        dya = dyb
        fa = fb
    return t_end, False
