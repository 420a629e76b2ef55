"""``mode = "adaptive"``: a grid scene simulated by refinement without barriers.

The refinement logic is :class:`tasks.stream.StreamRefinement` (pure
numerics): a cell is split as soon as its corners are known. This plan hands
out its ready points as units of work (:mod:`study.chunks` describes the
interface every plan shares): point lists of about ``task_seconds`` of work
(the chunk target; a smaller list only when few of the plane's lists are in
flight, :data:`PARTIAL_BELOW`, so workers never wait for a full one), each
keyed by the plane, its length and a hash of its points' r and beta values, and
saved in the work folder with the points' indices as it arrives. Each point
list goes out with the solved orbits of the points nearest to its points (the
corners of the cells that asked for them, :class:`tasks.orbits.Orbits`), which seed their
searches (warm starts, :mod:`tasks.seeds`): fewer periods, the same labels, the
other fields equal to the polish. The result
does not depend on the order in which point lists arrive, so a rerun after an
interruption loads every saved point list of a plane, answers the refinement's
requests from them and computes only the missing points. When a plane (one
combination of the swept ratios) is complete, its assembled fields are saved in
the work folder too (:data:`PLANES_AT_ONCE` planes in client memory at a time)
and the netCDF writer (:mod:`study.netcdf`) copies them into the result (the
last plane finished by the run from memory, the others from their files). Saved
planes and point lists (their exact length, from the key) are verified before
any computing (:meth:`AdaptivePlan.prepare`), and a point list's indices
against its key when its plane starts: a damaged one is discarded, named and
computed again in the same run.

A plane of one contact with warm starts starts with tiles instead
(:mod:`study.tiles`): strips of whole coarse cells, each refined by one worker
alone (with :attr:`AdaptivePlan.sample_in_tiles`, then also its share of the
verification sample: the points it left inferred of a seeded priority below the
sample's fraction, :func:`tasks.adaptive.verification_sample`); their points
arrive as a point list's do, and point lists follow for what they left
unsettled, then the verification sample's (those the tiles did not hold). A
finished tile is saved under its own key and reused by a rerun.

The result has the layout of a grid scene (dims ``(gamma, kappa, beta, r)``,
every variable of :data:`tasks.result.FIELDS`) plus ``simulated`` and
``verification`` (:data:`tasks.adaptive.ADAPTIVE_FIELDS`) and attributes with
the verification sample's agreement.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import TextIO

import numpy as np

from study import contacts
from study.adaptive_attrs import VERIFY_SEED, plane_stats, result_attrs
from study.compute import point_fields
from study.cost import chunk_target, spec_factor
from study.definition import SceneSpec, Study
from study.plans import CHUNK_FORMAT, SECONDS, WAIT, ScenePlan
from study.store import discard
from study.tiles import (
    TILE_CELLS,
    Candidates,
    Tile,
    first_tile,
    longest_first,
    sample_threshold,
    tile_cells,
    tile_key,
    tile_layout,
    tile_rows,
    tile_task,
)
from study.verify import Expected
from tasks.adaptive import (
    ADAPTIVE_FIELDS,
    DEFAULT_VERIFY_MIN,
    VerificationSummary,
)
from tasks.orbits import Orbits
from tasks.stream import StreamRefinement

#: Seconds between two progress lines of one plane.
PRINT_EVERY = 10.0
#: Plane statistics saved with each plane (0-d or 1-d arrays in the plane file).
STAT_NAMES = ("levels", "n_points", "verify_inferred", "verify_sampled", "verify_agree")
#: Planes refined at the same time (in memory at once): one plane's points fill the
#: workers while another has few ready.
PLANES_AT_ONCE = 2
#: A point list shorter than the chunk target is handed out only while fewer than this
#: many point lists of its plane are in flight (else the ready points wait to fill one).
PARTIAL_BELOW = 4
#: Fewest points of a list cut smaller than the chunk target (its overhead stays small:
#: 256 rather than 64 halves the point lists of a 1000 x 500 map, and its CPU falls by
#: 10-20 %, benchmarks/bench_adaptive.py --cluster).
MIN_LIST = 256
#: A point list of at most this many points is computed in the client's thread
#: (:meth:`AdaptivePlan.compute_here`): at the end of a refinement, boundaries are
#: followed by chains of lists of a few points, each waiting for the one before, and
#: a round trip through the cluster (about 10 ms) costs ten times their computing.
LOCAL_POINTS = 16
#: A point list of at most this many points is computed in the client's thread also
#: while a worker thread has nothing else to do (:meth:`AdaptivePlan.compute_here`),
#: if its points cost at most :data:`LOCAL_SECONDS_IDLE` by the plane's lists so far.
LOCAL_POINTS_IDLE = 64
#: Seconds of computing a point list may cost in the client while a worker thread is
#: free: about the round trip through the cluster it saves (client, scheduler, worker
#: and back: 3-10 ms on 2 busy cores).
LOCAL_SECONDS_IDLE = 0.01
#: Fraction of the points an adaptive scene is expected to simulate (planning only).
ADAPTIVE_SIMULATED_FRACTION = 0.05


@dataclass(frozen=True)
class PointList:
    """One unit of work of an adaptive scene: the points ``idx`` (flat, sorted) of a plane."""

    scene: str
    key: str
    idx: np.ndarray = field(repr=False, compare=False)
    task: dict = field(repr=False, compare=False)
    sweep: tuple[int, ...] = ()  # the plane it belongs to
    phase: str = "refine"  # or "verify": a point list of the verification sample

    @property
    def n_points(self) -> int:
        return int(self.idx.size)

    @property
    def saved_with(self) -> dict[str, np.ndarray]:
        """Saved with the results (:mod:`study.drive`): the points' indices, so a resumed
        run answers the refinement from them."""
        return {"index": self.idx}


@dataclass
class _Plane:
    """The refinement of one (r, beta) plane while it runs."""

    sweep: tuple[int, ...]
    ref: StreamRefinement
    ident: dict
    tag: str  # the plane's part of its point lists' keys
    t0: float
    saved: dict = field(default_factory=dict)  # results of saved point lists, by field
    row: np.ndarray | None = None  # flat index -> row of ``saved`` (-1: not saved)
    phase: str = "refine"  # then "verify"
    todo: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))  # ready
    cut: int = 0  # points per list of the ready points (0: to decide, _list_size)
    sample: np.ndarray | None = None  # the verification sample (sorted)
    out: dict = field(default_factory=dict)  # its results
    outstanding: set = field(default_factory=set)  # keys handed out, not arrived
    arrived: list = field(default_factory=list)  # (idx, arrays) not yet given to ``ref``
    hint_due: bool = False  # the closed-form hint is computed at the first result
    inferred: bool = False  # the inferred points are filled (during the verification)
    handed: bool = False  # a point list was handed out since the last result arrived
    presampled: bool = False  # the sample's candidates drawn (Refinement.presample)
    orbits: Orbits | None = None  # solved orbits that seed new point lists (warm starts)
    tiles: list = field(default_factory=list)  # tiles to hand out (study.tiles)
    pending: dict = field(default_factory=dict)  # tile key -> rows, not in ``ref`` yet
    landed: set = field(default_factory=set)  # keys of those arrived (in tiles_arrived)
    held: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))  # in them
    tiled: int = 0  # tiles of the plane (0: point lists only)
    tiles_done: int = 0  # tiles computed by this run
    # (idx, arrays, rows, verify, cells) of tiles not in ``ref`` (verify: sample candidates)
    tiles_arrived: list = field(default_factory=list)
    cand: Candidates | None = None  # the tiles' candidates of the verification sample
    first_row: np.ndarray | None = None  # point -> first row of the tile its fields are from
    batches: int = 0
    here: int = 0  # point lists computed by the client (AdaptivePlan.compute_here)
    cost: list = field(default_factory=lambda: [0.0, 0])  # compute seconds, points so far
    reused: int = 0  # points answered from saved point lists
    computed: int = 0
    shown: float = field(default_factory=time.monotonic)


class AdaptivePlan(ScenePlan):
    """A grid scene whose points are simulated where refinement asks (tasks.adaptive)."""

    kind = "adaptive"
    planar = True
    work_per_point = ADAPTIVE_SIMULATED_FRACTION
    unit_noun = "adaptive planes"
    stream: TextIO | None = None  # where the planes' lines go (set by the run)
    verbose: bool = True
    #: True: the old wave-by-wave barriers (new points only once every point list of
    #: the plane has arrived), kept for ``benchmarks/bench_adaptive.py``; same result.
    barriers: bool = False
    #: False: no solved orbits sent with the point lists (:class:`tasks.orbits.Orbits`), as before
    #: they were (``benchmarks/bench_adaptive.py --before``); same labels.
    seed_lists: bool = True
    #: Fewest points of a list cut smaller than the chunk target (:data:`MIN_LIST`).
    min_list: int = MIN_LIST
    #: Largest point list computed in the client's thread (:meth:`compute_here`; 0: none,
    #: not even when no other is in flight).
    local_points: int = LOCAL_POINTS
    #: Largest point list computed there while a worker thread is free.
    local_points_idle: int = LOCAL_POINTS_IDLE
    #: False: no tiles (:mod:`study.tiles`), the coarse lattice handed out as point lists.
    tiles: bool = True
    #: True: each settled tile also simulates its share of the verification sample
    #: (:func:`study.tiles.tile_chunk`), no sample round after the refinement; the same
    #: map. Off: measured no faster (docs/adaptive.md, Tiles: the inferred fill, which
    #: the sample round hides, then follows the last tile).
    sample_in_tiles: bool = False
    #: No byte shuffle in the netCDF file (:data:`study.netcdf.COMPRESSION`): inferred
    #: points repeat their cell's corner, which deflate finds better unshuffled.
    nc_shuffle: bool = False

    @classmethod
    def build(cls, spec: SceneSpec, study: Study) -> AdaptivePlan:
        target = study.chunk_points or chunk_target(
            spec.dof, study.fidelity, study.task_seconds, spec.n_points // 20, spec_factor(spec)
        )
        return cls(spec, study.fidelity, study.settings.to_dict(), (target, 1))

    def variables(self) -> dict[str, str]:
        return super().variables() | {k: dt for k, (dt, _) in ADAPTIVE_FIELDS.items()}

    @property
    def n_chunks(self) -> int:  # an estimate: the refinement decides
        return max(1, -(-int(self.work_per_point * self.spec.n_points) // self.block[0]))

    # ------------------------------------------------------------ keys and layouts
    def planes(self) -> Iterator[tuple[int, ...]]:
        """The sweep indices of every (r, beta) plane of the scene."""
        return itertools.product(*(range(n) for n in self.spec.sweep_shape))

    def _ident(self, sweep: tuple[int, ...], axes: dict) -> dict:
        return {
            "format": CHUNK_FORMAT,
            "scene": self.spec.name,
            "physics": self.scene_dict(sweep, axes),
            "fidelity": self.fidelity,
            "settings": self.settings,
        }

    def plane_key(self, sweep: tuple[int, ...], axes: dict | None = None) -> str:
        """Work-folder key of a finished plane: physics, settings, axes, refinement settings."""
        axes = self.axes() if axes is None else axes
        spec = self.spec
        ident = self._ident(sweep, axes) | {
            "kind": "adaptive-plane",
            "coarse_step": spec.coarse_step,
            "verify_fraction": spec.verify_fraction,
            "verify_min": DEFAULT_VERIFY_MIN,
            "hint": spec.hint,
            "seed": VERIFY_SEED,
            "sample": "priority",  # tasks.adaptive.verification_sample
            "guide": "predicted",  # the prediction keeps cells open (tasks.adaptive)
        }
        h = hashlib.sha256(json.dumps(ident, sort_keys=True).encode())
        h.update(np.ascontiguousarray(axes["r"]).tobytes())
        h.update(np.ascontiguousarray(axes["beta"]).tobytes())
        index = "-".join(str(i) for i in sweep) or "0"
        return f"{spec.name}-plane-{index}-{h.hexdigest()[:20]}"

    def plane_expected(self) -> Expected:
        """What a saved plane holds: every field at every point, and its counts."""
        shape = self.spec.plane_shape
        out = {k: (dt, self._shape(k, shape)) for k, dt in self.variables().items()}
        return out | {"levels": ("int64", None)} | {k: ("int64", ()) for k in STAT_NAMES[1:]}

    def expected(self, n: int | None) -> Expected:
        """What a point list of ``n`` points holds; a tile's file (any length, ``n`` None)
        also its cells (:func:`study.tiles.tile_cells`) and, with :attr:`sample_in_tiles`,
        which of its points are candidates of the verification sample."""
        out = {
            k: (dt, None if n is None else self._shape(k, (n,)))
            for k, dt in self.point_fields().items()
        }
        out |= dict.fromkeys(TILE_CELLS, ("int64", None)) if n is None else {}
        out |= {"verify": ("bool", None)} if n is None and self.sample_in_tiles else {}
        return out | SECONDS | {"index": ("int64", None if n is None else (n,))}

    def point_fields(self) -> dict[str, str]:
        """{field: dtype} a point list holds (one contact:
        :func:`study.compute.point_fields`, without the design quantities when they
        are off; several: those of :mod:`study.contacts`), ``regime_rest`` included."""
        if contacts.is_multi(self.spec.structure):
            return dict(contacts.MULTI_DTYPES)
        return point_fields(self.settings)

    def _shape(self, name: str, shape: tuple[int, ...]) -> tuple[int, ...]:
        n = self.trailing(name)  # per mass, or per contact
        return (*shape, n) if n else shape

    def _empty(self, n: int = 0) -> dict[str, np.ndarray]:
        return {
            k: np.zeros(self._shape(k, (n,)), dtype=dt) for k, dt in self.point_fields().items()
        }

    def _new_refinement(self, hint: np.ndarray | None = None) -> StreamRefinement:
        """A plane's refinement: labels and fields of one contact, or the combined
        label of several contacts (:mod:`study.contacts`) with their per-contact fields."""
        spec = self.spec
        fields = {k: (dt, self.trailing(k)) for k, dt in self.point_fields().items()}
        if not contacts.is_multi(spec.structure):  # design quantities only when computed
            return StreamRefinement(
                spec.plane_shape, spec.coarse_step, hint, dof=spec.dof, fields=fields
            )
        return StreamRefinement(
            spec.plane_shape,
            spec.coarse_step,
            hint,
            contacts.KEY_FIELDS,
            fields=fields,
            label=contacts.COMBINED,
        )

    def _list_key(self, tag: str, idx: np.ndarray) -> str:
        """Key of a point list of the plane ``tag``: the length, a hash of the points'
        r and beta."""
        r, beta = self._axes["r"], self._axes["beta"]
        i_r, i_b = np.unravel_index(idx, (r.size, beta.size))
        h = hashlib.sha256(tag.encode())
        h.update(np.ascontiguousarray(r[i_r]).tobytes())
        h.update(np.ascontiguousarray(beta[i_b]).tobytes())
        return f"{tag}-{idx.size}-{h.hexdigest()[:16]}"

    @staticmethod
    def merge_group(unit: PointList | Tile) -> str:
        """Point lists of one plane can be saved as one (:mod:`study.saving`); a tile is
        saved alone, under its own key (a rerun knows it is done)."""
        if isinstance(unit, Tile):
            return unit.key
        return unit.key.rsplit("-", 2)[0]  # the plane's tag

    def merge(
        self, units: list[PointList], arrays: list[dict[str, np.ndarray]]
    ) -> tuple[str, dict[str, np.ndarray]]:
        """Point lists of one plane (their arrays with ``index``) as one point list
        (sorted by index), and its key: a rerun reads it as any point list."""
        index = np.concatenate([a["index"] for a in arrays])
        order = np.argsort(index, kind="stable")
        out = {k: np.concatenate([a[k] for a in arrays])[order] for k in self.point_fields()}
        out["index"] = index[order]
        out["seconds"] = np.float64(sum(float(a["seconds"]) for a in arrays))
        return self._list_key(self.merge_group(units[0]), out["index"]), out

    @staticmethod
    def _list_length(key: str) -> int | None:
        """The length a point list's key names (None: not a key of this format)."""
        parts = key.rsplit("-", 2)
        return int(parts[1]) if len(parts) == 3 and parts[1].isdigit() else None

    # ------------------------------------------------------------ driving (study.drive)
    def prepare(self, work) -> tuple[int, int, int]:
        """Verify the saved planes and point lists (discarding damaged ones); the planes to do."""
        axes = self._axes = self.axes()
        keys = {self.plane_key(s, axes): s for s in self.planes()}
        self._missing = []
        reused = 0
        for key, sweep in keys.items():
            if work.reuse(self.spec.name, key, self.plane_expected()):
                reused += 1
            else:
                self._missing.append(sweep)
        for key in work.keys(self.spec.name):
            if key not in keys:  # a point list: its fields, dtypes and length now
                work.reuse(self.spec.name, key, self.expected(self._list_length(key)))
        self._active: dict[tuple[int, ...], _Plane] = {}
        self._here: bool | None = None  # the simulator is cached (compute_here)
        self._unsaved: tuple[str, dict] | None = None  # the last plane (keep)
        self.finished_points = reused * int(np.prod(self.spec.plane_shape))
        return len(keys), reused, self.finished_points

    def next_unit(self, work):
        """A point list of any plane in refinement: while one plane waits for points in
        flight, the next plane's refinement runs (at most :data:`PLANES_AT_ONCE` planes
        in memory)."""
        while True:
            waiting = False
            for pl in list(self._active.values()):
                unit = self._next_of(pl, work)
                if unit is not None and unit is not WAIT:
                    return unit
                waiting |= unit is WAIT
            if self._missing and len(self._active) < PLANES_AT_ONCE:
                sweep = self._missing.pop(0)
                self._active[sweep] = self._start(sweep, work)
                continue
            return WAIT if waiting else None

    def _next_of(self, pl: _Plane, work):
        """The next point list of one plane, WAIT, or None when the plane is saved."""
        while pl.sweep in self._active:
            if pl.tiles:  # the plane's first units (study.tiles)
                tile = pl.tiles.pop(0)
                pl.outstanding.add(tile.key)
                return tile
            self._replay(pl)
            size = self._list_size(pl)
            few = len(pl.outstanding) < PARTIAL_BELOW or self.barriers
            if pl.todo.size >= size or (pl.todo.size and few):
                idx, pl.todo = pl.todo[:size], pl.todo[size:]
                pl.handed = True
                return self._unit(pl, np.sort(idx))
            if pl.todo.size or pl.outstanding:
                if pl.phase == "verify" and not (pl.todo.size or pl.inferred or pl.handed):
                    # the inferred points' fields (accept_verification compares them) are
                    # filled while the sample computes, not after: refinement is done; not
                    # before the point lists just handed out are submitted (pl.handed)
                    pl.ref._fill_inferred()
                    pl.inferred = True
                return WAIT
            if pl.phase == "refine":
                self._verify(pl)
            else:
                self._finish(pl, pl.ref.accept_verification(pl.sample, pl.out), work)
        return None

    def _list_size(self, pl: _Plane) -> int:
        """Points per list: the ready points cut into :data:`PARTIAL_BELOW` lists or more
        (workers busy, short dependency chains), at most the chunk target, at least
        :attr:`min_list` points (with barriers: the chunk target). The cut is kept until
        new points are ready: the lists of the same ready points have equal lengths, and
        those handed out together end together (no short remainder waits for a later
        round: the verification sample's last 7 points and then the inferred fill, on
        Fig. 4). More lists for the same points (the coarse lattice, the verification
        sample) measured no faster: each costs Dask about 6 ms of CPU (client,
        scheduler, worker)."""
        target = max(1, self.block[0])
        if self.barriers:
            return target
        if not pl.cut:
            n = max(PARTIAL_BELOW, -(-pl.todo.size // target))
            pl.cut = min(target, max(self.min_list, -(-pl.todo.size // n)))
        return pl.cut

    def _replay(self, pl: _Plane) -> None:
        """Move the refinement's ready points to ``todo``, answering at once those a saved
        point list holds or a tile simulated as a candidate of the verification sample
        (:class:`study.tiles.Candidates`; their answers may make more points ready)."""
        if pl.arrived:  # every point list arrived since the last look, in one call
            idx = np.concatenate([i for i, _ in pl.arrived])
            arrays = {k: np.concatenate([a[k] for _, a in pl.arrived]) for k in pl.arrived[0][1]}
            pl.arrived = []
            self._refinement(pl).accept(idx, arrays)
        if pl.tiles_arrived:
            self._accept_tiles(pl)
        while True:
            wave_open = self.barriers and (pl.outstanding or pl.todo.size)
            if pl.phase == "refine" and not wave_open:
                new = pl.ref.take()
                if pl.tiled:
                    new = self._hold(pl, new)
                if new.size:
                    pl.todo, pl.cut = np.concatenate([pl.todo, new]), 0
            answered = False  # from saved point lists, then from the tiles' candidates
            cand = (pl.cand.row, pl.cand.arrays) if pl.cand is not None else (None, None)
            for row, store, saved in ((pl.row, pl.saved, True), (*cand, False)):
                rows = row[pl.todo] if row is not None and pl.todo.size else None
                known = rows >= 0 if rows is not None else None
                if known is None or not known.any():
                    continue
                idx, pl.todo = pl.todo[known], pl.todo[~known]
                arrays = {k: v[rows[known]] for k, v in store.items()}
                if pl.phase == "refine":
                    self._refinement(pl).accept(idx, arrays)
                else:
                    self._put(pl, idx, arrays)
                pl.reused += idx.size if saved else 0
                answered = True
            if not answered:
                return

    def _accept_tiles(self, pl: _Plane) -> None:
        """The points of the tiles arrived since the last look to the refinement. A point
        of two tiles (on the row they share) keeps the fields of the tile of smaller r,
        whichever arrives first: they agree to the polish only (other seeds), and a
        resumed run, which gets every saved tile at once, makes the same map.

        Called at each arrival, while the other tiles compute. The refinement takes a
        tile's cells as the tile decided them (:func:`study.tiles.tile_cells`,
        :meth:`tasks.stream.StreamRefinement.install`), examining again only those
        along the rows tiles share (Fig. 4 at 1000 x 500: a few ms a tile, not most of
        the client's CPU: docs/benchmarks.md, Adaptive maps)."""
        parts, pl.tiles_arrived = pl.tiles_arrived, []
        for key in pl.landed:
            pl.pending.pop(key, None)
        pl.landed.clear()
        for idx, arrays, rows, cand, cells in parts:
            first = np.full(idx.size, rows[0])
            if cand.any():  # the verification sample's candidates: answers, kept aside
                if pl.cand is None:
                    pl.cand = Candidates(pl.ref.n_points)
                pl.cand.add(idx[cand], {k: v[cand] for k, v in arrays.items()}, first[cand])
                idx, first = idx[~cand], first[~cand]
                arrays = {k: v[~cand] for k, v in arrays.items()}
            take = first_tile(idx, first, pl.first_row)
            idx = idx[take]
            pl.first_row[idx] = first[take]
            arrays = {k: v[take] for k, v in arrays.items()}
            self._refinement(pl).install(idx, arrays, rows, cells)  # the same map

    @staticmethod
    def _hold(pl: _Plane, new: np.ndarray) -> np.ndarray:
        """Of the ready points ``new`` and those held before, the ones to hand out: not
        simulated, and in no tile still computing (held until it arrives: it may
        simulate them)."""
        points = np.concatenate([pl.held, new])
        points = points[~pl.ref.simulated.reshape(-1)[points]]
        i_r = points // pl.ref.shape[1]
        inside = np.zeros(points.size, dtype=bool)
        for i0, i1 in pl.pending.values():
            inside |= (i_r >= i0) & (i_r <= i1)
        pl.held = points[inside]
        return np.sort(points[~inside]) if pl.held.size else points[~inside]

    def _unit(self, pl: _Plane, idx: np.ndarray) -> PointList:
        r, beta = self._axes["r"], self._axes["beta"]
        i_r, i_b = np.unravel_index(idx, (r.size, beta.size))
        task = {
            "kind": "adaptive",
            "scene": pl.ident["physics"],
            "settings": self.settings,
            "r": r[i_r],
            "beta": beta[i_b],
        }
        if pl.orbits is not None:  # the result holds the points' orbits (final)
            task["given"] = pl.orbits.given(idx, r, beta)
        key = self._list_key(pl.tag, idx)
        pl.outstanding.add(key)
        return PointList(self.spec.name, key, idx, task, pl.sweep, pl.phase)

    def task(self, unit: PointList, axes=None) -> dict:
        return unit.task

    def compute_here(self, unit: PointList) -> bool:
        """Whether the client computes this point list itself (:mod:`study.drive`): at most
        :attr:`local_points` points, or while a worker thread has nothing else of this
        scene to do (it would wait a round trip for it) at most :attr:`local_points_idle`
        costing at most :data:`LOCAL_SECONDS_IDLE` (the plane's lists so far), of one
        contact (whose simulator releases the GIL), and the simulator in numba's on-disk
        cache (the client loads it, about 0.2 s once; it never compiles it, e.g. on the
        login node of a cluster)."""
        if isinstance(unit, Tile):  # a worker's
            return False
        pl = self._active[unit.sweep]
        others = sum(len(p.outstanding) for p in self._active.values()) - 1  # not this one
        limit = self.local_points
        if others < max(1, self.worker_threads) and pl.cost[1]:  # a worker thread is free
            cheap = int(LOCAL_SECONDS_IDLE * pl.cost[1] / max(pl.cost[0], 1e-9))
            limit = max(limit, min(self.local_points_idle, cheap))
        if not self.local_points or unit.n_points > limit or contacts.is_multi(self.spec.structure):
            return False
        if self._here is None:
            from tasks import numba_cache

            self._here = numba_cache.is_compiled()
        if self._here:
            pl.here += 1
        return self._here

    def accept(self, unit: PointList, arrays: dict[str, np.ndarray], work) -> None:
        """Hand a point list's results (saved with its indices by :mod:`study.drive`,
        :attr:`PointList.saved_with`) to the refinement or the verification sample."""
        pl = self._active[unit.sweep]
        pl.outstanding.discard(unit.key)
        pl.computed += 1
        pl.handed = False
        if not pl.presampled:  # while the workers compute (Refinement.presample)
            pl.ref.presample(self.spec.verify_fraction, VERIFY_SEED)
            pl.presampled = True
        if isinstance(unit, Tile):  # every point it simulated, as an arrived point list
            index = np.asarray(arrays["index"], dtype=np.int64)
            pl.landed.add(unit.key)  # its rows stay held until the refinement has it
            pl.tiles_done += 1
            pl.cost[0] += float(arrays["seconds"])
            pl.cost[1] += index.size
            if pl.orbits is not None and "final" in arrays:
                pl.orbits.add(index, arrays["final"])
            pl.tiles_arrived.append(self._tile_part(index, arrays, unit.rows))
            return
        pl.cost[0] += float(arrays["seconds"])
        pl.cost[1] += unit.n_points
        if pl.orbits is not None and "final" in arrays:
            pl.orbits.add(unit.idx, arrays["final"])
        if unit.phase == "verify":
            self._put(pl, unit.idx, arrays)
            return
        # accepted at the next look for points (_replay): results that arrive together
        # make one call of the refinement (the result does not depend on the grouping)
        pl.arrived.append((unit.idx, {k: arrays[k] for k in self.point_fields()}))
        pl.batches += 1
        if self.verbose and time.monotonic() - pl.shown > PRINT_EVERY:
            pl.shown = time.monotonic()
            self._say(
                f"{self._where(pl)}: {pl.batches} point lists, "
                f"{int(pl.ref.simulated.sum()):,} of {pl.ref.n_points:,} points simulated so far"
            )

    def _tile_part(self, index: np.ndarray, arrays: dict, rows: tuple[int, int]) -> tuple:
        """A tile's points as ``tiles_arrived`` holds them: indices, fields, the tile's
        rows, which are candidates of the verification sample, its cells (tile_cells)."""
        verify = arrays.get("verify")
        verify = np.zeros(index.size, dtype=bool) if verify is None else np.asarray(verify)
        fields = {k: arrays[k] for k in self.point_fields()}
        return index, fields, rows, verify, tile_cells(arrays, ~verify)

    @staticmethod
    def _put(pl: _Plane, idx: np.ndarray, arrays: dict[str, np.ndarray]) -> None:
        """Results of points of the verification sample."""
        at = np.searchsorted(pl.sample, idx)
        for k in pl.out:
            pl.out[k][at] = arrays[k]

    def _verify(self, pl: _Plane) -> None:
        """Refinement is done: the verification sample's points become the ones to do
        (:meth:`_replay` answers those the tiles simulated as candidates, or saved
        point lists hold; the others go out as point lists)."""
        pl.phase = "verify"
        sample = pl.ref.verification(self.spec.verify_fraction, DEFAULT_VERIFY_MIN, VERIFY_SEED)
        pl.sample, pl.out = sample, self._empty(sample.size)
        pl.todo, pl.cut = sample.copy(), 0

    def _start(self, sweep: tuple[int, ...], work) -> _Plane:
        axes, spec = self._axes, self.spec
        ref = self._new_refinement()
        tag = f"{spec.name}-pts-{self.plane_key(sweep, axes).rsplit('-', 1)[1][:12]}"
        pl = _Plane(sweep, ref, self._ident(sweep, axes), tag, time.perf_counter())
        # several contacts: no closed-form hints (analysis.contact_bounds)
        pl.hint_due = spec.hint != "none" and not contacts.is_multi(spec.structure)
        warm = self.settings.get("warm", True) and self.seed_lists
        if warm and not contacts.is_multi(spec.structure):
            pl.orbits = Orbits(spec.plane_shape, spec.coarse_step)
        self._load_saved(pl, work)
        return pl

    def _refinement(self, pl: _Plane) -> StreamRefinement:
        """The plane's refinement, its hint set before its first result: the coarse
        lattice does not depend on the hint, so the client computes the hint while the
        first point lists compute."""
        if pl.hint_due:
            pl.ref.set_hint(*self._hint(pl.sweep, self._axes))
            pl.hint_due = False
        return pl.ref

    def _load_saved(self, pl: _Plane, work) -> None:
        """The saved point lists of a plane (verified in :meth:`prepare`), their indices
        checked against their keys; the plane's requests are answered from them. Its
        tiles (:meth:`_tile`): those saved arrive at once, the others are handed out."""
        idx, parts, tiles = [], [], {}
        for key in work.keys(self.spec.name):
            if not key.startswith(pl.tag + "-"):
                continue
            arrays = work.load(self.spec.name, key, self.expected(self._list_length(key)))
            index = np.asarray(arrays["index"], dtype=np.int64)
            n = pl.ref.n_points
            inside = index.size and index.min() >= 0 and index.max() < n
            rows = tile_rows(pl.tag, key)
            if inside and rows is not None:  # a tile's points lie in its rows
                i_r = index // pl.ref.shape[1]
                if i_r.min() >= rows[0] and i_r.max() <= rows[1]:
                    tiles[rows] = (index, arrays)
                    continue
            if not (inside and self._list_key(pl.tag, index) == key):
                path = work.chunk_path(self.spec.name, key)
                discard(path)
                work.report(
                    f"study: discarded {path}: its points do not match its key; "
                    "computing them again"
                )
                continue
            idx.append(index)
            parts.append(arrays)
        layout = self._tile_layout(pl, untiled=bool(idx) and not tiles)
        for rows, (index, arrays) in tiles.items():
            if rows in layout:  # a finished tile: its points arrive at once
                pl.tiles_arrived.append(self._tile_part(index, arrays, rows))
                pl.reused += index.size
            else:  # a tile of another layout (other worker threads): answers requests
                idx.append(index)
                parts.append(arrays)
        self._tile(pl, [rows for rows in layout if rows not in tiles], len(layout))
        if not idx:
            return
        pl.saved = {k: np.concatenate([a[k] for a in parts]) for k in self.point_fields()}
        pl.row = np.full(pl.ref.n_points, -1, dtype=np.int64)
        pl.row[np.concatenate(idx)] = np.arange(sum(i.size for i in idx))

    def _tile_layout(self, pl: _Plane, untiled: bool) -> list[tuple[int, int]]:
        """The plane's tiles (:mod:`study.tiles`): :data:`~study.tiles.TILES_PER_THREAD`
        per worker thread, of at least :data:`~study.tiles.MIN_TILE_CELLS` coarse cells,
        two or more; none with several contacts or without seeds (``warm`` off,
        :attr:`seed_lists` off), with :attr:`barriers`, or when the plane's saved point
        lists come from a run without tiles (``untiled``: they answer its requests)."""
        if not self.tiles or self.barriers or pl.orbits is None or untiled:
            return []
        return tile_layout(self.spec.plane_shape[0], self.spec.coarse_step, self.worker_threads)

    def _tile(self, pl: _Plane, rows: list[tuple[int, int]], n_tiles: int) -> None:
        """The tiles ``rows`` to hand out first (out of ``n_tiles``), the costliest
        predicted first (:func:`~study.tiles.longest_first`); the hint is computed now
        (each tile refines with its part)."""
        pl.tiled = n_tiles
        if not n_tiles:
            return
        pl.first_row = np.full(pl.ref.n_points, np.iinfo(np.int64).max, dtype=np.int64)
        ref = self._refinement(pl)
        hint, predicted = ref.hint, ref.predicted
        spec = self.spec
        threshold = sample_threshold(spec.verify_fraction, DEFAULT_VERIFY_MIN, pl.ref.n_points)
        verify = (threshold, VERIFY_SEED) if self.sample_in_tiles else None
        for i0, i1 in longest_first(rows, hint, self._axes["r"], spec.coarse_step):
            physics = pl.ident["physics"]
            task = tile_task(physics, self.settings, self._axes, (i0, i1), hint, verify, predicted)
            task["coarse_step"] = self.spec.coarse_step
            tile = Tile(self.spec.name, tile_key(pl.tag, (i0, i1)), (i0, i1), task, pl.sweep)
            pl.tiles.append(tile)
            pl.pending[tile.key] = (i0, i1)

    def _hint(self, sweep: tuple[int, ...], axes: dict) -> tuple[np.ndarray, np.ndarray]:
        """The closed-form hint and prediction (analysis.adaptive.closed_form_guide)."""
        from analysis.adaptive import closed_form_guide

        ratios = {k: float(axes[k][i]) for k, i in zip(self.spec.sweeps, sweep, strict=True)}
        scene = self.spec.scene_at(**ratios)
        return closed_form_guide(scene, axes["r"], axes["beta"], self.spec.hint)

    def _finish(self, pl: _Plane, summary: VerificationSummary, work) -> None:
        """Save the finished plane (its fields and counts) and say so in one line."""
        ref = pl.ref
        fields = ref.result()
        n_sim = int(fields["simulated"].sum())
        self._say(  # the plane's line with its verification estimate is always printed
            f"{self._where(pl)}: {n_sim:,} of {ref.n_points:,} points simulated "
            f"({100 * n_sim / ref.n_points:.2f} %, verification included) in "
            f"{len(ref.level_sizes())} levels, {time.perf_counter() - pl.t0:.1f} s; "
            f"{pl.computed - pl.tiles_done} point lists computed ({pl.here} by the client), "
            f"{f'{pl.tiles_done} of {pl.tiled} tiles computed, ' if pl.tiled else ''}"
            f"{pl.reused:,} saved points reused; "
            f"{summary.line()}",
            always=True,
        )
        fields["levels"] = np.asarray(ref.level_sizes(), dtype=np.int64)
        fields["n_points"] = np.int64(ref.n_points)
        fields["verify_inferred"] = np.int64(summary.inferred)
        fields["verify_sampled"] = np.int64(summary.sampled)
        fields["verify_agree"] = np.int64(summary.agree)
        key = self.plane_key(pl.sweep, self._axes)
        if self._missing or len(self._active) > 1:
            work.save(self.spec.name, key, fields)
        else:  # the last plane: saved only if the run stops before its file is written
            self._unsaved = (key, fields)
        self._last = (pl.sweep, fields)  # the writer reads the last plane from here
        self.finished_points += ref.n_points
        del self._active[pl.sweep]

    def keep(self, work) -> None:
        """Save the plane only memory holds (the run's last, :meth:`_finish`): the run
        stopped before its result file was written (:func:`study.run.run_study`).

        A finished run writes it from memory and then removes the work folder, so it
        is not saved first (its 10-50 MB cost more than the netCDF file). Had the
        client been killed meanwhile, its saved point lists still hold every
        simulated point: the rerun refines the plane again from them, computing none.
        """
        unsaved, self._unsaved = getattr(self, "_unsaved", None), None
        if unsaved is not None:
            work.save(self.spec.name, *unsaved)

    def _where(self, pl: _Plane) -> str:
        return f"study: {self.spec.name}{list(pl.sweep) if pl.sweep else ''}"

    def _say(self, line: str, always: bool = False) -> None:
        if always or self.verbose:
            print(line, file=self.stream if self.stream is not None else sys.stderr)

    # ------------------------------------------------------------ writing (study.netcdf)
    def writes(self, work):
        """``(variable, index, values)`` of every saved plane (one plane in memory at a
        time); their counts are kept for :meth:`result_attrs`.

        Planes are saved as ``(r, beta[, mass])`` arrays; the stored layout is
        ``(..., [mass,] beta, r)`` (:mod:`study.netcdf`).
        """
        axes = self.axes()
        self._stats = []
        last = getattr(self, "_last", None)  # saved by this run: already in memory
        self._last = None
        for sweep in self.planes():
            if last is not None and last[0] == sweep:
                arrays = last[1]
            else:
                key = self.plane_key(sweep, axes)
                arrays = work.load(self.spec.name, key, self.plane_expected())
            for name in self.variables():
                extra = (slice(None),) if self.trailing(name) else ()
                yield name, (*sweep, *extra, slice(None), slice(None)), np.asarray(arrays[name]).T
            self._stats.append(plane_stats(arrays))

    def result_attrs(self, work) -> dict[str, object]:
        """Scene attributes summed over its planes (after :meth:`writes`)."""
        return result_attrs(self, self._stats)
