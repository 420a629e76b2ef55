"""The work folder beside the output (``OUT.nc.work/``): one ``.npz`` file per finished chunk.

Each chunk is written atomically (``np.savez`` to a temporary file in the same
folder, then ``os.replace``), so a crash or Ctrl-C never leaves a half-written
chunk: a chunk file either exists complete or not at all. The folder is removed
only after the final netCDF file is in place.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np


class WorkDir:
    """Chunk results of one study run, keyed by the stable chunk key."""

    def __init__(self, output: str | os.PathLike) -> None:
        output = Path(output)
        self.path = output.with_name(output.name + ".work")

    def chunk_path(self, scene: str, key: str) -> Path:
        return self.path / scene / f"{key}.npz"

    def has(self, scene: str, key: str) -> bool:
        return self.chunk_path(scene, key).is_file()

    def save(self, scene: str, key: str, arrays: dict[str, np.ndarray]) -> Path:
        """Write one chunk atomically."""
        final = self.chunk_path(scene, key)
        final.parent.mkdir(parents=True, exist_ok=True)
        tmp = final.with_name(f".{final.name}.{os.getpid()}.tmp")
        with open(tmp, "wb") as f:
            np.savez(f, **arrays)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, final)
        return final

    def load(self, scene: str, key: str) -> dict[str, np.ndarray]:
        with np.load(self.chunk_path(scene, key)) as z:
            return {k: z[k] for k in z.files}

    def count(self) -> int:
        """Number of chunk files on disk (any study)."""
        if not self.path.is_dir():
            return 0
        return sum(1 for _ in self.path.glob("*/*.npz"))

    def remove(self) -> None:
        shutil.rmtree(self.path, ignore_errors=True)
