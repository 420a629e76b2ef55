"""Study definition: a TOML file (or the same data in Python), validated field by field.

A study is a list of scenes (``tasks.Scene`` plus the points to classify) and
one fidelity with optional solver-setting overrides (``tasks.fidelity``)::

    [study]
    name = "quickstart"
    fidelity = "balanced"          # fast | balanced | exact

    [settings]                     # optional overrides of the preset
    max_cycles = 2000

    [[scene]]
    contact = "ground"             # ground | base | mass
    dof = 2
    contact_mass = 1
    gamma = 1.0                    # or [g2, ..., gN], or a sweep {values=[...]}
    kappa = {values = [0.5, 1.0, 2.0]}
    r = {start = 0.05, stop = 2.5, num = 40}
    beta = {start = 0.0, stop = 1.0, num = 25}

One validation for every door: :class:`Study`, :class:`SceneSpec`,
:class:`~study.axes.Axis` and :class:`~study.axes.Points` check their fields
when they are built (``__post_init__``), whether from a study file
(:meth:`Study.from_toml`), plain data (:meth:`Study.from_dict`) or Python, and
against the limits of :mod:`study.limits` before any axis is materialised.
numpy integer and float scalars are accepted wherever Python ones are; bools
are never numbers (:mod:`study.fields`). Every rule broken raises
:class:`~study.errors.StudyError` (a ``ValueError``) naming the field in one
line, e.g. ``scene[0].r.num: must be an integer >= 1, got -3`` (scenes count
from 0 in file order; a scene built alone names its own fields, ``r.num``).
See README "Study files" and ``docs/limits.md``.
"""

from __future__ import annotations

import json
import math
import os
import re
import stat
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from dataclasses import fields as dataclass_fields
from pathlib import Path
from typing import Any

import numpy as np

from study import contacts, fields, structures
from study.axes import SPACINGS, Axis, Points
from study.errors import StudyError, field_error
from study.fields import show as _show
from study.fields import within
from study.limits import (
    BETA_MAX,
    MAX_CHUNK_POINTS,
    MAX_POINTS_CAP,
    MAX_STUDY_BYTES,
    R_RANGE,
    RATIO_RANGE,
    TASK_SECONDS_RANGE,
    check_name,
    check_range,
    check_size,
    entry_kind,
)
from tasks.fidelity import PRESETS, Settings, resolve
from tasks.scene import Scene

__all__ = ["ADAPTIVE_HINTS", "MODES", "SPACINGS", "Axis", "Points", "SceneSpec", "Study"]

#: Default limit on the number of points of one study (``[study] max_points``).
DEFAULT_MAX_POINTS = 50_000_000
#: Default target duration of one Dask task, in seconds (``[study] task_seconds``).
DEFAULT_TASK_SECONDS = 0.5
MODES = ("grid", "trace", "adaptive")
#: Closed-form hints an adaptive scene can refine around (``analysis.boundaries`` methods).
ADAPTIVE_HINTS = ("exact", "paper", "none")
#: Settings of ``mode = "adaptive"`` only.
ADAPTIVE_KEYS = ("coarse_step", "verify_fraction", "hint")
_AXIS_KEYS = ("start", "stop", "num", "spacing", "values")
_POINT_KEYS = ("r", "beta", "gamma", "kappa")
_NAME_RE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$")
_NAME_RULE = "a string of letters, digits, '_', '.', '-' (a file and netCDF group name)"


def _name(v: object, field_: str) -> str:
    """A study or scene name: :data:`_NAME_RULE`, at most ``MAX_NAME`` characters."""
    if not isinstance(v, str) or not _NAME_RE.match(v):
        raise StudyError(field_, f"must be {_NAME_RULE}, got {_show(v)}")
    check_name(v, field_)
    return str(v)


# --------------------------------------------------------------------------- reading helpers
class _Table:
    """The keys of one TOML table: read them, then reject any key left over."""

    def __init__(self, data: object, path: str) -> None:
        if not isinstance(data, Mapping):
            raise StudyError(path, f"must be a table, got {_show(data)}")
        self.data = data
        self.path = path
        self.used: set[str] = set()

    def at(self, key: str) -> str:
        return f"{self.path}.{key}" if self.path else key

    def has(self, key: str) -> bool:
        return key in self.data

    def get(self, key: str, default: object = None) -> object:
        self.used.add(key)
        return self.data.get(key, default)

    def given(self, keys) -> dict[str, object]:
        """The keys of ``keys`` present in the table, with their values."""
        return {k: self.get(k) for k in keys if self.has(k)}

    def finish(self) -> None:
        unknown = [k for k in self.data if k not in self.used]
        if unknown:
            known = ", ".join(sorted(self.used))
            raise StudyError(self.at(str(unknown[0])), f"unknown key (known keys here: {known})")


def _unknown_key(raw: Mapping, known: tuple[str, ...]) -> None:
    for k in raw:
        if k not in known:
            raise StudyError(str(k), f"unknown key (known keys here: {', '.join(known)})")


def as_axis(raw: object, lower: float | None = None, strict: bool = False) -> Axis:
    """An :class:`Axis` from an Axis, a number, a list of values or a table of its fields.

    With ``lower``, every value must be ``> lower`` (``strict``) or ``>= lower``;
    explicit values are checked in order, so the first bad one is named.
    """
    if isinstance(raw, Axis):
        axis = raw
    elif isinstance(raw, Mapping | list | tuple | np.ndarray) or fields.is_number(raw):
        if fields.is_number(raw):
            raw = {"values": (raw,)}
        elif not isinstance(raw, Mapping):
            raw = {"values": raw}
        _unknown_key(raw, _AXIS_KEYS)
        values = raw.get("values")
        if lower is not None and fields.is_list(values):
            for i, v in enumerate(values):
                fields.number(v, f"values[{i}]", lower, strict)
        axis = Axis(**raw)
    else:
        raise StudyError(
            "",
            "must be a number, a list or an axis {start, stop, num} or {values}, "
            f"got {_show(raw)}",
        )
    if lower is not None:
        axis.check_bound(lower, strict)
    return axis


def as_points(raw: object) -> Points:
    """:class:`Points` from Points, ``[[r, beta], ...]`` or a table of columns."""
    if isinstance(raw, Points):
        return raw
    if isinstance(raw, Mapping):
        _unknown_key(raw, _POINT_KEYS)
        return Points(**{k: raw.get(k) for k in _POINT_KEYS})
    if not fields.is_list(raw):
        raise StudyError(
            "", f"must be a list of [r, beta] pairs or a table of columns, got {_show(raw)}"
        )
    if len(raw) == 0:
        raise StudyError("", "must not be empty")
    check_size(len(raw), "")
    rs, bs = [], []
    for i, p in enumerate(raw):
        if not fields.is_list(p) or len(p) != 2:
            raise StudyError(f"[{i}]", f"must be a pair [r, beta], got {_show(p)}")
        rs.append(fields.number(p[0], f"[{i}][0]", 0.0, strict=True))
        bs.append(fields.number(p[1], f"[{i}][1]", 0.0))
    return Points(tuple(rs), tuple(bs))


def _ratio(raw: object, key: str, dof: int) -> float | tuple[float, ...] | Axis:
    """A fixed ratio (one number, or dof - 1 numbers) or a sweep (an :class:`Axis`)."""
    if isinstance(raw, Axis | Mapping):
        if dof < 2:
            raise StudyError(key, "dof 1 has no mass or stiffness ratios to sweep")
        with within(key):
            axis = as_axis(raw, 0.0, strict=True)
        check_range(axis.ends, key, *RATIO_RANGE, f"every {key}")
        return axis
    if fields.is_number(raw):
        return fields.number(raw, key, 0.0, strict=True)
    if fields.is_list(raw):
        if len(raw) != dof - 1:
            raise StudyError(
                key,
                f"a list gives the ratios of masses/springs 2..{dof}, so it needs dof - 1 = "
                f"{dof - 1} entries, got {len(raw)} (to sweep, write {{values = [...]}})",
            )
        return fields.numbers(raw, key, 0.0, strict=True)
    raise StudyError(key, f"must be a number, a list or a sweep (Axis), got {_show(raw)}")


# --------------------------------------------------------------------------- scenes
@dataclass(frozen=True)
class SceneSpec:
    """One scene of a study: a :class:`tasks.Scene` and where to classify it.

    ``gamma``/``kappa`` are either fixed (a number, or one number per mass
    2..N, as in :class:`tasks.Scene`) or an :class:`Axis` *sweep*: a swept
    value sets every ratio 2..N to that value and becomes a dimension of the
    result. Exactly one of (``r`` and ``beta``) or ``points`` is given; ``r``
    and ``beta`` may be an :class:`Axis`, a number or a list of values,
    ``points`` a :class:`Points`, a list of ``[r, beta]`` pairs or a table of
    columns. An empty ``name`` becomes the scene's label (``2dof_ground_m1``).

    Every field is checked on construction (types, ``tasks.Scene``'s rules,
    :mod:`study.limits`), before any axis is materialised.

    Raises
    ------
    StudyError
        Naming the field, e.g. ``mode: must be one of ('grid', 'trace', 'adaptive'),
        got 'bogus'``; inside a study file prefixed by the scene, ``scene[0].mode``.
    """

    name: str
    contact: str | Mapping | tuple | None = None
    dof: int | None = None
    contact_mass: int = 1
    gamma: float | tuple[float, ...] | Axis = 1.0
    kappa: float | tuple[float, ...] | Axis = 1.0
    r: Axis | None = None
    beta: Axis | None = None
    points: Points | None = None
    mode: str = "grid"
    #: ``mode = "adaptive"`` only (:mod:`tasks.adaptive`): the coarsest spacing in grid
    #: steps, the verification sample's fraction of the inferred points, and the
    #: closed-form boundaries refined around.
    coarse_step: int = 16
    verify_fraction: float = 0.005
    hint: str = "exact"
    #: A structure instead of a chain (:mod:`study.structures`): its matrices (a table
    #: or a ``.npz`` path) with ``contact = {ground = j}``, or a beam table; and damping.
    matrices: object = field(default=None, compare=False, repr=False)
    beam: Mapping | None = field(default=None, compare=False)
    damping: object = field(default=None, compare=False, repr=False)
    #: Several contacts (docs/contacts.md): ``beta_c = beta_ratio[c] * beta``, with a list
    #: ``contact_mass`` (a chain) or a list ``contact`` (matrices).
    beta_ratio: object = field(default=None, compare=False, repr=False)
    #: The scene of ``matrices`` or ``beam``, or of several contacts (None for a chain).
    structure: Scene | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        def put(key: str, value: object) -> None:
            object.__setattr__(self, key, value)

        put("beta_ratio", contacts.checked_ratio(self.beta_ratio))
        if self.matrices is not None or self.beam is not None:
            self._check_structure()
            dof = self.dof
        elif self.damping is not None:
            raise StudyError("damping", "applies to scenes of matrices or beams only")
        elif fields.is_list(self.contact_mass) or fields.is_list(self.contact):
            self._check_chain_contacts()
            dof = self.dof
        else:
            contacts.no_ratio(self.beta_ratio)
            put("contact", fields.string(self.contact, "contact"))
            dof = fields.integer(self.dof, "dof", minimum=1)
            put("dof", dof)
            put("contact_mass", fields.integer(self.contact_mass, "contact_mass"))
            put("gamma", _ratio(self.gamma, "gamma", dof))
            put("kappa", _ratio(self.kappa, "kappa", dof))
        mode = fields.string(self.mode, "mode", MODES)
        put("coarse_step", fields.integer(self.coarse_step, "coarse_step", minimum=1))
        fraction = fields.number(self.verify_fraction, "verify_fraction")
        if not 0.0 <= fraction <= 1.0:
            raise StudyError("verify_fraction", f"must be in [0, 1], got {fraction:g}")
        put("verify_fraction", fraction)
        put("hint", fields.string(self.hint, "hint", ADAPTIVE_HINTS))
        contacts.check_mode(self.structure, mode)
        if self.points is not None:
            self._check_points(mode, dof)
        else:
            bounds = {"r": (True, R_RANGE), "beta": (False, (0.0, BETA_MAX))}
            for key, (strict, (lo, hi)) in bounds.items():
                raw = getattr(self, key)
                if raw is None:
                    raise StudyError(key, "is required (or give points = [[r, beta], ...])")
                with within(key):
                    axis = as_axis(raw, 0.0, strict)
                check_range(axis.ends, key, lo, hi, f"every {key}")
                put(key, axis)
            if mode == "trace" and len(self.beta) < 2:
                raise StudyError(
                    "beta",
                    "a traced scene needs a beta range of at least 2 values (the bisection "
                    f"tolerance is half the beta step), got {len(self.beta)}",
                )
        try:  # tasks.Scene checks contact, dof, contact_mass and the fixed ratios' range
            base = self.base_scene
        except ValueError as exc:
            raise field_error("", exc) from None
        unnamed = self.name is None or (isinstance(self.name, str) and not self.name)
        put("name", base.label if unnamed else _name(self.name, "name"))

    def _check_chain_contacts(self) -> None:
        """A chain with several contacts (a list ``contact_mass``); sets ``structure``."""
        dof = fields.integer(self.dof, "dof", minimum=1)
        ratios = {k: _ratio(getattr(self, k), k, dof) for k in ("gamma", "kappa")}
        kinds, masses, scene = contacts.chain_scene(
            self.contact, dof, self.contact_mass, ratios, self.beta_ratio
        )
        for key, value in (("dof", dof), ("contact", kinds), ("contact_mass", masses)):
            object.__setattr__(self, key, value)
        for key, value in ratios.items():
            object.__setattr__(self, key, value)
        object.__setattr__(self, "beta_ratio", list(scene.beta_ratio))
        object.__setattr__(self, "structure", scene)

    def _check_structure(self) -> None:
        """A scene of matrices or a beam (:mod:`study.structures`); sets ``structure``."""
        if self.matrices is not None and self.beam is not None:
            raise StudyError("beam", "give either matrices or beam, not both")
        for k in ("gamma", "kappa"):
            if not (fields.is_number(getattr(self, k)) and getattr(self, k) == 1.0):
                raise StudyError(k, "a structure has no chain ratios (its matrices say it all)")
        if self.beam is not None:
            if self.contact is not None:
                raise StudyError("contact", "a beam's contact is beam.contact_node")
            scene = structures.beam_scene(self.beam, self.damping, self.beta_ratio)
        else:
            contact = structures.contact_specs(self.contact)
            scene = structures.matrices_scene(
                self.matrices, contact, self.damping, Path.cwd(), self.beta_ratio
            )
            object.__setattr__(self, "contact", contact)
        if not contacts.is_multi(scene):  # a beam: one contact
            contacts.no_ratio(self.beta_ratio)
        object.__setattr__(self, "structure", structures.check_simulable(scene))
        object.__setattr__(self, "dof", scene.dof)
        if contacts.is_multi(scene):
            object.__setattr__(self, "beta_ratio", list(scene.beta_ratio))
        else:
            object.__setattr__(self, "contact_mass", scene.contact_mass)

    def _check_points(self, mode: str, dof: int) -> None:
        grid = [k for k in ("r", "beta") if getattr(self, k) is not None]
        if grid:
            raise StudyError(
                "points",
                f"give either r and beta grids or points, not both ({grid[0]} is also given)",
            )
        if mode in ("trace", "adaptive"):
            raise StudyError("points", f"mode {mode!r} needs r and beta axes, not a point list")
        with within("points"):
            points = as_points(self.points)
        for k in ("gamma", "kappa"):
            if getattr(points, k) is not None and self.structure is not None:
                raise StudyError(f"points.{k}", "a structure has no chain ratios")
            if getattr(points, k) is not None and dof < 2:
                raise StudyError(f"points.{k}", "dof 1 has no mass or stiffness ratios")
            if isinstance(getattr(self, k), Axis):
                raise StudyError(
                    k,
                    "a sweep cannot be combined with points; give per-point values in a "
                    "points table {r = [...], beta = [...], " + k + " = [...]}",
                )
        object.__setattr__(self, "points", points)

    # ------------------------------------------------------------ derived views
    @property
    def sweeps(self) -> dict[str, Axis]:
        """The swept ratios, in dimension order (gamma before kappa)."""
        return {k: v for k in ("gamma", "kappa") if isinstance(v := getattr(self, k), Axis)}

    @property
    def sweep_shape(self) -> tuple[int, ...]:
        return tuple(len(a) for a in self.sweeps.values())

    @property
    def plane_shape(self) -> tuple[int, ...]:
        """Shape of one (r, beta) plane, (n_points,) for a point list, (n_r,) for tracing."""
        if self.points is not None:
            return (len(self.points),)
        if self.mode == "trace":
            return (len(self.r),)
        return (len(self.r), len(self.beta))

    @property
    def n_points(self) -> int:
        return math.prod(self.sweep_shape) * math.prod(self.plane_shape)

    def scene_at(self, **ratios: float) -> Scene:
        """The :class:`tasks.Scene` with the swept ratios set to ``ratios``."""
        if self.structure is not None:
            return contacts.chain_at(self, ratios) if self.sweeps else self.structure
        fixed = {k: getattr(self, k) for k in ("gamma", "kappa") if k not in self.sweeps}
        return Scene(self.contact, self.dof, self.contact_mass, **{**fixed, **ratios})

    @property
    def base_scene(self) -> Scene:
        """The scene with each sweep at its first value (for labels and checks)."""
        return self.scene_at(**{k: a.first for k, a in self.sweeps.items()})

    def scene_attr(self) -> dict[str, object]:
        """``Scene.to_dict()`` with each swept field given as its list of values
        (a structure: what it is, its matrices being variables of the result)."""
        if contacts.is_multi(self.structure):
            return contacts.scene_attr(self)
        if self.structure is not None:
            return structures.scene_attr(self.structure, self.beam)
        d = self.base_scene.to_dict()
        for k, a in self.sweeps.items():
            d[k] = [float(v) for v in a.values_array()]
        return d

    def to_toml_dict(self) -> dict[str, object]:
        if contacts.is_multi(self.structure) and not fields.is_list(self.contact_mass):
            return {"name": self.name, **contacts.toml_fields(self)} | self._axes_toml()
        if self.structure is not None and not contacts.is_multi(self.structure):
            d = {"name": self.name, **structures.toml_fields(self.structure, self.beam)}
            return d | self._axes_toml()
        d: dict[str, object] = {
            "name": self.name,
            "contact": self.contact,
            "dof": self.dof,
            "contact_mass": self.contact_mass,
        }
        if contacts.is_multi(self.structure):
            d["beta_ratio"] = self.beta_ratio
        for k in ("gamma", "kappa"):
            v = getattr(self, k)
            d[k] = (
                v.to_toml_value()
                if isinstance(v, Axis)
                else (list(v) if isinstance(v, tuple) else v)
            )
        return d | self._axes_toml()

    def _axes_toml(self) -> dict[str, object]:
        d: dict[str, object] = {}
        if self.points is not None:
            d["points"] = self.points.to_toml_value()
        else:
            d["r"] = self.r.to_toml_value()
            d["beta"] = self.beta.to_toml_value()
        if self.mode != "grid":
            d["mode"] = self.mode
        if self.mode == "adaptive":
            d["coarse_step"] = self.coarse_step
            d["verify_fraction"] = self.verify_fraction
            d["hint"] = self.hint
        return d


_SCENE_KEYS = tuple(f.name for f in dataclass_fields(SceneSpec))


def _read_scene(raw: object, path: str, directory: Path) -> SceneSpec:
    """One ``[[scene]]`` table; errors are prefixed with ``path`` (``scene[0]``).

    A ``.npz`` path of ``matrices`` is relative to ``directory`` (the study file's).
    """
    t = _Table(raw, path)
    kw = t.given(tuple(k for k in _SCENE_KEYS if k != "structure"))
    t.finish()
    if "matrices" in kw or "beam" in kw:
        for k in ("dof", "contact_mass"):
            if k in kw:
                raise StudyError(t.at(k), "a structure's DOFs and contact come from its matrices")
        if isinstance(kw.get("matrices"), str):
            kw["matrices"] = str(directory / kw["matrices"])
    mode = kw.get("mode", "grid")
    if mode != "adaptive":
        for k in ADAPTIVE_KEYS:
            if k in kw:
                raise StudyError(t.at(k), f"applies to mode = 'adaptive' only (mode is {mode!r})")
    with within(path):
        spec = SceneSpec(
            name=kw.pop("name", ""),
            contact=kw.pop("contact", None),
            dof=kw.pop("dof", None),
            **kw,
        )
    if spec.points is not None:
        for k in ("gamma", "kappa"):
            if getattr(spec.points, k) is not None and t.has(k):
                raise StudyError(
                    t.at(k), f"must be omitted when the points table gives per-point {k}"
                )
    return spec


# --------------------------------------------------------------------------- the study
def read_study_text(path: Path) -> str:
    """The text of a study file: a regular file of at most ``MAX_STUDY_BYTES`` bytes, UTF-8.

    Never blocks and never reads without end: the entry is looked at before it is
    opened (a FIFO, a device, a directory or a socket is refused), opened without
    blocking, looked at again (it may have been swapped) and read up to the limit.
    """
    where = str(path)
    try:
        st = os.stat(path)
        if not stat.S_ISREG(st.st_mode):
            raise StudyError(
                "", f"a study file must be a regular file, this is {entry_kind(st.st_mode)}", where
            )
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0))
    except FileNotFoundError:
        raise StudyError("", "no such study file", where) from None
    except OSError as exc:
        raise StudyError("", f"cannot read the study file: {exc.strerror}", where) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise StudyError(
                "", f"a study file must be a regular file, this is {entry_kind(st.st_mode)}", where
            )
        with os.fdopen(os.dup(fd), "rb") as f:
            data = f.read(MAX_STUDY_BYTES + 1)
    except OSError as exc:
        raise StudyError("", f"cannot read the study file: {exc.strerror}", where) from None
    finally:
        os.close(fd)
    if len(data) > MAX_STUDY_BYTES:
        raise StudyError(
            "", f"a study file holds at most {MAX_STUDY_BYTES:,} bytes (study.limits)", where
        )
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise StudyError(
            "", f"cannot read the study file: not UTF-8 text ({exc.reason})", where
        ) from None


def _overrides(raw: object) -> tuple[tuple[str, Any], ...]:
    """Setting overrides as ``((name, value), ...)``; numpy scalars become Python ones."""
    items = list(raw.items()) if isinstance(raw, Mapping) else raw
    if not fields.is_list(items):
        raise StudyError(
            "settings", f"must be a table of setting names and values, got {_show(raw)}"
        )
    out = []
    for pair in items:
        if not (fields.is_list(pair) and len(pair) == 2 and isinstance(pair[0], str)):
            raise StudyError("settings", f"must be pairs (name, value), got {_show(pair)}")
        key, value = pair
        out.append((str(key), value.item() if isinstance(value, np.generic) else value))
    return tuple(out)


@dataclass(frozen=True)
class Study:
    """A validated study: scenes, fidelity and solver settings.

    Build it with :meth:`from_toml`, :meth:`from_dict` or directly from
    :class:`SceneSpec` objects: every door validates on construction, with the
    rules and the one-line errors of a study file (``study.max_points: ...``).
    ``overrides`` may be given as a mapping of setting names to values.

    Raises
    ------
    StudyError
        Naming the field: a bad name, fidelity, setting or size, a scene that
        is not a :class:`SceneSpec`, two scenes of one name, too many points.
    """

    name: str
    scenes: tuple[SceneSpec, ...]
    description: str = ""
    fidelity: str = "balanced"
    overrides: tuple[tuple[str, Any], ...] = ()
    max_points: int = DEFAULT_MAX_POINTS
    task_seconds: float = DEFAULT_TASK_SECONDS
    chunk_points: int | None = None
    text: str = field(default="", repr=False, compare=False)
    source: str | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        def put(key: str, value: object) -> None:
            object.__setattr__(self, key, value)

        put("name", _name(self.name, "study.name"))
        put("description", fields.string(self.description, "study.description"))
        put("fidelity", fields.string(self.fidelity, "study.fidelity", tuple(PRESETS)))
        put(
            "max_points",
            fields.integer(self.max_points, "study.max_points", 1, MAX_POINTS_CAP),
        )
        seconds = fields.number(self.task_seconds, "study.task_seconds", 0.0, strict=True)
        lo, hi = TASK_SECONDS_RANGE
        if not lo <= seconds <= hi:
            raise StudyError("study.task_seconds", f"must be in [{lo:g}, {hi:g}], got {seconds:g}")
        put("task_seconds", seconds)
        if self.chunk_points is not None:
            points = fields.integer(self.chunk_points, "study.chunk_points", 1, MAX_CHUNK_POINTS)
            put("chunk_points", points)
        put("overrides", _overrides(self.overrides))
        if not fields.is_list(self.scenes) or len(self.scenes) == 0:
            raise StudyError(
                "scene", f"must be a non-empty list of SceneSpec, got {_show(self.scenes)}"
            )
        seen: dict[str, int] = {}
        for i, s in enumerate(self.scenes):
            if not isinstance(s, SceneSpec):
                raise StudyError(f"scene[{i}]", f"must be a SceneSpec, got {_show(s)}")
            if s.name in seen:
                raise StudyError(
                    f"scene[{i}].name",
                    f"duplicate scene name {s.name!r} (also scene[{seen[s.name]}]); "
                    "give each scene a distinct name",
                )
            seen[s.name] = i
        put("scenes", tuple(self.scenes))
        if not isinstance(self.text, str):
            raise StudyError("text", f"must be a string, got {_show(self.text)}")
        if self.source is not None and not isinstance(self.source, str):
            raise StudyError("source", f"must be a string or None, got {_show(self.source)}")
        self.settings  # noqa: B018  (raises a StudyError naming the setting)
        total = self.n_points
        if total > self.max_points:
            raise StudyError(
                "study.max_points",
                f"the study has {total:,} points, more than the limit {self.max_points:,}; "
                "raise study.max_points to allow it",
            )

    # ------------------------------------------------------------ constructors
    @classmethod
    def from_toml(cls, path: str | os.PathLike) -> Study:
        """Read and validate a study file (``tomllib``); see :func:`read_study_text`."""
        path = Path(path)
        source = path.name
        text = read_study_text(path)
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise StudyError("", f"TOML syntax error: {exc}", source) from None
        except RecursionError:  # tables or arrays nested hundreds deep
            raise StudyError("", "TOML nested too deeply to read", source) from None
        return cls.from_dict(
            data, source=source, text=text, default_name=path.stem, directory=path.parent
        )

    @classmethod
    def from_dict(
        cls,
        data: Mapping[str, object],
        *,
        source: str | None = None,
        text: str | None = None,
        default_name: str = "study",
        directory: str | os.PathLike | None = None,
    ) -> Study:
        """Validate a study given as plain data (the structure of the TOML file).

        ``directory``: where the ``.npz`` files of scenes of matrices are
        (default: the current directory; a study file's own directory for
        :meth:`from_toml`).
        """
        where = Path.cwd() if directory is None else Path(directory)
        try:
            study = cls._parse(data, default_name, where)
            return replace(study, text=text if text is not None else study.to_toml(), source=source)
        except StudyError as exc:
            raise exc.with_source(source) from None

    @classmethod
    def _parse(cls, data: Mapping[str, object], default_name: str, directory: Path) -> Study:
        top = _Table(data, "")
        head = _Table(top.get("study", {}), "study")
        kw = head.given(("description", "fidelity", "max_points", "task_seconds", "chunk_points"))
        name = head.get("name", default_name)
        head.finish()
        settings = top.get("settings", {})
        if not isinstance(settings, Mapping):
            raise StudyError("settings", f"must be a table, got {_show(settings)}")
        raw_scenes = top.get("scene")
        if raw_scenes is None:
            raise StudyError("scene", "at least one [[scene]] table is required")
        if not isinstance(raw_scenes, list) or not raw_scenes:
            raise StudyError("scene", "must be a non-empty array of tables ([[scene]])")
        top.finish()
        scenes = tuple(_read_scene(s, f"scene[{i}]", directory) for i, s in enumerate(raw_scenes))
        return cls(name=name, scenes=scenes, overrides=tuple(settings.items()), **kw)

    def validated(self) -> Study:
        """``self``: a study is validated on construction (kept for older callers)."""
        return self

    def with_fidelity(self, fidelity: str) -> Study:
        """The same study at another fidelity preset (CLI ``--fidelity``)."""
        if fidelity not in PRESETS:
            raise StudyError("--fidelity", f"must be one of {tuple(PRESETS)}, got {fidelity!r}")
        return replace(self, fidelity=fidelity)

    # ------------------------------------------------------------ derived
    @property
    def settings(self) -> Settings:
        """Resolved solver settings (``tasks.fidelity.resolve``)."""
        kinds = {
            "bool": "true or false",
            "int": "an integer",
            "float": "a number",
            "str": "a string",
            "tuple": "a list of names",
        }
        for key, value in self.overrides:
            default = getattr(PRESETS["balanced"], key, None)
            if default is None:
                continue  # unknown names are reported by resolve()
            kind = type(default)
            ok = isinstance(value, kind) and not (kind is not bool and isinstance(value, bool))
            if kind is tuple:
                ok = isinstance(value, list | tuple) and all(isinstance(v, str) for v in value)
            if kind is float:
                ok = fields.is_number(value) and math.isfinite(value)
            if not ok:
                msg = f"must be {kinds[kind.__name__]}, got {_show(value)}"
                raise StudyError(f"settings.{key}", msg, self.source)
        try:
            return resolve(self.fidelity, **dict(self.overrides))
        except ValueError as exc:
            err = field_error("settings", exc)
            if err.field == "settings.fidelity":
                err = StudyError("study.fidelity", err.message)
            raise err.with_source(self.source) from None
        except TypeError as exc:  # e.g. a string where a number is expected
            raise StudyError("settings", str(exc), self.source) from None

    @property
    def n_points(self) -> int:
        return sum(s.n_points for s in self.scenes)

    def to_dict(self) -> dict[str, object]:
        head: dict[str, object] = {"name": self.name, "fidelity": self.fidelity}
        if self.description:
            head["description"] = self.description
        if self.max_points != DEFAULT_MAX_POINTS:
            head["max_points"] = self.max_points
        if self.task_seconds != DEFAULT_TASK_SECONDS:
            head["task_seconds"] = self.task_seconds
        if self.chunk_points is not None:
            head["chunk_points"] = self.chunk_points
        d: dict[str, object] = {"study": head}
        if self.overrides:
            d["settings"] = dict(self.overrides)
        d["scene"] = [s.to_toml_dict() for s in self.scenes]
        return d

    def to_toml(self) -> str:
        """TOML text of the study (provenance for studies built in Python)."""
        lines: list[str] = []
        d = self.to_dict()
        for table in ("study", "settings"):
            if table in d:
                lines.append(f"[{table}]")
                lines += [f"{k} = {_toml_value(v)}" for k, v in d[table].items()]
                lines.append("")
        for s in d["scene"]:
            lines.append("[[scene]]")
            lines += [f"{k} = {_toml_value(v)}" for k, v in s.items()]
            lines.append("")
        return "\n".join(lines)


def _toml_value(v: object) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, Mapping):
        return "{" + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"cannot write {v!r} as TOML")
