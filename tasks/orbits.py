"""The solved orbits of an adaptive plane, by point: the seeds of later points.

Pure numerics (no Dask, no files): :mod:`study.adaptive` keeps one per plane in
the client, :mod:`tasks.tiles` one per tile in a worker.
"""

from __future__ import annotations

import numpy as np

from tasks.seeds import grid_neighbours, grid_offsets

#: Solved points (nearest first, :func:`tasks.seeds.grid_neighbours`) whose orbits are
#: sent with a point list to seed each of its points (one contact, warm starts on):
#: four, so that a cell's middle finds two corners to interpolate between and a
#: point next to a change of regime a seed on its own side (2 cost 4 % more periods on
#: the 6DOF ground-m5 map, as many on Fig. 4: benchmarks/bench_refine_seeded.py).
GIVEN_PER_POINT = 4


class Orbits:
    """The solved moving period-1 orbits of a plane in this run (section state, phase,
    section phase: ``final`` of :func:`tasks.classifier.classify_given`), by point.

    A new point list is sent the orbits of the solved points nearest to its points
    (the corners of the cells that asked for them), which seed their searches as
    an earlier point of the list would: fewer periods, the same labels, the other
    fields equal to the polish (:mod:`tasks.seeds`). Not saved: a resumed run seeds
    only from what it solves itself.
    """

    def __init__(self, shape: tuple[int, int], reach: int) -> None:
        self.shape = shape
        self.row = np.full(shape[0] * shape[1], -1, dtype=np.int64)  # point -> row
        self.flat = np.zeros(0, dtype=np.int64)  # row -> point
        self.state = np.zeros((0, 0))
        self.n = 0
        self.offsets = grid_offsets(reach)

    def add(self, idx: np.ndarray, final: np.ndarray) -> None:
        """Keep the orbits of the points ``idx`` that have one (finite rows of ``final``)."""
        ok = np.isfinite(final).all(axis=1)
        idx, final = idx[ok], final[ok]
        m = idx.size
        if not m:
            return
        if self.n + m > self.flat.size:  # grow by doubling
            cap = max(2 * self.flat.size, self.n + m, 1024)
            self.flat = np.resize(self.flat, cap)
            state = np.empty((cap, final.shape[1]))
            if self.n:
                state[: self.n] = self.state[: self.n]
            self.state = state
        self.flat[self.n : self.n + m] = idx
        self.state[self.n : self.n + m] = final
        self.row[idx] = np.arange(self.n, self.n + m)
        self.n += m

    def given(self, idx: np.ndarray, r: np.ndarray, beta: np.ndarray) -> tuple:
        """``(r, beta, final)`` of the solved points nearest to the points ``idx`` (maybe
        none), for :func:`study.compute._point_list`."""
        rows = np.zeros(0, dtype=np.int64)
        if self.n:
            rows = grid_neighbours(idx, self.shape, self.row, self.offsets, GIVEN_PER_POINT)
            rows = np.unique(rows[rows >= 0])
        i_r, i_b = np.unravel_index(self.flat[rows], self.shape)
        return r[i_r], beta[i_b], self.state[rows]
