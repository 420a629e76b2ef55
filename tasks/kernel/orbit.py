"""The orbit invariant: a converged period re-checked densely, independently of the event search.

Through each stick phase ``|g| <= beta`` and through each slip phase the
contact velocity keeps its sign, sampled in closed form between the recorded
events: a missed unsticking or reversal shows as a violation, and the point is
flagged (never reported).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from tasks.kernel.context import _context, motion_floor
from tasks.kernel.cycle import _max_abs, replay_cycles
from tasks.kernel.layout import (
    BETA,
    CTX_B,
    CTX_BETA,
    CTX_F_R2,
    CTX_H_SLIP,
    CTX_H_STICK,
    CTX_PHI_T_GAMMA,
    CTX_SC,
    CTX_SEG_SLIP,
    CTX_SEG_STICK,
    CTX_TOL,
    EV_END,
    EV_SECTION,
    EVALS,
    KIND,
    KIND_STICK,
    LEAF,
    N_STATS,
    OUT_CONVERGED,
    OUT_CYCLES,
    OUT_IC,
    OUT_PERIOD,
    OUT_REGIME,
    REC_KIND,
    REC_MODE,
    REC_TAU,
    REC_X,
    SIGN,
    ST_STATUS,
    STATUS_OK,
    WORK_CAP,
)
from tasks.kernel.outcome import _undetermined
from tasks.kernel.phases import _dot, _start_slip, start_stick_in
from tasks.kernel.propagation import derivative_bounds, observable_range
from tasks.regimes import NO_MOTION, NOT_CONVERGED, NUMERICAL_FAILURE, WORK_LIMIT

# Orbit invariant (:func:`orbit_holds`): stated tolerance of ``|g| <= beta`` in
# stick phases, relative to beta, and samples per shortest modal half-period.
ORBIT_RTOL = 1e-9
ORBIT_SAMPLES = 8.0
ORBIT_MAX_SAMPLES = 4096.0
# The replayed period must close (:func:`closes`): its end state within this many
# times ``section_rtol`` of the motion (or of :func:`motion_floor`) of its start.
# Every accepted orbit closes to ``section_rtol`` by its own acceptance test; the
# margin covers the plain iteration's reference, which can include the first
# cycles' motion.
CLOSE_MARGIN = 10.0


@njit(**LEAF)
def _phase_holds(seg, sc, t_len, h, tol, eta, etad, scratch):
    """The invariant through one phase of length ``t_len`` (start already set in ``seg, sc``).

    Samples the observable at spacing at most ``h / ORBIT_SAMPLES`` (at most
    ``ORBIT_MAX_SAMPLES`` per phase) strictly inside the phase. Stuck:
    ``|g| <= beta (1 + ORBIT_RTOL) + tol max|g'|`` (the second term is what an
    event located to ``tol`` can leave). Sliding: the contact velocity keeps the
    phase's sign, ``s v >= -1e-9 max|v|``. Returns 1 (holds), 0 (violated) or -1
    (the work budget ran out first). ``eta, etad`` are scratch arrays of the
    phase's modes, ``scratch`` too (:func:`observable_range`).
    """
    m = seg.shape[1]
    n_samples = int(min(max(2.0, ORBIT_SAMPLES * t_len / h), ORBIT_MAX_SAMPLES))
    if sc[EVALS] + n_samples * (1.0 + m) > sc[WORK_CAP]:
        return -1
    dt = t_len / (n_samples + 1)
    ymin, ymax, finite = observable_range(seg, sc, dt, n_samples, eta, etad, scratch)
    if sc[KIND] == KIND_STICK:
        slope, _ = derivative_bounds(seg, sc, t_len)
        limit = sc[BETA] * (1.0 + ORBIT_RTOL) + tol * slope
        if not (finite and max(abs(ymin), abs(ymax)) <= limit):
            return 0
        sc[EVALS] += n_samples * (1.0 + m)
        return 1
    # sliding: the contact velocity s y keeps the sign s (NaN samples left out)
    s = sc[SIGN]
    vmax = max(abs(ymin), abs(ymax)) if ymin <= ymax else 0.0
    vmin = min(0.0, s * ymin if s > 0.0 else s * ymax) if ymin <= ymax else 0.0
    sc[EVALS] += n_samples * (1.0 + m)
    return 1 if vmin >= -1e-9 * vmax else 0


@njit(cache=True)
def record_orbit(X, mode, theta, period, ctx, work):
    """Replay ``period`` cycles from ``(X, mode)`` at ``tau = theta`` recording every event.

    Returns ``(rec, n_records, status)``: the records (:func:`replay_cycles`, the
    buffer grown until they fit) and the status of the replay (``n_records`` is 0
    unless ``STATUS_OK``).
    """
    n = X.shape[0] // 2
    rows = 64
    stats = np.zeros(N_STATS)
    while True:
        rec = np.zeros((rows, REC_X + 2 * n))
        rec_n = np.zeros(1, dtype=np.int64)
        x = X[:n].copy()
        xd = X[n:].copy()
        replay_cycles(x, xd, mode, theta, period, stats, ctx, work, rec, rec_n)
        if stats[ST_STATUS] != STATUS_OK:
            return rec, 0, stats[ST_STATUS]
        if rec_n[0] < rows:
            return rec, rec_n[0], stats[ST_STATUS]
        rows *= 4


@njit(cache=True)
def orbit_holds(X, mode, theta, period, ctx, work):
    """Orbit invariant: the converged period from the section state is a solution.

    Re-simulates ``period`` cycles from ``(X, mode)`` at ``tau = theta`` with
    every event recorded (:func:`record_orbit`), then checks every phase densely
    in closed form (:func:`records_hold`). Costs about one period more per point.
    Returns 1 (holds), 0 (violated) or -1 (the work budget ran out first).
    """
    rec, nr, status = record_orbit(X, mode, theta, period, ctx, work)
    if status != STATUS_OK:
        return -1 if status == WORK_LIMIT else 0
    return records_hold(rec, nr, ctx, work)


@njit(cache=True)
def records_hold(rec, nr, ctx, work):
    """The orbit invariant on ``nr`` recorded phase boundaries (:func:`record_orbit`).

    Checks every phase densely in closed form (:func:`_phase_holds`): through
    each stick phase ``|g| <= beta`` (to ``ORBIT_RTOL``), through each slip
    phase the contact velocity keeps its sign. Independent of the event search
    it checks: a missed unsticking or reversal shows as a violation. Returns 1
    (holds), 0 (violated) or -1 (the work budget ran out first).
    """
    n = (rec.shape[1] - REC_X) // 2
    beta = ctx[CTX_BETA]
    h_slip = ctx[CTX_H_SLIP]
    h_stick = ctx[CTX_H_STICK]
    tol = ctx[CTX_TOL]
    sc = ctx[CTX_SC]
    eta, etad, eta_s, etad_s, q, stack = work
    x = np.empty(n)
    xd = np.empty(n)
    for j in range(nr - 1):
        t_len = rec[j + 1, REC_TAU] - rec[j, REC_TAU]
        if not t_len > 0.0:
            continue
        tau0 = rec[j, REC_TAU]
        for i in range(n):
            x[i] = rec[j, REC_X + i]
            xd[i] = rec[j, REC_X + n + i]
        phase = int(rec[j, REC_MODE])
        if phase == 0:
            seg = ctx[CTX_SEG_STICK]
            start_stick_in(ctx, x, xd, tau0, beta, q)
            ok = _phase_holds(seg, sc, t_len, h_stick, tol, eta_s, etad_s, stack)
        else:
            seg = ctx[CTX_SEG_SLIP]
            # the contact velocity at a section start; 0 at an event, as in run_cycle
            v0 = _dot(ctx[CTX_B], xd) if rec[j, REC_KIND] == EV_SECTION else 0.0
            _start_slip(
                seg, sc, x, xd, tau0, float(phase), v0, beta, ctx[CTX_F_R2], ctx[CTX_PHI_T_GAMMA]
            )
            ok = _phase_holds(seg, sc, t_len, h_slip, tol, eta, etad, stack)
        if ok != 1:
            return ok
    return 1


@njit(cache=True)
def _check_orbit(r, beta, scene, settings, out, final, keep, kept):
    """Flag a converged point whose orbit fails :func:`orbit_holds` (never report it).

    The point becomes ``NUMERICAL_FAILURE`` (an event the search could not
    locate), ``WORK_LIMIT`` if the check ran out of budget (it has a budget
    of its own, ``max_work``), or ``NOT_CONVERGED`` if the replayed period does
    not close (:func:`closes`: the section state is a transient). No-motion
    points are certified by :func:`never_unsticks` and continuous points at
    beta = 0 are linear: neither is re-checked.

    ``keep`` may hold ``kept`` rows: the records of a period-1 orbit's verified
    period (:func:`tasks.kernel.shooting._shoot`); when they start from exactly
    the state, phase and section of ``final``, they are the replay (the same
    events, bit for bit) and are checked without replaying it again.

    Returns ``(rec, n_records)``: the checked orbit's records (:func:`record_orbit`,
    reused by the design pass), ``n_records`` 0 where nothing was checked or the
    check failed.
    """
    n = (final.shape[0] - 2) // 2
    if out[OUT_CONVERGED] != 1.0 or out[OUT_REGIME] == NO_MOTION or beta == 0.0:
        return np.zeros((0, REC_X + 2 * n)), 0
    ctx, work, X_start, _, _ = _context(r, beta, scene, settings)
    X = final[: 2 * n].copy()
    mode = int(final[2 * n])
    theta = final[2 * n + 1]
    period = int(out[OUT_PERIOD])
    same = period == 1 and kept > 1 and keep[kept - 1, REC_KIND] == EV_END
    same = same and keep[0, REC_TAU] == theta and int(keep[0, REC_MODE]) == mode
    for i in range(2 * n):
        same = same and keep[0, REC_X + i] == X[i]
    if same:
        rec = keep[:kept].copy()
        nr = kept
        status = STATUS_OK
    else:
        rec, nr, status = record_orbit(X, mode, theta, period, ctx, work)
    if status != STATUS_OK:
        holds = -1 if status == WORK_LIMIT else 0
    else:
        holds = records_hold(rec, nr, ctx, work)
    if holds == 0:
        _undetermined(out, NUMERICAL_FAILURE, out[OUT_CYCLES], out[OUT_IC])
    elif holds < 0:
        _undetermined(out, WORK_LIMIT, out[OUT_CYCLES], out[OUT_IC])
    elif not closes(rec, nr, X, settings[2], motion_floor(ctx, X_start)):
        # a transient still creeping is not a steady state: never reported
        _undetermined(out, NOT_CONVERGED, out[OUT_CYCLES], out[OUT_IC])
        holds = 0
    return rec, nr if holds == 1 else 0


@njit(cache=True)
def closes(rec, nr, X, rtol, floor):
    """Whether a replayed orbit (``nr`` records from the section state ``X``) is periodic.

    The state at its end (the ``EV_END`` row, one or two periods on) must equal
    ``X`` to ``CLOSE_MARGIN * rtol`` of the larger of the motion and ``floor``
    (:func:`tasks.kernel.context.motion_floor`): ``P(X) = X`` on the Poincare
    section, docs/simulator.md 5. Independent of how the orbit was accepted (plain
    iteration, shooting, a warm start, the polish), it refuses an orbit whose
    section state is a transient.
    """
    n = X.shape[0] // 2
    if nr < 2 or rec[nr - 1, REC_KIND] != EV_END:
        return False
    end = rec[nr - 1, REC_X : REC_X + 2 * n]
    diff = 0.0
    for i in range(2 * n):
        diff = max(diff, abs(end[i] - X[i]))
    scale = max(_max_abs(X), _max_abs(end), floor)
    return diff <= CLOSE_MARGIN * rtol * scale
