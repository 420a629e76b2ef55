"""Closed-form propagation of a linear phase (slip or stick) and bounds of its observable.

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
``F = beta - |y|`` while stuck (unsticking when F reaches 0). A phase is the
pair of arrays ``seg`` (per mode) and ``sc`` (scalars) of
:mod:`tasks.kernel.layout`, filled by :mod:`tasks.kernel.phases`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.kernel.damping import derivative_bounds_damped, evaluate_damped
from tasks.kernel.layout import (
    ALPHA,
    BETA,
    COS_TAU0,
    DAMPED,
    DELTA,
    ETA0,
    ETAD0,
    EVALS,
    KIND,
    KIND_SLIP,
    LEAF,
    LOAD_CONST,
    LOAD_COS,
    OBS0,
    OBS_COS,
    OMEGA,
    SIGN,
    SIN_TAU0,
)


@njit(**LEAF)
def sin_over(e: float, u: float) -> float:
    """``sin(e u) / e``, exact as e -> 0 (limit u)."""
    x = e * u
    if abs(x) < 1e-3:
        x2 = x * x
        return u * (1.0 - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0)))
    return math.sin(x) / e


@njit(inline="always", cache=True)
def _increments(w, e0, v0, a, c, s1, c1, sh, ch, sint, ct0, st0, h):
    """Increments ``(eta - eta0, eta' - eta0')`` of one mode at ``t = 2 h`` (Eq. (1),
    product form), from ``s1, c1 = sin, cos(Omega h)``, ``sh, ch = sin, cos(h)``,
    ``sint = sin t`` and ``ct0, st0 = cos, sin(tau0)``: the arithmetic of
    :func:`evaluate`, shared with :func:`observable_range`."""
    sin_wt = 2.0 * s1 * c1
    one_m_cos = 2.0 * s1 * s1
    sdw = s1 / w
    p = w + 1.0
    e = w - 1.0
    sp = s1 * ch + c1 * sh
    cp = c1 * ch - s1 * sh
    if abs(e) < 0.5:
        sde = sin_over(e, h)
    else:  # sin(e h) = sin(w h) cos h - cos(w h) sin h, one trig call less; as
        # accurate as the sine itself (|w / e| <= 3 bounds the cancellation as t -> 0)
        sde = (s1 * ch - c1 * sh) / e
    cc = 2.0 * sp * sde / p
    cd = (sin_wt + 2.0 * cp * sde) / p
    if abs(e) < 0.5:
        ss = (sint - 2.0 * cp * sde) / (w * p)
    else:
        ss = (sint - 2.0 * sdw * c1) / (w * w - 1.0)
    d_eta = -e0 * one_m_cos + v0 * 2.0 * sdw * c1 + c * 2.0 * sdw * sdw + a * (ct0 * cc - st0 * ss)
    d_etad = -e0 * w * sin_wt - v0 * one_m_cos + c * 2.0 * sdw * c1 + a * (ct0 * cd - st0 * cc)
    return d_eta, d_etad


@njit(inline="always", cache=True)
def _mode_state(seg, k, d_eta, d_etad, ctau, eta, etad):
    """Write mode k's state (its start plus the increments) into ``eta, etad`` and
    return its terms of ``(y, y')`` (``eta'' = -Omega^2 eta + a cos(tau) + c``, Eq. (1))."""
    w = seg[OMEGA, k]
    ek = seg[ETA0, k] + d_eta
    vk = seg[ETAD0, k] + d_etad
    eta[k] = ek
    etad[k] = vk
    return (
        seg[ALPHA, k] * d_eta + seg[DELTA, k] * d_etad,
        seg[ALPHA, k] * vk
        + seg[DELTA, k] * (-w * w * ek + seg[LOAD_COS, k] * ctau + seg[LOAD_CONST, k]),
    )


@njit(**LEAF)
def evaluate(seg, sc, t, eta, etad):
    """State and observable of a phase at time ``t`` after its start.

    Writes the modal displacements and velocities into ``eta`` and ``etad`` and
    returns ``(y, y')``, the observable and its derivative. A damped scene
    (``sc[DAMPED]``) takes :func:`tasks.kernel.damping.evaluate_damped`.
    """
    if sc[DAMPED] != 0.0:
        return evaluate_damped(seg, sc, t, eta, etad)
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
        e0 = seg[ETA0, k]
        v0 = seg[ETAD0, k]
        a = seg[LOAD_COS, k]
        c = seg[LOAD_CONST, k]
        d_eta, d_etad = _increments(w, e0, v0, a, c, s1, c1, sh, ch, sint, ct0, st0, h)
        y_k, dy_k = _mode_state(seg, k, d_eta, d_etad, ctau, eta, etad)
        y += y_k
        dy += dy_k
    return y, dy


@njit(**LEAF)
def evaluate_start(seg, sc, eta, etad):
    """:func:`evaluate` at the phase start (``t = 0``) without its trigonometry.

    At ``t = 0`` every increment of the closed form vanishes, so the state is
    ``(eta0, eta0')`` and ``y = y0``, ``y' = -A sin(tau0) + sum_k alpha_k eta0'_k +
    delta_k eta0''_k`` (``eta0'' = -Omega^2 eta0 + a cos(tau0) + c``, Eq. (1)): the
    same values as ``evaluate(seg, sc, 0.0, eta, etad)`` to the last bit (non-finite
    data propagate as there).
    """
    if sc[DAMPED] != 0.0:
        return evaluate_damped(seg, sc, 0.0, eta, etad)
    ct0 = sc[COS_TAU0]
    amp = sc[OBS_COS]
    y = sc[OBS0] - 0.0 * amp
    dy = -amp * sc[SIN_TAU0]
    for k in range(seg.shape[1]):
        # the increments: 0 (NaN where evaluate's are)
        zero = 0.0 * (
            seg[ETA0, k] + seg[ETAD0, k] + seg[LOAD_COS, k] + seg[LOAD_CONST, k] + seg[OMEGA, k]
        )
        y_k, dy_k = _mode_state(seg, k, zero, zero, ct0, eta, etad)
        y += y_k
        dy += dy_k
    return y, dy


@njit(inline="always", cache=True)
def _extend(y, ymin, ymax, finite):
    """The range ``(ymin, ymax, finite)`` with the sample y (NaN left out, ``finite`` False)."""
    if y != y:
        return ymin, ymax, False
    return min(ymin, y), max(ymax, y), finite


#: Samples between exact re-evaluations of the rotations in :func:`observable_range`
#: (the rounding of a rotation, ~1e-16 relative, grows at most this many times).
ANCHOR = 16


@njit(**LEAF)
def observable_range(seg, sc, dt, n, eta, etad, scratch):
    """Smallest and largest observable ``y`` at the times ``t = i dt``, i = 1..n, of a phase.

    Uniformly spaced times: the sines and cosines of ``t / 2`` and ``Omega_k t / 2``
    are advanced by rotation (angle addition by ``dt / 2``, ``Omega_k dt / 2``: four
    products instead of a trigonometric call per mode and sample) and recomputed
    exactly every :data:`ANCHOR` samples, so the rounding they add stays a few
    1e-15 of each term; the rest is :func:`evaluate`'s arithmetic (``y`` only).
    Returns ``(ymin, ymax, finite)``; NaN samples are left out of the range and make
    ``finite`` False. ``eta, etad`` are scratch; ``scratch`` (at least m rows of 4
    columns) holds the rotations (a damped scene, or fewer rows, evaluates every
    sample with :func:`evaluate`).
    """
    m = seg.shape[1]
    ymin = np.inf
    ymax = -np.inf
    finite = True
    if sc[DAMPED] != 0.0 or scratch.shape[0] < m or scratch.shape[1] < 4:
        for i in range(1, n + 1):
            y, _ = evaluate(seg, sc, i * dt, eta, etad)
            ymin, ymax, finite = _extend(y, ymin, ymax, finite)
        return ymin, ymax, finite
    hd = 0.5 * dt
    sd0 = math.sin(hd)
    cd0 = math.cos(hd)
    for k in range(m):
        whd = seg[OMEGA, k] * hd
        scratch[k, 2] = math.sin(whd)
        scratch[k, 3] = math.cos(whd)
    ct0 = sc[COS_TAU0]
    st0 = sc[SIN_TAU0]
    amp = sc[OBS_COS]
    y0 = sc[OBS0]
    sh = 0.0
    ch = 1.0
    for i in range(1, n + 1):
        anchor = (i - 1) % ANCHOR == 0
        h = 0.5 * (i * dt)
        if anchor:
            sh = math.sin(h)
            ch = math.cos(h)
        else:
            sh, ch = sh * cd0 + ch * sd0, ch * cd0 - sh * sd0
        sint = 2.0 * sh * ch
        y = y0 - 2.0 * amp * (st0 * ch + ct0 * sh) * sh
        for k in range(m):
            w = seg[OMEGA, k]
            if anchor:
                s1 = math.sin(w * h)
                c1 = math.cos(w * h)
            else:
                s_old = scratch[k, 0]
                c_old = scratch[k, 1]
                s1 = s_old * scratch[k, 3] + c_old * scratch[k, 2]
                c1 = c_old * scratch[k, 3] - s_old * scratch[k, 2]
            scratch[k, 0] = s1
            scratch[k, 1] = c1
            d_eta, d_etad = _increments(
                w,
                seg[ETA0, k],
                seg[ETAD0, k],
                seg[LOAD_COS, k],
                seg[LOAD_CONST, k],
                s1,
                c1,
                sh,
                ch,
                sint,
                ct0,
                st0,
                h,
            )
            y += seg[ALPHA, k] * d_eta + seg[DELTA, k] * d_etad
        ymin, ymax, finite = _extend(y, ymin, ymax, finite)
    return ymin, ymax, finite


@njit(**LEAF)
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


@njit(**LEAF)
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
    of the sums). Returns ``inf`` only for non-finite data. A damped scene takes
    :func:`tasks.kernel.damping.derivative_bounds_damped`.
    """
    if sc[DAMPED] != 0.0:
        return derivative_bounds_damped(seg, sc, t_end)
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


@njit(**LEAF)
def start_taylor(seg, sc, t_end):
    """``y''(0)`` and a bound of ``|y'''|`` over ``[0, t_end]`` of a phase's observable.

    With ``F(0)`` and ``F'(0)`` from :func:`evaluate`, the Taylor bound
    ``F(t) >= F(0) + F'(0) t + F''(0) t^2 / 2 - max|F'''| t^3 / 6`` clears the start
    of a phase that begins at an event where ``F'`` vanishes too (the slip after an
    unsticking: the contact velocity and its derivative are zero there), which the
    curvature certificate cannot do. ``y''(0)`` is exact from Eq. (1)
    (``eta'' = -Omega^2 eta + a cos(tau) + c``, ``eta''' = -Omega^2 eta' - a sin(tau)``);
    the bound covers every term as :func:`derivative_bounds` does, one derivative
    higher (modal split ``Omega^4 A_free + |P|``, Duhamel
    ``Omega^4 A0 + |a| (1 + Omega^2 + Omega^3 t)``), times ``1 + 1e-9``.
    Returns ``(y''(0), bound, scale)``, ``scale`` the sum of the absolute values of
    the terms of ``y''(0)`` (its rounding is a few 1e-16 of that); ``(0, inf, 0)``
    for a damped scene (no certificate: the search then bisects as before).
    """
    if sc[DAMPED] != 0.0:
        return 0.0, np.inf, 0.0
    ct0 = sc[COS_TAU0]
    st0 = sc[SIN_TAU0]
    amp = sc[OBS_COS]
    y2 = -amp * ct0
    scale = abs(y2)
    d3 = abs(amp)
    for k in range(seg.shape[1]):
        w = seg[OMEGA, k]
        a = seg[LOAD_COS, k]
        c = seg[LOAD_CONST, k]
        e0 = seg[ETA0, k]
        v0 = seg[ETAD0, k]
        alpha = seg[ALPHA, k]
        delta = seg[DELTA, k]
        w2 = w * w
        y2 += alpha * (-w2 * e0 + a * ct0 + c) + delta * (-w2 * v0 - a * st0)
        scale += abs(alpha) * (abs(w2 * e0) + abs(a * ct0) + abs(c))
        scale += abs(delta) * (abs(w2 * v0) + abs(a * st0))
        abs_a = abs(a)
        static = c / w2
        a0 = math.hypot(e0 - static, v0 / w)
        b3 = w2 * w * a0 + abs_a * (1.0 + w2 * t_end)
        b4 = w2 * w2 * a0 + abs_a * (1.0 + w2 + w2 * w * t_end)
        den = w2 - 1.0
        if den != 0.0:
            pk = a / den
            d = e0 - static - pk * ct0
            e = (v0 + pk * st0) / w
            free = math.hypot(d, e)
            ap = abs(pk)
            b3 = min(b3, w2 * w * free + ap)
            b4 = min(b4, w2 * w2 * free + ap)
        d3 += abs(alpha) * b3 + abs(delta) * b4
    d3 *= 1.0 + 1e-9
    if not (math.isfinite(d3) and math.isfinite(y2)):
        return 0.0, np.inf, 0.0
    return y2, d3, scale
