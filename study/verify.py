"""The work folder is verified, not trusted: what a chunk file must hold to be reused.

Every chunk file (:mod:`study.store`) stores, beside its arrays,

* ``_key``: the chunk key it was computed for (a file copied or renamed under
  another chunk's name is caught);
* ``_version``: :func:`simulator_version`, a hash of the simulator's source
  files (``tasks/*.py``, ``study/compute.py``, ``study/trace.py``); it is also
  part of every chunk key (:mod:`study.chunks`), so chunks computed by another
  version of the code are never reused;
* ``_checksum``: SHA-256 of the arrays' names, dtypes, shapes and bytes
  (truncation, bit flips, garbage).

A valid checksum only says the file is what some run wrote; the plan says what
it must hold (:meth:`study.chunks.ScenePlan.expected`: every field, its dtype
and its shape), so a file re-signed with other shapes, a missing field or
another dtype is refused too. :func:`check_chunk` returns why a file fails (or
None); the run reports each failing file by path, moves it aside and computes
the chunk again.
"""

from __future__ import annotations

import hashlib
import zipfile
from functools import lru_cache
from pathlib import Path

import numpy as np

#: Metadata entries of a chunk file (not result arrays).
META = ("_key", "_version", "_checksum")
_ROOT = Path(__file__).resolve().parents[1]
#: Source files whose content defines the simulator's results.
SIMULATOR_SOURCES = ("tasks/*.py", "study/compute.py", "study/trace.py")
#: What a unit's file must hold: field -> (dtype, shape); a shape of None means
#: any shape (bookkeeping of variable length, e.g. an adaptive plane's levels).
Expected = dict[str, tuple[str, tuple[int, ...] | None]]


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


def with_metadata(key: str, arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``arrays`` plus the metadata entries a chunk file stores."""
    return {
        **arrays,
        "_key": np.array(key),
        "_version": np.array(simulator_version()),
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


def check_layout(arrays: dict[str, np.ndarray], expected: Expected) -> str | None:
    """Why ``arrays`` do not hold every field of ``expected`` with its dtype and shape."""
    for name, (dtype, shape) in expected.items():
        if name not in arrays:
            return f"has no field {name!r}"
        a = np.asarray(arrays[name])
        if a.dtype != np.dtype(dtype):
            return f"field {name!r} is {a.dtype}, expected {np.dtype(dtype)}"
        if shape is not None and a.shape != tuple(shape):
            return f"field {name!r} has shape {a.shape}, expected {tuple(shape)}"
    return None


def check_arrays(
    arrays: dict[str, np.ndarray], key: str, expected: Expected | None = None
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
    return check_layout(arrays, expected) if expected is not None else None


def check_chunk(path: Path, key: str, expected: Expected | None = None) -> str | None:
    """Why the chunk file at ``path`` cannot be reused as chunk ``key``, or None if it can."""
    if not path.is_file() or path.is_symlink() and not path.exists():
        return "is not a regular file"
    try:
        arrays = read_chunk(path)
    except ValueError as exc:
        return str(exc)
    return check_arrays(arrays, key, expected)
