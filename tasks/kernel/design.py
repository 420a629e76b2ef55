"""Design quantities of a converged orbit: amplitudes, contact force amplitude, dissipation.

The orbit is replayed event by event and sampled exactly (closed-form phases);
extrema between samples are located on the cubic Hermite interpolant of the
exact values and velocities and evaluated exactly (docs/theory.md 2). The viscous
dissipation of a damped orbit, the integral of ``r x'^T C x'`` (docs/structures.md
1, Eq. 1.1), is a Gauss-Legendre quadrature on the same sub-intervals, whose ends
include every event, so the integrand is analytic on each of them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.kernel.context import _context
from tasks.kernel.cycle import replay_cycles
from tasks.kernel.damping import particular, stick_force_bound_damped
from tasks.kernel.extrema import hermite_peak, orbit_extrema
from tasks.kernel.layout import (
    CTX_B,
    CTX_G_LOAD,
    CTX_H_SLIP,
    CTX_H_STICK,
    CTX_K,
    CTX_MAX_EVENTS,
    CTX_P,
    CTX_PHI,
    CTX_PHI_S,
    CTX_PHI_T_GAMMA,
    CTX_SC,
    CTX_SEG_SLIP,
    CTX_SEG_STICK,
    CTX_T,
    DAMP,
    DAMPED,
    LEAF,
    LOAD_COS,
    N_STATS,
    OMEGA,
    OUT_CONVERGED,
    OUT_PERIOD,
    OUT_REGIME,
    REC_MODE,
    REC_TAU,
    REC_X,
    ST_STATUS,
    STATUS_OK,
    TWO_PI,
)
from tasks.kernel.phases import _contact_force, _dot, _matvec, start_stick_in
from tasks.kernel.records import sample_states
from tasks.kernel.starts import _held_response

# Columns of :func:`orbit_designs`'s output, per point (n = number of masses):
# [0, n) amplitude of the scene coordinate q_i (x_i; z_i = x_i - y for a base-fixed wall),
# [n, 2n) amplitude of the other coordinate q_i - c_i cos(tau) (:func:`other_frame`: the
# absolute z_i + u_i cos(tau) under a base load, x_i - cos(tau) under a force load),
# 2n the contact force amplitude, 2n + 1 the energy dissipated per excitation cycle by
# the contact, 2n + 2 the energy dissipated per excitation cycle by the viscous damping.
DESIGN_FORCE = 0  # offset from 2 n
DESIGN_DISSIPATION = 1  # offset from 2 n
DESIGN_VISCOUS = 2  # offset from 2 n
#: Columns after the 2 n amplitudes.
DESIGN_SCALARS = 3
#: Gauss-Legendre nodes (on [0, 1]) and weights of the viscous dissipation quadrature.
_GL_NODES = np.array(
    [
        0.5 - 0.5 * 0.8611363115940526,
        0.5 - 0.5 * 0.3399810435848563,
        0.5 + 0.5 * 0.3399810435848563,
        0.5 + 0.5 * 0.8611363115940526,
    ]
)
_GL_WEIGHTS = (
    np.array([0.3478548451374538, 0.6521451548625461, 0.6521451548625461, 0.3478548451374538]) * 0.5
)
#: Samples per excitation cycle (at least; more where modal periods are short).
DESIGN_SAMPLES = 32
#: Samples per half period of the highest mode (exact extrema, :mod:`tasks.kernel.extrema`).
MODE_SAMPLES = 4.0
#: Samples per excitation cycle at most (very stiff chains: the modes far above
#: the excitation are then resolved only as far as this allows).
DESIGN_MAX_SAMPLES = 4096


@njit(cache=True)
def other_frame(scene, n):
    """The coefficients ``c_i`` of the other frame's coordinate ``q_i - c_i cos tau``.

    A force load: ``c_i = 1`` (``x_i - cos tau``, relative to a moving base). A base
    load ``p = r^2 M u`` (docs/theory.md 2, Eq. 98; docs/structures.md 1): the
    coordinates are relative to the supports and the absolute displacement is ``z_i
    + u_i cos tau``, so ``c_i = -u_i``, with ``u = Phi Phi^T p_hat`` (the modes
    ``Phi`` of ``(K, M)`` with ``Phi^T M Phi = I``, so ``Phi Phi^T = M^-1``, and
    ``p_hat = M u`` the load before its factor ``r^2``: ``scene[3]``). An influence
    within ``1e-9 max |u|`` of 1 is taken as exactly 1 (``c_i = -1``: the samples of
    ``z_i + cos tau``, a chain's and a translation's).
    Under damping that is not proportional the modes are the pairs' (no ``Phi``):
    ``c_i = -1`` for every DOF, and a DOF with another ``u_i`` has no absolute
    amplitude (:func:`tasks.classifier.design_fields`).
    """
    c = np.ones(n)
    if not scene[4]:
        return c
    c[:] = -1.0
    phi = scene[6]
    if phi.shape[0] != n:  # the pairs of non-proportional damping
        return c
    p_hat = scene[3]
    modal = np.zeros(n)
    for k in range(n):
        for j in range(n):
            modal[k] += phi[j, k] * p_hat[j]
    u = np.zeros(n)
    top = 0.0
    for i in range(n):
        for k in range(n):
            u[i] += phi[i, k] * modal[k]
        top = max(top, abs(u[i]))
    for i in range(n):
        if abs(u[i] - 1.0) > 1e-9 * top:
            c[i] = -u[i]
    return c


@njit(**LEAF)
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
    s, y = hermite_peak(h, y0, y1, v0, v1)
    if s < 0.0:
        return
    if y < acc[0]:
        acc[0] = y
        acc[2] = t0 + s * h
    if y > acc[1]:
        acc[1] = y
        acc[3] = t0 + s * h


@njit(cache=True)
def orbit_design(r, beta, scene, settings, state, period, samples, dout):
    """:func:`orbit_design_recorded` replaying the orbit itself; returns the number of samples."""
    n = (state.shape[0] - 2) // 2
    rec = np.zeros((0, REC_X + 2 * n))
    return orbit_design_recorded(r, beta, scene, settings, state, period, samples, dout, rec, 0)


@njit(cache=True)
def orbit_design_recorded(r, beta, scene, settings, state, period, samples, dout, rec_in, nr_in):
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
    ``period`` (units k_1 Y^2; docs/theory.md 2), and the viscous energy dissipated
    per excitation cycle (``int r x'^T C x' dtau`` over the orbit divided by
    ``period``; 0 when undamped). ``rec_in`` may hold the orbit's ``nr_in > 0``
    records already (:func:`tasks.kernel.orbit.record_orbit`, the same replay):
    then it is not replayed again. Returns the number of samples.

    An undamped orbit that slides takes :func:`tasks.kernel.extrema.orbit_extrema`
    (samples of the rotation form, extrema polished by Halley's step on the exact
    motion) at the same sample spacing, and needs no quadrature.
    """
    ctx, work = _context(r, beta, scene, settings)[:2]
    n = (state.shape[0] - 2) // 2
    c = other_frame(scene, n)  # other frame: z + u cos tau (base) or x - cos tau
    p = ctx[CTX_P]
    K = ctx[CTX_K]
    b = ctx[CTX_B]
    g_load = ctx[CTX_G_LOAD]
    damped = ctx[CTX_SC][DAMPED] != 0.0
    C = scene[25]  # general damping only (else empty): r x'^T C x' directly
    if beta == 0.0 and C.shape[0] == n:  # linear, general damping (pairs, eta' = xi)
        seg = ctx[CTX_SEG_SLIP]
        V = ctx[CTX_PHI]
        cos_v = np.zeros(n)
        sin_v = np.zeros(n)
        for i in range(n):
            vc = 0.0
            vs = 0.0
            for k in range(n):
                P, Q = particular(seg[OMEGA, k], seg[DAMP, k], seg[LOAD_COS, k])
                vc += V[i, k] * P + V[i, n + k] * Q
                vs += V[i, k] * Q - V[i, n + k] * P
                cos_v[i] += V[n + i, k] * P + V[n + i, n + k] * Q
                sin_v[i] += V[n + i, k] * Q - V[n + i, n + k] * P
            dout[i] = math.hypot(vc, vs)
            dout[n + i] = math.hypot(vc - c[i], vs)
        dout[2 * n + DESIGN_FORCE] = 0.0
        dout[2 * n + DESIGN_DISSIPATION] = 0.0
        visc = 0.0
        for i in range(n):
            for j in range(n):
                visc += C[i, j] * (cos_v[i] * cos_v[j] + sin_v[i] * sin_v[j])
        dout[2 * n + DESIGN_VISCOUS] = math.pi * r * visc
        return 0
    if beta == 0.0 and damped:  # linear, damped: sum_k phi_k (P_k cos + Q_k sin)
        seg = ctx[CTX_SEG_SLIP]
        phi = ctx[CTX_PHI]
        for i in range(n):
            vc = 0.0
            vs = 0.0
            for k in range(n):
                P, Q = particular(seg[OMEGA, k], seg[DAMP, k], seg[LOAD_COS, k])
                vc += phi[i, k] * P
                vs += phi[i, k] * Q
            dout[i] = math.hypot(vc, vs)
            dout[n + i] = math.hypot(vc - c[i], vs)
        dout[2 * n + DESIGN_FORCE] = 0.0
        dout[2 * n + DESIGN_DISSIPATION] = 0.0
        dout[2 * n + DESIGN_VISCOUS] = _harmonic_viscous(seg, r)
        return 0
    if beta == 0.0:  # linear, undamped: the forced response (K - M)^-1 p cos tau
        seg = ctx[CTX_SEG_SLIP]
        phi = ctx[CTX_PHI]
        for i in range(n):
            v = 0.0
            for k in range(n):
                v += phi[i, k] * seg[LOAD_COS, k] / (seg[OMEGA, k] ** 2 - 1.0)
            dout[i] = abs(v)
            dout[n + i] = abs(v - c[i])
        dout[2 * n + DESIGN_FORCE] = 0.0
        dout[2 * n + DESIGN_DISSIPATION] = 0.0
        dout[2 * n + DESIGN_VISCOUS] = 0.0
        return 0
    theta = state[2 * n + 1]
    if not damped and C.shape[0] != n and _held_design(ctx, state, period, c, dout):
        return 0
    rows = 32 * period  # grown (and the orbit replayed) if the events do not fit
    rec = rec_in
    rec_n = np.zeros(1, dtype=np.int64)
    rec_n[0] = nr_in
    stats = np.zeros(N_STATS)
    while nr_in == 0:
        rec = np.empty((rows, REC_X + 2 * n))
        rec_n[0] = 0
        x = state[:n].copy()
        xd = state[n : 2 * n].copy()
        replay_cycles(x, xd, int(state[2 * n]), theta, period, stats, ctx, work, rec, rec_n)
        if stats[ST_STATUS] != STATUS_OK:  # the replay ran out of budget: no answer
            for i in range(dout.shape[0]):
                dout[i] = np.nan
            return 0
        if rec_n[0] < rows or rows > period * (ctx[CTX_MAX_EVENTS] + 4):
            break
        rows *= 8
    nr = rec_n[0]
    rec = rec[:nr]
    slip, sliding = _slip_distance(rec, b)
    if sliding and not damped and C.shape[0] != n:  # exact extrema (tasks.kernel.extrema)
        om_max = 1.0
        for seg in (ctx[CTX_SEG_SLIP], ctx[CTX_SEG_STICK]):
            for k in range(seg.shape[1]):
                om_max = max(om_max, seg[OMEGA, k])
        h = min(TWO_PI / samples, math.pi / (MODE_SAMPLES * om_max))
        h = max(h, TWO_PI / DESIGN_MAX_SAMPLES)
        count = orbit_extrema(ctx, work, rec, h, c, dout)
        dout[2 * n + DESIGN_FORCE] = beta
        dout[2 * n + DESIGN_DISSIPATION] = beta * slip / period
        dout[2 * n + DESIGN_VISCOUS] = 0.0
        return count
    # sample times: every phase start and end, and at most h apart inside a phase
    h = min(TWO_PI / samples, 0.5 * min(ctx[CTX_H_SLIP], ctx[CTX_H_STICK]))
    h = max(h, TWO_PI / DESIGN_MAX_SAMPLES)
    count = 1
    for j in range(nr - 1):
        length = rec[j + 1, REC_TAU] - rec[j, REC_TAU]
        if length > 0.0:
            count += max(1, int(math.ceil(length / h)))
    taus = np.empty(count)
    i_s = 0
    for j in range(nr - 1):
        length = rec[j + 1, REC_TAU] - rec[j, REC_TAU]
        if length <= 0.0:
            continue
        k_j = max(1, int(math.ceil(length / h)))
        for k in range(k_j):
            taus[i_s] = rec[j, REC_TAU] + length * k / k_j
            i_s += 1
    taus[count - 1] = rec[nr - 1, REC_TAU]
    states = sample_states(ctx, work, rec, taus)
    cos_t = np.empty(count)
    sin_t = np.empty(count)
    for s in range(count):
        cos_t[s] = math.cos(taus[s])
        sin_t[s] = math.sin(taus[s])
    _amplitudes(ctx, work, rec, taus, states, cos_t, sin_t, c, dout)
    acc = np.empty(6)
    refine = np.empty(2)
    if sliding:
        force = beta
    elif damped:  # stuck the whole (converged) orbit: G0 + Hc cos + Hs sin, no free part left
        x = state[:n].copy()
        xd = state[n : 2 * n].copy()
        eta, etad, eta_s, etad_s, q, _ = work
        start_stick_in(ctx, x, xd, theta, beta, q)
        force = stick_force_bound_damped(ctx[CTX_SEG_STICK], ctx[CTX_SC])
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
            ga = _contact_force(p, cos_t[s], K, states[s, :n].copy(), g_load)
            gb = _contact_force(p, cos_t[s + 1], K, states[s + 1, :n].copy(), g_load)
            _matvec(K, states[s, n:].copy(), kxd)
            dga = -sin_t[s] * gp - _dot(g_load, kxd)
            _matvec(K, states[s + 1, n:].copy(), kxd)
            dgb = -sin_t[s + 1] * gp - _dot(g_load, kxd)
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
    viscous = 0.0
    if damped:
        viscous = _viscous_work(ctx, work, rec, taus, r, C) / period
    dout[2 * n + DESIGN_VISCOUS] = viscous
    return count


@njit(cache=True)
def _amplitudes(ctx, work, rec, taus, states, cos_t, sin_t, c, dout):
    """Amplitudes (half peak-to-peak) of every coordinate in both frames into ``dout[:2 n]``.

    ``states`` are the exact states at the sample times ``taus`` (``cos_t``, ``sin_t``
    their cosines and sines), ``c`` the other frame's coefficients (``q_i - c_i cos
    tau``, :func:`other_frame`).
    The extrema between samples are located on the cubic Hermite interpolant
    (:func:`_hermite_extremes`); the interpolated smallest and largest value of each
    coordinate are then evaluated exactly, all in one pass over the records.
    """
    n = states.shape[1] // 2
    count = taus.shape[0]
    acc = np.empty((2 * n, 6))
    for col in range(2 * n):
        acc[col, 0] = np.inf
        acc[col, 1] = -np.inf
        acc[col, 4] = np.inf
        acc[col, 5] = -np.inf
    for s in range(count - 1):
        ta = taus[s]
        tb = taus[s + 1]
        for which in range(2):
            for i in range(n):
                cf = 0.0 if which == 0 else -c[i]
                ya = states[s, i] + cf * cos_t[s]
                yb = states[s + 1, i] + cf * cos_t[s + 1]
                va = states[s, n + i] - cf * sin_t[s]
                vb = states[s + 1, n + i] - cf * sin_t[s + 1]
                _hermite_extremes(ta, tb, ya, yb, va, vb, acc[which * n + i])
    # the interpolated extrema evaluated exactly (error O(h^6), never above)
    times = np.empty(4 * n)
    for col in range(2 * n):
        times[2 * col] = min(acc[col, 2], acc[col, 3])
        times[2 * col + 1] = max(acc[col, 2], acc[col, 3])
    order = np.argsort(times)
    exact = sample_states(ctx, work, rec, times[order])
    for pos in range(4 * n):
        col = order[pos] // 2
        i = col % n
        cf = 0.0 if col < n else -c[i]
        y = exact[pos, i] + cf * math.cos(times[order[pos]])
        acc[col, 4] = min(acc[col, 4], y)
        acc[col, 5] = max(acc[col, 5], y)
    for col in range(2 * n):
        dout[col] = 0.5 * (acc[col, 5] - acc[col, 4])


@njit(cache=True)
def _slip_distance(rec, b):
    """``(sum |delta (b . x)|`` over the slip phases of the records, whether any slips)."""
    n = b.shape[0]
    slip = 0.0
    sliding = False
    for j in range(rec.shape[0] - 1):
        if rec[j + 1, REC_TAU] - rec[j, REC_TAU] <= 0.0 or rec[j, REC_MODE] == 0.0:
            continue
        sliding = True
        d0 = 0.0
        d1 = 0.0
        for i in range(n):
            d0 += b[i] * rec[j, REC_X + i]
            d1 += b[i] * rec[j + 1, REC_X + i]
        slip += abs(d1 - d0)
    return slip, sliding


@njit(cache=True)
def _held_design(ctx, state, period, c, dout):
    """Design quantities of the held steady state in closed form, if ``state`` is it.

    The held steady state (:func:`tasks.kernel.starts._held_response`, undamped)
    is ``x_h(tau) = x_h(0) cos tau`` with the contact stuck at zero relative
    displacement, so its amplitudes are ``|x_h,i(0)|`` and ``|x_h,i(0) - c_i|``,
    its contact force amplitude ``|g_h(0)|`` (``g_h(tau) = g_h(0) cos tau``) and
    it dissipates nothing (no slip, no damping). Applies only when ``state`` is
    exactly that orbit at its section (stuck, ``theta = 0``, period 1, the held
    state to the last bit: the no-motion points decided in their first cycle or
    by :func:`tasks.kernel.starts.held_margin`); returns whether it did.
    """
    n = (state.shape[0] - 2) // 2
    if period != 1 or state[2 * n] != 0.0 or state[2 * n + 1] != 0.0:
        return False
    X_held, exists = _held_response(
        ctx[CTX_SEG_STICK], ctx[CTX_PHI_S], ctx[CTX_T], n, ctx[CTX_P], ctx[CTX_K], ctx[CTX_G_LOAD]
    )
    if not exists:
        return False
    for i in range(2 * n):
        if state[i] != X_held[i]:
            return False
    for i in range(n):
        dout[i] = abs(X_held[i])
        dout[n + i] = abs(X_held[i] - c[i])
    g0 = _contact_force(ctx[CTX_P], 1.0, ctx[CTX_K], X_held[:n], ctx[CTX_G_LOAD])
    dout[2 * n + DESIGN_FORCE] = abs(g0)
    dout[2 * n + DESIGN_DISSIPATION] = 0.0
    dout[2 * n + DESIGN_VISCOUS] = 0.0
    return True


@njit(cache=True)
def _harmonic_viscous(seg, r):
    """Viscous dissipation per cycle of the damped forced response without friction:
    ``2 pi r^2 sum_k sigma_k (P_k^2 + Q_k^2)`` (``r c_k = 2 r^2 sigma_k``, Eq. 4.2)."""
    acc = 0.0
    for k in range(seg.shape[1]):
        P, Q = particular(seg[OMEGA, k], seg[DAMP, k], seg[LOAD_COS, k])
        acc += seg[DAMP, k] * (P * P + Q * Q)
    return TWO_PI * r * r * acc


@njit(cache=True)
def _viscous_work(ctx, work, rec, taus, r, C):
    """``int r x'^T C x' dtau`` over ``[taus[0], taus[-1]]``: 4-point Gauss-Legendre on
    every interval between consecutive ``taus`` (events among them). In the sliding
    modes (proportional damping, docs/structures.md 4.1) ``r x'^T C x' =
    2 r^2 sum_k sigma_k eta_k'^2`` with ``eta' = phi^T Gamma x'`` for any velocity;
    general damping (``C`` not empty) takes ``r x'^T C x'`` itself."""
    seg = ctx[CTX_SEG_SLIP]
    phi_t_gamma = ctx[CTX_PHI_T_GAMMA]
    n = seg.shape[1]
    nq = _GL_NODES.shape[0]
    m = taus.shape[0] - 1
    nodes = np.empty(m * nq)
    for s in range(m):
        h = taus[s + 1] - taus[s]
        for g in range(nq):
            nodes[s * nq + g] = taus[s] + h * _GL_NODES[g]
    states = sample_states(ctx, work, rec, nodes)
    etad = np.empty(n)
    total = 0.0
    general = C.shape[0] == n
    for s in range(m):
        h = taus[s + 1] - taus[s]
        for g in range(nq):
            power = 0.0
            if general:
                for i in range(n):
                    for j in range(n):
                        power += C[i, j] * states[s * nq + g, n + i] * states[s * nq + g, n + j]
                power *= 0.5 / r  # so that 2 r^2 power = r x'^T C x'
            else:
                _matvec(phi_t_gamma, states[s * nq + g, n:].copy(), etad)
                for k in range(n):
                    power += seg[DAMP, k] * etad[k] * etad[k]
            total += h * _GL_WEIGHTS[g] * power
    return 2.0 * r * r * total


@njit(cache=True, nogil=True)
def orbit_designs(r, beta, scene, settings, out, final, samples):
    """:func:`orbit_design` for every converged point of :func:`run_points`' output.

    Returns ``(design, n_samples)``: ``design`` is ``(n_points, 2 n + 3)``, NaN
    where the point has no steady state (regime code < 0).
    """
    n = scene[0].shape[0]
    design = np.full((r.shape[0], 2 * n + DESIGN_SCALARS), np.nan)
    total = 0
    rec = np.zeros((0, REC_X + 2 * n))
    for i in range(r.shape[0]):
        total += point_design(
            r[i], beta[i], scene, settings, out[i], final[i], samples, design[i], rec, 0
        )
    return design, total


@njit(cache=True)
def point_design(r, beta, scene, settings, out, final, samples, dout, rec, nr):
    """:func:`orbit_design_recorded` of one point of :func:`run_points`' output (its
    ``out`` and ``final`` rows) if it converged; ``dout`` is left alone otherwise."""
    if out[OUT_REGIME] < 0.0 or out[OUT_CONVERGED] == 0.0:
        return 0
    period = max(1, int(out[OUT_PERIOD]))
    return orbit_design_recorded(r, beta, scene, settings, final, period, samples, dout, rec, nr)
