"""Where a local study computes (study.drive.local_threads): threads of the client's
process while the planned compute is short, worker processes beyond it.

The single-contact simulator releases the GIL (``nogil`` entry points), the
several-contact one does not. The runs themselves (same file either way) are in
``tests/test_study_cluster.py``; the wall times in ``benchmarks/bench_small.py``.
"""

from __future__ import annotations

import pytest

from study import Study
from study.chunks import plan
from study.drive import IN_PROCESS_SECONDS, local_threads
from study.memory import MemoryWork
from tasks import kernel

SCENE = """
[study]
name = "where"
fidelity = "balanced"

[[scene]]
name = "s"
contact = "ground"
dof = 2
{extra}
r = {{start = 0.02, stop = 2.5, num = {n_r}}}
beta = {{start = 0.0, stop = 1.5, num = 500}}
"""


def _threads(study_file, cores, n_r, extra=""):
    study = Study.from_toml(study_file(SCENE.format(n_r=n_r, extra=extra)))
    plans, work = plan(study), MemoryWork()
    for p in plans:
        p.prepare(work)
    cpu = sum(p.est_seconds for p in plans)
    return local_threads(plans, work, cores), cpu


def test_threads_while_the_planned_compute_is_short(study_file):
    threads, cpu = _threads(study_file, 2, 20)  # 10,000 points: seconds of compute
    assert threads == 2 and cpu / 2 <= IN_PROCESS_SECONDS
    threads, cpu = _threads(study_file, 2, 1000, 'mode = "adaptive"')  # a few % simulated
    assert threads == 2 and cpu / 2 <= IN_PROCESS_SECONDS
    threads, cpu = _threads(study_file, 2, 3000)  # the dense grid: minutes
    assert threads == 0 and cpu / 2 > IN_PROCESS_SECONDS
    assert _threads(study_file, 1, 3000)[0] == 1  # one core: nothing to gain from processes


def test_several_contacts_hold_the_gil_one_thread_at_most(study_file):
    extra = "contact_mass = [1, 2]\nbeta_ratio = [1.0, 0.5]"
    study = SCENE.format(n_r=4, extra=extra).replace("num = 500", "num = 4")
    plans, work = plan(Study.from_toml(study_file(study))), MemoryWork()
    for p in plans:
        p.prepare(work)
    assert local_threads(plans, work, 2) == 1
    assert _threads(study_file, 2, 200, extra)[0] == 0  # longer than the start-up


@pytest.mark.parametrize("entry", ["run_points_given", "orbit_designs"])
def test_the_simulator_entry_points_release_the_gil(entry):
    assert getattr(kernel, entry).targetoptions.get("nogil") is True


@pytest.mark.parametrize("entry", ["run_points", "run_points_design", "run_points_seeded"])
def test_the_other_entry_points_compute_in_the_one_that_releases_it(entry, monkeypatch):
    """run_points and its kin are Python around the compiled run_points_given (one
    compile of the kernel, tasks.kernel.batch): the points are computed there."""
    import numpy as np

    from tasks.classifier import scene_modes_cached, settings_args
    from tasks.fidelity import resolve
    from tasks.kernel import batch
    from tasks.scene import Scene

    calls = []
    monkeypatch.setattr(batch, "run_points_given", lambda *a: calls.append(a) or (a[0],) * 3)
    r, beta = np.array([0.8, 1.6]), np.array([0.2, 0.6])
    scene = scene_modes_cached(Scene("ground", 2)).kernel_args()
    args = (r, beta, scene, settings_args(resolve("fast")), 0, np.zeros((2, 0), np.int64))
    getattr(kernel, entry)(*args[: {"run_points": 4, "run_points_design": 5}.get(entry, 6)])
    assert len(calls) == 1 and calls[0][0] is r and calls[0][1] is beta
