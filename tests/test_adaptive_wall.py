"""What an adaptive map's client does less of, with the same map (study.adaptive, tasks.stream).

* a tile's refinement taken as the tile decided it
  (:meth:`tasks.stream.StreamRefinement.install`) ends, in any order of the tiles'
  arrival, at the same simulated points, fields and level sizes as the plane's
  refinement examining the tiles' points itself, and as the plane refined alone;
* the verification sample drawn from the points below the fraction before the
  refinement ends (:meth:`tasks.adaptive.Refinement.presample`) is the sample
  drawn from the inferred points after it, also when fewer than its minimum
  are below the fraction.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_adaptive import N_B, N_R, map_with_features, synthetic, truth
from test_adaptive_tiles import _refined

from study.tiles import first_tile
from tasks.adaptive import Refinement, verification_sample
from tasks.cells import unique_boxes
from tasks.stream import StreamRefinement
from tasks.tiles import refine_tile_cells, strips


def _tiles(batch, hint, k, predicted=None):
    """Each tile of ``strips(N_R, 16, k)`` refined alone: rows, plane indices, fields, cells
    (with the hint and the prediction restricted to it)."""

    def simulate(r, beta, given):  # r and beta are the grid indices here; no orbits
        return batch(r.astype(int), beta.astype(int)) | {"final": np.full((r.size, 4), np.nan)}

    out = []
    for i0, i1 in strips(N_R, 16, k):
        part = None if hint is None else hint[i0 : i1 + 1]
        guess = None if predicted is None else predicted[i0 : i1 + 1]
        axis_r = np.arange(i0, i1 + 1, dtype=float)
        idx, arrays, _, cells = refine_tile_cells(
            simulate, axis_r, np.arange(N_B, dtype=float), 16, part, guess
        )
        leaves = cells["leaves"] + np.array([i0, i0, 0, 0])  # in the plane's rows
        plane_cells = {
            "leaves": leaves,
            "leaf_depth": cells["leaf_depth"],
            "level": cells["level"],
            "points": idx + i0 * N_B,
        }
        out.append(((i0, i1), idx + i0 * N_B, arrays, plane_cells))
    return out


def _arrive(tiles, order, install: bool, predicted=None) -> StreamRefinement:
    """The plane's refinement receiving the tiles in ``order`` as the client does (a point
    of two tiles keeps the fields of the tile of smaller r), then refined to the end."""
    hint = tiles[0][4]
    plane = StreamRefinement((N_R, N_B), 16, hint, predicted=predicted)
    plane.take()  # the coarse lattice: the tiles simulate it
    first_row = np.full(plane.n_points, np.iinfo(np.int64).max, dtype=np.int64)
    for n in order:
        rows, idx, arrays, cells = tiles[n][:4]
        take = first_tile(idx, np.full(idx.size, rows[0]), first_row)
        first_row[idx[take]] = rows[0]
        fields = {k: v[take] for k, v in arrays.items()}
        if install:
            plane.install(idx[take], fields, rows, cells)
        else:
            plane.accept(idx[take], fields)
    return _refined(plane, tiles[0][5])


@pytest.mark.parametrize(("hinted", "k"), [(False, 4), (True, 4), (True, 7), (False, 2)])
def test_tiles_installed_end_at_the_map_of_tiles_examined_again(hinted, k):
    batch = synthetic(map_with_features)
    lab = truth(map_with_features)
    hint = None
    if hinted:  # the points beside a change of label along r
        hint = np.zeros(lab.shape, dtype=bool)
        hint[1:] |= lab[1:] != lab[:-1]
        hint[:-1] |= lab[1:] != lab[:-1]
    tiles = [(*t, hint, batch) for t in _tiles(batch, hint, k)]
    plain = _refined(StreamRefinement((N_R, N_B), 16, hint), batch)
    rng = np.random.default_rng(k + hinted)
    orders = [list(range(len(tiles))), list(range(len(tiles)))[::-1]]
    orders += [list(rng.permutation(len(tiles))) for _ in range(2)]
    examined = _arrive(tiles, orders[0], install=False)
    for order in orders:
        installed = _arrive(tiles, order, install=True)
        np.testing.assert_array_equal(installed.simulated, examined.simulated)
        np.testing.assert_array_equal(installed.simulated, plain.simulated)
        assert installed.level_sizes() == examined.level_sizes()
        a, b = installed.result(), examined.result()
        for name in a:
            np.testing.assert_array_equal(a[name], b[name], err_msg=name)
        np.testing.assert_array_equal(a["regime"], plain.result()["regime"])


def test_a_tile_disagreeing_on_its_shared_row_reopens_its_neighbours_cells():
    """Tile B's points on the row it shares with A, which A did not simulate, fall in
    A's uniform cells; a different label there must reopen them (both paths agree)."""
    t = strips(N_R, 16, 4)[0][1]  # the row tiles 0 and 1 share

    def label(i, j):  # a wedge from a coarse node of tile 1 to the shared row, where it
        # lies between the coarse nodes (tile 0 alone leaves its cells there uniform)
        return np.where((i >= t) & (i <= t + 18) & (np.abs(j - 24) <= 4 + (i - t) // 2), 2, 1)

    batch = synthetic(label)
    tiles = [(*t, None, batch) for t in _tiles(batch, None, 4)]
    _, idx0, arrays0, _ = tiles[0][:4]
    row = idx0 // N_B == t
    assert (arrays0["regime"][row] == 1).all()  # tile 0 saw no feature on the shared row
    for order in ([1, 0, 2, 3], [0, 1, 2, 3]):
        examined = _arrive(tiles, order, install=False)
        installed = _arrive(tiles, order, install=True)
        np.testing.assert_array_equal(installed.simulated, examined.simulated)
        np.testing.assert_array_equal(installed.result()["regime"], examined.result()["regime"])
        assert installed.level_sizes() == examined.level_sizes()
    np.testing.assert_array_equal(installed.result()["regime"], truth(label))


@pytest.mark.parametrize(("fraction", "minimum"), [(0.01, 20), (0.01, 2000), (0.0, 50), (0.5, 0)])
def test_presampled_verification_is_the_sample_drawn_after(fraction, minimum):
    batch = synthetic(map_with_features)
    drawn = []
    for pre in (False, True):
        ref = StreamRefinement((N_R, N_B), 16)
        if pre:
            ref.presample(fraction, seed=3)
        drawn.append(ref_sample := _refined(ref, batch).verification(fraction, minimum, seed=3))
        inferred = np.flatnonzero(~ref.simulated.ravel())
        np.testing.assert_array_equal(
            ref_sample, verification_sample(inferred, fraction, minimum, 3)
        )
    np.testing.assert_array_equal(drawn[0], drawn[1])
    assert drawn[1].size == max(min(minimum, N_R * N_B - int(ref.simulated.sum())), drawn[1].size)


def test_presample_of_another_fraction_or_seed_is_not_used():
    ref = Refinement((N_R, N_B), 16)
    ref.presample(0.5, seed=1)
    inferred = np.arange(N_R * N_B)  # nothing simulated
    np.testing.assert_array_equal(
        ref.verification(0.01, 10, seed=2), verification_sample(inferred, 0.01, 10, 2)
    )


@pytest.mark.parametrize("high", [40, 1 << 15, 1 << 20])
def test_unique_boxes_is_numpys_unique_by_rows(high):
    rng = np.random.default_rng(high)
    boxes = rng.integers(0, high, size=(500, 4))
    boxes = np.concatenate([boxes, boxes[rng.integers(0, 500, 300)]])  # repeated cells
    rng.shuffle(boxes)
    got, at = unique_boxes(boxes)
    want, want_at = np.unique(boxes, axis=0, return_index=True)
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(at, want_at)
    empty = unique_boxes(np.zeros((0, 4), dtype=np.int64))
    assert empty[0].shape == (0, 4) and empty[1].size == 0
