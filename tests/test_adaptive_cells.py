"""The refinement's cells examined as arrays (tasks.cells) against the per-cell methods
of tasks.adaptive.Refinement, on random cells, keys and simulated points.

The per-cell methods are the reference (the wave refinement uses them, and
tests/test_adaptive.py checks the maps they make against exact truths); every
vectorised function must take the same decision for every cell.
"""

from __future__ import annotations

import numpy as np
import pytest

from tasks import cells
from tasks.adaptive import Refinement
from tasks.stream import StreamRefinement

SHAPE = (41, 23)


def _state(seed: int, n_keys: int, fill: float) -> Refinement:
    """A refinement whose keys and simulated points are random (few keys: many ties)."""
    rng = np.random.default_rng(seed)
    ref = Refinement(SHAPE, 8)
    ref.key[...] = rng.integers(0, n_keys, SHAPE)
    ref.simulated[...] = rng.random(SHAPE) < fill
    return ref


def _boxes(seed: int, n: int = 400) -> np.ndarray:
    """Random cells of every kind: large, thin, strips both ways, unit and width-0 cells."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        kind = rng.integers(4)
        if kind == 0:  # a strip, either way
            w, t = ((1, 2), (2, 1))[rng.integers(2)]
        elif kind == 1:  # small
            w, t = rng.integers(0, 3, 2)
        else:
            w, t = rng.integers(1, 12, 2)
        i0 = rng.integers(0, SHAPE[0] - w)
        j0 = rng.integers(0, SHAPE[1] - t)
        out.append((i0, i0 + w, j0, j0 + t))
    return np.array(out, dtype=np.int64)


def _as_tuples(boxes: np.ndarray) -> list[tuple[int, int, int, int]]:
    return [tuple(int(v) for v in b) for b in boxes]


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("n_keys", [1, 2, 3])
def test_settled_cells_and_strips_as_arrays_equal_the_per_cell_methods(seed, n_keys):
    ref = _state(seed, n_keys, fill=(0.2, 0.6, 0.95)[seed % 3])
    boxes = _boxes(seed)
    key, sim = ref.key.reshape(-1), ref.simulated.reshape(-1)
    n_b = SHAPE[1]
    want = [ref._uniform(b) for b in _as_tuples(boxes)]
    np.testing.assert_array_equal(cells.uniform(boxes, key, sim, n_b), want)
    strip = cells.strips(boxes)
    assert strip.sum() > 50 and (~strip).sum() > 50
    np.testing.assert_array_equal(strip, [bool(ref._strip_points(b)) for b in _as_tuples(boxes)])
    a, m, b = cells.strip_edges(boxes[strip], n_b)
    for n, box in enumerate(_as_tuples(boxes[strip])):
        edges = ref._strip_points(box)
        flat = [[p[0] * n_b + p[1] for p in edge] for edge in edges]
        assert [[a[n, e], m[n, e], b[n, e]] for e in (0, 1)] == flat
    resolved = cells.resolved_strips(a, m, b, key, sim)
    np.testing.assert_array_equal(
        resolved, [ref._resolved_strip(x) for x in _as_tuples(boxes[strip])]
    )
    ask = cells.strip_middles(a, m, b, key, sim)
    for n, box in enumerate(_as_tuples(boxes[strip])):
        if resolved[n]:
            continue  # a resolved strip asks for nothing (never examined so)
        want_m = sorted(i * n_b + j for i, j in ref._strip_middles(box))
        assert sorted(m[n][ask[n]].tolist()) == want_m, box
    # the stream's settled test (uniform, or a resolved strip) on the same state
    stream = StreamRefinement(SHAPE, 8)
    stream.key[...], stream.simulated[...] = ref.key, ref.simulated
    want = [ref._settled(x) for x in _as_tuples(boxes)]
    np.testing.assert_array_equal(stream._settled_many(boxes), want)


@pytest.mark.parametrize("seed", range(4))
def test_halves_and_hints_as_arrays_equal_the_per_cell_methods(seed):
    ref = _state(seed, 2, 0.5)
    boxes = _boxes(seed + 10)
    boxes = boxes[(boxes[:, 1] - boxes[:, 0] > 1) | (boxes[:, 3] - boxes[:, 2] > 1)]
    halves = cells.halves(boxes, ref.key).reshape(-1, 2, 4)
    for n, box in enumerate(_as_tuples(boxes)):
        assert _as_tuples(halves[n]) == ref._children(box), box
    hint = np.random.default_rng(seed).random(SHAPE) < 0.01
    ref.hint = hint  # (set_hint refuses a hint once points are simulated)
    stream = StreamRefinement(SHAPE, 8, hint)
    want = [ref._hinted(b) for b in _as_tuples(boxes)]
    assert any(want) and not all(want)
    np.testing.assert_array_equal(stream._hinted_many(boxes), want)


def _sources_by_loop(boxes: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """The former per-cell fill: each cell in turn paints the nearer corner along each
    axis over all its points (a later cell overwrites an earlier one)."""
    src_i = np.full(shape, -1, dtype=np.int64)
    src_j = np.full(shape, -1, dtype=np.int64)
    for i0, i1, j0, j1 in boxes.tolist():
        mi, mj = (i0 + i1) // 2 + 1, (j0 + j1) // 2 + 1
        src_i[i0:mi, j0 : j1 + 1] = i0
        src_i[mi : i1 + 1, j0 : j1 + 1] = i1
        src_j[i0 : i1 + 1, j0:mj] = j0
        src_j[i0 : i1 + 1, mj : j1 + 1] = j1
    return src_i.ravel(), src_j.ravel()


@pytest.mark.parametrize("seed", range(3))
def test_nearest_corner_sources_equal_painting_cell_by_cell(seed):
    """Overlapping cells (shared edges, and here also nested ones): the last cell wins."""
    boxes = _boxes(seed, 150)
    todo = np.arange(SHAPE[0] * SHAPE[1])
    want_i, want_j = _sources_by_loop(boxes, SHAPE)
    covered = want_i >= 0
    assert covered.mean() > 0.5 and not covered.all()
    got_i, got_j = cells.nearest_corner_sources(boxes, todo[covered], SHAPE)
    np.testing.assert_array_equal(got_i, want_i[covered])
    np.testing.assert_array_equal(got_j, want_j[covered])
    got_i, _ = cells.nearest_corner_sources(boxes, todo, SHAPE)  # a point in no cell
    assert (got_i == -1).all()


@pytest.mark.parametrize("seed", range(3))
def test_cells_holding_points_equal_the_broadcast_comparison(seed):
    """:func:`tasks.cells.holding` (the compiled path of ``Refinement._leaves_hit``)
    against the comparison of every cell with every point."""
    rng = np.random.default_rng(seed)
    boxes = _boxes(seed)
    pi, pj = rng.integers(0, SHAPE[0], 40), rng.integers(0, SHAPE[1], 40)
    i0, i1, j0, j1 = (c[:, None] for c in boxes.T)
    want = ((i0 <= pi) & (pi <= i1) & (j0 <= pj) & (pj <= j1)).any(axis=1)
    assert want.any() and not want.all()
    np.testing.assert_array_equal(cells.holding(boxes, pi, pj), want)
