"""Steady states by Newton's method on the Poincare map (shooting).

Slow continuous transients (a Floquet multiplier near 1) are settled by
solving ``P(X) - X = 0`` for the section state ``X = (x, x')``: :func:`_shoot`
(the exact Jacobian of the recorded period, :mod:`tasks.kernel.monodromy`, at
every verified iterate; forward differences and Broyden updates where it cannot
be used) and, for points where that fails, :func:`newton_settle` (a fresh
difference Jacobian every step) from one or more
sections of the period (:func:`settle_at_phases`). A fixed point is accepted
only if its residual is small and it is not unstable: shooting must find the
attractor the point's own trajectory reaches, not any periodic orbit.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.kernel.acceptance import (
    STABLE_RADIUS,
    _near_fixed_point,
    radius_within,
)
from tasks.kernel.cycle import _advance, _cycle, _max_abs, replay_cycles
from tasks.kernel.layout import (
    BETA,
    CTX_B,
    CTX_BETA,
    CTX_F_R2,
    CTX_P,
    CTX_PHI,
    CTX_PHI_S,
    CTX_PHI_T_GAMMA,
    CTX_PROJ,
    CTX_SC,
    CTX_SEG_SLIP,
    CTX_SEG_STICK,
    CTX_T,
    CTX_W,
    ETAD_OFF,
    EV_END,
    EV_GRAZE,
    EV_REVERSAL,
    LEAF,
    N_STATS,
    REC_G,
    REC_KIND,
    REC_MODE,
    REC_TAU,
    REC_X,
    ST_DMAX,
    ST_DMIN,
    ST_FOREVER,
    ST_STATUS,
    STATUS_OK,
    TWO_PI,
)
from tasks.kernel.linsolve import _solve
from tasks.kernel.monodromy import exact_jacobian
from tasks.kernel.phases import _dot, _slip_state, _start_slip, _stick_state, start_stick_in
from tasks.kernel.propagation import evaluate
from tasks.kernel.starts import start_phase

# Rows of the event record a shooting period keeps (:func:`_period_recorded`); a
# period with more events differences its Jacobian columns over full periods.
REC_ROWS = 512
# How far (relative to its phase) a recorded event may move in a followed period:
# for a difference column (:func:`_fd_jacobian`) and for a Newton step on the
# followed map (:func:`_follow_newton`, verified by a full period after: a step
# whose events moved by up to half their phase is still a candidate; 0.1 ended
# the steps across the short phases next to a change of regime, where each then
# cost a full period).
FD_REACH = 1e-3
STEP_REACH = 0.5
# Newton's method on an event of a followed period (:func:`_follow_records`) has
# converged when its correction is below EVENT_RTOL of the time, or below EVENT_NOISE
# of it and no longer halving (rounding: the observable is known to about 1e-16 of
# the motion, and its slope at the event can be small, e.g. where a tiny slip stops).
EVENT_RTOL = 1e-15
EVENT_NOISE = 1e-13
# Newton steps on the followed map between two full periods of :func:`_shoot`.
FOLLOW_NEWTON = 12
# Halvings of a Newton step on the followed map that does not reduce the residual.
FOLLOW_HALVINGS = 3
# Sections a slow point's Newton settle tries (:func:`settle_at_phases`).
SETTLE_PHASES = 4
SETTLE_CYCLES = 150


@njit(cache=True)
def _broyden_update(J, dR, step):
    """Broyden's rank-one update of the Jacobian ``J`` (in place) after a step ``s`` that
    changed the residual by ``dR``: ``J += (dR - J s) s^T / (s . s)``."""
    ss = _dot(step, step)
    if ss > 0.0:
        dim = J.shape[0]
        u = dR.copy()
        for i in range(dim):
            for k in range(dim):
                u[i] -= J[i, k] * step[k]
        for i in range(dim):
            for k in range(dim):
                J[i, k] += u[i] * step[k] / ss


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


@njit(**LEAF)
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


@njit(**LEAF)
def _same_chart(mode_a, mode_b):
    return (mode_a == 0) == (mode_b == 0)


@njit(cache=True)
def _period_recorded(X, mode, stats, ctx, work, theta, rec, rec_n):
    """:func:`_cycle` from ``(X, mode)`` at ``tau = theta`` (stick start ``theta``),
    recording its events in ``rec`` (:func:`replay_cycles`; the same period bit for
    bit). Returns the new section state and phase."""
    n = X.shape[0] // 2
    X1 = X.copy()  # advanced in place through its two halves (views)
    rec_n[0] = 0
    m1, _ = replay_cycles(X1[:n], X1[n:], mode, theta, 1, stats, ctx, work, rec, rec_n)
    return X1, m1


@njit(**LEAF)
def _records_usable(rec, nr):
    """Whether a recorded period can carry nearby starts (:func:`_follow_records`):
    complete (it ends with its ``EV_END`` row) and without grazes (a touching zero
    that a nearby start may not reach)."""
    if nr < 2 or nr >= rec.shape[0] or rec[nr - 1, REC_KIND] != EV_END:
        return False
    for j in range(1, nr - 1):
        if rec[j, REC_KIND] == EV_GRAZE:
            return False
    return True


@njit(**LEAF)
def _follow_records(X, mode, rec, nr, ctx, work, theta, out, reach):
    """The period from a start near the recorded one, with the recorded event pattern.

    Each phase of the record (:func:`_period_recorded`) is started from the state
    reached so far and ended at the same kind of event, located by Newton's method
    on the phase's observable (contact velocity 0 while sliding, ``|g|`` at the
    unsticking limit while stuck) from the recorded time; the last phase ends at
    the section ``theta + 2 pi``. For nearby starts this is the Poincare map itself
    (the events move smoothly with the start) at the cost of a few evaluations per
    event instead of a bracket scan. Writes the end state into ``out``; returns
    False (``out`` undefined) where the pattern may not hold: a different starting
    phase (except a start past a reversal that the record has within ``reach`` of
    the section: the pattern is then followed from that reversal), an event time
    that Newton's method does not settle or that moves by more than ``reach`` times
    its phase (or beyond the section).
    """
    n = X.shape[0] // 2
    seg_slip = ctx[CTX_SEG_SLIP]
    seg_stick = ctx[CTX_SEG_STICK]
    sc = ctx[CTX_SC]
    beta = ctx[CTX_BETA]
    b = ctx[CTX_B]
    eta, etad, eta_s, etad_s, q, _ = work
    phase = _phase_of(X, mode, b)
    first = 0
    if phase != int(rec[0, REC_MODE]):
        # the recorded period reverses just after the section and this start has
        # already reversed (its contact velocity has the sign after the reversal,
        # e.g. a secant seed overshooting zero): the pattern from the reversal on
        if not (
            nr > 2
            and rec[1, REC_KIND] == EV_REVERSAL
            and phase == int(rec[1, REC_MODE])
            and rec[1, REC_TAU] - theta <= reach * max(rec[2, REC_TAU] - rec[1, REC_TAU], 1e-3)
        ):
            return False
        first = 1
    # the state is carried in ``out`` itself (views: nothing allocated)
    x = out[:n]
    xd = out[n:]
    for i in range(2 * n):
        out[i] = X[i]
    tau = theta
    tau_end = theta + TWO_PI
    v0 = _dot(b, xd)
    for j in range(first, nr - 1):
        stuck = phase == 0
        d0 = 0.0
        if stuck:
            seg = seg_stick
            ev = eta_s
            evd = etad_s
            d0 = start_stick_in(ctx, x, xd, tau, beta, q)
        else:
            seg = seg_slip
            ev = eta
            evd = etad
            _start_slip(
                seg, sc, x, xd, tau, float(phase), v0, beta, ctx[CTX_F_R2], ctx[CTX_PHI_T_GAMMA]
            )
        if j + 1 == nr - 1:  # the last phase ends at the section
            t = tau_end - tau
            if not t >= 0.0:
                return False
        else:
            t_rec = rec[j + 1, REC_TAU] - rec[j, REC_TAU]
            t = rec[j + 1, REC_TAU] - tau
            target = 0.0
            if stuck:
                target = sc[BETA] if rec[j + 1, REC_G] > 0.0 else -sc[BETA]
            settled = False
            dt_prev = np.inf
            for _ in range(12):
                y, dy = evaluate(seg, sc, t, ev, evd)
                if not (dy != 0.0 and math.isfinite(dy)):
                    return False
                dt = (target - y) / dy
                t += dt
                # converged, or at the rounding of the observable: a correction that
                # no longer halves is noise (a small slope, e.g. the stop of a tiny
                # slip, amplifies it far above 1e-15)
                if abs(dt) <= EVENT_RTOL * (1.0 + abs(t)) or (
                    abs(dt) <= EVENT_NOISE * (1.0 + abs(t)) and abs(dt) > 0.5 * dt_prev
                ):
                    settled = True
                    break
                dt_prev = abs(dt)
            if not settled or not (
                abs(t - (rec[j + 1, REC_TAU] - tau)) <= reach * max(t_rec, 1e-3)
            ):
                return False
            if not (t > 0.0 and tau + t < tau_end):
                return False
        evaluate(seg, sc, t, ev, evd)
        if stuck:
            _stick_state(
                ctx[CTX_PHI_S], ctx[CTX_T], ctx[CTX_W], d0, ev, evd, q, x, xd, seg[ETAD_OFF]
            )
        else:
            _slip_state(ctx[CTX_PHI], ev, evd, x, xd, seg[ETAD_OFF])
        tau += t
        phase = int(rec[j + 1, REC_MODE])
        v0 = 0.0
    return True


@njit(cache=True)
def _fd_jacobian(y0, y1, mode, ctx, work, scale, J, theta, rec, nr):
    """``J = dP/dy - I`` by forward differences.

    With a usable record of the period from ``y0`` (``nr`` rows,
    :func:`_records_usable`), each column follows the recorded event pattern
    (:func:`_follow_records`, a few evaluations per event), differenced against
    the recorded start followed the same way; a column that cannot follow it
    costs one full period (:func:`_cycle`), differenced against ``y1``.

    Returns the full periods used, or -1 if a perturbed period left the chart.
    """
    n = ctx[CTX_P].shape[0]
    b = ctx[CTX_B]
    w = ctx[CTX_W]
    T = ctx[CTX_T]
    proj = ctx[CTX_PROJ]
    dim = y0.shape[0]
    probe = np.empty(N_STATS)
    Pk = np.empty(2 * n)
    y1f = y1
    follow = _records_usable(rec, nr)
    if follow:
        X0 = _expand(y0, mode, n, w, T)
        follow = _follow_records(X0, mode, rec, nr, ctx, work, theta, Pk, FD_REACH)
        if follow:
            y1f = _reduce(Pk, mode, b, w, proj)
    used = 0
    for k in range(dim):
        hk = 1e-7 * max(abs(y0[k]), 1e-3 * scale)
        yp = y0.copy()
        yp[k] += hk
        Xp = _expand(yp, mode, n, w, T)
        if follow and _follow_records(Xp, mode, rec, nr, ctx, work, theta, Pk, FD_REACH):
            yk = _reduce(Pk, mode, b, w, proj)
            base = y1f
        else:
            Pk, mk, _ = _cycle(Xp, _phase_of(Xp, mode, b), theta, probe, ctx, work, theta)
            used += 1
            if not _same_chart(mk, mode) or probe[ST_STATUS] != STATUS_OK:
                return -1
            yk = _reduce(Pk, mode, b, w, proj)
            base = y1
        for i in range(dim):
            J[i, k] = (yk[i] - base[i]) / hk
        J[k, k] -= 1.0
    return used


@njit(cache=True)
def _probe(y0, scale):
    """The steps of :func:`_fd_jacobian`'s columns at ``y0``, then ``FD_REACH``: how far
    :func:`tasks.kernel.monodromy.exact_jacobian` checks that the events follow."""
    dim = y0.shape[0]
    probe = np.empty(dim + 1)
    for k in range(dim):
        probe[k] = 1e-7 * max(abs(y0[k]), 1e-3 * scale)
    probe[dim] = FD_REACH
    return probe


@njit(cache=True)
def _exact(y0, mode, rec, nr, ctx, work, J, scale):
    """:func:`tasks.kernel.monodromy.exact_jacobian` on a usable record (``J`` left as
    it was where it returns False); ``scale``: the motion, as for :func:`_probe`."""
    if not _records_usable(rec, nr):
        return False
    return exact_jacobian(y0, mode, rec, nr, ctx, work, J, _probe(y0, max(scale, 1e-300)))


@njit(cache=True)
def _jacobian(y0, y1, mode, ctx, work, scale, J, theta, rec, nr):
    """``J = dP/dy - I``: exact along a usable record of the period from ``y0``
    (:func:`tasks.kernel.monodromy.exact_jacobian`, no period), else by forward
    differences (:func:`_fd_jacobian`). Returns the full periods used, or -1 as
    :func:`_fd_jacobian`."""
    if _exact(y0, mode, rec, nr, ctx, work, J, scale):
        return 0
    return _fd_jacobian(y0, y1, mode, ctx, work, scale, J, theta, rec, nr)


@njit(cache=True)
def _follow_newton(y0, R0, J, mode, rec, nr, ctx, work, theta, target, scale):
    """Newton's method with Broyden updates of ``J`` on the followed Poincare map.

    The map is the current period's event pattern followed from nearby starts
    (:func:`_follow_records`, events moving by up to ``STEP_REACH`` of their
    phase): no bracket scan, so a step costs a few evaluations per event. At most
    ``FOLLOW_NEWTON`` steps, each of which must reduce the residual (else it is
    halved, up to ``FOLLOW_HALVINGS`` times, as long as it follows the pattern),
    until it is below ``target``. The result is only a candidate: :func:`_shoot` verifies it on
    a full period (a new event would change the map there, and the residual).
    Returns ``(y, moved)``; ``J`` is updated in place.
    """
    n = ctx[CTX_P].shape[0]
    b = ctx[CTX_B]
    w = ctx[CTX_W]
    T = ctx[CTX_T]
    proj = ctx[CTX_PROJ]
    yf = y0.copy()
    Rf = R0.copy()
    res_f = _max_abs(Rf)
    Pf = np.empty(2 * n)
    moved = False
    for _ in range(FOLLOW_NEWTON):
        step = _solve(J, -Rf)  # (NaN where J is singular)
        if not np.all(np.isfinite(step)) or _max_abs(step) > 10.0 * scale:
            break
        # a step that does not reduce the residual is halved (a damped Newton step
        # on the followed map, FOLLOW_HALVINGS times at most); one that leaves the
        # recorded pattern ends the steps (the full period decides there)
        lam = 1.0
        reduced = False
        for _ls in range(FOLLOW_HALVINGS + 1):
            yn = yf + lam * step
            if not _follow_records(
                _expand(yn, mode, n, w, T), mode, rec, nr, ctx, work, theta, Pf, STEP_REACH
            ):
                break
            Rn = _reduce(Pf, mode, b, w, proj) - yn
            rn = _max_abs(Rn)
            if rn < res_f:
                reduced = True
                break
            lam *= 0.5
        if not reduced:
            break
        _broyden_update(J, Rn - Rf, yn - yf)
        yf = yn
        Rf = Rn
        res_f = rn
        moved = True
        if res_f <= target:
            break
    return yf, moved


@njit(cache=True)
def _shoot(X0, mode, stats, ctx, work, rtol, floor, max_newton, theta, keep, kept, give_up):
    """Newton's method on the Poincare map ``P(X) - X = 0`` (shooting).

    Works in the coordinates of the phase the section falls in
    (:func:`_reduce`); the section must fall in the same kind of phase (stuck
    or sliding) before and after the period. The Jacobian is exact along the
    recorded period of each verified iterate (:func:`_jacobian`,
    :mod:`tasks.kernel.monodromy`), or built by forward differences where the
    record cannot carry it, and updated by Broyden's rank-one formula between
    full periods. A fixed point is accepted only
    if its residual is below ``rtol`` of the motion (or of ``floor``, the static
    response) and it is not unstable (spectral radius of ``dP/dy`` at most
    1 + 1e-6): shooting must find the attractor, not any periodic orbit.

    With ``give_up`` (a warm start, which the held start backs up) the shot
    ends at the first full period that does not reduce the residual (no halved
    steps, no rebuilt Jacobian after a failed step), so a start that is not
    converging costs one or two periods instead of up to a dozen.

    Returns ``(success, X, cycles_used)``; on success ``stats`` holds the
    statistics of the verified period ``X -> P(X)`` and its recorded events are
    copied into ``keep`` (``kept[0]`` rows, if they fit; else ``kept`` is left).
    """
    n = X0.shape[0] // 2
    b = ctx[CTX_B]
    w = ctx[CTX_W]
    T = ctx[CTX_T]
    proj = ctx[CTX_PROJ]
    cycles = 0
    y0 = _reduce(X0, mode, b, w, proj)
    X0 = _expand(y0, mode, n, w, T)
    # the events of the current iterate's period (rec) and of a trial step (rec_t)
    rec = np.empty((REC_ROWS, REC_X + 2 * n))
    rec_t = np.empty((REC_ROWS, REC_X + 2 * n))
    rec_n = np.zeros(1, dtype=np.int64)
    rec_tn = np.zeros(1, dtype=np.int64)
    X1, m1 = _period_recorded(X0, _phase_of(X0, mode, b), stats, ctx, work, theta, rec, rec_n)
    cycles += 1
    if not _same_chart(m1, mode) or stats[ST_STATUS] != STATUS_OK or stats[ST_FOREVER] > 0.0:
        return False, X0, cycles
    y1 = _reduce(X1, mode, b, w, proj)
    dim = y0.shape[0]
    J = np.empty((dim, dim))
    scale = max(_max_abs(X1), 1e-300)
    used = _jacobian(y0, y1, mode, ctx, work, scale, J, theta, rec, rec_n[0])
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
        amp = 0.5 * (stats[ST_DMAX] - stats[ST_DMIN])
        tol = rtol * max(scale, floor)
        if res <= tol and _near_fixed_point(J, R, tol, ctx, mode, amp, rtol):
            dP = J.copy()
            for i in range(dim):
                dP[i, i] += 1.0
            stable = radius_within(dP, STABLE_RADIUS)
            nr = rec_n[0]
            if stable and nr < rec.shape[0] and nr <= keep.shape[0]:
                keep[:nr] = rec[:nr]  # the verified period's events, for the orbit check
                kept[0] = nr
            return stable, X0, cycles
        if _records_usable(rec, rec_n[0]):
            # Newton on the followed map (no bracket scans), then one full period
            # from its candidate: the new iterate if it reduced the residual
            target = 0.01 * rtol * max(scale, floor)
            yf, moved = _follow_newton(
                y0, R, J, mode, rec, rec_n[0], ctx, work, theta, target, scale
            )
            if not moved and not fresh:
                # the updated Jacobian no longer reduces the residual of the
                # followed map: rebuild it here from followed columns (cheap)
                # before a step on full periods
                used = _jacobian(y0, y1, mode, ctx, work, scale, J, theta, rec, rec_n[0])
                if used < 0:
                    return False, X0, cycles + dim
                cycles += used
                if not np.all(np.isfinite(J)):
                    return False, X0, cycles
                fresh = True
                yf, moved = _follow_newton(
                    y0, R, J, mode, rec, rec_n[0], ctx, work, theta, target, scale
                )
            if moved:
                Xn = _expand(yf, mode, n, w, T)
                X1n, mn = _period_recorded(
                    Xn, _phase_of(Xn, mode, b), stats, ctx, work, theta, rec_t, rec_tn
                )
                cycles += 1
                ok = _same_chart(mn, mode) and stats[ST_STATUS] == STATUS_OK
                if ok and stats[ST_FOREVER] == 0.0:
                    y1n = _reduce(X1n, mode, b, w, proj)
                    if _max_abs(y1n - yf) < res:
                        y0 = yf
                        y1 = y1n
                        X0 = Xn
                        X1 = X1n
                        rec, rec_t = rec_t, rec
                        rec_n, rec_tn = rec_tn, rec_n
                        # the exact Jacobian at the new iterate replaces the
                        # Broyden-updated one (no period: monodromy.py)
                        fresh = _exact(y0, mode, rec, rec_n[0], ctx, work, J, _max_abs(X1))
                        continue
                if give_up:  # the full period did not confirm the step
                    return False, X0, cycles
        step = _solve(J, -R)  # (NaN where J is singular: no isolated fixed point)
        # trust region: a fixed point far beyond the current motion is not a
        # settled transient but a (near-)singular map, e.g. resonant growth
        if not np.all(np.isfinite(step)) or _max_abs(step) > 10.0 * scale:
            return False, X0, cycles
        lam = 1.0
        accepted = False
        for _ls in range(5):
            yn = y0 + lam * step
            Xn = _expand(yn, mode, n, w, T)
            X1n, mn = _period_recorded(
                Xn, _phase_of(Xn, mode, b), stats, ctx, work, theta, rec_t, rec_tn
            )
            cycles += 1
            if _same_chart(mn, mode) and stats[ST_STATUS] == STATUS_OK and stats[ST_FOREVER] == 0.0:
                y1n = _reduce(X1n, mode, b, w, proj)
                Rn = y1n - yn
                if _max_abs(Rn) < res:
                    _broyden_update(J, Rn - R, yn - y0)
                    y0 = yn
                    y1 = y1n
                    X0 = Xn
                    X1 = X1n
                    rec, rec_t = rec_t, rec
                    rec_n, rec_tn = rec_tn, rec_n
                    accepted = True
                    fresh = _exact(y0, mode, rec, rec_n[0], ctx, work, J, _max_abs(X1))
                    break
            if give_up:  # no halved steps in a warm start
                break
            lam *= 0.5
        if not accepted:
            if fresh or give_up:
                return False, X0, cycles
            # the updated Jacobian went stale: rebuild it once here
            used = _jacobian(y0, y1, mode, ctx, work, scale, J, theta, rec, rec_n[0])
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
    point's own trajectory. Costs ``dim + 1`` periods per step. Its Jacobians stay
    forward differences (:func:`_fd_jacobian`): a difference column that cannot
    follow the period ends the settle early, where the exact Jacobian would let
    Newton's method wander on a map cut by events (a long creep then ran out of
    its work budget instead of settling as no motion).

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
    rec = np.empty((REC_ROWS, REC_X + 2 * n))
    rec_n = np.zeros(1, dtype=np.int64)
    for _ in range(max_iter):
        X = _expand(y, mode, n, w, T)
        P, m1 = _period_recorded(X, _phase_of(X, mode, b), stats, ctx, work, theta, rec, rec_n)
        cycles += 1
        if stats[ST_STATUS] != STATUS_OK or stats[ST_FOREVER] > 0.0:
            return False, X, cycles
        y1 = _reduce(P, mode, b, w, proj)
        R = y1 - y
        scale = max(_max_abs(P), 1e-300)
        # (a period that left the chart has no usable record in it)
        nr = rec_n[0] if _same_chart(m1, mode) else 0
        used = _fd_jacobian(y, y1, mode, ctx, work, scale, J, theta, rec, nr)
        if used < 0 or not np.all(np.isfinite(J)):
            return False, X, cycles + dim
        cycles += used
        tol = rtol * max(scale, floor)
        amp = 0.5 * (stats[ST_DMAX] - stats[ST_DMIN])
        if (
            _max_abs(R) <= tol
            and _same_chart(m1, mode)
            and _near_fixed_point(J, R, tol, ctx, mode, amp, rtol)
        ):
            dP = J.copy()
            for i in range(dim):
                dP[i, i] += 1.0
            if not radius_within(dP, STABLE_RADIUS):
                return False, X, cycles
            _cycle(X, _phase_of(X, mode, b), theta, stats, ctx, work, theta)
            return True, X, cycles + 1
        step = _solve(J, -R)  # (NaN where J is singular: no isolated fixed point)
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
