"""Event-driven simulation of one point: cycles, Poincare section, shooting, regime.

The motion alternates between two linear systems (:mod:`tasks.model`):

* sliding with sign ``s`` (all N coordinates), until the contact velocity
  ``v = b . x'`` reaches 0. There the contact force ``g`` decides: ``|g| <= beta``
  sticks (Eqs. 11, 12, 79, 103), otherwise the slip reverses (``s = sgn g``);
* stuck (N - 1 coordinates, the contact frozen at ``d0 = b . x``), until
  ``|g|`` reaches ``beta``; the contact then slides with ``s = sgn g``.

Each phase is propagated in closed form (section "Phase propagation" below), each event
located by a bracketed root find. Steady state is detected on the Poincare
section ``tau = 2 pi n`` (the excitation has period 2 pi): the section state
``X = (x, x')`` repeating to a relative tolerance (period 1 or 2). Slow
continuous transients are settled by Newton's method on the Poincare map
(shooting). A stick phase that provably never ends (:func:`never_unsticks`)
is the no-motion steady state.

Everything here is compiled with numba (``cache=True``); with
``NUMBA_DISABLE_JIT=1`` the same code runs as plain Python (slowly).

One module on purpose: numba's on-disk cache (``cache=True``) checks only
the file a compiled function is defined in, so every compiled function that
calls another lives here, and an edit anywhere invalidates them all.

Phase propagation
-----------------
Closed-form propagation of a linear phase (slip or stick) and event location.

Between two events every configuration is linear with constant plus harmonic
forcing (docs/theory.md section 2). In the modal coordinates of the moving system
each mode obeys

    eta'' + Omega^2 eta = a cos(tau) + c,                                 (1)

whose solution from ``(eta0, eta0')`` at ``tau0`` is, with ``t = tau - tau0``,

    eta(t) = eta0 cos(Omega t) + eta0' sin(Omega t)/Omega + c (1 - cos(Omega t))/Omega^2
             + a [cos(tau0) C(t) - sin(tau0) S(t)],

``C`` and ``S`` being the zero-start responses to ``cos t`` and ``sin t``:

    C(t) = (cos t - cos Omega t)/(Omega^2 - 1),  S(t) = (sin t - sin(Omega t)/Omega)/(Omega^2 - 1).

They are evaluated in product form (``cos t - cos Omega t = 2 sin(pt/2) sin(et/2)``
with ``p = Omega + 1``, ``e = Omega - 1``), so they stay exact at and near
resonance (Omega = 1, secular growth) and keep full relative accuracy for small
t. Everything here works on *increments* from the phase start, so an event
function that is zero at the start of a phase (the slip velocity after a stop)
keeps its sign right even a few 1e-12 after it.

An *observable* of a phase is ``y = A cos(tau) + y0 + sum_k alpha_k eta_k + delta_k eta_k'``
(slip: the contact velocity; stick: the contact force ``g``). The *event
function* is ``F = s y`` while sliding with sign s (a stop when F reaches 0) or
``F = beta - |y|`` while stuck (unsticking when F reaches 0).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.regimes import (
    CONTINUOUS,
    CREEP_FORCE_RTOL,
    CREEP_SLIP_RTOL,
    CREEP_WINDOW,
    EVENT_LIMIT,
    IC_HELD,
    IC_RANDOM,
    IC_REST,
    NO_MOTION,
    NOT_CONVERGED,
    NUMERICAL_FAILURE,
    SLIP_RTOL,
    STICK_SLIP,
    UNBOUNDED,
    WORK_LIMIT,
)

# Rows of the per-mode segment array ``seg`` (shape (N_ROWS, m)).
OMEGA, ETA0, ETAD0, LOAD_COS, LOAD_CONST, ALPHA, DELTA = range(7)
N_ROWS = 7
# Entries of the scalar segment array ``sc``.
TAU0, COS_TAU0, SIN_TAU0, OBS_COS, OBS0, KIND, SIGN, BETA, EVALS, WORK_CAP = range(10)
N_SCALARS = 10
KIND_SLIP = 0.0
KIND_STICK = 1.0
# Work units (``sc[EVALS]``, mode evaluations) charged per event and per N^2:
# the bookkeeping of an event (state projections, contact force) is O(N^2).
EVENT_WORK = 4.0
# Orbit invariant (:func:`orbit_holds`): stated tolerance of ``|g| <= beta`` in
# stick phases, relative to beta, and samples per shortest modal half-period.
ORBIT_RTOL = 1e-9
ORBIT_SAMPLES = 8.0
ORBIT_MAX_SAMPLES = 4096.0
# A stick phase ends when |g| exceeds beta by more than this (relative): the
# rounding of g's terms, as in :func:`never_unsticks` (else a tangential touch of
# |g| = beta at a no-motion boundary unsticks on rounding noise).
STICK_RTOL = 1e-12
# Sections a slow point's Newton settle tries (:func:`settle_at_phases`).
SETTLE_PHASES = 4
SETTLE_CYCLES = 150
# held_margin must exceed this fraction of beta to decide no motion (rounding of g_h).
HELD_MARGIN_RTOL = 1e-9


@njit(cache=True)
def sin_over(e: float, u: float) -> float:
    """``sin(e u) / e``, exact as e -> 0 (limit u)."""
    x = e * u
    if abs(x) < 1e-3:
        x2 = x * x
        return u * (1.0 - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0)))
    return math.sin(x) / e


@njit(cache=True)
def evaluate(seg, sc, t, eta, etad):
    """State and observable of a phase at time ``t`` after its start.

    Writes the modal displacements and velocities into ``eta`` and ``etad`` and
    returns ``(y, y')``, the observable and its derivative.
    """
    m = seg.shape[1]
    h = 0.5 * t
    sh = math.sin(h)
    ch = math.cos(h)
    sint = 2.0 * sh * ch
    ct0 = sc[COS_TAU0]
    st0 = sc[SIN_TAU0]
    ctau = ct0 * (1.0 - 2.0 * sh * sh) - st0 * sint
    stau = st0 * (1.0 - 2.0 * sh * sh) + ct0 * sint
    amp = sc[OBS_COS]
    # A (cos tau - cos tau0) = -2 A sin(tau0 + t/2) sin(t/2)
    y = sc[OBS0] - 2.0 * amp * (st0 * ch + ct0 * sh) * sh
    dy = -amp * stau
    for k in range(m):
        w = seg[OMEGA, k]
        hw = w * h
        s1 = math.sin(hw)
        c1 = math.cos(hw)
        sin_wt = 2.0 * s1 * c1
        one_m_cos = 2.0 * s1 * s1
        sdw = s1 / w
        p = w + 1.0
        e = w - 1.0
        sp = s1 * ch + c1 * sh
        cp = c1 * ch - s1 * sh
        sde = sin_over(e, h)
        cc = 2.0 * sp * sde / p
        cd = (sin_wt + 2.0 * cp * sde) / p
        if abs(e) < 0.5:
            ss = (sint - 2.0 * cp * sde) / (w * p)
        else:
            ss = (sint - 2.0 * sdw * c1) / (w * w - 1.0)
        e0 = seg[ETA0, k]
        v0 = seg[ETAD0, k]
        a = seg[LOAD_COS, k]
        c = seg[LOAD_CONST, k]
        d_eta = (
            -e0 * one_m_cos + v0 * 2.0 * sdw * c1 + c * 2.0 * sdw * sdw + a * (ct0 * cc - st0 * ss)
        )
        d_etad = -e0 * w * sin_wt - v0 * one_m_cos + c * 2.0 * sdw * c1 + a * (ct0 * cd - st0 * cc)
        ek = e0 + d_eta
        vk = v0 + d_etad
        eta[k] = ek
        etad[k] = vk
        y += seg[ALPHA, k] * d_eta + seg[DELTA, k] * d_etad
        dy += seg[ALPHA, k] * vk + seg[DELTA, k] * (-w * w * ek + a * ctau + c)
    return y, dy


@njit(cache=True)
def event_function(seg, sc, t, eta, etad):
    """``(F, F')`` at t: ``s y`` while sliding, ``beta - |y|`` while stuck.

    Counts the work in ``sc[EVALS]``, in mode evaluations (the budget of a point)."""
    sc[EVALS] += 1.0 + seg.shape[1]
    y, dy = evaluate(seg, sc, t, eta, etad)
    if sc[KIND] == KIND_SLIP:
        return sc[SIGN] * y, sc[SIGN] * dy
    if y >= 0.0:
        return sc[BETA] - y, -dy
    return sc[BETA] + y, dy


@njit(cache=True)
def derivative_bounds(seg, sc, t_end):
    """Upper bounds of ``|y'|`` and ``|y''|`` over ``[0, t_end]`` of a phase.

    ``y`` is the observable of the phase, so the bounds hold for ``|F'|`` and
    ``|F''|`` of both branches ``beta - y`` and ``beta + y`` of a stick phase.
    Every term is covered: the observable's own harmonic ``A cos(tau)`` and,
    mode by mode, the smaller of two bounds of ``|eta^(k)|`` (k = 1, 2, 3):

    * the modal split (module docstring, Eq. (1)): free oscillation of amplitude
      ``A_free`` about the static part ``c / Omega^2`` plus the harmonic particular
      part ``P = a / (Omega^2 - 1)``: ``Omega^k A_free + |P|``;
    * Duhamel's integral (valid at and near resonance, where the first bound
      grows without limit): free oscillation of amplitude
      ``A0 = |(eta0 - c / Omega^2, eta0' / Omega)|`` plus the zero-start forced
      response ``f`` of ``a cos(tau)``, with ``|f'| <= |a| t``,
      ``|f''| <= |a| (1 + Omega t)``, ``|f'''| <= |a| (1 + Omega^2 t)``:
      ``Omega^k A0 + (those)`` at ``t = t_end``.

    Both are multiplied by ``1 + 1e-9`` (a safety margin far above the rounding
    of the sums). Returns ``inf`` only for non-finite data.
    """
    harmonic = abs(sc[OBS_COS])
    d1 = harmonic
    d2 = harmonic
    for k in range(seg.shape[1]):
        w = seg[OMEGA, k]
        a = seg[LOAD_COS, k]
        c = seg[LOAD_CONST, k]
        e0 = seg[ETA0, k]
        v0 = seg[ETAD0, k]
        abs_a = abs(a)
        static = c / (w * w)
        # Duhamel: free part about the static offset, zero-start forced part
        a0 = math.hypot(e0 - static, v0 / w)
        b1 = w * a0 + abs_a * t_end
        b2 = w * w * a0 + abs_a * (1.0 + w * t_end)
        b3 = w * w * w * a0 + abs_a * (1.0 + w * w * t_end)
        den = w * w - 1.0
        if den != 0.0:
            pk = a / den
            d = e0 - static - pk * sc[COS_TAU0]
            e = (v0 + pk * sc[SIN_TAU0]) / w
            free = math.hypot(d, e)
            ap = abs(pk)
            b1 = min(b1, w * free + ap)
            b2 = min(b2, w * w * free + ap)
            b3 = min(b3, w * w * w * free + ap)
        alpha = abs(seg[ALPHA, k])
        delta = abs(seg[DELTA, k])
        d1 += alpha * b1 + delta * b2
        d2 += alpha * b2 + delta * b3
    d1 *= 1.0 + 1e-9
    d2 *= 1.0 + 1e-9
    if not (math.isfinite(d1) and math.isfinite(d2)):
        return np.inf, np.inf
    return d1, d2


@njit(cache=True)
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


@njit(cache=True)
def never_unsticks(seg, sc):
    """Certificate that a stick phase lasts for ever (docs/theory.md 4.2, held contact).

    While stuck, ``g = G0 + H cos(tau) + free modes``; if
    ``|G0| + |H| + sum_k |alpha_k| A_free,k <= beta`` then ``|g| <= beta`` at
    every future time, whatever the phases of the free modes.
    """
    harmonic = sc[OBS_COS]
    free_sum = 0.0
    # sc[OBS0] is g at tau0; rebuild the constant part from the modal split.
    const = sc[OBS0] - sc[OBS_COS] * sc[COS_TAU0]
    for k in range(seg.shape[1]):
        w = seg[OMEGA, k]
        den = w * w - 1.0
        if den == 0.0:
            return False
        pk = seg[LOAD_COS, k] / den
        static = seg[LOAD_CONST, k] / (w * w)
        d = seg[ETA0, k] - static - pk * sc[COS_TAU0]
        e = (seg[ETAD0, k] + pk * sc[SIN_TAU0]) / w
        alpha = seg[ALPHA, k]
        # g(tau0) contains alpha * eta0 = alpha * (static + P cos tau0 + d)
        const -= alpha * (pk * sc[COS_TAU0] + d)
        harmonic += alpha * pk
        free_sum += abs(alpha) * math.hypot(d, e)
    total = abs(const) + abs(harmonic) + free_sum
    # |g| <= beta sticks (Eq. 3, sgn in [-1, 1]): the bound itself is no motion
    # (Tables 1-3: beta >= bound); 1e-12 absorbs the rounding of the modal sums.
    return math.isfinite(total) and total <= sc[BETA] * (1.0 + 1e-12)


@njit(cache=True)
def _solve_bracket(seg, sc, which, lo, hi, flo, fhi, tol, eta, etad):
    """Illinois regula falsi on F (which=0) or F' (which=1) in a sign-changing bracket.

    ``flo`` and ``fhi`` have opposite signs (``fhi`` may be 0). Returns
    ``(lo, hi)`` with ``hi - lo <= tol``; ``hi`` is on the side of ``fhi``.
    """
    sign_lo = 1.0 if flo > 0.0 else -1.0
    side = 0
    width = hi - lo
    for _ in range(200):
        if hi - lo <= tol or fhi == 0.0:
            break
        t = (lo * fhi - hi * flo) / (fhi - flo)
        if not (lo < t < hi):
            t = 0.5 * (lo + hi)
        f, df = event_function(seg, sc, t, eta, etad)
        ft = f if which == 0 else df
        if ft * sign_lo > 0.0:
            lo = t
            flo = ft
            if side == 1:
                fhi *= 0.5
            side = 1
        else:
            hi = t
            fhi = ft
            if side == -1:
                flo *= 0.5
            side = -1
        # guarantee progress: bisect when the bracket did not halve in two steps
        new_width = hi - lo
        if new_width > 0.5 * width:
            t = 0.5 * (lo + hi)
            f, df = event_function(seg, sc, t, eta, etad)
            ft = f if which == 0 else df
            if ft * sign_lo > 0.0:
                lo = t
                flo = ft
            else:
                hi = t
                fhi = ft
            side = 0
        width = hi - lo
    return lo, hi


@njit(cache=True)
def _observe(seg, sc, t, eta, etad):
    """``(y, y')`` of the phase's observable at t, counting the work in ``sc[EVALS]``."""
    sc[EVALS] += 1.0 + seg.shape[1]
    return evaluate(seg, sc, t, eta, etad)


@njit(cache=True)
def _event_value(sc, y, dy):
    """``(F, F')`` from the observable: ``s y`` sliding, ``beta - |y|`` stuck."""
    if sc[KIND] == KIND_SLIP:
        return sc[SIGN] * y, sc[SIGN] * dy
    if y >= 0.0:
        return sc[BETA] - y, -dy
    return sc[BETA] + y, dy


@njit(cache=True)
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


@njit(cache=True)
def _out_of_work(sc):
    return sc[EVALS] > sc[WORK_CAP]


@njit(cache=True)
def _dip(seg, sc, ta, tb, ya, dya, yb, dyb, curvature, slope, tol, skip_graze, floor, eta, etad):
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
    zero known to rounding).
    """
    stack_a = np.empty(128)
    stack_b = np.empty(128)
    vals = np.empty((128, 4))
    stack_a[0] = ta
    stack_b[0] = tb
    vals[0, 0] = ya
    vals[0, 1] = dya
    vals[0, 2] = yb
    vals[0, 3] = dyb
    top = 1
    skip = skip_graze or sc[KIND] == KIND_STICK
    while top > 0:
        top -= 1
        a = stack_a[top]
        b = stack_b[top]
        y_a = vals[top, 0]
        d_a = vals[top, 1]
        y_b = vals[top, 2]
        d_b = vals[top, 3]
        if _clear(sc, y_a, d_a, y_b, d_b, b - a, curvature, slope):
            continue
        m = 0.5 * (a + b)
        if b - a <= tol or not (a < m < b) or top >= 126:
            if skip:
                continue
            return a, m, 2
        if _out_of_work(sc):
            return a, b, 3
        y_m, d_m = _observe(seg, sc, m, eta, etad)
        f_m, _ = _event_value(sc, y_m, d_m)
        if f_m <= -floor:
            return a, m, 1
        # right half first on the stack, so the left half is searched first
        stack_a[top] = m
        stack_b[top] = b
        vals[top, 0] = y_m
        vals[top, 1] = d_m
        vals[top, 2] = y_b
        vals[top, 3] = d_b
        top += 1
        stack_a[top] = a
        stack_b[top] = m
        vals[top, 0] = y_a
        vals[top, 1] = d_a
        vals[top, 2] = y_m
        vals[top, 3] = d_m
        top += 1
    return ta, tb, 0


@njit(cache=True)
def _first_zero(seg, sc, lo, hi, curvature, slope, tol, eta, etad):
    """The first zero of F in ``(lo, hi]`` (F(lo) > 0 >= F(hi), no zero before lo).

    Solves the bracket (:func:`_solve_bracket`), then proves with :func:`_dip`
    that F has no zero between ``lo`` and the root found; if it has, the search
    moves to the earlier sign change (or touching zero). Returns ``(t, ok)``,
    ``t`` on the far side of the first zero; ``ok`` is False if the work budget
    ran out.
    """
    while True:
        y_lo, dy_lo = _observe(seg, sc, lo, eta, etad)
        f_lo, _ = _event_value(sc, y_lo, dy_lo)
        y_hi, dy_hi = _observe(seg, sc, hi, eta, etad)
        f_hi, _ = _event_value(sc, y_hi, dy_hi)
        if not f_lo > 0.0:  # rounding at the bracket's end: take it as the zero
            return lo, True
        r_lo, r_hi = _solve_bracket(seg, sc, 0, lo, hi, f_lo, f_hi, tol, eta, etad)
        if r_lo <= lo:
            return r_hi, True
        y_r, dy_r = _observe(seg, sc, r_lo, eta, etad)
        a, b, kind = _dip(
            seg, sc, lo, r_lo, y_lo, dy_lo, y_r, dy_r, curvature, slope, tol, False, 0.0, eta, etad
        )
        if kind == 0:
            return r_hi, True
        if kind == 2:
            return b, True
        if kind == 3:
            return r_hi, False
        lo = a
        hi = b


@njit(cache=True)
def next_event(seg, sc, t_end, h, tol, eta, etad):
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
    y0, dy0 = _observe(seg, sc, 0.0, eta, etad)
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
            # (0, t1) is cleared from F(0) = 0 and F'(0) > 0, or searched
            lo, hi, kind = _dip(
                seg, sc, 0.0, t1, y0, dy0, y1, dy1, curvature, slope, tol, True, noise, eta, etad
            )
            if kind == 3:
                return t1, False
            if kind == 1 and lo > 0.0:
                return _first_zero(seg, sc, lo, hi, curvature, slope, tol, eta, etad)
            if kind == 1:
                t1 = hi
                f1 = -np.inf
        if not f1 > -noise:
            tm = t1
            for _ in range(60):
                tm = 0.5 * tm
                ym, dym = _observe(seg, sc, tm, eta, etad)
                fm, _ = _event_value(sc, ym, dym)
                if fm > 0.0:
                    return _first_zero(seg, sc, tm, t1, curvature, slope, tol, eta, etad)
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
            safe = fa / slope if slope > 0.0 else t_end - ta
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
            return _first_zero(seg, sc, ta, tb, curvature, slope, tol, eta, etad)
        if not certified:
            lo, hi, kind = _dip(
                seg, sc, ta, tb, ya, dya, yb, dyb, curvature, slope, tol, False, 0.0, eta, etad
            )
            if kind == 2:  # the contact velocity touches zero: a stop if it can stick
                return hi, True
            if kind == 1:
                return _first_zero(seg, sc, lo, hi, curvature, slope, tol, eta, etad)
            if kind == 3:
                return tb, False
        ta = tb
        ya = yb
        dya = dyb
        fa = fb
    return t_end, False


# Entries of the per-point context tuple ``ctx`` (built by :func:`_context`).
CTX_SEG_SLIP = 0
CTX_SEG_STICK = 1
CTX_SC = 2
CTX_BETA = 3
CTX_P = 4
CTX_K = 5
CTX_B = 6
CTX_W = 7
CTX_T = 8
CTX_PHI = 9
CTX_PHI_T_GAMMA = 10
CTX_PHI_S = 11
CTX_PHI_S_T_GAMMA_S = 12
CTX_PROJ = 13
CTX_F_R2 = 14
CTX_DSTAT_R2 = 15
CTX_G_LOAD = 16
CTX_G_COS = 17
CTX_G_D0 = 18
CTX_H_SLIP = 19
CTX_H_STICK = 20
CTX_TOL = 21
CTX_STICK_MIN = 22
CTX_MAX_EVENTS = 23
CTX_MAX_WORK = 24

TWO_PI = 2.0 * math.pi

# Entries of the per-cycle statistics array.
(
    ST_STOPS,
    ST_REVERSALS,
    ST_STUCK_TIME,
    ST_DMIN,
    ST_DMAX,
    ST_FOREVER,
    ST_EVENTS,
    ST_STATUS,
    ST_MID,
    ST_LONGEST,
) = range(10)
N_STATS = 10
STATUS_OK = 0.0

# Event records (tasks.trajectory): kinds and columns of the record buffer.
EV_SECTION, EV_STOP, EV_REVERSAL, EV_UNSTICK, EV_GRAZE, EV_END = 0.0, 1.0, 2.0, 3.0, 4.0, 5.0
REC_TAU, REC_KIND, REC_MODE, REC_G, REC_X = range(5)

# Fields of the per-point output array (see tasks.result.FIELDS).
OUT_REGIME, OUT_CONVERGED, OUT_CYCLES, OUT_STOPS, OUT_AMP, OUT_STICK, OUT_PERIOD, OUT_IC = range(8)
OUT_ASYMPTOTIC = 8
N_OUT = 9


@njit(cache=True)
def _matvec(a, x, out):
    for i in range(a.shape[0]):
        acc = 0.0
        for j in range(a.shape[1]):
            acc += a[i, j] * x[j]
        out[i] = acc


@njit(cache=True)
def _dot(a, b):
    acc = 0.0
    for i in range(a.shape[0]):
        acc += a[i] * b[i]
    return acc


@njit(cache=True)
def _contact_force(p, ctau, K, x, g_load):
    """g = g_load . (p cos tau - K x): the force the contact must transmit."""
    acc = 0.0
    n = x.shape[0]
    for i in range(n):
        kx = 0.0
        for j in range(n):
            kx += K[i, j] * x[j]
        acc += g_load[i] * (p[i] * ctau - kx)
    return acc


@njit(cache=True)
def _start_slip(seg, sc, x, xd, tau, s, v0, beta, f_r2, phi_t_gamma):
    _matvec(phi_t_gamma, x, seg[ETA0])
    _matvec(phi_t_gamma, xd, seg[ETAD0])
    for k in range(seg.shape[1]):
        seg[LOAD_CONST, k] = -beta * s * f_r2[k]
    sc[TAU0] = tau
    sc[COS_TAU0] = math.cos(tau)
    sc[SIN_TAU0] = math.sin(tau)
    sc[OBS_COS] = 0.0
    sc[OBS0] = v0
    sc[KIND] = KIND_SLIP
    sc[SIGN] = s
    sc[BETA] = beta


@njit(cache=True)
def _start_stick(seg, sc, x, xd, tau, beta, b, w, proj, phi_s_t_gamma_s, dstat_r2, g_cos, g_d0, q):
    """Freeze the contact at d0 = b . x; returns d0."""
    n = x.shape[0]
    m = seg.shape[1]
    d0 = _dot(b, x)
    # q = proj (x - d0 w), q' = proj x' (momentum-conserving)
    for i in range(m):
        acc = 0.0
        accd = 0.0
        for j in range(n):
            acc += proj[i, j] * (x[j] - d0 * w[j])
            accd += proj[i, j] * xd[j]
        q[i] = acc
        q[m + i] = accd
    for k in range(m):
        e0 = 0.0
        v0 = 0.0
        for i in range(m):
            e0 += phi_s_t_gamma_s[k, i] * q[i]
            v0 += phi_s_t_gamma_s[k, i] * q[m + i]
        seg[ETA0, k] = e0
        seg[ETAD0, k] = v0
        seg[LOAD_CONST, k] = -dstat_r2[k] * d0
    ctau = math.cos(tau)
    g0 = g_cos * ctau - g_d0 * d0
    for k in range(m):
        g0 += seg[ALPHA, k] * seg[ETA0, k]
    sc[TAU0] = tau
    sc[COS_TAU0] = ctau
    sc[SIN_TAU0] = math.sin(tau)
    sc[OBS_COS] = g_cos
    sc[OBS0] = g0
    sc[KIND] = KIND_STICK
    sc[SIGN] = 0.0
    sc[BETA] = beta * (1.0 + STICK_RTOL)
    return d0


@njit(cache=True)
def _slip_state(phi, eta, etad, x, xd):
    _matvec(phi, eta, x)
    _matvec(phi, etad, xd)


@njit(cache=True)
def _stick_state(phi_s, T, w, d0, eta, etad, q, x, xd):
    m = eta.shape[0]
    n = x.shape[0]
    for i in range(m):
        acc = 0.0
        accd = 0.0
        for k in range(m):
            acc += phi_s[i, k] * eta[k]
            accd += phi_s[i, k] * etad[k]
        q[i] = acc
        q[m + i] = accd
    for j in range(n):
        acc = d0 * w[j]
        accd = 0.0
        for i in range(m):
            acc += T[j, i] * q[i]
            accd += T[j, i] * q[m + i]
        x[j] = acc
        xd[j] = accd


@njit(cache=True)
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


@njit(cache=True)
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
    ) = ctx
    eta, etad, eta_s, etad_s, q = work
    for i in range(N_STATS):
        stats[i] = 0.0
    d = _dot(b, x)
    stats[ST_DMIN] = d
    stats[ST_DMAX] = d
    tau = tau_start
    v0 = _dot(b, xd)
    events = 0
    _record(
        rec, rec_n, tau, EV_SECTION, mode, _contact_force(p, math.cos(tau), K, x, g_load), x, xd
    )
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
            if never_unsticks(seg_stick, sc):
                stats[ST_FOREVER] = 1.0
                t, found = remaining, False
            else:
                t, found = next_event(seg_stick, sc, remaining, h_stick, tol, eta_s, etad_s)
            g, _ = evaluate(seg_stick, sc, t, eta_s, etad_s)
            _stick_state(phi_s, T, w, d0, eta_s, etad_s, q, x, xd)
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
            t, found = next_event(seg_slip, sc, remaining, h_slip, tol, eta, etad)
            evaluate(seg_slip, sc, t, eta, etad)
            _slip_state(phi, eta, etad, x, xd)
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
    _record(
        rec, rec_n, tau_end, EV_END, mode, _contact_force(p, math.cos(tau_end), K, x, g_load), x, xd
    )
    return mode, stick_start


@njit(cache=True)
def _max_abs(v):
    acc = 0.0
    for i in range(v.shape[0]):
        a = abs(v[i])
        if a > acc:
            acc = a
    return acc


@njit(cache=True)
def _max_abs_diff(a, b):
    acc = 0.0
    for i in range(a.shape[0]):
        d = abs(a[i] - b[i])
        if d > acc:
            acc = d
    return acc


@njit(cache=True)
def _advance(X, mode, stick_start, stats, ctx, work, tau_start, tau_end):
    """``X = (x, x')`` at ``tau_start`` -> state at ``tau_end``; returns the new state."""
    n = X.shape[0] // 2
    x = X[:n].copy()
    xd = X[n:].copy()
    no_record = np.zeros((0, 1))
    no_count = np.zeros(1, dtype=np.int64)
    mode, stick_start = run_cycle(
        x, xd, mode, stick_start, stats, ctx, work, no_record, no_count, tau_start, tau_end
    )
    out = np.empty(2 * n)
    out[:n] = x
    out[n:] = xd
    return out, mode, stick_start


@njit(cache=True)
def _cycle(X, mode, stick_start, stats, ctx, work, theta):
    """One period from the section state ``X = (x, x')`` at ``tau = theta``.

    Returns the new section state, its phase and the stick start shifted by one
    period (so that it stays relative to the section).
    """
    X1, mode, stick_start = _advance(X, mode, stick_start, stats, ctx, work, theta, theta + TWO_PI)
    return X1, mode, stick_start - TWO_PI


@njit(cache=True)
def _finish(out, stats, stats_prev, period, cycles, ic_used):
    """Regime, stops, amplitude and stick fraction of a converged period."""
    stops = stats[ST_STOPS]
    stuck = stats[ST_STUCK_TIME]
    dmin = stats[ST_DMIN]
    dmax = stats[ST_DMAX]
    moved = stats[ST_EVENTS] > 0.0 or stuck < TWO_PI * (1.0 - 1e-12)
    if period == 2:
        stops += stats_prev[ST_STOPS]
        stuck += stats_prev[ST_STUCK_TIME]
        dmin = min(dmin, stats_prev[ST_DMIN])
        dmax = max(dmax, stats_prev[ST_DMAX])
        moved = moved or stats_prev[ST_EVENTS] > 0.0
    if not moved:
        regime = NO_MOTION
    elif stops > 0.0:
        regime = STICK_SLIP
    else:
        regime = CONTINUOUS
    out[OUT_REGIME] = regime
    out[OUT_CONVERGED] = 1.0
    out[OUT_CYCLES] = cycles
    out[OUT_STOPS] = stops
    out[OUT_AMP] = 0.5 * (dmax - dmin) if moved else 0.0
    out[OUT_STICK] = stuck / (TWO_PI * period)
    out[OUT_PERIOD] = period
    out[OUT_IC] = ic_used


@njit(cache=True)
def _undetermined(out, code, cycles, ic_used):
    out[OUT_REGIME] = code
    out[OUT_CONVERGED] = 0.0
    out[OUT_CYCLES] = cycles
    out[OUT_STOPS] = 0.0
    out[OUT_AMP] = np.nan
    out[OUT_STICK] = np.nan
    out[OUT_PERIOD] = 0.0
    out[OUT_IC] = ic_used


@njit(cache=True)
def _reduce(X, mode, b, w, proj):
    """Coordinates of the section state in its phase: ``(x, x')`` while sliding,
    ``(d0, q, q')`` while stuck (the contact frozen: ``x = T q + d0 w``, ``x' = T q'``)."""
    if mode != 0:
        return X.copy()
    n = X.shape[0] // 2
    m = proj.shape[0]
    y = np.empty(2 * m + 1)
    d0 = _dot(b, X[:n])
    y[0] = d0
    for i in range(m):
        acc = 0.0
        accd = 0.0
        for j in range(n):
            acc += proj[i, j] * (X[j] - d0 * w[j])
            accd += proj[i, j] * X[n + j]
        y[1 + i] = acc
        y[1 + m + i] = accd
    return y


@njit(cache=True)
def _expand(y, mode, n, w, T):
    """Inverse of :func:`_reduce`."""
    if mode != 0:
        return y.copy()
    m = T.shape[1]
    X = np.zeros(2 * n)
    for j in range(n):
        acc = y[0] * w[j]
        accd = 0.0
        for i in range(m):
            acc += T[j, i] * y[1 + i]
            accd += T[j, i] * y[1 + m + i]
        X[j] = acc
        X[n + j] = accd
    return X


@njit(cache=True)
def _phase_of(X, mode, b):
    """Phase a section state starts in: stuck stays stuck; a sliding state slides
    with the sign of its contact velocity (the flow is continuous across a
    reversal, so both signs belong to one chart)."""
    if mode == 0:
        return 0
    n = X.shape[0] // 2
    v = _dot(b, X[n:])
    if v > 0.0:
        return 1
    if v < 0.0:
        return -1
    return mode


@njit(cache=True)
def _same_chart(mode_a, mode_b):
    return (mode_a == 0) == (mode_b == 0)


@njit(cache=True)
def _fd_jacobian(y0, y1, mode, ctx, work, scale, J, theta):
    """``J = dP/dy - I`` by forward differences (one period per column).

    Returns the periods used, or -1 if a perturbed period left the chart.
    """
    n = ctx[CTX_P].shape[0]
    b = ctx[CTX_B]
    w = ctx[CTX_W]
    T = ctx[CTX_T]
    proj = ctx[CTX_PROJ]
    dim = y0.shape[0]
    probe = np.empty(N_STATS)
    for k in range(dim):
        hk = 1e-7 * max(abs(y0[k]), 1e-3 * scale)
        yp = y0.copy()
        yp[k] += hk
        Xp = _expand(yp, mode, n, w, T)
        Pk, mk, _ = _cycle(Xp, _phase_of(Xp, mode, b), theta, probe, ctx, work, theta)
        if not _same_chart(mk, mode) or probe[ST_STATUS] != STATUS_OK:
            return -1
        yk = _reduce(Pk, mode, b, w, proj)
        for i in range(dim):
            J[i, k] = (yk[i] - y1[i]) / hk
        J[k, k] -= 1.0
    return dim


@njit(cache=True)
def _shoot(X0, mode, stats, ctx, work, rtol, floor, max_newton, theta):
    """Newton's method on the Poincare map ``P(X) - X = 0`` (shooting).

    Works in the coordinates of the phase the section falls in
    (:func:`_reduce`); the section must fall in the same kind of phase (stuck
    or sliding) before and after the period. The Jacobian is built once by
    forward differences (one period per column) and then updated by Broyden's
    rank-one formula (one period per iteration). A fixed point is accepted only
    if its residual is below ``rtol`` of the motion (or of ``floor``, the static
    response) and it is not unstable (spectral radius of ``dP/dy`` at most
    1 + 1e-6): shooting must find the attractor, not any periodic orbit.

    Returns ``(success, X, cycles_used)``; on success ``stats`` holds the
    statistics of the verified period ``X -> P(X)``.
    """
    n = X0.shape[0] // 2
    b = ctx[CTX_B]
    w = ctx[CTX_W]
    T = ctx[CTX_T]
    proj = ctx[CTX_PROJ]
    cycles = 0
    y0 = _reduce(X0, mode, b, w, proj)
    X0 = _expand(y0, mode, n, w, T)
    X1, m1, _ = _cycle(X0, _phase_of(X0, mode, b), theta, stats, ctx, work, theta)
    cycles += 1
    if not _same_chart(m1, mode) or stats[ST_STATUS] != STATUS_OK or stats[ST_FOREVER] > 0.0:
        return False, X0, cycles
    y1 = _reduce(X1, mode, b, w, proj)
    dim = y0.shape[0]
    J = np.empty((dim, dim))
    scale = max(_max_abs(X1), 1e-300)
    used = _fd_jacobian(y0, y1, mode, ctx, work, scale, J, theta)
    if used < 0:
        return False, X0, cycles + dim
    cycles += used
    if not np.all(np.isfinite(J)):
        return False, X0, cycles
    fresh = True
    for _ in range(max_newton):
        R = y1 - y0
        scale = max(_max_abs(X1), 1e-300)
        res = _max_abs(R)
        if res <= rtol * max(scale, floor):
            dP = J.copy()
            for i in range(dim):
                dP[i, i] += 1.0
            radius = np.max(np.abs(np.linalg.eigvals(dP.astype(np.complex128))))
            return radius <= 1.0 + 1e-6, X0, cycles
        try:
            step = np.linalg.solve(J, -R)
        except Exception:  # singular: no isolated fixed point (e.g. resonance)
            return False, X0, cycles
        # trust region: a fixed point far beyond the current motion is not a
        # settled transient but a (near-)singular map, e.g. resonant growth
        if not np.all(np.isfinite(step)) or _max_abs(step) > 10.0 * scale:
            return False, X0, cycles
        lam = 1.0
        accepted = False
        for _ls in range(5):
            yn = y0 + lam * step
            Xn = _expand(yn, mode, n, w, T)
            X1n, mn, _ = _cycle(Xn, _phase_of(Xn, mode, b), theta, stats, ctx, work, theta)
            cycles += 1
            if _same_chart(mn, mode) and stats[ST_STATUS] == STATUS_OK and stats[ST_FOREVER] == 0.0:
                y1n = _reduce(X1n, mode, b, w, proj)
                Rn = y1n - yn
                if _max_abs(Rn) < res:
                    # Broyden: J += ((Rn - R) - J s) s^T / (s . s), s = yn - y0
                    sv = yn - y0
                    ss = _dot(sv, sv)
                    if ss > 0.0:
                        u = (Rn - R) - J @ sv
                        for i in range(dim):
                            for k in range(dim):
                                J[i, k] += u[i] * sv[k] / ss
                    y0 = yn
                    y1 = y1n
                    X0 = Xn
                    X1 = X1n
                    accepted = True
                    fresh = False
                    break
            lam *= 0.5
        if not accepted:
            if fresh:
                return False, X0, cycles
            # the updated Jacobian went stale: rebuild it once here
            used = _fd_jacobian(y0, y1, mode, ctx, work, scale, J, theta)
            if used < 0:
                return False, X0, cycles + dim
            cycles += used
            fresh = True
    return False, X0, cycles


@njit(cache=True)
def newton_settle(X0, mode, stats, ctx, work, rtol, floor, max_iter, theta):
    """Newton's method on the Poincare map with a fresh Jacobian at every step.

    The fallback for slow points (a Floquet multiplier near 1, e.g. next to an
    antiresonance, where the held system is nearly resonant and the free mode
    beats with the excitation over thousands of periods), where the
    Broyden-updated shooting of :func:`_shoot` fails its line search. Works in
    the chart of ``mode`` (:func:`_reduce`); an iterate may leave the chart for a
    step (its image is projected back), but the fixed point must lie in it. A
    fixed point is accepted only if its residual is below ``rtol`` of the motion
    (or of ``floor``) and it is not unstable (spectral radius of the Jacobian at
    the fixed point at most 1 + 1e-6), so it is an attractor, reached from the
    point's own trajectory. Costs ``dim + 1`` periods per step.

    Returns ``(success, X, cycles_used)``; on success ``stats`` holds the
    statistics of the verified period ``X -> P(X)``.
    """
    n = X0.shape[0] // 2
    b = ctx[CTX_B]
    w = ctx[CTX_W]
    T = ctx[CTX_T]
    proj = ctx[CTX_PROJ]
    y = _reduce(X0, mode, b, w, proj)
    dim = y.shape[0]
    J = np.empty((dim, dim))
    cycles = 0
    for _ in range(max_iter):
        X = _expand(y, mode, n, w, T)
        P, m1, _s = _cycle(X, _phase_of(X, mode, b), theta, stats, ctx, work, theta)
        cycles += 1
        if stats[ST_STATUS] != STATUS_OK or stats[ST_FOREVER] > 0.0:
            return False, X, cycles
        y1 = _reduce(P, mode, b, w, proj)
        R = y1 - y
        scale = max(_max_abs(P), 1e-300)
        used = _fd_jacobian(y, y1, mode, ctx, work, scale, J, theta)
        if used < 0 or not np.all(np.isfinite(J)):
            return False, X, cycles + dim
        cycles += used
        if _max_abs(R) <= rtol * max(scale, floor) and _same_chart(m1, mode):
            dP = J.copy()
            for i in range(dim):
                dP[i, i] += 1.0
            radius = np.max(np.abs(np.linalg.eigvals(dP.astype(np.complex128))))
            if radius > 1.0 + 1e-6:
                return False, X, cycles
            _cycle(X, _phase_of(X, mode, b), theta, stats, ctx, work, theta)
            return True, X, cycles + 1
        try:
            step = np.linalg.solve(J, -R)
        except Exception:  # singular: no isolated fixed point
            return False, X, cycles
        if not np.all(np.isfinite(step)) or _max_abs(step) > 100.0 * max(scale, floor):
            return False, X, cycles
        y = y + step
    return False, _expand(y, mode, n, w, T), cycles


@njit(cache=True)
def settle_at_phases(X, mode, stick_start, stats, ctx, work, rtol, floor, theta, n_phases):
    """:func:`newton_settle` from the section at ``theta`` (up to 30 steps), then
    from ``n_phases - 1`` sections moved by ``1 / n_phases`` of the period each
    (about ``SETTLE_CYCLES`` periods each, i.e. 30 Newton steps for 2 DOF and 13
    for 5 DOF). Used with one phase for the slow-point settles of the iteration
    and with ``SETTLE_PHASES`` as the last resort when ``max_cycles`` is spent.

    The Poincare map of a slow point can be smooth at one phase and cut by an
    event (a stop or a reversal that moves with the iterate) at another, where
    Newton's method with difference Jacobians stalls. The trajectory is carried
    to each new section (one part of a period); the fixed point is accepted with
    the same conditions (residual, not unstable) at whichever section finds it.

    Returns ``(success, X, mode, theta, cycles_used)``: the fixed point, its phase
    and its section; on success ``stats`` holds the statistics of the verified
    period.
    """
    used_total = 0
    Xa = X
    mode_a = mode
    start_a = stick_start
    theta_a = theta
    for j in range(n_phases):
        if j > 0:
            target = theta_a + TWO_PI / n_phases
            Xa, mode_a, start_a = _advance(Xa, mode_a, start_a, stats, ctx, work, theta_a, target)
            if stats[ST_STATUS] != STATUS_OK:
                break
            theta_a = target - TWO_PI * math.floor(target / TWO_PI)
            start_a -= target - theta_a
        # the extra sections get about SETTLE_CYCLES periods each (dim + 1 per step)
        steps = 30 if j == 0 else max(4, SETTLE_CYCLES // (X.shape[0] + 1))
        ok, Xs, used = newton_settle(Xa, mode_a, stats, ctx, work, rtol, floor, steps, theta_a)
        used_total += used
        if ok:
            mode_s = start_phase(Xs, ctx[CTX_BETA], ctx, theta_a) if mode_a != 0 else 0
            return True, Xs, mode_s, theta_a, used_total
    return False, X, mode, theta, used_total


@njit(cache=True)
def _context(r, beta, scene, settings):
    """Per-point constants of both phases, the held initial condition and its phase.

    ``scene`` is :meth:`tasks.model.SceneModes.kernel_args`, ``settings`` is
    :func:`tasks.classifier.settings_args`. Returns ``(ctx, work, X0, mode0,
    ic_used)``: ``ctx`` is the tuple :func:`run_cycle` takes, ``X0 = (x, x')``
    the initial section state.
    """
    (
        gamma,
        K,
        b,
        p0,
        load_scales_r2,
        lam,
        phi,
        phi_t_gamma,
        w_slip,
        f_slip,
        T,
        w,
        lam_s,
        phi_s,
        phi_s_t_gamma_s,
        load_s,
        d_static,
        proj,
        g_load,
        g_modes_s,
        g_d0,
    ) = scene
    event_tol = settings[0]
    step_fraction = settings[1]
    max_events = settings[7]
    initial_condition = settings[9]
    max_work = settings[10]
    n = gamma.shape[0]
    m = lam_s.shape[0]
    r2 = r * r
    p = p0 * r2 if load_scales_r2 else p0.copy()
    seg_slip = np.zeros((N_ROWS, n))
    om_max = 1.0
    for k in range(n):
        om = math.sqrt(lam[k]) / r
        seg_slip[OMEGA, k] = om
        acc = 0.0
        for i in range(n):
            acc += phi[i, k] * p[i]
        seg_slip[LOAD_COS, k] = acc / r2
        seg_slip[DELTA, k] = w_slip[k]
        om_max = max(om_max, om)
    h_slip = step_fraction * math.pi / om_max
    om_slip = om_max
    seg_stick = np.zeros((N_ROWS, m))
    om_max = 1.0
    for k in range(m):
        om = math.sqrt(lam_s[k]) / r
        seg_stick[OMEGA, k] = om
        acc = 0.0
        for i in range(n):
            acc += load_s[k, i] * p[i]
        seg_stick[LOAD_COS, k] = acc / r2
        seg_stick[ALPHA, k] = -g_modes_s[k]
        om_max = max(om_max, om)
    h_stick = step_fraction * math.pi / om_max
    sc = np.zeros(N_SCALARS)
    sc[WORK_CAP] = max_work
    ctx = (
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
        f_slip / r2,
        d_static / r2,
        g_load,
        _dot(g_load, p),
        g_d0,
        h_slip,
        h_stick,
        event_tol,
        1e3 * event_tol,
        max(max_events, _event_cap(8.0 * max(om_slip, om_max))),
        max_work,
    )
    work = (np.zeros(n), np.zeros(n), np.zeros(m), np.zeros(m), np.zeros(2 * m))
    # Held start: contact at d0 = 0, the rest on the forced response of the
    # held system at tau = 0 (from rest if the held system is resonant).
    X_held, held_exists = _held_response(seg_stick, phi_s, T, n)
    ic_used = initial_condition
    X = np.zeros(2 * n)
    if initial_condition == IC_HELD or initial_condition >= IC_RANDOM:
        if held_exists:
            X = X_held
        else:
            ic_used = IC_REST
    if initial_condition >= IC_RANDOM:
        X = _random_start(X, gamma, K, p, r, beta, initial_condition - IC_RANDOM, settings[11])
        ic_used = initial_condition
        return ctx, work, X, start_phase(X, beta, ctx, 0.0), ic_used
    g0 = _contact_force(p, 1.0, K, X[:n], g_load)
    mode = 0 if abs(g0) <= beta else (1 if g0 > 0.0 else -1)
    return ctx, work, X, mode, ic_used


@njit(cache=True)
def _held_response(seg_stick, phi_s, T, n):
    """The held steady state at ``tau = 0``: contact held at zero relative
    displacement, the other coordinates on the forced response of the held
    system (``x_h(tau) = x_h(0) cos tau``). Returns ``(X, exists)``; it does not
    exist when a loaded mode of the held system is resonant."""
    m = seg_stick.shape[1]
    X = np.zeros(2 * n)
    zeta = np.zeros(m)
    for k in range(m):
        den = seg_stick[OMEGA, k] ** 2 - 1.0
        if seg_stick[LOAD_COS, k] == 0.0:
            continue  # mode not loaded: no forced response
        if abs(den) < 1e-9 * max(seg_stick[OMEGA, k] ** 2, 1.0):
            return X, False
        zeta[k] = seg_stick[LOAD_COS, k] / den
    for i in range(m):
        qi = 0.0
        for k in range(m):
            qi += phi_s[i, k] * zeta[k]
        for j in range(n):
            X[j] += T[j, i] * qi
    return X, True


@njit(cache=True)
def held_margin(ctx):
    """``beta - max_tau |g_h|``: how far inside the friction limit the held steady
    state stays, or ``-inf`` where the held system is resonant.

    The held steady state (:func:`_held_response`) needs the contact force
    ``g_h(tau) = g_h(0) cos tau``. When the margin ``delta`` is positive, every
    start reaches no motion (docs/theory.md 3, "every start reaches no motion
    above the motion bound"): Coulomb friction is monotone, so the energy of the
    difference between any motion and the held one decreases by at least
    ``delta |v|`` per unit time while the contact slides, and the total future
    sliding is at most that energy over ``delta``.
    """
    seg_stick = ctx[CTX_SEG_STICK]
    n = ctx[CTX_P].shape[0]
    X, exists = _held_response(seg_stick, ctx[CTX_PHI_S], ctx[CTX_T], n)
    if not exists:
        return -np.inf
    g0 = _contact_force(ctx[CTX_P], 1.0, ctx[CTX_K], X[:n], ctx[CTX_G_LOAD])
    return ctx[CTX_BETA] - abs(g0)


@njit(cache=True)
def creep_threshold(ctx, beta):
    """Slip amplitude below which a slip is not motion: ``SLIP_RTOL * beta * c``.

    ``c = b^T K^-1 b`` is the static compliance the contact sees, so ``beta c``
    is the static deflection the friction force produces at the contact. A slip
    of amplitude ``a`` changes the spring force at the contact by about
    ``a / c``; below the threshold that is less than ``SLIP_RTOL`` of the
    friction force, i.e. indistinguishable from holding with a friction ratio
    changed by one part in ``1 / SLIP_RTOL`` (docs/theory.md 3, creep).
    """
    b = ctx[CTX_B]
    c = _dot(b, np.linalg.solve(ctx[CTX_K], b))
    return SLIP_RTOL * beta * abs(c)


@njit(cache=True)
def stick_force_bound(seg, sc):
    """``|G0| + |H| + sum_k |alpha_k| A_free,k``: the largest ``|g|`` a stick phase
    can ever reach (the bound of :func:`never_unsticks`; tight when the free
    frequencies are incommensurate with the excitation and each other)."""
    harmonic = sc[OBS_COS]
    free_sum = 0.0
    const = sc[OBS0] - sc[OBS_COS] * sc[COS_TAU0]
    for k in range(seg.shape[1]):
        w = seg[OMEGA, k]
        den = w * w - 1.0
        if den == 0.0:
            return np.inf
        pk = seg[LOAD_COS, k] / den
        static = seg[LOAD_CONST, k] / (w * w)
        d = seg[ETA0, k] - static - pk * sc[COS_TAU0]
        e = (seg[ETAD0, k] + pk * sc[SIN_TAU0]) / w
        alpha = seg[ALPHA, k]
        const -= alpha * (pk * sc[COS_TAU0] + d)
        harmonic += alpha * pk
        free_sum += abs(alpha) * math.hypot(d, e)
    return abs(const) + abs(harmonic) + free_sum


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
    _start_stick(
        seg,
        sc,
        X[:n].copy(),
        X[n:].copy(),
        theta,
        beta,
        ctx[CTX_B],
        ctx[CTX_W],
        ctx[CTX_PROJ],
        ctx[CTX_PHI_S_T_GAMMA_S],
        ctx[CTX_DSTAT_R2],
        ctx[CTX_G_COS],
        ctx[CTX_G_D0],
        work,
    )
    bound = stick_force_bound(seg, sc)
    return math.isfinite(bound) and bound <= beta * (1.0 + CREEP_FORCE_RTOL)


@njit(cache=True)
def _creep_limit(out, slip_tol):
    """A converged stick-slip orbit whose slip is below the creep threshold is
    no motion (reached asymptotically; the measured slip stays in ``out``)."""
    if out[OUT_REGIME] == STICK_SLIP and out[OUT_AMP] < slip_tol:
        out[OUT_REGIME] = NO_MOTION
        out[OUT_STOPS] = 0.0
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


@njit(cache=True)
def _no_motion_by_margin(out, ic_used):
    """No motion reached from a start off the held steady state, decided by
    :func:`held_margin` without simulating (``cycles = 0``, flagged asymptotic)."""
    out[OUT_REGIME] = NO_MOTION
    out[OUT_CONVERGED] = 1.0
    out[OUT_CYCLES] = 0.0
    out[OUT_STOPS] = 0.0
    out[OUT_AMP] = 0.0
    out[OUT_STICK] = 1.0
    out[OUT_PERIOD] = 1.0
    out[OUT_IC] = ic_used
    out[OUT_ASYMPTOTIC] = 1.0


@njit(cache=True)
def _random_start(X_held, gamma, K, p, r, beta, k, seed):
    """Seeded random start number ``k`` on the energy scale of the forced response.

    A random direction in the state space ``(x, x')`` scaled to an energy
    ``E = 1/2 x^T K x + 1/2 x'^T M x'`` drawn uniformly in ``(0, 2 E_ref]``,
    ``E_ref`` the larger of the energies of the held start (the forced response
    of the held system) and of the static response ``K^-1 p``. The stream
    depends only on ``(seed, k, r, beta)``: the same point gets the same starts
    in any chunk and on any worker.
    """
    n = K.shape[0]
    h = (seed * 1000003 + k * 7919) & 0x7FFFFFFF
    h = (h * 31 + int(r * 1e9)) & 0x7FFFFFFF
    h = (h * 31 + int(beta * 1e9)) & 0x7FFFFFFF
    np.random.seed(h)  # noqa: NPY002 (numba: the legacy API only)
    x_stat = np.linalg.solve(K, p)
    e_ref = max(_energy(X_held, gamma, K, r), 0.5 * _dot(x_stat, p), 1e-300)
    X = np.empty(2 * n)
    for i in range(2 * n):
        X[i] = np.random.standard_normal()  # noqa: NPY002
    e = _energy(X, gamma, K, r)
    u = 1.0 - np.random.random()  # noqa: NPY002
    scale = math.sqrt(2.0 * e_ref * u / max(e, 1e-300))
    for i in range(2 * n):
        X[i] *= scale
    return X


@njit(cache=True)
def _energy(X, gamma, K, r):
    """``1/2 x^T K x + 1/2 x'^T M x'`` with ``M = r^2 diag(gamma)`` (Eq. 68)."""
    n = K.shape[0]
    e = 0.0
    for i in range(n):
        e += 0.5 * r * r * gamma[i] * X[n + i] * X[n + i]
        for j in range(n):
            e += 0.5 * X[i] * K[i, j] * X[j]
    return e


@njit(cache=True)
def start_phase(X, beta, ctx, theta):
    """Phase a section state starts in: sliding with the sign of ``b . x'``, or
    (at rest relative to the contact) stuck if ``|g| <= beta``."""
    p = ctx[CTX_P]
    K = ctx[CTX_K]
    b = ctx[CTX_B]
    g_load = ctx[CTX_G_LOAD]
    n = X.shape[0] // 2
    v = _dot(b, X[n:])
    if v > 0.0:
        return 1
    if v < 0.0:
        return -1
    g0 = _contact_force(p, math.cos(theta), K, X[:n], g_load)
    return 0 if abs(g0) <= beta else (1 if g0 > 0.0 else -1)


@njit(cache=True)
def _linear_amplitude(seg_slip):
    """Amplitude of ``b . x`` on the forced response of the sliding system without
    friction: ``|b . (K - M)^-1 p|`` (inf at a resonance)."""
    amp = 0.0
    for k in range(seg_slip.shape[1]):
        den = seg_slip[OMEGA, k] ** 2 - 1.0
        if den == 0.0:
            return np.inf
        amp += seg_slip[DELTA, k] * seg_slip[LOAD_COS, k] / den
    return abs(amp)


@njit(cache=True)
def _resonant_growth(seg_slip, f_r2, beta):
    """Den Hartog's resonance rule, extended mode by mode (docs/theory.md 3).

    At an exact resonance of the sliding system (``Omega_k = 1``) the load feeds
    mode k with ``pi |a_k| A`` per cycle while the contact dissipates at most
    ``4 beta |phi_k . b| A / r^2``; the amplitude A grows without bound when
    ``beta < pi |a_k| / (4 |f_k|)`` (SDOF: beta < pi/4). Used only where the
    rate of growth can be too slow to see in simulation.
    """
    for k in range(seg_slip.shape[1]):
        w = seg_slip[OMEGA, k]
        a = seg_slip[LOAD_COS, k]
        if abs(w * w - 1.0) <= 1e-12 and a != 0.0:
            if 4.0 * beta * abs(f_r2[k]) < math.pi * abs(a):
                return True
    return False


@njit(cache=True)
def simulate_point(r, beta, scene, settings, out, final):
    """Classify one (r, beta) point; writes the fields into ``out`` and the last
    section state and phase ``(x, x', mode)`` into ``final``."""
    (
        _event_tol,
        _step_fraction,
        section_rtol,
        max_cycles,
        min_cycles,
        shooting,
        shooting_after,
        _max_events,
        growth_factor,
        _initial_condition,
        _max_work,
        _seed,
    ) = settings
    ctx, work, X, mode, ic_used = _context(r, beta, scene, settings)
    out[OUT_ASYMPTOTIC] = 0.0
    slip_tol = creep_threshold(ctx, beta)
    small_run = 0
    quiet_run = 0
    n = X.shape[0] // 2
    theta = 0.0  # phase of the Poincare section
    final[: 2 * n] = X
    final[2 * n] = mode
    final[2 * n + 1] = theta
    if beta == 0.0:  # undamped linear system: continuous by definition
        amp = _linear_amplitude(ctx[CTX_SEG_SLIP])
        if not math.isfinite(amp):  # ... unless exactly at a resonance
            _undetermined(out, UNBOUNDED, 0, ic_used)
            return
        out[OUT_REGIME] = CONTINUOUS
        out[OUT_CONVERGED] = 1.0
        out[OUT_CYCLES] = 0.0
        out[OUT_STOPS] = 0.0
        out[OUT_AMP] = amp
        out[OUT_STICK] = 0.0
        out[OUT_PERIOD] = 1.0
        out[OUT_IC] = ic_used
        return
    if ic_used != IC_HELD and held_margin(ctx) > HELD_MARGIN_RTOL * beta:
        # every start reaches no motion (held_margin): the limit is the held
        # steady state plus a free vibration of the held system that the
        # contact never feels enough to slide
        X_held, _ = _held_response(ctx[CTX_SEG_STICK], ctx[CTX_PHI_S], ctx[CTX_T], n)
        final[: 2 * n] = X_held
        final[2 * n] = 0
        _no_motion_by_margin(out, ic_used)
        return
    if _resonant_growth(ctx[CTX_SEG_SLIP], ctx[CTX_F_R2], beta):
        _undetermined(out, UNBOUNDED, 0, ic_used)
        return
    stats = np.zeros(N_STATS)
    stats_prev = np.zeros(N_STATS)
    X_prev = X.copy()
    mode_prev = mode
    mode_prev2 = mode
    X_prev2 = X.copy()
    diff_prev = np.inf
    # scale of the motion: the static response to the load amplitude, or more
    ref = max(_max_abs(X), _max_abs(np.linalg.solve(ctx[CTX_K], ctx[CTX_P])), 1e-300)
    stick_start = 0.0
    cycles = 0
    next_shot = shooting_after
    shots_failed = 0
    unit_ratio_run = 0
    run_start_scale = 0.0
    chart_flips = 0
    moves = 0
    while cycles < max_cycles:
        X_new, mode_new, stick_start = _cycle(X, mode, stick_start, stats, ctx, work, theta)
        cycles += 1
        final[: 2 * n] = X_new
        final[2 * n] = mode_new
        final[2 * n + 1] = theta
        status = stats[ST_STATUS]
        if status != STATUS_OK:
            _undetermined(out, status, cycles, ic_used)
            return
        if stats[ST_FOREVER] > 0.0:  # stuck for ever: no motion
            final[: 2 * n] = X
            final[2 * n] = mode
            stats[ST_EVENTS] = 0.0
            stats[ST_STUCK_TIME] = TWO_PI
            stats[ST_STOPS] = 0.0
            _finish(out, stats, stats_prev, 1, cycles, ic_used)
            return
        X_prev2 = X_prev
        X_prev = X
        mode_prev2 = mode_prev
        mode_prev = mode
        X = X_new
        mode = mode_new
        # creep towards the stuck set: small slips for a window of cycles, most
        # cycles without any event (so no orbit of period 1 or 2), and a contact
        # force that can exceed beta only marginally
        if 0.5 * (stats[ST_DMAX] - stats[ST_DMIN]) < CREEP_SLIP_RTOL / SLIP_RTOL * slip_tol:
            small_run += 1
            quiet_run += 1 if stats[ST_EVENTS] == 0.0 else 0
        else:
            small_run = 0
            quiet_run = 0
        if (
            small_run >= CREEP_WINDOW
            and 2 * quiet_run > small_run
            and mode == 0
            and creep_settled(X, ctx, theta)
        ):
            _asymptotic_no_motion(out, stats, cycles, ic_used)
            return
        scale = max(_max_abs(X), 1e-300)
        if cycles <= 2:
            ref = max(ref, scale)
        elif scale > growth_factor * ref:
            _undetermined(out, UNBOUNDED, cycles, ic_used)
            return
        diff = _max_abs_diff(X, X_prev)
        # the section repeats (to rtol of the motion, or of the static response
        # when the motion is far smaller) and so does the event pattern
        if (
            cycles >= min_cycles
            and _same_chart(mode, mode_prev)
            and stats[ST_STOPS] == stats_prev[ST_STOPS]
            and stats[ST_REVERSALS] == stats_prev[ST_REVERSALS]
        ):
            rho = diff / diff_prev if diff_prev > 0.0 else 0.0
            err = diff / (1.0 - min(rho, 0.999))
            if err <= section_rtol * max(scale, ref) or diff <= 1e-13 * scale:
                final[: 2 * n] = X_prev
                final[2 * n] = mode_prev
                _finish(out, stats, stats_prev, 1, cycles, ic_used)
                _creep_limit(out, slip_tol)
                return
        chart_flips = chart_flips + 1 if not _same_chart(mode, mode_prev) else 0
        if cycles >= min_cycles + 1 and _same_chart(mode, mode_prev2):
            diff2 = _max_abs_diff(X, X_prev2)
            tol2 = section_rtol * max(scale, ref)
            if diff2 <= tol2 and diff > 10.0 * tol2:
                final[: 2 * n] = X_prev2
                final[2 * n] = mode_prev2
                _finish(out, stats, stats_prev, 2, cycles, ic_used)
                _creep_limit(out, slip_tol)
                return
        # linear growth (resonance without enough friction): increments repeat
        # (Coulomb-damped decay also repeats its increments: growth must be seen)
        if 0.0 < diff_prev < np.inf and diff > 0.0 and abs(diff / diff_prev - 1.0) < 1e-6:
            if unit_ratio_run == 0:
                run_start_scale = scale
            unit_ratio_run += 1
        else:
            unit_ratio_run = 0
        if (
            unit_ratio_run >= 10
            and scale > 10.0 * ref
            and scale - run_start_scale >= 5.0 * diff
            and (shots_failed > 0 or not shooting)
        ):
            _undetermined(out, UNBOUNDED, cycles, ic_used)
            return
        for i in range(N_STATS):
            stats_prev[i] = stats[i]
        diff_prev = diff
        shoot_now = shooting and cycles >= next_shot
        if (shoot_now or chart_flips >= 2) and moves < 8:
            # The section falls near an event (the phase there flips between
            # cycles): move it to the middle of the longest phase of the last
            # period, where the Poincare map is smooth, and restart the history.
            target = stats[ST_MID]
            if abs(target - theta) > 1e-6 and stats[ST_LONGEST] > 0.0:
                X, mode, stick_start = _advance(
                    X, mode, stick_start, stats_prev, ctx, work, theta, target
                )
                if stats_prev[ST_STATUS] != STATUS_OK:
                    _undetermined(out, stats_prev[ST_STATUS], cycles, ic_used)
                    return
                shift = TWO_PI * math.floor(target / TWO_PI)
                theta = target - shift
                stick_start -= shift
                moves += 1
                X_prev = X.copy()
                X_prev2 = X.copy()
                mode_prev = mode
                mode_prev2 = mode
                diff_prev = np.inf
                stats_prev[ST_STOPS] = -1.0  # no period at this section yet
                chart_flips = 0
                unit_ratio_run = 0
        if shoot_now:
            next_shot = 2 * next_shot
            ok, Xs, used = _shoot(X, mode, stats, ctx, work, section_rtol, ref, 20, theta)
            cycles += used
            if ok:
                final[: 2 * n] = Xs
                final[2 * n] = start_phase(Xs, ctx[CTX_BETA], ctx, theta) if mode != 0 else 0
                final[2 * n + 1] = theta
                _finish(out, stats, stats_prev, 1, cycles, ic_used)
                _creep_limit(out, slip_tol)
                return
            shots_failed += 1
            if shots_failed in (2, 4, 6):  # a slow point: full Newton from here
                ok, Xs, mode_s, theta_s, used = settle_at_phases(
                    X,
                    mode,
                    stick_start,
                    stats,
                    ctx,
                    work,
                    section_rtol,
                    ref,
                    theta,
                    1,
                )
                cycles += used
                if ok:
                    theta = theta_s
                    final[: 2 * n] = Xs
                    final[2 * n] = mode_s
                    final[2 * n + 1] = theta
                    _finish(out, stats, stats_prev, 1, cycles, ic_used)
                    _creep_limit(out, slip_tol)
                    return
    if shooting:
        # last resort before giving up: Newton from four sections of the period
        # (a map cut by an event at one section can be smooth at another); it
        # runs only for points the budget could not settle, so they may end with
        # up to SETTLE_PHASES * SETTLE_CYCLES periods beyond max_cycles
        ok, Xs, mode_s, theta_s, used = settle_at_phases(
            X, mode, stick_start, stats, ctx, work, section_rtol, ref, theta, SETTLE_PHASES
        )
        cycles += used
        if ok:
            final[: 2 * n] = Xs
            final[2 * n] = mode_s
            final[2 * n + 1] = theta_s
            _finish(out, stats, stats_prev, 1, cycles, ic_used)
            _creep_limit(out, slip_tol)
            return
    _undetermined(out, NOT_CONVERGED, cycles, ic_used)


@njit(cache=True)
def _event_cap(events):
    """The per-cycle event limit implied by the fastest mode, as an int (capped at 1e9)."""
    if not events < 1e9:
        return 1_000_000_000
    return int(events)


@njit(cache=True)
def _phase_holds(seg, sc, t_len, h, tol):
    """The invariant through one phase of length ``t_len`` (start already set in ``seg, sc``).

    Samples the observable at spacing at most ``h / ORBIT_SAMPLES`` (at most
    ``ORBIT_MAX_SAMPLES`` per phase) strictly inside the phase. Stuck:
    ``|g| <= beta (1 + ORBIT_RTOL) + tol max|g'|`` (the second term is what an
    event located to ``tol`` can leave). Sliding: the contact velocity keeps the
    phase's sign, ``s v >= -1e-9 max|v|``. Returns 1 (holds), 0 (violated) or -1
    (the work budget ran out first).
    """
    m = seg.shape[1]
    eta = np.empty(m)
    etad = np.empty(m)
    n_samples = int(min(max(2.0, ORBIT_SAMPLES * t_len / h), ORBIT_MAX_SAMPLES))
    if sc[EVALS] + n_samples * (1.0 + m) > sc[WORK_CAP]:
        return -1
    dt = t_len / (n_samples + 1)
    if sc[KIND] == KIND_STICK:
        slope, _ = derivative_bounds(seg, sc, t_len)
        limit = sc[BETA] * (1.0 + ORBIT_RTOL) + tol * slope
        for i in range(1, n_samples + 1):
            y, _ = evaluate(seg, sc, i * dt, eta, etad)
            if not abs(y) <= limit:
                return 0
        sc[EVALS] += n_samples * (1.0 + m)
        return 1
    s = sc[SIGN]
    vmax = 0.0
    vmin = 0.0
    for i in range(1, n_samples + 1):
        y, _ = evaluate(seg, sc, i * dt, eta, etad)
        v = s * y
        vmax = max(vmax, abs(v))
        vmin = min(vmin, v)
    sc[EVALS] += n_samples * (1.0 + m)
    return 1 if vmin >= -1e-9 * vmax else 0


@njit(cache=True)
def orbit_holds(X, mode, theta, period, ctx, work):
    """Orbit invariant: the converged period from the section state is a solution.

    Re-simulates ``period`` cycles from ``(X, mode)`` at ``tau = theta`` with
    every event recorded, then checks every phase densely in closed form
    (:func:`_phase_holds`): through each stick phase ``|g| <= beta`` (to
    ``ORBIT_RTOL``), through each slip phase the contact velocity keeps its
    sign. Independent of the event search it checks: a missed unsticking or
    reversal shows as a violation. Costs about one period more per point.
    Returns 1 (holds), 0 (violated) or -1 (the work budget ran out first).
    """
    n = X.shape[0] // 2
    beta = ctx[CTX_BETA]
    h_slip = ctx[CTX_H_SLIP]
    h_stick = ctx[CTX_H_STICK]
    tol = ctx[CTX_TOL]
    sc = ctx[CTX_SC]
    rows = 64
    stats = np.zeros(N_STATS)
    while True:
        rec = np.zeros((rows, REC_X + 2 * n))
        rec_n = np.zeros(1, dtype=np.int64)
        x = X[:n].copy()
        xd = X[n:].copy()
        m = mode
        stick_start = theta
        for k in range(period):
            t0 = theta + TWO_PI * k
            m, stick_start = run_cycle(
                x, xd, m, stick_start, stats, ctx, work, rec, rec_n, t0, t0 + TWO_PI
            )
            if stats[ST_STATUS] != STATUS_OK:
                return -1 if stats[ST_STATUS] == WORK_LIMIT else 0
        if rec_n[0] < rows:
            break
        rows *= 4
    eta, etad, eta_s, etad_s, q = work
    x = np.empty(n)
    xd = np.empty(n)
    for j in range(rec_n[0] - 1):
        t_len = rec[j + 1, REC_TAU] - rec[j, REC_TAU]
        if not t_len > 0.0:
            continue
        tau0 = rec[j, REC_TAU]
        for i in range(n):
            x[i] = rec[j, REC_X + i]
            xd[i] = rec[j, REC_X + n + i]
        phase = int(rec[j, REC_MODE])
        if phase == 0:
            seg = ctx[CTX_SEG_STICK]
            _start_stick(
                seg,
                sc,
                x,
                xd,
                tau0,
                beta,
                ctx[CTX_B],
                ctx[CTX_W],
                ctx[CTX_PROJ],
                ctx[CTX_PHI_S_T_GAMMA_S],
                ctx[CTX_DSTAT_R2],
                ctx[CTX_G_COS],
                ctx[CTX_G_D0],
                q,
            )
            ok = _phase_holds(seg, sc, t_len, h_stick, tol)
        else:
            seg = ctx[CTX_SEG_SLIP]
            # the contact velocity at a section start; 0 at an event, as in run_cycle
            v0 = _dot(ctx[CTX_B], xd) if rec[j, REC_KIND] == EV_SECTION else 0.0
            _start_slip(
                seg, sc, x, xd, tau0, float(phase), v0, beta, ctx[CTX_F_R2], ctx[CTX_PHI_T_GAMMA]
            )
            ok = _phase_holds(seg, sc, t_len, h_slip, tol)
        if ok != 1:
            return ok
    return 1


@njit(cache=True)
def _check_orbit(r, beta, scene, settings, out, final):
    """Flag a converged point whose orbit fails :func:`orbit_holds` (never report it).

    The point becomes ``NUMERICAL_FAILURE`` (an event the search could not
    locate), or ``WORK_LIMIT`` if the check ran out of budget (it has a budget
    of its own, ``max_work``). No-motion points are certified by :func:`never_unsticks` and
    continuous points at beta = 0 are linear: neither is re-checked.
    """
    if out[OUT_CONVERGED] != 1.0 or out[OUT_REGIME] == NO_MOTION or beta == 0.0:
        return
    ctx, work, _, _, _ = _context(r, beta, scene, settings)
    n = (final.shape[0] - 2) // 2
    X = final[: 2 * n].copy()
    mode = int(final[2 * n])
    theta = final[2 * n + 1]
    holds = orbit_holds(X, mode, theta, int(out[OUT_PERIOD]), ctx, work)
    if holds == 0:
        _undetermined(out, NUMERICAL_FAILURE, out[OUT_CYCLES], out[OUT_IC])
    elif holds < 0:
        _undetermined(out, WORK_LIMIT, out[OUT_CYCLES], out[OUT_IC])


@njit(cache=True)
def run_points(r, beta, scene, settings):
    """Classify every point ``(r[i], beta[i])``.

    Returns ``(out, final)``: ``out`` is ``(n_points, N_OUT)`` (columns
    ``OUT_*``), ``final`` the last section state and phase of each point.
    """
    n = scene[0].shape[0]
    out = np.empty((r.shape[0], N_OUT))
    final = np.empty((r.shape[0], 2 * n + 2))
    for i in range(r.shape[0]):
        simulate_point(r[i], beta[i], scene, settings, out[i], final[i])
        _check_orbit(r[i], beta[i], scene, settings, out[i], final[i])
    return out, final


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
    stick_start = theta
    status = STATUS_OK
    for k in range(n_cycles):
        t0 = theta + TWO_PI * k
        mode, stick_start = run_cycle(
            x, xd, mode, stick_start, stats, ctx, work, rec, rec_n, t0, t0 + TWO_PI
        )
        if stats[ST_STATUS] != STATUS_OK:
            status = stats[ST_STATUS]
            break
    out = np.empty(2 * n)
    out[:n] = x
    out[n:] = xd
    return rec, rec_n[0], out, mode, status


@njit(cache=True)
def sample_states(ctx, work, rec, taus):
    """States ``(x, x')`` at the absolute times ``taus`` (ascending) from the records."""
    n = (rec.shape[1] - REC_X) // 2
    beta = ctx[CTX_BETA]
    out = np.empty((taus.shape[0], 2 * n))
    x = np.empty(n)
    xd = np.empty(n)
    j = 0
    for i in range(taus.shape[0]):
        tau = taus[i]
        while j + 1 < rec.shape[0] - 1 and rec[j + 1, REC_TAU] <= tau:
            j += 1
        tau0 = rec[j, REC_TAU]
        mode = int(rec[j, REC_MODE])
        for k in range(n):
            x[k] = rec[j, REC_X + k]
            xd[k] = rec[j, REC_X + n + k]
        eta, etad, eta_s, etad_s, q = work
        if mode == 0:
            seg = ctx[CTX_SEG_STICK]
            d0 = _start_stick(
                seg,
                ctx[CTX_SC],
                x,
                xd,
                tau0,
                beta,
                ctx[CTX_B],
                ctx[CTX_W],
                ctx[CTX_PROJ],
                ctx[CTX_PHI_S_T_GAMMA_S],
                ctx[CTX_DSTAT_R2],
                ctx[CTX_G_COS],
                ctx[CTX_G_D0],
                q,
            )
            evaluate(seg, ctx[CTX_SC], tau - tau0, eta_s, etad_s)
            _stick_state(ctx[CTX_PHI_S], ctx[CTX_T], ctx[CTX_W], d0, eta_s, etad_s, q, x, xd)
        else:
            seg = ctx[CTX_SEG_SLIP]
            _start_slip(
                seg,
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
            evaluate(seg, ctx[CTX_SC], tau - tau0, eta, etad)
            _slip_state(ctx[CTX_PHI], eta, etad, x, xd)
        out[i, :n] = x
        out[i, n:] = xd
    return out


# --------------------------------------------------------------------------- design quantities
# Columns of :func:`orbit_designs`'s output, per point (n = number of masses):
# [0, n) amplitude of the scene coordinate q_i (x_i; z_i = x_i - y for a base-fixed wall),
# [n, 2n) amplitude of the other coordinate q_i - c cos(tau) (c = -1 base-fixed, else +1),
# 2n the contact force amplitude, 2n + 1 the energy dissipated per excitation cycle.
DESIGN_FORCE = 0  # offset from 2 n
DESIGN_DISSIPATION = 1  # offset from 2 n
#: Samples per excitation cycle (at least; more where modal periods are short).
DESIGN_SAMPLES = 32
#: Samples per excitation cycle at most (very stiff chains: the modes far above
#: the excitation are then resolved only as far as this allows).
DESIGN_MAX_SAMPLES = 4096


@njit(cache=True)
def _hermite_extremes(t0, t1, y0, y1, v0, v1, acc):
    """Fold the extrema of ``y`` on ``[t0, t1]`` into ``acc``.

    ``y`` and its derivative ``v`` are exact at both ends (``acc[4:6]``: the
    smallest and largest exact value); a sign change of ``v`` marks an interior
    extremum, located on the cubic Hermite interpolant (``acc[0:2]``: the
    smallest and largest interpolated value, ``acc[2:4]``: their times, to be
    evaluated exactly by the caller).
    """
    for t, y in ((t0, y0), (t1, y1)):
        if y < acc[4]:
            acc[4] = y
        if y > acc[5]:
            acc[5] = y
        if y < acc[0]:
            acc[0] = y
            acc[2] = t
        if y > acc[1]:
            acc[1] = y
            acc[3] = t
    if v0 * v1 >= 0.0:
        return
    h = t1 - t0
    # p(s) = y0 h00 + h v0 h10 + y1 h01 + h v1 h11 on s in [0, 1]; p'(s) / h:
    # (6 s^2 - 6 s)(y0 - y1)/h + (3 s^2 - 4 s + 1) v0 + (3 s^2 - 2 s) v1
    dy = (y0 - y1) / h
    a = 6.0 * dy + 3.0 * v0 + 3.0 * v1
    b = -6.0 * dy - 4.0 * v0 - 2.0 * v1
    c = v0
    s = -1.0
    if abs(a) < 1e-300:
        if b != 0.0:
            s = -c / b
    else:
        disc = b * b - 4.0 * a * c
        if disc >= 0.0:
            sq = math.sqrt(disc)
            q = -0.5 * (b + math.copysign(sq, b))
            s1 = q / a
            s2 = c / q if q != 0.0 else -1.0
            if 0.0 < s1 < 1.0:
                s = s1
            elif 0.0 < s2 < 1.0:
                s = s2
    if not (0.0 < s < 1.0):
        return
    h00 = (1.0 + 2.0 * s) * (1.0 - s) ** 2
    h10 = s * (1.0 - s) ** 2
    h01 = s * s * (3.0 - 2.0 * s)
    h11 = s * s * (s - 1.0)
    y = y0 * h00 + h * v0 * h10 + y1 * h01 + h * v1 * h11
    if y < acc[0]:
        acc[0] = y
        acc[2] = t0 + s * h
    if y > acc[1]:
        acc[1] = y
        acc[3] = t0 + s * h


@njit(cache=True)
def orbit_design(r, beta, scene, settings, state, period, samples, dout):
    """Design quantities of the converged orbit that starts at the section ``state``.

    ``state`` is a row of :func:`run_points`' ``final`` (``x, x'``, phase, section
    phase theta), ``period`` the orbit's period in excitation cycles. The orbit is
    replayed event by event (:func:`run_cycle`) and sampled exactly (closed-form
    phases, :func:`sample_states`) at least ``samples`` times per cycle and at
    every event; extrema between samples are located on the cubic Hermite
    interpolant of the exact values and velocities. Writes into ``dout``
    (columns above): amplitudes (half peak-to-peak) of every coordinate in both
    frames, the contact force amplitude (``beta`` while sliding, ``|g|`` while
    stuck) and the energy dissipated per excitation cycle, ``beta`` times the
    slip distance ``sum |delta (b . x)|`` over the slip phases, divided by
    ``period`` (units k_1 Y^2; docs/theory.md 2). Returns the number of samples.
    """
    ctx, work = _context(r, beta, scene, settings)[:2]
    n = (state.shape[0] - 2) // 2
    c = -1.0 if scene[4] else 1.0  # other frame: z + cos tau (base) or x - cos tau
    p = ctx[CTX_P]
    K = ctx[CTX_K]
    b = ctx[CTX_B]
    g_load = ctx[CTX_G_LOAD]
    if beta == 0.0:  # linear, undamped: the forced response (K - M)^-1 p cos tau
        seg = ctx[CTX_SEG_SLIP]
        phi = ctx[CTX_PHI]
        for i in range(n):
            v = 0.0
            for k in range(n):
                v += phi[i, k] * seg[LOAD_COS, k] / (seg[OMEGA, k] ** 2 - 1.0)
            dout[i] = abs(v)
            dout[n + i] = abs(v - c)
        dout[2 * n + DESIGN_FORCE] = 0.0
        dout[2 * n + DESIGN_DISSIPATION] = 0.0
        return 0
    theta = state[2 * n + 1]
    rows = 32 * period  # grown (and the orbit replayed) if the events do not fit
    rec = np.zeros((0, REC_X + 2 * n))
    rec_n = np.zeros(1, dtype=np.int64)
    stats = np.zeros(N_STATS)
    while True:
        rec = np.empty((rows, REC_X + 2 * n))
        rec_n[0] = 0
        mode = int(state[2 * n])
        x = state[:n].copy()
        xd = state[n : 2 * n].copy()
        stick_start = theta
        for k in range(period):
            t0 = theta + TWO_PI * k
            mode, stick_start = run_cycle(
                x, xd, mode, stick_start, stats, ctx, work, rec, rec_n, t0, t0 + TWO_PI
            )
            if stats[ST_STATUS] != STATUS_OK:
                break
        if stats[ST_STATUS] != STATUS_OK:  # the replay ran out of budget: no answer
            for i in range(dout.shape[0]):
                dout[i] = np.nan
            return 0
        if rec_n[0] < rows or rows > period * (ctx[CTX_MAX_EVENTS] + 4):
            break
        rows *= 8
    nr = rec_n[0]
    rec = rec[:nr]
    # sample times: every phase start and end, and at most h apart inside a phase
    h = min(TWO_PI / samples, 0.5 * min(ctx[CTX_H_SLIP], ctx[CTX_H_STICK]))
    h = max(h, TWO_PI / DESIGN_MAX_SAMPLES)
    count = 1
    for j in range(nr - 1):
        length = rec[j + 1, REC_TAU] - rec[j, REC_TAU]
        if length > 0.0:
            count += max(1, int(math.ceil(length / h)))
    taus = np.empty(count)
    slip = 0.0
    sliding = False
    i_s = 0
    for j in range(nr - 1):
        length = rec[j + 1, REC_TAU] - rec[j, REC_TAU]
        if length <= 0.0:
            continue
        if rec[j, REC_MODE] != 0.0:
            sliding = True
            d0 = 0.0
            d1 = 0.0
            for i in range(n):
                d0 += b[i] * rec[j, REC_X + i]
                d1 += b[i] * rec[j + 1, REC_X + i]
            slip += abs(d1 - d0)
        k_j = max(1, int(math.ceil(length / h)))
        for k in range(k_j):
            taus[i_s] = rec[j, REC_TAU] + length * k / k_j
            i_s += 1
    taus[count - 1] = rec[nr - 1, REC_TAU]
    states = sample_states(ctx, work, rec, taus)
    acc = np.empty(6)
    refine = np.empty(2)
    for which in range(2):
        cf = 0.0 if which == 0 else -c
        for i in range(n):
            acc[0] = np.inf
            acc[1] = -np.inf
            acc[4] = np.inf
            acc[5] = -np.inf
            for s in range(count - 1):
                ta = taus[s]
                tb = taus[s + 1]
                ya = states[s, i] + cf * math.cos(ta)
                yb = states[s + 1, i] + cf * math.cos(tb)
                va = states[s, n + i] - cf * math.sin(ta)
                vb = states[s + 1, n + i] - cf * math.sin(tb)
                _hermite_extremes(ta, tb, ya, yb, va, vb, acc)
            # the interpolated extrema evaluated exactly (error O(h^6), never above)
            refine[0] = min(acc[2], acc[3])
            refine[1] = max(acc[2], acc[3])
            exact = sample_states(ctx, work, rec, refine)
            lo = acc[4]
            hi = acc[5]
            for k in range(2):
                y = exact[k, i] + cf * math.cos(refine[k])
                lo = min(lo, y)
                hi = max(hi, y)
            dout[which * n + i] = 0.5 * (hi - lo)
    if sliding:
        force = beta
    else:  # stuck the whole orbit: the largest |g| (g' = -g_load . (p sin tau + K x'))
        acc[0] = np.inf
        acc[1] = -np.inf
        acc[4] = np.inf
        acc[5] = -np.inf
        kxd = np.empty(n)
        gp = _dot(g_load, p)
        for s in range(count - 1):
            ta = taus[s]
            tb = taus[s + 1]
            ga = _contact_force(p, math.cos(ta), K, states[s, :n].copy(), g_load)
            gb = _contact_force(p, math.cos(tb), K, states[s + 1, :n].copy(), g_load)
            _matvec(K, states[s, n:].copy(), kxd)
            dga = -math.sin(ta) * gp - _dot(g_load, kxd)
            _matvec(K, states[s + 1, n:].copy(), kxd)
            dgb = -math.sin(tb) * gp - _dot(g_load, kxd)
            _hermite_extremes(ta, tb, ga, gb, dga, dgb, acc)
        refine[0] = min(acc[2], acc[3])
        refine[1] = max(acc[2], acc[3])
        exact = sample_states(ctx, work, rec, refine)
        force = max(abs(acc[4]), abs(acc[5]))
        for k in range(2):
            g = _contact_force(p, math.cos(refine[k]), K, exact[k, :n].copy(), g_load)
            force = max(force, abs(g))
    dout[2 * n + DESIGN_FORCE] = force
    dout[2 * n + DESIGN_DISSIPATION] = beta * slip / period
    return count


@njit(cache=True)
def orbit_designs(r, beta, scene, settings, out, final, samples):
    """:func:`orbit_design` for every converged point of :func:`run_points`' output.

    Returns ``(design, n_samples)``: ``design`` is ``(n_points, 2 n + 2)``, NaN
    where the point has no steady state (regime code < 0).
    """
    n = scene[0].shape[0]
    design = np.full((r.shape[0], 2 * n + 2), np.nan)
    total = 0
    for i in range(r.shape[0]):
        if out[i, OUT_REGIME] < 0.0 or out[i, OUT_CONVERGED] == 0.0:
            continue
        period = max(1, int(out[i, OUT_PERIOD]))
        total += orbit_design(r[i], beta[i], scene, settings, final[i], period, samples, design[i])
    return design, total
