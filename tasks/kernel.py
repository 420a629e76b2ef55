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
TAU0, COS_TAU0, SIN_TAU0, OBS_COS, OBS0, KIND, SIGN, BETA, EVALS = range(9)
N_SCALARS = 9
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
def derivative_bounds(seg, sc):
    """Upper bounds of ``|F'|`` and ``|F''|`` over the whole phase (inf at resonance).

    Each mode is split into its free oscillation (amplitude ``A_free``), its
    harmonic particular part ``P = a / (Omega^2 - 1)`` and its static part, so
    that ``|eta^(k)| <= Omega^k A_free + |P|`` for k >= 1.
    """
    d1 = abs(sc[OBS_COS])
    d2 = abs(sc[OBS_COS])
    for k in range(seg.shape[1]):
        w = seg[OMEGA, k]
        den = w * w - 1.0
        if den == 0.0:
            return np.inf, np.inf
        pk = abs(seg[LOAD_COS, k] / den)
        d = seg[ETA0, k] - seg[LOAD_CONST, k] / (w * w) - seg[LOAD_COS, k] / den * sc[COS_TAU0]
        e = (seg[ETAD0, k] + seg[LOAD_COS, k] / den * sc[SIN_TAU0]) / w
        free = math.hypot(d, e)
        alpha = abs(seg[ALPHA, k])
        delta = abs(seg[DELTA, k])
        d1 += alpha * (w * free + pk) + delta * (w * w * free + pk)
        d2 += alpha * (w * w * free + pk) + delta * (w * w * w * free + pk)
    if not (math.isfinite(d1) and math.isfinite(d2)):
        return np.inf, np.inf
    return d1, d2


@njit(cache=True)
def _no_zero_between(fa, da, fb, db, h, curvature):
    """Certificate that F > 0 on ``[a, a + h]`` from its values and slopes at both
    ends and ``|F''| <= curvature``: the concave lower bounds
    ``fa + da u - c u^2 / 2`` and ``fb - db w - c w^2 / 2`` (w = h - u) are
    positive on intervals that together cover the bracket."""
    if curvature <= 0.0:
        return True
    ua = (da + math.sqrt(da * da + 2.0 * curvature * fa)) / curvature
    wb = (-db + math.sqrt(db * db + 2.0 * curvature * fb)) / curvature
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
def _dip(seg, sc, ta, tb, fa, da, fb, db, curvature, tol, eta, etad):
    """Search ``(ta, tb)`` (F > 0 at both ends) for a point where F <= 0.

    Bisects the parts of the bracket the curvature certificate cannot clear,
    left to right. Returns ``(lo, hi, kind)``: kind 0 = no zero, 1 = a sign
    change in ``(lo, hi]`` (F(lo) > 0 >= F(hi), no zero before lo), 2 = a
    touching zero at ``hi`` (the bracket shrank to ``tol`` with F still not
    provably positive: a graze).
    """
    stack_a = np.empty(64)
    stack_b = np.empty(64)
    vals = np.empty((64, 4))
    top = 0
    stack_a[0] = ta
    stack_b[0] = tb
    vals[0, 0] = fa
    vals[0, 1] = da
    vals[0, 2] = fb
    vals[0, 3] = db
    top = 1
    budget = 400
    while top > 0:
        top -= 1
        a = stack_a[top]
        b = stack_b[top]
        f_a = vals[top, 0]
        d_a = vals[top, 1]
        f_b = vals[top, 2]
        d_b = vals[top, 3]
        if _no_zero_between(f_a, d_a, f_b, d_b, b - a, curvature):
            continue
        if b - a <= tol or budget <= 0 or top >= 62:
            # cannot clear it: F comes within curvature * tol^2 of zero
            return a, 0.5 * (a + b), 2 if b - a <= tol else 0
        budget -= 1
        m = 0.5 * (a + b)
        f_m, d_m = event_function(seg, sc, m, eta, etad)
        if f_m <= 0.0:
            return a, m, 1
        # right half first on the stack, so the left half is searched first
        stack_a[top] = m
        stack_b[top] = b
        vals[top, 0] = f_m
        vals[top, 1] = d_m
        vals[top, 2] = f_b
        vals[top, 3] = d_b
        top += 1
        stack_a[top] = a
        stack_b[top] = m
        vals[top, 0] = f_a
        vals[top, 1] = d_a
        vals[top, 2] = f_m
        vals[top, 3] = d_m
        top += 1
    return ta, tb, 0


@njit(cache=True)
def next_event(seg, sc, t_end, h, tol, eta, etad):
    """First time ``t`` in ``(0, t_end]`` where the event function ``F`` reaches 0.

    ``F > 0`` just after the phase start (it may start at 0, right after an
    event). The interval is scanned in brackets no longer than ``h`` (a
    fraction of the shortest modal half-period): a sign change is solved to
    ``tol``. A bracket without one is cleared by a curvature certificate
    (``|F''|`` bounded over the phase, :func:`_no_zero_between`) or else
    bisected where it cannot be cleared (:func:`_dip`), which finds pairs of
    zeros and grazing zeros however close together. Where ``F`` is far from 0
    the scan jumps ahead by ``F / max|F'|``, an interval that provably holds no
    zero.

    Returns ``(t, found)``; ``t`` is on the far side of the zero (F <= 0), or at
    a touching zero.
    """
    f0, d0 = event_function(seg, sc, 0.0, eta, etad)
    slope_bound, curvature = derivative_bounds(seg, sc)
    ta = 0.0
    if f0 > 0.0:
        fa = f0
        da = d0
    else:
        # phase start at an event (F(0) = 0): step off it to a point where
        # F > 0 (a zero closer than h / 64 to the start is taken as immediate)
        t1 = min(h / 64.0, t_end)
        f1, d1 = event_function(seg, sc, t1, eta, etad)
        if f1 <= 0.0:
            tm = t1
            for _ in range(60):
                tm = 0.5 * tm
                fm, dm = event_function(seg, sc, tm, eta, etad)
                if fm > 0.0:
                    lo, hi = _solve_bracket(seg, sc, 0, tm, t1, fm, f1, tol, eta, etad)
                    return hi, True
            return tm, True
        ta = t1
        fa = f1
        da = d1
    while ta < t_end:
        step = h
        certified = False
        if slope_bound < np.inf:
            safe = fa / slope_bound if slope_bound > 0.0 else t_end - ta
            if safe > step:
                step = safe
                certified = True
        tb = min(ta + step, t_end)
        fb, db = event_function(seg, sc, tb, eta, etad)
        if fb <= 0.0:
            lo, hi = _solve_bracket(seg, sc, 0, ta, tb, fa, fb, tol, eta, etad)
            return hi, True
        if not certified:
            if curvature < np.inf:
                lo, hi, kind = _dip(seg, sc, ta, tb, fa, da, fb, db, curvature, tol, eta, etad)
                if kind == 2 and sc[KIND] == KIND_SLIP:
                    # the contact velocity touches zero: a stop if it can stick
                    return hi, True
                if kind == 1:
                    f_lo, _ = event_function(seg, sc, lo, eta, etad)
                    f_hi, _ = event_function(seg, sc, hi, eta, etad)
                    lo, hi = _solve_bracket(seg, sc, 0, lo, hi, f_lo, f_hi, tol, eta, etad)
                    return hi, True
            elif da < 0.0 and db > 0.0:  # no curvature bound: locate the interior minimum
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
    sc[BETA] = beta
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
    ctx = (
        seg_slip,
        seg_stick,
        np.zeros(N_SCALARS),
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
        max(max_events, int(8.0 * max(om_slip, om_max))),
        max_work,
    )
    work = (np.zeros(n), np.zeros(n), np.zeros(m), np.zeros(m), np.zeros(2 * m))
    # Held start: contact at d0 = 0, the rest on the forced response of the
    # held system at tau = 0 (from rest if the held system is resonant).
    ic_used = initial_condition
    X = np.zeros(2 * n)
    if initial_condition == IC_HELD or initial_condition >= IC_RANDOM:
        zeta = np.zeros(m)
        for k in range(m):
            den = seg_stick[OMEGA, k] ** 2 - 1.0
            if seg_stick[LOAD_COS, k] == 0.0:
                continue  # mode not loaded: no forced response
            if abs(den) < 1e-9 * max(seg_stick[OMEGA, k] ** 2, 1.0):
                ic_used = IC_REST
                break
            zeta[k] = seg_stick[LOAD_COS, k] / den
        if ic_used != IC_REST:
            for i in range(m):
                qi = 0.0
                for k in range(m):
                    qi += phi_s[i, k] * zeta[k]
                for j in range(n):
                    X[j] += T[j, i] * qi
    if initial_condition >= IC_RANDOM:
        X = _random_start(X, gamma, K, p, r, beta, initial_condition - IC_RANDOM, settings[11])
        ic_used = initial_condition
        return ctx, work, X, start_phase(X, beta, ctx, 0.0), ic_used
    g0 = _contact_force(p, 1.0, K, X[:n], g_load)
    mode = 0 if abs(g0) <= beta else (1 if g0 > 0.0 else -1)
    return ctx, work, X, mode, ic_used


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
                ok, Xs, used = newton_settle(
                    X, mode, stats, ctx, work, section_rtol, ref, 30, theta
                )
                cycles += used
                if ok:
                    final[: 2 * n] = Xs
                    final[2 * n] = start_phase(Xs, ctx[CTX_BETA], ctx, theta) if mode != 0 else 0
                    final[2 * n + 1] = theta
                    _finish(out, stats, stats_prev, 1, cycles, ic_used)
                    _creep_limit(out, slip_tol)
                    return
    _undetermined(out, NOT_CONVERGED, cycles, ic_used)


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
