"""Fault injection (issue 13): nothing hangs, nothing lies. Real processes, 127.0.0.1 only,
every wait bounded.

* a damaged work folder: truncated, empty, garbage, bit-flipped chunk files, a
  well-formed chunk of the wrong shape, a chunk saved under another chunk's key,
  one computed by another simulator version, one without metadata: each is
  reported by path, discarded and recomputed; the result equals
  ``tasks.classify`` on the same points (a real LocalCluster computes them);
* an external scheduler killed mid-run: one line, exit 1, no traceback;
* every worker of an external cluster killed: the run stops after
  ``--worker-timeout`` with one line, exit 1, the finished chunks kept;
* a cluster without workers (API): ``StudyFailed`` after ``worker_timeout``;
* Ctrl-C while the local cluster starts: one line, exit 130;
* an interrupted run says which older result of its output is still in place;
* the watchdog and the cost tracker on a fake clock (deterministic).
"""

from __future__ import annotations

import io
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from test_study_cluster import LONG, _env, dask_cluster

from study import Study
from study.chunks import plan
from study.compute import compute_chunk
from study.cost import CostTracker
from study.errors import StudyFailed
from study.run import run_study
from study.store import WorkDir
from study.verify import META, check_chunk, simulator_version, with_metadata
from study.watchdog import ASK_TIMEOUT, LOOK_INTERVAL, SCHEDULER_GRACE, Watchdog
from tasks import Scene, classify

pytestmark = pytest.mark.cluster

SMALL = """
[study]
name = "small"
fidelity = "fast"
chunk_points = 6

[[scene]]
contact = "ground"
dof = 2
r = {start = 0.3, stop = 2.1, num = 10}
beta = {start = 0.05, stop = 1.0, num = 6}
"""
WAIT = 240  # seconds: the bound of every subprocess in this file


def _study(tmp_path: Path, text: str = SMALL) -> Study:
    path = tmp_path / "study.toml"
    path.write_text(text, encoding="utf-8")
    return Study.from_toml(path)


def _fill_work(study: Study, output: Path) -> tuple[WorkDir, list[Path]]:
    """Every chunk computed here (the pure task) and saved as a run saves it."""
    work = WorkDir(output)
    for p in plan(study):
        axes = p.axes()
        for c in p.chunks():
            work.save(c.scene, c.key, compute_chunk(p.task(c, axes)))
    return work, sorted(work.path.glob("*/*.npz"))


def _corrupt(files: list[Path]) -> dict[str, Path]:
    """Damage one chunk file per kind of fault; return kind -> damaged path."""
    kinds = {}
    f = iter(files)
    p = next(f)
    p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])
    kinds["truncated"] = p
    p = next(f)
    p.write_bytes(b"")
    kinds["empty"] = p
    p = next(f)
    p.write_bytes(np.random.default_rng(0).bytes(4096))
    kinds["garbage"] = p
    p = next(f)
    data = bytearray(p.read_bytes())
    data[len(data) // 2] ^= 0x08
    p.write_bytes(bytes(data))
    kinds["bit-flipped"] = p
    p = next(f)  # well-formed, self-consistent, but one row short
    with np.load(p) as z:
        arrays = {k: z[k] for k in z.files if k not in META}
    cut = {k: (v[:-1] if v.ndim else v) for k, v in arrays.items()}
    with open(p, "wb") as fh:
        np.savez(fh, **with_metadata(p.stem, cut))
    kinds["wrong shape"] = p
    p, other = next(f), next(f)
    shutil.copyfile(other, p)  # another chunk's file under this chunk's name
    kinds["another chunk's key"] = p
    p = next(f)
    with np.load(p) as z:
        entries = {k: z[k] for k in z.files}
    entries["_version"] = np.array("0123456789abcdef")  # an older simulator
    with open(p, "wb") as fh:
        np.savez(fh, **entries)
    kinds["other version"] = p
    p = next(f)
    with open(p, "wb") as fh:  # the format before verification: arrays only
        np.savez(fh, **{k: v for k, v in entries.items() if k not in META})
    kinds["no metadata"] = p
    return kinds


@pytest.fixture(scope="module")
def local_client(cluster_client):
    """A real LocalCluster on 127.0.0.1: the session's (2 worker processes, none killed)."""
    return cluster_client


def test_damaged_work_folder_is_reported_discarded_recomputed(tmp_path, local_client):
    study = _study(tmp_path)
    out = tmp_path / "small.nc"
    _, files = _fill_work(study, out)
    assert len(files) == 10
    damaged = _corrupt(files)
    (p,) = plan(study)
    expected = p.expected(next(p.chunks()))  # every chunk of SMALL is one row of 6 points
    for kind, path in damaged.items():
        assert check_chunk(path, path.stem, expected) is not None, kind
    log = io.StringIO()
    summary = run_study(study, out, client=local_client, progress=False, stream=log)
    text = log.getvalue()
    for kind, path in damaged.items():
        assert f"study: discarded {path}: " in text, (kind, text)
    assert summary.computed == len(damaged) and summary.reused == 10 - len(damaged), text
    assert "Traceback" not in text
    with xr.open_dataset(out, mask_and_scale=False) as ds:
        r, beta = np.meshgrid(ds.r.values, ds.beta.values, indexing="ij")
        # one call per chunk (a row of r): the warm starts' seeds are the chunk's own
        ref = [
            classify(Scene("ground", 2), r[i : i + 1], beta[i : i + 1], fidelity="fast")
            for i in range(r.shape[0])
        ]
        for name in ("regime", "slip_amplitude", "cycles", "stops_per_cycle"):
            expected = np.concatenate([getattr(x, name) for x in ref])
            np.testing.assert_array_equal(
                ds[name].transpose("r", "beta").values, expected, err_msg=name
            )


def test_chunk_keys_hold_the_simulator_version(tmp_path, monkeypatch):
    study = _study(tmp_path)
    keys = [c.key for p in plan(study) for c in p.chunks()]
    import study.plans as plans_module

    monkeypatch.setattr(plans_module, "simulator_version", lambda: "another-version")
    assert not set(keys) & {c.key for p in plan(study) for c in p.chunks()}
    assert len(simulator_version()) == 16


def test_cluster_without_workers_stops_after_the_timeout(tmp_path):
    from distributed import Client, LocalCluster

    study = _study(tmp_path)
    with (
        LocalCluster(
            n_workers=0, processes=True, host="127.0.0.1", dashboard_address="127.0.0.1:0"
        ) as cluster,
        Client(cluster) as client,
    ):
        t0 = time.monotonic()
        with pytest.raises(StudyFailed, match="no worker connected to the scheduler for"):
            run_study(
                study,
                tmp_path / "o.nc",
                client=client,
                progress=False,
                stream=io.StringIO(),
                worker_timeout=3,
            )
        assert time.monotonic() - t0 < 60
    assert not (tmp_path / "o.nc").exists()


#: Four times the points of LONG with the `exact` preset: a run still busy when its
#: fault arrives, however fast the machine (it ends at the fault, not by finishing).
LONGER = LONG.replace("num = 60", "num = 240").replace('"balanced"', '"exact"')


def _start_run(where: Path, *args: str, study: str = LONG) -> subprocess.Popen:
    (where / "long.toml").write_text(study, encoding="utf-8")
    return subprocess.Popen(
        [sys.executable, "-m", "study", "run", "long.toml", *args],
        cwd=where,
        env=_env(),
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def _wait_saved(out: Path, n: int, proc: subprocess.Popen) -> None:
    deadline = time.monotonic() + WAIT
    work = out.with_name(out.name + ".work")
    while len(list(work.glob("*/*.npz"))) < n:
        assert proc.poll() is None, proc.stderr.read()
        assert time.monotonic() < deadline, "the run saved nothing"
        time.sleep(0.2)


def _finish(proc: subprocess.Popen) -> tuple[int, list[str], str]:
    _, err = proc.communicate(timeout=WAIT)
    return proc.returncode, [ln for ln in err.splitlines() if ln.strip()], err


@pytest.mark.parametrize("fault", ["scheduler", "workers"])
def test_external_cluster_lost_one_line_exit_1(tmp_path, fault):
    """A killed scheduler is given up after ``--scheduler-timeout`` (here 5 s, not the
    default 30 s: the same watchdog path, study.watchdog); lost workers after
    ``--worker-timeout`` (5 s) while the scheduler answers within the default."""
    lost_scheduler = ("--scheduler-timeout", "5") if fault == "scheduler" else ()
    with dask_cluster(tmp_path / "cluster", n_workers=1, nanny=False, dashboard=False) as cl:
        out = tmp_path / "long.nc"
        proc = _start_run(
            tmp_path,
            "-o",
            "long.nc",
            "--scheduler-file",
            str(cl.scheduler_file),
            "--worker-timeout",
            "5",
            *lost_scheduler,
            "--quiet",
        )
        _wait_saved(out, 2, proc)
        t0 = time.monotonic()
        for p in [cl.scheduler] if fault == "scheduler" else cl.workers:
            p.kill()
        rc, lines, err = _finish(proc)
        took = time.monotonic() - t0
    assert rc == 1, err
    assert "Traceback" not in err and "CommClosedError" not in err, err
    errors = [ln for ln in lines if ln.startswith("study: error:")]
    assert len(errors) == 1 and lines[-1] == errors[0], err
    assert "rerun to resume" in errors[0]
    if fault == "workers":
        assert "no worker connected to the scheduler for" in errors[0], err
        assert took < 5 + SCHEDULER_GRACE + 60
    else:  # "lost the scheduler", or its tasks "cancelled by the scheduler"
        assert took < 5 + LOOK_INTERVAL + ASK_TIMEOUT + 2 * 5 + 30, took  # see test_door_faults
    assert len(list(out.with_name("long.nc.work").glob("*/*.npz"))) >= 2  # work kept


def test_local_workers_killed_until_their_nannies_give_up(tmp_path):
    """The audit's hang: kill the local worker process every 0.5 s; after some kills its
    nanny stops restarting it. The run must stop after --worker-timeout, one line."""
    import psutil

    proc = _start_run(
        tmp_path,
        *("-o", "long.nc", "--workers", "1", "--quiet", "--worker-timeout", "10"),
        study=LONGER,  # with LONG, the run finished between 5 kills on a CI run
    )
    _wait_saved(tmp_path / "long.nc", 1, proc)
    deadline = time.monotonic() + WAIT
    kills = 0
    while proc.poll() is None and time.monotonic() < deadline:
        for child in psutil.Process(proc.pid).children(recursive=True):
            try:
                if "spawn_main" in " ".join(child.cmdline()):
                    child.kill()
                    kills += 1
            except psutil.NoSuchProcess:
                pass
        time.sleep(0.5)  # a kill lands inside the restarted worker's start-up
    rc, lines, err = _finish(proc)
    if rc == 0:  # the run won the race (finished between kills): nothing to check
        pytest.skip(f"the run finished despite {kills} kills")
    assert rc == 1, err
    assert "Traceback" not in err, err
    assert lines[-1].startswith("study: error: ") and "rerun to resume" in lines[-1], err
    assert sum(ln.startswith("study: error:") for ln in lines) == 1, err


def test_ctrl_c_during_local_cluster_start_one_line(tmp_path):
    proc = _start_run(tmp_path, "-o", "long.nc", "--workers", "2")
    first = proc.stderr.readline()  # the plan line: the cluster starts now
    assert first.startswith("study: long:"), first
    time.sleep(0.5)
    os.killpg(proc.pid, signal.SIGINT)  # as a terminal sends it: to the whole group
    rc, lines, err = _finish(proc)
    assert rc == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    # the cluster may have come up just before the signal (a loaded machine): its
    # one information line may precede the interruption's, nothing else may
    lines = [ln for ln in lines if not ln.startswith("study: local cluster with")]
    assert len(lines) == 1 and lines[0].startswith("study: interrupted:"), err
    work = tmp_path / "long.nc.work"  # named only where it is kept
    assert (str(work) in lines[0] or "long.nc.work" in lines[0]) == work.is_dir(), err


def test_interrupted_run_names_the_older_result(tmp_path):
    older = tmp_path / "long.nc"
    older.write_bytes(b"an older result")
    proc = _start_run(
        tmp_path, "-o", "long.nc", "--workers", "1", "--quiet", "--overwrite", study=LONGER
    )
    _wait_saved(older, 1, proc)
    proc.send_signal(signal.SIGTERM)
    rc, lines, err = _finish(proc)
    assert rc == 143, err
    assert "the older long.nc (of " in lines[-1] and "is still in place" in lines[-1], err
    assert older.read_bytes() == b"an older result"


# --------------------------------------------------------------------------- fake clock
class _FakeClient:
    def __init__(self) -> None:
        self.status = "running"
        self.workers = 2
        self.scheduler = type("S", (), {"address": "tcp://127.0.0.1:1"})()

    def scheduler_info(self, n_workers: int = 0) -> dict:
        return {"n_workers": self.workers, "workers": {}}


def test_watchdog_on_a_fake_clock():
    now = [0.0]
    client = _FakeClient()
    dog = Watchdog(client, worker_timeout=30, clock=lambda: now[0])
    for t in range(0, 100, 1):  # workers present: never stops
        now[0] = float(t)
        dog.check()
    client.workers = 0
    now[0] = 100.0
    dog.check()
    now[0] = 129.0
    dog.check()  # 29 s without workers: still waiting
    now[0] = 131.0
    with pytest.raises(StudyFailed, match="no worker connected to the scheduler for 31 s"):
        dog.check()
    client.workers, client.status = 2, "connecting"  # the scheduler is gone
    dog = Watchdog(client, worker_timeout=30, clock=lambda: now[0])
    dog.check()
    now[0] += SCHEDULER_GRACE + 1
    with pytest.raises(StudyFailed, match="lost the scheduler tcp://127.0.0.1:1"):
        dog.check()


def test_cost_tracker_learns_a_slow_scene():
    """A 20-DOF scene 50 times slower than its estimate: after its first chunk the ETA
    counts it at its measured cost, not at the fast scene's rate."""
    now = [0.0]
    model = 1e-4  # seconds per point, both scenes
    tracker = CostTracker({"fast": (10_000, model), "slow": (10_000, model)}, clock=lambda: now[0])
    assert tracker.eta() is None
    now[0] = 1.0
    tracker.record("fast", 1000, 0.1)  # as estimated
    assert tracker.eta() == pytest.approx((9000 + 10_000) * model / 1.0)
    now[0] = 2.0
    tracker.record("slow", 100, 0.5)  # 5e-3 s per point: 50 times the model
    parallel = max(1.0, 0.6 / 2.0)
    expected = (9000 * model + 9900 * 5e-3) / parallel
    assert tracker.eta() == pytest.approx(expected)
    assert tracker.per_point("slow") == pytest.approx(5e-3)
    naive = (20_000 - 1100) / (1100 / 2.0)  # points left / overall point rate
    assert tracker.eta() > naive


def test_cost_tracker_scales_unseen_scenes_by_the_machine_speed():
    now = [0.0]
    tracker = CostTracker({"a": (1000, 1e-4), "b": (1000, 2e-4)}, clock=lambda: now[0])
    now[0] = 1.0
    tracker.record("a", 100, 0.03)  # this machine is 3 times slower than the model
    assert tracker.per_point("b") == pytest.approx(6e-4)
