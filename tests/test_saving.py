"""Saving in the background (study.saving), with worker processes and with threads of the run.

* the writer merges queued point lists of one plane into one file that a rerun
  reads as a point list (its key checked against its points), writes every
  queued result on close, and raises its error in the client's thread;
* a small adaptive study computed in threads of this process, interrupted
  (Ctrl-C) mid-run: every point list that arrived is on disk, in fewer files
  than point lists; the rerun reuses them and writes the same file as an
  uninterrupted run;
* ``kill -9`` of the client mid-run (the kill comes from inside, after a fixed
  number of point lists, so it is always mid-run): what is on disk is whole, and
  the rerun writes the same file as an uninterrupted run.
"""

from __future__ import annotations

import io
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from test_adaptive import ADAPTIVE  # two planes of 64 x 40 (a gamma sweep), fast fidelity
from test_study_cluster import _env, assert_same_result

from study import Study
from study.adaptive import AdaptivePlan, PointList
from study.chunks import plan
from study.drive import Driven
from study.errors import StudyFailed, StudyInterrupted
from study.run import run_study
from study.saving import Saver
from study.store import WorkDir

WAIT = 240


@pytest.fixture
def adaptive_study(tmp_path):
    path = tmp_path / "adaptive.toml"
    path.write_text(ADAPTIVE, encoding="utf-8")
    return Study.from_toml(path)


@pytest.fixture
def clean(tmp_path_factory, adaptive_study):
    """An uninterrupted run of the study (threads of this process)."""
    out = tmp_path_factory.mktemp("clean") / "clean.nc"
    run_study(adaptive_study, out, progress=False, stream=io.StringIO())
    return out


def _lists(out):
    return sorted(out.with_name(out.name + ".work").glob("*/*-pts-*.npz"))


def test_queued_point_lists_of_a_plane_become_one_file(tmp_path, adaptive_study):
    (p,) = plan(adaptive_study)
    p.verbose = False
    work = WorkDir(tmp_path / "x.nc")
    p.prepare(work)
    first = p.next_unit(work)  # the coarse lattice of the first plane, in three lists
    tag = AdaptivePlan.merge_group(first)
    units = [
        PointList(first.scene, p._list_key(tag, part), part, {}, first.sweep)
        for part in np.array_split(first.idx, 3)
    ]
    n = sum(u.n_points for u in units)
    done = Driven()
    saver = Saver(work, done, background=False)
    results = []
    for u in units:
        arrays = p._empty(u.n_points)  # every field, its dtype and shape
        arrays["regime"] = (u.idx % 3).astype(np.int8)  # a value that follows each point
        arrays["seconds"] = np.float64(1.0)
        results.append((p, u, arrays | u.saved_with))
    saver._write(results)
    (path,) = _lists(tmp_path / "x.nc")
    assert done.saved == 3
    key = path.stem
    assert AdaptivePlan._list_length(key) == n
    saved = work.load("sweep", key, p.expected(n))
    idx = np.sort(np.concatenate([u.idx for u in units]))
    np.testing.assert_array_equal(saved["index"], idx)
    np.testing.assert_array_equal(saved["regime"], idx % 3)  # rows moved with their points
    assert float(saved["seconds"]) == 3.0
    assert p._list_key(AdaptivePlan.merge_group(units[0]), saved["index"]) == key


def test_writer_error_reaches_the_client_and_close_writes_everything(tmp_path, monkeypatch):
    class Unit:
        scene = "s"

        def __init__(self, key):
            self.key = key

    work = WorkDir(tmp_path / "x.nc")
    done = Driven()
    saver = Saver(work, done)
    for i in range(5):
        saver.put(object(), Unit(f"k{i}"), {"a": np.arange(3) + i})
    saver.close()
    assert done.saved == 5 and len(list(work.path.glob("s/*.npz"))) == 5
    np.testing.assert_array_equal(work.load("s", "k4")["a"], np.arange(3) + 4)

    def full(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr("study.store.np.savez", full)
    saver = Saver(work, Driven())
    saver.put(object(), Unit("k9"), {"a": np.arange(3)})
    with pytest.raises(StudyFailed, match="No space left on device"):
        saver.close()
    assert not list(work.path.glob("s/.*tmp"))


def test_threads_ctrl_c_keeps_every_arrived_list_and_resumes_identically(
    tmp_path, adaptive_study, clean, monkeypatch
):
    out = tmp_path / "adaptive.nc"
    real_accept = AdaptivePlan.accept
    arrived = []

    def interrupted_accept(self, unit, arrays, *args, **kwargs):
        real_accept(self, unit, arrays, *args, **kwargs)  # a tile saves the points it simulated
        arrived.append(arrays["index"].size if "index" in arrays else unit.n_points)
        if len(arrived) == 3:  # 3 of the 8 tiles: no plane finished (4 tiles each)
            raise KeyboardInterrupt

    monkeypatch.setattr(AdaptivePlan, "accept", interrupted_accept)
    log = io.StringIO()
    with pytest.raises(StudyInterrupted):
        run_study(adaptive_study, out, progress=False, stream=log)
    assert "computing in this process" in log.getvalue()
    monkeypatch.setattr(AdaptivePlan, "accept", real_accept)
    files = _lists(out)
    on_disk = sum(AdaptivePlan._list_length(f.stem) or np.load(f)["index"].size for f in files)
    assert on_disk == sum(arrived)  # nothing that arrived is lost at Ctrl-C
    assert 1 <= len(files) <= len(arrived)
    log = io.StringIO()
    run_study(adaptive_study, out, progress=False, stream=log)
    reused = [ln for ln in log.getvalue().splitlines() if "saved points reused" in ln]
    n = [int(ln.split(" saved points reused")[0].split()[-1].replace(",", "")) for ln in reused]
    assert sum(n) == on_disk
    assert_same_result(clean, out, regrouped=True)


KILLED = """
import os, signal, sys
from study.adaptive import AdaptivePlan, PointList
from study.cli import main

real, seen = AdaptivePlan.accept, []

def accept(self, unit, *args, **kwargs):
    real(self, unit, *args, **kwargs)
    seen.append(unit)
    if len(seen) == {n}:
        os.kill(os.getpid(), signal.SIGKILL)

AdaptivePlan.accept = accept
sys.exit(main(["run", "adaptive.toml", "-o", "adaptive.nc", "--quiet"]))
"""


def test_kill_9_mid_run_loses_nothing_whole_and_resumes_identically(tmp_path, clean):
    (tmp_path / "adaptive.toml").write_text(ADAPTIVE, encoding="utf-8")
    script = textwrap.dedent(KILLED.format(n=8))
    proc = subprocess.run(
        [sys.executable, "-c", script], cwd=tmp_path, env=_env(), timeout=WAIT, capture_output=True
    )
    assert proc.returncode == -9, proc.stderr
    out = tmp_path / "adaptive.nc"
    assert not out.exists()
    work = WorkDir(out)
    for f in _lists(out):  # whatever is on disk under a final name is whole
        arrays = work.load("sweep", f.stem)  # a tile's key names no length: its fields'
        n = AdaptivePlan._list_length(f.stem) or arrays["regime"].size
        assert arrays["index"].size == n == arrays["regime"].size
    rerun = subprocess.run(
        [sys.executable, "-m", "study", "run", "adaptive.toml", "-o", "adaptive.nc", "--quiet"],
        cwd=tmp_path,
        env=_env(),
        timeout=WAIT,
        capture_output=True,
        text=True,
    )
    assert rerun.returncode == 0, rerun.stderr
    assert "discarded" not in rerun.stderr and "Traceback" not in rerun.stderr
    assert_same_result(clean, out, regrouped=True)
