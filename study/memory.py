"""Chunk results kept in memory: the work folder of a run that writes no file.

:func:`study.run.run_study` without an output path computes on the same Dask
machinery and keeps each finished chunk here instead of ``OUT.nc.work/``; the
labelled result is then assembled in memory (:func:`study.netcdf.result_tree`).
"""

from __future__ import annotations

import numpy as np


class MemoryWork:
    """The interface of :class:`study.store.WorkDir`, backed by a dict."""

    path = "memory"

    def __init__(self, report=None) -> None:
        self._chunks: dict[tuple[str, str], dict[str, np.ndarray]] = {}
        self.report = report or (lambda line: None)

    def has(self, scene: str, key: str) -> bool:
        return (scene, key) in self._chunks

    def save(self, scene: str, key: str, arrays: dict[str, np.ndarray]) -> None:
        self._chunks[(scene, key)] = {k: np.asarray(v) for k, v in arrays.items()}

    def load(self, scene: str, key: str, expected=None) -> dict[str, np.ndarray]:
        return self._chunks[(scene, key)]

    def reuse(self, scene: str, key: str, expected) -> bool:
        return self.has(scene, key)

    def keys(self, scene: str) -> list[str]:
        return sorted(k for s, k in self._chunks if s == scene)

    def count(self) -> int:
        return len(self._chunks)

    def scan(self, scenes: list[str]) -> int:
        return 0

    def lock(self) -> bool:
        return True

    def unlock(self) -> None:
        pass

    def remove(self) -> None:
        self._chunks.clear()
