"""Shared test fixtures (kept small)."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

#: Test data kept in the repository (see tests/data/README.md).
DATA = Path(__file__).resolve().parent / "data"
#: The 170 independently labelled reference cases.
REFERENCE_CASES = DATA / "reference_cases.json"


@pytest.fixture(scope="session")
def reference_cases_path() -> Path:
    return REFERENCE_CASES


@contextlib.contextmanager
def local_cluster_client(n_workers: int = 2) -> Iterator:
    """A client of a real LocalCluster: ``n_workers`` single-threaded worker processes on
    127.0.0.1, no dashboard. The numba kernel is loaded (or compiled) here first, so the
    workers load it from the cache."""
    from distributed import Client, LocalCluster

    from tasks import Scene, classify

    classify(Scene("ground", 2), 1.0, 0.3, fidelity="fast")
    with (
        LocalCluster(
            n_workers=n_workers,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
        ) as cluster,
        Client(cluster) as client,
    ):
        yield client


@pytest.fixture
def study_file(tmp_path):
    """Write a study TOML text into ``tmp_path/study.toml`` and return its path."""

    def write(text: str, name: str = "study.toml") -> Path:
        path = tmp_path / name
        path.write_text(text, encoding="utf-8")
        return path

    return write


@pytest.fixture
def cli_env() -> dict[str, str]:
    """Environment for subprocesses: this interpreter's, with the repo importable."""
    env = dict(os.environ)
    repo = str(Path(__file__).resolve().parents[1])
    env["PYTHONPATH"] = os.pathsep.join(p for p in (repo, env.get("PYTHONPATH")) if p)
    return env


@pytest.fixture
def run_cli(cli_env, tmp_path):
    """Run ``python -m study ARGS`` in ``tmp_path``; return the CompletedProcess."""

    def run(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
        return subprocess.run(
            [sys.executable, "-m", "study", *map(str, args)],
            cwd=tmp_path,
            env=cli_env,
            capture_output=True,
            text=True,
            timeout=timeout,
        )

    return run
