"""examples/hpc_slurm.md: its code is valid for the batch systems it names.

The Python blocks are executed with recording stand-ins for the dask-jobqueue
classes; every argument they pass must be one the real class (dask-jobqueue
>= 0.9) accepts; the SLURM and PBS job scripts are then built by the real
classes (no batch system needed) and checked. The batch script's signal
handling is run in bash with a stand-in for ``study run``.
"""

from __future__ import annotations

import inspect
import os
import re
import signal
import subprocess
import sys
import time
import types
from pathlib import Path

import pytest

dask_jobqueue = pytest.importorskip("dask_jobqueue")
from dask_jobqueue.core import Job, JobQueueCluster  # noqa: E402

RECIPE = Path(__file__).resolve().parents[1] / "examples" / "hpc_slurm.md"
CLASSES = ("SLURMCluster", "PBSCluster", "SGECluster", "LSFCluster", "HTCondorCluster")
LOOPBACK = {"host": "127.0.0.1", "dashboard_address": ":0"}


def blocks(language: str) -> list[str]:
    """The fenced code blocks of the recipe in ``language``."""
    return re.findall(rf"```{language}\n(.*?)```", RECIPE.read_text(), flags=re.S)


class _Stop(Exception):
    pass


def recorded_calls(code: str, stop_after_first: bool) -> list[tuple[str, dict]]:
    """Run ``code`` with stand-ins for the dask-jobqueue classes; their (name, kwargs)."""
    calls: list[tuple[str, dict]] = []
    fake = types.ModuleType("dask_jobqueue")

    def recorder(name):
        def make(**kwargs):
            calls.append((name, kwargs))
            if stop_after_first:
                raise _Stop
            return types.SimpleNamespace()

        return make

    for name in CLASSES:
        setattr(fake, name, recorder(name))
    saved = sys.modules.get("dask_jobqueue")
    sys.modules["dask_jobqueue"] = fake
    try:
        exec(compile(code, str(RECIPE), "exec"), {"__name__": "recipe"})
    except _Stop:
        pass
    finally:
        sys.modules["dask_jobqueue"] = saved
    return calls


def accepted(name: str) -> set[str]:
    """Keyword arguments the real cluster class accepts (cluster, its job class, Job)."""
    cls = getattr(dask_jobqueue, name)
    out = set()
    for fn in (JobQueueCluster.__init__, cls.job_cls.__init__, Job.__init__):
        out |= set(inspect.signature(fn).parameters)
    return out - {"self", "base_class_kwargs", "kwargs"}


def job_script(name: str, kwargs: dict, tmp_path: Path, monkeypatch) -> str:
    """The real job script of ``kwargs`` (scheduler on the loopback, no scheduler file)."""
    monkeypatch.chdir(tmp_path)  # log_directory is created relative to here
    kwargs = {k: v for k, v in kwargs.items() if k != "interface"}
    kwargs["scheduler_options"] = LOOPBACK
    with getattr(dask_jobqueue, name)(**kwargs) as cluster:
        return cluster.job_script()


def test_recipe_names_only_arguments_each_class_accepts():
    calls = recorded_calls(blocks("python")[0], stop_after_first=True)
    calls += recorded_calls(blocks("python")[1], stop_after_first=False)
    assert [n for n, _ in calls] == [
        "SLURMCluster",
        "PBSCluster",
        "SGECluster",
        "LSFCluster",
        "HTCondorCluster",
    ]
    for name, kwargs in calls:
        unknown = set(kwargs) - accepted(name)
        assert not unknown, f"{name} rejects {sorted(unknown)}"
    # what the recipe says about the differences, against the library
    assert "account" not in accepted("SGECluster") | accepted("LSFCluster")
    assert "queue" not in accepted("HTCondorCluster")


def test_slurm_and_pbs_job_scripts(tmp_path, monkeypatch):
    (_, slurm), *_ = recorded_calls(blocks("python")[0], stop_after_first=True)
    script = job_script("SLURMCluster", slurm, tmp_path, monkeypatch)
    for line in ("#SBATCH -p compute", "#SBATCH -A myproject", "#SBATCH -t 04:00:00"):
        assert line in script.splitlines(), script
    assert "#SBATCH --cpus-per-task=32" in script
    assert "source ~/venvs/friction/bin/activate" in script
    assert re.search(r"--nthreads 1 .*--nworkers 32", script), script

    pbs = dict(recorded_calls(blocks("python")[1], stop_after_first=False))["PBSCluster"]
    script = job_script("PBSCluster", pbs, tmp_path, monkeypatch)
    for line in ("#PBS -q workq", "#PBS -A myproject", "#PBS -l walltime=04:00:00"):
        assert line in script.splitlines(), script
    assert "ncpus=32" in script
    assert re.search(r"--nthreads 1 .*--nworkers 32", script), script


def batch_script() -> str:
    (script,) = (b for b in blocks("bash") if b.startswith("#!/bin/bash\n#SBATCH"))
    return script


def test_batch_script_signal_line():
    lines = batch_script().splitlines()
    assert any(re.match(r"#SBATCH --signal=B:TERM@\d+", line) for line in lines), lines


@pytest.mark.skipif(sys.platform == "win32", reason="bash")
def test_batch_script_forwards_sigterm_to_study_run(tmp_path):
    """SIGTERM to the batch shell reaches ``study run``, whose exit code the job returns."""
    script = batch_script()
    tail = script[re.search(r"^study run ", script, flags=re.M).start() :]
    started, got = tmp_path / "started", tmp_path / "got-term"
    fake = tmp_path / "fake_study.sh"  # stands in for study run: exits 143 on SIGTERM
    fake.write_text(
        f"trap 'touch {got}; exit 143' TERM\ntouch {started}\nwhile true; do sleep 0.05; done\n"
    )
    tail, n = re.subn(r"^study run [^\n]*&$", lambda _: f"bash {fake} &", tail, count=1, flags=re.M)
    assert n == 1
    path = tmp_path / "job.sh"
    path.write_text("workers_pid=\nscheduler_pid=\n" + tail)
    job = subprocess.Popen(["bash", str(path)], cwd=tmp_path)
    try:
        deadline = time.monotonic() + 30
        while not started.exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert started.exists()
        os.kill(job.pid, signal.SIGTERM)  # what --signal=B:TERM does
        assert job.wait(timeout=30) == 143
        assert got.exists()
    finally:
        if job.poll() is None:
            job.kill()
