"""Adaptive regime maps: a dense grid's labels from a few percent of its simulations.

A regime map is three regions and the curves between them; a dense (r, beta)
grid spends almost all of its simulations deep inside the regions. The
refinement here simulates a coarse lattice of the grid (every ``coarse_step``
grid steps along r and beta), then splits every cell whose simulated points
disagree (a different regime, or a different flag: an undetermined code, not
converged) into two halves, level by level, down to cells of one grid
step. A cell whose simulated points all agree is *uniform*: its other points
inherit the label and every other field from the nearest simulated corner and
are marked ``simulated = False``.

Guarantees (in grid steps of the requested resolution):

* a boundary between two simulated neighbours is always resolved to one grid
  step: refinement stops only at cells of one step, at uniform cells, or at
  resolved strips of 1 x 2 steps (:meth:`Refinement._resolved_strip`): long
  edges each uniform (the boundary crosses both short edges between simulated
  neighbours), or each simulated whole or uniform with the neighbour across
  the strip agreeing. An unsimulated middle takes its edge's label, so only a
  feature one step long can hide there. A strip asks for middles instead of
  being split (:meth:`Refinement._strip_middles`).
  Cells are halved along one axis at a time, the one their corners disagree
  across (:meth:`Refinement._split_axes`), about two simulations per grid row a
  boundary crosses;
* a region of one label (or flag) that contains a square of ``coarse_step`` x
  ``coarse_step`` grid steps contains a coarse node, so it is sure to be found,
  and its boundary is then followed cell by cell down to one step. ``coarse_step``
  is therefore the size of the smallest feature the map is sure to find;
* what can be missed: a feature that touches no simulated point, i.e. narrower
  than the cells around it (a strip or island thinner than ``coarse_step`` lying
  between coarse nodes, or a bump of a boundary narrower than the local cell).
  Closed-form boundaries can be passed as a ``hint`` (points to refine around:
  cells holding a hinted point inside, or on an edge longer than
  :data:`HINT_CELL` steps, are split down to :data:`HINT_CELL` steps even when
  uniform, and a cell is cut on the hinted grid line nearest its middle rather
  than at its middle, :func:`tasks.cells.split_at`) but never decide a label;
  with their ``predicted`` labels, a uniform cell whose corners the prediction
  gets right is kept open, halved towards a point it predicts otherwise down to
  one step (:meth:`Refinement._guided_open`), so a feature the closed forms hold
  is found whatever its width (an inferred point takes the predicted label
  wherever the prediction is right at its cell's corners). The verification
  sample (:meth:`Refinement.verification`) estimates the error of the inferred
  labels.

The logic is pure numerics: the classification of a batch of points is injected
(:func:`refine`), or the caller drives the refinement itself, without barriers
(:class:`tasks.stream.StreamRefinement`: ``take`` gives points ready to simulate,
``accept`` takes results of any handed-out points in any order, e.g. as Dask
tasks finish; cells that complete together are examined as arrays,
:mod:`tasks.cells`) or wave by wave (:class:`Refinement`:
:meth:`~Refinement.wave` gives the points of the next level, all of whose results
go to :meth:`~Refinement.accept` before the next wave). Both end at the same
cells, simulated points and labels. No Dask, no files.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from tasks import cells, regimes
from tasks.result import FIELDS, MASS_FIELDS
from tasks.verification import (  # the verification sample, named here too
    VerificationSummary,
    disagreement_upper_bound,
    sample_priority,
    verification_sample,
)

#: Default coarsest spacing, in grid steps: the smallest feature the map is sure to find.
DEFAULT_COARSE_STEP = 16
#: Hinted cells are split, even when uniform, down to this size in grid steps: a
#: feature along a hint at least this wide gets a simulated point, and is then
#: followed to one step like any boundary. Below it only disagreement splits,
#: so a hint far from any boundary costs no simulation at the finest levels
#: (measured on Fig. 10a at 1000 x 500: 1 step 7.5 %, 4 steps 4.6 % of the
#: points simulated, the same agreement with the dense grid). A hinted point on a
#: cell's edge counts only while that edge is longer than this (its corners are
#: simulated): cuts at the hint (:func:`tasks.cells.split_at`) put hinted points
#: on edges.
HINT_CELL = 4
#: Largest batch of ready points :func:`refine` classifies at once without barriers.
DEFAULT_BATCH_POINTS = 256
#: Default verification sample: this fraction of the inferred points ...
DEFAULT_VERIFY_FRACTION = 0.005
#: ... but at least this many (or all the inferred points if there are fewer).
DEFAULT_VERIFY_MIN = 200
#: Fields whose values must agree for a cell to be uniform (the label and its flags);
#: any of them missing from the results is skipped.
KEY_FIELDS: tuple[str, ...] = ("regime", "converged", "start_dependent")

#: Variables an adaptive map adds to those of a grid (:data:`tasks.result.FIELDS`).
ADAPTIVE_FIELDS: dict[str, tuple[str, str]] = {
    "simulated": (
        "bool",
        "the point was simulated (true) or inferred from the nearest simulated corner of "
        "a uniform refinement cell (false)",
    ),
    "verification": (
        "int8",
        "verification sample: 0 not in the sample, 1 inferred label confirmed by "
        "simulation, 2 inferred label contradicted (the simulated values are stored)",
    ),
}
VERIFY_NONE, VERIFY_AGREE, VERIFY_DISAGREE = 0, 1, 2

#: Largest (leaves x new points) comparison done by broadcasting when leaves are rechecked
#: (beyond it a summed-area table of the new points: the refinement of Fig. 4 at 1000 x 500
#: in point lists of 64 replayed in 0.113 s of CPU with 50,000, 0.128 s with 200,000).
_BROADCAST_LIMIT = 50_000

ClassifyBatch = Callable[[np.ndarray, np.ndarray], Mapping[str, np.ndarray]]
"""Classify points given by their (r index, beta index) arrays; return FIELDS arrays."""


def _fill(dtype: str) -> object:
    if dtype == "int8":
        return regimes.NOT_COMPUTED
    return np.nan if dtype.startswith("float") else 0


def coarse_nodes(n: int, step: int) -> np.ndarray:
    """Indices of the coarse lattice along an axis of ``n`` points: every ``step``-th, the last."""
    return np.unique(np.append(np.arange(0, n, step), n - 1))


class Refinement:
    """The state of one adaptive map of shape ``(n_r, n_beta)``, level by level.

    Parameters
    ----------
    shape : (int, int)
        Points along r and along beta of the requested resolution.
    coarse_step : int
        Spacing of the first lattice in grid steps (>= 1; 1 simulates everything).
    hint : bool array of ``shape``, optional
        Points near an expected boundary (e.g. the closed forms): a cell holding
        one is split even when uniform. Never decides a label.
    key_fields : sequence of str
        Fields that must agree within a uniform cell.
    dof : int
        Masses of the per-mass fields of :data:`tasks.result.FIELDS`.
    fields : mapping, optional
        ``{name: (dtype, n)}`` of the fields to keep instead of
        :data:`tasks.result.FIELDS` (``n`` the length of a trailing axis, 0 for
        none: e.g. the per-contact fields of several contacts).
    label : str
        The field the verification sample compares (any integer label).
    predicted : int8 array of ``shape``, optional
        The label the closed forms give every point (:func:`analysis.predict`;
        negative: none). A cell whose four corners share a label it gives them too
        is split, even when uniform, while it gives a point of the cell another
        label (:meth:`_guided_open`); it never decides a label.

    Use: ``while (idx := ref.wave()).size: ref.accept(idx, simulate(idx))``,
    then optionally ``ref.verification()`` / ``ref.accept_verification``, then
    :meth:`result`. Indices are flat (``numpy.ravel_multi_index`` of (i_r, i_beta)).
    """

    def __init__(
        self,
        shape: tuple[int, int],
        coarse_step: int = DEFAULT_COARSE_STEP,
        hint: np.ndarray | None = None,
        key_fields: tuple[str, ...] = KEY_FIELDS,
        dof: int = 1,
        fields: Mapping[str, tuple[str, int]] | None = None,
        label: str = "regime",
        predicted: np.ndarray | None = None,
    ) -> None:
        n_r, n_b = (int(n) for n in shape)
        if n_r < 1 or n_b < 1:
            raise ValueError(f"shape: needs at least one point along r and beta, got {shape}")
        if not isinstance(coarse_step, int | np.integer) or coarse_step < 1:
            raise ValueError(f"coarse_step: must be an integer >= 1, got {coarse_step!r}")
        self.shape = (n_r, n_b)
        self.coarse_step = int(coarse_step)
        self.key_fields = tuple(key_fields)
        self.label = label
        if fields is None:  # per-mass fields have a trailing mass axis
            fields = {k: (dt, dof if k in MASS_FIELDS else 0) for k, (dt, _) in FIELDS.items()}
        self.fields = {
            k: np.full((*self.shape, n) if n else self.shape, _fill(dt), dtype=dt)
            for k, (dt, n) in fields.items()
        }
        self.simulated = np.zeros(self.shape, dtype=bool)
        self.set_hint(hint, predicted)
        self.key = np.zeros(self.shape, dtype=np.int64)
        self.verification_flag = np.zeros(self.shape, dtype=np.int8)
        self.levels: list[int] = []  # points simulated per wave
        ir = coarse_nodes(n_r, self.coarse_step)
        ib = coarse_nodes(n_b, self.coarse_step)
        # cells between consecutive nodes; a single point along an axis is a cell of width 0
        er = ir if n_r > 1 else np.array([0, 0])
        eb = ib if n_b > 1 else np.array([0, 0])
        self._active = [
            (int(a), int(b), int(c), int(d))
            for a, b in zip(er[:-1], er[1:], strict=True)
            for c, d in zip(eb[:-1], eb[1:], strict=True)
        ]
        self._leaves = np.zeros((0, 4), dtype=np.int64)  # uniform cells (i0, i1, j0, j1)
        self._leaves_new: list[tuple[int, int, int, int]] = []  # not yet in _leaves
        self._first = np.ravel_multi_index(np.meshgrid(ir, ib, indexing="ij"), self.shape).ravel()
        self._last_new: tuple[np.ndarray, np.ndarray] | None = None
        self._sample: np.ndarray | None = None
        self._below: dict[tuple[float, int], np.ndarray] = {}  # presample
        self._filled = False

    def set_hint(self, hint: np.ndarray | None, predicted: np.ndarray | None = None) -> None:
        """Set the hint and the prediction (see the class notes). The first points (the
        coarse lattice) do not depend on them, so they may come after them, but before
        any result arrives."""
        if self.simulated.any():
            raise ValueError("hint: must be set before the first results arrive")
        self.hint = None if hint is None else np.asarray(hint, dtype=bool)
        self.predicted = None if predicted is None else np.asarray(predicted, dtype=np.int8)
        for name in ("hint", "predicted"):
            if (a := getattr(self, name)) is not None and a.shape != self.shape:
                raise ValueError(f"{name}: shape {a.shape} differs from the map's {self.shape}")
        self._hint_table: np.ndarray | None = None
        self._mismatch_table: np.ndarray | None = None

    @property
    def mismatch_tables(self) -> np.ndarray | None:
        """The prediction's :func:`tasks.cells.mismatch_tables`, None without one; made at
        first use."""
        if self.predicted is not None and self._mismatch_table is None:
            self._mismatch_table = cells.mismatch_tables(self.predicted)
        return self._mismatch_table

    @property
    def hint_table(self) -> np.ndarray | None:
        """The hint's summed-area table (:func:`tasks.cells.summed_table`), None without a
        hint; made at first use."""
        if self.hint is not None and self._hint_table is None:
            self._hint_table = cells.summed_table(self.hint)
        return self._hint_table

    # ------------------------------------------------------------ waves
    @property
    def n_points(self) -> int:
        return self.shape[0] * self.shape[1]

    def wave(self) -> np.ndarray:
        """Flat indices of the points to simulate next (sorted); empty when refinement is done."""
        if self._first is not None:
            first, self._first = np.sort(self._first), None
            return first
        while True:
            self._reopen_leaves()
            if not self._active:
                return np.zeros(0, dtype=np.int64)
            new: list[tuple[int, int]] = []
            children: list[tuple[int, int, int, int]] = []
            for box in self._active:
                if self._settled(box) and not self._hinted(box) and not self._guided_open(box):
                    self._leaves_new.append(box)
                    continue
                i0, i1, j0, j1 = box
                if i1 - i0 <= 1 and j1 - j0 <= 1:
                    continue  # every point of the cell is a simulated corner
                if self._strip_points(box):  # a strip asks for middles, is not split
                    children.append(box)
                    new.extend(self._strip_middles(box))
                    continue
                for a, b, c, d in self._children(box):
                    children.append((a, b, c, d))
                    for p in ((a, c), (a, d), (b, c), (b, d)):
                        if not self.simulated[p]:
                            new.append(p)
            self._active = children
            self._last_new = None
            if new:
                idx = np.unique(np.ravel_multi_index(tuple(np.array(new).T), self.shape))
                return idx.astype(np.int64)

    def level_sizes(self) -> list[int]:
        """Points simulated per wave (the verification sample excluded)."""
        return list(self.levels)

    def _children(self, box: tuple[int, int, int, int]) -> list[tuple[int, int, int, int]]:
        """The halves of a cell along :meth:`_split_axes`, cut at its middle or, with a
        hint, at the hinted grid line nearest the middle (:func:`tasks.cells.split_at`)."""
        i0, i1, j0, j1 = box
        split_r, split_b = self._split_axes(box)
        table, layer = self.hint_table, None
        if (trust := self._trusted(box)) >= 0 and self._guided(box):  # towards the prediction
            table, layer = self.mismatch_tables, np.array([trust])
        at = int(cells.split_at(np.array([box]), np.array([split_r]), table, layer)[0])
        im = at if split_r else None
        jm = at if split_b else None
        rs = [(i0, im), (im, i1)] if im is not None else [(i0, i1)]
        bs = [(j0, jm), (jm, j1)] if jm is not None else [(j0, j1)]
        return [(a, b, c, d) for a, b in rs for c, d in bs]

    def _split_axes(self, box: tuple[int, int, int, int]) -> tuple[bool, bool]:
        """Which axis to halve a cell along: one axis at a time, across the disagreement.

        A boundary crossing the cell between its left and right corners (labels
        change along r) is followed by halving along r only, down to one step,
        then along beta: about two simulations per grid row the boundary crosses,
        instead of the five of a split into four at every level. A cell whose
        corners disagree along both axes (a boundary cutting a corner, or a
        diagonal one), or agree (refined for a disagreeing inner point or a
        hint), is halved along its longer axis (r if square): two new points
        instead of five, and only the half the boundary or the hint lies in is
        halved again. The choice depends on the cell's corners only, so it does
        not depend on the order in which points arrive.
        """
        i0, i1, j0, j1 = box
        if self._guided(box):  # across a line holding a point predicted otherwise
            trust = np.array([self._trusted(box)])
            r = bool(cells.guided_axes(np.array([box]), trust, self.mismatch_tables)[0])
            return r, not r
        k = self.key
        along_r = k[i0, j0] != k[i1, j0] or k[i0, j1] != k[i1, j1]
        along_b = k[i0, j0] != k[i0, j1] or k[i1, j0] != k[i1, j1]
        wide, tall = i1 - i0, j1 - j0
        if along_r == along_b:  # both or neither: the longer axis
            along_r = wide >= tall
        split_r = wide > 1 and (along_r or tall <= 1)
        return split_r, tall > 1 and not split_r

    def accept(self, idx: np.ndarray, results: Mapping[str, np.ndarray]) -> None:
        """Store the simulated fields of the points ``idx`` (flat indices)."""
        idx = np.asarray(idx, dtype=np.int64).ravel()
        ij = np.unravel_index(idx, self.shape)
        for name, arr in self.fields.items():
            arr[ij] = np.asarray(results[name]).reshape(idx.size, *arr.shape[2:])
        self.key[ij] = self._key_of(results, idx.size)
        self.simulated[ij] = True
        self._last_new = ij
        self._filled = False
        self.levels.append(int(idx.size))

    def _key_of(self, results: Mapping[str, np.ndarray], n: int) -> np.ndarray:
        key = np.zeros(n, dtype=np.int64)
        for name in self.key_fields:
            if name in results:
                key = key * 1024 + (np.asarray(results[name]).ravel().astype(np.int64) + 512)
        return key

    def _uniform(self, box: tuple[int, int, int, int]) -> bool:
        i0, i1, j0, j1 = box
        sl = (slice(i0, i1 + 1), slice(j0, j1 + 1))
        keys = self.key[sl][self.simulated[sl]]
        return bool(keys.size == 0 or (keys == keys[0]).all())

    def _settled(self, box: tuple[int, int, int, int]) -> bool:
        """Uniform, or a boundary already resolved to one step (:meth:`_resolved_strip`)."""
        return self._uniform(box) or self._resolved_strip(box)

    @staticmethod
    def _strip_points(
        box: tuple[int, int, int, int],
    ) -> tuple[tuple[tuple[int, int], tuple[int, int], tuple[int, int]], ...]:
        """The two long edges of a 1 x 2 strip as (end, middle, end) points; none otherwise."""
        i0, i1, j0, j1 = box
        if (i1 - i0, j1 - j0) == (1, 2):
            return tuple(((i, j0), (i, j0 + 1), (i, j1)) for i in (i0, i1))
        if (i1 - i0, j1 - j0) == (2, 1):
            return tuple(((i0, j), (i0 + 1, j), (i1, j)) for j in (j0, j1))
        return ()

    def _strip_middles(self, box: tuple[int, int, int, int]) -> list[tuple[int, int]]:
        """The middles a strip that is not resolved (:meth:`_resolved_strip`) asks for:
        those of its long edges whose ends disagree; once they are simulated, those of
        its uniform edges whose neighbour across the strip disagrees with them."""
        k, sim = self.key, self.simulated
        edges = self._strip_points(box)
        if self.predicted is not None and self._settled(box):  # kept open (_guided_open)
            return self._guided_middles(box)
        ask = [m for a, m, b in edges if k[a] != k[b] and not sim[m]]
        if ask:
            return ask
        return [
            m
            for (a, m, _), (_, m_other, _) in (edges, edges[::-1])
            if not sim[m] and not (sim[m_other] and k[m_other] == k[a])
        ]

    def _resolved_strip(self, box: tuple[int, int, int, int]) -> bool:
        """A cell one step wide and two long where every point left unsimulated is sure of
        its label up to a feature one step long.

        Either (a) its two long edges are each uniform: the boundary crosses both
        short edges between simulated neighbours one step apart, i.e. it is
        resolved to one step at both ends, and the middle point of each long
        edge takes the label its edge's two ends share (as any point of a
        uniform cell does); or (b) each long edge is simulated whole, or has
        ends that agree and a simulated neighbour across the strip (the other
        edge's middle) with their label: its middle then takes the label of
        three simulated neighbours, and every pair of neighbours with different
        labels in the strip is simulated on both sides. A strip that is neither
        asks for middles (:meth:`_strip_middles`) instead of being split: those
        of the long edges whose ends disagree, then, if the boundary passes
        next to a uniform edge's middle, that middle too. Only a feature one
        step long could hide there.
        """
        edges = self._strip_points(box)
        if not edges:
            return False
        k, sim = self.key, self.simulated
        uniform = True  # (a)
        for a, m, b in edges:
            if k[a] != k[b] or (sim[m] and k[m] != k[a]):
                uniform = False
        if uniform:
            return True
        for (a, m, b), (_, m_other, _) in (edges, edges[::-1]):  # (b)
            if sim[m]:
                continue
            if k[a] != k[b] or not sim[m_other] or k[m_other] != k[a]:
                return False
        return True

    def _hinted(self, box: tuple[int, int, int, int]) -> bool:
        """The cell holds a hinted point off its edges (along an axis of more than one
        step) and is larger than :data:`HINT_CELL` steps. A hinted point on its edge is
        on a line a cut put there (:func:`tasks.cells.split_at`) or is held inside the
        cell beside it (the closed-form hint marks both grid points around its curve)."""
        if self.hint is None:
            return False
        i0, i1, j0, j1 = box
        if i1 - i0 <= HINT_CELL and j1 - j0 <= HINT_CELL:
            return False
        h = self.hint
        a, b = (i0 + 1, i1 - 1) if i1 - i0 > 1 else (i0, i1)
        c, d = (j0 + 1, j1 - 1) if j1 - j0 > 1 else (j0, j1)
        inside = h[a : b + 1, c : d + 1].any()
        along_r = i1 - i0 > HINT_CELL and h[i0 + 1 : i1, [j0, j1]].any()
        along_b = j1 - j0 > HINT_CELL and h[[i0, i1], j0 + 1 : j1].any()
        return bool(inside or along_r or along_b)

    def _trusted(self, box: tuple[int, int, int, int]) -> int:
        """The label the cell's four corners share and the prediction gives them too (a
        label of the prediction, :data:`tasks.cells.PREDICTED_LABELS`), else -1."""
        if self.predicted is None:
            return -1
        i0, i1, j0, j1 = box
        lab = self.fields[self.label]
        first = int(lab[i0, j0])
        for p in ((i0, j0), (i0, j1), (i1, j0), (i1, j1)):
            if lab[p] != first or self.predicted[p] != first:
                return -1
        return first if 0 <= first < cells.PREDICTED_LABELS else -1

    def _mismatch(self, box: tuple[int, int, int, int], label: int) -> np.ndarray:
        """Which points of the cell the prediction gives another label than ``label``."""
        i0, i1, j0, j1 = box
        p = self.predicted[i0 : i1 + 1, j0 : j1 + 1]
        return (p >= 0) & (p != label)

    def _guided(self, box: tuple[int, int, int, int]) -> bool:
        """Its corners trusted (:meth:`_trusted`), the cell holds a point (no corner) the
        prediction gives another label: it is halved towards it (:meth:`_split_axes`,
        :meth:`_children`). Depends on the cell, its corners and the prediction only."""
        trust = self._trusted(box)
        return trust >= 0 and bool(self._mismatch(box, trust).any())

    def _guided_middles(self, box: tuple[int, int, int, int]) -> list[tuple[int, int]]:
        """The middles of a strip's long edges not simulated yet that the prediction gives
        another label than the one the edge's ends share and it gives them too (an
        inferred middle takes its edge's label, :meth:`_resolved_strip`)."""
        if self.predicted is None:
            return []
        lab, p, sim = self.fields[self.label], self.predicted, self.simulated
        out = []
        for a, m, b in self._strip_points(box):
            la = int(lab[a])
            trusted = lab[b] == la == p[a] == p[b] and 0 <= la < cells.PREDICTED_LABELS
            if trusted and 0 <= p[m] != la and not sim[m]:
                out.append(m)
        return out

    def _guided_open(self, box: tuple[int, int, int, int]) -> bool:
        """The prediction keeps a settled cell open: a cell :meth:`_guided` (split down to
        one step), or a strip with a middle :meth:`_guided_middles` asks for. Hints never
        decide a label: this only asks for simulations."""
        if self._strip_points(box):
            return bool(self._guided_middles(box))
        return self._guided(box)

    def _reopen_leaves(self) -> None:
        """Leaves (uniform cells) that received new simulated points disagreeing with them are
        active again (a neighbour's refinement put points on their edges)."""
        boxes = self._leaf_boxes()
        if self._last_new is None or not boxes.shape[0]:
            return
        count = self._leaves_hit(boxes)
        reopen = np.zeros(boxes.shape[0], dtype=bool)
        for n in np.flatnonzero(count):
            box = tuple(int(v) for v in boxes[n])
            if not self._settled(box):
                self._active.append(box)
                reopen[n] = True
        self._leaves = boxes[~reopen]
        self._last_new = None

    def _leaves_hit(self, boxes: np.ndarray) -> np.ndarray:
        """Which of the cells ``boxes`` hold a point of the last accepted results (nonzero)."""
        pi, pj = self._last_new
        if boxes.shape[0] * pi.size <= _BROADCAST_LIMIT:  # few new points: compare directly
            return cells.holding(boxes, pi, pj)
        # many: a summed-area table of the new points, on their own rows and columns
        ui, ci = np.unique(pi, return_inverse=True)
        uj, cj = np.unique(pj, return_inverse=True)
        s = np.zeros((ui.size + 1, uj.size + 1), dtype=np.int32)
        s[1 + ci, 1 + cj] = 1
        s = s.cumsum(0, dtype=np.int32).cumsum(1, dtype=np.int32)
        i0, i1, j0, j1 = boxes.T  # a box's rows [a, b) and columns [c, d) of the table
        a, b = np.searchsorted(ui, i0, "left"), np.searchsorted(ui, i1, "right")
        c, d = np.searchsorted(uj, j0, "left"), np.searchsorted(uj, j1, "right")
        return s[b, d] - s[a, d] - s[b, c] + s[a, c]

    def _leaf_boxes(self) -> np.ndarray:
        if self._leaves_new:
            new = np.array(self._leaves_new, dtype=np.int64).reshape(-1, 4)
            self._leaves = np.concatenate([self._leaves, new])
            self._leaves_new = []
        return self._leaves

    # ------------------------------------------------------------ verification
    def verification(
        self,
        fraction: float = DEFAULT_VERIFY_FRACTION,
        minimum: int = DEFAULT_VERIFY_MIN,
        seed: int = 0,
    ) -> np.ndarray:
        """A seeded random sample of inferred points (flat indices) to simulate as a check.

        Call after refinement is done (:meth:`wave` returned nothing). Each
        inferred point is in the sample with probability ``fraction``, and the
        sample holds at least ``minimum`` points, at most all of the inferred ones
        (:func:`verification_sample`).
        """
        sim = self.simulated.ravel()
        n_inferred = int(sim.size - np.count_nonzero(sim))
        below = self._below.get((float(fraction), int(seed)))
        if below is not None:  # the points below the fraction, drawn before (presample)
            below = below[~sim[below]]
        if below is None or below.size < min(n_inferred, int(minimum)):
            below = verification_sample(np.flatnonzero(~sim), fraction, minimum, seed)
        self._sample = below
        self._inferred_before = n_inferred
        return self._sample

    def presample(self, fraction: float = DEFAULT_VERIFY_FRACTION, seed: int = 0) -> None:
        """Draw, before refinement ends, every point of the plane whose priority
        (:func:`sample_priority`) is below ``fraction``: :meth:`verification` then keeps
        those still inferred (the same sample, :func:`verification_sample`, unless
        fewer than its minimum are: then it draws as without) instead of hashing every
        inferred point after the refinement (Fig. 4 at 1000 x 500: 10-40 ms of the
        client between the last tile and the sample's point lists)."""
        u = sample_priority(np.arange(self.n_points, dtype=np.int64), seed)
        self._below[(float(fraction), int(seed))] = np.flatnonzero(u < fraction)

    def accept_verification(
        self, idx: np.ndarray, results: Mapping[str, np.ndarray]
    ) -> VerificationSummary:
        """Compare the sample's simulated regimes with the inferred ones; keep the simulated
        values (the sample's points count as simulated from then on)."""
        idx = np.asarray(idx, dtype=np.int64).ravel()
        self._fill_inferred()
        ij = np.unravel_index(idx, self.shape)
        inferred = self.fields[self.label][ij].copy()
        simulated = np.asarray(results[self.label]).ravel()
        agree = inferred == simulated
        for name, arr in self.fields.items():
            arr[ij] = np.asarray(results[name]).reshape(idx.size, *arr.shape[2:])
        self.key[ij] = self._key_of(results, idx.size)
        self.simulated[ij] = True
        self.verification_flag[ij] = np.where(agree, VERIFY_AGREE, VERIFY_DISAGREE)
        n_agree = int(agree.sum())
        return VerificationSummary(
            inferred=getattr(self, "_inferred_before", int(idx.size)),
            sampled=int(idx.size),
            agree=n_agree,
            upper_95=disagreement_upper_bound(int(idx.size), int(idx.size) - n_agree),
        )

    # ------------------------------------------------------------ result
    def _fill_inferred(self) -> None:
        """Give every point not simulated the fields of the nearest corner of its uniform cell."""
        todo = ~self.simulated
        if self._filled or not todo.any():
            return
        boxes = self._leaf_boxes()
        boxes = boxes[np.lexsort(boxes.T[::-1])]  # one order whatever the arrival order
        dst = np.flatnonzero(todo)  # from the nearer corner along each axis of its cell
        src = cells.nearest_corner_sources(boxes, dst, self.shape)
        if (src[0] < 0).any():  # cannot happen: uniform cells and unit cells tile the map
            raise RuntimeError("adaptive map: a point lies in no refinement cell")
        n = self.n_points
        take = np.arange(n)  # every point's source: itself, or its corner
        take[dst] = src[0] * self.shape[1] + src[1]
        for arr in (*self.fields.values(), self.key):  # one whole take per field: a quarter
            flat = arr.reshape(n, *arr.shape[2:])  # less CPU than a scatter to ``dst``
            flat[...] = flat[take]
        self._filled = True

    def result(self) -> dict[str, np.ndarray]:
        """Every field of :data:`tasks.result.FIELDS` at every point, plus ``simulated`` and
        ``verification`` (:data:`ADAPTIVE_FIELDS`)."""
        self._fill_inferred()
        out = dict(self.fields)
        out["simulated"] = self.simulated.copy()
        out["verification"] = self.verification_flag.copy()
        return out


@dataclass
class AdaptiveResult:
    """An adaptive map: ``fields`` as a dense grid would give them, plus bookkeeping."""

    fields: dict[str, np.ndarray]  #: FIELDS + ``simulated`` + ``verification``, shape (n_r, n_beta)
    levels: list[int]  #: points per refinement level (:meth:`Refinement.level_sizes`)
    verification: VerificationSummary | None

    @property
    def simulated_points(self) -> int:
        """Points simulated, the verification sample included."""
        return int(self.fields["simulated"].sum())

    @property
    def simulated_fraction(self) -> float:
        return self.simulated_points / self.fields["simulated"].size


def refine(
    shape: tuple[int, int],
    classify_batch: ClassifyBatch,
    coarse_step: int = DEFAULT_COARSE_STEP,
    hint: np.ndarray | None = None,
    verify_fraction: float = DEFAULT_VERIFY_FRACTION,
    verify_min: int = DEFAULT_VERIFY_MIN,
    seed: int = 0,
    key_fields: tuple[str, ...] = KEY_FIELDS,
    dof: int = 1,
    barriers: bool = False,
    batch_points: int = DEFAULT_BATCH_POINTS,
    predicted: np.ndarray | None = None,
) -> AdaptiveResult:
    """Run a whole refinement with an injected batch classifier.

    ``classify_batch(i_r, i_beta)`` gets integer index arrays and returns one
    array per field of :data:`tasks.result.FIELDS` (per-mass fields with a
    trailing axis of ``dof`` masses). ``verify_fraction = 0`` and
    ``verify_min = 0`` skip the verification sample. ``barriers = True`` runs
    the wave refinement (:meth:`Refinement.wave`, one batch per level), else
    :class:`tasks.stream.StreamRefinement` in batches of at most ``batch_points``; the
    labels are the same. ``predicted``: see :class:`Refinement`.
    """
    if barriers:
        ref = Refinement(shape, coarse_step, hint, key_fields, dof, predicted=predicted)
        while (idx := ref.wave()).size:
            ref.accept(idx, classify_batch(*np.unravel_index(idx, ref.shape)))
    else:
        from tasks.stream import StreamRefinement

        ref = StreamRefinement(shape, coarse_step, hint, key_fields, dof, predicted=predicted)
        while (idx := ref.take(batch_points)).size:
            ref.accept(idx, classify_batch(*np.unravel_index(idx, ref.shape)))
    summary = None
    if verify_fraction > 0 or verify_min > 0:
        sample = ref.verification(verify_fraction, verify_min, seed)
        if sample.size:
            res = classify_batch(*np.unravel_index(sample, ref.shape))
        else:
            res = {k: np.zeros(0, dtype=dt) for k, (dt, _) in FIELDS.items()}
        summary = ref.accept_verification(sample, res)
    return AdaptiveResult(ref.result(), ref.level_sizes(), summary)


def adaptive_map(
    scene,
    r: np.ndarray,
    beta: np.ndarray,
    coarse_step: int = DEFAULT_COARSE_STEP,
    hint: np.ndarray | None = None,
    verify_fraction: float = DEFAULT_VERIFY_FRACTION,
    verify_min: int = DEFAULT_VERIFY_MIN,
    seed: int = 0,
    classify_fn: Callable | None = None,
    fidelity: str = "balanced",
    barriers: bool = False,
    predicted: np.ndarray | None = None,
    **settings: object,
) -> AdaptiveResult:
    """The regime map of ``scene`` on the grid ``r`` x ``beta``, simulated adaptively.

    Parameters
    ----------
    scene : tasks.Scene
    r, beta : 1-D arrays
        The axes of the requested grid (the result has shape ``(r.size, beta.size)``).
    coarse_step : int
        Spacing of the first lattice, in grid steps: the smallest feature the
        map is sure to find (see the module notes).
    hint : bool array, optional
        Points near expected boundaries, e.g. ``analysis.adaptive.closed_form_hint``.
    verify_fraction, verify_min, seed
        The verification sample of inferred points.
    classify_fn : callable, optional
        ``classify_fn(scene, r, beta, fidelity=..., **settings)`` returning an
        object with the FIELDS as attributes; default :func:`tasks.classify`.
    barriers : bool
        Refine wave by wave (the old path, kept for comparison) instead of
        point list by point list (:class:`tasks.stream.StreamRefinement`); same labels.
    predicted : int8 array, optional
        The closed forms' label of every point (see :class:`Refinement`).
    """
    if classify_fn is None:
        from tasks.classifier import classify as classify_fn
    r = np.asarray(r, dtype=float)
    beta = np.asarray(beta, dtype=float)

    skipped: set[str] = set()  # fields not computed (design quantities unless asked)

    def batch(i: np.ndarray, j: np.ndarray) -> dict[str, np.ndarray]:
        res = classify_fn(scene, r[i], beta[j], fidelity=fidelity, **settings)
        out = {}
        for k in FIELDS:
            if (v := getattr(res, k)) is None:  # a placeholder, dropped from the result
                skipped.add(k)
                v = np.full((i.size, scene.dof) if k in MASS_FIELDS else i.size, np.nan)
            out[k] = np.asarray(v)
        return out

    result = refine(
        (r.size, beta.size),
        batch,
        coarse_step,
        hint,
        verify_fraction,
        verify_min,
        seed,
        dof=scene.dof,
        barriers=barriers,
        predicted=predicted,
    )
    for k in skipped:  # absent, never NaN-filled
        del result.fields[k]
    return result
