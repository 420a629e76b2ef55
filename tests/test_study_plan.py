"""Study definition round trips, expansion into chunks and stable chunk keys (no Dask)."""

from __future__ import annotations

import subprocess
import sys
import tomllib

import numpy as np
import pytest

from study import Study
from study.chunks import plan
from study.cost import points_per_task
from study.store import WorkDir

TEXT = """
[study]
name = "t"
fidelity = "fast"
task_seconds = 0.05

[settings]
max_cycles = 300

[[scene]]
name = "sweep"
contact = "ground"
dof = 2
gamma = {values = [0.5, 2.0]}
kappa = {start = 0.5, stop = 2.0, num = 3, spacing = "log"}
r = {start = 0.05, stop = 2.5, num = 23}
beta = {start = 0.0, stop = 1.0, num = 17}

[[scene]]
contact = "mass"
dof = 2
points = [[0.5, 0.1], [1.0, 0.2], [2.0, 0.3]]
"""


def test_from_toml_equals_from_dict_and_round_trips(study_file):
    a = Study.from_toml(study_file(TEXT))
    b = Study.from_dict(tomllib.loads(TEXT))
    assert a == b
    assert a.text == TEXT  # provenance keeps the file as written
    c = Study.from_dict(tomllib.loads(a.to_toml()))
    assert c == a
    assert a.settings.max_cycles == 300 and a.settings.event_tol == 1e-9  # fast preset
    assert [s.name for s in a.scenes] == ["sweep", "2dof_mass_m1"]  # default name = label


def test_axes_and_sizes(study_file):
    s = Study.from_toml(study_file(TEXT))
    sweep = s.scenes[0]
    kappa = sweep.kappa.values_array()
    np.testing.assert_allclose(kappa, [0.5, 1.0, 2.0])  # geometric: ratio 2 each step
    r = sweep.r.values_array()
    assert r[0] == 0.05 and r[-1] == 2.5 and np.allclose(np.diff(r), 2.45 / 22)
    assert sweep.sweep_shape == (2, 3) and sweep.plane_shape == (23, 17)
    assert s.n_points == 2 * 3 * 23 * 17 + 3
    scene = sweep.scene_at(gamma=2.0, kappa=0.5)
    assert scene.gammas == (1.0, 2.0) and scene.kappas == (1.0, 0.5)


def test_chunks_cover_every_point_once(study_file):
    s = Study.from_toml(study_file(TEXT))
    for p in plan(s):
        count = np.zeros((*p.spec.sweep_shape, *p.spec.plane_shape), dtype=int)
        target = points_per_task(p.spec.dof, s.fidelity, s.task_seconds)
        chunks = list(p.chunks())
        assert len(chunks) == p.n_chunks
        assert len({c.key for c in chunks}) == len(chunks)
        for c in chunks:
            assert 1 <= c.n_points <= max(target, 1)
            if p.kind == "grid":
                count[(*c.sweep, slice(*c.rows), slice(*c.cols))] += 1
            else:
                count[slice(*c.rows)] += 1
        assert (count == 1).all()
    # Tasks group many points: not one task per point.
    sweep = plan(s)[0]
    assert sweep.n_chunks < sweep.spec.n_points / 10


def _keys(study: Study) -> list[str]:
    return [c.key for p in plan(study) for c in p.chunks()]


def test_keys_are_stable_and_follow_the_content(study_file):
    s = Study.from_toml(study_file(TEXT))
    keys = _keys(s)
    assert keys == _keys(Study.from_toml(study_file(TEXT)))
    # Another interpreter (other hash seed) maps the study to the same keys.
    code = (
        "import sys; from study import Study; from study.chunks import plan; "
        "print('\\n'.join(c.key for p in plan(Study.from_toml(sys.argv[1])) for c in p.chunks()))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code, str(study_file(TEXT))],
        capture_output=True,
        text=True,
        check=True,
        env={"PYTHONHASHSEED": "123", "PATH": ""},
    ).stdout.split()
    assert out == keys
    # Any change of settings, physics or points gives new keys.
    changed = [
        TEXT.replace("max_cycles = 300", "max_cycles = 301"),
        TEXT.replace('fidelity = "fast"', 'fidelity = "balanced"\nchunk_points = 40'),
        TEXT.replace("gamma = {values = [0.5, 2.0]}", "gamma = {values = [0.5, 2.5]}"),
        TEXT.replace("[2.0, 0.3]", "[2.0, 0.31]"),
    ]
    for text in changed:
        other = _keys(Study.from_toml(study_file(text, "other.toml")))
        assert set(other) != set(keys)
    # Changing only the points of the second scene keeps the first scene's keys.
    kept = set(_keys(Study.from_toml(study_file(changed[3], "other.toml"))))
    assert {k for k in keys if k.startswith("sweep-")} <= kept


def test_work_dir_save_is_atomic_and_loadable(tmp_path):
    work = WorkDir(tmp_path / "out.nc")
    assert work.path == tmp_path / "out.nc.work"
    arrays = {"regime": np.array([[0, 1], [2, -1]], dtype=np.int8), "seconds": np.float64(0.5)}
    work.save("s", "k1", arrays)
    assert work.has("s", "k1") and not work.has("s", "k2")
    back = work.load("s", "k1")
    np.testing.assert_array_equal(back["regime"], arrays["regime"])
    assert back["regime"].dtype == np.int8
    assert [p.name for p in (tmp_path / "out.nc.work" / "s").iterdir()] == ["k1.npz"]
    work.remove()
    assert not work.path.exists()


def test_plan_command(study_file, run_cli):
    study_file(TEXT)
    proc = run_cli("plan", "study.toml", "--workers", "2")
    assert proc.returncode == 0, proc.stderr
    s = Study.from_toml(study_file(TEXT))
    for p in plan(s):
        row = next(line for line in proc.stdout.splitlines() if line.startswith(p.spec.name))
        cols = row.split()
        assert int(cols[2].replace(",", "")) == p.spec.n_points
        assert int(cols[3].replace(",", "")) == p.n_chunks
    assert f"{s.n_points:,} points" in proc.stdout


def test_plan_wall_estimate_where_the_run_computes(study_file, run_cli):
    """Without --workers a short study runs in threads of its own process
    (study.drive.local_threads): no cluster start-up in the estimate."""
    import re

    from study.cost import IN_PROCESS_STARTUP_SECONDS, SCHEDULING_OVERHEAD, STARTUP_SECONDS

    study_file(TEXT)
    total = {}
    for extra in ((), ("--workers", "2")):
        proc = run_cli("plan", "study.toml", *extra)
        assert proc.returncode == 0, proc.stderr
        line = proc.stdout.splitlines()[-1]
        cpu = sum(float(r.split()[-1]) for r in proc.stdout.splitlines()[2:-1])
        total[extra] = float(re.search(r"about ([\d.,]+) s (in|on)", line).group(1))
        if extra:
            assert "on 2 workers" in line and "thread" not in line
            expected = STARTUP_SECONDS + cpu / 2 * (1 + SCHEDULING_OVERHEAD)
        else:
            m = re.search(r"in (\d+) threads? of the run's process", line)
            assert m, line
            threads = int(m.group(1))
            expected = IN_PROCESS_STARTUP_SECONDS + cpu / threads * (1 + SCHEDULING_OVERHEAD)
        assert abs(total[extra] - expected) <= 0.6, (line, expected)
    assert total[()] < total[("--workers", "2")]


@pytest.mark.parametrize(
    "name", ["quickstart", "fig03", "fig04", "fig05", "fig10a", "fig10b", "fig14", "fig15", "fig17"]
)
def test_example_studies_are_valid(name):
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "examples" / f"{name}.toml"
    s = Study.from_toml(path)
    assert s.n_points > 0 and all(p.n_chunks >= 1 for p in plan(s))
