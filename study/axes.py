"""Where a scene is classified: an :class:`Axis` of values or a list of :class:`Points`.

Both validate on construction (the same rules whether they come from a study
file or from Python) and are checked against the size limit
(:data:`study.limits.MAX_AXIS`) before any value is made: an axis of
``num = 2**63 - 1`` is refused in microseconds, never allocated. Errors are
:class:`~study.errors.StudyError` naming the field relative to the axis
(``num``, ``values[3]``); a scene prefixes where the axis lives
(``scene[0].r.num``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from study import fields
from study.errors import StudyError
from study.limits import BETA_MAX, MAX_AXIS, R_RANGE, RATIO_RANGE, check_range, check_size

SPACINGS = ("linear", "log")


def _round15(v: float) -> float:
    """``v`` rounded to 15 significant digits (see :meth:`Axis.values_array`)."""
    return float(f"{v:.15g}")


@dataclass(frozen=True)
class Axis:
    """One coordinate axis: explicit ``values`` or ``num`` points from ``start`` to ``stop``.

    ``spacing="log"`` spaces the points geometrically (``numpy.geomspace``).
    Values are materialised only by :meth:`values_array`, so a huge axis costs
    nothing to describe; at most :data:`study.limits.MAX_AXIS` values.

    Parameters
    ----------
    start, stop : float
        First and last value (``stop > start``; ``stop`` may be omitted when ``num = 1``).
    num : int
        Number of values, 1..``MAX_AXIS``.
    spacing : {"linear", "log"}
        ``"log"`` needs ``start > 0``.
    values : sequence of float
        Explicit values, strictly increasing (instead of start/stop/num).

    Raises
    ------
    StudyError
        Naming the field, e.g. ``num: must be an integer >= 1, got 0``.
    """

    start: float | None = None
    stop: float | None = None
    num: int | None = None
    spacing: str = "linear"
    values: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        given = [k for k in ("start", "stop", "num") if getattr(self, k) is not None]
        set_ = object.__setattr__
        if self.values is not None:
            if given:
                raise StudyError("", "give either values or start/stop/num, not both")
            if fields.string(self.spacing, "spacing", SPACINGS) != "linear":
                raise StudyError("spacing", "applies to start/stop/num, not to values")
            vals = fields.numbers(self.values, "values", limit=MAX_AXIS)
            if any(b <= a for a, b in zip(vals, vals[1:], strict=False)):
                raise StudyError("values", "must be strictly increasing")
            set_(self, "values", vals)
            return
        if not given:
            raise StudyError("", "needs start, stop and num, or values")
        num = fields.integer(self.num, "num", minimum=1)
        check_size(num, "num")  # before anything is made of it
        start = fields.number(self.start, "start")
        stop = fields.number(start if self.stop is None and num == 1 else self.stop, "stop")
        spacing = fields.string(self.spacing, "spacing", SPACINGS)
        if num > 1 and not stop > start:
            raise StudyError("stop", f"must be > start ({start:g}), got {stop:g}")
        if spacing == "log" and start <= 0:
            raise StudyError("start", f"must be > 0 for log spacing, got {start:g}")
        for k, v in (("start", start), ("stop", stop), ("num", num), ("spacing", spacing)):
            set_(self, k, v)

    def __len__(self) -> int:
        return len(self.values) if self.values is not None else int(self.num)

    @property
    def first(self) -> float:
        """``values_array()[0]``, without building the axis."""
        if self.values is not None:
            return self.values[0]
        return self.start if self.num == 1 else _round15(self.start)

    @property
    def ends(self) -> tuple[float, float]:
        """Smallest and largest value, without building the axis."""
        if self.values is not None:
            return self.values[0], self.values[-1]
        return self.start, self.stop

    def check_bound(self, lower: float, strict: bool) -> None:
        """Every value ``> lower`` (``strict``) or ``>= lower``; names ``start``/``values[i]``."""
        rule = f"a finite number {'>' if strict else '>='} {lower:g}"
        if self.values is None:
            fields.number(self.start, "start", lower, strict)
            return
        for i, v in enumerate(self.values):
            if not (v > lower if strict else v >= lower):
                raise StudyError(f"values[{i}]", f"must be {rule}, got {fields.show(v)}")

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
        return np.array([_round15(v) for v in raw], dtype=np.float64)

    def to_toml_value(self) -> dict[str, object]:
        if self.values is not None:
            return {"values": list(self.values)}
        return {"start": self.start, "stop": self.stop, "num": self.num, "spacing": self.spacing}


@dataclass(frozen=True)
class Points:
    """An explicit list of (r, beta) points, optionally with a uniform gamma/kappa per point.

    Every column holds the same number of finite values (at most
    :data:`study.limits.MAX_AXIS`): r in ``R_RANGE``, beta in 0..``BETA_MAX``,
    gamma and kappa in ``RATIO_RANGE`` (:mod:`study.limits`).

    Raises
    ------
    StudyError
        Naming the column, e.g. ``beta: has 1 entries, but r has 2``.
    """

    r: tuple[float, ...]
    beta: tuple[float, ...]
    gamma: tuple[float, ...] | None = None
    kappa: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        rules = {
            "r": (0.0, True, R_RANGE),
            "beta": (0.0, False, (0.0, BETA_MAX)),
            "gamma": (0.0, True, RATIO_RANGE),
            "kappa": (0.0, True, RATIO_RANGE),
        }
        n = None
        for key, (lower, strict, (lo, hi)) in rules.items():
            raw = getattr(self, key)
            if raw is None and key in ("gamma", "kappa"):
                continue
            col = fields.numbers(raw, key, lower, strict, limit=MAX_AXIS)
            if n is not None and len(col) != n:
                raise StudyError(key, f"has {len(col)} entries, but r has {n}")
            n = len(col)
            check_range((min(col), max(col)), key, lo, hi, f"every {key}")
            object.__setattr__(self, key, col)

    def __len__(self) -> int:
        return len(self.r)

    def columns(self) -> dict[str, np.ndarray]:
        cols = {"r": self.r, "beta": self.beta, "gamma": self.gamma, "kappa": self.kappa}
        return {k: np.asarray(v, dtype=np.float64) for k, v in cols.items() if v is not None}

    def to_toml_value(self) -> object:
        if self.gamma is None and self.kappa is None:
            return [[a, b] for a, b in zip(self.r, self.beta, strict=True)]
        return {k: list(v) for k, v in self.columns().items()}
