"""Classification of one (r, beta) point: the steady-state search (of many points in
order, seeded by their solved neighbours: :mod:`tasks.kernel.batch`).

Steady state is detected on the Poincare section ``tau = theta + 2 pi n`` (the
excitation has period 2 pi): the section state ``X = (x, x')`` repeating to a
relative tolerance (period 1 or 2). Slow continuous transients are settled by
Newton's method on the Poincare map (:mod:`tasks.kernel.shooting`). A stick
phase that provably never ends (:func:`tasks.kernel.events.never_unsticks`) is
the no-motion steady state; slips below the creep threshold are no motion
(:mod:`tasks.kernel.creep`). Every converged orbit is re-checked by the orbit
invariant (:mod:`tasks.kernel.orbit`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.kernel.acceptance import contact_within
from tasks.kernel.context import _context, motion_floor
from tasks.kernel.creep import _asymptotic_no_motion, _creep_limit, creep_settled, creep_threshold
from tasks.kernel.cycle import _advance, _cycle, _max_abs, _max_abs_diff
from tasks.kernel.damping import is_damped, linear_amplitude_damped
from tasks.kernel.layout import (
    CTX_BETA,
    CTX_F_R2,
    CTX_G_LOAD,
    CTX_K,
    CTX_P,
    CTX_PHI_S,
    CTX_SEG_SLIP,
    CTX_SEG_STICK,
    CTX_T,
    DAMP,
    DELTA,
    LOAD_COS,
    N_STATS,
    OMEGA,
    OUT_AMP,
    OUT_ASYMPTOTIC,
    OUT_CONVERGED,
    OUT_CYCLES,
    OUT_IC,
    OUT_PERIOD,
    OUT_REGIME,
    OUT_STICK,
    OUT_STOPS,
    ST_DMAX,
    ST_DMIN,
    ST_EVENTS,
    ST_FOREVER,
    ST_LONGEST,
    ST_MID,
    ST_REVERSALS,
    ST_STATUS,
    ST_STOPS,
    ST_STUCK_TIME,
    STATUS_OK,
    TWO_PI,
)
from tasks.kernel.linsolve import _solve
from tasks.kernel.outcome import _finish, _no_motion_by_margin, _undetermined
from tasks.kernel.shooting import (
    SETTLE_PHASES,
    _same_chart,
    _shoot,
    settle_at_phases,
)
from tasks.kernel.starts import _held_response, held_margin, start_phase
from tasks.regimes import (
    CONTINUOUS,
    CREEP_SLIP_RTOL,
    CREEP_WINDOW,
    IC_HELD,
    NOT_CONVERGED,
    SLIP_RTOL,
    STICK_SLIP,
    UNBOUNDED,
)

# held_margin must exceed this fraction of beta to decide no motion (rounding of g_h).
HELD_MARGIN_RTOL = 1e-9
# Newton steps a warm start may take before the point falls back to the held start.
WARM_NEWTON = 6
# The polish of a converged period-1 orbit (:func:`polish_point`): residual of the
# Poincare map sought, relative to the motion (far below ``section_rtol``: the fixed
# point then no longer depends on where the search started), and Newton steps. The
# map is known only as well as its events are located (``event_tol`` in tau), so the
# residual sought is never below ``event_tol`` (the fast preset's 1e-9).
POLISH_RTOL = 1e-12
POLISH_NEWTON = 4


@njit(cache=True)
def _polish_rtol(settings):
    """Residual a polished fixed point reaches: ``POLISH_RTOL``, or ``event_tol`` if larger."""
    return max(POLISH_RTOL, settings[0])


# One early shot (before shooting_after) once this many cycles (and min_cycles)
# have run and the event pattern (chart, stops, reversals) has repeated this many
# times in a row.
EARLY_SHOT = 3
EARLY_PATTERN = 2


@njit(cache=True)
def _linear_amplitude(seg_slip):
    """Amplitude of ``b . x`` on the forced response of the sliding system without
    friction: ``|b . (K - M)^-1 p|`` (inf at a resonance; damped: tasks.kernel.damping)."""
    if is_damped(seg_slip):
        return linear_amplitude_damped(seg_slip)
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
    rate of growth can be too slow to see in simulation. A damped mode never
    grows without bound (docs/structures.md 4.6).
    """
    for k in range(seg_slip.shape[1]):
        w = seg_slip[OMEGA, k]
        a = seg_slip[LOAD_COS, k]
        if abs(w * w - 1.0) <= 1e-12 and a != 0.0 and seg_slip[DAMP, k] == 0.0:
            if 4.0 * beta * abs(f_r2[k]) < math.pi * abs(a):
                return True
    return False


@njit(cache=True)
def simulate_point(r, beta, scene, settings, out, final, keep, kept):
    """Classify one (r, beta) point; writes the fields into ``out`` and the last
    section state and phase ``(x, x', mode)`` into ``final``. A point settled by
    shooting leaves its verified period's records in ``keep`` (``kept[0]`` rows,
    else 0: :func:`tasks.kernel.shooting._shoot`)."""
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
        _warm,
    ) = settings
    ctx, work, X, mode, ic_used = _context(r, beta, scene, settings)
    out[OUT_ASYMPTOTIC] = 0.0
    kept[0] = 0
    slip_tol = creep_threshold(ctx, beta, r)
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
        seg, phi_s, T = ctx[CTX_SEG_STICK], ctx[CTX_PHI_S], ctx[CTX_T]
        X_held, _ = _held_response(seg, phi_s, T, n, ctx[CTX_P], ctx[CTX_K], ctx[CTX_G_LOAD])
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
    # scale of the motion: the load's response at the excitation frequency, or more
    ref = motion_floor(ctx, X)
    stick_start = 0.0
    cycles = 0
    next_shot = shooting_after
    shots_failed = 0
    unit_ratio_run = 0
    run_start_scale = 0.0
    chart_flips = 0
    moves = 0
    pattern_run = 0
    early_tried = False
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
            # ... at the contact too, whose motion can be far smaller (shooting.py)
            amp = 0.5 * (stats[ST_DMAX] - stats[ST_DMIN])
            moved = (X - X_prev) / (1.0 - min(rho, 0.999))
            settled = err <= section_rtol * max(scale, ref)
            settled = settled and contact_within(ctx, moved, 1, amp, section_rtol)  # (full X)
            if settled or diff <= 1e-13 * scale:
                final[: 2 * n] = X_prev
                final[2 * n] = mode_prev
                _finish(out, stats, stats_prev, 1, cycles, ic_used)
                _creep_limit(out, slip_tol)
                return
        chart_flips = chart_flips + 1 if not _same_chart(mode, mode_prev) else 0
        if cycles >= min_cycles + 1 and _same_chart(mode, mode_prev2):
            diff2 = _max_abs_diff(X, X_prev2)
            tol2 = section_rtol * max(scale, ref)
            amp = 0.5 * (stats[ST_DMAX] - stats[ST_DMIN])
            if (
                diff2 <= tol2
                and diff > 10.0 * tol2
                and contact_within(ctx, X - X_prev2, 1, amp, section_rtol)
            ):
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
        if (
            _same_chart(mode, mode_prev)
            and stats[ST_STOPS] == stats_prev[ST_STOPS]
            and stats[ST_REVERSALS] == stats_prev[ST_REVERSALS]
        ):
            pattern_run += 1
        else:
            pattern_run = 0
        for i in range(N_STATS):
            stats_prev[i] = stats[i]
        diff_prev = diff
        # one early shot once the event pattern has repeated (cheap: the Jacobian
        # and the Newton steps follow the recorded events, shooting.py), from the
        # current section
        early = (
            shooting
            and not early_tried
            and cycles >= max(EARLY_SHOT, min_cycles)
            and pattern_run >= EARLY_PATTERN
            and cycles < next_shot
        )
        early_tried = early_tried or early
        shoot_now = shooting and (cycles >= next_shot or early)
        # (an early shot keeps the section: a failed one leaves the iteration as it was)
        if ((shoot_now and not early) or chart_flips >= 2) and moves < 8:
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
            if not early:
                next_shot = 2 * next_shot
            ok, Xs, used = _shoot(
                X, mode, stats, ctx, work, section_rtol, ref, 20, theta, keep, kept, False
            )
            cycles += used
            if ok:
                final[: 2 * n] = Xs
                final[2 * n] = start_phase(Xs, ctx[CTX_BETA], ctx, theta) if mode != 0 else 0
                final[2 * n + 1] = theta
                _finish(out, stats, stats_prev, 1, cycles, ic_used)
                _creep_limit(out, slip_tol)
                return
            if early:  # a failed early shot changes nothing of the schedule
                continue
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


# The floor of a polished residual (:func:`_polish_floor`): the static response, at
# most this many times the motion floor.
POLISH_FLOOR_CAP = 100.0


@njit(cache=True)
def _polish_floor(ctx, X_held):
    """Floor of the residual a warm start or the polish seeks (``POLISH_RTOL``).

    That target lies at the rounding of the Poincare map (its events are located to
    ``event_tol``, its phases carry the static deflections of the load and the
    friction), so it is measured against the larger of
    :func:`tasks.kernel.context.motion_floor` and the static response ``K^-1 p``,
    the latter capped at ``POLISH_FLOOR_CAP`` times the motion floor (far above a
    soft mode it is orders of magnitude above the motion). Against the motion floor
    alone, a warm start on a continuous SDOF point (Fig. 3, r = 1.28, motion 0.56)
    stopped at a residual of 1.03e-12 for a target of 6.1e-13 and fell back to the
    held start (2.1 -> 2.6 periods per continuous point on the panel). A fixed point
    accepted here still closes to ``section_rtol`` of the motion, or the orbit check
    refuses it (:func:`tasks.kernel.orbit.closes`) and the point runs from the held
    start.
    """
    floor = motion_floor(ctx, X_held)
    static = _max_abs(_solve(ctx[CTX_K], ctx[CTX_P]))
    return max(floor, min(static, POLISH_FLOOR_CAP * floor))


@njit(cache=True)
def warm_point(r, beta, scene, settings, out, final, seed, keep, kept):
    """Steady state of a point by shooting from a neighbour's converged orbit (a warm start).

    ``seed`` is the neighbour's row of :func:`tasks.kernel.batch.run_points`' ``final`` (section
    state, phase, section phase theta). Newton's method on this point's
    Poincare map at the same section (:func:`tasks.kernel.shooting._shoot`, at
    most ``WARM_NEWTON`` steps, given up at the first full period that does not
    reduce the residual) starts from the seed and must reach a residual
    of ``POLISH_RTOL`` of the motion (or ``event_tol``: :func:`_polish_rtol`; the
    polish of :func:`polish_point`, so the fixed point does not depend on the
    seed), not unstable; its period's
    statistics give the fields (:func:`_finish`) and the creep rule applies
    (:func:`_creep_limit`). Only a moving orbit is accepted (one that the creep
    rule calls no motion is left to the held start, which decides how no motion
    is reached). Tried only where the held start of :func:`simulate_point`
    would iterate: held start, beta > 0, strictly below the motion bound
    (:func:`held_margin` below ``-HELD_MARGIN_RTOL beta``: at or above it the
    held start is proved stuck for ever in its first cycle), no resonant growth.

    Why the label is the held start's (docs/theory.md 3, "One regime per
    point"): the energy of the difference of two motions of a point never
    increases, and stays constant only while both stick and both slide (the
    same way) at the same times. So the held start's trajectory, whatever its
    transient, ends with the stick and slip intervals of any periodic orbit of
    the point: the regime, stops and stick fraction of the orbit found here.

    Returns ``(accepted, cycles)``; when not accepted, ``out`` and ``final``
    are left to :func:`simulate_point`. ``keep``, ``kept``: as for
    :func:`simulate_point`.
    """
    shooting = settings[5]
    ctx, work, X_held, _, ic_used = _context(r, beta, scene, settings)
    if beta == 0.0 or ic_used != IC_HELD or not shooting:
        return False, 0
    if held_margin(ctx) >= -HELD_MARGIN_RTOL * beta:
        # at or above the motion bound the held start is proved stuck for ever
        # in its first cycle; on the bound, orbits with slips below the creep
        # threshold coexist with it (docs/theory.md 3): the held start decides
        return False, 0
    if _resonant_growth(ctx[CTX_SEG_SLIP], ctx[CTX_F_R2], beta):
        return False, 0
    n = X_held.shape[0] // 2
    X0 = seed[: 2 * n].copy()
    mode0 = int(seed[2 * n])
    theta = seed[2 * n + 1]
    stats = np.zeros(N_STATS)
    kept[0] = 0
    ok, Xs, used = _shoot(
        X0,
        mode0,
        stats,
        ctx,
        work,
        _polish_rtol(settings),
        _polish_floor(ctx, X_held),
        WARM_NEWTON,
        theta,
        keep,
        kept,
        True,  # a failed warm start gives up early: the held start backs it up
    )
    if not ok:
        return False, used
    out[OUT_ASYMPTOTIC] = 0.0
    _finish(out, stats, stats, 1, used, ic_used)
    _creep_limit(out, creep_threshold(ctx, beta, r))
    if not _seeds_next(out):  # no motion by the creep rule: the held start decides
        kept[0] = 0
        return False, used
    final[: 2 * n] = Xs
    final[2 * n] = start_phase(Xs, ctx[CTX_BETA], ctx, theta) if mode0 != 0 else 0
    final[2 * n + 1] = theta
    return True, used


@njit(cache=True)
def polish_point(r, beta, scene, settings, out, final, keep, kept):
    """Polish a converged period-1 motion to the fixed point of its Poincare map.

    The search stops once the section repeats to ``section_rtol`` (1e-8 in
    ``balanced``): the fixed point is that close, and where exactly depends on
    where the search started. Newton's method from the converged section
    (:func:`tasks.kernel.shooting._shoot`, at most ``POLISH_NEWTON`` steps, the
    Jacobian and steps on the followed map, each step verified on a full
    period) brings the residual to ``POLISH_RTOL`` of the motion (or to
    ``event_tol``, to which the map itself is known: :func:`_polish_rtol`), so that the
    fields of the orbit agree whatever seeded the search (to about
    ``POLISH_RTOL`` over one minus the slowest Floquet multiplier). The fields
    are then those of the polished period (:func:`_finish`, creep rule) and
    its records are left in ``keep`` for the orbit check. Where the polish
    does not settle (the chart changes in a step, the Jacobian is singular),
    the point keeps its converged result. Returns the periods used.
    """
    ctx, work, X_held, _, _ = _context(r, beta, scene, settings)
    n = X_held.shape[0] // 2
    mode = int(final[2 * n])
    theta = final[2 * n + 1]
    stats = np.zeros(N_STATS)
    ok, Xs, used = _shoot(
        final[: 2 * n].copy(),
        mode,
        stats,
        ctx,
        work,
        _polish_rtol(settings),
        _polish_floor(ctx, X_held),
        POLISH_NEWTON,
        theta,
        keep,
        kept,
        False,
    )
    cycles = out[OUT_CYCLES] + used
    out[OUT_CYCLES] = cycles
    if not ok:
        return used
    final[: 2 * n] = Xs
    final[2 * n] = start_phase(Xs, ctx[CTX_BETA], ctx, theta) if mode != 0 else 0
    _finish(out, stats, stats, 1, cycles, out[OUT_IC])
    _creep_limit(out, creep_threshold(ctx, beta, r))
    return used


@njit(cache=True)
def _seeds_next(out):
    """Whether a point's orbit can seed its neighbour: a verified period-1 motion."""
    return (
        out[OUT_CONVERGED] == 1.0
        and out[OUT_PERIOD] == 1.0
        and out[OUT_ASYMPTOTIC] == 0.0
        and (out[OUT_REGIME] == STICK_SLIP or out[OUT_REGIME] == CONTINUOUS)
    )
