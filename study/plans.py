"""The interface every scene kind implements: a plan that yields units of work.

A study is a list of plans, one per scene (:func:`study.chunks.plan`). Every
plan has the same interface (like ``scipy.integrate.OdeSolver``, one class per
method), so the run (:mod:`study.drive`), the work folder (:mod:`study.store`)
and the writer (:mod:`study.netcdf`) handle every kind the same way:

* :meth:`ScenePlan.layout` and :meth:`ScenePlan.coordinates`: dims, shapes and
  dtypes of the scene's variables in the result;
* :meth:`ScenePlan.prepare`, :meth:`ScenePlan.next_unit`, :meth:`ScenePlan.task`,
  :meth:`ScenePlan.accept`: the units of work still missing, handed out one at a
  time (:data:`WAIT` when the next ones depend on results still computing);
* :meth:`ScenePlan.expected`: the fields, dtypes and shapes a unit's stored
  result must hold (:mod:`study.verify`);
* :meth:`ScenePlan.writes` and :meth:`ScenePlan.result_attrs`: the stored
  results, one unit at a time, as blocks of the scene's variables.

The kinds: :class:`study.chunks.GridPlan`, :class:`study.chunks.PointsPlan`,
:class:`study.chunks.TracePlan` (a fixed list of units, :class:`Chunk`) and
:class:`study.adaptive.AdaptivePlan` (units decided as results arrive).

Chunks are generated lazily (:meth:`ScenePlan.chunks`): the client never holds
one Python object per point, only the axes. Each chunk has a stable key, a
hash of (scene name, scene physics, resolved settings, chunk index, chunk
contents), so a rerun of the same study maps every chunk to the same key and
finds it in the work folder (resume), while any change of the physics, settings
or points gives new keys.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from study import contacts
from study.compute import design_on, point_fields
from study.cost import chunk_target, seconds_per_point, spec_factor
from study.definition import SceneSpec, Study
from study.verify import Expected, simulator_version
from tasks.result import MASS_FIELDS

#: Bump when the meaning of a chunk changes, so old work folders are not reused.
CHUNK_FORMAT = 4  # 2: design quantities; 3: no _shape entry; 4: dissipation_viscous
#: Returned by :meth:`ScenePlan.next_unit` when the plan needs results still computing.
WAIT = "wait"
#: Variables of a result unit beside its fields: the compute seconds (0-d).
SECONDS: Expected = {"seconds": ("float64", ())}


@dataclass(frozen=True)
class Chunk:
    """One unit of work of one scene (indices only; values come from the plan).

    ``sweep`` indexes the swept ratios (gamma, kappa; empty when none),
    ``rows`` is the range of r indices (grid, trace) or point indices (point
    list), ``cols`` the range of beta indices (grid only, else ``(0, 1)``).
    """

    scene: str
    index: int
    sweep: tuple[int, ...]
    rows: tuple[int, int]
    cols: tuple[int, int]
    key: str

    @property
    def n_points(self) -> int:
        return (self.rows[1] - self.rows[0]) * (self.cols[1] - self.cols[0])


@dataclass
class ScenePlan:
    """One scene cut into units of work; the interface every scene kind implements."""

    spec: SceneSpec
    fidelity: str
    settings: dict[str, object]
    block: tuple[int, int]  # (rows, cols) of a full chunk

    #: The scene kind ("grid", "points", "trace", "adaptive").
    kind: ClassVar[str] = ""
    #: Simulations per point of the scene (for estimates).
    work_per_point: ClassVar[float] = 1.0
    #: Variables stored as (beta, r) planes (else along one dim: r or point).
    planar: ClassVar[bool] = False
    #: What the run calls this kind's units in its first line.
    unit_noun: ClassVar[str] = "chunks"

    def __post_init__(self) -> None:
        #: Points whose results are final (progress), and the units still to hand out.
        self.finished_points = 0
        self._todo: Iterator[Chunk] | None = None
        #: Worker threads of the cluster (set by :mod:`study.drive` as it looks).
        self.worker_threads = 0

    @classmethod
    def build(cls, spec: SceneSpec, study: Study) -> ScenePlan:
        work = int(spec.n_points * cls.work_per_point)
        target = study.chunk_points or chunk_target(
            spec.dof, study.fidelity, study.task_seconds, work, spec_factor(spec)
        )
        return cls(spec, study.fidelity, study.settings.to_dict(), cls.block_for(spec, target))

    @classmethod
    def block_for(cls, spec: SceneSpec, target: int) -> tuple[int, int]:
        """(rows, cols) of a full unit of about ``target`` points of work."""
        return (max(1, min(spec.plane_shape[0], int(target // cls.work_per_point))), 1)

    # ------------------------------------------------------------ the result's layout
    def axes(self) -> dict[str, np.ndarray]:
        """Coordinate arrays: swept ratios, then r and beta (or point columns)."""
        out = {k: a.values_array() for k, a in self.spec.sweeps.items()}
        out["r"] = self.spec.r.values_array()
        out["beta"] = self.spec.beta.values_array()
        return out

    def variables(self) -> dict[str, str]:
        """{variable: dtype} of the per-point (or per-r) result variables.

        ``regime_rest`` only where rest is one of the starts: elsewhere it would
        hold nothing but the placeholder -127 (``tasks.regimes.NOT_COMPUTED``),
        which a written result never holds. The design quantities only where
        they are computed (:func:`study.compute.point_fields`).
        """
        starts = self.settings.get("starts") or [self.settings.get("initial_condition", "held")]
        if contacts.is_multi(self.spec.structure):  # several contacts: study.contacts
            return contacts.variables(list(starts))
        skip = () if "rest" in starts else ("regime_rest",)
        return {k: dt for k, dt in point_fields(self.settings).items() if k not in skip}

    def design_quantities(self) -> str | None:
        """The scene attribute ``design_quantities``: "on" or "off" (the setting
        ``design``), None where it does not apply (a traced scene holds none; the
        fields of several contacts are always computed)."""
        if contacts.is_multi(self.spec.structure):
            return "on"
        return "on" if design_on(self.settings) else "off"

    def trailing(self, name: str) -> int:
        """Length of the trailing axis of a field in a unit's arrays (per mass or
        per contact; the dim before the plane in the result), 0 for none."""
        if contacts.is_multi(self.spec.structure):
            return self.spec.structure.n_contacts if name in contacts.CONTACT_FIELDS else 0
        return self.spec.dof if name in MASS_FIELDS else 0

    def layout(self) -> tuple[tuple[str, ...], tuple[int, ...], dict[str, str]]:
        """Dims, shape and {variable: dtype} of the per-point (or per-r) variables
        (per-mass fields get the dim ``mass`` before the plane: :func:`var_layout`)."""
        spec = self.spec
        if self.planar:
            dims = (*spec.sweeps, "beta", "r")
            return dims, (*spec.sweep_shape, len(spec.beta), len(spec.r)), self.variables()
        return (*spec.sweeps, "r"), (*spec.sweep_shape, len(spec.r)), self.variables()

    def coordinates(self, axes: dict[str, np.ndarray]) -> dict[str, tuple[str, np.ndarray]]:
        """Coordinate name -> (dim, values) of the scene's result."""
        names = (*self.spec.sweeps, "beta", "r") if self.planar else (*self.spec.sweeps, "r")
        return {n: (n, axes[n]) for n in names}

    def boundary_groups(self, axes: dict[str, np.ndarray]):
        """Dims of the closed-form boundaries, then ``(index, scene, r)`` per scene in them."""
        sweeps = list(self.spec.sweeps)
        yield (*sweeps, "r"), (*self.spec.sweep_shape, len(axes["r"]))
        for idx in np.ndindex(*self.spec.sweep_shape):
            ratios = {n: float(axes[n][i]) for n, i in zip(sweeps, idx, strict=True)}
            yield idx, self.spec.scene_at(**ratios), axes["r"]

    def extra_attrs(self, axes: dict[str, np.ndarray]) -> dict[str, object]:
        """Scene attributes of this kind known before computing."""
        return {}

    # ------------------------------------------------------------ sizes and estimates
    @property
    def n_chunks(self) -> int:
        rows, cols = self.block
        return (
            math.prod(self.spec.sweep_shape)
            * math.ceil(self.spec.plane_shape[0] / rows)
            * math.ceil(self._plane_cols / cols)
        )

    @property
    def est_seconds(self) -> float:
        per = seconds_per_point(self.spec.dof, self.fidelity, spec_factor(self.spec))
        per *= self.work_per_point
        return per * self.spec.n_points

    @property
    def _plane_cols(self) -> int:
        return 1

    # ------------------------------------------------------------ units of work
    def scene_dict(self, sweep: tuple[int, ...], axes: dict[str, np.ndarray]) -> dict:
        """``Scene.to_dict()`` of the scene at one combination of the swept ratios."""
        ratios = {k: float(axes[k][i]) for k, i in zip(self.spec.sweeps, sweep, strict=True)}
        return self.spec.scene_at(**ratios).to_dict()

    def chunks(self) -> Iterator[Chunk]:
        """All chunks of the scene, in a fixed order, generated lazily."""
        axes = self.axes()
        rows, cols = self.block
        n_rows, n_cols = self.spec.plane_shape[0], self._plane_cols
        index = 0
        for sweep in itertools.product(*(range(n) for n in self.spec.sweep_shape)):
            head = self.key_head(sweep, axes, self.kind)
            for r0 in range(0, n_rows, rows):
                r1 = min(r0 + rows, n_rows)
                for c0 in range(0, n_cols, cols):
                    c1 = min(c0 + cols, n_cols)
                    h = head.copy()
                    h.update(f"|{index}|{r0}:{r1}|{c0}:{c1}|".encode())
                    for arr in self.contents(axes, (r0, r1), (c0, c1)).values():
                        h.update(np.ascontiguousarray(arr).tobytes())
                    key = f"{self.spec.name}-{index:07d}-{h.hexdigest()[:20]}"
                    yield Chunk(self.spec.name, index, sweep, (r0, r1), (c0, c1), key)
                    index += 1

    def key_head(self, sweep: tuple[int, ...], axes: dict[str, np.ndarray], kind: str):
        """SHA-256 of what every unit key of one plane of the scene depends on."""
        ident = {
            "format": CHUNK_FORMAT,
            "scene": self.spec.name,
            "physics": self.scene_dict(sweep, axes),
            "kind": kind,
            "fidelity": self.fidelity,
            "settings": self.settings,
            "code": simulator_version(),  # chunks of another simulator are never reused
        }
        return hashlib.sha256(json.dumps(ident, sort_keys=True).encode())

    def contents(
        self, axes: dict[str, np.ndarray], rows: tuple[int, int], cols: tuple[int, int]
    ) -> dict[str, np.ndarray]:
        """The coordinates of a unit's points (part of its key and of its task)."""
        raise NotImplementedError

    def task(self, chunk: Chunk, axes: dict[str, np.ndarray] | None = None) -> dict:
        """The pure input of :func:`study.compute.compute_chunk` for one unit."""
        axes = self.axes() if axes is None else axes
        return {
            "kind": self.kind,
            "scene": self.scene_dict(chunk.sweep, axes),
            "settings": self.settings,
            **self.contents(axes, chunk.rows, chunk.cols),
        }

    def unit_shape(self, chunk: Chunk) -> tuple[int, ...]:
        return (chunk.rows[1] - chunk.rows[0],)

    def expected(self, chunk) -> Expected:
        """Fields, dtypes and shapes the stored result of ``chunk`` must hold."""
        shape = self.unit_shape(chunk)
        fields = {
            k: (dt, (*shape, n) if (n := self.trailing(k)) else shape)
            for k, dt in self.variables().items()
        }
        return fields | SECONDS

    # ------------------------------------------------------------ driving (study.drive)
    def prepare(self, work) -> tuple[int, int, int]:
        """Verify the units on disk (a failing one is discarded and named by ``work``).

        Returns (units, units reused, points reused).
        """
        n = reused = points = 0
        for c in self.chunks():
            n += 1
            if work.reuse(c.scene, c.key, self.expected(c)):
                reused += 1
                points += c.n_points
        self.finished_points = points
        self._todo = self.chunks()
        return n, reused, points

    def missing_points(self, work) -> int:
        """Points whose results are not on disk yet (after :meth:`prepare`)."""
        return self.spec.n_points - self.finished_points

    def next_unit(self, work):
        """The next unit to compute, :data:`WAIT`, or None when every unit is handed out."""
        if self._todo is None:
            self._todo = self.chunks()
        for c in self._todo:
            if not work.has(c.scene, c.key):
                return c
        return None

    def accept(self, chunk, arrays: dict[str, np.ndarray], work) -> None:
        """A unit's result arrived (and is saved in ``work``)."""
        self.finished_points += chunk.n_points

    # ------------------------------------------------------------ writing (study.netcdf)
    def index(self, chunk: Chunk) -> tuple:
        """Where a unit's values go in the scene's variables (without the mass dim)."""
        return (*chunk.sweep, slice(*chunk.rows))

    def writes(self, work):
        """``(variable, index, values)`` of every stored unit, one unit in memory at a time.

        Units are ``(r, beta)`` blocks or runs of points (per-mass fields with a
        trailing mass axis); the stored layout is ``(..., [mass,] beta, r)``.
        """
        for chunk in self.chunks():
            arrays = work.load(chunk.scene, chunk.key, self.expected(chunk))
            index = self.index(chunk)
            k = len(chunk.sweep)
            for name in self.variables():
                where = (*index[:k], slice(None), *index[k:]) if self.trailing(name) else index
                yield name, where, np.asarray(arrays[name]).T

    def result_attrs(self, work) -> dict[str, object]:
        """Scene attributes known once every unit is stored."""
        return {}
