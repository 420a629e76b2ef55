"""Closed-form propagation of a linear phase (slip or stick) and event location.

Between two events every configuration is linear with constant plus harmonic
forcing (MODEL.md section 2). In the modal coordinates of the moving system
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

All functions are compiled with numba (``cache=True``); with
``NUMBA_DISABLE_JIT=1`` the same code runs as plain Python.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# Rows of the per-mode segment array ``seg`` (shape (N_ROWS, m)).
OMEGA, ETA0, ETAD0, LOAD_COS, LOAD_CONST, ALPHA, DELTA = range(7)
N_ROWS = 7
# Entries of the scalar segment array ``sc``.
TAU0, COS_TAU0, SIN_TAU0, OBS_COS, OBS0, KIND, SIGN, BETA = range(8)
N_SCALARS = 8
KIND_SLIP = 0.0
KIND_STICK = 1.0


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
    """``(F, F')`` at t: ``s y`` while sliding, ``beta - |y|`` while stuck."""
    y, dy = evaluate(seg, sc, t, eta, etad)
    if sc[KIND] == KIND_SLIP:
        return sc[SIGN] * y, sc[SIGN] * dy
    if y >= 0.0:
        return sc[BETA] - y, -dy
    return sc[BETA] + y, dy


@njit(cache=True)
def derivative_bound(seg, sc):
    """Upper bound of ``|F'|`` over the whole phase (inf near resonance).

    Each mode is split into its free oscillation (amplitude ``A_free``), its
    harmonic particular part ``P = a / (Omega^2 - 1)`` and its static part, so
    ``|eta'| <= Omega A_free + |P|`` and ``|eta''| <= Omega^2 A_free + |P|``.
    """
    bound = abs(sc[OBS_COS])
    for k in range(seg.shape[1]):
        w = seg[OMEGA, k]
        den = w * w - 1.0
        if den == 0.0:
            return np.inf
        pk = seg[LOAD_COS, k] / den
        d = seg[ETA0, k] - seg[LOAD_CONST, k] / (w * w) - pk * sc[COS_TAU0]
        e = (seg[ETAD0, k] + pk * sc[SIN_TAU0]) / w
        free = math.hypot(d, e)
        bound += abs(seg[ALPHA, k]) * (w * free + abs(pk))
        bound += abs(seg[DELTA, k]) * (w * w * free + abs(pk))
    if not math.isfinite(bound):
        return np.inf
    return bound


@njit(cache=True)
def never_unsticks(seg, sc):
    """Certificate that a stick phase lasts for ever (MODEL.md 4.2, held contact).

    While stuck, ``g = G0 + H cos(tau) + free modes``; if
    ``|G0| + |H| + sum_k |alpha_k| A_free,k < beta`` then ``|g| < beta`` at
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
    return math.isfinite(total) and total < sc[BETA] * (1.0 - 1e-12)


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
def next_event(seg, sc, t_end, h, tol, eta, etad):
    """First time ``t`` in ``(0, t_end]`` where the event function ``F`` reaches 0.

    ``F > 0`` just after the phase start (it may start at 0, right after an
    event). The interval is scanned in brackets no longer than ``h`` (a
    fraction of the shortest modal half-period): a sign change is solved to
    ``tol``; without one, an interior minimum of F (``F'`` going from - to +) is
    located and a dip to ``F <= 0`` is an event too, which catches pairs of
    zeros and grazing zeros inside one bracket. Where ``F`` is far from 0 the
    scan jumps ahead by ``F / max|F'|``, an interval that provably holds no zero.

    Returns ``(t, found)``; ``t`` is on the far side of the zero (F <= 0).
    """
    f0, d0 = event_function(seg, sc, 0.0, eta, etad)
    fa = f0 if f0 > 0.0 else 0.0
    da = d0 if f0 > 0.0 else max(d0, 0.0)
    lipschitz = derivative_bound(seg, sc)
    ta = 0.0
    while ta < t_end:
        step = h
        certified = False
        if fa > 0.0 and lipschitz < np.inf:
            safe = fa / lipschitz
            if safe > step:
                step = safe
                certified = True
        tb = min(ta + step, t_end)
        fb, db = event_function(seg, sc, tb, eta, etad)
        if fb <= 0.0:
            if fa > 0.0:
                lo, hi = _solve_bracket(seg, sc, 0, ta, tb, fa, fb, tol, eta, etad)
                return hi, True
            # phase start with F(0) = 0: find a point where F > 0 first
            tm = tb
            for _ in range(60):
                tm = 0.5 * tm
                fm, dm = event_function(seg, sc, tm, eta, etad)
                if fm > 0.0:
                    lo, hi = _solve_bracket(seg, sc, 0, tm, tb, fm, fb, tol, eta, etad)
                    return hi, True
            return tm, True
        if not certified and fa > 0.0 and da < 0.0 and db > 0.0:
            lo, hi = _solve_bracket(seg, sc, 1, ta, tb, da, db, tol, eta, etad)
            tm = 0.5 * (lo + hi)
            fm, dm = event_function(seg, sc, tm, eta, etad)
            if fm <= 0.0:
                lo, hi = _solve_bracket(seg, sc, 0, ta, tm, fa, fm, tol, eta, etad)
                return hi, True
        ta = tb
        fa = fb
        da = db
    return t_end, False
