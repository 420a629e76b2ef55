"""Several contacts through studies (docs/contacts.md, docs/results.md).

Independent truths: the written file equals :func:`tasks.classify` on the same
points and scene (built here from the TOML values, not from the file);
``regime_combined`` is recomputed from the per-contact regimes by its stated
rule; the stored arrays rebuild the scene; a one-contact scene in the same
study keeps its layout (no ``contact`` dim, the one-contact field set).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from study import Study
from study.errors import StudyError
from tasks import classify
from tasks.multicontact import MultiScene
from tasks.result import FIELDS

ROOT = Path(__file__).resolve().parents[1]

M3 = {
    "mass": [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 1.0]],
    "stiffness": [[2.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]],
    "load": [1.0, 0.0, 0.0],
}
POINTS = [[0.4, 0.1], [0.9, 0.3], [1.3, 0.05], [1.8, 0.6], [0.6, 1.5]]

STUDY = f"""
[study]
name = "contacts"
fidelity = "fast"

[[scene]]
name = "two_walls"
contact = "ground"
dof = 2
contact_mass = [1, 2]
beta_ratio = [1.0, 0.5]
kappa = 0.5
r = {{start = 0.2, stop = 2.4, num = 9}}
beta = {{start = 0.0, stop = 1.2, num = 7}}

[[scene]]
name = "mixed"
contact = [{{ground = 0}}, {{between = [1, 2]}}]
beta_ratio = [1.0, 2.0]
points = {json.dumps(POINTS)}
[scene.matrices]
mass = {json.dumps(M3["mass"])}
stiffness = {json.dumps(M3["stiffness"])}
load = {json.dumps(M3["load"])}

[[scene]]
name = "one"
contact = "ground"
dof = 2
contact_mass = 1
r = {{start = 0.2, stop = 2.4, num = 5}}
beta = {{start = 0.0, stop = 1.2, num = 4}}
"""


def study_cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)
    env["MPLBACKEND"] = "Agg"
    return subprocess.run(
        [sys.executable, "-m", "study", *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )


def run_study_file(ws: Path, text: str) -> xr.DataTree:
    """``study run`` of the study ``text`` in ``ws`` (a local cluster of 2 workers): the
    written ``s.nc``, opened."""
    (ws / "s.toml").write_text(text)
    done = study_cli("run", "s.toml", "-o", "s.nc", "--workers", "2", "--quiet", cwd=ws)
    assert done.returncode == 0, done.stderr[-3000:]
    return xr.open_datatree(ws / "s.nc")


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    ws = tmp_path_factory.mktemp("contacts")
    tree = run_study_file(ws, STUDY)
    yield ws, tree
    tree.close()


def test_grid_of_two_contacts_equals_classify(written):
    _, tree = written
    ds = tree["two_walls"].to_dataset()
    assert ds.regime.dims == ("contact", "beta", "r")
    assert ds.regime_combined.dims == ("beta", "r")
    assert list(ds.contact_where.values) == ["ground 0", "ground 1"]
    np.testing.assert_array_equal(ds.beta_ratio.values, [1.0, 0.5])
    scene = MultiScene.chain("ground", 2, [1, 2], kappa=0.5, beta_ratio=[1.0, 0.5])
    r, beta = np.meshgrid(ds.r.values, ds.beta.values)  # (beta, r)
    res = classify(scene, r, beta, fidelity="fast")
    np.testing.assert_array_equal(ds.regime.values, np.moveaxis(res.regime, -1, 0))
    np.testing.assert_array_equal(ds.converged.values, res.converged)
    np.testing.assert_allclose(
        ds.dissipation.values, np.moveaxis(res.dissipation, -1, 0), rtol=1e-12, equal_nan=True
    )
    # the combined label by its stated rule, from the stored per-contact regimes
    reg = ds.regime.values.astype(int)
    expect = np.where(reg.min(axis=0) < 0, reg.min(axis=0), reg[0] + 3 * reg[1])
    np.testing.assert_array_equal(ds.regime_combined.values, expect)
    assert len(np.unique(expect)) >= 3  # the map is not trivial: several combinations
    meanings = ds.regime_combined.attrs["flag_meanings"].split()
    values = list(ds.regime_combined.attrs["flag_values"])
    assert meanings[values.index(5)] == "c0_continuous_c1_stick_slip"


def test_points_of_matrices_with_mixed_contacts_equal_classify(written):
    _, tree = written
    ds = tree["mixed"].to_dataset()
    assert ds.regime.dims == ("contact", "point")
    assert list(ds.contact_where.values) == ["ground 0", "between 1 2"]
    # the stored arrays rebuild the scene (not read from the study file)
    np.testing.assert_array_equal(ds.contact_vector.values, [[1, 0, 0], [0, -1, 1]])
    scene = MultiScene.from_matrices(
        ds.mass_matrix.values,
        ds.stiffness_matrix.values,
        ds.load_vector.values,
        [("ground", 0), ("between", 1, 2)],
        beta_ratio=list(ds.beta_ratio.values),
    )
    pts = np.array(POINTS)
    res = classify(scene, pts[:, 0], pts[:, 1], fidelity="fast")
    np.testing.assert_array_equal(ds.regime.values, res.regime.T)
    np.testing.assert_array_equal(ds.regime_combined.values, res.combined)
    assert json.loads(ds.attrs["scene"])["beta_ratio"] == [1.0, 2.0]
    assert ds.attrs["n_contacts"] == 2 and "contact_mass" not in ds.attrs


def test_one_contact_scene_keeps_its_layout(written):
    _, tree = written
    ds = tree["one"].to_dataset()
    assert "contact" not in ds.dims and "regime_combined" not in ds
    fields = set(FIELDS) - {"regime_rest"}
    assert fields <= set(ds.data_vars)
    assert {v for v in ds.data_vars if not v.startswith("beta_")} == fields
    assert ds.regime.dims == ("beta", "r") and ds.amplitude.dims == ("mass", "beta", "r")
    assert ds.attrs["contact_mass"] == 1 and "n_contacts" not in ds.attrs


def test_report_has_a_section_per_contact(written):
    ws, _ = written
    done = study_cli("report", "s.nc", "-o", "rep", cwd=ws)
    assert done.returncode == 0, done.stderr[-3000:]
    text = (ws / "rep" / "report.md").read_text()
    assert "### Contact 0: ground 0 (beta_ratio 1)" in text
    assert "### Contact 1: between 1 2 (beta_ratio 2)" in text
    assert "with the **other contacts held** are drawn on each contact's map" in text
    assert (ws / "rep" / "two_walls_contacts.png").stat().st_size > 10_000


# --------------------------------------------------------------------------- the door
BASE = {"r": [0.5, 1.0], "beta": [0.1]}


def refused(scene: dict) -> str:
    with pytest.raises(StudyError) as info:
        Study.from_dict({"scene": [{"name": "s", **BASE, **scene}]})
    line = str(info.value)
    assert "\n" not in line
    return line


def test_door_names_the_field():
    chain = {"contact": "ground", "dof": 2, "contact_mass": [1, 2]}
    assert "scene[0].beta_ratio: expected one number per contact (2), got 3" in refused(
        {**chain, "beta_ratio": [1.0, 0.5, 0.2]}
    )
    assert "scene[0].contact_mass: at most 4 contacts, got 5" in refused(
        {"contact": "ground", "dof": 5, "contact_mass": [1, 2, 3, 4, 5]}
    )
    assert "scene[0].contact: one kind per contact_mass (2), got 3" in refused(
        {**chain, "contact": ["ground", "ground", "mass"]}
    )
    assert "scene[0].mode: 'trace' is not available for several contacts" in refused(
        {**chain, "mode": "trace", "beta": [0.1, 0.2]}
    )
    assert "scene[0].beta_ratio: applies to scenes with several contacts" in refused(
        {"contact": "ground", "dof": 2, "contact_mass": 1, "beta_ratio": [1.0]}
    )
    with pytest.raises(StudyError, match=r"^settings.n_random: random starts are not available"):
        Study.from_dict({"settings": {"n_random": 2}, "scene": [{"name": "s", **BASE, **chain}]})
    m2 = {"mass": [[1.0, 0.0], [0.0, 1.0]], "stiffness": [[2.0, -1.0], [-1.0, 1.0]]}
    m2["load"] = [1.0, 0.0]
    two = [{"ground": 0}, {"ground": 1}]
    assert "scene[0].damping: scenes with several contacts are undamped" in refused(
        {"matrices": m2, "contact": two, "damping": {"rayleigh": [0.01, 0.0]}}
    )
    assert "scene[0].contact[1].ground" in refused(
        {"matrices": m2, "contact": [{"ground": 0}, {"ground": -1}]}
    )
    assert "scene[0].beta_ratio: applies to scenes with several contacts" in refused(
        {"matrices": m2, "contact": {"ground": 0}, "beta_ratio": [1.0]}
    )


def test_provenance_rebuilds_the_study():
    import tomllib

    study = Study.from_dict(tomllib.loads(STUDY))
    again = Study.from_dict(tomllib.loads(study.to_toml()))
    assert again == study
    assert [s.structure for s in again.scenes[:2]] == [s.structure for s in study.scenes[:2]]
