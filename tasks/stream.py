"""Refinement without barriers: the adaptive map's cells split as their corners arrive.

:class:`StreamRefinement` is the :class:`tasks.adaptive.Refinement` a study drives
(:mod:`study.adaptive`): points are taken when ready and their results accepted in
any order, and the cells that complete together are examined together, as arrays
(:mod:`tasks.cells`). It ends at the same cells, simulated points and labels as
the wave refinement (:meth:`tasks.adaptive.Refinement.wave`). No Dask, no files.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from tasks import cells
from tasks.adaptive import HINT_CELL, Refinement


class StreamRefinement(Refinement):
    """A :class:`Refinement` without barriers: cells split as soon as their corners arrive.

    The caller takes the points ready to simulate (:meth:`take`), in batches of
    any size and as many batches in flight as it likes, and hands back results
    point list by point list in any order (:meth:`accept`). A cell is examined
    when its last corner arrives; a uniform cell (a leaf) that later receives a
    disagreeing point is examined again, as in :meth:`Refinement.wave`.

    The result does not depend on the arrival order: a cell is split only when
    the points known so far prove it unsettled (:meth:`Refinement._settled`; more
    points can only keep it unsettled) or it is hinted; a 1 x 2 strip asks for
    a middle only when the points that end up simulated require it
    (:meth:`Refinement._strip_middles`: a disagreeing edge, or a middle across
    that disagrees; a strip settled earlier is examined again when a point
    arrives on it); and refinement ends only when every unsplit cell is
    settled given every simulated point. Both this and the wave refinement
    therefore end at the least such set of splits and middles: the same
    simulated points, the same labels (``tests/test_adaptive.py`` checks
    shuffled orders against the waves).

    The cells that complete together (one :meth:`accept`) are examined together,
    as arrays (:mod:`tasks.cells`): the same decisions as the per-cell methods of
    :class:`Refinement`, without a Python loop per cell.
    """

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)
        first, self._first = np.sort(self._first), None
        self._ready = first  # emitted, not handed out yet (in the order emitted)
        self._requested = np.zeros(self.n_points, dtype=bool)
        self._requested[first] = True
        self._level = np.full(self.n_points, np.iinfo(np.int64).max, dtype=np.int64)
        # cells waiting for points: the cell, its depth (halvings from its coarse cell)
        # and the four points it waits for (its corners, or a strip's middles, repeated)
        self._pending = np.zeros((0, 4), dtype=np.int64)
        self._pending_depth = np.zeros(0, dtype=np.int64)
        self._pending_on = np.zeros((0, 4), dtype=np.int64)
        self._leaf_depth = np.zeros(0, dtype=np.int64)  # depth of each row of _leaves
        self._leaf_parts: list[tuple[np.ndarray, np.ndarray]] = []  # not yet in _leaves
        coarse = np.array(self._active, dtype=np.int64).reshape(-1, 4)
        self._active = []
        self._evaluate(*self._wait(coarse, np.zeros(coarse.shape[0], dtype=np.int64)))

    def wave(self) -> np.ndarray:  # pragma: no cover - guard
        raise TypeError("StreamRefinement: use take() and accept(), not wave()")

    @property
    def ready(self) -> int:
        """Points ready to simulate, not handed out yet."""
        return int(self._ready.size)

    @property
    def done(self) -> bool:
        """Every requested point arrived and no cell is left to examine."""
        return not self._ready.size and not self._pending.shape[0]

    def take(self, n: int | None = None) -> np.ndarray:
        """Up to ``n`` (all if None) ready points to simulate, as flat indices (sorted)."""
        n = self._ready.size if n is None else max(0, int(n))
        out, self._ready = self._ready[:n], self._ready[n:]
        return np.sort(out)

    def accept(self, idx: np.ndarray, results: Mapping[str, np.ndarray]) -> None:
        """Store the results of points ``idx`` (any handed-out points, in any order) and
        examine every cell they complete or contradict; new points become ready."""
        idx = np.asarray(idx, dtype=np.int64).ravel()
        super().accept(idx, results)
        self._examine()

    def _examine(self) -> None:
        """Examine the leaves the last points contradict and the cells they complete."""
        boxes, depth = self._reopened()  # leaves holding a new disagreeing point
        done = self.simulated.reshape(-1)[self._pending_on].all(axis=1)
        if done.any():
            boxes = np.concatenate([boxes, self._pending[done]])
            depth = np.concatenate([depth, self._pending_depth[done]])
            self._pending = self._pending[~done]
            self._pending_depth = self._pending_depth[~done]
            self._pending_on = self._pending_on[~done]
        self._evaluate(boxes, depth)

    def install(
        self,
        idx: np.ndarray,
        results: Mapping[str, np.ndarray],
        rows: tuple[int, int],
        cells: Mapping[str, np.ndarray],
    ) -> None:
        """:meth:`accept` of the points of a tile refined alone (:func:`tasks.tiles.refine_tile`):
        the tile's own cells (``cells``: its final ``leaves`` and their ``leaf_depth``, in
        the plane's rows, and the ``level`` of each of its points ``points``) are taken as
        the tile decided them instead of being examined again.

        ``idx`` (with ``results``) are the tile's points to store (those another tile
        of smaller r did not give first), ``rows`` its first and last r index. The same
        state as :meth:`accept` reaches, up to the order-independence of the
        refinement: a cell of the tile's rows depends only on its own points and the
        hint, which the tile had, but for the points on the two rows it shares with its
        neighbours, which a neighbour may have simulated too; so every leaf holding a
        simulated point of those rows is examined again (:meth:`_reopened`), and the
        cells waiting for the tile's points are examined as :meth:`accept` does
        (``tests/test_adaptive_wall.py`` compares both paths)."""
        idx = np.asarray(idx, dtype=np.int64).ravel()
        Refinement.accept(self, idx, results)
        t0, t1 = rows
        points = np.asarray(cells["points"], dtype=np.int64)
        np.minimum.at(self._level, points, np.asarray(cells["level"], dtype=np.int64))
        self._requested[points] = True
        inside = (self._pending[:, 0] >= t0) & (self._pending[:, 1] <= t1)
        if inside.any():  # the tile's coarse cells: decided by the tile
            self._pending = self._pending[~inside]
            self._pending_depth = self._pending_depth[~inside]
            self._pending_on = self._pending_on[~inside]
        leaves = np.asarray(cells["leaves"], dtype=np.int64).reshape(-1, 4)
        self._leaf_parts.append((leaves, np.asarray(cells["leaf_depth"], dtype=np.int64)))
        n_b = self.shape[1]
        edge = np.concatenate([np.arange(t * n_b, (t + 1) * n_b) for t in (t0, t1)])
        edge = edge[self.simulated.reshape(-1)[edge]]  # the shared rows' simulated points
        self._last_new = np.divmod(edge, n_b)
        self._examine()

    def level_sizes(self) -> list[int]:
        """Points of the refinement per level: a point's level is the smallest depth (in
        halvings from the coarse lattice) of a cell it is a corner of. Unlike the batches,
        this does not depend on the arrival order (the cells are those of the waves)."""
        flat = self._level[self._level < np.iinfo(np.int64).max]
        return np.bincount(flat).tolist() if flat.size else []

    # ------------------------------------------------------------ cells as arrays
    def _wait(
        self, boxes: np.ndarray, depth: np.ndarray, on: np.ndarray | None = None, at=None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Register cells for the points ``on`` (default: their corners, at level
        ``depth``; a strip's middles at ``at``) not simulated yet, requesting them; the
        cells whose points are all simulated are returned (to examine now)."""
        if on is None:
            on, at = cells.corners(boxes, self.shape[1]), depth
        if not boxes.shape[0]:
            return boxes, depth
        np.minimum.at(self._level, on.ravel(), np.repeat(at, on.shape[1]))
        missing = ~self.simulated.reshape(-1)[on]
        new = np.unique(on[missing])
        new = new[~self._requested[new]]
        if new.size:
            self._requested[new] = True
            self._ready = np.concatenate([self._ready, new])
        wait = missing.any(axis=1)
        self._pending = np.concatenate([self._pending, boxes[wait]])
        self._pending_depth = np.concatenate([self._pending_depth, depth[wait]])
        self._pending_on = np.concatenate([self._pending_on, on[wait]])
        return boxes[~wait], depth[~wait]

    def _evaluate(self, boxes: np.ndarray, depth: np.ndarray) -> None:
        """Examine cells whose points are all simulated, as arrays: each becomes a leaf,
        or is split (as in :meth:`wave`), or, a strip, asks for middles; halves whose
        corners are simulated already are examined in the next round."""
        key, sim = self.key.reshape(-1), self.simulated.reshape(-1)
        while boxes.shape[0]:
            boxes, at = cells.unique_boxes(boxes)  # each cell once
            depth = depth[at]
            settled = leaf = self._settled_many(boxes)
            if self.hint is not None and leaf.any():
                leaf = leaf.copy()
                leaf[leaf] = ~self._hinted_many(boxes[leaf])
            wide, tall = boxes[:, 1] - boxes[:, 0], boxes[:, 3] - boxes[:, 2]
            is_strip = cells.strips(boxes)
            trust = guided = None
            if self.predicted is not None:  # the prediction keeps guided cells open
                trust, guided = self._guided_many(boxes)
                ask = self._guided_middles_many(boxes[is_strip], sim)
                open_ = guided.copy()
                open_[is_strip] = ask.any(axis=1)
                leaf = leaf & ~open_
            if leaf.any():
                self._leaf_parts.append((boxes[leaf], depth[leaf]))
            strip = ~leaf & is_strip
            split = ~leaf & ~strip & ~((wide <= 1) & (tall <= 1))  # unit cells: all known
            open_strip = settled[strip] if trust is not None else None  # kept open
            again_b, again_d = self._ask_middles(boxes[strip], depth[strip], key, sim, open_strip)
            guide = None
            if trust is not None:  # guided cells halve towards the prediction
                guide = (np.where(guided, trust, -1)[split], self.mismatch_tables)
            halves = cells.halves(boxes[split], self.key, self.hint_table, guide)
            half_b, half_d = self._wait(halves, np.repeat(depth[split] + 1, 2))
            boxes = np.concatenate([again_b, half_b])
            depth = np.concatenate([again_d, half_d])

    def _ask_middles(
        self,
        boxes: np.ndarray,
        depth: np.ndarray,
        key: np.ndarray,
        sim: np.ndarray,
        settled: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Unresolved strips wait for the middles they ask for (:func:`tasks.cells.strip_middles`,
        at the level of a halving), strips kept open by the prediction (``settled``) for
        theirs (:func:`tasks.cells.guided_middles`); those whose middles are simulated
        already are returned."""
        if not boxes.shape[0]:
            return boxes, depth
        a, m, b = cells.strip_edges(boxes, self.shape[1])
        ask = cells.strip_middles(a, m, b, key, sim)
        if settled is not None and settled.any():
            ask[settled] = self._guided_middles_many(boxes[settled], sim)
        on = np.where(ask, m, np.where(ask[:, ::-1], m[:, ::-1], m))  # a lone middle twice
        return self._wait(boxes, depth, np.concatenate([on, on], axis=1), depth + 1)

    def _settled_many(self, boxes: np.ndarray) -> np.ndarray:
        """:meth:`Refinement._settled` of every cell of ``boxes``."""
        key, sim = self.key.reshape(-1), self.simulated.reshape(-1)
        out = cells.uniform(boxes, key, sim, self.shape[1])
        strip = ~out & cells.strips(boxes)
        if strip.any():
            a, m, b = cells.strip_edges(boxes[strip], self.shape[1])
            out[strip] = cells.resolved_strips(a, m, b, key, sim)
        return out

    def _guided_many(self, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`Refinement._trusted` (the label, -1) and :meth:`Refinement._guided` of every
        cell of ``boxes`` (a prediction is set)."""
        label = self.fields[self.label].reshape(-1)
        trust = cells.trusted(boxes, label, self.predicted.reshape(-1), self.shape[1])
        return trust, cells.guided(boxes, trust, self.mismatch_tables)

    def _guided_middles_many(self, boxes: np.ndarray, sim: np.ndarray) -> np.ndarray:
        """:meth:`Refinement._guided_middles` of the strips ``boxes``, as a ``(k, 2)`` mask
        over their long edges."""
        a, m, b = cells.strip_edges(boxes, self.shape[1])
        label = self.fields[self.label].reshape(-1)
        return cells.guided_middles(a, m, b, label, self.predicted.reshape(-1), sim)

    def _hinted_many(self, boxes: np.ndarray) -> np.ndarray:
        """:meth:`Refinement._hinted` of every cell of ``boxes`` (a hint set is fixed)."""
        return cells.hinted(boxes, self.hint_table, HINT_CELL)

    def _reopened(self) -> tuple[np.ndarray, np.ndarray]:
        """Leaves holding a point of the last results that are no longer settled (removed
        from the leaves, to examine again) and their depths."""
        boxes, depth = self._leaf_boxes(), self._leaf_depth
        none = (np.zeros((0, 4), dtype=np.int64), np.zeros(0, dtype=np.int64))
        if self._last_new is None or not boxes.shape[0]:
            return none
        hit = np.flatnonzero(self._leaves_hit(boxes))
        self._last_new = None
        hit = hit[~self._settled_many(boxes[hit])]
        if not hit.size:
            return none
        keep = np.ones(boxes.shape[0], dtype=bool)
        keep[hit] = False
        self._leaves, self._leaf_depth = boxes[keep], depth[keep]
        return boxes[hit], depth[hit]

    def _leaf_boxes(self) -> np.ndarray:
        if self._leaf_parts:
            parts = [(self._leaves, self._leaf_depth), *self._leaf_parts]
            self._leaves = np.concatenate([b for b, _ in parts])
            self._leaf_depth = np.concatenate([d for _, d in parts])
            self._leaf_parts = []
        return self._leaves
