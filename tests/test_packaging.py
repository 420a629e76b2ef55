"""The product outside a development clone: version, examples, numba cache, first run."""

from __future__ import annotations

import io
import os
import re
import shlex
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

import frictionregimes
from study.definition import Study

REPO = Path(__file__).resolve().parents[1]
#: PEP 440 with an optional local part, e.g. 0.1.0+g0f7b1cb2176c.dirty
PEP440 = re.compile(r"^\d+(\.\d+)*(\+[a-z0-9]+(\.[a-z0-9]+)*)?$")


# --------------------------------------------------------------------------- version
def test_version_is_the_release_with_the_commit():
    version = frictionregimes.__version__
    assert PEP440.match(version), version
    assert version.split("+")[0] == frictionregimes.RELEASE
    if (REPO / ".git").exists() and shutil.which("git"):
        sha = subprocess.run(
            ["git", "-C", str(REPO), "rev-parse", "HEAD"], capture_output=True, text=True
        ).stdout.strip()
        assert version.split("+")[1].removeprefix("g").split(".")[0] == sha[:12]


def test_cli_version(run_cli):
    proc = run_cli("--version")
    assert proc.returncode == 0
    assert proc.stdout.strip() == f"study (frictionregimes) {frictionregimes.__version__}"


def test_license_and_spdx():
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    assert project["license"] == "MIT"
    assert "MIT License" in (REPO / "LICENSE").read_text()


# --------------------------------------------------------------------------- examples
def test_every_example_is_listed(run_cli):
    """The clone's examples/ (a wheel carries a copy of every file: setup.py)."""
    files = sorted(p for p in (REPO / "examples").iterdir() if p.is_file())
    assert frictionregimes.examples_dir().resolve() == (REPO / "examples").resolve()
    proc = run_cli("examples")
    assert proc.returncode == 0, proc.stderr
    for path in files:
        assert re.search(rf"^  {re.escape(path.stem)} ", proc.stdout, flags=re.M), path.name


def test_write_an_example(run_cli, tmp_path):
    proc = run_cli("examples", "quickstart", "-o", "q.toml")
    assert proc.returncode == 0, proc.stderr
    written = (tmp_path / "q.toml").read_text()
    assert written == (REPO / "examples" / "quickstart.toml").read_text()
    assert Study.from_toml(tmp_path / "q.toml").n_points > 0
    again = run_cli("examples", "quickstart", "-o", "q.toml")
    assert again.returncode == 2
    assert len(again.stderr.strip().splitlines()) == 1 and "q.toml exists" in again.stderr
    unknown = run_cli("examples", "fig99")
    assert unknown.returncode == 2 and "no example 'fig99'" in unknown.stderr


# --------------------------------------------------------------------------- study run
def test_run_refuses_a_complete_output(run_cli, tmp_path):
    shutil.copy(REPO / "examples" / "quickstart.toml", tmp_path / "q.toml")
    (tmp_path / "q.nc").write_bytes(b"complete result")
    proc = run_cli("run", "q.toml", "-o", "q.nc", "--workers", "1")
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "--overwrite" in lines[0], proc.stderr
    assert (tmp_path / "q.nc").read_bytes() == b"complete result"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["q.nc", "q.toml"]


# --------------------------------------------------------------------------- first run
def test_eta_starts_at_the_first_finished_chunk(monkeypatch):
    """Start-up and compile time before the first chunk never enter the rate or ETA."""
    from study import progress

    clock = [0.0]
    monkeypatch.setattr(progress.time, "monotonic", lambda: clock[0])
    bar = progress.Progress(1000, stream=io.StringIO(), interval=1e9)
    bar.start()
    clock[0] = 300.0  # workers compiled for 5 minutes
    bar.update(100)
    assert bar.line().endswith("ETA ?")
    clock[0] = 310.0
    bar.update(100)  # 100 points in 10 s since the first chunk
    assert bar.rate() == pytest.approx(10.0)
    assert bar.line().endswith("ETA 0:01:20")  # 800 points at 10 points/s
    clock[0] = 400.0  # e.g. the cluster shutting down: not computing
    assert bar.rate() == pytest.approx(10.0)


def test_compile_is_announced(monkeypatch):
    from study.firstrun import compile_once
    from tasks import numba_cache

    monkeypatch.setattr(numba_cache, "is_compiled", lambda: False)
    monkeypatch.setattr(numba_cache, "compile_simulator", lambda: 31.4)
    out = io.StringIO()
    assert compile_once(out) == 31.4
    assert out.getvalue().startswith(
        "study: compiling the simulator once (40 s to 2 min on 2 cores"
    )
    monkeypatch.setattr(numba_cache, "is_compiled", lambda: True)
    assert compile_once(io.StringIO()) == 0.0


def _python(code: str, env: dict, cwd: Path, read_only=()) -> subprocess.CompletedProcess:
    """Run ``code``; as root, in a private mount namespace with ``read_only`` folders
    bind-mounted read-only (root writes through file modes)."""
    command = [sys.executable, "-c", code]
    if read_only and os.geteuid() == 0:
        mounts = " && ".join(
            f"mount --bind -o ro {shlex.quote(str(p))} {shlex.quote(str(p))}" for p in read_only
        )
        command = ["unshare", "--mount", "sh", "-c", f'{mounts} && exec "$@"', "sh", *command]
    return subprocess.run(command, env=env, cwd=cwd, capture_output=True, text=True, timeout=300)


def test_cache_detection_after_a_compile():
    """A filled on-disk cache is detected; a fresh NUMBA_CACHE_DIR holds no compiled
    simulator (tests/test_kernel_cache.py, test_a_fresh_cache_folder_is_detected_as_cold)."""
    from tasks import numba_cache

    numba_cache.compile_simulator()  # compiles or loads; the on-disk cache is then filled
    assert numba_cache.is_compiled()


def test_import_from_a_read_only_package_without_a_writable_home(tmp_path):
    """numba's cache falls back to a per-user folder (here: the temporary folder).

    Without the fallback, ``import tasks`` fails: "cannot cache function
    'sin_over': no locator available".
    """
    site, home, tmp = tmp_path / "site", tmp_path / "home", tmp_path / "tmp"
    shutil.copytree(REPO / "tasks", site / "tasks", ignore=shutil.ignore_patterns("__pycache__"))
    home.mkdir()
    tmp.mkdir()
    if os.geteuid() == 0:
        if (
            shutil.which("unshare") is None
            or subprocess.run(["unshare", "--mount", "true"], capture_output=True).returncode
        ):
            pytest.skip("root without unshare --mount: cannot make a folder read-only")
    else:
        for path in [site, *site.rglob("*"), home]:
            path.chmod(0o555 if path.is_dir() else 0o444)
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("NUMBA_CACHE_DIR", "XDG_CACHE_HOME", "PYTHONPATH")
    }
    env.update(HOME=str(home), TMPDIR=str(tmp), PYTHONPATH=str(site))
    code = (
        "import os, tasks; from tasks import numba_cache; "
        "print(tasks.__file__); print(os.environ['NUMBA_CACHE_DIR']); "
        "print(numba_cache.cache_dir())"
    )
    try:
        proc = _python(code, env, tmp_path, read_only=(site, home))
    finally:
        for path in [site, *site.rglob("*"), home]:
            path.chmod(0o755 if path.is_dir() else 0o644)
    assert proc.returncode == 0, proc.stderr
    where, chosen, cache = proc.stdout.split()
    assert where.startswith(str(site))
    assert Path(chosen).parent == tmp and Path(cache).is_relative_to(chosen)
