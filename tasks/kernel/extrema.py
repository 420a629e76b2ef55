"""Extrema of every coordinate of a recorded orbit: the design amplitudes.

Each phase between two recorded events is closed-form and smooth. It is sampled
uniformly (the recorded events are samples too, exact); the extrema between
samples are located on the cubic Hermite interpolant of the sampled values and
velocities, and every located extremum that may be the largest (or smallest)
of its coordinate is then polished on the exact motion: its exact value,
velocity, acceleration and jerk there (:func:`tasks.kernel.records.sample_motion`)
give Halley's step to the zero of the velocity and the value there to fourth
order in that step (the step is the Hermite location error, ~1e-4 of a modal
period at the default spacing: the neglected term is ~1e-16 relative). Every
recorded event is an exact sample too (the extreme of a coordinate may sit on
an event, where its acceleration jumps).

In an undamped phase whose modes are away from resonance the samples are
computed from the modal closed form written in the mode's own harmonics,
``eta = c / Omega^2 + P cos tau + F cos(Omega t) + G sin(Omega t) / Omega``
(``P = a / (Omega^2 - 1)``, Eq. (1) of :mod:`tasks.kernel.propagation`), with
the harmonics advanced by rotation (angle addition, re-anchored exactly every
``ANCHOR`` samples): no trigonometric call per sample and mode. Those samples
only place the Hermite brackets; the values reported come from exact evaluations.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.kernel.layout import (
    COS_TAU0,
    CTX_PHI,
    CTX_PHI_S,
    CTX_SC,
    CTX_SEG_SLIP,
    CTX_SEG_STICK,
    CTX_T,
    CTX_W,
    DAMPED,
    ETA0,
    ETAD0,
    ETAD_OFF,
    LEAF,
    LOAD_CONST,
    LOAD_COS,
    OMEGA,
    REC_MODE,
    REC_TAU,
    REC_X,
    SIN_TAU0,
)
from tasks.kernel.propagation import evaluate
from tasks.kernel.records import modal_to_state, phase_start, sample_motion

#: Samples of the rotation recurrence between two exact anchors (drift ~ ANCHOR eps).
ANCHOR = 32
#: Modes with ``|Omega^2 - 1|`` below this are sampled with the exact product form.
RESONANCE_GAP = 1e-2
#: Located extrema within this fraction of the coordinate's spread of the best
#: one are all polished (the Hermite value errs by ~1e-4 of a mode's amplitude).
MARGIN = 1e-2


@njit(**LEAF)
def hermite_peak(h, y0, y1, v0, v1):
    """The interior extremum of the cubic Hermite interpolant on ``[0, h]``.

    ``y`` and its derivative ``v`` are given at both ends, with ``v0 v1 < 0``.
    Returns ``(s, y)``: the extremum's place as a fraction ``s`` of ``h`` and its
    interpolated value, ``s = -1`` if none lies strictly inside.
    """
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
        return -1.0, 0.0
    h00 = (1.0 + 2.0 * s) * (1.0 - s) ** 2
    h10 = s * (1.0 - s) ** 2
    h01 = s * s * (3.0 - 2.0 * s)
    h11 = s * s * (s - 1.0)
    return s, y0 * h00 + h * v0 * h10 + y1 * h01 + h * v1 * h11


@njit(cache=True)
def _harmonic_form(seg, sc, coef):
    """Rows of ``coef`` per mode: ``c / Omega^2``, ``P``, ``F``, ``G / Omega`` of the
    phase set in ``seg``, ``sc`` (undamped); False if a mode is near resonance."""
    ct0 = sc[COS_TAU0]
    st0 = sc[SIN_TAU0]
    for k in range(seg.shape[1]):
        w = seg[OMEGA, k]
        d = w * w - 1.0
        if not abs(d) >= RESONANCE_GAP or not w > 0.0:
            return False
        P = seg[LOAD_COS, k] / d
        static = seg[LOAD_CONST, k] / (w * w)
        coef[0, k] = static
        coef[1, k] = P
        coef[2, k] = seg[ETA0, k] - static - P * ct0
        coef[3, k] = (seg[ETAD0, k] + P * st0) / w
    return True


@njit(cache=True)
def orbit_extrema(ctx, work, rec, h, c, dout):
    """Amplitudes of every coordinate in both frames into ``dout[:2 n]``.

    ``rec``: the orbit's records (every event, exact states); ``h``: the largest
    sample spacing inside a phase; ``c``: the other frame's sign (its coordinate is
    ``q_i - c cos tau``). Returns the number of samples taken.
    """
    n = (rec.shape[1] - REC_X) // 2
    nr = rec.shape[0]
    ncol = 2 * n
    # the rotation form: undamped, proportional (not the pairs of general damping)
    plain = ctx[CTX_SC][DAMPED] == 0.0 and ctx[CTX_PHI].shape[0] == n
    phi, phi_s, T, w_s, q = ctx[CTX_PHI], ctx[CTX_PHI_S], ctx[CTX_T], ctx[CTX_W], work[4]
    off_slip = ctx[CTX_SEG_SLIP][ETAD_OFF]
    off_stick = ctx[CTX_SEG_STICK][ETAD_OFF]
    lo = np.full(ncol, np.inf)  # exact extreme values
    hi = np.full(ncol, -np.inf)
    top = np.full(ncol, -np.inf)  # located (samples, interpolated) extremes
    bot = np.full(ncol, np.inf)
    top_t = np.zeros(ncol)
    bot_t = np.zeros(ncol)
    top_inexact = np.zeros(ncol, dtype=np.bool_)
    bot_inexact = np.zeros(ncol, dtype=np.bool_)
    prev_t = 0.0
    prev_y = np.empty(ncol)
    prev_v = np.empty(ncol)
    cap = 4 * ncol + 16
    cands = np.empty((cap, 6))
    n_c = 0
    x = np.empty(n)
    xd = np.empty(n)
    coef = np.empty((4, n))
    rot = np.empty((4, n))  # cos, sin of Omega t, and of Omega dt
    eta_slip = np.empty(n)
    etad_slip = np.empty(n)
    eta_stick = np.empty(ctx[CTX_SEG_STICK].shape[1])
    etad_stick = np.empty(ctx[CTX_SEG_STICK].shape[1])
    total = 0
    first = True
    for j in range(nr):
        last = j == nr - 1
        length = 0.0 if last else rec[j + 1, REC_TAU] - rec[j, REC_TAU]
        if not last and not length > 0.0:
            continue
        tau0 = rec[j, REC_TAU]
        k_j = 1 if last else max(1, int(math.ceil(length / h)))
        dt = length / k_j
        mode = int(rec[j, REC_MODE])
        fast = False
        seg = ctx[CTX_SEG_SLIP] if mode != 0 else ctx[CTX_SEG_STICK]
        m = seg.shape[1]
        eta = eta_slip if mode != 0 else eta_stick
        off = off_slip if mode != 0 else off_stick
        etad = etad_slip if mode != 0 else etad_stick
        d0 = 0.0
        if k_j > 1:
            d0 = phase_start(ctx, work, rec, j, x, xd)
            fast = plain and _harmonic_form(seg, ctx[CTX_SC], coef)
        cdt = math.cos(dt)
        sdt = math.sin(dt)
        ct = 0.0
        st = 0.0
        for k in range(k_j):
            t = k * dt
            tau = tau0 + t
            exact = k == 0
            if exact:  # the recorded event: exact
                for i in range(n):
                    x[i] = rec[j, REC_X + i]
                    xd[i] = rec[j, REC_X + n + i]
                ct = math.cos(tau)
                st = math.sin(tau)
            elif fast:
                anchor = (k - 1) % ANCHOR == 0  # exact harmonics, then rotated
                if anchor:
                    ct = math.cos(tau)
                    st = math.sin(tau)
                else:
                    ct, st = ct * cdt - st * sdt, st * cdt + ct * sdt
                for mo in range(m):
                    w = seg[OMEGA, mo]
                    if k == 1:
                        rot[2, mo] = math.cos(w * dt)
                        rot[3, mo] = math.sin(w * dt)
                    if anchor:
                        rot[0, mo] = math.cos(w * t)
                        rot[1, mo] = math.sin(w * t)
                    else:
                        cw = rot[0, mo]
                        sw = rot[1, mo]
                        rot[0, mo] = cw * rot[2, mo] - sw * rot[3, mo]
                        rot[1, mo] = sw * rot[2, mo] + cw * rot[3, mo]
                    cw = rot[0, mo]
                    sw = rot[1, mo]
                    eta[mo] = coef[0, mo] + coef[1, mo] * ct + coef[2, mo] * cw + coef[3, mo] * sw
                    etad[mo] = w * (coef[3, mo] * cw - coef[2, mo] * sw) - coef[1, mo] * st
                modal_to_state(mode == 0, d0, eta, etad, x, xd, phi, phi_s, T, w_s, q, off)
            else:  # near resonance or damped: the exact product form
                evaluate(seg, ctx[CTX_SC], t, eta, etad)
                modal_to_state(mode == 0, d0, eta, etad, x, xd, phi, phi_s, T, w_s, q, off)
                ct = math.cos(tau)
                st = math.sin(tau)
            total += 1
            for col in range(ncol):
                i = col % n
                cf = 0.0 if col < n else -c
                y = x[i] + cf * ct
                v = xd[i] - cf * st
                if exact:
                    lo[col] = min(lo[col], y)
                    hi[col] = max(hi[col], y)
                if y > top[col]:
                    top[col] = y
                    top_t[col] = tau
                    top_inexact[col] = not exact
                if y < bot[col]:
                    bot[col] = y
                    bot_t[col] = tau
                    bot_inexact[col] = not exact
                if not first and prev_v[col] * v < 0.0:
                    s, yi = hermite_peak(tau - prev_t, prev_y[col], y, prev_v[col], v)
                    if s > 0.0:
                        if n_c == cap:
                            grown = np.empty((2 * cap, 6))
                            grown[:cap] = cands
                            cands = grown
                            cap *= 2
                        kind = 1.0 if prev_v[col] > 0.0 else -1.0
                        cands[n_c, 0] = col
                        cands[n_c, 1] = prev_t + s * (tau - prev_t)
                        cands[n_c, 2] = yi
                        cands[n_c, 3] = kind
                        cands[n_c, 4] = prev_t
                        cands[n_c, 5] = tau
                        n_c += 1
                        if kind > 0.0 and yi > top[col]:
                            top[col] = yi
                            top_inexact[col] = False
                        if kind < 0.0 and yi < bot[col]:
                            bot[col] = yi
                            bot_inexact[col] = False
                prev_y[col] = y
                prev_v[col] = v
            prev_t = tau
            first = False
    # the located extrema that may be the largest or smallest: polished exactly
    pick = np.empty(n_c + 2 * ncol, dtype=np.int64)
    n_p = 0
    for k in range(n_c):
        col = int(cands[k, 0])
        margin = MARGIN * (top[col] - bot[col])
        if cands[k, 3] > 0.0 and cands[k, 2] >= top[col] - margin:
            pick[n_p] = k
            n_p += 1
        elif cands[k, 3] < 0.0 and cands[k, 2] <= bot[col] + margin:
            pick[n_p] = k
            n_p += 1
    extra = np.empty((2 * ncol, 6))
    n_e = 0
    for col in range(ncol):  # a sample beyond every located extremum (a missed pair)
        if top_inexact[col]:
            extra[n_e, 0] = col
            extra[n_e, 1] = top_t[col]
            extra[n_e, 3] = 0.0
            n_e += 1
        if bot_inexact[col]:
            extra[n_e, 0] = col
            extra[n_e, 1] = bot_t[col]
            extra[n_e, 3] = 0.0
            n_e += 1
    n_all = n_p + n_e
    times = np.empty(n_all)
    which = np.empty((n_all, 6))
    for k in range(n_p):
        which[k] = cands[pick[k]]
    for k in range(n_e):
        which[n_p + k] = extra[k]
    for k in range(n_all):
        times[k] = which[k, 1]
    order = np.argsort(times)
    derivs = np.empty((n_all, 2 * n))
    states = sample_motion(ctx, work, rec, times[order], derivs)
    for pos in range(n_all):
        k = order[pos]
        col = int(which[k, 0])
        i = col % n
        cf = 0.0 if col < n else -c
        t = times[k]
        cos_t = math.cos(t)
        sin_t = math.sin(t)
        y = states[pos, i] + cf * cos_t
        if which[k, 3] != 0.0:  # Halley's step to v = 0, the value to fourth order
            v = states[pos, n + i] - cf * sin_t
            a = derivs[pos, i] - cf * cos_t
            jerk = derivs[pos, n + i] + cf * sin_t
            denom = 2.0 * a * a - v * jerk
            if denom != 0.0:
                d = -2.0 * v * a / denom
                if which[k, 4] <= t + d <= which[k, 5]:
                    y += d * (v + d * (0.5 * a + d * jerk / 6.0))
        lo[col] = min(lo[col], y)
        hi[col] = max(hi[col], y)
    for col in range(ncol):
        dout[col] = 0.5 * (hi[col] - lo[col])
    return total
