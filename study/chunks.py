"""The scene kinds with a fixed list of units of work (:mod:`study.plans`), and :func:`plan`.

* a grid scene (:class:`GridPlan`): a stack of (r, beta) planes, one per
  combination of the swept ratios (gamma, kappa), each cut into blocks of
  ``rows x cols`` points holding about ``chunk_target`` points, so one task is
  ~``task_seconds`` of work (:mod:`study.cost`);
* a point list (:class:`PointsPlan`): runs of points;
* a traced scene (:class:`TracePlan`, ``mode = "trace"``): runs of r values.

An adaptive scene is :class:`study.adaptive.AdaptivePlan`.
"""

from __future__ import annotations

import json

import numpy as np

from study.adaptive import AdaptivePlan
from study.cost import TRACE_POINTS_PER_R
from study.definition import SceneSpec, Study
from study.plans import CHUNK_FORMAT, WAIT, Chunk, ScenePlan
from study.trace import TRACE_FIELDS

__all__ = [
    "CHUNK_FORMAT",
    "WAIT",
    "AdaptivePlan",
    "Chunk",
    "GridPlan",
    "PointsPlan",
    "ScenePlan",
    "TracePlan",
    "plan",
]


class GridPlan(ScenePlan):
    """A stack of (r, beta) planes, cut into blocks of ``rows x cols`` points."""

    kind = "grid"
    planar = True

    @classmethod
    def block_for(cls, spec: SceneSpec, target: int) -> tuple[int, int]:
        cols = min(len(spec.beta), target)
        return (max(1, min(len(spec.r), target // cols)), cols)

    @property
    def _plane_cols(self) -> int:
        return len(self.spec.beta)

    def contents(self, axes, rows, cols):
        return {"r": axes["r"][slice(*rows)], "beta": axes["beta"][slice(*cols)]}

    def unit_shape(self, chunk: Chunk) -> tuple[int, ...]:
        return (chunk.rows[1] - chunk.rows[0], chunk.cols[1] - chunk.cols[0])

    def index(self, chunk: Chunk) -> tuple:
        return (*chunk.sweep, slice(*chunk.cols), slice(*chunk.rows))


class PointsPlan(ScenePlan):
    """A list of points (r, beta and, per point, gamma and kappa), cut into runs."""

    kind = "points"

    def axes(self) -> dict[str, np.ndarray]:
        return dict(self.spec.points.columns())

    def layout(self):
        return ("point",), (len(self.spec.points),), self.variables()

    def coordinates(self, axes):
        out = {"point": ("point", np.arange(len(self.spec.points)))}
        return out | {n: ("point", axes[n]) for n in ("r", "beta", "gamma", "kappa") if n in axes}

    def boundary_groups(self, axes):
        n = len(self.spec.points)
        yield ("point",), (n,)
        gk = np.stack(
            [axes.get(k, np.full(n, np.nan)) for k in ("gamma", "kappa")],
            axis=1,
        )
        for g, k in np.unique(gk, axis=0):
            sel = np.all((gk == (g, k)) | (np.isnan(gk) & np.isnan([g, k])), axis=1)
            ratios = {n: float(v) for n, v in (("gamma", g), ("kappa", k)) if not np.isnan(v)}
            yield sel, self.spec.scene_at(**ratios), axes["r"][sel]

    def contents(self, axes, rows, cols):
        sl = slice(*rows)
        return {k: axes[k][sl] for k in ("r", "beta", "gamma", "kappa") if k in axes}


class TracePlan(ScenePlan):
    """Boundaries traced by bisection in beta at each r, cut into runs of r values."""

    kind = "trace"
    work_per_point = TRACE_POINTS_PER_R

    def variables(self) -> dict[str, str]:
        return {name: dt for name, (dt, _) in TRACE_FIELDS.items()}

    def contents(self, axes, rows, cols):
        return {"r": axes["r"][slice(*rows)], "beta": axes["beta"]}

    def design_quantities(self) -> None:
        return None  # a traced scene holds boundaries only

    def extra_attrs(self, axes):
        return {"beta_range": json.dumps([float(axes["beta"].min()), float(axes["beta"].max())])}


def plan_class(spec: SceneSpec) -> type[ScenePlan]:
    """The plan of a scene's kind (the one place that tells the kinds apart)."""
    kinds = {c.kind: c for c in (GridPlan, PointsPlan, TracePlan, AdaptivePlan)}
    return kinds["points" if spec.points is not None else spec.mode]


def plan(study: Study) -> list[ScenePlan]:
    """One :class:`ScenePlan` per scene of the study."""
    return [plan_class(s).build(s, study) for s in study.scenes]
