"""Tiles of an adaptive plane: the plane's first units, each refined in one worker.

An adaptive plane of one contact (:mod:`study.adaptive`) starts with a few tile
tasks instead of its coarse lattice as point lists: strips of whole coarse cells
along r (:func:`tasks.tiles.strips`), :data:`TILES_PER_THREAD` per worker thread
so the work balances. A worker refines its tile by itself
(:func:`tasks.tiles.refine_tile`: no round trip client -> scheduler -> worker per
refinement level) and returns every point it simulated (the plane's flat
indices ``index``), their fields and orbits. The client hands them to the
plane's refinement as it does an arrived point list; that refinement then
continues with point lists where the tiles meet (the cells beside a tile's
edge, which a point simulated by the neighbouring tile may reopen), then the
verification sample.

A finished tile is saved in the work folder under its own key (:func:`tile_key`,
never merged with point lists): a rerun hands its points to the refinement
without simulating them; a tile not saved is computed again.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import numpy as np

from tasks.adaptive import coarse_nodes
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


def tile_task(
    scene: dict, settings: dict, axes: dict, rows: tuple[int, int], hint: np.ndarray | None
) -> dict:
    """The task of the tile ``rows`` (:func:`tile_chunk`, without its ``coarse_step``)."""
    i0, i1 = rows
    return {
        "kind": "adaptive-tile",
        "scene": scene,
        "settings": settings,
        "r": axes["r"][i0 : i1 + 1],
        "beta": axes["beta"],
        "hint": None if hint is None else hint[i0 : i1 + 1],
        "offset": i0 * axes["beta"].size,
    }


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

    Returns every simulated point's fields, ``index`` (flat indices of the plane, sorted)
    and ``final`` (their orbits, not saved)."""
    from study.compute import _classify
    from tasks.tiles import refine_tile

    scene, settings = task["scene"], task["settings"]

    def simulate(r: np.ndarray, beta: np.ndarray, given: tuple) -> dict[str, np.ndarray]:
        return _classify(scene, settings, r, beta, given)

    r, beta = task["r"], task["beta"]
    idx, arrays, final = refine_tile(simulate, r, beta, task["coarse_step"], task["hint"])
    order = np.argsort(idx)
    out = {k: v[order] for k, v in arrays.items()}
    out["index"] = idx[order] + task["offset"]  # the tile's flat index + its first row's
    out["final"] = final[order]
    return out
