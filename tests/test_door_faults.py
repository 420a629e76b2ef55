"""Nothing hangs at the door (issue 22): real processes, 127.0.0.1 only, every wait bounded.

* a fake scheduler (a loopback TCP server that accepts and never answers), given as
  ``--scheduler`` or in a ``--scheduler-file``: one line, exit 2, within the
  ``--scheduler-timeout``, nothing written;
* a real scheduler stopped with SIGSTOP before the run: the same;
* a real scheduler stopped mid-run: one line, exit 1, within the
  ``--scheduler-timeout`` plus the look and close bounds, finished chunks kept;
* the local worker processes stopped mid-run: one line, exit 1, within the
  ``--worker-timeout`` plus bounds, finished chunks kept;
* :func:`study.connect.connect` on the fake scheduler (API): ``StudyError`` naming
  the option, within the timeout.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import pytest
from test_reliability_faults import _start_run, _wait_saved
from test_study_cluster import LONG, _env, dask_cluster

from study.connect import connect
from study.errors import StudyError
from study.watchdog import ASK_TIMEOUT, LOOK_INTERVAL

pytestmark = pytest.mark.cluster

WAIT = 240  # seconds: the bound of every subprocess in this file
#: A silent server: accepts every connection, reads nothing, never answers.
FAKE_SCHEDULER = """
import socket, sys
s = socket.socket()
s.bind(("127.0.0.1", 0))
s.listen(64)
print(s.getsockname()[1], flush=True)
held = []
while True:
    held.append(s.accept()[0])
"""


@contextmanager
def fake_scheduler():
    """The address of a silent TCP server running in its own process."""
    proc = subprocess.Popen(
        [sys.executable, "-c", FAKE_SCHEDULER], stdout=subprocess.PIPE, text=True
    )
    try:
        port = int(proc.stdout.readline())
        yield f"tcp://127.0.0.1:{port}"
    finally:
        proc.kill()
        proc.wait(timeout=20)


def _run(cwd: Path, *args: str, timeout: float = WAIT) -> tuple[subprocess.CompletedProcess, float]:
    (cwd / "long.toml").write_text(LONG, encoding="utf-8")
    t0 = time.monotonic()
    proc = subprocess.run(
        [sys.executable, "-m", "study", "run", "long.toml", "-o", "long.nc", "--quiet", *args],
        cwd=cwd,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    return proc, time.monotonic() - t0


def _one_error_line(proc: subprocess.CompletedProcess, rc: int) -> str:
    assert proc.returncode == rc, proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr
    errors = [ln for ln in proc.stderr.splitlines() if ln.startswith("study: error:")]
    assert len(errors) == 1, proc.stderr
    assert proc.stderr.strip().splitlines()[-1] == errors[0], proc.stderr
    return errors[0]


def _nothing_written(where: Path) -> None:
    assert not (where / "long.nc").exists()
    assert not (where / "long.nc.work").exists()


def test_fake_scheduler_address_one_line_exit_2(tmp_path):
    with fake_scheduler() as address:
        proc, took = _run(tmp_path, "--scheduler", address, "--scheduler-timeout", "3")
    line = _one_error_line(proc, 2)
    assert line.startswith(f"study: error: --scheduler: cannot connect to {address} within 3 s")
    assert "no answer" in line
    assert took < 3 + 30  # the timeout, the interpreter's start and the plan
    _nothing_written(tmp_path)


def test_scheduler_file_naming_a_fake_scheduler_one_line_exit_2(tmp_path):
    with fake_scheduler() as address:
        sched = tmp_path / "scheduler.json"
        sched.write_text(json.dumps({"address": address}))
        proc, took = _run(tmp_path, "--scheduler-file", str(sched), "--scheduler-timeout", "3")
    line = _one_error_line(proc, 2)
    assert line.startswith("study: error: --scheduler-file: cannot connect to"), line
    assert str(sched) in line
    assert took < 3 + 30
    _nothing_written(tmp_path)


def test_connect_api_fake_scheduler_bounded():
    with fake_scheduler() as address:
        t0 = time.monotonic()
        with pytest.raises(StudyError, match=r"^--scheduler: cannot connect .* within 1\.5 s"):
            connect(address, timeout=1.5)
        assert time.monotonic() - t0 < 10
    with pytest.raises(StudyError, match="^--scheduler-timeout"):
        connect("tcp://127.0.0.1:1", timeout=0)
    with pytest.raises(StudyError, match="exactly one"):
        connect()


def test_stopped_scheduler_before_the_run_one_line_exit_2(tmp_path):
    with dask_cluster(tmp_path / "cluster", n_workers=1, nanny=False, dashboard=False) as cl:
        cl.scheduler.send_signal(signal.SIGSTOP)
        try:
            proc, took = _run(
                tmp_path, "--scheduler-file", str(cl.scheduler_file), "--scheduler-timeout", "3"
            )
        finally:
            cl.scheduler.send_signal(signal.SIGCONT)
    line = _one_error_line(proc, 2)
    assert "cannot connect to" in line and "within 3 s" in line, line
    assert took < 3 + 30
    _nothing_written(tmp_path)


def _finish(proc: subprocess.Popen) -> subprocess.CompletedProcess:
    try:
        _, err = proc.communicate(timeout=WAIT)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        raise
    return subprocess.CompletedProcess(proc.args, proc.returncode, "", err)


def test_scheduler_stopped_mid_run_one_line_exit_1(tmp_path):
    with dask_cluster(tmp_path / "cluster", n_workers=1, nanny=False, dashboard=False) as cl:
        proc = _start_run(
            tmp_path,
            *("-o", "long.nc", "--quiet", "--scheduler-file", str(cl.scheduler_file)),
            *("--scheduler-timeout", "4"),
        )
        try:
            _wait_saved(tmp_path / "long.nc", 2, proc)
            cl.scheduler.send_signal(signal.SIGSTOP)
            t0 = time.monotonic()
            done = _finish(proc)
            took = time.monotonic() - t0
        finally:
            cl.scheduler.send_signal(signal.SIGCONT)
    line = _one_error_line(done, 1)
    assert "did not answer for" in line and "--scheduler-timeout" in line, line
    assert "rerun to resume" in line
    # the timeout and one look, the bounded cancel (ASK_TIMEOUT) and close (2 x timeout),
    # a margin for a loaded machine (measured: 5.5 s)
    assert took < 4 + LOOK_INTERVAL + ASK_TIMEOUT + 2 * 4 + 5, took
    assert len(list((tmp_path / "long.nc.work").glob("*/*.npz"))) >= 2  # work kept


def test_local_workers_stopped_mid_run_one_line_exit_1(tmp_path):
    import psutil

    proc = _start_run(
        tmp_path, "-o", "long.nc", "--quiet", "--workers", "1", "--worker-timeout", "6"
    )
    stopped = []
    try:
        _wait_saved(tmp_path / "long.nc", 1, proc)
        for child in psutil.Process(proc.pid).children(recursive=True):
            if "spawn_main" in " ".join(child.cmdline()):
                child.send_signal(signal.SIGSTOP)
                stopped.append(child)
        assert stopped, "no worker process found"
        t0 = time.monotonic()
        done = _finish(proc)
        took = time.monotonic() - t0
    finally:
        for child in stopped:
            try:
                child.send_signal(signal.SIGCONT)
            except psutil.NoSuchProcess:
                pass
    if done.returncode == 0:  # finished before the stop arrived: nothing to check
        pytest.skip("the run finished before its workers were stopped")
    line = _one_error_line(done, 1)
    assert "stopped answering" in line and "--worker-timeout" in line, line
    # the timeout and one look, the bounded close of the cluster, a margin (measured: 11 s)
    assert took < 6 + LOOK_INTERVAL + ASK_TIMEOUT + 2 * 30 + 5, took
    assert len(list((tmp_path / "long.nc.work").glob("*/*.npz"))) >= 1


def test_dask_logs_stay_quiet_when_distributed_is_imported_inside():
    """A run quiets Dask's logs before it connects, and connecting imports
    ``distributed``, whose import sets its own log levels: they must stay quiet (a lost
    scheduler's "Batched Comm Closed" traceback once reached stderr this way)."""
    code = (
        "import logging, sys\n"
        "from study.watchdog import quiet_dask_logs\n"
        "assert 'distributed' not in sys.modules\n"
        "with quiet_dask_logs():\n"
        "    import distributed.batched\n"
        "    inside = logging.getLogger('distributed.batched').getEffectiveLevel()\n"
        "print(inside, logging.getLogger('distributed').getEffectiveLevel())\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    inside, after = map(int, out.stdout.split())
    assert inside == 50 and after < 50, out.stdout  # CRITICAL inside, restored after
