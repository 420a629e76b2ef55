"""Several contacts through studies (docs/contacts.md, docs/results.md).

Independent truths: the written file equals :func:`tasks.classify` on the same
points and scene (built here from the TOML values, not from the file);
``regime_combined`` is recomputed from the per-contact regimes by its stated
rule; the stored arrays rebuild the scene; a one-contact scene in the same
study keeps its layout (no ``contact`` dim, the one-contact field set).

Beyond one fixed plane: sweeps of gamma and kappa on chains equal classify at
every ratio, a beam with two contact points, an adaptive map refined on the
combined label against the dense grid. The closed forms of one contact with the
others held (analysis.contact_bounds): the held structure is checked against the
chain held by hand (a wall: row and column removed; a contact between masses:
the pair merged); where every other contact is stuck the simulated regime is the
held structure's, which its closed forms predict; every contact is stuck exactly
above the largest held motion bound. One ``study run`` and one ``study report``
through the CLI on a local cluster for the whole module.
"""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from analysis import boundaries, contact_bounds
from analysis.contacts import planes
from study import Study
from study.errors import StudyError
from tasks import Scene, classify
from tasks.multicontact import MultiScene
from tasks.result import DESIGN_FIELDS, FIELDS
from tasks.scene import stuck_basis
from tasks.structures import beam

ROOT = Path(__file__).resolve().parents[1]

M3 = {
    "mass": [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 1.0]],
    "stiffness": [[2.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]],
    "load": [1.0, 0.0, 0.0],
}
POINTS = [[0.4, 0.1], [0.9, 0.3], [1.3, 0.05], [1.8, 0.6], [0.6, 1.5]]

#: The plane of the dense grid and of the adaptive map (41 x 21 points).
TWO_WALLS = """contact = "ground"
dof = 2
contact_mass = [1, 2]
beta_ratio = [1.0, 0.5]
kappa = 0.5
r = {start = 0.2, stop = 2.4, num = 41}
beta = {start = 0.0, stop = 1.6, num = 21}
"""
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
STUDY += """
[[scene]]
name = "swept"
contact = ["ground", "mass"]
dof = 3
contact_mass = [1, 2]
beta_ratio = [1.0, 0.5]
gamma = {values = [0.5, 2.0]}
kappa = {values = [0.7, 1.4, 3.0]}
r = {start = 0.3, stop = 2.2, num = 5}
beta = {start = 0.05, stop = 1.0, num = 3}

[[scene]]
name = "dense"
{TWO_WALLS}
[[scene]]
name = "adaptive"
mode = "adaptive"
coarse_step = 4
verify_fraction = 0.2
{TWO_WALLS}
[[scene]]
name = "beam"
beam = {n_elements = 10, contact_node = [5, 10], modes = 3}
beta_ratio = [1.0, 0.5]
r = {start = 0.3, stop = 2.8, num = 6}
beta = {start = 0.0, stop = 2.5, num = 4}
""".replace("{TWO_WALLS}", TWO_WALLS)


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
    # the design quantities off (the default): absent, and said so; several contacts
    # always hold their force and dissipation
    fields = set(FIELDS) - {"regime_rest", *DESIGN_FIELDS}
    assert {v for v in ds.data_vars if not v.startswith("beta_")} == fields
    assert ds.attrs["design_quantities"] == "off" and "mass" not in ds.dims
    assert tree["two_walls"].attrs["design_quantities"] == "on"
    assert ds.regime.dims == ("beta", "r")
    assert ds.attrs["contact_mass"] == 1 and "n_contacts" not in ds.attrs


def test_report_has_a_section_per_contact(written):
    ws, _ = written
    done = study_cli("report", "s.nc", "-o", "rep", cwd=ws)
    assert done.returncode == 0, done.stderr[-3000:]
    text = (ws / "rep" / "report.md").read_text()
    assert "### Contact 0: ground 0 (beta_ratio 1)" in text
    assert "### Contact 1: between 1 2 (beta_ratio 2)" in text
    assert "with the **other contacts held** (frictionless ones free) are drawn" in text
    assert (ws / "rep" / "two_walls_contacts.png").stat().st_size > 10_000
    # the held closed forms, a figure per plane of a sweep (the first 4), adaptive maps
    assert "### Closed forms with the other contacts held" in text
    assert "| 0: ground 0 (beta_ratio 1) | 38 | 38 | 100.0 % |" in text
    assert "Figures of the first 4 of 6 planes." in text
    for k in range(4):
        assert (ws / "rep" / f"swept_contacts_{k}.png").stat().st_size > 10_000
    for name in ("beam", "adaptive"):
        assert (ws / "rep" / f"{name}_contacts.png").stat().st_size > 10_000
    assert "refined on `regime_combined`; verification:" in text


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
    # random starts: taken as the simulator takes them (docs/contacts.md 4)
    both = Study.from_dict({"settings": {"n_random": 2}, "scene": [{"name": "s", **BASE, **chain}]})
    assert both.settings.n_random == 2
    m2 = {"mass": [[1.0, 0.0], [0.0, 1.0]], "stiffness": [[2.0, -1.0], [-1.0, 1.0]]}
    m2["load"] = [1.0, 0.0]
    two = [{"ground": 0}, {"ground": 1}]
    assert "scene[0].damping: must be positive semidefinite" in refused(
        {"matrices": m2, "contact": two, "damping": {"matrix": [[0.1, 0.5], [0.5, 0.01]]}}
    )
    assert "scene[0].contact[1].ground" in refused(
        {"matrices": m2, "contact": [{"ground": 0}, {"ground": -1}]}
    )
    assert "scene[0].beta_ratio: applies to scenes with several contacts" in refused(
        {"matrices": m2, "contact": {"ground": 0}, "beta_ratio": [1.0]}
    )


def test_adaptive_map_of_two_contacts_resumes_after_interruption(written, tmp_path, monkeypatch):
    """Interrupted after two point lists, then run again: the saved lists answer the
    refinement and the map is the uninterrupted one's (the module's CLI run)."""
    from study import StudyInterrupted, run_study
    from study.adaptive import AdaptivePlan

    _, tree = written
    text = '[study]\nname = "resume"\nfidelity = "fast"\n\n'
    text += STUDY[
        STUDY.index('[[scene]]\nname = "adaptive"') : STUDY.index('[[scene]]\nname = "beam"')
    ]
    study = Study.from_dict(tomllib.loads(text))
    out = tmp_path / "resume.nc"
    real_accept, kept = AdaptivePlan.accept, []

    def interrupted_accept(self, unit, *args, **kwargs):
        real_accept(self, unit, *args, **kwargs)
        kept.append(unit.idx.size)
        if len(kept) == 2:
            raise KeyboardInterrupt

    monkeypatch.setattr(AdaptivePlan, "accept", interrupted_accept)
    with pytest.raises(StudyInterrupted):
        run_study(study, out, progress=False, stream=io.StringIO())
    monkeypatch.setattr(AdaptivePlan, "accept", real_accept)
    log = io.StringIO()
    run_study(study, out, progress=False, stream=log)
    line = next(x for x in log.getvalue().splitlines() if "saved points reused" in x)
    assert int(line.split(" saved points reused")[0].split()[-1].replace(",", "")) == sum(kept)
    with xr.open_dataset(out) as again:
        whole = tree["adaptive"].to_dataset()
        for name in ("regime", "regime_combined", "simulated", "verification", "dissipation"):
            np.testing.assert_array_equal(again[name].values, whole[name].values, err_msg=name)


def test_provenance_rebuilds_the_study():

    study = Study.from_dict(tomllib.loads(STUDY))
    again = Study.from_dict(tomllib.loads(study.to_toml()))
    assert again == study
    multi = [s.structure for s in study.scenes if s.name != "one"]
    assert [s.structure for s in again.scenes if s.name != "one"] == multi
    assert again.scenes[3].name == "swept" and again.scenes[3].n_points == 2 * 3 * 5 * 3


def combined(regime: xr.DataArray) -> np.ndarray:
    """``sum_c regime_c 3^c``, the most severe negative code where one is undetermined."""
    reg = regime.transpose("contact", ...).values.astype(int)
    code = sum(reg[c] * 3**c for c in range(reg.shape[0]))
    return np.where(reg.min(axis=0) < 0, reg.min(axis=0), code)


def test_a_sweep_of_gamma_and_kappa_equals_classify_at_every_ratio(written):
    _, tree = written
    ds = tree["swept"].to_dataset()
    assert ds.regime.dims == ("gamma", "kappa", "contact", "beta", "r")
    assert ds.regime_combined.dims == ("gamma", "kappa", "beta", "r")
    assert ds.dissipation.dims == ("gamma", "kappa", "contact", "beta", "r")
    np.testing.assert_array_equal(ds.gamma.values, [0.5, 2.0])
    np.testing.assert_array_equal(ds.kappa.values, [0.7, 1.4, 3.0])
    assert list(ds.contact_where.values) == ["ground 0", "between 1 2"]
    assert "mass_matrix" not in ds  # a swept chain is rebuilt from its scene attribute
    chain = json.loads(ds.attrs["scene"])["chain"]
    assert chain == {
        "contact": ["ground", "mass"],
        "contact_mass": [1, 2],
        "gamma": [0.5, 2.0],
        "kappa": [0.7, 1.4, 3.0],
    }
    r, beta = np.meshgrid(ds.r.values, ds.beta.values)  # (beta, r)
    for i, g in enumerate(ds.gamma.values):
        for j, k in enumerate(ds.kappa.values):
            scene = MultiScene.chain(
                ["ground", "mass"], 3, [1, 2], gamma=g, kappa=k, beta_ratio=[1.0, 0.5]
            )
            res = classify(scene, r, beta, fidelity="fast")
            at = ds.isel(gamma=i, kappa=j)
            np.testing.assert_array_equal(at.regime.values, np.moveaxis(res.regime, -1, 0))
            np.testing.assert_allclose(
                at.slip_amplitude.values,
                np.moveaxis(res.slip_amplitude, -1, 0),
                rtol=1e-12,
                equal_nan=True,
            )
    np.testing.assert_array_equal(ds.regime_combined.values, combined(ds.regime))
    # the ratios move the map: not every (gamma, kappa) plane is the same
    planes = ds.regime_combined.values.reshape(6, -1)
    assert len({p.tobytes() for p in planes}) >= 3


def test_the_beam_with_two_contacts_equals_classify(written):
    _, tree = written
    ds = tree["beam"].to_dataset()
    assert ds.regime.dims == ("contact", "beta", "r")
    assert list(ds.contact_where.values) == ["ground 0", "ground 1"]
    attr = json.loads(ds.attrs["scene"])
    assert attr["beam"]["contact_node"] == [5, 10]
    assert attr["description"] == "cantilever beam, contacts at nodes 5, 10"
    scene = beam(10, contact_node=[5, 10], modes=3, beta_ratio=[1.0, 0.5])
    np.testing.assert_allclose(ds.mass_matrix.values, scene.mass_matrix(), rtol=1e-15)
    r, beta = np.meshgrid(ds.r.values, ds.beta.values)
    res = classify(scene, r, beta, fidelity="fast")
    np.testing.assert_array_equal(ds.regime.values, np.moveaxis(res.regime, -1, 0))
    np.testing.assert_array_equal(ds.regime_combined.values, combined(ds.regime))
    assert len(np.unique(ds.regime_combined.values)) >= 3


def test_adaptive_map_of_two_contacts_equals_the_dense_grid(written):
    _, tree = written
    dense, ada = tree["dense"].to_dataset(), tree["adaptive"].to_dataset()
    assert ada.regime.dims == ("contact", "beta", "r")
    assert ada.regime_combined.dims == ada.simulated.dims == ("beta", "r")
    sim = ada.simulated.values
    assert 0 < sim.sum() < sim.size  # some points inferred
    for name in ("regime", "dissipation"):  # simulated points: the dense grid's values
        np.testing.assert_array_equal(ada[name].values[:, sim], dense[name].values[:, sim])
    np.testing.assert_array_equal(ada.regime_combined.values, combined(ada.regime))
    assert len(np.unique(dense.regime_combined.values)) >= 4
    agree = ada.regime_combined.values == dense.regime_combined.values
    assert agree.mean() >= 0.99
    # the verification sample: its flags count what the attributes say
    flags = ada.verification.values
    assert ada.attrs["verification_sampled"] == int((flags > 0).sum()) > 0
    assert ada.attrs["verification_agree"] == int((flags == 1).sum())


def test_door_of_swept_and_beam_scenes():
    chain = {"contact": "ground", "dof": 2, "contact_mass": [1, 2]}
    assert "scene[0].gamma: every gamma must be in [1e-06, 1e+06], got 1e+07" in refused(
        {**chain, "gamma": {"values": [0.5, 1e7]}}
    )
    assert "scene[0].mode: 'trace' is not available for several contacts" in refused(
        {**chain, "mode": "trace", "beta": [0.1, 0.2]}
    )
    two = {"n_elements": 6, "contact_node": [3, 6]}
    assert "scene[0].beam.contact_node: a node is listed twice" in refused(
        {"beam": {**two, "contact_node": [3, 3]}}
    )
    assert "scene[0].beam.contact_node[1]: " in refused({"beam": {**two, "contact_node": [3, "x"]}})
    assert "scene[0].beta_ratio: expected one number per contact (2), got 3" in refused(
        {"beam": two, "beta_ratio": [1.0, 0.5, 0.2]}
    )
    assert "scene[0].beta_ratio: applies to scenes with several contacts" in refused(
        {"beam": {"n_elements": 6, "contact_node": 3}, "beta_ratio": [1.0]}
    )
    assert "scene[0].damping.modal" in refused({"beam": two, "damping": {"modal": -0.02}})


def test_held_structure_is_the_chain_held_by_hand():
    two = MultiScene.chain("ground", 2, [1, 2], kappa=0.5)
    held = contact_bounds.held_scene(two, 0)  # mass 2 held: mass 1 on k1 + k2
    np.testing.assert_allclose(held.structure.mass, [[1.0]], rtol=1e-14)
    np.testing.assert_allclose(held.structure.stiffness, [[1.5]], rtol=1e-14)
    assert contact_bounds.held_scene(two, 1) is None  # mass 1 held: the wall takes the load
    mixed = MultiScene.chain(["ground", "mass"], 3, [1, 2], gamma=0.5, kappa=1.4)
    M, K = mixed.mass_matrix(), mixed.stiffness_matrix()
    T, _ = stuck_basis(3, (1, 2))  # masses 2 and 3 merged
    merged = Scene.from_matrices(T.T @ M @ T, T.T @ K @ T, T.T @ mixed.load_vector(), ("ground", 0))
    r = np.linspace(0.3, 2.5, 23)
    for truth, ours in zip(
        boundaries(merged, r, method="exact"),
        boundaries(contact_bounds.held_scene(mixed, 0), r, method="exact"),
        strict=True,
    ):
        np.testing.assert_allclose(ours, truth, rtol=1e-9)


def test_a_frictionless_partner_stays_free():
    """beta_ratio 0: the held structure of the other contact is the scene without it,
    whose closed forms predict that contact's regime at every point (2DOF chain)."""
    scene = MultiScene.chain("ground", 2, [1, 2], kappa=0.5, beta_ratio=[1.0, 0.0])
    r, beta = np.linspace(0.3, 2.4, 15), np.linspace(0.05, 1.3, 8)
    for truth, ours in zip(
        boundaries(scene.single(0), r, method="exact"),
        boundaries(contact_bounds.held_scene(scene, 0), r, method="exact"),
        strict=True,
    ):
        np.testing.assert_allclose(ours, truth, rtol=1e-12)
    res = classify(scene, *np.meshgrid(r, beta), fidelity="fast")  # (beta, r, contact)
    regime = xr.DataArray(np.moveaxis(res.regime, -1, 0), dims=("contact", "beta", "r"))
    ds = xr.Dataset({"regime": regime}, {"r": r, "beta": beta, "beta_ratio": ("contact", [1, 0])})
    (n0, agree0), (n1, _) = contact_bounds.held_agreement(ds, scene)
    assert n0 == r.size * beta.size and agree0 >= 0.99 * n0 and n1 == 0
    assert len(np.unique(res.regime[..., 0])) == 3  # the three regimes are predicted


def test_held_closed_forms_predict_where_the_others_are_stuck(written):
    _, tree = written
    applied = 0
    for name in ("swept", "beam", "dense"):
        for label, plane in planes(tree[name].to_dataset()):
            scene = contact_bounds.scene_of(plane)
            for n, agree in contact_bounds.held_agreement(plane, scene):
                assert agree == n, (name, label)
                applied += n
            # every contact stuck exactly above the largest held motion bound
            _, motion = contact_bounds.held_bounds(scene, plane.r.values)
            above = plane.beta.values[:, None] >= contact_bounds.all_stuck_bound(motion) * (
                1 - contact_bounds.EDGE_RTOL
            )
            np.testing.assert_array_equal(plane.regime_combined.values == 0, above)
    assert applied >= 50
