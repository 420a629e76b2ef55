"""Closed-form propagation of a damped linear phase (docs/structures.md 4).

With proportional (e.g. Rayleigh) damping every mode of both phases obeys

    eta'' + 2 sigma eta' + Omega^2 eta = a cos(tau) + c,                  (4.1)

(``sigma = c_k / (2 r)``, ``c_k = phi_k^T C phi_k``, row ``DAMP`` of ``seg``).
Its solution from ``(eta0, eta0')`` at ``tau0`` is the static part
``c / Omega^2``, the harmonic particular part ``P cos(tau) + Q sin(tau)``,

    P = a (Omega^2 - 1) / D,  Q = 2 sigma a / D,  D = (Omega^2 - 1)^2 + 4 sigma^2,   (4.2)

and a free part ``f`` with ``f(0) = e``, ``f'(0) = v`` (what is left of the
initial state):

    f(t) = E(t) [e C1(t) + (v + sigma e) S1(t)],
    f'(t) = E(t) [v C1(t) - (sigma v + Omega^2 e) S1(t)],                  (4.3)

``E = exp(-sigma t)``, ``C1 = cos(mu t)``, ``S1 = sin(mu t) / mu`` with
``mu^2 = Omega^2 - sigma^2`` (``cosh``, ``sinh`` when overdamped, ``1, t`` at
critical damping). Increments from the phase start are computed with
``expm1`` and half-angle products, as in the undamped propagation, so an
event function that starts at zero keeps its sign right just after the start.

Bounds (rigorous for every sigma >= 0): a free solution ``f`` of (4.1) has the
non-increasing energy ``(f'^2 + Omega^2 f^2) / 2`` (its rate is
``-2 sigma f'^2``), and so has each derivative of it (they are free solutions
too); hence ``|f^(k+1)(t)| <= hypot(f^(k+1)(0), Omega f^(k)(0))`` for all t >= 0.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.kernel.layout import (
    ALPHA,
    COS_TAU0,
    DAMP,
    DELTA,
    ETA0,
    ETAD0,
    LEAF,
    LOAD_CONST,
    LOAD_COS,
    OBS0,
    OBS_COS,
    OMEGA,
    SIN_TAU0,
)


@njit(**LEAF)
def is_damped(seg):
    """True when some mode of the phase has damping (row DAMP)."""
    for k in range(seg.shape[1]):
        if seg[DAMP, k] != 0.0:
            return True
    return False


@njit(**LEAF)
def particular(w, sigma, a):
    """``(P, Q)`` of Eq. (4.2): the harmonic steady state ``P cos tau + Q sin tau``."""
    den = (w * w - 1.0) ** 2 + 4.0 * sigma * sigma
    if den == 0.0:
        return np.inf, np.inf
    return a * (w * w - 1.0) / den, 2.0 * sigma * a / den


@njit(**LEAF)
def mode_split(seg, k, ct0, st0):
    """Mode k of a phase split as in Eq. 4.2-4.3: ``(w, sigma, static, P, Q, e, v)``,
    the static part ``c / Omega^2``, the harmonic part ``(P, Q)`` and the free initial
    state ``(e, v)`` left at the phase start (``P, Q`` infinite at an undamped
    resonance)."""
    w = seg[OMEGA, k]
    sigma = seg[DAMP, k]
    static = seg[LOAD_CONST, k] / (w * w)
    P, Q = particular(w, sigma, seg[LOAD_COS, k])
    e = seg[ETA0, k] - static - (P * ct0 + Q * st0)
    v = seg[ETAD0, k] - (Q * ct0 - P * st0)
    return w, sigma, static, P, Q, e, v


@njit(**LEAF)
def free_factors(w, sigma, t):
    """``(E C1 - 1, E S1)`` of Eq. (4.3) at ``t >= 0``, accurate for small t."""
    mu2 = w * w - sigma * sigma
    if mu2 > 0.0:
        mu = math.sqrt(mu2)
        s = math.sin(0.5 * mu * t)
        c1 = 1.0 - 2.0 * s * s
        ex = math.exp(-sigma * t)
        return math.expm1(-sigma * t) * c1 - 2.0 * s * s, ex * math.sin(mu * t) / mu
    if mu2 < 0.0:
        nu = math.sqrt(-mu2)
        lo = math.expm1(-(sigma - nu) * t)  # sigma > nu: both decay
        hi = math.expm1(-(sigma + nu) * t)
        if nu * t < 1.0:  # near critical damping: no cancellation in lo - hi
            return 0.5 * (lo + hi), math.exp(-sigma * t) * math.sinh(nu * t) / nu
        return 0.5 * (lo + hi), 0.5 * (lo - hi) / nu
    return math.expm1(-sigma * t), math.exp(-sigma * t) * t


@njit(**LEAF)
def free_derivative_bounds(w, sigma, f0, f1):
    """Bounds, for all t >= 0, of ``|f'|``, ``|f''|`` and ``|f'''|`` of the free solution
    of Eq. 4.1 that starts at ``(f0, f1)``: ``hypot(f^(k+1)(0), Omega f^(k)(0))`` (Eq. 4.4)."""
    f2 = -2.0 * sigma * f1 - w * w * f0
    f3 = -2.0 * sigma * f2 - w * w * f1
    return math.hypot(f1, w * f0), math.hypot(f2, w * f1), math.hypot(f3, w * f2)


@njit(**LEAF)
def evaluate_damped(seg, sc, t, eta, etad):
    """:func:`tasks.kernel.propagation.evaluate` for damped modes (Eqs. 4.1-4.3)."""
    m = seg.shape[1]
    h = 0.5 * t
    sh = math.sin(h)
    ch = math.cos(h)
    ct0 = sc[COS_TAU0]
    st0 = sc[SIN_TAU0]
    sint = 2.0 * sh * ch
    ctau = ct0 * (1.0 - 2.0 * sh * sh) - st0 * sint
    stau = st0 * (1.0 - 2.0 * sh * sh) + ct0 * sint
    # cos tau - cos tau0 and sin tau - sin tau0 in product form
    dcos = -2.0 * (st0 * ch + ct0 * sh) * sh
    dsin = 2.0 * (ct0 * ch - st0 * sh) * sh
    amp = sc[OBS_COS]
    y = sc[OBS0] + amp * dcos
    dy = -amp * stau
    for k in range(m):
        w, sigma, _, P, Q, e, v = mode_split(seg, k, ct0, st0)
        a = seg[LOAD_COS, k]
        c = seg[LOAD_CONST, k]
        e0 = seg[ETA0, k]
        v0 = seg[ETAD0, k]
        ecm1, es = free_factors(w, sigma, t)
        d_eta = e * ecm1 + (v + sigma * e) * es + P * dcos + Q * dsin
        d_etad = v * ecm1 - (sigma * v + w * w * e) * es - P * dsin + Q * dcos
        ek = e0 + d_eta
        vk = v0 + d_etad
        eta[k] = ek
        etad[k] = vk
        y += seg[ALPHA, k] * d_eta + seg[DELTA, k] * d_etad
        acc = a * ctau + c - 2.0 * sigma * vk - w * w * ek
        dy += seg[ALPHA, k] * vk + seg[DELTA, k] * acc
    return y, dy


@njit(**LEAF)
def derivative_bounds_damped(seg, sc, t_end):
    """:func:`tasks.kernel.propagation.derivative_bounds` for damped modes.

    Mode by mode, the smaller of two bounds of ``|eta^(k)|``, k = 1, 2, 3:

    * the modal split: free part (energy bound of the module notes, from the
      free initial state) plus the harmonic amplitude ``hypot(P, Q)``;
    * Duhamel: free part about the static offset from the actual initial state,
      plus the zero-start response ``g`` to ``a cos(tau)``, whose energy grows at
      most at the rate ``|a|``: ``|g'| <= |a| t``, ``|g''| <= |a| (1 + t)``,
      ``|g'''| <= |a| (1 + 2 sigma + Omega + t)`` (docs/structures.md 4.2).
    """
    harmonic = abs(sc[OBS_COS])
    d1 = harmonic
    d2 = harmonic
    ct0 = sc[COS_TAU0]
    st0 = sc[SIN_TAU0]
    for k in range(seg.shape[1]):
        w, sigma, static, P, Q, e, v = mode_split(seg, k, ct0, st0)
        abs_a = abs(seg[LOAD_COS, k])
        # Duhamel: free about the static offset + zero-start forced response
        f1, f2, f3 = free_derivative_bounds(w, sigma, seg[ETA0, k] - static, seg[ETAD0, k])
        b1 = f1 + abs_a * t_end
        b2 = f2 + abs_a * (1.0 + t_end)
        b3 = f3 + abs_a * (1.0 + 2.0 * sigma + w + t_end)
        if math.isfinite(P) and math.isfinite(Q):
            ap = math.hypot(P, Q)
            f1, f2, f3 = free_derivative_bounds(w, sigma, e, v)
            b1 = min(b1, f1 + ap)
            b2 = min(b2, f2 + ap)
            b3 = min(b3, f3 + ap)
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
def stick_force_bound_damped(seg, sc):
    """The largest ``|g|`` a damped stick phase can ever reach (docs/structures.md 4.3):
    ``|G0| + hypot(Hc, Hs) + sum_k (|alpha_k| / Omega_k + |delta_k|) sqrt(2 E_k)``,
    ``g = G0 + Hc cos tau + Hs sin tau + sum_k alpha_k f_k + delta_k f_k'`` and
    ``E_k`` the (non-increasing) energy of the free part of mode k."""
    ct0 = sc[COS_TAU0]
    st0 = sc[SIN_TAU0]
    hc = sc[OBS_COS]
    hs = 0.0
    const = sc[OBS0] - sc[OBS_COS] * ct0
    free_sum = 0.0
    for k in range(seg.shape[1]):
        w, _, static, P, Q, e, v = mode_split(seg, k, ct0, st0)
        if not (math.isfinite(P) and math.isfinite(Q)):
            return np.inf
        alpha = seg[ALPHA, k]
        delta = seg[DELTA, k]
        # g(tau0) holds alpha eta0 + delta eta0'; keep only the static part in const
        const -= alpha * (seg[ETA0, k] - static) + delta * seg[ETAD0, k]
        hc += alpha * P + delta * Q
        hs += alpha * Q - delta * P
        free_sum += (abs(alpha) / w + abs(delta)) * math.hypot(v, w * e)
    return abs(const) + math.hypot(hc, hs) + free_sum


@njit(cache=True)
def held_modal_state(seg_stick):
    """Modal displacements and velocities at ``tau = 0`` of the damped held steady
    state (contact at zero relative displacement): ``(P_k, Q_k)`` of Eq. (4.2)."""
    m = seg_stick.shape[1]
    eta = np.zeros(m)
    etad = np.zeros(m)
    for k in range(m):
        if seg_stick[LOAD_COS, k] == 0.0:
            continue
        P, Q = particular(seg_stick[OMEGA, k], seg_stick[DAMP, k], seg_stick[LOAD_COS, k])
        eta[k] = P
        etad[k] = Q
    return eta, etad


@njit(cache=True)
def held_force_amplitude(seg_stick, g_cos):
    """Amplitude of the contact force of the damped held steady state:
    ``hypot(Hc, Hs)`` with ``g_h = Hc cos tau + Hs sin tau`` (docs/structures.md 3.1)."""
    hc = g_cos
    hs = 0.0
    for k in range(seg_stick.shape[1]):
        P, Q = particular(seg_stick[OMEGA, k], seg_stick[DAMP, k], seg_stick[LOAD_COS, k])
        if not (math.isfinite(P) and math.isfinite(Q)):
            return np.inf
        hc += seg_stick[ALPHA, k] * P + seg_stick[DELTA, k] * Q
        hs += seg_stick[ALPHA, k] * Q - seg_stick[DELTA, k] * P
    return math.hypot(hc, hs)


@njit(cache=True)
def linear_amplitude_damped(seg_slip):
    """Amplitude of ``b . x`` in the forced response of the sliding system without
    friction: ``|sum_k w_k (P_k + i Q_k)|`` (row DELTA holds ``w_k = b . phi_k``).
    General damping (row ALPHA not zero, docs/structures.md 4.5): the contact velocity
    ``sum_k alpha_k eta_k + delta_k eta_k' = Vc cos tau + Vs sin tau`` has the
    amplitude of ``b . x`` (unit frequency), ``hypot(Vc, Vs)``."""
    general = False
    for k in range(seg_slip.shape[1]):
        general = general or seg_slip[ALPHA, k] != 0.0
    if general:
        vc = 0.0
        vs = 0.0
        for k in range(seg_slip.shape[1]):
            P, Q = particular(seg_slip[OMEGA, k], seg_slip[DAMP, k], seg_slip[LOAD_COS, k])
            vc += seg_slip[ALPHA, k] * P + seg_slip[DELTA, k] * Q
            vs += seg_slip[ALPHA, k] * Q - seg_slip[DELTA, k] * P
        return math.hypot(vc, vs)
    re = 0.0
    im = 0.0
    for k in range(seg_slip.shape[1]):
        P, Q = particular(seg_slip[OMEGA, k], seg_slip[DAMP, k], seg_slip[LOAD_COS, k])
        re += seg_slip[DELTA, k] * P
        im += seg_slip[DELTA, k] * Q
    return math.hypot(re, im)
