"""Scenes of matrices and beams through studies (docs/studies.md, docs/structures.md).

Independent truths: a chain written as its matrices (Eq. 68-69) is the chain, so
the same study gives the same regimes for both; the matrices stored in the result
rebuild a scene that classifies identically; the cantilever example agrees with
the damped closed forms (docs/structures.md 3), computed here from the stored
matrices. Every scene kind (grid, points, trace, adaptive) runs through the CLI.
"""

from __future__ import annotations

import json
import os
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from conftest import assert_documented_lines_ran

from analysis import predict
from analysis.design import scene_of, stored_matrices
from study import Study
from study.definition import SceneSpec
from study.errors import StudyError
from study.structures import MAX_NPZ_BYTES
from tasks import Scene, classify
from tasks.structures import beam

ROOT = Path(__file__).resolve().parents[1]

STUDY = """
[study]
name = "structures"
fidelity = "fast"

[[scene]]
name = "chain"
contact = "ground"
dof = 2
contact_mass = 2
kappa = 0.5
r = {start = 0.2, stop = 2.4, num = 12}
beta = {start = 0.0, stop = 1.5, num = 11}

[[scene]]
name = "chain_matrices"
contact = {ground = 1}
r = {start = 0.2, stop = 2.4, num = 12}
beta = {start = 0.0, stop = 1.5, num = 11}
[scene.matrices]
mass = [[1.0, 0.0], [0.0, 1.0]]
stiffness = [[1.5, -0.5], [-0.5, 0.5]]
load = [1.0, 0.0]

[[scene]]
name = "chain_npz"
matrices = "chain.npz"
contact = {ground = 1}
points = [[0.5, 0.2], [1.3, 0.4], [2.0, 0.1]]

[[scene]]
name = "between_damped"
contact = {between = [1, 2]}
damping = {rayleigh = [0.02, 0.0]}
points = [[0.4, 0.1], [0.9, 0.3], [1.6, 0.05]]
[scene.matrices]
mass = [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 1.0]]
stiffness = [[2.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]]
load = [1.0, 0.0, 0.0]

[[scene]]
name = "beam_trace"
beam = {supports = "cantilever", n_elements = 6, contact_node = 5, modes = 2}
damping = {rayleigh = [0.01, 0.001]}
mode = "trace"
r = {start = 0.3, stop = 3.0, num = 4}
beta = {start = 0.0, stop = 2.0, num = 21}

[[scene]]
name = "beam_adaptive"
beam = {supports = "cantilever", n_elements = 6, contact_node = 5, modes = 2}
mode = "adaptive"
coarse_step = 4
r = {start = 0.3, stop = 3.0, num = 17}
beta = {start = 0.0, stop = 2.0, num = 9}
"""


def env() -> dict[str, str]:
    e = dict(os.environ)
    e["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), e.get("PYTHONPATH")) if p)
    e["MPLBACKEND"] = "Agg"
    return e


def study_cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "study", *args],
        cwd=cwd,
        env=env(),
        capture_output=True,
        text=True,
        timeout=900,
    )


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> tuple[Path, xr.DataTree]:
    """Every scene kind of a structure, written by ``study run`` and reported."""
    ws = tmp_path_factory.mktemp("structures")
    np.savez(
        ws / "chain.npz",
        mass=np.eye(2),
        stiffness=np.array([[1.5, -0.5], [-0.5, 0.5]]),
        load=np.array([1.0, 0.0]),
    )
    (ws / "s.toml").write_text(STUDY)
    done = study_cli("run", "s.toml", "-o", "s.nc", "--workers", "2", "--quiet", cwd=ws)
    assert done.returncode == 0, done.stderr[-3000:]
    tree = xr.open_datatree(ws / "s.nc")
    yield ws, tree
    tree.close()


def test_chain_as_matrices_gives_the_chains_regimes(written):
    _, tree = written
    chain = tree["chain"].to_dataset()
    as_matrices = tree["chain_matrices"].to_dataset()
    assert Scene("ground", 2, 2, kappa=0.5).matrices()["stiffness"].tolist() == [
        [1.5, -0.5],
        [-0.5, 0.5],
    ]
    assert set(np.unique(chain.regime.values)) >= {0, 1, 2}  # all three regimes occur
    np.testing.assert_array_equal(as_matrices.regime.values, chain.regime.values)
    np.testing.assert_array_equal(as_matrices.slip_amplitude.values, chain.slip_amplitude.values)
    for name in ("beta_continuous_exact", "beta_motion_exact"):
        np.testing.assert_allclose(as_matrices[name].values, chain[name].values, rtol=1e-12)


def test_npz_scene_equals_the_chain_at_its_points(written):
    _, tree = written
    ds = tree["chain_npz"].to_dataset()
    chain = Scene("ground", 2, 2, kappa=0.5)
    res = classify(chain, ds.r.values, ds.beta.values, fidelity="fast")
    np.testing.assert_array_equal(ds.regime.values, res.regime)


@pytest.mark.parametrize("name", ["chain_matrices", "between_damped", "beam_trace"])
def test_stored_matrices_rebuild_the_scene(written, name):
    """``Scene.from_matrices(**stored)`` is the study's scene and classifies identically."""
    ws, tree = written
    ds = tree[name].to_dataset()
    stored = stored_matrices(ds)
    rebuilt = Scene.from_matrices(**stored)
    spec = next(s for s in Study.from_toml(ws / "s.toml").scenes if s.name == name)
    assert rebuilt == spec.structure
    assert scene_of(ds) == spec.structure
    assert rebuilt.damped == (name != "chain_matrices")
    r, beta = np.array([0.45, 0.95, 1.7]), np.array([0.05, 0.25, 0.6])
    a = classify(rebuilt, r, beta, fidelity="fast")
    b = classify(spec.structure, r, beta, fidelity="fast")
    np.testing.assert_array_equal(a.regime, b.regime)
    np.testing.assert_array_equal(a.slip_amplitude, b.slip_amplitude)
    if "regime" in ds:  # the stored map itself
        if "point" in ds.dims:
            r, beta = ds.r.values, ds.beta.values
        else:
            r, beta = (a.ravel() for a in np.meshgrid(ds.r.values, ds.beta.values))
        res = classify(rebuilt, r, beta, fidelity="fast")
        np.testing.assert_array_equal(ds.regime.values.ravel(), res.regime)


def test_stored_layout_and_old_scenes_untouched(written):
    _, tree = written
    chain = tree["chain"].to_dataset()
    assert not any("dof" in chain[v].dims for v in chain.data_vars)
    assert "description" not in json.loads(chain.attrs["scene"])
    ds = tree["between_damped"].to_dataset()
    assert ds.mass_matrix.dims == ("dof", "dof2") and ds.mass_matrix.shape == (3, 3)
    assert ds.damping_matrix.attrs["damping"] == "rayleigh 0.02 0.0"
    np.testing.assert_array_equal(ds.contact_vector.values, [0.0, -1.0, 1.0])
    assert ds.attrs["contact"] == "matrices" and ds.attrs["dof"] == 3
    trace = tree["beam_trace"].to_dataset()
    assert "cantilever, contact at node 5" in json.loads(trace.attrs["scene"])["description"]
    # the traced boundaries meet the damped closed forms within the bisection tolerance
    step = 0.1
    for b in ("continuous", "motion"):
        gap = np.abs(trace[f"beta_{b}_numerical"] - trace[f"beta_{b}_exact"]).values
        assert np.all(gap <= 0.5 * step + 1e-9), (b, gap)
    adaptive = tree["beam_adaptive"].to_dataset()
    assert adaptive.regime.shape == (9, 17) and int(adaptive.regime.min()) >= 0


def test_report_of_structures(written):
    ws, _ = written
    done = study_cli("report", "s.nc", "-o", "rep", cwd=ws)
    assert done.returncode == 0, done.stderr[-3000:]
    text = (ws / "rep" / "report.md").read_text()
    assert "cantilever, contact at node 5" in text
    assert "3-DOF structure, contact at DOFs 1-2" in text
    assert (ws / "rep" / "beam_trace_map.png").stat().st_size > 10_000


# --------------------------------------------------------------------------- the door
BASE = {"r": [0.5, 1.0], "beta": [0.1]}
M2 = {"mass": [[1.0, 0.0], [0.0, 1.0]], "stiffness": [[2.0, -1.0], [-1.0, 1.0]], "load": [1, 0]}


def refused(scene: dict, tmp_path: Path | None = None) -> str:
    with pytest.raises(StudyError) as info:
        Study.from_dict({"scene": [{"name": "s", **BASE, **scene}]}, directory=tmp_path)
    line = str(info.value)
    assert "\n" not in line
    return line


def test_door_names_the_field(tmp_path):
    bad_mass = {**M2, "mass": [[1.0, 0.5], [0.0, 1.0]]}
    assert "scene[0].matrices.mass: must be symmetric" in refused(
        {"matrices": bad_mass, "contact": {"ground": 0}}
    )
    assert "scene[0].contact: DOF index 5 is outside" in refused(
        {"matrices": M2, "contact": {"ground": 5}}
    )
    assert "scene[0].contact: must be {ground = j}" in refused(
        {"matrices": M2, "contact": "ground"}
    )
    assert "scene[0].dof:" in refused({"matrices": M2, "contact": {"ground": 0}, "dof": 2})
    assert "scene[0].beam.bogus: unknown key" in refused({"beam": {"bogus": 1}})
    assert "scene[0].beam.contact_node" in refused({"beam": {"n_elements": 4, "contact_node": 9}})
    assert "scene[0].beam: give either" in refused(
        {"beam": {}, "matrices": M2, "contact": {"ground": 0}}
    )
    assert "scene[0].damping.rayleigh" in refused({"beam": {}, "damping": {"rayleigh": [-1, 0]}})
    assert "scene[0].damping: applies to scenes of matrices" in refused(
        {"contact": "ground", "dof": 1, "damping": {"modal": 0.1}}
    )
    assert "scene[0].gamma: a structure has no chain ratios" in refused({"beam": {}, "gamma": 2.0})
    # modal damping ratios are not proportional in the held system: the simulator takes
    # them through real pairs of damped eigenvalues (docs/structures.md 4.5), so the door does
    modal = {"beam": {"n_elements": 6, "modes": 2}, "damping": {"modal": 0.01}}
    assert Study.from_dict({"scene": [{"name": "s", **BASE, **modal}]}).scenes[0].damping
    assert "no such file" in refused({"matrices": "none.npz", "contact": {"ground": 0}}, tmp_path)


def test_npz_is_read_only_as_a_bounded_regular_file(tmp_path):
    os.mkfifo(tmp_path / "fifo.npz")
    line = refused({"matrices": "fifo.npz", "contact": {"ground": 0}}, tmp_path)
    assert "scene[0].matrices:" in line and "FIFO" in line
    (tmp_path / "big.npz").write_bytes(b"\0" * (MAX_NPZ_BYTES + 1))
    assert "at most" in refused({"matrices": "big.npz", "contact": {"ground": 0}}, tmp_path)
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    assert "not a readable .npz" in refused(
        {"matrices": "junk.npz", "contact": {"ground": 0}}, tmp_path
    )
    np.savez(tmp_path / "extra.npz", mass=np.eye(2), stiffness=np.eye(2), load=[1, 0], x=[1])
    assert "scene[0].matrices.x: unknown array" in refused(
        {"matrices": "extra.npz", "contact": {"ground": 0}}, tmp_path
    )
    np.savez(tmp_path / "ok.npz", **{k: np.asarray(v, dtype=float) for k, v in M2.items()})
    study = Study.from_dict(
        {"scene": [{"name": "s", **BASE, "matrices": "ok.npz", "contact": {"ground": 0}}]},
        directory=tmp_path,
    )
    inline = Study.from_dict(
        {"scene": [{"name": "s", **BASE, "matrices": M2, "contact": {"ground": 0}}]}
    )
    assert study.scenes[0].structure == inline.scenes[0].structure
    spec = SceneSpec("s", matrices=M2, contact=("ground", 0), r=BASE["r"], beta=BASE["beta"])
    assert spec == inline.scenes[0]
    # the Python classes take the same, and the provenance text rebuilds the study
    assert Study.from_dict(__import__("tomllib").loads(study.to_toml())) == study


def test_bad_structure_exits_2_with_one_line(tmp_path):
    (tmp_path / "bad.toml").write_text(
        '[[scene]]\nname = "b"\nbeam = {n_elements = 4, supports = "hinged"}\n'
        "r = [1.0]\nbeta = [0.1]\n"
    )
    done = study_cli("run", "bad.toml", "-o", "bad.nc", cwd=tmp_path)
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        "study: error: bad.toml: scene[0].beam.supports: must be one of "
        "('cantilever', 'pinned', 'free'), got 'hinged'"
    ]
    assert not (tmp_path / "bad.nc").exists()


# --------------------------------------------------------------------------- the example
def test_cantilever_example_agrees_with_the_damped_closed_forms(documented_runs):
    """The example map (docs/structures.md) against analysis.closed_form's damped
    boundaries, rebuilt from the stored matrices.

    The closed forms are exact for the motion bound and for the continuous /
    stick-slip bound (docs/structures.md 3.1-3.2), so the only misses are points
    within a grid step of a boundary that the simulation reaches asymptotically
    (flagged ``asymptotic``); the report prints 99.96 % (5098/5100). The floor
    99.5 % leaves room for a few such points and still fails if one boundary
    were off by one grid step along a tenth of its length (about 1 %).

    The map and its report are those of the documented commands (docs/studies.md:
    ``study run examples/cantilever.toml ...`` then ``study report``), run once per
    session and also checked by tests/test_docs.py."""
    from test_docs import BASH, study_lines

    texts = [t for _, t in BASH if "study run examples/cantilever.toml" in t]
    assert texts, "no documented block runs examples/cantilever.toml"
    lines = study_lines(texts[0])
    ws, procs = documented_runs(lines)
    assert_documented_lines_ran(lines, procs, "cantilever")
    args = {line.split()[1]: shlex.split(line, comments=True) for line in lines}
    result = args["run"][args["run"].index("-o") + 1]
    assert args["report"][2] == result, lines  # the report of that map
    report = ws / args["report"][args["report"].index("-o") + 1] / "report.md"
    with xr.open_dataset(ws / result) as ds:
        scene = scene_of(ds)
        assert scene == beam(
            n_elements=20, contact_node=18, modes=4, damping=("rayleigh", 0.0172, 0.00275)
        )
        r, beta = np.meshgrid(ds.r.values, ds.beta.values)
        theory = predict(scene, r.ravel(), beta.ravel(), method="exact").reshape(r.shape)
        agree = float(np.mean(ds.regime.values == theory))
        assert set(np.unique(ds.regime.values)) == {0, 1, 2}
        assert ds.regime.size == 5100  # the whole example map
        r_values = ds.r.values
    assert agree >= 0.995, agree
    assert r_values.min() < 1.0 and r_values.max() > 6.27  # the first two modes
    assert "cantilever, contact at node 18" in report.read_text()
