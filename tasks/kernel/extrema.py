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
``ANCHOR`` samples): no trigonometric call per sample and mode. An extremum
located in such a phase is polished at once on the same form, evaluated with
exact trigonometric values (a near-resonant mode, ``|Omega^2 - 1| <
RESONANCE_GAP``, or a damped phase is sampled and polished with the exact
product form of :func:`tasks.kernel.propagation.evaluate` instead).
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

_LO, _HI, _TOP, _BOT, _TOP_T, _BOT_T, _TOP_INEXACT, _BOT_INEXACT, _PREV_Y, _PREV_V = range(10)
#: Samples of the rotation recurrence between two exact anchors (drift ~ ANCHOR eps).
ANCHOR = 32
#: Modes with ``|Omega^2 - 1|`` below this are sampled with the exact product form.
RESONANCE_GAP = 1e-2
#: Located extrema within this fraction of the coordinate's spread of the best
#: one are all polished (the Hermite value errs by ~1e-4 of a mode's amplitude).
MARGIN = 1e-2


@njit(**LEAF)
def _keep_sample_peak(acc, col, yi, kind):
    """Keep the sample ``yi`` next to a maximum (``kind`` > 0) or minimum (``kind`` < 0)
    of column ``col`` as its best exact value so far (``_TOP`` / ``_BOT``), marked exact."""
    if kind > 0.0 and yi > acc[_TOP, col]:
        acc[_TOP, col] = yi
        acc[_TOP_INEXACT, col] = 0.0
    if kind < 0.0 and yi < acc[_BOT, col]:
        acc[_BOT, col] = yi
        acc[_BOT_INEXACT, col] = 0.0


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


@njit(**LEAF)
def _harmonic_form(seg, sc, mod):
    """Rows 2-5 of ``mod`` per mode: ``c / Omega^2``, ``P``, ``F``, ``G / Omega`` of the
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
        mod[2, k] = static
        mod[3, k] = P
        mod[4, k] = seg[ETA0, k] - static - P * ct0
        mod[5, k] = (seg[ETAD0, k] + P * st0) / w
    return True


@njit(**LEAF)
def _halley_value(motion, t_lo, t_hi):
    """The extreme value near ``t`` of a smooth motion given ``(t, y, y', y'', y''')``
    there: Halley's step ``d`` to ``y' = 0`` and ``y`` to fourth order in it (``y``
    itself if the step leaves ``[t_lo, t_hi]``, the smooth stretch)."""
    t, y, v, a, jerk = motion
    denom = 2.0 * a * a - v * jerk
    if denom == 0.0:
        return y
    d = -2.0 * v * a / denom
    if not t_lo <= t + d <= t_hi:
        return y
    return y + d * (v + d * (0.5 * a + d * jerk / 6.0))


@njit(cache=True)
def _polish_harmonic(ctx, work, loaded, mod, pol, col, c, t):
    """``(t, y, y', y'', y''')`` of column ``col`` at ``t`` from the harmonic form of
    the phase ``loaded`` (:func:`_harmonic_form`, in ``mod``): with ``f = F cos(Omega s)
    + G sin(Omega s)``, ``eta = c / Omega^2 + P cos tau + f`` and ``eta'' = -P cos tau
    - Omega^2 f``; ``pol`` is scratch."""
    n = pol.shape[1]
    stick = loaded[3] == 0.0
    seg = ctx[CTX_SEG_STICK] if stick else ctx[CTX_SEG_SLIP]
    m = seg.shape[1]
    s = t - loaded[2]
    ct = math.cos(t)
    st = math.sin(t)
    for mo in range(m):
        w = seg[OMEGA, mo]
        cw = math.cos(w * s)
        sw = math.sin(w * s)
        f = mod[4, mo] * cw + mod[5, mo] * sw
        fd = w * (mod[5, mo] * cw - mod[4, mo] * sw)
        pol[0, mo] = mod[2, mo] + mod[3, mo] * ct + f
        pol[1, mo] = fd - mod[3, mo] * st
        pol[2, mo] = -mod[3, mo] * ct - w * w * f
        pol[3, mo] = mod[3, mo] * st - w * w * fd
    phi, phi_s, T, w_s, q = ctx[CTX_PHI], ctx[CTX_PHI_S], ctx[CTX_T], ctx[CTX_W], work[4]
    off = seg[ETAD_OFF]
    d0 = loaded[4]
    modal_to_state(stick, d0, pol[0, :m], pol[1, :m], pol[4], pol[5], phi, phi_s, T, w_s, q, off)
    modal_to_state(stick, 0.0, pol[2, :m], pol[3, :m], pol[6], pol[7], phi, phi_s, T, w_s, q, off)
    i = col % n
    cf = 0.0 if col < n else -c[i]
    return (t, pol[4, i] + cf * ct, pol[5, i] - cf * st, pol[6, i] - cf * ct, pol[7, i] + cf * st)


@njit(cache=True)
def orbit_extrema(ctx, work, rec, h, c, dout):
    """Amplitudes of every coordinate in both frames into ``dout[:2 n]``.

    ``rec``: the orbit's records (every event, exact states); ``h``: the largest
    sample spacing inside a phase; ``c``: the other frame's coefficients (its
    coordinate is ``q_i - c_i cos tau``). Returns the number of samples taken.
    """
    n = (rec.shape[1] - REC_X) // 2
    nr = rec.shape[0]
    ncol = 2 * n
    # the rotation form: undamped, proportional (not the pairs of general damping)
    plain = ctx[CTX_SC][DAMPED] == 0.0 and ctx[CTX_PHI].shape[0] == n
    phi, phi_s, T, w_s, q = ctx[CTX_PHI], ctx[CTX_PHI_S], ctx[CTX_T], ctx[CTX_W], work[4]
    off_slip = ctx[CTX_SEG_SLIP][ETAD_OFF]
    off_stick = ctx[CTX_SEG_STICK][ETAD_OFF]
    # per column: exact extremes (lo, hi), located extremes (top, bot: samples and
    # interpolated), their times, whether they are inexact samples, the previous sample
    acc = np.empty((10, ncol))
    for col in range(ncol):
        acc[_LO, col] = np.inf
        acc[_HI, col] = -np.inf
        acc[_TOP, col] = -np.inf
        acc[_BOT, col] = np.inf
        acc[_TOP_INEXACT, col] = 0.0
        acc[_BOT_INEXACT, col] = 0.0
    prev_t = 0.0
    cap = 4 * ncol + 16
    cands = np.empty((cap, 6))
    n_c = 0
    mod = np.empty((10, n))  # x, x', the harmonic form (4 rows), its rotation (4 rows)
    x = mod[0]
    xd = mod[1]
    eta_slip, etad_slip, eta_stick, etad_stick = work[0], work[1], work[2], work[3]
    pol = np.empty((8, n))  # modal and physical motion and derivatives at an extremum
    loaded = (-1, 0.0, 0.0, 0.0, 0.0)  # the phase in mod: index, fast, tau0, mode, d0
    last_j = -1
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
            elif k == 1:  # (after the event's sample: its interval is the last phase's)
                d0 = phase_start(ctx, work, rec, j, x, xd)
                fast = plain and _harmonic_form(seg, ctx[CTX_SC], mod)
                loaded = (j, 1.0 if fast else 0.0, tau0, float(mode), d0)
            if exact:
                pass
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
                        mod[8, mo] = math.cos(w * dt)
                        mod[9, mo] = math.sin(w * dt)
                    if anchor:
                        mod[6, mo] = math.cos(w * t)
                        mod[7, mo] = math.sin(w * t)
                    else:
                        cw = mod[6, mo]
                        sw = mod[7, mo]
                        mod[6, mo] = cw * mod[8, mo] - sw * mod[9, mo]
                        mod[7, mo] = sw * mod[8, mo] + cw * mod[9, mo]
                    cw = mod[6, mo]
                    sw = mod[7, mo]
                    eta[mo] = mod[2, mo] + mod[3, mo] * ct + mod[4, mo] * cw + mod[5, mo] * sw
                    etad[mo] = w * (mod[5, mo] * cw - mod[4, mo] * sw) - mod[3, mo] * st
                modal_to_state(mode == 0, d0, eta, etad, x, xd, phi, phi_s, T, w_s, q, off)
            else:  # near resonance or damped: the exact product form
                evaluate(seg, ctx[CTX_SC], t, eta, etad)
                modal_to_state(mode == 0, d0, eta, etad, x, xd, phi, phi_s, T, w_s, q, off)
                ct = math.cos(tau)
                st = math.sin(tau)
            total += 1
            for col in range(ncol):
                i = col % n
                cf = 0.0 if col < n else -c[i]
                y = x[i] + cf * ct
                v = xd[i] - cf * st
                if exact:
                    acc[_LO, col] = min(acc[_LO, col], y)
                    acc[_HI, col] = max(acc[_HI, col], y)
                if y > acc[_TOP, col]:
                    acc[_TOP, col] = y
                    acc[_TOP_T, col] = tau
                    acc[_TOP_INEXACT, col] = 0.0 if exact else 1.0
                if y < acc[_BOT, col]:
                    acc[_BOT, col] = y
                    acc[_BOT_T, col] = tau
                    acc[_BOT_INEXACT, col] = 0.0 if exact else 1.0
                if not first and acc[_PREV_V, col] * v < 0.0:
                    s, yi = hermite_peak(tau - prev_t, acc[_PREV_Y, col], y, acc[_PREV_V, col], v)
                    span = j if k > 0 else last_j  # the phase of the interval
                    if s > 0.0 and loaded[0] == span and loaded[1] != 0.0:
                        kind = 1.0 if acc[_PREV_V, col] > 0.0 else -1.0
                        margin = MARGIN * (acc[_TOP, col] - acc[_BOT, col])
                        if (kind > 0.0 and yi >= acc[_TOP, col] - margin) or (
                            kind < 0.0 and yi <= acc[_BOT, col] + margin
                        ):  # polished now, on the phase's harmonic form
                            motion = _polish_harmonic(
                                ctx, work, loaded, mod, pol, col, c, prev_t + s * (tau - prev_t)
                            )
                            ye = _halley_value(motion, prev_t, tau)
                            acc[_LO, col] = min(acc[_LO, col], ye)
                            acc[_HI, col] = max(acc[_HI, col], ye)
                            _keep_sample_peak(acc, col, yi, kind)
                            s = -1.0
                    if s > 0.0:
                        if n_c == cap:
                            grown = np.empty((2 * cap, 6))
                            grown[:cap] = cands
                            cands = grown
                            cap *= 2
                        kind = 1.0 if acc[_PREV_V, col] > 0.0 else -1.0
                        cands[n_c, 0] = col
                        cands[n_c, 1] = prev_t + s * (tau - prev_t)
                        cands[n_c, 2] = yi
                        cands[n_c, 3] = kind
                        cands[n_c, 4] = prev_t
                        cands[n_c, 5] = tau
                        n_c += 1
                        _keep_sample_peak(acc, col, yi, kind)
                acc[_PREV_Y, col] = y
                acc[_PREV_V, col] = v
            prev_t = tau
            first = False
        last_j = j
    # the located extrema that may be the largest or smallest: polished exactly
    which = np.empty((n_c + 2 * ncol, 6))
    n_all = 0
    for k in range(n_c):
        col = int(cands[k, 0])
        margin = MARGIN * (acc[_TOP, col] - acc[_BOT, col])
        if cands[k, 3] > 0.0 and cands[k, 2] >= acc[_TOP, col] - margin:
            which[n_all] = cands[k]
            n_all += 1
        elif cands[k, 3] < 0.0 and cands[k, 2] <= acc[_BOT, col] + margin:
            which[n_all] = cands[k]
            n_all += 1
    for col in range(ncol):  # a sample beyond every located extremum (a missed pair)
        for row_t, row_inexact in ((_TOP_T, _TOP_INEXACT), (_BOT_T, _BOT_INEXACT)):
            if acc[row_inexact, col] != 0.0:
                which[n_all, 0] = col
                which[n_all, 1] = acc[row_t, col]
                which[n_all, 3] = 0.0
                n_all += 1
    if n_all > 0:  # the others, polished on the exact motion
        times = which[:n_all, 1].copy()
        order = np.argsort(times)
        derivs = np.empty((n_all, 2 * n))
        states = sample_motion(ctx, work, rec, times[order], derivs)
        for pos in range(n_all):
            k = order[pos]
            col = int(which[k, 0])
            i = col % n
            cf = 0.0 if col < n else -c[i]
            t = times[k]
            cos_t = math.cos(t)
            sin_t = math.sin(t)
            y = states[pos, i] + cf * cos_t
            if which[k, 3] != 0.0:
                v = states[pos, n + i] - cf * sin_t
                a = derivs[pos, i] - cf * cos_t
                jerk = derivs[pos, n + i] + cf * sin_t
                y = _halley_value((t, y, v, a, jerk), which[k, 4], which[k, 5])
            acc[_LO, col] = min(acc[_LO, col], y)
            acc[_HI, col] = max(acc[_HI, col], y)
    for col in range(ncol):
        dout[col] = 0.5 * (acc[_HI, col] - acc[_LO, col])
    return total
