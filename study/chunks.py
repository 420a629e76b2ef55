"""Expansion of a study into chunks: rectangular blocks of points, one Dask task each.

A grid scene is a stack of (r, beta) planes, one per combination of the swept
ratios (gamma, kappa). Each plane is cut into blocks of ``rows x cols`` points
(a run of r values times a run of beta values) holding about
``chunk_target`` points, so one task is ~``task_seconds`` of work
(:mod:`study.cost`). A point list is cut into runs of points; a traced scene
(``mode = "trace"``) into runs of r values.

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

import numpy as np

from study.cost import TRACE_POINTS_PER_R, chunk_target, seconds_per_point
from study.definition import SceneSpec, Study
from study.verify import simulator_version

#: Bump when the meaning of a chunk changes, so old work folders are not reused.
CHUNK_FORMAT = 3  # 2: design quantities (amplitude, dissipation, ...); 3: viscous dissipation
#: Fraction of the points an adaptive scene is expected to simulate (planning only).
ADAPTIVE_SIMULATED_FRACTION = 0.05


@dataclass(frozen=True)
class Chunk:
    """One block of points of one scene (indices only; values come from the plan).

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
    """Everything needed to cut one scene into chunks and to build their tasks."""

    spec: SceneSpec
    fidelity: str
    settings: dict[str, object]
    block: tuple[int, int]  # (rows, cols) of a full chunk

    @classmethod
    def build(cls, spec: SceneSpec, study: Study) -> ScenePlan:
        work = spec.n_points * (TRACE_POINTS_PER_R if spec.mode == "trace" else 1)
        target = study.chunk_points or chunk_target(
            spec.dof, study.fidelity, study.task_seconds, work
        )
        if spec.mode == "trace":
            block = (max(1, min(len(spec.r), target // TRACE_POINTS_PER_R)), 1)
        elif spec.points is not None:
            block = (min(len(spec.points), target), 1)
        else:
            cols = min(len(spec.beta), target)
            block = (max(1, min(len(spec.r), target // cols)), cols)
            if spec.mode == "adaptive":  # point lists of the refinement waves
                target = study.chunk_points or chunk_target(
                    spec.dof, study.fidelity, study.task_seconds, work // 20
                )
                block = (target, 1)
        return cls(spec, study.fidelity, study.settings.to_dict(), block)

    # ------------------------------------------------------------ axes
    @property
    def kind(self) -> str:
        return "points" if self.spec.points is not None else self.spec.mode

    def axes(self) -> dict[str, np.ndarray]:
        """Coordinate arrays: swept ratios, then r and beta (or point columns)."""
        out = {k: a.values_array() for k, a in self.spec.sweeps.items()}
        if self.spec.points is not None:
            out.update(self.spec.points.columns())
        else:
            out["r"] = self.spec.r.values_array()
            out["beta"] = self.spec.beta.values_array()
        return out

    @property
    def n_chunks(self) -> int:
        rows, cols = self.block
        plane = self.spec.plane_shape
        if self.kind == "adaptive":  # an estimate: the waves decide
            simulated = ADAPTIVE_SIMULATED_FRACTION * self.spec.n_points
            return max(1, math.ceil(simulated / rows))
        n_rows = math.ceil(plane[0] / rows)
        n_cols = math.ceil(plane[1] / cols) if self.kind == "grid" else 1
        return math.prod(self.spec.sweep_shape) * n_rows * n_cols

    @property
    def est_seconds(self) -> float:
        per = seconds_per_point(self.spec.dof, self.fidelity)
        if self.kind == "trace":
            per *= TRACE_POINTS_PER_R
        elif self.kind == "adaptive":
            per *= ADAPTIVE_SIMULATED_FRACTION
        return per * self.spec.n_points

    # ------------------------------------------------------------ chunks
    def scene_dict(self, sweep: tuple[int, ...], axes: dict[str, np.ndarray]) -> dict:
        """``Scene.to_dict()`` of the scene at one combination of the swept ratios."""
        ratios = {k: float(axes[k][i]) for k, i in zip(self.spec.sweeps, sweep, strict=True)}
        return self.spec.scene_at(**ratios).to_dict()

    def chunks(self) -> Iterator[Chunk]:
        """All chunks of the scene, in a fixed order, generated lazily."""
        axes = self.axes()
        plane = self.spec.plane_shape
        rows, cols = self.block
        row_starts = range(0, plane[0], rows)
        col_starts = range(0, plane[1], cols) if self.kind == "grid" else (0,)
        index = 0
        for sweep in itertools.product(*(range(n) for n in self.spec.sweep_shape)):
            head = self._key_head(sweep, axes)
            for r0 in row_starts:
                r1 = min(r0 + rows, plane[0])
                for c0 in col_starts:
                    c1 = min(c0 + cols, plane[1]) if self.kind == "grid" else 1
                    h = head.copy()
                    h.update(f"|{index}|{r0}:{r1}|{c0}:{c1}|".encode())
                    for arr in self._contents(axes, (r0, r1), (c0, c1)).values():
                        h.update(np.ascontiguousarray(arr).tobytes())
                    key = f"{self.spec.name}-{index:07d}-{h.hexdigest()[:20]}"
                    yield Chunk(self.spec.name, index, sweep, (r0, r1), (c0, c1), key)
                    index += 1

    def _key_head(self, sweep: tuple[int, ...], axes: dict[str, np.ndarray]):
        ident = {
            "format": CHUNK_FORMAT,
            "scene": self.spec.name,
            "physics": self.scene_dict(sweep, axes),
            "kind": self.kind,
            "fidelity": self.fidelity,
            "settings": self.settings,
            "code": simulator_version(),  # chunks of another simulator are never reused
        }
        return hashlib.sha256(json.dumps(ident, sort_keys=True).encode())

    def _contents(
        self, axes: dict[str, np.ndarray], rows: tuple[int, int], cols: tuple[int, int]
    ) -> dict[str, np.ndarray]:
        sl = slice(*rows)
        if self.kind == "points":
            return {k: axes[k][sl] for k in ("r", "beta", "gamma", "kappa") if k in axes}
        if self.kind == "trace":
            beta = axes["beta"]
            return {"r": axes["r"][sl], "beta": beta}
        return {"r": axes["r"][sl], "beta": axes["beta"][slice(*cols)]}

    def task(self, chunk: Chunk, axes: dict[str, np.ndarray] | None = None) -> dict:
        """The pure input of :func:`study.compute.compute_chunk` for one chunk."""
        axes = self.axes() if axes is None else axes
        return {
            "kind": self.kind,
            "scene": self.scene_dict(chunk.sweep, axes),
            "settings": self.settings,
            **self._contents(axes, chunk.rows, chunk.cols),
        }


def plan(study: Study) -> list[ScenePlan]:
    """One :class:`ScenePlan` per scene of the study."""
    return [ScenePlan.build(s, study) for s in study.scenes]
