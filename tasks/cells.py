"""Refinement cells examined many at a time: numpy over whole waves of cells.

The adaptive map (:mod:`tasks.adaptive`) examines cells ``(i0, i1, j0, j1)`` (grid
indices of their corners along r and beta, both ends included) as their
corners arrive. :class:`tasks.adaptive.Refinement` decides cell by cell; these
functions take the same decisions for an array of cells at once (shape
``(k, 4)``, int64), so that the client's share of an adaptive study does not
grow with a Python loop per cell. ``key`` is the flat array of the points'
key (regime and flags, :meth:`tasks.adaptive.Refinement._key_of`) and ``sim``
the flat array of simulated points; flat indices are ``i * n_beta + j``.

Each function is the vectorised form of one per-cell method of
:class:`~tasks.adaptive.Refinement` (named in its docstring), and
``tests/test_adaptive_cells.py`` checks them against those methods on random
cells and keys. No Dask, no files.
"""

from __future__ import annotations

import numpy as np
from numba import njit


def box_points(boxes: np.ndarray, n_b: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every point of every cell, cell after cell (rows of r, then beta).

    Returns
    -------
    start : (k,) int64
        Offset of each cell's first point in ``flat``.
    owner : (n,) int64
        The cell of each point (nondecreasing).
    flat : (n,) int64
        Flat indices of the points.
    """
    i0, i1, j0, j1 = boxes.T
    w = j1 - j0 + 1
    area = (i1 - i0 + 1) * w
    start = np.cumsum(area) - area
    owner = np.repeat(np.arange(boxes.shape[0]), area)
    t = np.arange(int(area.sum()), dtype=np.int64) - start[owner]
    wo = w[owner]
    return start, owner, (i0[owner] + t // wo) * n_b + j0[owner] + t % wo


def uniform(boxes: np.ndarray, key: np.ndarray, sim: np.ndarray, n_b: int) -> np.ndarray:
    """Cells whose simulated points all share one key (or have none):
    :meth:`~tasks.adaptive.Refinement._uniform`."""
    if not boxes.shape[0]:
        return np.zeros(0, dtype=bool)
    boxes = np.ascontiguousarray(boxes, dtype=np.int64)
    return _uniform(boxes, np.asarray(key, dtype=np.int64), np.asarray(sim, dtype=np.bool_), n_b)


@njit(cache=True, nogil=True)
def _uniform(boxes, key, sim, n_b):  # pragma: no cover - compiled
    """:func:`uniform`, cell by cell, each read until its first disagreeing point (the
    cells of a round hold up to (coarse step + 1)^2 points each: a numpy pass over all
    of them cost a tile about as much as the rest of its round's refinement)."""
    out = np.ones(boxes.shape[0], dtype=np.bool_)
    for c in range(boxes.shape[0]):
        seen = False
        first = 0
        for i in range(boxes[c, 0], boxes[c, 1] + 1):
            for p in range(i * n_b + boxes[c, 2], i * n_b + boxes[c, 3] + 1):
                if sim[p]:
                    if not seen:
                        seen, first = True, key[p]
                    elif key[p] != first:
                        out[c] = False
                        break
            if not out[c]:
                break
    return out


def strips(boxes: np.ndarray) -> np.ndarray:
    """Cells one step wide and two long (either way): the strips of
    :meth:`~tasks.adaptive.Refinement._strip_points`."""
    wide, tall = boxes[:, 1] - boxes[:, 0], boxes[:, 3] - boxes[:, 2]
    return ((wide == 1) & (tall == 2)) | ((wide == 2) & (tall == 1))


def strip_edges(boxes: np.ndarray, n_b: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The two long edges of strips as (end, middle, end) flat indices, each ``(k, 2)``
    (edge 0 at ``i0`` or ``j0``): :meth:`~tasks.adaptive.Refinement._strip_points`."""
    i0, i1, j0, j1 = (c[:, None] for c in boxes.T)
    along_b = (j1 - j0) == 2  # a 1 x 2 strip: long edges at i0 and i1, along beta
    edge = np.array([[0, 1]])
    i = np.where(along_b, np.where(edge == 0, i0, i1), i0)
    j = np.where(along_b, j0, np.where(edge == 0, j0, j1))
    di, dj = np.where(along_b, 0, 1), np.where(along_b, 1, 0)
    a = i * n_b + j
    return a, a + di * n_b + dj, a + 2 * (di * n_b + dj)


def resolved_strips(
    a: np.ndarray, m: np.ndarray, b: np.ndarray, key: np.ndarray, sim: np.ndarray
) -> np.ndarray:
    """Strips (their :func:`strip_edges`) resolved to one step:
    :meth:`~tasks.adaptive.Refinement._resolved_strip`, (a) or (b)."""
    ka, kb, km = key[a], key[b], key[m]
    sm = sim[m]
    edge_uniform = (ka == kb) & ~(sm & (km != ka))
    across = sim[m[:, ::-1]] & (key[m[:, ::-1]] == ka)  # the other edge's middle agrees
    edge_known = sm | ((ka == kb) & across)
    return edge_uniform.all(axis=1) | edge_known.all(axis=1)


def strip_middles(
    a: np.ndarray, m: np.ndarray, b: np.ndarray, key: np.ndarray, sim: np.ndarray
) -> np.ndarray:
    """Which middles (``(k, 2)`` mask over the edges) unresolved strips ask for:
    :meth:`~tasks.adaptive.Refinement._strip_middles`."""
    sm = sim[m]
    first = (key[a] != key[b]) & ~sm
    across = sim[m[:, ::-1]] & (key[m[:, ::-1]] == key[a])
    second = ~sm & ~across
    return np.where(first.any(axis=1)[:, None], first, second)


def guided_middles(
    a: np.ndarray,
    m: np.ndarray,
    b: np.ndarray,
    label: np.ndarray,
    predicted: np.ndarray,
    sim: np.ndarray,
) -> np.ndarray:
    """Which middles (``(k, 2)`` mask over the long edges of strips, :func:`strip_edges`)
    a settled strip asks for: those not simulated yet that the prediction gives another
    label than the one the edge's two ends share and it gives them too
    (:meth:`~tasks.adaptive.Refinement._guided_middles`)."""
    la, pm = label[a], predicted[m]
    trust = (la == label[b]) & (predicted[a] == la) & (predicted[b] == la)
    trust &= (la >= 0) & (la < PREDICTED_LABELS)
    return trust & (pm >= 0) & (pm != la) & ~sim[m]


def halves(
    boxes: np.ndarray,
    key2d: np.ndarray,
    hint_table: np.ndarray | None = None,
    guide: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """The two halves of each cell (``(2k, 4)``: both halves of cell 0, then of cell 1,
    ...), split along one axis as :meth:`~tasks.adaptive.Refinement._split_axes` and
    :meth:`~tasks.adaptive.Refinement._children` do, at :func:`split_at` (the
    middle, or the hinted line nearest it when ``hint_table``, the hint's
    :func:`summed_table`, is given). ``guide``: ``(trust, tables)``, the label of each
    guided cell (:func:`guided`; -1 for the others) and the :func:`mismatch_tables`:
    a guided cell is halved along :func:`guided_axes`, on the line nearest its middle
    that holds a point the prediction gives another label. Cells must not be unit
    cells."""
    i0, i1, j0, j1 = boxes.T
    along_r = (key2d[i0, j0] != key2d[i1, j0]) | (key2d[i0, j1] != key2d[i1, j1])
    along_b = (key2d[i0, j0] != key2d[i0, j1]) | (key2d[i1, j0] != key2d[i1, j1])
    wide, tall = i1 - i0, j1 - j0
    along_r = np.where(along_r == along_b, wide >= tall, along_r)
    split_r = (wide > 1) & (along_r | (tall <= 1))
    g = np.zeros(boxes.shape[0], dtype=bool) if guide is None else guide[0] >= 0
    if g.any():
        trust, tables = guide[0][g], guide[1]
        split_r[g] = guided_axes(boxes[g], trust, tables)
    at = split_at(boxes, split_r, hint_table)
    if g.any():
        at[g] = split_at(boxes[g], split_r[g], tables, trust)
    im, jm = np.where(split_r, at, i0), np.where(split_r, j0, at)
    first = np.stack([i0, np.where(split_r, im, i1), j0, np.where(split_r, j1, jm)], axis=1)
    second = np.stack([np.where(split_r, im, i0), i1, np.where(split_r, j0, jm), j1], axis=1)
    return np.stack([first, second], axis=1).reshape(-1, 4)


def split_at(
    boxes: np.ndarray,
    split_r: np.ndarray,
    hint_table: np.ndarray | None = None,
    layer: np.ndarray | None = None,
) -> np.ndarray:
    """Where each cell is cut across the axis it is split along (r where ``split_r``,
    else beta): its middle, or, when a hint is given (its :func:`summed_table`), the
    grid line across the cell nearest the middle that holds a hinted point, strictly
    inside the cell (the lower one of two as near).

    A hint that follows a boundary (the closed forms) then puts the cut on the
    boundary at once: the cell that holds the boundary is one or two steps
    across after one or two cuts instead of after halvings down to it, and
    the part beside it, uniform, holds the hinted points on its edge only,
    where they split it (:func:`hinted`) only while that edge is longer than
    :data:`tasks.adaptive.HINT_CELL`. Labels still come from simulated points
    only: a cut decides where corners go, never a label. With ``layer``,
    ``hint_table`` is a stack of tables (:func:`mismatch_tables`) and each cell
    looks in its layer's.
    """
    i0, i1, j0, j1 = boxes.T
    lo, hi = np.where(split_r, i0, j0), np.where(split_r, i1, j1)
    mid = (lo + hi) // 2
    if hint_table is None or not boxes.shape[0]:
        return mid
    r = split_r
    inside = np.stack(  # the lines strictly inside, across the whole cell
        [np.where(r, i0 + 1, i0), np.where(r, i1 - 1, i1),
         np.where(r, j0, j0 + 1), np.where(r, j1, j1 - 1)], axis=1
    )  # fmt: skip
    todo = np.flatnonzero(count_in(hint_table, inside, layer) > 0)  # a hinted line to find
    if not todo.size:
        return mid
    # candidate lines outwards from the middle: mid, mid - 1, mid + 1, mid - 2, ...
    half = int((hi[todo] - lo[todo]).max()) // 2 + 1
    step = np.arange(2 * half) // 2 * np.where(np.arange(2 * half) % 2, 1, -1)
    p = mid[todo, None] + step[None, :]
    t = np.broadcast_to(todo[:, None], p.shape)
    ok = (p > lo[t]) & (p < hi[t])
    p = np.where(ok, p, mid[t])  # an index inside the grid; masked out below
    rr, o0, o1 = r[t], np.where(r, j0, i0)[t], np.where(r, j1, i1)[t]
    lines = np.stack(
        [np.where(rr, p, o0), np.where(rr, p, o1), np.where(rr, o0, p), np.where(rr, o1, p)],
        axis=-1,
    )
    at_layer = None if layer is None else layer[t].reshape(-1)
    found = ok & (count_in(hint_table, lines.reshape(-1, 4), at_layer).reshape(p.shape) > 0)
    at = mid.copy()
    at[todo] = p[np.arange(todo.size), found.argmax(axis=1)]  # the first found (one is)
    return at


#: The labels a prediction gives (:data:`tasks.regimes.NO_MOTION`, ``STICK_SLIP``,
#: ``CONTINUOUS``: the codes of :func:`analysis.predict`); a negative code predicts nothing.
PREDICTED_LABELS = 3


def mismatch_tables(predicted: np.ndarray) -> np.ndarray:
    """Summed-area tables (:func:`summed_table`, int32, one per label ``c`` of
    :data:`PREDICTED_LABELS`) of the points a prediction gives another label than
    ``c``: ``(PREDICTED_LABELS, n_r + 1, n_b + 1)``."""
    predicted = np.asarray(predicted)
    out = np.zeros((PREDICTED_LABELS, predicted.shape[0] + 1, predicted.shape[1] + 1), np.int32)
    for c in range(PREDICTED_LABELS):
        other = (predicted >= 0) & (predicted != c)
        out[c, 1:, 1:] = other.cumsum(0, dtype=np.int32).cumsum(1, dtype=np.int32)
    return out


def trusted(boxes: np.ndarray, label: np.ndarray, predicted: np.ndarray, n_b: int) -> np.ndarray:
    """The label each cell's four corners share and the prediction gives them too (a
    label of the prediction), -1 where they do not: :meth:`~tasks.adaptive.Refinement._trusted`.
    ``label`` and ``predicted`` are flat (simulated labels, the prediction)."""
    c = corners(boxes, n_b)
    lab = label[c]
    first = lab[:, :1]
    same = (lab == first).all(axis=1) & (predicted[c] == first).all(axis=1)
    ok = same & (first[:, 0] >= 0) & (first[:, 0] < PREDICTED_LABELS)
    return np.where(ok, first[:, 0], -1).astype(np.int64)


def guided(boxes: np.ndarray, trust: np.ndarray, tables: np.ndarray) -> np.ndarray:
    """Cells whose corners the prediction gives their own label (``trust``, of
    :func:`trusted`) and that hold a point it gives another (``tables``, of
    :func:`mismatch_tables`): :meth:`~tasks.adaptive.Refinement._guided`."""
    out = trust >= 0
    if out.any():
        at = np.flatnonzero(out)
        out[at] = count_in(tables, boxes[at], trust[at]) > 0
    return out


def guided_axes(boxes: np.ndarray, trust: np.ndarray, tables: np.ndarray) -> np.ndarray:
    """For guided cells (:func:`guided`), whether to halve along r: the longer axis (r
    if square) of those with a line strictly inside that holds a point the prediction
    gives another label (one has: such a point is no corner), so that the cut
    (:func:`split_at` on that label's table) goes through one:
    :meth:`~tasks.adaptive.Refinement._split_axes`."""
    i0, i1, j0, j1 = boxes.T
    lines_r = np.stack([i0 + 1, i1 - 1, j0, j1], axis=1)  # the lines across r, inside
    lines_b = np.stack([i0, i1, j0 + 1, j1 - 1], axis=1)
    can_r = (i1 - i0 > 1) & (count_in(tables, lines_r, trust) > 0)
    can_b = (j1 - j0 > 1) & (count_in(tables, lines_b, trust) > 0)
    return np.where(can_r == can_b, i1 - i0 >= j1 - j0, can_r)


def interior(boxes: np.ndarray) -> np.ndarray:
    """Each cell without its edges, along each axis it spans more than one step of
    (along an axis of one step or none, the whole cell)."""
    i0, i1, j0, j1 = boxes.T
    wide, tall = i1 - i0 > 1, j1 - j0 > 1
    return np.stack(
        [np.where(wide, i0 + 1, i0), np.where(wide, i1 - 1, i1),
         np.where(tall, j0 + 1, j0), np.where(tall, j1 - 1, j1)], axis=1
    )  # fmt: skip


def hinted(boxes: np.ndarray, hint_table: np.ndarray, size: int) -> np.ndarray:
    """Cells larger than ``size`` steps along an axis that hold a hinted point inside
    (:func:`interior`) or on an edge longer than ``size`` steps (its corners apart;
    ``hint_table``: the hint's :func:`summed_table`):
    :meth:`~tasks.adaptive.Refinement._hinted`."""
    i0, i1, j0, j1 = boxes.T
    large = (i1 - i0 > size) | (j1 - j0 > size)
    parts = np.stack(  # the interior, then the inner points of the four edges
        [interior(boxes),
         np.stack([i0 + 1, i1 - 1, j0, j0], axis=1), np.stack([i0 + 1, i1 - 1, j1, j1], axis=1),
         np.stack([i0, i0, j0 + 1, j1 - 1], axis=1), np.stack([i1, i1, j0 + 1, j1 - 1], axis=1)]
    )  # fmt: skip
    held = count_in(hint_table, parts.reshape(-1, 4)).reshape(5, -1) > 0
    long_r, long_b = i1 - i0 > size, j1 - j0 > size  # edges along r, along beta
    found = held[0] | (long_r & (held[1] | held[2])) | (long_b & (held[3] | held[4]))
    return large & found


def corners(boxes: np.ndarray, n_b: int) -> np.ndarray:
    """Flat indices of each cell's four corners, ``(k, 4)`` (repeated for a cell of width 0)."""
    i0, i1, j0, j1 = boxes.T
    return np.stack([i0 * n_b + j0, i0 * n_b + j1, i1 * n_b + j0, i1 * n_b + j1], axis=1)


def summed_table(mask: np.ndarray) -> np.ndarray:
    """Summed-area table of a 2-D mask, one row and column of zeros in front."""
    out = np.zeros((mask.shape[0] + 1, mask.shape[1] + 1), dtype=np.int64)
    out[1:, 1:] = mask.cumsum(0, dtype=np.int64).cumsum(1)
    return out


def count_in(table: np.ndarray, boxes: np.ndarray, layer: np.ndarray | None = None) -> np.ndarray:
    """Points of the mask of :func:`summed_table` in each cell (ends included); with
    ``layer``, ``table`` is a stack of tables and each cell counts in its layer's."""
    i0, i1, j0, j1 = boxes.T
    if layer is not None:
        return (
            table[layer, i1 + 1, j1 + 1]
            - table[layer, i0, j1 + 1]
            - table[layer, i1 + 1, j0]
            + table[layer, i0, j0]
        )
    return table[i1 + 1, j1 + 1] - table[i0, j1 + 1] - table[i1 + 1, j0] + table[i0, j0]


def nearest_corner_sources(
    boxes: np.ndarray, todo: np.ndarray, shape: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """For the flat points ``todo``, the nearer corner along each axis of the last cell
    (in the order of ``boxes``) that contains it: the source of
    :meth:`~tasks.adaptive.Refinement._fill_inferred` (-1 where no cell contains it)."""
    n_r, n_b = shape
    last = np.full(n_r * n_b, -1, dtype=np.int64)
    if boxes.shape[0]:
        _, owner, flat = box_points(boxes, n_b)
        np.maximum.at(last, flat, owner)
    cell = last[todo]
    i, j = np.divmod(todo, n_b)
    if (cell < 0).any():
        return np.full(todo.size, -1, dtype=np.int64), np.full(todo.size, -1, dtype=np.int64)
    i0, i1, j0, j1 = boxes[cell].T
    src_i = np.where(i < (i0 + i1) // 2 + 1, i0, i1)
    src_j = np.where(j < (j0 + j1) // 2 + 1, j0, j1)
    return src_i, src_j


def unique_boxes(boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``numpy.unique(boxes, axis=0, return_index=True)``: each cell once, in the order of
    its ``(i0, i1, j0, j1)``, and the first row it is at. Its four indices packed into
    one int64 (each below 2**15) sort in that order, and a 1-D unique of them costs a
    few times less than the structured view ``axis=0`` sorts (the refinement calls it
    once per round of every cell it examines); larger indices take that path."""
    if not boxes.shape[0] or boxes.max() >= 1 << 15 or boxes.min() < 0:
        return np.unique(boxes, axis=0, return_index=True)
    packed = ((boxes[:, 0] << 45) | (boxes[:, 1] << 30)) | ((boxes[:, 2] << 15) | boxes[:, 3])
    _, at = np.unique(packed, return_index=True)
    return boxes[at], at


def holding(boxes: np.ndarray, pi: np.ndarray, pj: np.ndarray) -> np.ndarray:
    """Which cells hold at least one of the points ``(pi, pj)`` (grid indices, ends of a
    cell included): :meth:`tasks.adaptive.Refinement._leaves_hit` where cells times
    points are few (each cell read until its first point, no temporaries)."""
    return _holding(
        np.ascontiguousarray(boxes, dtype=np.int64),
        np.ascontiguousarray(pi, dtype=np.int64),
        np.ascontiguousarray(pj, dtype=np.int64),
    )


@njit(cache=True, nogil=True)
def _holding(boxes, pi, pj):  # pragma: no cover - compiled
    out = np.zeros(boxes.shape[0], dtype=np.bool_)
    for c in range(boxes.shape[0]):
        i0, i1, j0, j1 = boxes[c, 0], boxes[c, 1], boxes[c, 2], boxes[c, 3]
        for p in range(pi.size):
            if i0 <= pi[p] <= i1 and j0 <= pj[p] <= j1:
                out[c] = True
                break
    return out
