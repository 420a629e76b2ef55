"""Studies on real Dask clusters, end to end (loopback only).

* a real multi-process LocalCluster (``study run --workers 2``) on a study of
  several scenes (a gamma sweep and a point list): the file opens with
  ``xr.open_datatree``, every value equals ``tasks.classify`` on the same
  points, CF attributes and provenance are in place;
* a real ``dask scheduler`` and two ``dask worker`` processes started here,
  used once through ``--scheduler-file`` and once through ``--scheduler
  tcp://127.0.0.1:PORT`` (single-scene files: ``xr.open_dataset``), and for the
  trace study and the rest start (one cluster for the module: no worker is killed);
* ``kill -9`` of a worker process while it runs a task of the study: the run
  finishes with every point, equal to an undisturbed run;
* Ctrl-C (SIGINT to the whole process group, as a terminal sends it) of a
  ``study run`` on a LocalCluster: exit code 130, the work folder is kept, no
  result file; the rerun computes only the missing chunks (counted from the
  CLI's lines and, independently, from the scheduler's task stream) and the
  result is identical.

The numba kernels compile on first use in each process (about 20 s) and are
cached in tasks/__pycache__; the session fixture ``warm_kernels`` fills the
cache once in this process before any worker starts, so workers load it.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import urllib.request
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path

import netCDF4
import numpy as np
import pytest
import xarray as xr

from study import Study
from study.chunks import plan
from tasks import Scene, classify, regimes, resolve
from tasks.result import FIELDS

pytestmark = pytest.mark.cluster

REPO = Path(__file__).resolve().parents[1]
RUN_TIMEOUT = 300  # seconds for one `study run` (a loaded 2-core machine is slow)

# --------------------------------------------------------------------------- studies
#: Two scenes: a gamma sweep (dims gamma, r, beta) and a point list with
#: per-point gamma (dim point); a settings override that must reach the workers.
MULTI = """
[study]
name = "multi"
description = "two scenes on a LocalCluster"
fidelity = "fast"
chunk_points = 20

[settings]
max_cycles = 120
design = true  # the design quantities too: compared with classify's below

[[scene]]
name = "sweep"
contact = "ground"
dof = 2
gamma = {values = [0.5, 2.0]}
kappa = 1.0
r = {start = 0.1, stop = 2.4, num = 12}
beta = {start = 0.0, stop = 1.2, num = 9}

[[scene]]
name = "pts"
contact = "mass"
dof = 3

[scene.points]
r = [0.3, 0.8, 1.2, 1.7, 2.2, 0.9, 1.4]
beta = [0.05, 0.2, 0.4, 0.1, 0.6, 0.3, 0.02]
gamma = [1.0, 1.0, 1.0, 2.0, 2.0, 2.0, 2.0]
"""
MULTI_SWEEP = {"gamma": [0.5, 2.0], "r": np.linspace(0.1, 2.4, 12), "beta": np.linspace(0, 1.2, 9)}
MULTI_POINTS = {
    "r": [0.3, 0.8, 1.2, 1.7, 2.2, 0.9, 1.4],
    "beta": [0.05, 0.2, 0.4, 0.1, 0.6, 0.3, 0.02],
    "gamma": [1.0, 1.0, 1.0, 2.0, 2.0, 2.0, 2.0],
}

#: One scene with a kappa sweep (dims kappa, r, beta): the --scheduler-file run.
KAPPA = """
[study]
name = "kappa"
fidelity = "fast"
chunk_points = 30

[[scene]]
contact = "base"
dof = 2
kappa = {values = [0.5, 1.5]}
r = {start = 0.2, stop = 2.2, num = 10}
beta = [0.0, 0.1, 0.3, 0.6, 0.9, 1.3]
"""

#: One point-list scene (dim point): the --scheduler ADDRESS run.
POINTS = """
[study]
name = "points"
fidelity = "balanced"
chunk_points = 4

[[scene]]
contact = "ground"
dof = 3
contact_mass = 2
points = [
    [0.4, 0.1], [0.9, 0.05], [1.3, 0.5], [1.8, 0.2], [2.3, 0.8],
    [0.7, 0.0], [1.1, 1.5], [1.6, 0.3], [2.0, 0.01],
]
"""

#: Long enough to interrupt (240 chunks of 24 points, ~5-15 s on 2 workers). With the
#: design quantities: the work per chunk file these timings were set for (labels
#: only, a loaded machine wrote the chunk files more slowly than it computed them,
#: and the signal could come after the last chunk).
LONG = """
[study]
name = "long"
fidelity = "balanced"
chunk_points = 24

[settings]
design = true

[[scene]]
name = "sweep"
contact = "ground"
dof = 2
gamma = {values = [0.5, 2.0]}
r = {start = 0.05, stop = 2.5, num = 60}
beta = {start = 0.0, stop = 1.2, num = 48}
"""
#: Chunks saved before a signal is sent (of 240): the run is well under way.
SAVED_BEFORE_SIGNAL = 20


# --------------------------------------------------------------------------- helpers
def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO), env.get("PYTHONPATH")) if p)
    env.pop("DASK_SCHEDULER_ADDRESS", None)
    return env


def _dask_command() -> list[str]:
    exe = Path(sys.executable).with_name("dask")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "dask"]


def _study_command(*args: object) -> list[str]:
    return [sys.executable, "-m", "study", *map(str, args)]


def run_cli(cwd: Path, *args: object) -> subprocess.CompletedProcess:
    return subprocess.run(
        _study_command(*args),
        cwd=cwd,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=RUN_TIMEOUT,
    )


def write_study(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def chunk_files(output: Path) -> list[Path]:
    return sorted(output.with_name(output.name + ".work").glob("*/*.npz"))


def temporary_files(output: Path) -> list[Path]:
    """Temporary files the run may leave: the result's and the chunks'."""
    work = output.with_name(output.name + ".work")
    return sorted(
        [*output.parent.glob(f".{output.name}.*tmp"), *work.glob("*/.*tmp"), *work.glob(".*tmp")]
    )


def counts(stderr: str) -> dict[str, int]:
    """The chunk counts of the CLI's first and last lines."""
    first = re.search(
        r"in ([\d,]+) chunks; reusing ([\d,]+) chunks from .*, computing ([\d,]+)", stderr
    )
    last = re.search(
        r"wrote .* \(([\d,]+) points; ([\d,]+) chunks computed, ([\d,]+) reused\)", stderr
    )
    assert first and last, stderr
    n = [int(g.replace(",", "")) for g in (*first.groups(), *last.groups())]
    return {
        "chunks": n[0],
        "reusing": n[1],
        "computing": n[2],
        "points": n[3],
        "computed": n[4],
        "reused": n[5],
    }


def assert_ok(proc: subprocess.CompletedProcess) -> None:
    assert proc.returncode == 0, f"exit {proc.returncode}\n{proc.stdout}\n{proc.stderr}"
    assert "Traceback" not in proc.stderr, proc.stderr


def assert_progress_complete(stderr: str, n_points: int) -> None:
    assert f"{n_points:,}/{n_points:,} points (100.0%)" in stderr, stderr
    assert re.search(r"points/s \| elapsed \d+:\d\d:\d\d \| ETA", stderr), stderr


def assert_fields_equal(node: xr.Dataset, index: dict, expected) -> None:
    """Every result field of ``node`` at ``index`` equals the ClassifyResult ``expected``;
    ``regime_rest`` only where rest was a start (else it is not written: all -127).

    The study's chunks group the points otherwise than the one call of ``expected``,
    so with warm starts (the default) the labels are equal, the continuous fields
    agree to the polish of the orbits (the fast preset's event times, 1e-9: within
    1e-7 of the field's scale) and ``cycles``, the periods each search took from its
    seed, is not compared (docs/api.md, "Warm starts"). Design quantities that
    ``expected`` did not compute (None) must be absent from ``node`` (attribute "off")."""
    rest = (expected.regime_rest != regimes.NOT_COMPUTED).any()
    assert ("regime_rest" in node.data_vars) == rest
    for name in FIELDS:
        if name == "regime_rest" and not rest or name == "cycles":
            continue
        if getattr(expected, name) is None:  # not asked for: absent, never NaN-filled
            assert name not in node.data_vars and node.attrs["design_quantities"] == "off", name
            continue
        da = node[name].isel(index) if index else node[name]
        da = da.transpose(*(d for d in ("point", "r", "beta", "mass") if d in da.dims))
        want = np.asarray(getattr(expected, name))
        if want.dtype.kind == "f":
            np.testing.assert_array_equal(np.isnan(da.values), np.isnan(want), err_msg=name)
            scale = np.nanmax(np.abs(want), initial=0.0)
            np.testing.assert_allclose(da.values, want, rtol=0, atol=1e-7 * scale, err_msg=name)
        else:
            np.testing.assert_array_equal(da.values, want, err_msg=name)


def assert_cf_and_boundaries(
    node: xr.Dataset, boundary_dims: tuple[str, ...], **overrides: object
) -> None:
    """CF attributes, flags, no fill value, every point computed, boundaries, settings."""
    for name, var in {**node.data_vars, **node.coords}.items():
        if "flag_values" in var.attrs:  # coded: flags instead of units
            assert len(var.attrs["flag_meanings"].split()) == len(var.attrs["flag_values"]), name
        else:
            assert var.attrs.get("units") == "1", name
        assert var.attrs.get("long_name"), name
    for name in ("initial_condition", "period"):
        assert set(np.unique(node[name].values)) <= set(node[name].attrs["flag_values"]), name
    reg = node["regime"]
    codes = sorted(regimes.ALL_CODES)
    np.testing.assert_array_equal(reg.attrs["flag_values"], np.array(codes, dtype=np.int8))
    assert reg.attrs["flag_values"].dtype == np.int8
    assert reg.attrs["flag_meanings"].split() == [regimes.ALL_CODES[c] for c in codes]
    assert reg.dtype == np.int8  # codes as codes under plain open_dataset: no CF masking
    assert "_FillValue" not in reg.encoding
    assert not (reg == regimes.NOT_COMPUTED).any(), "a point was not computed"
    for method in ("paper", "exact"):
        for base in ("beta_continuous", "beta_motion"):
            b = node[f"{base}_{method}"]
            assert b.dims == boundary_dims, (b.name, b.dims)
            v = b.values
            assert not np.isnan(v).any() and (v >= 0).all(), (b.name, v)  # finite or inf
    assert (
        json.loads(node.attrs["settings"]) == resolve(node.attrs["fidelity"], **overrides).to_dict()
    )
    scene = json.loads(node.attrs["scene"])
    assert scene["contact"] == node.attrs["contact"] and scene["dof"] == node.attrs["dof"]


def assert_provenance(attrs: dict, study_text: str) -> None:
    assert attrs["study"] == study_text
    assert attrs["Conventions"].startswith("CF-")
    versions = json.loads(attrs["versions"])
    assert {"python", "numpy", "dask", "distributed", "xarray", "netCDF4"} <= set(versions)
    assert "study run" in attrs["history"]


def assert_same_result(a: Path, b: Path, regrouped: bool = False) -> None:
    """All groups, variables, coordinates and attributes equal (history aside).

    ``regrouped``: the points were grouped into other calls (an adaptive map's
    point lists formed anew on a resumed run), so with warm starts ``cycles`` may
    differ and the floating fields agree to the polish of the orbits (here the fast
    preset's: within 1e-7 of each field's scale, docs/api.md "Warm starts"); every
    other variable, coordinate and attribute is still equal."""
    loose = {"cycles"} | (set(FIELDS) - {"regime"} if regrouped else set())
    with xr.open_datatree(a) as ta, xr.open_datatree(b) as tb:
        assert sorted(ta.groups) == sorted(tb.groups)
        for group in ta.groups:
            da_, db_ = ta[group].to_dataset().load(), tb[group].to_dataset().load()
            da_.attrs.pop("history", None)
            db_.attrs.pop("history", None)
            if regrouped:
                for name in sorted(loose & set(da_.data_vars)):
                    x, y = da_[name].values, db_[name].values
                    if name != "cycles" and x.dtype.kind == "f":
                        np.testing.assert_array_equal(np.isnan(x), np.isnan(y), err_msg=name)
                        scale = np.nanmax(np.abs(x), initial=0.0)
                        np.testing.assert_allclose(x, y, rtol=0, atol=1e-7 * scale, err_msg=name)
                    elif name != "cycles":
                        np.testing.assert_array_equal(x, y, err_msg=name)
                drop = sorted(loose & set(da_.data_vars))
                da_, db_ = da_.drop_vars(drop), db_.drop_vars(drop)
            xr.testing.assert_identical(da_, db_)
    with netCDF4.Dataset(a) as na, netCDF4.Dataset(b) as nb:  # the raw bytes of the codes too
        for g in [na, *na.groups.values()]:
            h = nb if g is na else nb.groups[g.name]
            for name, var in g.variables.items():
                if regrouped and name in loose:
                    continue
                x, y = var[...], h.variables[name][...]
                np.testing.assert_array_equal(np.ma.getdata(x), np.ma.getdata(y), err_msg=name)


# --------------------------------------------------------------------------- clusters
@dataclass
class RemoteCluster:
    """A ``dask scheduler`` and ``dask worker`` processes started by this test run."""

    scheduler_file: Path
    address: str
    dashboard_port: int | None
    scheduler: subprocess.Popen
    workers: list[subprocess.Popen]
    monitor: object  # a distributed.Client of this process, for looking at the scheduler


def _stop(procs: list[subprocess.Popen]) -> None:
    for p in procs:
        if p.poll() is None:
            p.terminate()
    for p in procs:
        try:
            p.wait(timeout=20)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait(timeout=20)


@contextmanager
def dask_cluster(where: Path, n_workers: int = 2, nanny: bool = True, dashboard: bool = True):
    """Start ``dask scheduler`` + ``n_workers`` x ``dask worker`` on 127.0.0.1."""
    from distributed import Client

    where.mkdir(parents=True, exist_ok=True)
    sched_file = where / "scheduler.json"
    env = _env()
    procs: list[subprocess.Popen] = []
    logs = []

    def start(args: list[str], log: str) -> subprocess.Popen:
        f = open(where / log, "w")  # noqa: SIM115 - closed below
        logs.append(f)
        p = subprocess.Popen(args, cwd=where, env=env, stdout=f, stderr=subprocess.STDOUT)
        procs.append(p)
        return p

    monitor = None
    try:
        sched = start(
            [
                *_dask_command(),
                "scheduler",
                "--host",
                "127.0.0.1",
                "--port",
                "0",
                "--scheduler-file",
                str(sched_file),
                *(["--dashboard-address", "127.0.0.1:0"] if dashboard else ["--no-dashboard"]),
            ],
            "scheduler.log",
        )
        deadline = time.monotonic() + 120
        info = None
        while info is None:
            assert sched.poll() is None, (where / "scheduler.log").read_text()
            assert time.monotonic() < deadline, "the scheduler did not start"
            try:
                info = json.loads(sched_file.read_text())
            except (FileNotFoundError, json.JSONDecodeError):
                time.sleep(0.1)
        workers = [
            start(
                [
                    *_dask_command(),
                    "worker",
                    "--scheduler-file",
                    str(sched_file),
                    "--host",
                    "127.0.0.1",
                    "--nthreads",
                    "1",
                    "--nworkers",
                    "1",
                    "--no-dashboard",
                    "--death-timeout",
                    "60",
                    "--local-directory",
                    str(where / f"worker{i}"),
                    *([] if nanny else ["--no-nanny"]),
                ],
                f"worker{i}.log",
            )
            for i in range(n_workers)
        ]
        monitor = Client(scheduler_file=str(sched_file), timeout="60s")
        monitor.wait_for_workers(n_workers, timeout=120)
        yield RemoteCluster(
            sched_file,
            info["address"],
            info.get("services", {}).get("dashboard"),
            sched,
            workers,
            monitor,
        )
    finally:
        if monitor is not None:
            monitor.close()
        _stop(procs[::-1])  # workers first
        for f in logs:
            f.close()


# --------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="session")
def warm_kernels() -> None:
    """Compile (or load) the numba kernels once, so worker processes find them cached."""
    classify(Scene("ground", 2), np.array([1.0]), np.array([0.3]))
    classify(Scene("mass", 3), np.array([1.0]), np.array([0.3]), fidelity="fast")


@pytest.fixture(scope="module")
def remote(tmp_path_factory, warm_kernels):
    with dask_cluster(tmp_path_factory.mktemp("remote")) as cluster:
        yield cluster


@pytest.fixture(scope="module")
def long_reference(tmp_path_factory, remote) -> Path:
    """An undisturbed run of LONG (on the remote cluster)."""
    where = tmp_path_factory.mktemp("reference")
    write_study(where / "long.toml", LONG)
    proc = run_cli(
        where, "run", "long.toml", "-o", "ref.nc", "--scheduler-file", remote.scheduler_file
    )
    assert_ok(proc)
    return where / "ref.nc"


@pytest.fixture(scope="module")
def multi_on_local_cluster(
    tmp_path_factory, warm_kernels
) -> tuple[Path, subprocess.CompletedProcess]:
    """MULTI run once on a LocalCluster of 2 worker processes (``--workers 2``): the
    end-to-end checks and the comparison with the in-process run look at the same file."""
    where = tmp_path_factory.mktemp("multi")
    write_study(where / "multi.toml", MULTI)
    return where, run_cli(where, "run", "multi.toml", "-o", "multi.nc", "--workers", "2")


def long_chunk_keys(path: Path) -> list[str]:
    return [c.key for p in plan(Study.from_toml(path)) for c in p.chunks()]


# --------------------------------------------------------------------------- tests
def test_local_cluster_multi_scene_end_to_end(multi_on_local_cluster):
    where, proc = multi_on_local_cluster
    assert_ok(proc)
    assert "local cluster with 2 workers, dashboard http://127.0.0.1:" in proc.stderr
    n_points = 2 * 12 * 9 + 7
    assert_progress_complete(proc.stderr, n_points)
    c = counts(proc.stderr)
    n_chunks = sum(p.n_chunks for p in plan(Study.from_toml(where / "multi.toml")))
    assert c == {
        "chunks": n_chunks,
        "reusing": 0,
        "computing": n_chunks,
        "points": n_points,
        "computed": n_chunks,
        "reused": 0,
    }
    out = where / "multi.nc"
    assert not (where / "multi.nc.work").exists() and not temporary_files(out)

    tree = xr.open_datatree(out)
    assert set(tree.children) == {"sweep", "pts"}
    assert_provenance(tree.attrs, MULTI)
    assert "two scenes" in tree.attrs["comment"]

    sweep = tree["sweep"].to_dataset()
    assert sweep["regime"].dims == ("gamma", "beta", "r")
    assert float(sweep["kappa"]) == 1.0 and sweep["kappa"].dims == ()  # not swept: scalar
    np.testing.assert_allclose(sweep["gamma"], MULTI_SWEEP["gamma"])
    np.testing.assert_allclose(sweep["r"], MULTI_SWEEP["r"], rtol=1e-14)
    np.testing.assert_allclose(sweep["beta"], MULTI_SWEEP["beta"], rtol=1e-14, atol=1e-15)
    assert_cf_and_boundaries(sweep, ("gamma", "r"), max_cycles=120, design=True)
    assert json.loads(sweep.attrs["settings"])["max_cycles"] == 120
    R, B = np.meshgrid(sweep["r"].values, sweep["beta"].values, indexing="ij")
    for i, g in enumerate(MULTI_SWEEP["gamma"]):
        scene = Scene("ground", 2, 1, gamma=g, kappa=1.0)
        expected = classify(scene, R, B, "fast", max_cycles=120, design=True)
        assert_fields_equal(sweep, {"gamma": i}, expected)
    assert len(np.unique(sweep["regime"])) >= 2  # a map, not a constant

    pts = tree["pts"].to_dataset()
    assert pts["regime"].dims == ("point",)
    for name, values in MULTI_POINTS.items():
        np.testing.assert_array_equal(pts[name], values)
    assert_cf_and_boundaries(pts, ("point",), max_cycles=120, design=True)
    for i, (r, b, g) in enumerate(zip(*MULTI_POINTS.values(), strict=True)):
        expected = classify(
            Scene("mass", 3, 1, gamma=g), [r], [b], "fast", max_cycles=120, design=True
        )
        assert_fields_equal(pts, {"point": slice(i, i + 1)}, expected)

    with netCDF4.Dataset(out) as nc:  # on disk: int8 codes, no fill value, groups per scene
        assert set(nc.groups) == {"sweep", "pts"}
        var = nc["sweep"].variables["regime"]
        assert var.dtype == np.int8 and "_FillValue" not in var.ncattrs()
    root = xr.open_dataset(out)  # the root says what the file holds
    assert not root.data_vars and root.attrs["groups"].split() == ["sweep", "pts"]
    assert "open_datatree" in root.attrs["how_to_open"]


#: Two traced scenes: the README's (4 values of r, the size that failed with
#: "chunk arrays of different shapes: []") and a ground contact whose exact
#: closed forms (docs/theory.md 4.3, Eqs. 13, 63) are the truth the simulation
#: must find to within the bisection tolerance (half a beta step).
TRACE = """
[study]
name = "trace"
fidelity = "balanced"

[[scene]]
name = "traced"
contact = "base"
dof = 2
contact_mass = 2
mode = "trace"
r = {start = 0.1, stop = 3.0, num = 4}
beta = {start = 0.0, stop = 3.0, num = 3001}

[[scene]]
name = "ground"
contact = "ground"
dof = 2
contact_mass = 2
mode = "trace"
r = [0.3, 0.9, 1.3, 2.2]
beta = {start = 0.0, stop = 4.0, num = 4001}
"""


def test_trace_study_writes_its_result(tmp_path, remote):
    from analysis import boundaries

    write_study(tmp_path / "trace.toml", TRACE)
    proc = run_cli(
        tmp_path, "run", "trace.toml", "-o", "trace.nc", "--scheduler-file", remote.scheduler_file
    )
    assert_ok(proc)
    out = tmp_path / "trace.nc"
    assert not (tmp_path / "trace.nc.work").exists() and not temporary_files(out)
    tree = xr.open_datatree(out)
    assert set(tree.children) == {"traced", "ground"}
    for name, n_r in (("traced", 4), ("ground", 4)):
        ds = tree[name].to_dataset()
        for var in ("beta_continuous_numerical", "beta_motion_numerical"):
            assert ds[var].dims == ("r",) and ds[var].dtype == np.float64
            assert ds[var].shape == (n_r,)
        assert ds["trace_points"].dtype == np.int32 and (ds["trace_points"] > 0).all()
        assert ds["trace_monotone"].dtype == np.int8
        assert "beta" not in ds.dims
    np.testing.assert_allclose(tree["traced"]["r"], np.linspace(0.1, 3.0, 4), rtol=1e-14)
    ground = tree["ground"].to_dataset()
    step = 4.0 / 4000
    exact_c, exact_m = boundaries(
        Scene("ground", 2, 2, gamma=1.0, kappa=1.0), ground["r"].values, method="exact"
    )
    assert (ground["trace_monotone"] == 1).all()
    for var, exact in (("beta_continuous_numerical", exact_c), ("beta_motion_numerical", exact_m)):
        traced = ground[var].values
        assert np.all(np.isfinite(traced)), var
        # found by bisection to half a step; the closed form lies within a step of it
        # plus the relative tolerance of the traced-boundary tests (tests/test_trace.py)
        assert np.all(np.abs(traced - exact) <= step + 1e-3 * exact), (var, traced, exact)
    # the closed forms written beside the traced boundaries are the same closed forms
    np.testing.assert_allclose(ground["beta_motion_exact"], exact_m, rtol=1e-12)


STARTS = """
[study]
name = "starts"
fidelity = "fast"

[settings]
starts = ["held", "rest"]

[[scene]]
contact = "ground"
dof = 2
r = {start = 0.3, stop = 2.1, num = 6}
beta = {start = 0.05, stop = 1.0, num = 4}
"""


def test_regime_rest_is_written_only_where_rest_is_a_start(tmp_path, remote):
    write_study(tmp_path / "starts.toml", STARTS)
    args = ("run", "starts.toml", "-o", "starts.nc", "--scheduler-file", remote.scheduler_file)
    assert_ok(run_cli(tmp_path, *args))  # computed by worker processes
    ds = xr.open_dataset(tmp_path / "starts.nc")
    assert ds["regime_rest"].dtype == np.int8
    assert not (ds["regime_rest"] == regimes.NOT_COMPUTED).any()
    R, B = np.meshgrid(ds["r"].values, ds["beta"].values, indexing="ij")
    expected = classify(Scene("ground", 2), R, B, "fast", starts=("held", "rest"))
    assert_fields_equal(ds, {}, expected)


def test_small_study_runs_in_process_with_the_same_result(tmp_path, multi_on_local_cluster):
    """No worker processes to wait for when they would take longer to start than the
    study takes; --workers asks for them. Both files are identical (the --workers 2
    run is the one test_local_cluster_multi_scene_end_to_end checks)."""
    write_study(tmp_path / "multi.toml", MULTI)
    small = run_cli(tmp_path, "run", "multi.toml", "-o", "small.nc")
    assert_ok(small)
    assert "computing in this process (no worker processes" in small.stderr
    assert "local cluster with" not in small.stderr
    where, procs = multi_on_local_cluster
    assert_ok(procs)
    assert "local cluster with 2 workers" in procs.stderr
    assert_same_result(tmp_path / "small.nc", where / "multi.nc")


def test_remote_cluster_via_scheduler_file(tmp_path, remote):
    write_study(tmp_path / "kappa.toml", KAPPA)
    proc = run_cli(
        tmp_path, "run", "kappa.toml", "-o", "kappa.nc", "--scheduler-file", remote.scheduler_file
    )
    assert_ok(proc)
    assert f"connected to {remote.address} (2 workers)" in proc.stderr
    n_points = 2 * 10 * 6
    assert_progress_complete(proc.stderr, n_points)
    # The printed dashboard link is this scheduler's HTTP server.
    link = re.search(r"dashboard (http://\S+)", proc.stderr).group(1)
    assert link.startswith(f"http://127.0.0.1:{remote.dashboard_port}/")
    with urllib.request.urlopen(
        f"http://127.0.0.1:{remote.dashboard_port}/health", timeout=10
    ) as r:
        assert r.read() == b"ok"

    ds = xr.open_dataset(tmp_path / "kappa.nc")
    assert_provenance(ds.attrs, KAPPA)
    assert ds["regime"].dims == ("kappa", "beta", "r")
    assert_cf_and_boundaries(ds, ("kappa", "r"))
    R, B = np.meshgrid(ds["r"].values, ds["beta"].values, indexing="ij")
    for i, k in enumerate([0.5, 1.5]):
        assert_fields_equal(ds, {"kappa": i}, classify(Scene("base", 2, kappa=k), R, B, "fast"))


def test_remote_cluster_via_address(tmp_path, remote):
    assert remote.address.startswith("tcp://127.0.0.1:")
    write_study(tmp_path / "points.toml", POINTS)
    proc = run_cli(tmp_path, "run", "points.toml", "-o", "points.nc", "--scheduler", remote.address)
    assert_ok(proc)
    assert f"connected to {remote.address} (2 workers)" in proc.stderr
    assert_progress_complete(proc.stderr, 9)
    assert counts(proc.stderr)["computed"] == 3  # chunks of 4, 4 and 1 points

    ds = xr.open_dataset(tmp_path / "points.nc")
    assert_provenance(ds.attrs, POINTS)
    assert ds["regime"].dims == ("point",)
    assert_cf_and_boundaries(ds, ("point",))
    expected = classify(Scene("ground", 3, 2), ds["r"].values, ds["beta"].values)
    assert_fields_equal(ds, {}, expected)


def test_worker_killed_mid_run_loses_nothing(tmp_path, warm_kernels, long_reference):
    """kill -9 one of two workers while it runs a task: every point is still computed.

    Mid-run means: SAVED_BEFORE_SIGNAL chunks are on disk (the study has
    started) and the victim has a task of the study in processing on the
    scheduler at that moment; after the kill, fewer than all chunks are saved
    (the study had not finished). Workers run without a nanny, so the killed
    process is the worker itself and nothing restarts it: the other worker
    finishes the study.
    """
    study_path = write_study(tmp_path / "long.toml", LONG)
    keys = long_chunk_keys(study_path)
    out = tmp_path / "long.nc"
    with dask_cluster(tmp_path / "cluster", nanny=False, dashboard=False) as cluster:
        pids = cluster.monitor.run(os.getpid)
        assert sorted(pids.values()) == sorted(w.pid for w in cluster.workers)
        victim_addr, victim_pid = sorted(pids.items())[0]
        victim = next(w for w in cluster.workers if w.pid == victim_pid)
        proc = subprocess.Popen(
            _study_command(
                "run", "long.toml", "-o", "long.nc", "--scheduler-file", cluster.scheduler_file
            ),
            cwd=tmp_path,
            env=_env(),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            deadline = time.monotonic() + RUN_TIMEOUT
            while True:
                assert proc.poll() is None, "the run ended before the kill:\n" + proc.stderr.read()
                assert time.monotonic() < deadline, "no chunk was saved"
                if len(chunk_files(out)) >= SAVED_BEFORE_SIGNAL:
                    busy = cluster.monitor.processing().get(victim_addr, [])
                    if any(str(k).startswith("study-") for k in busy):
                        break
                time.sleep(0.01)
            os.kill(victim_pid, signal.SIGKILL)
            saved_at_kill = len(chunk_files(out))
            assert victim.wait(timeout=30) == -signal.SIGKILL
            stdout, stderr = proc.communicate(timeout=RUN_TIMEOUT)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        assert proc.returncode == 0, stderr
        assert SAVED_BEFORE_SIGNAL <= saved_at_kill < len(keys), "the kill was not mid-run"
        assert list(cluster.monitor.nthreads()) == [a for a in pids if a != victim_addr]
    c = counts(stderr)
    assert c["computed"] == c["chunks"] == len(keys) and c["reused"] == 0
    assert_progress_complete(stderr, c["points"])
    assert not chunk_files(out) and not temporary_files(out)
    assert_same_result(long_reference, out)


def _study_tasks(dashboard: str) -> int | None:
    """Tasks the scheduler of a LocalCluster holds (its dashboard's ``json/counts.json``),
    or None once it no longer answers (the cluster is closing)."""
    try:
        with urllib.request.urlopen(f"{dashboard}/json/counts.json", timeout=5) as reply:
            return int(json.load(reply)["tasks"])
    except OSError:
        return None


def test_interrupted_run_resumes_only_missing_chunks(tmp_path, remote, long_reference):
    """Ctrl-C (SIGINT to the process group), then the rerun computes only what is missing.

    The interrupted run uses a LocalCluster, whose worker processes are in the
    same process group and get the SIGINT too (as from a terminal). The rerun
    goes to the remote scheduler, whose task stream counts the tasks actually
    run, independently of the CLI's own count.

    Mid-run by construction, not by timing: once ``SAVED_BEFORE_SIGNAL`` chunks are
    saved the worker processes are stopped (SIGSTOP) before the Ctrl-C, and continued
    only when the client's scheduler holds no task of the study any more (it cancelled
    them: its dashboard's counts) or has closed; so no result arrives between the
    Ctrl-C and its handling, however loaded the machine (the rest of the study took
    about 1.5 s once 20 chunks were saved, its chunk files lagging behind).
    """
    import threading

    import psutil
    from distributed import get_task_stream

    study_path = write_study(tmp_path / "long.toml", LONG)
    keys = long_chunk_keys(study_path)
    out = tmp_path / "long.nc"
    proc = subprocess.Popen(
        _study_command("run", "long.toml", "-o", "long.nc", "--workers", "2"),
        cwd=tmp_path,
        env=_env(),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    lines: list[str] = []  # stderr, read as it comes (the pipe never fills)
    reader = threading.Thread(target=lambda: lines.extend(proc.stderr), daemon=True)
    reader.start()
    stopped: list[psutil.Process] = []
    try:
        deadline = time.monotonic() + RUN_TIMEOUT
        while len(chunk_files(out)) < SAVED_BEFORE_SIGNAL:
            assert proc.poll() is None, "the run ended before the interrupt"
            assert time.monotonic() < deadline, "no chunk was saved"
            time.sleep(0.01)
        workers = [  # the worker processes the LocalCluster spawned
            p
            for p in psutil.Process(proc.pid).children(recursive=True)
            if "spawn_main" in " ".join(p.cmdline())
        ]
        assert len(workers) == 2, [p.cmdline() for p in workers]
        for p in workers:
            p.suspend()
            stopped.append(p)
        assert proc.poll() is None, "the run ended before the interrupt"
        found = re.search(r"dashboard (http://127\.0\.0\.1:\d+)", "".join(lines))
        assert found, "".join(lines)
        assert _study_tasks(found[1])  # tasks in flight: the study is not over
        os.killpg(proc.pid, signal.SIGINT)
        deadline = time.monotonic() + 120
        while _study_tasks(found[1]):  # until the client has cancelled them
            assert time.monotonic() < deadline, "the Ctrl-C did not cancel the tasks"
            time.sleep(0.01)
        for p in stopped:
            p.resume()
        stopped.clear()
        proc.wait(timeout=120)
        reader.join(timeout=30)
        stderr = "".join(lines)
    finally:
        for p in stopped:
            with suppress(psutil.NoSuchProcess):
                p.resume()
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr, stderr
    saved = chunk_files(out)
    assert SAVED_BEFORE_SIGNAL <= len(saved) < len(keys), "the interrupt was not mid-run"
    assert f"interrupted: {len(saved)} of {len(keys)} chunks are saved" in stderr, stderr
    assert not out.exists() and not temporary_files(out)
    saved_keys = {p.stem for p in saved}
    assert saved_keys < set(keys)
    # The LocalCluster's processes are gone too (the whole group).
    deadline = time.monotonic() + 60
    while True:
        try:
            os.killpg(proc.pid, 0)
        except ProcessLookupError:
            break
        assert time.monotonic() < deadline, "processes of the interrupted run are still alive"
        time.sleep(0.1)

    with get_task_stream(client=remote.monitor) as stream:
        rerun = run_cli(
            tmp_path, "run", "long.toml", "-o", "long.nc", "--scheduler-file", remote.scheduler_file
        )
    assert_ok(rerun)
    c = counts(rerun.stderr)
    missing = len(keys) - len(saved)
    assert (c["reusing"], c["computing"], c["computed"], c["reused"]) == (
        len(saved),
        missing,
        missing,
        len(saved),
    )
    ran = [d["key"] for d in stream.data if str(d["key"]).startswith("study-")]
    assert sorted(ran) == sorted(f"study-{k}" for k in keys if k not in saved_keys)
    assert_progress_complete(rerun.stderr, c["points"])
    assert not out.with_name("long.nc.work").exists() and not temporary_files(out)
    assert_same_result(long_reference, out)
    shutil.rmtree(tmp_path / "long.nc.work", ignore_errors=True)
