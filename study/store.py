"""The work folder beside the output (``OUT.nc.work/``): one ``.npz`` file per finished chunk.

Each chunk is written atomically (``np.savez`` to a temporary file in the same
folder, flushed to disk, then ``os.replace``), so a crash, Ctrl-C or a killed
client never leaves a half-written chunk under its final name: a chunk file
either exists complete or not at all. A temporary file left by a process that
died mid-write is deleted by the next run (:meth:`WorkDir.clean`). The folder
is removed only after the final netCDF file is in place.

Chunk files are verified, not trusted (:mod:`study.verify`): each stores its
key, shape, simulator version and a checksum; :meth:`WorkDir.discard_if_bad`
deletes a file that fails (the run reports it and computes the chunk again),
and :meth:`WorkDir.load` refuses one.

One run at a time owns a work folder (:meth:`WorkDir.lock`, an advisory
``flock`` on ``.lock``), so two runs of the same output cannot delete each
other's temporary files.
"""

from __future__ import annotations

import os
import shutil
from glob import escape as glob_escape
from pathlib import Path

import numpy as np

from study.errors import StudyFailed
from study.verify import META, check_arrays, check_chunk, read_chunk, with_metadata

try:
    import fcntl
except ImportError:  # pragma: no cover - not on POSIX
    fcntl = None

#: Suffix of every temporary file written by the study layer.
TMP_SUFFIX = ".tmp"


def fsync_dir(path: Path) -> None:
    """Flush a directory entry (a rename) to disk, where the platform allows it."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def temporary_outputs(output: str | os.PathLike) -> list[Path]:
    """Temporary result files of ``output`` (``.OUT.nc.PID.tmp``) left by a killed run."""
    output = Path(output)
    return sorted(output.parent.glob(f".{glob_escape(output.name)}.*{TMP_SUFFIX}"))


class WorkDir:
    """Chunk results of one study run, keyed by the stable chunk key."""

    def __init__(self, output: str | os.PathLike) -> None:
        output = Path(output)
        self.path = output.with_name(output.name + ".work")
        self._lock_fd: int | None = None

    def chunk_path(self, scene: str, key: str) -> Path:
        return self.path / scene / f"{key}.npz"

    def has(self, scene: str, key: str) -> bool:
        return self.chunk_path(scene, key).is_file()

    def save(self, scene: str, key: str, arrays: dict[str, np.ndarray]) -> Path:
        """Write one chunk atomically (temporary file, fsync, ``os.replace``), with its
        key, shape, simulator version and checksum (:func:`study.verify.with_metadata`)."""
        arrays = with_metadata(key, arrays)
        final = self.chunk_path(scene, key)
        final.parent.mkdir(parents=True, exist_ok=True)
        tmp = final.with_name(f".{final.name}.{os.getpid()}{TMP_SUFFIX}")
        try:
            with open(tmp, "wb") as f:
                np.savez(f, **arrays)
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, final)
        except BaseException:  # KeyboardInterrupt included: never leave the temporary file
            tmp.unlink(missing_ok=True)
            raise
        return final

    def load(self, scene: str, key: str) -> dict[str, np.ndarray]:
        """The result arrays of a chunk, verified (``StudyFailed`` naming the file if not)."""
        path = self.chunk_path(scene, key)
        try:
            arrays = read_chunk(path)
            why = check_arrays(arrays, key)
        except ValueError as exc:
            why = str(exc)
        if why:
            path.unlink(missing_ok=True)
            raise StudyFailed(f"chunk file {path} {why}; it was deleted, rerun to compute it")
        return {k: v for k, v in arrays.items() if k not in META}

    def discard_if_bad(self, scene: str, key: str, shape: tuple[int, ...] | None) -> str | None:
        """Verify a chunk file on disk; delete it and return why if it fails, else None."""
        path = self.chunk_path(scene, key)
        why = check_chunk(path, key, shape)
        if why:
            path.unlink(missing_ok=True)
        return why

    def count(self) -> int:
        """Number of chunk files on disk (any study)."""
        if not self.path.is_dir():
            return 0
        return sum(1 for _ in self.path.glob("*/*.npz"))

    def temporary_files(self) -> list[Path]:
        """Temporary files in the work folder (left by a process killed mid-write)."""
        if not self.path.is_dir():
            return []
        return sorted(self.path.glob(f"*/.*{TMP_SUFFIX}"))

    def clean(self) -> int:
        """Delete temporary files left by a dead run; call it holding the lock."""
        stale = self.temporary_files()
        for p in stale:
            p.unlink(missing_ok=True)
        return len(stale)

    def lock(self) -> bool:
        """Take the advisory lock of the work folder (created if needed).

        Returns False if another process holds it; True if it is taken (or
        locking is not supported here, e.g. a file system without ``flock``).
        """
        self.path.mkdir(parents=True, exist_ok=True)
        if fcntl is None or self._lock_fd is not None:
            return True
        fd = os.open(self.path / ".lock", os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            return False
        except OSError:  # no locking on this file system: run unprotected
            os.close(fd)
            return True
        self._lock_fd = fd
        return True

    def unlock(self) -> None:
        if self._lock_fd is not None:
            os.close(self._lock_fd)  # releases the flock
            self._lock_fd = None

    def remove(self) -> None:
        shutil.rmtree(self.path, ignore_errors=True)
        self.unlock()
