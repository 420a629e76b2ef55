"""Fault injection in the work folder and the file system (issue 22). Real processes.

* damage that used to block every rerun or to be reused silently: a directory or
  a FIFO where a chunk file belongs, a file where a scene folder belongs, a
  chunk re-signed without a field ('stick_fraction') or with another dtype, an
  adaptive plane re-signed as a 1 x 1 array, an adaptive point list re-signed
  to length 1, an adaptive plane without a field, a stale lock of any form:
  each is named in one line, discarded and computed again, and the result is
  identical to a clean run's;
* a work folder deleted mid-run does not let a second run start on the output;
* the OS refusing a write (no space, permission, HDF error, I/O error) while
  computing or writing: one line naming the path and the cause, exit 1 from the
  CLI, the older result untouched, the finished work kept; a rerun completes;
* SIGINT 0.3 s after the start: one line, exit 130.
"""

from __future__ import annotations

import errno
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
from test_adaptive import ADAPTIVE  # two planes of 64 x 40 (a gamma sweep)
from test_reliability_faults import SMALL, _start_run, _wait_saved
from test_study_cluster import LONG, _env, assert_same_result

from study import Study
from study.errors import StudyFailed, StudyInterrupted
from study.run import run_study
from study.store import WorkDir
from study.verify import META, with_metadata

pytestmark = pytest.mark.cluster

WAIT = 240
#: SMALL (10 chunks of one row) plus a point list: two scene folders.
TWO = (
    SMALL.replace('name = "small"', 'name = "two"')
    + """
[[scene]]
name = "pts"
contact = "mass"
dof = 3
points = [[0.4, 0.1], [0.9, 0.05], [1.3, 0.5], [1.8, 0.2]]
"""
)


@pytest.fixture(scope="module")
def client(cluster_client):
    """The session's LocalCluster (2 worker processes, none killed)."""
    return cluster_client


def _study(where: Path, text: str) -> Study:
    path = where / "study.toml"
    path.write_text(text, encoding="utf-8")
    return Study.from_toml(path)


def _resign(path: Path, edit) -> None:
    """Rewrite a chunk file with ``edit(arrays)`` and a valid key, version and checksum."""
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files if k not in META}
    with open(path, "wb") as f:
        np.savez(f, **with_metadata(path.stem, edit(arrays)))


def _kept_work(study: Study, out: Path, client, monkeypatch) -> Path:
    """Write a clean result beside ``out`` (``clean.nc``), then compute every unit of
    ``study`` for ``out`` and keep its work folder (the write is interrupted)."""
    import study.run as run_module

    clean = out.with_name("clean.nc")
    run_study(study, clean, client=client, progress=False, stream=io.StringIO())

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    with monkeypatch.context() as m:
        m.setattr(run_module, "_assemble", interrupted)
        with pytest.raises(StudyInterrupted):
            run_study(study, out, client=client, progress=False, stream=io.StringIO())
    work = out.with_name(out.name + ".work")
    assert work.is_dir()
    return work


def _assert_discarded(log: str, expected: list[tuple[Path, str]]) -> None:
    """Each damaged entry named in exactly one line, with why; no other line; no traceback."""
    lines = [ln for ln in log.splitlines() if ln.startswith("study: discarded ")]
    for path, why in expected:
        assert sum(str(path) in ln and why in ln for ln in lines) == 1, (path, log)
    assert len(lines) == len(expected) and "Traceback" not in log, log


def test_damaged_entries_are_named_discarded_recomputed(tmp_path, client, monkeypatch):
    study = _study(tmp_path, TWO)
    out, clean = tmp_path / "two.nc", tmp_path / "clean.nc"
    work = _kept_work(study, out, client, monkeypatch)
    grid = sorted((work / "sweep").glob("*.npz")) if (work / "sweep").is_dir() else []
    grid = grid or sorted(p for p in work.glob("*/*.npz") if p.parent.name != "pts")
    assert len(grid) == 10
    grid[0].unlink()
    grid[0].mkdir()  # a directory where a chunk file belongs
    (grid[0] / "x").write_text("x")
    grid[1].unlink()
    os.mkfifo(grid[1])  # a FIFO where a chunk file belongs
    _resign(grid[2], lambda a: {k: v for k, v in a.items() if k != "stick_fraction"})
    _resign(grid[3], lambda a: a | {"regime": a["regime"].astype(np.int16)})
    shutil.rmtree(work / "pts")
    (work / "pts").write_text("not a folder")  # a file where a scene folder belongs
    lock = out.with_name(f".{out.name}.lock")
    lock.mkdir()  # a directory where the lock file belongs
    log = io.StringIO()
    summary = run_study(study, out, client=client, progress=False, stream=log)
    text = log.getvalue()
    expected = [
        (grid[0], "not a chunk file"),
        (grid[1], "not a chunk file"),
        (grid[2], "has no field 'stick_fraction'"),
        (grid[3], "field 'regime' is int16, expected int8"),
        (work / "pts", "not a scene folder"),
        (lock, "a stale lock"),
    ]
    _assert_discarded(text, expected)
    assert summary.computed == 4 + 1 and summary.reused == 6, text  # 4 grid chunks, 1 list
    assert not work.exists() and not lock.exists()
    assert_same_result(out, clean)


def test_adaptive_planes_and_point_lists_are_verified_before_use(tmp_path, client, monkeypatch):
    study = _study(tmp_path, ADAPTIVE)
    out, clean = tmp_path / "adaptive.nc", tmp_path / "clean.nc"
    work = _kept_work(study, out, client, monkeypatch)
    planes = sorted((work / "sweep").glob("*-plane-*.npz"))
    lists = sorted((work / "sweep").glob("*-pts-*.npz"))  # tiles (study.tiles) and lists
    assert len(planes) == 2 and len(lists) >= 2  # point lists merged (study.saving)
    # a plane re-signed as 1 x 1 (it was accepted: 118,274 of 540,000 regimes wrong)
    _resign(planes[0], lambda a: {k: (v[:1, :1] if v.ndim >= 2 else v) for k, v in a.items()})
    _resign(planes[1], lambda a: {k: v for k, v in a.items() if k != "stick_fraction"})
    _resign(lists[0], lambda a: a | {"regime": a["regime"].astype(np.int16)})
    _resign(lists[1], lambda a: {k: v for k, v in a.items() if k != "cycles"})
    log = io.StringIO()
    run_study(study, out, client=client, progress=False, stream=log)
    expected = [
        (planes[0], "field 'regime' has shape (1, 1), expected (64, 40)"),
        (planes[1], "has no field 'stick_fraction'"),
        (lists[0], "field 'regime' is int16, expected int8"),
        (lists[1], "has no field 'cycles'"),
    ]
    _assert_discarded(log.getvalue(), expected)
    assert not work.exists()
    assert_same_result(out, clean, regrouped=True)  # lists recomputed: other warm seeds


def test_stale_locks_of_any_form_are_discarded(tmp_path):
    out = tmp_path / "o.nc"
    said: list[str] = []
    lock = out.with_name(".o.nc.lock")
    for make in (
        lambda p: p.mkdir(),
        lambda p: os.mkfifo(p),  # os.open of a FIFO would wait for a writer for ever
        lambda p: p.symlink_to(tmp_path / "nowhere"),
        lambda p: p.write_text("pid 12345 of a dead run"),  # a regular file: just reused
    ):
        make(lock)
        work = WorkDir(out, said.append)
        assert work.lock()
        work.remove()
        assert not os.path.lexists(lock)
    assert len(said) == 3 and all("a stale lock" in s for s in said), said


def test_a_held_lock_refuses_a_second_process(tmp_path):
    """A real second process holding the lock: this one is refused, then it is free."""
    out = tmp_path / "o.nc"
    code = (
        "import sys, time; from study.store import WorkDir; "
        "w = WorkDir(sys.argv[1]); assert w.lock(); print('locked', flush=True); time.sleep(60)"
    )
    holder = subprocess.Popen(
        [sys.executable, "-c", code, str(out)], env=_env(), stdout=subprocess.PIPE, text=True
    )
    try:
        assert holder.stdout.readline().strip() == "locked"
        assert not WorkDir(out).lock()
    finally:
        holder.kill()
        holder.wait(timeout=WAIT)
    assert WorkDir(out).lock()


def test_work_folder_deleted_mid_run_blocks_a_second_run(tmp_path):
    out = tmp_path / "long.nc"
    longer = LONG.replace("num = 60", "num = 240").replace('"balanced"', '"exact"')
    first = _start_run(tmp_path, "-o", "long.nc", "--workers", "1", "--quiet", study=longer)
    try:
        _wait_saved(out, 2, first)
        # the run saves meanwhile: a temporary file may be renamed under rmtree's feet
        shutil.rmtree(out.with_name("long.nc.work"), ignore_errors=True)
        second = subprocess.run(
            [sys.executable, "-m", "study", "run", "long.toml", "-o", "long.nc", "--quiet"],
            cwd=tmp_path,
            env=_env(),
            capture_output=True,
            text=True,
            timeout=WAIT,
        )
        assert second.returncode == 2, second.stderr
        assert "another run is writing" in second.stderr and "Traceback" not in second.stderr
        assert first.poll() is None, first.stderr.read()  # the first run goes on
        _wait_saved(out, 2, first)  # and saves into a work folder made again
    finally:
        os.killpg(first.pid, signal.SIGINT)
        first.communicate(timeout=WAIT)


# --------------------------------------------------------------------------- OS faults
def _fault(kind: str) -> BaseException:
    if kind == "no space":
        return OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    if kind == "permission":
        return PermissionError(errno.EACCES, os.strerror(errno.EACCES))
    if kind == "I/O error":
        return OSError(errno.EIO, os.strerror(errno.EIO))
    return RuntimeError("NetCDF: HDF error")


@pytest.mark.parametrize("kind", ["no space", "permission", "I/O error"])
def test_os_fault_while_computing_one_line_nothing_lost(tmp_path, client, monkeypatch, kind):
    import study.store as store

    study = _study(tmp_path, SMALL)
    out = tmp_path / "small.nc"
    out.write_bytes(b"an older result")
    real = store.np.savez
    calls = [0]

    def savez(f, **arrays):
        calls[0] += 1
        if calls[0] == 4:  # the fourth chunk: three are saved already
            raise _fault(kind)
        return real(f, **arrays)

    monkeypatch.setattr(store.np, "savez", savez)
    with pytest.raises(StudyFailed) as err:
        run_study(study, out, client=client, progress=False, stream=io.StringIO(), overwrite=True)
    msg = str(err.value)
    assert "\n" not in msg and "cannot save " in msg and os.strerror(_fault(kind).errno) in msg
    assert str(out.with_name("small.nc.work")) in msg and "rerun to resume" in msg
    assert out.read_bytes() == b"an older result"
    kept = list(out.with_name("small.nc.work").glob("*/*.npz"))
    assert len(kept) == 3 and not list(out.parent.glob(".*tmp")), kept
    monkeypatch.setattr(store.np, "savez", real)
    log = io.StringIO()
    summary = run_study(study, out, client=client, progress=False, stream=log, overwrite=True)
    assert summary.reused == 3 and summary.computed == 7, log.getvalue()


@pytest.mark.parametrize("kind", ["no space", "permission", "HDF error"])
def test_os_fault_while_writing_one_line_older_result_untouched(
    tmp_path, client, monkeypatch, kind
):
    import study.netcdf as netcdf

    study = _study(tmp_path, TWO)
    out = tmp_path / "two.nc"
    out.write_bytes(b"an older result")
    real = netcdf._fill_units
    calls = [0]

    def failing(group, *args, **kwargs):
        calls[0] += 1
        if calls[0] == 2:  # the second scene: the temporary file holds the first
            assert Path(group.filepath()).exists()
            raise _fault(kind)
        return real(group, *args, **kwargs)

    monkeypatch.setattr(netcdf, "_fill_units", failing)
    with pytest.raises(StudyFailed) as err:
        run_study(study, out, client=client, progress=False, stream=io.StringIO(), overwrite=True)
    msg = str(err.value)
    cause = "NetCDF: HDF error" if kind == "HDF error" else os.strerror(_fault(kind).errno)
    assert "\n" not in msg and f"cannot write {tmp_path}/.two.nc." in msg and cause in msg, msg
    assert "the older " in msg and "is still in place" in msg
    assert out.read_bytes() == b"an older result"
    assert not list(tmp_path.glob(".two.nc.*tmp"))  # no temporary file left
    monkeypatch.setattr(netcdf, "_fill_units", real)
    summary = run_study(
        study, out, client=client, progress=False, stream=io.StringIO(), overwrite=True
    )
    assert summary.computed == 0 and summary.reused == summary.n_chunks


def test_cli_os_fault_one_line_exit_1(tmp_path):
    """The CLI in a real process, with the disk full on the third chunk saved."""
    (tmp_path / "small.toml").write_text(SMALL, encoding="utf-8")
    code = (
        "import errno, os, sys, numpy\n"
        "import study.store as store\n"
        "real, calls = numpy.savez, [0]\n"
        "def savez(f, **a):\n"
        "    calls[0] += 1\n"
        "    if calls[0] == 3:\n"
        "        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))\n"
        "    return real(f, **a)\n"
        "store.np.savez = savez\n"
        "from study.cli import main\n"
        "sys.exit(main(['run', 'small.toml', '-o', 'small.nc', '--workers', '1', '--quiet']))\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code],
        cwd=tmp_path,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=WAIT,
    )
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("study: error:")]
    assert proc.returncode == 1, proc.stderr
    assert "Traceback" not in proc.stderr and len(lines) == 1, proc.stderr
    assert "No space left on device" in lines[0] and "small.nc.work" in lines[0]


#: ``python -m study ARGS`` that first says "up" on stderr, once the interpreter has
#: started (``site`` imported): a SIGINT before that ends in the interpreter's own
#: "Fatal Python error: init_import_site", which no program can catch (seen on a
#: loaded machine, where starting takes more than 0.05 s).
STUDY_SAYING_UP = (
    "import sys; print('up', file=sys.stderr, flush=True); import runpy; "
    "runpy.run_module('study', run_name='__main__', alter_sys=True)"
)


def test_sigint_right_after_the_start_one_line(tmp_path):
    (tmp_path / "small.toml").write_text(SMALL, encoding="utf-8")
    for delay in (0.05, 0.3):
        proc = subprocess.Popen(
            [sys.executable, "-c", STUDY_SAYING_UP, "run", "small.toml", "-o", f"{delay}.nc"],
            cwd=tmp_path,
            env=_env(),
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
        )
        assert proc.stderr.readline() == "up\n"
        time.sleep(delay)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=WAIT)
        assert "Traceback" not in err and "KeyboardInterrupt" not in err, (delay, err)
        if proc.returncode == 0:  # finished before the signal: nothing to say
            continue
        assert proc.returncode == 130, (delay, err)
        assert err.splitlines()[-1].startswith("study: interrupted"), (delay, err)
        assert not (tmp_path / f"{delay}.nc").exists()
