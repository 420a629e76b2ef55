"""Tiles of an adaptive plane: the plane's first units, each refined in one worker.

An adaptive plane of one contact (:mod:`study.adaptive`) starts with a few tile
tasks instead of its coarse lattice as point lists: strips of whole coarse cells
along r (:func:`tasks.tiles.strips`), :data:`TILES_PER_THREAD` per worker thread
so the work balances. A worker refines its tile by itself
(:func:`tasks.tiles.refine_tile`: no round trip client -> scheduler -> worker per
refinement level), then (``study.adaptive.AdaptivePlan.sample_in_tiles``, off by
default) simulates its share of the plane's verification sample
(:func:`_with_sample`: the points it left inferred whose seeded priority,
:func:`tasks.adaptive.sample_priority`, is below the sample's fraction), and
returns every point it simulated (the plane's flat indices ``index``, ``verify``
marking the sample's candidates), their fields and orbits. The client hands the
refinement's points to the plane's refinement as it does an arrived point list,
and keeps the candidates (:class:`Candidates`); that refinement then continues
with point lists where the tiles meet (the cells beside a tile's edge, which a
point simulated by the neighbouring tile may reopen: a candidate answers it),
and the plane's sample, drawn from its final inferred points, is a subset of the
candidates: no round of its own after the refinement (otherwise the sample goes
out as point lists after it).

A finished tile is saved in the work folder under its own key (:func:`tile_key`,
never merged with point lists): a rerun hands its points to the refinement
without simulating them; a tile not saved is computed again.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import numpy as np

from tasks.adaptive import coarse_nodes, sample_priority
from tasks.tiles import strips

#: Tiles per worker thread (the plane's first units): a thread that ends its tile
#: early takes another (queued by the scheduler) while the slowest computes. Their
#: costs differ by up to 6x (Fig. 4 at 1000 x 500: the tiles of small r cost most);
#: with 2 workers, 4 per thread measured 0.65 s wall on Fig. 4 and 1.32 s on the 6DOF
#: ground-m5 map, 2 per thread 0.65 s and 1.76 s, 8 per thread 0.68 s and 1.43 s
#: (benchmarks/bench_adaptive.py --cluster, same run).
TILES_PER_THREAD = 4
#: Fewest coarse cells along r per tile: a plane with fewer than two tiles of this
#: width is refined by point lists only (its one tile would be the whole plane).
MIN_TILE_CELLS = 2
#: A tile simulates the inferred points of priority below this many times the share of
#: the plane the verification sample's minimum takes (:func:`sample_threshold`): the
#: sample's last points are those of least priority among the plane's final inferred
#: points, about that share (binomial: 200 points give 7 % of spread).
SAMPLE_MARGIN = 1.5
#: The part of a tile's key after the plane's tag (``{tag}-tile{i0}to{i1}-{hash}``).
TILE_WORD = "tile"


@dataclass(frozen=True)
class Tile:
    """A tile of a plane as a unit of work: r indices ``rows`` (first, last) of ``sweep``."""

    scene: str
    key: str
    rows: tuple[int, int]
    task: dict = field(repr=False, compare=False)
    sweep: tuple[int, ...] = ()
    phase: str = "tile"

    @property
    def n_points(self) -> int:  # the points it covers (most are inferred)
        return (self.rows[1] - self.rows[0] + 1) * self.task["beta"].size

    @property
    def idx(self) -> np.ndarray:  # no point list: the result holds its "index"
        return np.zeros(0, dtype=np.int64)


def tile_layout(n_r: int, coarse_step: int, threads: int) -> list[tuple[int, int]]:
    """The tiles of a plane of ``n_r`` points along r: :data:`TILES_PER_THREAD` per
    worker thread, of at least :data:`MIN_TILE_CELLS` coarse cells, two or more (else
    none: the plane is refined by point lists only)."""
    cells = coarse_nodes(n_r, coarse_step).size - 1
    k = min(TILES_PER_THREAD * max(1, threads), cells // MIN_TILE_CELLS)
    return strips(n_r, coarse_step, k) if k >= 2 else []


def longest_first(
    rows: list[tuple[int, int]], hint: np.ndarray | None, r: np.ndarray, coarse_step: int
) -> list[tuple[int, int]]:
    """The tiles ``rows`` in the order to hand them out: the costliest predicted first, so
    the last to end are cheap ones (a tile's cost varies up to 30x at 1000 x 500).

    The prediction: the points the tile will simulate at least, its coarse lattice and
    its hinted points (the closed-form boundaries,
    :func:`analysis.adaptive.closed_form_hint`), over the square root of its middle r (a
    point of small r costs more periods: Fig. 4 measured 2.2e-4 CPU s per hinted point
    at r = 0.18, 0.6e-4 at r = 2.4); without a hint, the order of r (small r costs
    most). Dask gives a batch's tasks in the order submitted, two to each single-threaded
    worker at first: on the tiles of Fig. 4 and the 3DOF, 4DOF and 6DOF maps of
    ``benchmarks/bench_adaptive.py --cluster`` the two workers then end within 0-4 % of
    an even split of the measured costs (in the order of r: 0-11 %). The order changes
    no result."""
    if hint is None:
        return list(rows)
    n_beta = hint.shape[1]
    lattice = coarse_nodes(n_beta, coarse_step).size

    def cost(i0: int, i1: int) -> float:
        points = (
            int(hint[i0 : i1 + 1].sum()) + lattice * coarse_nodes(i1 - i0 + 1, coarse_step).size
        )
        return points / np.sqrt(max(float(np.mean(r[i0 : i1 + 1])), 1e-3))

    return sorted(rows, key=lambda rows_: (-cost(*rows_), rows_))


def tile_task(
    scene: dict,
    settings: dict,
    axes: dict,
    rows: tuple[int, int],
    hint: np.ndarray | None,
    verify: tuple[float, int] | None = None,
    predicted: np.ndarray | None = None,
) -> dict:
    """The task of the tile ``rows`` (:func:`tile_chunk`, without its ``coarse_step``);
    ``verify``: ``(threshold, seed)`` of its share of the verification sample; ``hint``
    and ``predicted`` the plane's (:func:`analysis.adaptive.closed_form_guide`)."""
    i0, i1 = rows
    return {
        "verify": verify,
        "kind": "adaptive-tile",
        "scene": scene,
        "settings": settings,
        "r": axes["r"][i0 : i1 + 1],
        "beta": axes["beta"],
        "hint": None if hint is None else hint[i0 : i1 + 1],
        "predicted": None if predicted is None else predicted[i0 : i1 + 1],
        "offset": i0 * axes["beta"].size,
    }


class Candidates:
    """The candidates of a plane's verification sample its tiles simulated
    (:func:`_with_sample`), by point: they answer the sample's points, and any point
    the plane's refinement asks for later (beside a tile's edge). A point two tiles
    simulated keeps the fields of the tile of smaller r (:func:`first_tile`)."""

    def __init__(self, n_points: int) -> None:
        self.row = np.full(n_points, -1, dtype=np.int64)  # point -> row of arrays (-1: none)
        self.first = np.full(n_points, np.iinfo(np.int64).max, dtype=np.int64)
        self.arrays: dict[str, np.ndarray] = {}

    def add(self, idx: np.ndarray, arrays: dict[str, np.ndarray], first: np.ndarray) -> None:
        """Keep the candidates ``idx`` (fields ``arrays``) of the tiles of first rows ``first``."""
        take = first_tile(idx, first, self.first)
        idx = idx[take]
        self.first[idx] = first[take]
        base = next(iter(self.arrays.values())).shape[0] if self.arrays else 0
        old = self.arrays or {k: v[:0] for k, v in arrays.items()}
        self.arrays = {k: np.concatenate([v, arrays[k][take]]) for k, v in old.items()}
        self.row[idx] = np.arange(base, base + idx.size)


def first_tile(idx: np.ndarray, first: np.ndarray, current: np.ndarray) -> np.ndarray:
    """Of the points ``idx`` arriving from tiles whose first rows are ``first`` (a point
    of two tiles, on the row they share, arrives twice), the positions to keep: each
    point once, from the tile of smallest first row, and only if that is smaller than
    ``current[point]`` (the first row of the tile it was kept from before, or the
    largest int64): the same fields whatever order the tiles arrive in."""
    order = np.lexsort((first, idx))  # by point, then by the tile's first row
    idx, first = idx[order], first[order]
    keep = np.ones(idx.size, dtype=bool)
    keep[1:] = idx[1:] != idx[:-1]
    keep[keep] = first[keep] < current[idx[keep]]
    return order[keep]


def tile_key(tag: str, rows: tuple[int, int]) -> str:
    """Work-folder key of the tile ``rows`` of the plane ``tag``."""
    h = hashlib.sha256(f"{tag}:{rows[0]}:{rows[1]}".encode()).hexdigest()[:16]
    return f"{tag}-{TILE_WORD}{rows[0]}to{rows[1]}-{h}"


def tile_rows(tag: str, key: str) -> tuple[int, int] | None:
    """The rows a key of the plane ``tag`` names, if it is a tile's key (and valid)."""
    word = key[len(tag) + 1 :].split("-", 1)[0]
    if not key.startswith(tag + "-") or not word.startswith(TILE_WORD):
        return None
    try:
        i0, i1 = (int(v) for v in word[len(TILE_WORD) :].split("to"))
    except ValueError:
        return None
    return (i0, i1) if tile_key(tag, (i0, i1)) == key else None


def tile_chunk(task: dict) -> dict[str, np.ndarray]:
    """The Dask task of a tile (:func:`study.compute.compute_chunk`, kind "adaptive-tile"):
    :func:`tasks.tiles.refine_tile` on the tile's axes, each round of points classified
    as a point list is (:func:`study.compute._classify`, seeded by the tile's orbits).

    With ``verify`` (``(threshold, seed)``), the settled tile then simulates its share
    of the plane's verification sample (:func:`_with_sample`): no round of its own
    after the refinement.

    Returns every simulated point's fields, ``index`` (flat indices of the plane, sorted),
    ``final`` (their orbits, not saved) and, with ``verify``, ``verify`` (the points
    simulated as candidates of the sample)."""
    from study.compute import _classify
    from tasks.scene import Scene
    from tasks.tiles import refine_tile_cells

    scene, settings = Scene.from_dict(task["scene"]), task["settings"]  # built once

    def simulate(r: np.ndarray, beta: np.ndarray, given: tuple) -> dict[str, np.ndarray]:
        return _classify(scene, settings, r, beta, given)

    r, beta = task["r"], task["beta"]
    idx, arrays, final, cells = refine_tile_cells(
        simulate, r, beta, task["coarse_step"], task["hint"], task.get("predicted")
    )
    level = cells["level"]
    if task.get("verify") is not None:  # then its share of the verification sample
        idx, arrays, final = _with_sample(simulate, task, idx, arrays, final)
        level = np.concatenate([level, np.full(idx.size - level.size, LEVEL_NONE)])
    order = np.argsort(idx)
    out = {k: v[order] for k, v in arrays.items()}
    out["index"] = idx[order] + task["offset"]  # the tile's flat index + its first row's
    out["final"] = final[order]
    out["level"] = level[order]  # the tile's cells, for the plane (tile_cells)
    out["leaves"] = cells["leaves"] + np.array([1, 1, 0, 0]) * (task["offset"] // beta.size)
    out["leaf_depth"] = cells["leaf_depth"]
    return out


#: ``level`` of a tile's point that is no refinement's (a candidate of the sample).
LEVEL_NONE = np.iinfo(np.int64).max
#: The arrays of a tile's result that hold its cells (:func:`tile_cells`).
TILE_CELLS = ("leaves", "leaf_depth", "level")


def tile_cells(arrays: dict[str, np.ndarray], refined: np.ndarray) -> dict:
    """The cells of a tile's result (:func:`tile_chunk`, or its file: it must hold them,
    ``study.adaptive.AdaptivePlan.expected``) as
    :meth:`tasks.stream.StreamRefinement.install` takes them (``refined``: its points
    of the refinement, not of the sample)."""
    index = np.asarray(arrays["index"], dtype=np.int64)
    return {
        "leaves": np.asarray(arrays["leaves"], dtype=np.int64).reshape(-1, 4),
        "leaf_depth": np.asarray(arrays["leaf_depth"], dtype=np.int64),
        "level": np.asarray(arrays["level"], dtype=np.int64)[refined],
        "points": index[refined],
    }


def _with_sample(
    simulate, task: dict, idx: np.ndarray, arrays: dict[str, np.ndarray], final: np.ndarray
) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
    """A settled tile's candidates for the plane's verification sample, simulated and
    appended (``verify`` True; the refinement's points False): the points it left
    inferred whose :func:`tasks.adaptive.sample_priority` (their plane index, the seed)
    is below the task's threshold (:func:`sample_threshold`), seeded by the tile's
    orbits. The plane's sample is a subset (:meth:`study.adaptive.AdaptivePlan.accept`)."""
    from tasks.orbits import Orbits

    threshold, seed = task["verify"]
    r, beta = task["r"], task["beta"]
    shape = (r.size, beta.size)
    left = np.ones(r.size * beta.size, dtype=bool)
    left[idx] = False
    inferred = np.flatnonzero(left)
    cand = inferred[sample_priority(inferred + task["offset"], seed) < threshold]
    flags = np.zeros(idx.size + cand.size, dtype=bool)
    flags[idx.size :] = True
    if cand.size:
        orbits = Orbits(shape, task["coarse_step"])
        orbits.add(idx, final)
        i_r, i_b = np.unravel_index(cand, shape)
        out = simulate(r[i_r], beta[i_b], orbits.given(cand, r, beta))
        arrays = {k: np.concatenate([v, out[k]]) for k, v in arrays.items()}
        final = np.concatenate([final, out["final"]])
        idx = np.concatenate([idx, cand])
    return idx, arrays | {"verify": flags}, final


def sample_threshold(fraction: float, minimum: int, n_points: int) -> float:
    """The priority below which a tile simulates its inferred points for the plane's
    verification sample (:func:`tasks.adaptive.verification_sample`): the sample's
    ``fraction``, or, where the sample's ``minimum`` takes more of the plane's
    ``n_points``, :data:`SAMPLE_MARGIN` times that share (the few the tiles miss are
    simulated after the refinement; those they add beyond the sample are not kept)."""
    return max(float(fraction), SAMPLE_MARGIN * int(minimum) / max(1, int(n_points)))
