"""Limits of a study, checked on construction, before anything is allocated or computed.

:mod:`study.fields` checks the type of each value; this module holds the ranges
the numerics support and the sizes the machine can hold, so that a well-formed
study never fails after compute and never swells before it:

* ratios: r in ``tasks.classifier.R_RANGE`` (1e-4..1e4), beta in
  0..``BETA_MAX`` (1e6), every gamma and kappa (sweeps and per-point values
  included) in ``tasks.scene.RATIO_RANGE`` (1e-6..1e6); solver settings in
  ``tasks.fidelity.LIMITS``;
* sizes: an axis (r, beta or a gamma/kappa sweep) or a point list of at most
  :data:`MAX_AXIS` values, checked on its ``num`` before any value is made; at
  most :data:`MAX_POINTS_CAP` points even with ``max_points`` raised;
  ``chunk_points`` and ``task_seconds`` in range;
* names of at most :data:`MAX_NAME` characters (they become file and netCDF
  group names);
* a study file: a regular file (never a FIFO, device or directory, which would
  block or never end) of at most :data:`MAX_STUDY_BYTES` bytes;
* a traced scene (``mode = "trace"``) needs at least two beta values (the
  bisection tolerance is half the beta step).

The checks are called by ``Axis``, ``Points``, ``SceneSpec`` and ``Study``
(:mod:`study.definition`) when they are built; every violation raises
:class:`~study.errors.StudyError` naming the field. This module imports nothing
of the study layer but its errors (no import circle).
"""

from __future__ import annotations

import stat

from study.errors import StudyError
from tasks.classifier import BETA_MAX, R_RANGE
from tasks.scene import RATIO_RANGE

__all__ = [
    "BETA_MAX",
    "MAX_AXIS",
    "MAX_CHUNK_POINTS",
    "MAX_NAME",
    "MAX_POINTS_CAP",
    "MAX_STUDY_BYTES",
    "RATIO_RANGE",
    "R_RANGE",
    "TASK_SECONDS_RANGE",
    "check_name",
    "check_range",
    "check_size",
    "entry_kind",
]

#: Longest study or scene name: names become file names (``NAME.nc``,
#: ``NAME-0000001-<hash>.npz``) and netCDF group names; 255 bytes is the usual
#: limit of one file name.
MAX_NAME = 100
#: Most values of one axis (r, beta or a sweep) or one point list: held in memory.
MAX_AXIS = 1_000_000
#: Most points of a study even with ``[study] max_points`` raised (the result
#: file holds about 40 bytes per point).
MAX_POINTS_CAP = 10_000_000_000
#: Range of ``[study] task_seconds``.
TASK_SECONDS_RANGE = (0.01, 3600.0)
#: Most points of one task (``[study] chunk_points``).
MAX_CHUNK_POINTS = 10_000_000
#: Largest study file read, in bytes (16 MiB: a point list of about 500,000 pairs).
MAX_STUDY_BYTES = 16 * 1024 * 1024


def check_name(name: str, field: str) -> None:
    """At most :data:`MAX_NAME` characters."""
    if len(name) > MAX_NAME:
        raise StudyError(field, f"must be at most {MAX_NAME} characters, got {len(name)}")


def check_range(ends: tuple[float, float], field: str, lo: float, hi: float, what: str) -> None:
    """``ends`` = (smallest, largest) of a field; both must be in [lo, hi]."""
    for v in ends:
        if not lo <= v <= hi:
            raise StudyError(field, f"{what} must be in [{lo:g}, {hi:g}], got {v:g}")


def check_size(n: int, field: str) -> None:
    """An axis or point list of at most :data:`MAX_AXIS` values (``n`` may be any int)."""
    if n > MAX_AXIS:
        raise StudyError(field, f"an axis holds at most {MAX_AXIS:,} values, got {n:,}")


def entry_kind(mode: int) -> str:
    """What a file system entry that is not a regular file is (for a message)."""
    kinds = {
        stat.S_IFDIR: "a directory",
        stat.S_IFIFO: "a FIFO (named pipe)",
        stat.S_IFCHR: "a character device",
        stat.S_IFBLK: "a block device",
        stat.S_IFSOCK: "a socket",
    }
    return kinds.get(stat.S_IFMT(mode), "not a regular file")
