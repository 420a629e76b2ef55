"""Secant seeds (tasks.kernel.secant): where a warm start from a neighbour's copied orbit
fails, the orbit extrapolated from two solved points on a line settles the point.

Fig. 4 (2DOF, ground contact on m_1, gamma = 1, kappa = 0.5) at r = 0.7072, next
to the resonance of the held system (its frequency sqrt(1/2) relative to the
chain's, Eq. 7): a Floquet multiplier of the stick-slip orbit is 0.999, the held
start needs about 2000 periods (its shots fail until the last-resort settle), and
the fixed point moves so fast with beta that the neighbour's orbit is too far
for Newton's method. The labels must be the held start's (docs/theory.md 3,
"One regime per point") and the fields its, to the polish.
"""

from __future__ import annotations

import numpy as np

from tasks import Scene, classify, kernel
from tasks.classifier import scene_modes_cached, settings_args
from tasks.fidelity import resolve
from tasks.kernel.layout import N_OUT, OUT_REGIME, OUT_STICK, OUT_STOPS, REC_X
from tasks.kernel.secant import _along, secant_seed
from tasks.kernel.shooting import REC_ROWS
from tasks.regimes import IC_HELD, STICK_SLIP
from tasks.seeds import warm_seeds

SCENE = Scene("ground", 2, 1, gamma=1.0, kappa=0.5)
#: a column of the bench_warm 250 x 100 panel (r index 69, beta indices 46-53)
R_SLOW = np.linspace(0.02, 2.5, 250)[69]
BETA_SLOW = np.linspace(0.0, 1.5, 100)[46:54]


def test_along_extrapolates_beyond_j_and_interpolates_between_j_and_k():
    p = {"i": (1.0, 0.3), "j": (1.0, 0.2), "k": (1.0, 0.1), "off": (1.1, 0.1), "far": (1.0, 0.6)}

    def along(i, j, k):
        return _along(*p[i], *p[j], *p[k])

    assert abs(along("i", "j", "k") - 1.0) < 1e-12  # extrapolation: X_j + (X_j - X_k)
    assert abs(along("j", "i", "k") + 0.5) < 1e-12  # midpoint: (X_i + X_k) / 2
    assert along("i", "j", "off") == 0.0  # not on one line
    assert along("far", "i", "j") == 0.0  # too far beyond j (t = 3)
    assert along("k", "i", "j") == 0.0  # beyond k on the other side (t = -2)
    assert along("i", "j", "j") == 0.0  # j and k the same point


def test_secant_seed_settles_where_the_copied_seed_fails():
    args = scene_modes_cached(SCENE).kernel_args()
    settings = settings_args(resolve("balanced"), IC_HELD)
    r = np.full(3, R_SLOW)
    beta = BETA_SLOW[2:5].copy()  # k, j, i along beta
    seeds = warm_seeds(r, beta, float(args[5][-1]))
    cold = classify(SCENE, r, beta, warm=False, design=False)
    assert np.all(cold.regime == STICK_SLIP)
    assert cold.cycles[2] > 1000  # a slow point: the held start's shots fail
    # k and j solved (warm, as in a call), then i from j's copied orbit: fails
    out, final, _ = kernel.run_points_seeded(r[:2], beta[:2], args, settings, 0, seeds[:2])
    assert np.all(out[:, OUT_REGIME] == STICK_SLIP)
    n = args[0].shape[0]
    keep = np.empty((REC_ROWS, REC_X + 2 * n))
    kept = np.zeros(1, dtype=np.int64)
    out_i, final_i = np.empty(N_OUT), np.empty(2 * n + 2)
    seed = final[1]
    ok, used = kernel.warm_point(r[2], beta[2], args, settings, out_i, final_i, seed, keep, kept)
    assert not ok and used > 0
    # the secant prediction X_j + (X_j - X_k) settles it in a few periods
    all_final = np.vstack([final, np.zeros((1, 2 * n + 2))])
    pred = np.empty(2 * n + 2)
    seedable = np.array([True, True, False])
    given = np.zeros((0, 2 * n + 4))
    assert secant_seed(
        r, beta, 2, 0, seeds, seedable, all_final, given, args, settings, pred, False
    )
    np.testing.assert_array_equal(pred[2 * n :], final[1, 2 * n :])  # j's phase and section
    assert np.max(np.abs(pred[: 2 * n] - final[1, : 2 * n])) > 0.0
    ok, used = kernel.warm_point(r[2], beta[2], args, settings, out_i, final_i, pred, keep, kept)
    assert ok and used <= 6
    assert out_i[OUT_REGIME] == cold.regime[2]
    assert out_i[OUT_STOPS] == cold.stops_per_cycle[2]
    assert abs(out_i[OUT_STICK] - cold.stick_fraction[2]) < 1e-6


def test_slow_column_warm_equals_cold_in_far_fewer_periods():
    r = np.full(BETA_SLOW.size, R_SLOW)
    cold = classify(SCENE, r, BETA_SLOW, warm=False, design=False)
    warm = classify(SCENE, r, BETA_SLOW, design=False)
    np.testing.assert_array_equal(warm.regime, cold.regime)
    np.testing.assert_array_equal(warm.stops_per_cycle, cold.stops_per_cycle)
    np.testing.assert_array_equal(warm.converged, cold.converged)
    np.testing.assert_allclose(warm.stick_fraction, cold.stick_fraction, rtol=0, atol=1e-6)
    np.testing.assert_allclose(warm.slip_amplitude, cold.slip_amplitude, rtol=1e-5)
    assert cold.cycles.sum() > 5000
    # the first two points from the held start (no line yet), the rest by secant seeds
    assert warm.cycles[2:].sum() < 0.02 * cold.cycles[2:].sum()
