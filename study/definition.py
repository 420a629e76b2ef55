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

Every rule broken raises :class:`~study.errors.StudyError` naming the field,
e.g. ``scene[0].r.num: must be an integer >= 1, got -3`` (scenes count from 0
in file order). See README "Study files".
"""

from __future__ import annotations

import json
import math
import re
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from study.errors import StudyError, field_error
from study.limits import check_study
from tasks.fidelity import PRESETS, Settings, resolve
from tasks.scene import Scene

#: Default limit on the number of points of one study (``[study] max_points``).
DEFAULT_MAX_POINTS = 50_000_000
#: Default target duration of one Dask task, in seconds (``[study] task_seconds``).
DEFAULT_TASK_SECONDS = 0.5
MODES = ("grid", "trace", "adaptive")
#: Closed-form hints an adaptive scene can refine around (``analysis.boundaries`` methods).
ADAPTIVE_HINTS = ("exact", "paper", "none")
SPACINGS = ("linear", "log")
_NAME_RE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$")


# --------------------------------------------------------------------------- reading helpers
def _is_number(v: object) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _show(v: object) -> str:
    s = repr(v)
    return s if len(s) <= 60 else s[:57] + "..."


class _Table:
    """Read the keys of one TOML table, then reject any key left over."""

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

    def string(self, key: str, default: str | None = None, choices: Sequence[str] = ()) -> str:
        v = self.get(key, default)
        if v is None:
            raise StudyError(self.at(key), "is required")
        if not isinstance(v, str):
            raise StudyError(self.at(key), f"must be a string, got {_show(v)}")
        if choices and v not in choices:
            raise StudyError(self.at(key), f"must be one of {tuple(choices)}, got {v!r}")
        return v

    def integer(self, key: str, default: int | None = None, minimum: int | None = None) -> int:
        v = self.get(key, default)
        rule = "an integer" + (f" >= {minimum}" if minimum is not None else "")
        if v is None:
            raise StudyError(self.at(key), f"is required ({rule})")
        if not isinstance(v, int) or isinstance(v, bool) or (minimum is not None and v < minimum):
            raise StudyError(self.at(key), f"must be {rule}, got {_show(v)}")
        return v

    def number(self, key: str, default: float | None = None, positive: bool = False) -> float:
        v = self.get(key, default)
        rule = "a positive finite number" if positive else "a finite number"
        if v is None:
            raise StudyError(self.at(key), f"is required ({rule})")
        if not _is_number(v) or not math.isfinite(v) or (positive and v <= 0):
            raise StudyError(self.at(key), f"must be {rule}, got {_show(v)}")
        return float(v)

    def finish(self) -> None:
        unknown = [k for k in self.data if k not in self.used]
        if unknown:
            known = ", ".join(sorted(self.used))
            raise StudyError(self.at(unknown[0]), f"unknown key (known keys here: {known})")


# --------------------------------------------------------------------------- axes and sweeps
@dataclass(frozen=True)
class Axis:
    """One coordinate axis: explicit ``values`` or ``num`` points from ``start`` to ``stop``.

    ``spacing="log"`` spaces the points geometrically (``numpy.geomspace``).
    Values are materialised only by :meth:`values_array`, so a huge axis costs
    nothing to describe.
    """

    start: float | None = None
    stop: float | None = None
    num: int | None = None
    spacing: str = "linear"
    values: tuple[float, ...] | None = None

    def __len__(self) -> int:
        return len(self.values) if self.values is not None else int(self.num)

    def values_array(self) -> np.ndarray:
        """The axis values; generated values are rounded to 15 significant digits.

        ``linspace(0, 1.2, 25)`` gives ``0.9999999999999999`` where the user
        wrote a grid of steps 0.05; rounding puts such values on the decimal
        numbers meant (here exactly 1.0, which matters on a boundary such as
        beta = 1, the motion bound of a ground contact on m_1).
        """
        if self.values is not None:
            return np.asarray(self.values, dtype=np.float64)
        if self.num == 1:
            return np.array([self.start], dtype=np.float64)
        make = np.geomspace if self.spacing == "log" else np.linspace
        raw = make(self.start, self.stop, self.num, dtype=np.float64)
        return np.array([float(f"{v:.15g}") for v in raw], dtype=np.float64)

    def to_toml_value(self) -> dict[str, object]:
        if self.values is not None:
            return {"values": list(self.values)}
        return {"start": self.start, "stop": self.stop, "num": self.num, "spacing": self.spacing}


def _finite_values(raw: object, path: str, lower: float, strict: bool, what: str) -> list[float]:
    if not isinstance(raw, list) or not raw:
        raise StudyError(path, f"must be a non-empty list of numbers, got {_show(raw)}")
    out = []
    for i, v in enumerate(raw):
        ok = _is_number(v) and math.isfinite(v) and (v > lower if strict else v >= lower)
        if not ok:
            raise StudyError(f"{path}[{i}]", f"must be {what}, got {_show(v)}")
        out.append(float(v))
    return out


def _read_axis(raw: object, path: str, lower: float, strict: bool) -> Axis:
    """Parse an axis given as ``{start, stop, num, spacing}``, ``{values}``, a list or a number."""
    what = f"a finite number {'>' if strict else '>='} {lower:g}"
    if _is_number(raw):
        raw = [raw]
    if isinstance(raw, list):
        raw = {"values": raw}
    t = _Table(raw, path)
    if t.has("values"):
        if any(t.has(k) for k in ("start", "stop", "num", "spacing")):
            raise StudyError(path, "give either values or start/stop/num, not both")
        vals = _finite_values(t.get("values"), t.at("values"), lower, strict, what)
        if any(b <= a for a, b in zip(vals, vals[1:], strict=False)):
            raise StudyError(t.at("values"), "must be strictly increasing")
        t.finish()
        return Axis(values=tuple(vals))
    if not t.has("start") and not t.has("stop") and not t.has("num"):
        raise StudyError(path, "needs start, stop and num, or values")
    start = t.number("start")
    if not (start > lower if strict else start >= lower):
        raise StudyError(t.at("start"), f"must be {what}, got {start:g}")
    num = t.integer("num", minimum=1)
    stop = t.number("stop", default=start if num == 1 else None)
    spacing = t.string("spacing", "linear", SPACINGS)
    t.finish()
    if num > 1 and not stop > start:
        raise StudyError(t.at("stop"), f"must be > start ({start:g}), got {stop:g}")
    if spacing == "log" and start <= 0:
        raise StudyError(t.at("start"), f"must be > 0 for log spacing, got {start:g}")
    return Axis(start=start, stop=stop, num=num, spacing=spacing)


@dataclass(frozen=True)
class Points:
    """An explicit list of (r, beta) points, optionally with a uniform gamma/kappa per point."""

    r: tuple[float, ...]
    beta: tuple[float, ...]
    gamma: tuple[float, ...] | None = None
    kappa: tuple[float, ...] | None = None

    def __len__(self) -> int:
        return len(self.r)

    def columns(self) -> dict[str, np.ndarray]:
        cols = {"r": self.r, "beta": self.beta, "gamma": self.gamma, "kappa": self.kappa}
        return {k: np.asarray(v, dtype=np.float64) for k, v in cols.items() if v is not None}

    def to_toml_value(self) -> object:
        if self.gamma is None and self.kappa is None:
            return [[a, b] for a, b in zip(self.r, self.beta, strict=True)]
        return {k: list(v) for k, v in self.columns().items()}


def _read_points(raw: object, path: str, dof: int) -> Points:
    """``[[r, beta], ...]`` or a table of columns ``{r=[...], beta=[...], gamma=[...]}``."""
    rule_r, rule_b = "a finite number > 0", "a finite number >= 0"
    if isinstance(raw, list):
        if not raw:
            raise StudyError(path, "must not be empty")
        rs, bs = [], []
        for i, p in enumerate(raw):
            if not isinstance(p, list) or len(p) != 2:
                raise StudyError(f"{path}[{i}]", f"must be a pair [r, beta], got {_show(p)}")
            r, b = p
            if not (_is_number(r) and math.isfinite(r) and r > 0):
                raise StudyError(f"{path}[{i}][0]", f"r must be {rule_r}, got {_show(r)}")
            if not (_is_number(b) and math.isfinite(b) and b >= 0):
                raise StudyError(f"{path}[{i}][1]", f"beta must be {rule_b}, got {_show(b)}")
            rs.append(float(r))
            bs.append(float(b))
        return Points(tuple(rs), tuple(bs))
    t = _Table(raw, path)
    r = _finite_values(t.get("r"), t.at("r"), 0.0, True, rule_r)
    b = _finite_values(t.get("beta"), t.at("beta"), 0.0, False, rule_b)
    extra = {}
    for name in ("gamma", "kappa"):
        if t.has(name):
            if dof < 2:
                raise StudyError(t.at(name), "dof 1 has no mass or stiffness ratios")
            extra[name] = tuple(
                _finite_values(t.get(name), t.at(name), 0.0, True, "a positive finite number")
            )
    t.finish()
    for name, col in (("beta", b), *extra.items()):
        if len(col) != len(r):
            raise StudyError(t.at(name), f"has {len(col)} entries, but r has {len(r)}")
    return Points(tuple(r), tuple(b), extra.get("gamma"), extra.get("kappa"))


# --------------------------------------------------------------------------- scenes
@dataclass(frozen=True)
class SceneSpec:
    """One scene of a study: a :class:`tasks.Scene` and where to classify it.

    ``gamma``/``kappa`` are either fixed (a number, or one number per mass
    2..N, as in :class:`tasks.Scene`) or an :class:`Axis` *sweep*: a swept
    value sets every ratio 2..N to that value and becomes a dimension of the
    result. Exactly one of (``r`` and ``beta``) or ``points`` is given.
    """

    name: str
    contact: str
    dof: int
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
        fixed = {k: getattr(self, k) for k in ("gamma", "kappa") if k not in self.sweeps}
        return Scene(self.contact, self.dof, self.contact_mass, **{**fixed, **ratios})

    @property
    def base_scene(self) -> Scene:
        """The scene with each sweep at its first value (for labels and checks)."""
        return self.scene_at(**{k: float(a.values_array()[0]) for k, a in self.sweeps.items()})

    def scene_attr(self) -> dict[str, object]:
        """``Scene.to_dict()`` with each swept field given as its list of values."""
        d = self.base_scene.to_dict()
        for k, a in self.sweeps.items():
            d[k] = [float(v) for v in a.values_array()]
        return d

    def to_toml_dict(self) -> dict[str, object]:
        d: dict[str, object] = {
            "name": self.name,
            "contact": self.contact,
            "dof": self.dof,
            "contact_mass": self.contact_mass,
        }
        for k in ("gamma", "kappa"):
            v = getattr(self, k)
            d[k] = (
                v.to_toml_value()
                if isinstance(v, Axis)
                else (list(v) if isinstance(v, tuple) else v)
            )
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


def _read_ratio(t: _Table, key: str, dof: int) -> float | tuple[float, ...] | Axis:
    raw = t.get(key, 1.0)
    path = t.at(key)
    if isinstance(raw, Mapping):
        if dof < 2:
            raise StudyError(path, "dof 1 has no mass or stiffness ratios to sweep")
        return _read_axis(raw, path, 0.0, True)
    if _is_number(raw):
        if not (math.isfinite(raw) and raw > 0):
            raise StudyError(path, f"must be a positive finite number, got {_show(raw)}")
        return float(raw)
    if isinstance(raw, list):
        vals = _finite_values(raw, path, 0.0, True, "a positive finite number")
        if len(vals) != dof - 1:
            raise StudyError(
                path,
                f"a list gives the ratios of masses/springs 2..{dof}, so it needs dof - 1 = "
                f"{dof - 1} entries, got {len(vals)} (to sweep, write {{values = [...]}})",
            )
        return tuple(vals)
    raise StudyError(path, f"must be a number, a list or a sweep table, got {_show(raw)}")


def _read_adaptive(t: _Table, mode: str) -> dict[str, object]:
    """The settings of ``mode = "adaptive"`` (refused with any other mode)."""
    keys = ("coarse_step", "verify_fraction", "hint")
    if mode != "adaptive":
        for k in keys:
            if t.has(k):
                raise StudyError(t.at(k), f"applies to mode = 'adaptive' only (mode is {mode!r})")
        return {}
    out: dict[str, object] = {"coarse_step": t.integer("coarse_step", 16, minimum=1)}
    fraction = t.number("verify_fraction", 0.005)
    if not 0.0 <= fraction <= 1.0:
        raise StudyError(t.at("verify_fraction"), f"must be in [0, 1], got {fraction:g}")
    out["verify_fraction"] = fraction
    out["hint"] = t.string("hint", "exact", ADAPTIVE_HINTS)
    return out


def _read_scene(raw: object, path: str) -> SceneSpec:
    t = _Table(raw, path)
    contact = t.string("contact")
    dof = t.integer("dof", minimum=1)
    contact_mass = t.integer("contact_mass", 1)
    gamma = _read_ratio(t, "gamma", dof)
    kappa = _read_ratio(t, "kappa", dof)
    mode = t.string("mode", "grid", MODES)
    adaptive = _read_adaptive(t, mode)
    name = t.get("name")
    if name is not None and (not isinstance(name, str) or not _NAME_RE.match(name)):
        raise StudyError(
            t.at("name"),
            f"must be a string of letters, digits, '_', '.', '-' (a netCDF group name), "
            f"got {_show(name)}",
        )
    grid = [k for k in ("r", "beta") if t.has(k)]
    points = None
    r_axis = beta_axis = None
    if t.has("points"):
        if grid:
            raise StudyError(
                t.at("points"),
                f"give either r and beta grids or points, not both ({grid[0]} is also given)",
            )
        if mode in ("trace", "adaptive"):
            raise StudyError(
                t.at("points"), f"mode {mode!r} needs r and beta axes, not a point list"
            )
        points = _read_points(t.get("points"), t.at("points"), dof)
        for k, v in (("gamma", gamma), ("kappa", kappa)):
            if isinstance(v, Axis):
                raise StudyError(
                    t.at(k),
                    "a sweep cannot be combined with points; give per-point values in a "
                    "points table {r = [...], beta = [...], " + k + " = [...]}",
                )
    else:
        for k in ("r", "beta"):
            if not t.has(k):
                raise StudyError(t.at(k), "is required (or give points = [[r, beta], ...])")
        r_axis = _read_axis(t.get("r"), t.at("r"), 0.0, True)
        beta_axis = _read_axis(t.get("beta"), t.at("beta"), 0.0, False)
    t.finish()
    spec = SceneSpec(
        name=name or "",
        contact=contact,
        dof=dof,
        contact_mass=contact_mass,
        gamma=gamma,
        kappa=kappa,
        r=r_axis,
        beta=beta_axis,
        points=points,
        mode=mode,
        **adaptive,
    )
    try:  # tasks.Scene checks contact, dof and contact_mass
        base = spec.base_scene
    except ValueError as exc:
        raise field_error(path, exc) from None
    if points is not None:
        for k in ("gamma", "kappa"):
            if getattr(points, k) is not None and t.has(k):
                raise StudyError(
                    t.at(k), f"must be omitted when the points table gives per-point {k}"
                )
    return replace(spec, name=name or base.label)


# --------------------------------------------------------------------------- the study
@dataclass(frozen=True)
class Study:
    """A validated study: scenes, fidelity and solver settings.

    Build it with :meth:`from_toml` or :meth:`from_dict` (both validate), or
    directly from :class:`SceneSpec` objects and then call :meth:`validated`.
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

    # ------------------------------------------------------------ constructors
    @classmethod
    def from_toml(cls, path: str | Path) -> Study:
        """Read and validate a study file (``tomllib``)."""
        path = Path(path)
        source = path.name
        try:
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise StudyError("", "no such study file", str(path)) from None
        except (OSError, UnicodeDecodeError) as exc:
            raise StudyError("", f"cannot read the study file: {exc}", str(path)) from None
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise StudyError("", f"TOML syntax error: {exc}", source) from None
        except RecursionError:  # tables or arrays nested hundreds deep
            raise StudyError("", "TOML nested too deeply to read", source) from None
        return cls.from_dict(data, source=source, text=text, default_name=path.stem)

    @classmethod
    def from_dict(
        cls,
        data: Mapping[str, object],
        *,
        source: str | None = None,
        text: str | None = None,
        default_name: str = "study",
    ) -> Study:
        """Validate a study given as plain data (the structure of the TOML file)."""
        try:
            study = cls._parse(data, default_name)
        except StudyError as exc:
            raise exc.with_source(source) from None
        return replace(study, text=text if text is not None else study.to_toml(), source=source)

    @classmethod
    def _parse(cls, data: Mapping[str, object], default_name: str) -> Study:
        top = _Table(data, "")
        head = _Table(top.get("study", {}), "study")
        name = head.string("name", default_name)
        if not _NAME_RE.match(name):
            raise StudyError("study.name", f"must be letters, digits, '_', '.', '-', got {name!r}")
        description = head.string("description", "")
        fidelity = head.string("fidelity", "balanced", tuple(PRESETS))
        max_points = head.integer("max_points", DEFAULT_MAX_POINTS, minimum=1)
        task_seconds = head.number("task_seconds", DEFAULT_TASK_SECONDS, positive=True)
        chunk_points = head.get("chunk_points")
        if chunk_points is not None:
            chunk_points = head.integer("chunk_points", minimum=1)
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
        scenes = tuple(_read_scene(s, f"scene[{i}]") for i, s in enumerate(raw_scenes))
        study = cls(
            name=name,
            scenes=scenes,
            description=description,
            fidelity=fidelity,
            overrides=tuple(settings.items()),
            max_points=max_points,
            task_seconds=task_seconds,
            chunk_points=chunk_points,
        )
        return study.validated()

    def validated(self) -> Study:
        """Check the whole-study rules (names, settings, size); return ``self``."""
        check_study(self)  # ranges and sizes the numerics support (study.limits)
        seen: dict[str, int] = {}
        for i, s in enumerate(self.scenes):
            if s.name in seen:
                raise StudyError(
                    f"scene[{i}].name",
                    f"duplicate scene name {s.name!r} (also scene[{seen[s.name]}]); "
                    "give each scene a distinct name",
                )
            seen[s.name] = i
        self.settings  # noqa: B018  (raises a StudyError naming the setting)
        total = self.n_points
        if total > self.max_points:
            raise StudyError(
                "study.max_points",
                f"the study has {total:,} points, more than the limit {self.max_points:,}; "
                "raise study.max_points to allow it",
            )
        return self

    def with_fidelity(self, fidelity: str) -> Study:
        """The same study at another fidelity preset (CLI ``--fidelity``)."""
        if fidelity not in PRESETS:
            raise StudyError("--fidelity", f"must be one of {tuple(PRESETS)}, got {fidelity!r}")
        return replace(self, fidelity=fidelity).validated()

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
                ok = _is_number(value) and math.isfinite(value)
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
