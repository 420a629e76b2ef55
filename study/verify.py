"""The work folder is verified, not trusted: what a chunk file must hold to be reused.

Every chunk file (:mod:`study.store`) stores, beside its arrays,

* ``_key``: the chunk key it was computed for (a file copied or renamed under
  another chunk's name is caught);
* ``_version``: :func:`simulator_version`, a hash of the simulator's source
  files (``tasks/*.py``, ``study/compute.py``, ``study/trace.py``); it is also
  part of every chunk key (:mod:`study.chunks`), so chunks computed by another
  version of the code are never reused;
* ``_shape``: the shape of its arrays (checked against the chunk's block);
* ``_checksum``: SHA-256 of the arrays' names, dtypes, shapes and bytes
  (truncation, bit flips, garbage).

:func:`check_chunk` returns why a file fails (or None); the run reports each
failing file by path, deletes it and computes the chunk again.
"""

from __future__ import annotations

import hashlib
import zipfile
from functools import lru_cache
from pathlib import Path

import numpy as np

from study.trace import TRACE_FIELDS
from tasks.adaptive import ADAPTIVE_FIELDS
from tasks.result import FIELDS, MASS_FIELDS

#: Metadata entries of a chunk file (not result arrays).
META = ("_key", "_version", "_shape", "_checksum")
_ROOT = Path(__file__).resolve().parents[1]
#: Source files whose content defines the simulator's results.
SIMULATOR_SOURCES = ("tasks/*.py", "study/compute.py", "study/trace.py")


@lru_cache(maxsize=1)
def simulator_version() -> str:
    """A 16-hex-digit hash of the simulator's source files (changes with any edit)."""
    h = hashlib.sha256()
    for pattern in SIMULATOR_SOURCES:
        for path in sorted(_ROOT.glob(pattern)):
            h.update(path.relative_to(_ROOT).as_posix().encode())
            h.update(path.read_bytes())
    return h.hexdigest()[:16]


def checksum(arrays: dict[str, np.ndarray]) -> str:
    """SHA-256 over the names, dtypes, shapes and bytes of the result arrays."""
    h = hashlib.sha256()
    for name in sorted(k for k in arrays if k not in META):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def data_shape(arrays: dict[str, np.ndarray]) -> tuple[int, ...]:
    """The common shape of the non-scalar result arrays (``seconds`` is 0-d; per-mass
    fields of ``tasks.result.MASS_FIELDS`` have one more, trailing axis: the mass)."""
    shapes = {
        np.shape(v)[:-1] if k in MASS_FIELDS else np.shape(v)
        for k, v in arrays.items()
        # result fields only, not bookkeeping (``seconds``, an adaptive plane's levels)
        if k in FIELDS or k in ADAPTIVE_FIELDS or k in TRACE_FIELDS
    }
    if len(shapes) != 1:
        raise ValueError(f"chunk arrays of different shapes: {sorted(shapes)}")
    return shapes.pop()


def with_metadata(key: str, arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``arrays`` plus the metadata entries a chunk file stores."""
    return {
        **arrays,
        "_key": np.array(key),
        "_version": np.array(simulator_version()),
        "_shape": np.array(data_shape(arrays), dtype=np.int64),
        "_checksum": np.array(checksum(arrays)),
    }


def read_chunk(path: Path) -> dict[str, np.ndarray]:
    """All entries of a chunk file (raises ``ValueError`` with the reason if unreadable)."""
    try:
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except (OSError, EOFError, ValueError, KeyError, zipfile.BadZipFile, RuntimeError) as exc:
        text = str(exc).splitlines()[0] if str(exc) else ""
        raise ValueError(f"unreadable ({type(exc).__name__}: {text[:80]})") from None


def check_arrays(
    arrays: dict[str, np.ndarray], key: str, shape: tuple[int, ...] | None = None
) -> str | None:
    """Why the loaded entries of a chunk file cannot be reused as chunk ``key``, or None."""
    missing = [m for m in META if m not in arrays]
    if missing:
        return f"no {missing[0]} entry (written by an older version, or not a chunk)"
    if str(arrays["_key"]) != key:
        return f"holds chunk {str(arrays['_key'])[:80]!r}, not {key!r}"
    if str(arrays["_version"]) != simulator_version():
        return f"computed by another simulator version ({str(arrays['_version'])[:16]})"
    if str(arrays["_checksum"]) != checksum(arrays):
        return "checksum mismatch (the file was altered or damaged)"
    stored = tuple(int(n) for n in np.atleast_1d(arrays["_shape"]))
    try:
        actual = data_shape(arrays)
    except ValueError as exc:
        return str(exc)
    if actual != stored:
        return f"arrays of shape {actual}, but the file says {stored}"
    if shape is not None and tuple(shape) != actual:
        return f"arrays of shape {actual}, but the chunk has shape {tuple(shape)}"
    return None


def check_chunk(path: Path, key: str, shape: tuple[int, ...] | None = None) -> str | None:
    """Why the chunk file at ``path`` cannot be reused as chunk ``key``, or None if it can."""
    try:
        arrays = read_chunk(path)
    except ValueError as exc:
        return str(exc)
    return check_arrays(arrays, key, shape)


def chunk_shape(kind: str, rows: tuple[int, int], cols: tuple[int, int]) -> tuple[int, ...] | None:
    """Shape of a chunk's arrays: (rows, cols) of a grid block, (rows,) of a point list
    or traced scene; None (not checked) for another kind."""
    n = rows[1] - rows[0]
    if kind == "grid":
        return (n, cols[1] - cols[0])
    return (n,) if kind in ("points", "trace") else None
