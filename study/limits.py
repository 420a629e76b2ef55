"""Limits of a study, checked before anything is computed or written.

:class:`study.definition.Study` checks types and shapes field by field; this
module checks that a well-formed study also lies in the ranges the numerics
support and fits the machine, so that nothing fails after compute:

* ratios: r in ``tasks.classifier.R_RANGE`` (1e-4..1e4), beta in
  0..``BETA_MAX`` (1e6), every gamma and kappa (sweeps and per-point values
  included) in ``tasks.scene.RATIO_RANGE`` (1e-6..1e6); solver settings in
  ``tasks.fidelity.LIMITS``;
* sizes: an axis of at most :data:`MAX_AXIS` values (its values are held in
  memory), at most :data:`MAX_POINTS_CAP` points even with ``max_points``
  raised, ``chunk_points`` and ``task_seconds`` in range;
* names of at most :data:`MAX_NAME` characters (they become file and netCDF
  group names);
* a traced scene (``mode = "trace"``) needs at least two beta values (the
  bisection tolerance is half the beta step).

Every violation raises :class:`~study.errors.StudyError` naming the field.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from study.errors import StudyError
from tasks.classifier import BETA_MAX, R_RANGE
from tasks.scene import RATIO_RANGE

if TYPE_CHECKING:
    from study.definition import Axis, SceneSpec, Study

#: Longest study or scene name: names become file names (``NAME.nc``,
#: ``NAME-0000001-<hash>.npz``) and netCDF group names; 255 bytes is the usual
#: limit of one file name.
MAX_NAME = 100
#: Most values of one axis (r, beta or a sweep): the axis is held in memory.
MAX_AXIS = 1_000_000
#: Most points of a study even with ``[study] max_points`` raised (the result
#: file holds about 40 bytes per point).
MAX_POINTS_CAP = 10_000_000_000
#: Range of ``[study] task_seconds``.
TASK_SECONDS_RANGE = (0.01, 3600.0)
#: Most points of one task (``[study] chunk_points``).
MAX_CHUNK_POINTS = 10_000_000


def _name(name: str, field: str) -> None:
    if len(name) > MAX_NAME:
        raise StudyError(field, f"must be at most {MAX_NAME} characters, got {len(name)}")


def _range(values: tuple[float, float], field: str, lo: float, hi: float, what: str) -> None:
    """``values`` = (smallest, largest) of a field; both must be in [lo, hi]."""
    for v in values:
        if not lo <= v <= hi:
            raise StudyError(field, f"{what} must be in [{lo:g}, {hi:g}], got {v:g}")


def _axis_ends(axis: Axis) -> tuple[float, float]:
    """Smallest and largest value of an axis, without building it."""
    if axis.values is not None:
        return min(axis.values), max(axis.values)
    return axis.start, axis.stop


def _axis(axis: Axis, field: str, lo: float, hi: float, what: str) -> None:
    n = len(axis.values) if axis.values is not None else axis.num  # len() overflows at 2^63
    if n > MAX_AXIS:
        raise StudyError(
            f"{field}.num" if axis.values is None else field,
            f"an axis holds at most {MAX_AXIS:,} values, got {n:,}",
        )
    _range(_axis_ends(axis), field, lo, hi, what)


def check_scene(spec: SceneSpec, path: str) -> None:
    """Check one scene against the limits (see the module docstring)."""
    _name(spec.name, f"{path}.name")
    lo, hi = RATIO_RANGE
    for key in ("gamma", "kappa"):
        v = getattr(spec, key)
        field = f"{path}.{key}"
        if isinstance(v, tuple):
            _range((min(v), max(v)), field, lo, hi, f"every {key}")
        elif isinstance(v, float):
            _range((v, v), field, lo, hi, key)
        else:
            _axis(v, field, lo, hi, f"every {key}")
    if spec.points is not None:
        pts = spec.points
        _range((min(pts.r), max(pts.r)), f"{path}.points", *R_RANGE, "every r")
        _range((min(pts.beta), max(pts.beta)), f"{path}.points", 0.0, BETA_MAX, "every beta")
        for key in ("gamma", "kappa"):
            col = getattr(pts, key)
            if col is not None:
                _range((min(col), max(col)), f"{path}.points.{key}", lo, hi, f"every {key}")
        return
    _axis(spec.r, f"{path}.r", *R_RANGE, "every r")
    _axis(spec.beta, f"{path}.beta", 0.0, BETA_MAX, "every beta")
    if spec.mode == "trace" and len(spec.beta) < 2:
        raise StudyError(
            f"{path}.beta",
            "a traced scene needs a beta range of at least 2 values (the bisection "
            f"tolerance is half the beta step), got {len(spec.beta)}",
        )


def check_study(study: Study) -> None:
    """Check a study against the limits; raise :class:`StudyError` naming the field."""
    _name(study.name, "study.name")
    lo, hi = TASK_SECONDS_RANGE
    if not lo <= study.task_seconds <= hi:
        raise StudyError(
            "study.task_seconds", f"must be in [{lo:g}, {hi:g}], got {study.task_seconds:g}"
        )
    if study.chunk_points is not None and study.chunk_points > MAX_CHUNK_POINTS:
        raise StudyError(
            "study.chunk_points",
            f"must be at most {MAX_CHUNK_POINTS:,}, got {study.chunk_points:,}",
        )
    if study.max_points > MAX_POINTS_CAP:
        raise StudyError(
            "study.max_points", f"must be at most {MAX_POINTS_CAP:,}, got {study.max_points:,}"
        )
    for i, spec in enumerate(study.scenes):
        check_scene(spec, f"scene[{i}]")
