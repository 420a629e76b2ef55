"""Cuts at the hint (tasks.cells.split_at): a cell crossed by a hinted curve is cut on
the hinted grid line nearest its middle instead of at its middle.

* a synthetic map with a known wavy boundary and a flat one, the hint exactly on
  them (as the closed forms are): every label right, every differing pair of
  neighbours resolved, and the hint costs at most 3 % more simulations than no
  hint (the cuts at the middle cost 9 % more here: 1639 against 1499 points);
* the same map in any order of arrival as the wave refinement, with the hint on
  the boundary and beside it;
* ``split_at`` against a brute-force search over the lines of random cells;
* a hinted point on a cut line stays hinted (the island test of
  ``tests/test_adaptive.py`` is the map-level check).
"""

from __future__ import annotations

import numpy as np
import pytest
from test_adaptive import (
    N_B,
    N_R,
    assert_boundaries_simulated,
    shuffled_stream,
    synthetic,
    truth,
    waves,
)

from analysis.adaptive import curve_hint
from tasks import cells, regimes
from tasks.adaptive import HINT_CELL, refine


def _lower(i):
    return 40 + 25 * np.sin(i / 30.0) + 0.1 * i


def _wavy_and_flat(i, j):
    """Continuous below a wavy curve, stick-slip above it, no motion above a flat line."""
    lab = np.where(j < _lower(i), regimes.CONTINUOUS, regimes.STICK_SLIP)
    return np.where(j > 100.5, regimes.NO_MOTION, lab)


def _hint():
    axis = np.arange(N_B, dtype=float)
    i = np.arange(N_R)
    return curve_hint(axis, _lower(i)) | curve_hint(axis, np.full(N_R, 100.5))


def test_an_exact_hint_costs_almost_nothing_and_every_label_is_right():
    hint = _hint()
    batch = synthetic(_wavy_and_flat)
    want = truth(_wavy_and_flat)
    plain = refine((N_R, N_B), batch, 16, None, verify_min=0, verify_fraction=0)
    hinted = refine((N_R, N_B), batch, 16, hint, verify_min=0, verify_fraction=0)
    for res in (plain, hinted):
        np.testing.assert_array_equal(res.fields["regime"], want)
        assert_boundaries_simulated(res.fields["simulated"], want)
    assert hinted.simulated_points <= 1.03 * plain.simulated_points, (
        hinted.simulated_points,
        plain.simulated_points,
    )


@pytest.mark.parametrize("off", [0, 7])
def test_cuts_at_the_hint_give_the_same_map_in_any_order(off):
    """Point lists in shuffled orders against the wave refinement, with a curve hint
    (``off`` steps away from the boundary it follows: a wrong hint costs points, never
    labels)."""
    batch = synthetic(_wavy_and_flat)
    axis = np.arange(N_B, dtype=float)
    hint = curve_hint(axis, _lower(np.arange(N_R)) + off)
    want = waves((N_R, N_B), batch, 16, hint).result()
    np.testing.assert_array_equal(want["regime"], truth(_wavy_and_flat))
    for seed in range(3):
        got = shuffled_stream((N_R, N_B), batch, seed, 16, hint).result()
        np.testing.assert_array_equal(got["simulated"], want["simulated"])
        np.testing.assert_array_equal(got["regime"], want["regime"])
        np.testing.assert_array_equal(got["slip_amplitude"], want["slip_amplitude"])


def _split_at_by_search(box, split_r, hint):
    """The hinted line strictly inside the cell nearest its middle (the lower of two)."""
    i0, i1, j0, j1 = box
    lo, hi = (i0, i1) if split_r else (j0, j1)
    mid = (lo + hi) // 2
    lines = [
        p
        for p in range(lo + 1, hi)
        if (hint[p, j0 : j1 + 1] if split_r else hint[i0 : i1 + 1, p]).any()
    ]
    return min(lines, key=lambda p: (abs(p - mid), p)) if lines else mid


@pytest.mark.parametrize("seed", range(3))
def test_split_at_is_the_hinted_line_nearest_the_middle(seed):
    rng = np.random.default_rng(seed)
    shape = (70, 50)
    hint = rng.random(shape) < 0.004
    i0, j0 = rng.integers(0, 40, 300), rng.integers(0, 30, 300)
    boxes = np.stack([i0, i0 + rng.integers(2, 30, 300), j0, j0 + rng.integers(2, 20, 300)], 1)
    split_r = rng.random(300) < 0.5
    got = cells.split_at(boxes, split_r, cells.summed_table(hint))
    want = [_split_at_by_search(b, s, hint) for b, s in zip(boxes.tolist(), split_r, strict=True)]
    np.testing.assert_array_equal(got, want)
    moved = got != cells.split_at(boxes, split_r)
    assert moved.any() and not moved.all()


def test_a_hinted_point_on_a_long_edge_keeps_the_cell_hinted():
    """A cut through a hinted point puts it on the edge of both halves: they stay hinted
    while that edge is longer than HINT_CELL (its points are not simulated); on a shorter
    edge or at a corner (simulated) it no longer splits the cell."""
    hint = np.zeros((40, 40), dtype=bool)
    hint[8, 5] = True
    table = cells.summed_table(hint)
    halves = np.array([[0, 8, 0, 16], [8, 16, 0, 16]])  # the point on their shared edge
    assert cells.hinted(halves, table, HINT_CELL).all()
    short_edge = np.array([[0, 8, 4, 8]])  # on its edge of 4 steps at i = 8
    corner = np.array([[8, 24, 5, 21]])
    inside = np.array([[4, 12, 0, 8]])
    assert not cells.hinted(short_edge, table, HINT_CELL).any()
    assert not cells.hinted(corner, table, HINT_CELL).any()
    assert cells.hinted(inside, table, HINT_CELL).all()
    assert not cells.hinted(inside, table, 8).any()  # not larger than the hint cell
