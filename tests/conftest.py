"""Shared test fixtures (kept small)."""

from __future__ import annotations

import contextlib
import os
import shlex
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

try:
    import fcntl
except ImportError:  # not POSIX: no compile ahead of the tests (each test compiles)
    fcntl = None

import pytest

#: Test data kept in the repository (see tests/data/README.md).
DATA = Path(__file__).resolve().parent / "data"
#: The 170 independently labelled reference cases.
REFERENCE_CASES = DATA / "reference_cases.json"
#: The repository.
ROOT = DATA.parents[1]
#: Bound of one documented command (the first simulation of a fresh checkout compiles).
DOCUMENTED_TIMEOUT = 600


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


@pytest.fixture(scope="session")
def cluster_client() -> Iterator:
    """One real LocalCluster for the session (:func:`local_cluster_client`, 2 worker
    processes), shared by the tests that only compute on it: a test that kills, stops
    or interrupts workers starts its own."""
    with local_cluster_client(2) as client:
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


def docs_env() -> dict[str, str]:
    """This interpreter's environment with the repository importable, no display."""
    e = dict(os.environ)
    e["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), e.get("PYTHONPATH")) if p)
    e["MPLBACKEND"] = "Agg"
    return e


def workspace(path: Path) -> Path:
    """A folder where a user would run the documented commands: ``examples/`` beside."""
    path.mkdir(parents=True, exist_ok=True)
    (path / "examples").symlink_to(ROOT / "examples", target_is_directory=True)
    return path


def study_cli(
    line: str, cwd: Path, timeout: float = DOCUMENTED_TIMEOUT
) -> subprocess.CompletedProcess:
    """Run a documented ``study ...`` command line through ``python -m study``."""
    args = shlex.split(line, comments=True)
    assert args[0] == "study", line
    return subprocess.run(
        [sys.executable, "-m", "study", *args[1:]],
        cwd=cwd,
        env=docs_env(),
        capture_output=True,
        text=True,
        timeout=timeout,
    )


@pytest.fixture(scope="session")
def documented_runs(tmp_path_factory):
    """``run(lines)``: the ``study ...`` lines of one documented block, run in order through
    the CLI in a fresh :func:`workspace` (up to the first that fails), once per session;
    returns ``(workspace, [CompletedProcess per line run])``. tests/test_docs.py checks
    every block this way, and tests that check the result of a documented command (the
    cantilever example against the closed forms, the quickstart file the snippets read)
    look at the same run instead of computing it again."""
    done: dict[tuple[str, ...], tuple[Path, list[subprocess.CompletedProcess]]] = {}

    def run(lines: list[str] | tuple[str, ...]) -> tuple[Path, list[subprocess.CompletedProcess]]:
        key = tuple(lines)
        if key not in done:
            ws = workspace(tmp_path_factory.mktemp("documented") / "ws")
            procs = []
            for line in key:
                procs.append(study_cli(line, ws))
                if procs[-1].returncode != 0:
                    break
            done[key] = ws, procs
        return done[key]

    return run


def assert_documented_lines_ran(lines, procs, where: str = "") -> None:
    """Every line of a documented block ran with exit code 0."""
    for line, proc in zip(lines, procs, strict=False):
        assert proc.returncode == 0, f"{where}: {line}\n{proc.stderr[-3000:]}"
    assert len(procs) == len(lines), where


# ------------------------------------------------------------------ parallel runs
# The suite runs in 2 worker processes (pytest-xdist, ``-n 2 --dist loadgroup`` in
# pyproject.toml). Each test file is one group, run whole by one worker, so a
# module-scoped fixture (a module's CLI run) runs once; files sharing a costly
# session fixture are one group, so it is set up once. Groups start longest first
# (rough seconds of a warm run on 2 cores; an unlisted file counts as short): the
# last groups are short, and neither worker waits long for the other at the end.
#: Files run together by one worker: the files that use ``documented_runs``, and
#: the files that start real Dask processes, kill or interrupt them (loopback only),
#: so no two of those run at the same time (a timed SIGINT or a worker timeout does
#: not meet a second cluster on the 2 cores).
SHARED_GROUPS = {
    "documented": ("test_docs.py", "test_study_structures.py"),
    "processes": (
        "test_adaptive.py",
        "test_adaptive_client.py",
        "test_adaptive_sample.py",
        "test_adaptive_tiles.py",
        "test_door_faults.py",
        "test_door_tiles_resume.py",
        "test_layout.py",
        "test_reliability_faults.py",
        "test_study_cluster.py",
        "test_work_folder_faults.py",
    ),
}
#: Rough seconds per group (warm, 2 cores): only the order the groups are handed out in.
GROUP_SECONDS: dict[str, float] = {
    "processes": 250,
    "documented": 60,
    "test_general_damping.py": 30,
    "test_steady_states.py": 25,
}
#: Precompile only for a run of (most of) the suite: a few tests compile what they use.
PRECOMPILE_MIN_TESTS = 200


def _group(path: Path) -> str:
    for group, files in SHARED_GROUPS.items():
        if path.name in files:
            return group
    return path.name


def pytest_collection_modifyitems(config, items) -> None:
    """One ``xdist_group`` per file (or :data:`SHARED_GROUPS`); under xdist, the groups
    ordered longest first (:data:`GROUP_SECONDS`), the order inside each kept."""
    groups = {}
    for item in items:
        group = _group(item.path)
        item.add_marker(pytest.mark.xdist_group(group))
        groups.setdefault(group, []).append(item)
    if getattr(config.option, "loadgroup", False):  # an xdist worker
        order = sorted(groups, key=lambda g: -GROUP_SECONDS.get(g, 0.0))
        items[:] = [item for group in order for item in groups[group]]


def pytest_collection_finish(session) -> None:
    """Compile the simulators not yet cached, both at once in two subprocesses, before
    the first test of a run of the suite (:data:`PRECOMPILE_MIN_TESTS`).

    Without it, each of the 2 workers compiles the one-contact kernel (and then the
    several-contact one) at its first simulation: twice the work on the same 2 cores.
    The first worker here takes a lock in the cache folder and compiles; the other
    waits for it, then finds the cache filled. Each compile runs
    :func:`tasks.numba_cache.compile_simulator` in its own process, as ``study run``
    compiles in the client. The tests of the first compile replace the compile by a
    recorder (tests/test_first_compile.py) or run in a fresh cache folder
    (tests/test_kernel_cache.py): a filled cache changes none of them.
    """
    if fcntl is None or session.config.option.collectonly:
        return
    if len(session.items) < PRECOMPILE_MIN_TESTS:
        return
    import numba.core.config

    from tasks import numba_cache

    if numba.core.config.DISABLE_JIT:
        return
    base = Path(numba_cache.cache_dir()).parent
    base.mkdir(parents=True, exist_ok=True)
    with open(base / "precompile.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # the other worker waits here
        try:
            missing = [k for k in numba_cache.KERNELS if not numba_cache.is_compiled(k)]
            procs = [
                subprocess.Popen(
                    [sys.executable, "-c", PRECOMPILE.format(kernel=kernel)],
                    cwd=ROOT,
                    env=docs_env(),
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.PIPE,
                    text=True,
                )
                for kernel in missing
            ]
            for kernel, proc in zip(missing, procs, strict=True):
                _, err = proc.communicate()
                if proc.returncode:  # the tests that simulate compile, and fail, again
                    print(f"conftest: compiling {kernel} failed:\n{err[-2000:]}", file=sys.stderr)
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


#: One subprocess compile (:func:`pytest_collection_finish`).
PRECOMPILE = "from tasks import numba_cache; numba_cache.compile_simulator({kernel!r})"
