"""Which seed a point of an adaptive map tries first (tasks.kernel.batch._warm_tries).

Fig. 4's scene (2DOF, ground contact on m_1, gamma = kappa = 1). A point between
two solved points on a line is seeded first by the interpolation of their orbits
(error of order h^2, where the copied orbit's is of order h); a point whose
nearest solved neighbour lies across a change of regime is seeded by another
candidate before the held start. The labels stay the held start's, the fields
agree with it to the polish: a seed only seeds (docs/theory.md 3).
"""

from __future__ import annotations

import numpy as np

from tasks import Scene, classify, regimes
from tasks.classifier import classify_given, scene_modes_cached, settings_args
from tasks.fidelity import resolve
from tasks.kernel.secant import secant_seed

SCENE = Scene("ground", 2, 1, gamma=1.0, kappa=1.0)
#: The 1000 x 500 grid of the adaptive Fig. 4 benchmark (benchmarks/bench_adaptive.py).
R_GRID, BETA_GRID = np.linspace(0.02, 2.5, 1000), np.linspace(0.0, 1.5, 500)


def _agree(seeded, cold):
    """Labels equal to the held start's, the other fields to the polish."""
    for name in ("regime", "stops_per_cycle", "converged", "period"):
        np.testing.assert_array_equal(getattr(seeded, name), getattr(cold, name), err_msg=name)
    for name in ("slip_amplitude", "stick_fraction"):
        a, b = np.asarray(getattr(seeded, name)), np.asarray(getattr(cold, name))
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-6 * max(np.abs(b).max(), 1.0))


def test_midpoint_prediction_is_the_mean_of_the_two_orbits():
    args = scene_modes_cached(SCENE).kernel_args()
    settings = settings_args(resolve("balanced"))
    r, beta = np.full(3, 0.9), np.array([0.5, 0.55, 0.6])  # j, i, k along beta
    solved, final = classify_given(SCENE, r[[0, 2]], beta[[0, 2]], None)
    assert np.isfinite(final).all() and (solved.regime == regimes.STICK_SLIP).all()
    n = args[0].shape[0]
    given = np.column_stack([final, r[[0, 2]], beta[[0, 2]]])
    seeds = np.array([[-1, -1], [-2, -3], [-1, -1]], dtype=np.int64)
    pred = np.empty(2 * n + 2)
    point = (r, beta, 1, 0, seeds, np.zeros(3, dtype=bool), np.zeros((3, 2 * n + 2)), given)
    assert secant_seed(*point, args, settings, pred, True)
    if final[0, 2 * n + 1] == final[1, 2 * n + 1]:  # the same section: the plain mean
        np.testing.assert_allclose(pred[: 2 * n], final[:, : 2 * n].mean(axis=0), rtol=1e-12)
    np.testing.assert_array_equal(pred[2 * n :], final[0, 2 * n :])  # j's phase and section
    # no interpolation without a point on each side
    one = (r, beta, 1, 0, seeds[:, :1], np.zeros(3, dtype=bool), np.zeros((3, 2 * n + 2)))
    assert not secant_seed(*one, given[:1], args, settings, pred, True)


def test_interpolated_seeds_settle_the_midpoints_in_fewer_periods():
    """Every other point of a beta segment solved; each midpoint seeded by both ends
    (interpolation first) costs fewer periods than seeded by one end (its copied orbit):
    24 against 30 periods for 12 points here (34 before the followed map settled events
    at rounding and followed steps across short phases, tasks.kernel.shooting; the old
    order, copy first, 30)."""
    r, beta = np.full(33, 0.9), np.linspace(0.3, 1.2, 33)
    ends, final = classify_given(SCENE, r[::2], beta[::2], None)
    orbit = np.isfinite(final).all(axis=1)
    mids = [m for m in range(1, 33, 2) if orbit[m // 2] and orbit[m // 2 + 1]]
    assert len(mids) >= 10
    both, one = [], []
    for m in mids:
        k = [m // 2, m // 2 + 1]
        g2 = (r[[m - 1, m + 1]], beta[[m - 1, m + 1]], final[k])
        g1 = (r[[m - 1]], beta[[m - 1]], final[k[:1]])
        both.append(classify_given(SCENE, r[[m]], beta[[m]], g2)[0])
        one.append(classify_given(SCENE, r[[m]], beta[[m]], g1)[0])
    cold = classify(SCENE, r[mids], beta[mids], warm=False)
    for res in (both, one):
        merged = type(cold)(
            **{
                name: np.concatenate([np.atleast_1d(getattr(x, name)) for x in res])
                if getattr(res[0], name) is not None
                else None
                for name in cold.__dataclass_fields__
            }
        )
        _agree(merged, cold)
    c_both = sum(int(x.cycles[0]) for x in both)
    c_one = sum(int(x.cycles[0]) for x in one)
    assert c_both < 0.85 * c_one, (c_both, c_one)


def test_a_point_across_a_regime_change_is_seeded_from_its_own_side():
    """A continuous point next to the stick-slip region (Fig. 4, r = 0.6158, beta =
    0.785): its nearest solved neighbour (one r step on, stick-slip) does not
    settle it, the farther continuous one does, in 4 periods where the held start
    needs 23 (the old order went from the failed copy to the held start: 27)."""
    i, j = 240, 261
    near_r, near_b = R_GRID[[241, 239]], BETA_GRID[[261, 263]]
    solved, final = classify_given(SCENE, near_r, near_b, None)
    assert list(solved.regime) == [regimes.STICK_SLIP, regimes.CONTINUOUS]
    p_r, p_b = R_GRID[[i]], BETA_GRID[[j]]
    cold = classify(SCENE, p_r, p_b, warm=False)
    nearest = classify_given(SCENE, p_r, p_b, (near_r[:1], near_b[:1], final[:1]))[0]
    assert nearest.cycles[0] >= cold.cycles[0]  # the stick-slip orbit alone: no warm start
    both = classify_given(SCENE, p_r, p_b, (near_r, near_b, final))[0]
    _agree(both, cold)
    assert both.regime[0] == regimes.CONTINUOUS
    assert both.cycles[0] <= 6 and cold.cycles[0] >= 20
