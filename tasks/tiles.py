"""One tile of an adaptive map refined in one call: no round trip per refinement level.

A tile is a strip of whole coarse cells of an (r, beta) plane: every beta, the r
indices between two nodes of the coarse lattice (:func:`tasks.adaptive.coarse_nodes`),
so its own coarse lattice is the plane's, and each of its cells is a cell of the
plane's refinement. :func:`refine_tile` runs the refinement of
:class:`tasks.stream.StreamRefinement` on the tile alone, simulating each round's
ready points in one call seeded by the tile's solved orbits
(:class:`tasks.orbits.Orbits`), until the tile is settled. The plane's refinement
(:mod:`study.adaptive`) then receives every simulated point and continues where
the tiles' edges meet. No Dask, no files.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from tasks import cells
from tasks.adaptive import KEY_FIELDS, coarse_nodes
from tasks.orbits import Orbits
from tasks.result import FIELDS
from tasks.stream import StreamRefinement

Simulate = Callable[[np.ndarray, np.ndarray, tuple], dict[str, np.ndarray]]
"""Classify points ``(r, beta)`` seeded by ``given`` (``(r, beta, final)`` of solved
points): their fields by name and ``final``, their orbits (as
:func:`tasks.classifier.classify_given` returns them)."""


class _TileRefinement(StreamRefinement):
    """A tile's refinement that also keeps each point's ``corner_level``: the least depth
    of the cells it is a corner of. A point's level in the plane's refinement, which
    receives the tile's points all at once (:meth:`tasks.stream.StreamRefinement.install`):
    there a strip's middles are simulated already when it is examined, so unlike in the
    tile they are not asked for at the level of a halving."""

    def __init__(self, shape: tuple[int, int], *args: object, **kwargs: object) -> None:
        self.corner_level = np.full(shape[0] * shape[1], np.iinfo(np.int64).max, dtype=np.int64)
        super().__init__(shape, *args, **kwargs)

    def _wait(self, boxes, depth, on=None, at=None):
        if on is None and boxes.shape[0]:  # cells (not a strip's middles) at their depth
            corners = cells.corners(boxes, self.shape[1])
            np.minimum.at(self.corner_level, corners.ravel(), np.repeat(depth, 4))
        return super()._wait(boxes, depth, on, at)


def strips(n_r: int, coarse_step: int, k: int) -> list[tuple[int, int]]:
    """At most ``k`` tiles ``(i0, i1)`` (first and last r index, both nodes of the coarse
    lattice) covering ``n_r`` points, of whole coarse cells as equal in number as they
    can be; one tile when the lattice has a single cell."""
    nodes = coarse_nodes(n_r, coarse_step)
    cells = nodes.size - 1
    k = max(1, min(int(k), cells))
    cuts = np.round(np.linspace(0, cells, k + 1)).astype(int)
    return [(int(nodes[a]), int(nodes[b])) for a, b in zip(cuts[:-1], cuts[1:], strict=True)]


def refine_tile(
    simulate: Simulate,
    r: np.ndarray,
    beta: np.ndarray,
    coarse_step: int,
    hint: np.ndarray | None = None,
    predicted: np.ndarray | None = None,
) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
    """Refine the map of axes ``r`` x ``beta`` (a tile's) until it is settled: the first
    three returns of :func:`refine_tile_cells`."""
    return refine_tile_cells(simulate, r, beta, coarse_step, hint, predicted)[:3]


def refine_tile_cells(
    simulate: Simulate,
    r: np.ndarray,
    beta: np.ndarray,
    coarse_step: int,
    hint: np.ndarray | None = None,
    predicted: np.ndarray | None = None,
) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray, dict[str, np.ndarray]]:
    """Refine the map of axes ``r`` x ``beta`` (a tile's) until it is settled.

    Parameters
    ----------
    simulate : Simulate
        Classifies points; the refinement reads their :data:`tasks.adaptive.KEY_FIELDS`.
    r, beta : numpy.ndarray
        The tile's axes.
    coarse_step : int
        The coarse lattice's step in grid steps.
    hint : bool array of shape ``(r.size, beta.size)``, optional
        The closed-form hint restricted to the tile.
    predicted : int8 array of shape ``(r.size, beta.size)``, optional
        The closed-form prediction restricted to the tile
        (:class:`tasks.adaptive.Refinement`).

    Returns
    -------
    idx : numpy.ndarray
        The simulated points (flat indices of the tile, in the order simulated).
    arrays : dict of numpy.ndarray
        Their fields (every field ``simulate`` returns but ``final``).
    final : numpy.ndarray
        Their orbits (rows of ``final``).
    cells : dict of numpy.ndarray
        The tile's refinement as it ended, in the tile's indices: ``leaves`` (its
        uniform cells ``(i0, i1, j0, j1)``), ``leaf_depth`` (their halvings from the
        coarse cells) and ``level`` (of each point of ``idx``, as
        :meth:`tasks.stream.StreamRefinement.level_sizes` counts them): the plane's
        refinement takes them instead of examining the tile's cells again
        (:meth:`tasks.stream.StreamRefinement.install`).
    """
    shape = (r.size, beta.size)
    layout = {k: (FIELDS[k][0], 0) for k in KEY_FIELDS}
    ref = _TileRefinement(shape, coarse_step, hint, fields=layout, predicted=predicted)
    orbits = Orbits(shape, coarse_step)
    done: list[tuple[np.ndarray, dict[str, np.ndarray]]] = []
    while (idx := ref.take()).size:  # every ready point at once: one call per round
        i_r, i_b = np.unravel_index(idx, shape)
        out = simulate(r[i_r], beta[i_b], orbits.given(idx, r, beta))
        orbits.add(idx, out["final"])
        ref.accept(idx, out)
        done.append((idx, out))
    index = np.concatenate([i for i, _ in done])
    arrays = {k: np.concatenate([a[k] for _, a in done]) for k in done[0][1]}
    cells = {
        "leaves": ref._leaf_boxes().copy(),
        "leaf_depth": ref._leaf_depth.copy(),
        "level": ref.corner_level[index],
    }
    return index, arrays, arrays.pop("final"), cells
