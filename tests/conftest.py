"""Shared test fixtures (kept small)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

#: Test data kept in the repository (see tests/data/README.md).
DATA = Path(__file__).resolve().parent / "data"
#: The 170 independently labelled reference cases.
REFERENCE_CASES = DATA / "reference_cases.json"


@pytest.fixture(scope="session")
def reference_cases_path() -> Path:
    return REFERENCE_CASES


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
