"""Checks of single field values, shared by the study file reader and the classes.

One home for the type rules of every door (a TOML study file, ``Study.from_dict``,
``Study(...)``, ``SceneSpec(...)``, ``Axis(...)``, ``Points(...)``):

* a number is a real number, Python's or numpy's (``np.int64(3)``,
  ``np.float32(0.5)``), never a bool nor a string;
* an integer is a Python or numpy integer, never a bool nor a float (``2.0``);
* a list of numbers is a list, a tuple or a one-dimensional numpy array.

Each check returns the value as a plain Python ``int``/``float``/``tuple`` (so
studies compare, hash and print the same whichever door they came through) or
raises :class:`~study.errors.StudyError` naming the field, in one line.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from contextlib import contextmanager
from numbers import Integral, Real

import numpy as np

from study.errors import StudyError


def is_number(v: object) -> bool:
    """A real number (Python or numpy), not a bool."""
    return isinstance(v, Real) and not isinstance(v, bool | np.bool_)


def is_integer(v: object) -> bool:
    """An integer (Python or numpy), not a bool."""
    return isinstance(v, Integral) and not isinstance(v, bool | np.bool_)


def is_list(v: object) -> bool:
    """A list, a tuple or a one-dimensional numpy array (not a string)."""
    if isinstance(v, np.ndarray):
        return v.ndim == 1
    return isinstance(v, list | tuple)


def show(v: object) -> str:
    """``repr(v)`` cut to 60 characters (error messages stay one short line)."""
    try:
        s = repr(v)
    except Exception:  # noqa: BLE001 - a broken __repr__ must not hide the real error
        s = f"<{type(v).__name__}>"
    s = " ".join(s.split())
    return s if len(s) <= 60 else s[:57] + "..."


def string(v: object, field: str, choices: Sequence[str] = ()) -> str:
    """A string (one of ``choices`` when given)."""
    if v is None:
        raise StudyError(field, "is required (a string)")
    if not isinstance(v, str):
        raise StudyError(field, f"must be a string, got {show(v)}")
    if choices and v not in choices:
        raise StudyError(field, f"must be one of {tuple(choices)}, got {v!r}")
    return str(v)


def integer(v: object, field: str, minimum: int | None = None, maximum: int | None = None) -> int:
    """An integer in ``[minimum, maximum]`` (either end optional)."""
    rule = "an integer" + (f" >= {minimum}" if minimum is not None else "")
    if v is None:
        raise StudyError(field, f"is required ({rule})")
    if not is_integer(v) or (minimum is not None and v < minimum):
        raise StudyError(field, f"must be {rule}, got {show(v)}")
    if maximum is not None and v > maximum:
        raise StudyError(field, f"must be at most {maximum:,}, got {int(v):,}")
    return int(v)


def number(v: object, field: str, lower: float | None = None, strict: bool = False) -> float:
    """A finite number, ``> lower`` (``strict``) or ``>= lower`` when ``lower`` is given."""
    rule = "a finite number" + ("" if lower is None else f" {'>' if strict else '>='} {lower:g}")
    if v is None:
        raise StudyError(field, f"is required ({rule})")
    try:
        ok = is_number(v) and math.isfinite(v)
    except OverflowError:  # an integer beyond any float
        ok = False
    if ok and lower is not None:
        ok = v > lower if strict else v >= lower
    if not ok:
        raise StudyError(field, f"must be {rule}, got {show(v)}")
    return float(v)


def numbers(
    v: object, field: str, lower: float | None = None, strict: bool = False, limit: int = 0
) -> tuple[float, ...]:
    """A non-empty list of finite numbers (each as :func:`number`), of at most ``limit``."""
    if not is_list(v) or len(v) == 0:
        raise StudyError(field, f"must be a non-empty list of numbers, got {show(v)}")
    if limit and len(v) > limit:
        raise StudyError(field, f"holds at most {limit:,} values, got {len(v):,}")
    return tuple(number(x, f"{field}[{i}]", lower, strict) for i, x in enumerate(v))


@contextmanager
def within(path: str):
    """Re-home a :class:`StudyError` raised inside under ``path`` (``r`` -> ``scene[0].r``)."""
    try:
        yield
    except StudyError as exc:
        sub = exc.field
        if sub and path:
            sub = f"{path}{sub}" if sub.startswith("[") else f"{path}.{sub}"
        raise StudyError(sub or path, exc.message, exc.source) from None
