"""The work folder beside the output (``OUT.nc.work/``): one ``.npz`` file per finished chunk.

Each chunk is written atomically (``np.savez`` to a temporary file in the same
folder, flushed to disk, then ``os.replace``), so a crash, Ctrl-C or a killed
client never leaves a half-written chunk under its final name: a chunk file
either exists complete or not at all. A temporary file left by a process that
died mid-write is deleted by the next run (:meth:`WorkDir.clean`). The folder
is removed only after the final netCDF file is in place.

Chunk files are verified, not trusted (:mod:`study.verify`): each stores its
key, simulator version and a checksum, and must hold the fields, dtypes and
shapes its plan expects; :meth:`WorkDir.reuse` discards a file that fails (the
run names it in one line and computes the chunk again), and
:meth:`WorkDir.load` refuses one. Anything else where a chunk or a scene folder
belongs (a directory, a FIFO, a file where a scene folder should be) is
discarded the same way by :meth:`WorkDir.scan`.

One run at a time owns an output (:meth:`WorkDir.lock`, an advisory ``flock`` on
``.OUT.nc.lock`` beside the output, not inside the work folder: deleting the
work folder mid-run does not let a second run start on the same output).
"""

from __future__ import annotations

import os
import shutil
from glob import escape as glob_escape
from pathlib import Path

import numpy as np

from study.errors import StudyFailed
from study.verify import META, Expected, check_arrays, check_chunk, read_chunk, with_metadata

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


def os_cause(exc: BaseException) -> str:
    """The cause of an OS error in a few words (``No space left on device``)."""
    text = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
    return " ".join(str(text).split())


def discard(path: Path) -> None:
    """Remove whatever file system entry is at ``path`` (file, link, FIFO, directory)."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


class WorkDir:
    """Chunk results of one study run, keyed by the stable chunk key.

    ``report`` receives one line per discarded entry of the work folder.
    """

    def __init__(self, output: str | os.PathLike, report=None) -> None:
        output = Path(output)
        self.path = output.with_name(output.name + ".work")
        self.lock_path = output.with_name(f".{output.name}.lock")
        self.report = report or (lambda line: None)
        self._lock_fd: int | None = None

    def chunk_path(self, scene: str, key: str) -> Path:
        return self.path / scene / f"{key}.npz"

    def has(self, scene: str, key: str) -> bool:
        return self.chunk_path(scene, key).is_file()

    def save(self, scene: str, key: str, arrays: dict[str, np.ndarray]) -> Path:
        """Write one chunk atomically (temporary file, fsync, ``os.replace``), with its
        key, simulator version and checksum (:func:`study.verify.with_metadata`)."""
        arrays = with_metadata(key, arrays)
        final = self.chunk_path(scene, key)
        tmp = final.with_name(f".{final.name}.{os.getpid()}{TMP_SUFFIX}")
        try:
            for attempt in range(3):  # the folder deleted under us: made again
                try:
                    final.parent.mkdir(parents=True, exist_ok=True)
                    with open(tmp, "wb") as f:
                        np.savez(f, **arrays)
                        f.flush()
                        os.fsync(f.fileno())
                    os.replace(tmp, final)
                    break
                except FileNotFoundError:
                    if attempt == 2:
                        raise
        except OSError as exc:  # no space, permission, I/O error: one line, nothing lost
            tmp.unlink(missing_ok=True)
            raise StudyFailed(
                f"cannot save {final}: {os_cause(exc)}; the chunks saved so far are kept "
                f"in {self.path}, rerun to resume"
            ) from None
        except BaseException:  # KeyboardInterrupt included: never leave the temporary file
            tmp.unlink(missing_ok=True)
            raise
        return final

    def load(self, scene: str, key: str, expected: Expected | None = None) -> dict[str, np.ndarray]:
        """The result arrays of a chunk, verified (``StudyFailed`` naming the file if not)."""
        path = self.chunk_path(scene, key)
        try:
            arrays = read_chunk(path)
            why = check_arrays(arrays, key, expected)
        except ValueError as exc:
            why = str(exc)
        if why:
            discard(path)
            raise StudyFailed(f"chunk file {path} {why}; it was deleted, rerun to compute it")
        return {k: v for k, v in arrays.items() if k not in META}

    def reuse(self, scene: str, key: str, expected: Expected) -> bool:
        """True if a verified chunk ``key`` is on disk; a failing entry is discarded and named."""
        path = self.chunk_path(scene, key)
        if not os.path.lexists(path):
            return False
        why = check_chunk(path, key, expected)
        if why:
            discard(path)
            self.report(f"study: discarded {path}: {why}; computing it again")
            return False
        return True

    def keys(self, scene: str) -> list[str]:
        """Keys of the chunk files of ``scene`` on disk."""
        folder = self.path / scene
        return sorted(p.stem for p in folder.glob("*.npz")) if folder.is_dir() else []

    def count(self) -> int:
        """Number of chunk files on disk (any study)."""
        if not self.path.is_dir():
            return 0
        return sum(1 for p in self.path.glob("*/*.npz") if p.is_file())

    def temporary_files(self) -> list[Path]:
        """Temporary files in the work folder (left by a process killed mid-write)."""
        if not self.path.is_dir():
            return []
        return sorted(self.path.glob(f"*/.*{TMP_SUFFIX}"))

    def scan(self, scenes: list[str]) -> int:
        """Clear the work folder of what no run can use; call it holding the lock.

        Temporary files of a dead run are deleted (their number is returned);
        a scene folder that is not a directory, or an entry of a scene folder
        that is not a regular file, is discarded and named in one line.
        """
        stale = self.temporary_files()
        for p in stale:
            discard(p)
        for scene in scenes:
            folder = self.path / scene
            if os.path.lexists(folder) and (folder.is_symlink() or not folder.is_dir()):
                discard(folder)
                self.report(f"study: discarded {folder}: not a scene folder; computing it again")
                continue
            if not folder.is_dir():
                continue
            for entry in folder.iterdir():
                if entry.is_symlink() or not entry.is_file():
                    discard(entry)
                    self.report(f"study: discarded {entry}: not a chunk file; computing it again")
        return len(stale)

    def clean(self) -> int:
        """Delete temporary files left by a dead run (:meth:`scan` without scenes)."""
        return self.scan([])

    def lock(self) -> bool:
        """Take the advisory lock of the output (its ``.lock`` file beside it).

        Returns False if another process holds it; True if it is taken (or
        locking is not supported here, e.g. a file system without ``flock``).
        An entry at the lock's path that is not a regular file (a directory, a
        FIFO, a dangling link) is stale: it is discarded and named.
        """
        self.path.mkdir(parents=True, exist_ok=True)
        if fcntl is None or self._lock_fd is not None:
            return True
        p = self.lock_path
        if os.path.lexists(p) and (p.is_symlink() or not p.is_file()):
            discard(p)
            self.report(f"study: discarded {p}: a stale lock (not a regular file)")
        while True:
            fd = os.open(p, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                return False
            except OSError:  # no locking on this file system: run unprotected
                os.close(fd)
                return True
            try:  # the holder may have removed the file before we locked it: lock the new one
                same = os.path.samestat(os.fstat(fd), os.stat(p))
            except OSError:
                same = False
            if same:
                self._lock_fd = fd
                return True
            os.close(fd)

    def unlock(self) -> None:
        if self._lock_fd is not None:
            try:
                self.lock_path.unlink(missing_ok=True)  # while holding it (see lock)
            except OSError:  # e.g. the folder became read-only: the flock still goes
                pass
            os.close(self._lock_fd)  # releases the flock
            self._lock_fd = None

    def remove(self) -> None:
        shutil.rmtree(self.path, ignore_errors=True)
        self.unlock()
