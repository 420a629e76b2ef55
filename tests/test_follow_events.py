"""The followed Poincare map (:func:`tasks.kernel.shooting._follow_records`) next to the
no-motion boundary, where the slips are tiny.

There the contact velocity stops with a small slope (about 1e-2 on Fig. 4 (1, 1) at
beta = 0.998, just below the motion bound beta = 1), so Newton's method on the stop
time ends at a rounding noise of about 1e-14 in tau, above the 1e-15 the followed map
once demanded: every followed period failed, and each Newton step of a warm start
or polish there cost a full period (bench: the stick-slip points next to no motion
cost 4-5 periods instead of 2). The truth the followed map is checked against is the
simulated map itself (:func:`_period_recorded`, events by the bracketing search).
"""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from tasks import Scene
from tasks.classifier import classify_given, scene_modes_cached, settings_args, start_codes
from tasks.fidelity import resolve
from tasks.kernel.context import _context
from tasks.kernel.layout import (
    CTX_B,
    CTX_PROJ,
    CTX_T,
    CTX_W,
    EV_REVERSAL,
    EV_SECTION,
    N_STATS,
    REC_KIND,
    REC_TAU,
    REC_X,
)
from tasks.kernel.shooting import (
    REC_ROWS,
    STEP_REACH,
    _expand,
    _follow_records,
    _period_recorded,
    _phase_of,
    _records_usable,
    _reduce,
)
from tasks.regimes import STICK_SLIP


@njit(cache=False)
def _followed_and_simulated(r, beta, scene, settings, row, rel):
    """From the section state ``row`` moved by ``rel`` of the motion along every
    coordinate: the recorded period of ``row`` followed from there, and the simulated
    period from there (both as section states), and whether the follow succeeded."""
    n = scene[0].shape[0]
    ctx, work, _, _, _ = _context(r, beta, scene, settings)
    b, w, T, proj = ctx[CTX_B], ctx[CTX_W], ctx[CTX_T], ctx[CTX_PROJ]
    mode = int(row[2 * n])
    theta = row[2 * n + 1]
    y0 = _reduce(row[: 2 * n].copy(), mode, b, w, proj)
    X0 = _expand(y0, mode, n, w, T)
    stats = np.zeros(N_STATS)
    rec = np.empty((REC_ROWS, REC_X + 2 * n))
    rec_n = np.zeros(1, dtype=np.int64)
    _period_recorded(X0, _phase_of(X0, mode, b), stats, ctx, work, theta, rec, rec_n)
    usable = _records_usable(rec, rec_n[0])
    scale = np.max(np.abs(X0))
    Xp = X0.copy()
    for k in range(2 * n):
        Xp[k] += rel * scale * (1.0 if k % 2 == 0 else -1.0)
    yp = _reduce(Xp, mode, b, w, proj)
    Xp = _expand(yp, mode, n, w, T)
    followed = np.empty(2 * n)
    ok = _follow_records(Xp, mode, rec, rec_n[0], ctx, work, theta, followed, STEP_REACH)
    rec2 = np.empty((REC_ROWS, REC_X + 2 * n))
    rec2_n = np.zeros(1, dtype=np.int64)
    simulated, _ = _period_recorded(
        Xp, _phase_of(Xp, mode, b), stats, ctx, work, theta, rec2, rec2_n
    )
    return usable, ok, followed, simulated, rec_n[0], rec2_n[0]


@pytest.mark.parametrize("beta", [0.998, 0.995])
@pytest.mark.parametrize("rel", [0.0, 1e-6])
def test_followed_period_of_a_tiny_slip_equals_the_simulated_one(beta, rel):
    scene = Scene("ground", 2, 1, gamma=1.0, kappa=1.0)
    r = np.array([0.7796, 0.7796])
    betas = np.array([beta - 0.003, beta])  # the first seeds the second (a warm start)
    res, final = classify_given(scene, r, betas, None)
    assert res.regime[1] == STICK_SLIP
    assert res.slip_amplitude[1] < 1e-3  # tiny slips next to the motion bound (beta = 1)
    resolved = resolve("balanced")
    settings = settings_args(resolved, start_codes(resolved)[0])
    args = scene_modes_cached(scene).kernel_args()
    usable, ok, followed, simulated, nr, nr2 = _followed_and_simulated(
        r[1], betas[1], args, settings, final[1], rel
    )
    assert usable and nr == nr2  # the same events in the same order
    assert ok, "the followed period failed where the simulated one has the same events"
    scale = np.max(np.abs(simulated))
    assert np.max(np.abs(followed - simulated)) <= 1e-10 * scale


@njit(cache=False)
def _followed_past_a_reversal(r, beta, scene, settings, row, rel_velocity):
    """The section state ``row`` (sliding) with its contact velocity turned to
    ``-rel_velocity`` times itself reverses just after the section; its recorded
    period is followed from ``row`` itself (already past that reversal) and compared
    with the simulated period from ``row``. Returns the first two recorded event
    kinds, the reversal's time after the section, whether the follow succeeded, and
    the followed and simulated end states."""
    n = scene[0].shape[0]
    ctx, work, _, _, _ = _context(r, beta, scene, settings)
    b = ctx[CTX_B]
    mode = int(row[2 * n])
    theta = row[2 * n + 1]
    X0 = row[: 2 * n].copy()
    v = 0.0
    bb = 0.0
    for i in range(n):
        v += b[i] * X0[n + i]
        bb += b[i] * b[i]
    Xm = X0.copy()
    for i in range(n):
        Xm[n + i] -= (1.0 + rel_velocity) * v * b[i] / bb
    stats = np.zeros(N_STATS)
    rec = np.empty((REC_ROWS, REC_X + 2 * n))
    rec_n = np.zeros(1, dtype=np.int64)
    _period_recorded(Xm, _phase_of(Xm, mode, b), stats, ctx, work, theta, rec, rec_n)
    followed = np.empty(2 * n)
    ok = _follow_records(X0, mode, rec, rec_n[0], ctx, work, theta, followed, STEP_REACH)
    rec2 = np.empty((REC_ROWS, REC_X + 2 * n))
    rec2_n = np.zeros(1, dtype=np.int64)
    simulated, _ = _period_recorded(
        X0, _phase_of(X0, mode, b), stats, ctx, work, theta, rec2, rec2_n
    )
    return rec[0, REC_KIND], rec[1, REC_KIND], rec[1, REC_TAU] - theta, ok, followed, simulated


def test_a_start_past_a_reversal_after_the_section_follows_the_rest_of_the_pattern():
    # a secant seed next to the motion bound overshoots the small contact velocity at
    # the section: its period reverses at once, the next iterate no longer does, and
    # the followed map once refused it (another starting phase), so every such step
    # cost a full period
    scene = Scene("ground", 2, 1, gamma=1.0, kappa=1.0)
    r = np.array([0.7796, 0.7796])
    betas = np.array([0.995, 0.998])
    res, final = classify_given(scene, r, betas, None)
    assert res.regime[1] == STICK_SLIP
    n = 2
    assert final[1, 2 * n] != 0  # the section falls in a slip phase
    resolved = resolve("balanced")
    settings = settings_args(resolved, start_codes(resolved)[0])
    args = scene_modes_cached(scene).kernel_args()
    k0, k1, t_rev, ok, followed, simulated = _followed_past_a_reversal(
        r[1], betas[1], args, settings, final[1], 1e-3
    )
    assert k0 == EV_SECTION and k1 == EV_REVERSAL and 0.0 < t_rev < 1e-3
    assert ok, "the pattern after the reversal was not followed"
    assert np.max(np.abs(followed - simulated)) <= 1e-10 * np.max(np.abs(simulated))
