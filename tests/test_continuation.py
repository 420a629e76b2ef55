"""Continuation along beta for an adaptive map's points next to a resonance
(tasks.kernel.batch._continuation).

The 6DOF ground contact on m5 (gamma = kappa = 1) at r = 0.709, the square root of
its second eigenvalue (0.503), continuous sliding: the held start needs about
2,000 periods; a warm start from the point one grid step away along r fails (the
orbit moves fast along r next to the resonance), from the point 16 grid steps
below along beta too (Newton's method over that distance), from the point 8 steps
below it settles in 2. An adaptive map's point list holding both points at that r
(the second seeded by the first) reaches the second by continuation along beta in
a few periods; the labels stay the held start's and the other fields agree to the
polish (docs/theory.md 3).
"""

from __future__ import annotations

import numpy as np

from tasks import Scene, classify, regimes
from tasks.classifier import classify_given
from tasks.kernel.batch import CONTINUATION_PERIODS, CONTINUATION_WORTH

SCENE = Scene("ground", 6, 5, gamma=1.0, kappa=1.0)
#: The grid of benchmarks/bench_adaptive.py's dof6_ground_m5 scene at 1000 x 500.
R_GRID, BETA_GRID = np.linspace(0.02, 3.0, 1000), np.linspace(0.0, 1.5, 500)


def test_a_slow_point_next_to_a_resonance_is_reached_along_beta():
    r = np.full(2, R_GRID[231])
    beta = BETA_GRID[[352, 368]]  # 16 grid steps apart along beta, the same r
    seeded, final = classify_given(SCENE, r, beta, None)
    cold = classify(SCENE, r, beta, warm=False)
    # the first point from the held start: slow (the continuation's gate)
    assert seeded.cycles[0] >= CONTINUATION_WORTH
    assert (seeded.regime == regimes.CONTINUOUS).all() and np.isfinite(final).all()
    # the second by continuation from the first: a few periods, not thousands
    failed_tries = 12 * 2  # at most a few periods per failed warm start
    assert seeded.cycles[1] <= failed_tries + CONTINUATION_PERIODS < seeded.cycles[0] / 10
    for name in ("regime", "stops_per_cycle", "converged", "period", "asymptotic"):
        np.testing.assert_array_equal(getattr(seeded, name), getattr(cold, name), err_msg=name)
    for name in ("slip_amplitude", "stick_fraction"):
        a, b = np.asarray(getattr(seeded, name)), np.asarray(getattr(cold, name))
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-6 * max(np.abs(b).max(), 1.0))


def test_a_dense_grid_does_not_continue():
    """Without the adaptive map's extra tries (``classify``: a grid's chain of neighbours
    one step apart) the same two points run the held start as before."""
    r = np.full(2, R_GRID[231])
    res = classify(SCENE, r, BETA_GRID[[352, 368]])
    assert (res.cycles >= CONTINUATION_WORTH).all()
