"""The closed-form prediction keeps cells open (tasks.adaptive.Refinement, ``predicted``).

A uniform cell whose four corners the prediction gives their own label is not
settled while it gives a point of the cell another label: the cell is halved
towards that point down to one step (a strip asks for that middle), so a feature
narrower than the cells that the closed forms hold (the tip of a peak of the
motion bound at a held resonance) gets a simulated point. The prediction never
decides a label.

* a peak of the no-motion boundary one grid step wide at its tip, between coarse
  nodes: the hint alone misses the tip where the cells around it are of
  ``HINT_CELL`` steps (``coarse_step`` 4) or where a cut at the hint leaves it
  inside one; with the prediction every label is right, for a few points more;
* the same map in any order of arrival as the wave refinement, with an exact and
  with a wrong prediction, and with tiles installed as without;
* a prediction wrong over a region or of a feature that is not there costs points,
  never labels;
* the vectorised decisions (tasks.cells) against the per-cell methods.

The random audit's map that the hint alone got wrong: tests/test_adaptive_peak_audit.py.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_adaptive import (
    N_B,
    N_R,
    assert_boundaries_simulated,
    map_with_features,
    shuffled_stream,
    synthetic,
    truth,
    waves,
)
from test_adaptive_tiles import _refined
from test_adaptive_wall import _arrive, _tiles

from analysis.adaptive import curve_hint
from tasks import cells, regimes
from tasks.adaptive import Refinement, coarse_nodes, refine
from tasks.stream import StreamRefinement


def _peak(k: int):
    """Stick-slip below a motion bound with a peak at column ``k`` (one column wide above
    48 steps, as at a held resonance), continuous below a low line, no motion above."""

    def bound(i):
        return 30.0 + 90.0 / (1.0 + 4.0 * (i - k) ** 2)

    def label(i, j):
        out = np.where(j >= bound(i), regimes.NO_MOTION, regimes.STICK_SLIP)
        return np.where(j < 10 + 0.05 * i, regimes.CONTINUOUS, out)

    i = np.arange(N_R)
    axis = np.arange(N_B, dtype=float)
    hint = curve_hint(axis, bound(i)) | curve_hint(axis, 10 + 0.05 * i)
    return label, hint


def _quiet(step, batch, hint, predicted=None):
    return refine(
        (N_R, N_B), batch, step, hint, verify_min=0, verify_fraction=0, predicted=predicted
    )


@pytest.mark.parametrize("step", [4, 16])
def test_a_peak_one_step_wide_at_its_tip_is_found_through_the_prediction(step):
    missed = 0
    for k in range(100, 120):
        label, hint = _peak(k)
        want = truth(label)
        plain = _quiet(step, synthetic(label), hint)
        guided = _quiet(step, synthetic(label), hint, want)  # the closed forms, exact
        lost = int((plain.fields["regime"] != want).sum())
        missed += lost > 0
        np.testing.assert_array_equal(guided.fields["regime"], want, err_msg=str(k))
        assert_boundaries_simulated(guided.fields["simulated"], want)
        # a few points more where the hint alone was right; the tip's sides where it was not
        extra = 2 * lost + 20 if lost else 0.02 * plain.simulated_points
        assert guided.simulated_points <= plain.simulated_points + extra, (k, lost)
    assert missed  # the hint alone loses the tip (72 points) in some positions


def _island(i, j):
    """An island of 5 x 5 steps between coarse nodes (missed without a hint)."""
    i0 = int(coarse_nodes(N_R, 16)[3]) + 5
    inside = (i >= i0) & (i <= i0 + 4) & (j >= 37) & (j <= 41)
    return np.where(inside, regimes.NO_MOTION, regimes.CONTINUOUS)


def _dots(i, j):
    """Single points of stick-slip on strip edges and in cells, beside a boundary."""
    lab = np.where(j < 0.4 * i + 7, regimes.CONTINUOUS, regimes.NO_MOTION)
    dots = ((i % 23 == 5) & (j % 19 == 3)) | ((i == 100) & (j == 47))
    return np.where(dots, regimes.STICK_SLIP, lab)


@pytest.mark.parametrize(
    ("label", "step", "missed"),
    [(map_with_features, 16, False), (_island, 8, False), (_island, 16, True),
     (_dots, 8, True), (_dots, 16, True), ("peak", 8, True), ("peak", 16, True)],
)  # fmt: skip
def test_an_exact_prediction_gives_the_exact_map(label, step, missed):
    """A prediction equal to the simulation at every point: every inferred point lies in
    a cell whose corners it gets right, so it takes the predicted label (with or without
    the hint; ``missed``: the map without either loses a feature)."""
    hint = None
    if label == "peak":
        label, hint = _peak(111)
    want = truth(label)
    for h in (hint, None):
        res = _quiet(step, synthetic(label), h, want)
        np.testing.assert_array_equal(res.fields["regime"], want)
    plain = _quiet(step, synthetic(label), None).fields["regime"]
    assert (plain != want).any() == missed


def _wrong(i, j):
    """A prediction of ``map_with_features`` that is wrong: its wavy boundary 6 steps
    off, an island that is not there, no strip."""
    x, y = i / N_R, j / N_B
    lab = np.where(y < 0.3 + 0.15 * np.sin(5 * x) + 6 / N_B, regimes.CONTINUOUS, 1)
    lab = np.where(y > 0.85 - 0.1 * x, regimes.NO_MOTION, lab)
    lab = np.where((i - 60) ** 2 + (j - 80) ** 2 < 15**2, regimes.NO_MOTION, lab)
    return np.where((i - 200) ** 2 + (j - 60) ** 2 < 3**2, regimes.NO_MOTION, lab)


@pytest.mark.parametrize("case", ["peak", "wrong"])
def test_the_prediction_gives_the_same_map_in_any_order(case):
    if case == "peak":
        label, hint = _peak(111)
        predicted = truth(label)
    else:
        label, hint, predicted = map_with_features, None, truth(_wrong)
    batch = synthetic(label)
    want = waves((N_R, N_B), batch, 16, hint, predicted=predicted).result()
    np.testing.assert_array_equal(want["regime"], truth(label))
    for seed in range(3):
        got = shuffled_stream((N_R, N_B), batch, seed, 16, hint, predicted=predicted).result()
        np.testing.assert_array_equal(got["simulated"], want["simulated"])
        np.testing.assert_array_equal(got["regime"], want["regime"])
        np.testing.assert_array_equal(got["slip_amplitude"], want["slip_amplitude"])


def test_a_wrong_prediction_costs_points_never_labels():
    batch = synthetic(map_with_features)
    want = truth(map_with_features)
    plain = _quiet(16, batch, None)
    guided = _quiet(16, batch, None, truth(_wrong))
    for res in (plain, guided):
        np.testing.assert_array_equal(res.fields["regime"], want)
        assert_boundaries_simulated(res.fields["simulated"], want)
    sim = guided.fields["simulated"]
    assert sim[197:204, 57:64].any()  # the island predicted there was looked for
    assert guided.simulated_points <= 1.15 * plain.simulated_points


@pytest.mark.parametrize("k", [2, 4])
def test_tiles_with_the_prediction_end_at_the_plane_refinements_map(k):
    label, hint = _peak(111)
    predicted = truth(label)
    batch = synthetic(label)
    tiles = [(*t, hint, batch) for t in _tiles(batch, hint, k, predicted)]
    plain = _refined(StreamRefinement((N_R, N_B), 16, hint, predicted=predicted), batch)
    np.testing.assert_array_equal(plain.result()["regime"], predicted)
    examined = _arrive(tiles, list(range(len(tiles))), install=False, predicted=predicted)
    orders = [list(range(len(tiles)))[::-1], list(np.random.default_rng(k).permutation(k))]
    for order in orders:
        installed = _arrive(tiles, order, install=True, predicted=predicted)
        for other in (examined, plain):
            np.testing.assert_array_equal(installed.simulated, other.simulated)
            np.testing.assert_array_equal(installed.result()["regime"], other.result()["regime"])
        assert installed.level_sizes() == examined.level_sizes()


# ------------------------------------------------------------------ cells as arrays
SHAPE = (41, 23)


def _state(seed: int) -> Refinement:
    """Labels in blocks (cells with corners that agree), a prediction right at most points."""
    rng = np.random.default_rng(seed)
    i, j = np.meshgrid(np.arange(SHAPE[0]), np.arange(SHAPE[1]), indexing="ij")
    blocks = rng.integers(0, 3, (SHAPE[0] // 9 + 1, SHAPE[1] // 7 + 1))
    label = blocks[i // 9, j // 7]
    label = np.where(rng.random(SHAPE) < 0.05, regimes.NOT_CONVERGED, label)
    predicted = np.where(rng.random(SHAPE) < 0.9, label, rng.integers(-1, 3, SHAPE))
    ref = Refinement(SHAPE, 8, predicted=predicted.astype(np.int8))
    ref.fields["regime"][...] = label
    ref.key[...] = label
    ref.simulated[...] = rng.random(SHAPE) < 0.5
    return ref


def _boxes(seed: int, n: int = 600) -> np.ndarray:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        w, t = ((1, 2), (2, 1), *rng.integers(1, 10, (3, 2)).tolist())[rng.integers(5)]
        i0, j0 = rng.integers(0, SHAPE[0] - w), rng.integers(0, SHAPE[1] - t)
        out.append((i0, i0 + w, j0, j0 + t))
    return np.array(out, dtype=np.int64)


@pytest.mark.parametrize("seed", range(4))
def test_guided_cells_as_arrays_equal_the_per_cell_methods(seed):
    ref = _state(seed)
    boxes = _boxes(seed)
    as_tuples = [tuple(int(v) for v in b) for b in boxes]
    stream = StreamRefinement(SHAPE, 8, predicted=ref.predicted)
    stream.fields["regime"][...] = ref.fields["regime"]
    stream.key[...], stream.simulated[...] = ref.key, ref.simulated
    trust, guided = stream._guided_many(boxes)
    np.testing.assert_array_equal(trust, [ref._trusted(b) for b in as_tuples])
    np.testing.assert_array_equal(guided, [ref._guided(b) for b in as_tuples])
    assert guided.sum() > 20 and (~guided).sum() > 50
    split = (boxes[:, 1] - boxes[:, 0] > 1) | (boxes[:, 3] - boxes[:, 2] > 1)
    guide = (np.where(guided, trust, -1)[split], ref.mismatch_tables)
    halves = cells.halves(boxes[split], ref.key, None, guide).reshape(-1, 2, 4)
    for n, box in enumerate(b for b, s in zip(as_tuples, split, strict=True) if s):
        assert [tuple(int(v) for v in h) for h in halves[n]] == ref._children(box), box
    strip = cells.strips(boxes)
    sim = ref.simulated.reshape(-1)
    ask = stream._guided_middles_many(boxes[strip], sim)
    m = cells.strip_edges(boxes[strip], SHAPE[1])[1]
    for n, box in enumerate(b for b, s in zip(as_tuples, strip, strict=True) if s):
        want = sorted(i * SHAPE[1] + j for i, j in ref._guided_middles(box))
        assert sorted(m[n][ask[n]].tolist()) == want, box
        assert ref._guided_open(box) == bool(ask[n].any())
