"""Agreement scores on hand-made regime maps with known disagreements (numbers by hand)."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from analysis.deviations import column_boundaries
from analysis.scoring import (
    REGIME_ORDER,
    agreement,
    agreement_points,
    agreement_trace,
    regime_from_bounds,
    score_dataset,
)
from tasks import regimes

C, S, N = regimes.CONTINUOUS, regimes.STICK_SLIP, regimes.NO_MOTION
NC, UB, NA = regimes.NOT_CONVERGED, regimes.UNBOUNDED, regimes.NOT_COMPUTED
INF = np.inf

# A 4 x 4 map (rows r, columns beta) against bc = 0.15, bm = 0.3 everywhere, which
# predicts C C S N in every row. Disagreements: (r=1, beta=0.1) and (r=2, beta=0.1)
# are stick-slip where continuous is predicted; (r=1.5, beta=0.1) did not converge;
# (r=2, beta=0.2) is continuous where stick-slip is predicted (non-monotone column);
# (r=2.5, beta=0.3) was not computed.
R = np.array([0.5, 1.0, 1.5, 2.0, 2.5])
BETA = np.array([0.0, 0.1, 0.2, 0.3])
MAP = np.array(
    [
        [C, C, S, N],
        [C, S, S, N],
        [C, NC, S, N],
        [C, S, C, N],
        [C, C, S, NA],
    ]
)
BC = np.full(5, 0.15)
BM = np.full(5, 0.3)


def test_regime_from_bounds_rule():
    beta = [0.1, 0.5, 0.7, 1.0, 0.3, 0.3, 5.0, 0.4]
    bc = [0.5, 0.5, 0.5, 0.5, 0.8, INF, INF, 0.2]
    bm = [1.0, 1.0, 1.0, 1.0, 0.3, 1.0, INF, 0.3]
    # below bc: C; at bc: S; between: S; at bm: N; crossed bounds: N wins;
    # bc = inf: C; bm = inf: never N; above bm: N
    assert regime_from_bounds(beta, bc, bm).tolist() == [C, S, S, N, N, C, C, N]
    assert regime_from_bounds(0.7, 0.5, 1.0).dtype == np.int8


def test_regime_from_bounds_nan_gives_no_prediction():
    got = regime_from_bounds(
        [np.nan, 0.1, 0.1, 2.0, 0.6],
        [0.5, np.nan, 0.5, np.nan, np.nan],
        [1.0, 1.0, np.nan, 1.0, 1.0],
    )
    # NaN beta; NaN bc deciding; NaN bm deciding; NaN bc irrelevant (N); NaN bc deciding
    assert got.tolist() == [NA, NA, NA, N, NA]


def test_confusion_matrix_and_accuracies():
    a = agreement(MAP, R, BETA, BC, BM, method="paper")
    assert REGIME_ORDER == (N, S, C)
    # rows = theory (N, S, C), columns = simulation (N, S, C)
    expected = np.array(
        [
            [4, 0, 0],  # predicted N at beta = 0.3: 4 computed, all N
            [0, 4, 1],  # predicted S at beta = 0.2: S S S C S
            [0, 2, 7],  # predicted C at beta 0, 0.1: 9 determined, 2 are S
        ]
    )
    np.testing.assert_array_equal(a.confusion, expected)
    assert a.count(predicted=C, simulated=S) == 2
    assert a.n_points == 20 and a.n_not_computed == 1 and a.n_scored == 18
    assert a.n_determined == 18 and a.n_undetermined == 1 and a.n_unpredicted == 0
    assert a.accuracy == pytest.approx(15 / 18)
    # per simulated regime: column sums N 4, S 6, C 8
    assert a.accuracy_by_simulated == pytest.approx({N: 1.0, S: 4 / 6, C: 7 / 8})
    # per predicted regime: row sums N 4, S 5, C 9
    assert a.accuracy_by_predicted == pytest.approx({N: 1.0, S: 4 / 5, C: 7 / 9})


def test_undetermined_points_are_listed_with_coordinates():
    regime = MAP.copy()
    regime[0, 0] = UB
    a = agreement(regime, R, BETA, BC, BM)
    assert a.undetermined_counts == {NC: 1, UB: 1}
    rows = sorted(a.undetermined.rows(), key=lambda d: d["index"])
    assert rows == [
        {"code": UB, "reason": "unbounded_growth", "index": (0, 0), "r": 0.5, "beta": 0.0},
        {"code": NC, "reason": "not_converged", "index": (2, 1), "r": 1.5, "beta": 0.1},
    ]
    assert a.undetermined.dims == ("r", "beta")
    assert a.n_scored == 17 and a.n_not_computed == 1


def test_column_boundaries_by_hand():
    nb = column_boundaries(MAP, R, BETA)
    np.testing.assert_allclose(
        nb.continuous_bracket,
        [[0.1, 0.2], [0.0, 0.1], [0.0, 0.2], [0.0, 0.1], [0.1, 0.2]],
    )
    # last column: beta = 0.3 not computed, so it moves at its top: open bracket
    np.testing.assert_allclose(
        nb.motion_bracket, [[0.2, 0.3], [0.2, 0.3], [0.2, 0.3], [0.2, 0.3], [0.2, INF]]
    )
    np.testing.assert_allclose(nb.continuous, [0.15, 0.05, 0.1, 0.05, 0.15])
    np.testing.assert_allclose(nb.motion, [0.25, 0.25, 0.25, 0.25, np.nan])
    assert nb.non_monotone.tolist() == [False, False, False, True, False]
    assert nb.n_skipped.tolist() == [0, 0, 1, 0, 1]
    # the unconverged point at beta = 0.1 sits inside the widened bracket (0, 0.2],
    # the not-computed one at beta = 0.3 inside the open bracket (0.2, inf)
    assert nb.skipped_in_bracket.tolist() == [
        [False, False],
        [False, False],
        [True, False],
        [False, False],
        [False, True],
    ]


def test_column_edge_cases():
    beta = np.array([0.3, 0.0, 0.2, 0.1])  # unsorted on purpose
    regime = np.array(
        [
            [C, C, C, C],  # all continuous, moving at the top
            [N, N, N, N],  # all stuck
            [NC, NC, NC, NC],  # nothing determined
            [S, S, S, S],  # no continuous bottom run, moving at top
            [C, C, N, C],  # continuous then stuck, no stick-slip (sorted: C C N C)
        ]
    )
    nb = column_boundaries(regime, np.arange(5.0), beta)
    cb, mb = nb.continuous_bracket, nb.motion_bracket
    np.testing.assert_array_equal(cb[0], [0.3, INF])
    np.testing.assert_array_equal(mb[0], [0.3, INF])
    np.testing.assert_array_equal(cb[1], [-INF, 0.0])
    np.testing.assert_array_equal(mb[1], [-INF, 0.0])
    assert np.isnan(cb[2]).all() and np.isnan(mb[2]).all()
    np.testing.assert_array_equal(cb[3], [-INF, 0.0])
    np.testing.assert_array_equal(mb[3], [0.3, INF])
    # sorted by beta: 0.0 C, 0.1 C, 0.2 N, 0.3 C -> bottom run ends at 0.1, last moving 0.3
    np.testing.assert_array_equal(cb[4], [0.1, 0.2])
    np.testing.assert_array_equal(mb[4], [0.3, INF])
    assert nb.non_monotone.tolist() == [False, False, False, False, True]
    assert np.isnan(nb.continuous[:4]).all() and nb.continuous[4] == pytest.approx(0.15)


def test_boundary_deviation_statistics():
    # closed forms chosen against the MAP brackets: continuous estimates 0.15 0.05 0.1 0.05 0.15
    bc = np.array([0.15, 0.10, 0.20, 0.05, INF])
    bm = np.array([0.20, 0.25, INF, 0.50, 1.0])
    a = agreement(MAP, R, BETA, bc, bm)
    dc, dm = a.deviations["continuous"], a.deviations["motion"]
    np.testing.assert_allclose(dc.deviation, [0.0, -0.05, -0.1, 0.0, np.nan], atol=1e-12)
    assert dc.n_compared == 4 and dc.n_columns == 5
    assert dc.max_abs == pytest.approx(0.1)
    assert dc.median_abs == pytest.approx(0.025)
    assert dc.max_rel == pytest.approx(0.5)  # 0.1 / 0.2 and 0.05 / 0.1
    assert dc.median_rel == pytest.approx(0.25)  # of 0, 0.5, 0.5, 0
    # closed form inside (lower, upper]: 0.15 in (0.1, 0.2]; 0.1 in (0, 0.1]; 0.2 in (0, 0.2];
    # 0.05 in (0, 0.1]; inf not in (0.1, 0.2]
    assert dc.n_consistent == 4
    # motion estimates 0.25 0.25 0.25 0.25 nan (open): deviations 0.05 0 nan -0.25 nan
    np.testing.assert_allclose(dm.deviation, [0.05, 0.0, np.nan, -0.25, np.nan], atol=1e-12)
    assert dm.n_compared == 3
    assert dm.max_abs == pytest.approx(0.25) and dm.median_abs == pytest.approx(0.05)
    assert dm.max_rel == pytest.approx(0.5) and dm.median_rel == pytest.approx(0.25)
    # 0.2 not in (0.2, 0.3]; 0.25 in; inf not in (0.2, 0.3]; 0.5 no; 1.0 in (0.2, inf)
    assert dm.n_consistent == 2


def test_points_agreement():
    r = [0.5, 1.0, 1.5, 2.0, 2.5, 3.0]
    beta = [0.1, 0.5, 0.9, 0.3, 0.7, 0.2]
    bc = [0.3, 0.3, 0.3, 0.3, 0.3, 0.3]
    bm = [0.8, 0.8, 0.8, 0.8, 0.8, 0.1]  # last: crossed bounds -> no motion
    regime = [C, S, N, C, UB, S]
    a = agreement_points(
        regime, r, beta, bc, bm, method="paper", coords={"gamma": [1, 1, 2, 2, 2, 3]}
    )
    # predicted C S N S (beta == bc) S N
    assert a.kind == "points" and a.n_points == 6 and a.n_scored == 5
    assert a.count(C, C) == 1 and a.count(S, S) == 1 and a.count(N, N) == 1
    assert a.count(S, C) == 1 and a.count(N, S) == 1
    assert a.accuracy == pytest.approx(3 / 5)
    assert a.undetermined.rows() == [
        {
            "code": UB,
            "reason": "unbounded_growth",
            "index": (4,),
            "r": 2.5,
            "beta": 0.7,
            "gamma": 2.0,
        }
    ]
    assert a.numerical is None and a.deviations == {}


def test_trace_agreement_uses_numerical_boundaries():
    a = agreement_trace(
        [0.5, 1.0, 2.0], [0.5, 0.8, INF], [1.0, 2.0, 3.0], [0.4, 1.0, 2.0], [1.0, INF, 2.0]
    )
    dc, dm = a.deviations["continuous"], a.deviations["motion"]
    np.testing.assert_allclose(dc.deviation, [0.1, -0.2, np.nan])
    assert dc.max_abs == pytest.approx(0.2) and dc.max_rel == pytest.approx(0.25)
    np.testing.assert_allclose(dm.deviation, [0.0, np.nan, 1.0])
    assert dm.median_abs == pytest.approx(0.5) and dm.n_consistent is None
    assert a.n_scored == 0 and np.isnan(a.accuracy)


def test_unknown_codes_are_rejected():
    with pytest.raises(ValueError, match="unknown"):
        agreement([[C, 7]], [1.0], [0.0, 0.1], [0.1], [1.0])


def _sweep_dataset(fill_as_nan: bool) -> xr.Dataset:
    """gamma sweep of two planes of MAP[:2] (second plane with one unconverged point)."""
    planes = np.stack([MAP[:2], MAP[:2]]).astype(float)
    planes[1, 0, 2] = NC
    planes[1, 1, 3] = np.nan if fill_as_nan else NA
    bc = np.array([[0.15, 0.15], [0.25, 0.25]])
    bm = np.array([[0.3, 0.3], [INF, INF]])
    ds = xr.Dataset(
        {
            "regime": (("gamma", "r", "beta"), planes if fill_as_nan else planes.astype("int8")),
            "beta_continuous_paper": (("gamma", "r"), bc),
            "beta_motion_paper": (("gamma", "r"), bm),
        },
        coords={"gamma": [0.5, 2.0], "r": R[:2], "beta": BETA},
        attrs={"mode": "grid"},
    )
    return ds


@pytest.mark.parametrize("fill_as_nan", [False, True])
def test_score_dataset_sweep_total_and_planes(fill_as_nan):
    scores = score_dataset(_sweep_dataset(fill_as_nan))
    assert list(scores) == ["paper"]  # no exact bounds in this dataset
    a = scores["paper"]
    (c0, p0), (c1, p1) = a.planes
    assert c0 == {"gamma": 0.5} and c1 == {"gamma": 2.0}
    # plane 0: rows C C S N / C S S N vs C C S N: 7 of 8
    assert (p0.n_correct, p0.n_scored) == (7, 8)
    # plane 1: bc 0.25, bm inf predicts C C C S; rows C C NC N / C S S NA
    # -> row 0: C C agree, N vs S wrong; row 1: C ok, S vs C wrong, S vs C wrong
    assert (p1.n_correct, p1.n_scored) == (3, 6)
    assert p1.n_not_computed == 1 and p1.n_undetermined == 1
    assert (a.n_correct, a.n_scored, a.n_not_computed) == (10, 14, 1)
    np.testing.assert_array_equal(a.confusion, p0.confusion + p1.confusion)
    assert a.undetermined.rows() == [
        {
            "code": NC,
            "reason": "not_converged",
            "index": (1, 0, 2),
            "gamma": 2.0,
            "r": 0.5,
            "beta": 0.2,
        }
    ]
    assert a.undetermined.dims == ("gamma", "r", "beta")
    # pooled columns: continuous brackets (0.1,0.2] (0,0.1] | (0.1,0.3] (0,0.1]
    np.testing.assert_allclose(
        a.deviations["continuous"].deviation, [0.0, -0.1, -0.05, -0.2], atol=1e-12
    )
    assert a.deviations["continuous"].n_consistent == 2
    assert a.numerical.non_monotone.tolist() == [False, False, False, False]
