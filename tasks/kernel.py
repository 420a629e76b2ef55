"""Event-driven simulation of one point: cycles, Poincare section, shooting, regime.

The motion alternates between two linear systems (:mod:`tasks.model`):

* sliding with sign ``s`` (all N coordinates), until the contact velocity
  ``v = b . x'`` reaches 0. There the contact force ``g`` decides: ``|g| <= beta``
  sticks (Eqs. 11, 12, 79, 103), otherwise the slip reverses (``s = sgn g``);
* stuck (N - 1 coordinates, the contact frozen at ``d0 = b . x``), until
  ``|g|`` reaches ``beta``; the contact then slides with ``s = sgn g``.

Each phase is propagated in closed form (:mod:`tasks.propagate`), each event
located by a bracketed root find. Steady state is detected on the Poincare
section ``tau = 2 pi n`` (the excitation has period 2 pi): the section state
``X = (x, x')`` repeating to a relative tolerance (period 1 or 2). Slow
continuous transients are settled by Newton's method on the Poincare map
(shooting). A stick phase that provably never ends (:func:`never_unsticks`)
is the no-motion steady state.

Everything here is compiled with numba (``cache=True``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.propagate import (
    ALPHA,
    BETA,
    COS_TAU0,
    DELTA,
    ETA0,
    ETAD0,
    KIND,
    KIND_SLIP,
    KIND_STICK,
    LOAD_CONST,
    LOAD_COS,
    N_ROWS,
    N_SCALARS,
    OBS0,
    OBS_COS,
    OMEGA,
    SIGN,
    SIN_TAU0,
    TAU0,
    evaluate,
    never_unsticks,
    next_event,
)
from tasks.regimes import (
    CONTINUOUS,
    EVENT_LIMIT,
    IC_HELD,
    IC_REST,
    NO_MOTION,
    NOT_CONVERGED,
    NUMERICAL_FAILURE,
    STICK_SLIP,
    UNBOUNDED,
)

TWO_PI = 2.0 * math.pi

# Entries of the per-cycle statistics array.
ST_STOPS, ST_REVERSALS, ST_STUCK_TIME, ST_DMIN, ST_DMAX, ST_FOREVER, ST_EVENTS, ST_STATUS = range(8)
N_STATS = 8
STATUS_OK = 0.0

# Event records (tasks.trajectory): kinds and columns of the record buffer.
EV_SECTION, EV_STOP, EV_REVERSAL, EV_UNSTICK, EV_GRAZE, EV_END = 0.0, 1.0, 2.0, 3.0, 4.0, 5.0
REC_TAU, REC_KIND, REC_MODE, REC_G, REC_X = range(5)

# Fields of the per-point output array (see tasks.result.FIELDS).
OUT_REGIME, OUT_CONVERGED, OUT_CYCLES, OUT_STOPS, OUT_AMP, OUT_STICK, OUT_PERIOD, OUT_IC = range(8)
N_OUT = 8


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
def run_cycle(x, xd, mode, stick_start, stats, ctx, work, rec, rec_n):
    """Advance ``(x, x', mode)`` over one excitation period ``0 <= tau <= 2 pi``.

    ``mode`` is +1 / -1 (sliding with that sign) or 0 (stuck). ``stick_start``
    is the time the current stick phase began (relative to this cycle's start;
    negative if it began earlier). Fills ``stats`` (stops of duration above
    ``stick_min`` ending in this cycle, reversals, stuck time, min / max of the
    contact displacement ``b . x``, whether the contact provably stays stuck for
    ever, events, status). Returns ``(mode, stick_start)`` for the next cycle
    (``stick_start`` shifted by -2 pi).

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
    ) = ctx
    eta, etad, eta_s, etad_s, q = work
    for i in range(N_STATS):
        stats[i] = 0.0
    d = _dot(b, x)
    stats[ST_DMIN] = d
    stats[ST_DMAX] = d
    tau = 0.0
    v0 = _dot(b, xd)
    events = 0
    _record(rec, rec_n, 0.0, EV_SECTION, mode, _contact_force(p, 1.0, K, x, g_load), x, xd)
    while True:
        remaining = TWO_PI - tau
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
    stats[ST_EVENTS] = events
    for i in range(x.shape[0]):
        if not (math.isfinite(x[i]) and math.isfinite(xd[i])):
            stats[ST_STATUS] = NUMERICAL_FAILURE
    _record(rec, rec_n, TWO_PI, EV_END, mode, _contact_force(p, 1.0, K, x, g_load), x, xd)
    return mode, stick_start - TWO_PI


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
def _cycle(X, mode, stick_start, stats, ctx, work):
    """One period from the section state ``X = (x, x')``; returns the new state."""
    n = X.shape[0] // 2
    x = X[:n].copy()
    xd = X[n:].copy()
    no_record = np.zeros((0, 1))
    no_count = np.zeros(1, dtype=np.int64)
    mode, stick_start = run_cycle(x, xd, mode, stick_start, stats, ctx, work, no_record, no_count)
    out = np.empty(2 * n)
    out[:n] = x
    out[n:] = xd
    return out, mode, stick_start


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
def _shoot(X0, mode, stats, ctx, work, rtol, max_newton):
    """Newton's method on the Poincare map ``P(X) - X = 0`` (shooting).

    Works in the coordinates of the phase the section falls in
    (:func:`_reduce`), with the Jacobian by forward differences (one period per
    column); the section must fall in the same kind of phase (stuck or
    sliding) before and after the period. Returns ``(success, X, cycles_used)``;
    on success ``stats`` holds the statistics of the verified period ``X -> P(X)``.
    """
    n = X0.shape[0] // 2
    b = ctx[6]
    w = ctx[7]
    T = ctx[8]
    proj = ctx[13]
    cycles = 0
    y0 = _reduce(X0, mode, b, w, proj)
    X0 = _expand(y0, mode, n, w, T)
    X1, m1, _ = _cycle(X0, _phase_of(X0, mode, b), 0.0, stats, ctx, work)
    cycles += 1
    if not _same_chart(m1, mode) or stats[ST_STATUS] != STATUS_OK or stats[ST_FOREVER] > 0.0:
        return False, X0, cycles
    y1 = _reduce(X1, mode, b, w, proj)
    dim = y0.shape[0]
    probe = np.empty(N_STATS)
    J = np.empty((dim, dim))
    for _ in range(max_newton):
        R = y1 - y0
        scale = max(_max_abs(X1), 1e-300)
        res = _max_abs(R)
        if res <= rtol * scale:
            return True, X0, cycles
        for k in range(dim):
            hk = 1e-7 * max(abs(y0[k]), 1e-3 * scale)
            yp = y0.copy()
            yp[k] += hk
            Xp = _expand(yp, mode, n, w, T)
            Pk, mk, _ = _cycle(Xp, _phase_of(Xp, mode, b), 0.0, probe, ctx, work)
            cycles += 1
            if not _same_chart(mk, mode) or probe[ST_STATUS] != STATUS_OK:
                return False, X0, cycles
            yk = _reduce(Pk, mode, b, w, proj)
            for i in range(dim):
                J[i, k] = (yk[i] - y1[i]) / hk
        for i in range(dim):
            J[i, i] -= 1.0
        if not np.all(np.isfinite(J)):
            return False, X0, cycles
        try:
            step = np.linalg.solve(J, -R)
        except Exception:  # singular: no isolated fixed point (e.g. resonance)
            return False, X0, cycles
        if not np.all(np.isfinite(step)):
            return False, X0, cycles
        # trust region: a fixed point far beyond the current motion is not a
        # settled transient but a (near-)singular map, e.g. resonant growth
        if _max_abs(step) > 10.0 * scale:
            return False, X0, cycles
        lam = 1.0
        accepted = False
        for _ls in range(5):
            yn = y0 + lam * step
            Xn = _expand(yn, mode, n, w, T)
            X1n, mn, _ = _cycle(Xn, _phase_of(Xn, mode, b), 0.0, stats, ctx, work)
            cycles += 1
            if _same_chart(mn, mode) and stats[ST_STATUS] == STATUS_OK and stats[ST_FOREVER] == 0.0:
                y1n = _reduce(X1n, mode, b, w, proj)
                if _max_abs(y1n - yn) < res:
                    y0 = yn
                    y1 = y1n
                    X0 = Xn
                    X1 = X1n
                    accepted = True
                    break
            lam *= 0.5
        if not accepted:
            return False, X0, cycles
    ok = _max_abs(y1 - y0) <= rtol * max(_max_abs(X1), 1e-300)
    return ok, X0, cycles


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
        max_events,
    )
    work = (np.zeros(n), np.zeros(n), np.zeros(m), np.zeros(m), np.zeros(2 * m))
    # Held start: contact at d0 = 0, the rest on the forced response of the
    # held system at tau = 0 (from rest if the held system is resonant).
    ic_used = initial_condition
    X = np.zeros(2 * n)
    if initial_condition == IC_HELD:
        zeta = np.zeros(m)
        for k in range(m):
            den = seg_stick[OMEGA, k] ** 2 - 1.0
            if seg_stick[LOAD_COS, k] == 0.0:
                continue  # mode not loaded: no forced response
            if abs(den) < 1e-9 * max(seg_stick[OMEGA, k] ** 2, 1.0):
                ic_used = IC_REST
                break
            zeta[k] = seg_stick[LOAD_COS, k] / den
        if ic_used == IC_HELD:
            for i in range(m):
                qi = 0.0
                for k in range(m):
                    qi += phi_s[i, k] * zeta[k]
                for j in range(n):
                    X[j] += T[j, i] * qi
    g0 = _contact_force(p, 1.0, K, X[:n], g_load)
    mode = 0 if abs(g0) <= beta else (1 if g0 > 0.0 else -1)
    return ctx, work, X, mode, ic_used


@njit(cache=True)
def start_phase(X, beta, ctx):
    """Phase a section state starts in: sliding with the sign of ``b . x'``, or
    (at rest relative to the contact) stuck if ``|g| <= beta``."""
    p = ctx[4]
    K = ctx[5]
    b = ctx[6]
    g_load = ctx[16]
    n = X.shape[0] // 2
    v = _dot(b, X[n:])
    if v > 0.0:
        return 1
    if v < 0.0:
        return -1
    g0 = _contact_force(p, 1.0, K, X[:n], g_load)
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
    ) = settings
    ctx, work, X, mode, ic_used = _context(r, beta, scene, settings)
    n = X.shape[0] // 2
    final[: 2 * n] = X
    final[2 * n] = mode
    if beta == 0.0:  # undamped linear system: continuous by definition
        out[OUT_REGIME] = CONTINUOUS
        out[OUT_CONVERGED] = 1.0
        out[OUT_CYCLES] = 0.0
        out[OUT_STOPS] = 0.0
        out[OUT_AMP] = _linear_amplitude(ctx[0])
        out[OUT_STICK] = 0.0
        out[OUT_PERIOD] = 1.0
        out[OUT_IC] = ic_used
        return
    stats = np.zeros(N_STATS)
    stats_prev = np.zeros(N_STATS)
    X_prev = X.copy()
    mode_prev = mode
    mode_prev2 = mode
    X_prev2 = X.copy()
    diff_prev = np.inf
    ref = max(_max_abs(X), 1e-300)
    stick_start = 0.0
    cycles = 0
    next_shot = shooting_after
    shots_failed = 0
    unit_ratio_run = 0
    while cycles < max_cycles:
        X_new, mode_new, stick_start = _cycle(X, mode, stick_start, stats, ctx, work)
        cycles += 1
        final[: 2 * n] = X_new
        final[2 * n] = mode_new
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
        scale = max(_max_abs(X), 1e-300)
        if cycles <= 2:
            ref = max(ref, scale)
        elif scale > growth_factor * ref:
            _undetermined(out, UNBOUNDED, cycles, ic_used)
            return
        diff = _max_abs_diff(X, X_prev)
        if cycles >= min_cycles and _same_chart(mode, mode_prev):
            rho = diff / diff_prev if diff_prev > 0.0 else 0.0
            err = diff / (1.0 - min(rho, 0.999))
            if err <= section_rtol * scale or diff <= 1e-13 * scale:
                final[: 2 * n] = X_prev
                final[2 * n] = mode_prev
                _finish(out, stats, stats_prev, 1, cycles, ic_used)
                return
        if cycles >= min_cycles + 1 and _same_chart(mode, mode_prev2):
            diff2 = _max_abs_diff(X, X_prev2)
            if diff2 <= section_rtol * scale and diff > 10.0 * section_rtol * scale:
                final[: 2 * n] = X_prev2
                final[2 * n] = mode_prev2
                _finish(out, stats, stats_prev, 2, cycles, ic_used)
                return
        # linear growth (resonance without enough friction): increments repeat
        if diff_prev < np.inf and diff > 0.0 and abs(diff / diff_prev - 1.0) < 1e-6:
            unit_ratio_run += 1
        else:
            unit_ratio_run = 0
        if unit_ratio_run >= 10 and scale > 10.0 * ref and (shots_failed > 0 or not shooting):
            _undetermined(out, UNBOUNDED, cycles, ic_used)
            return
        for i in range(N_STATS):
            stats_prev[i] = stats[i]
        diff_prev = diff
        if shooting and cycles >= next_shot:
            next_shot = 2 * next_shot
            ok, Xs, used = _shoot(X, mode, stats, ctx, work, section_rtol, 8)
            cycles += used
            if ok:
                final[: 2 * n] = Xs
                final[2 * n] = start_phase(Xs, ctx[3], ctx) if mode != 0 else 0
                _finish(out, stats, stats_prev, 1, cycles, ic_used)
                return
            shots_failed += 1
    _undetermined(out, NOT_CONVERGED, cycles, ic_used)


@njit(cache=True)
def run_points(r, beta, scene, settings):
    """Classify every point ``(r[i], beta[i])``.

    Returns ``(out, final)``: ``out`` is ``(n_points, N_OUT)`` (columns
    ``OUT_*``), ``final`` the last section state and phase of each point.
    """
    n = scene[0].shape[0]
    out = np.empty((r.shape[0], N_OUT))
    final = np.empty((r.shape[0], 2 * n + 1))
    for i in range(r.shape[0]):
        simulate_point(r[i], beta[i], scene, settings, out[i], final[i])
    return out, final


@njit(cache=True)
def trace_cycles(r, beta, scene, settings, X0, mode0, n_cycles, max_records):
    """Simulate ``n_cycles`` periods from ``(X0, mode0)`` and record every event.

    ``mode0`` < -1 means: use the held initial condition of :func:`_context`.
    Returns ``(records, n_records, X, mode, status)``.
    """
    ctx, work, Xh, mode_h, ic_used = _context(r, beta, scene, settings)
    if mode0 < -1:
        X = Xh
        mode = mode_h
    else:
        X = X0.copy()
        mode = mode0
    n = X.shape[0] // 2
    rec = np.zeros((max_records, REC_X + 2 * n))
    rec_n = np.zeros(1, dtype=np.int64)
    stats = np.zeros(N_STATS)
    x = X[:n].copy()
    xd = X[n:].copy()
    stick_start = 0.0
    status = STATUS_OK
    for _ in range(n_cycles):
        mode, stick_start = run_cycle(x, xd, mode, stick_start, stats, ctx, work, rec, rec_n)
        if stats[ST_STATUS] != STATUS_OK:
            status = stats[ST_STATUS]
            break
    out = np.empty(2 * n)
    out[:n] = x
    out[n:] = xd
    return rec, rec_n[0], out, mode, status
