"""The result layout on the paper's example studies (reduced resolution), read with plain xarray.

One LocalCluster (2 processes, 127.0.0.1) for the module; each study is run
through ``study.run_study``, in memory and to a file.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import matplotlib
import numpy as np
import pytest
import xarray as xr

from study import Study, run_study
from tasks import Scene, classify
from tasks.result import DESIGN_FIELDS, FIELDS, FLAGS, MASS_FIELDS

matplotlib.use("Agg")

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
CODED = ("regime", "initial_condition", "period", "converged")


def reduced(name: str, n_r: int = 14, n_beta: int = 9, design: bool = False) -> Study:
    """An example study with coarser r and beta axes (same ranges); ``design``: with
    ``[settings] design = true`` added (the paper's examples are labels only)."""
    data = tomllib.loads((EXAMPLES / f"{name}.toml").read_text())
    if design:
        data.setdefault("settings", {})["design"] = True
    for scene in data["scene"]:
        scene["r"] = {**scene["r"], "num": n_r}
        scene["beta"] = {**scene["beta"], "num": n_beta}
    return Study.from_dict(data, source=f"{name}.toml", default_name=name)


@pytest.fixture(scope="module")
def client(cluster_client):
    """The session's LocalCluster (2 worker processes)."""
    return cluster_client


def assert_codes(ds: xr.Dataset) -> None:
    """Coded variables open as integer codes with CF flags, never as floats with NaN."""
    for name in CODED:
        var = ds[name]
        assert var.dtype.kind in "ib", (name, var.dtype)
        values = set(np.unique(var.values.astype(int)).tolist())
        assert values <= set(var.attrs["flag_values"].astype(int).tolist()), name
        assert len(var.attrs["flag_meanings"].split()) == len(var.attrs["flag_values"]), name
    assert ds["regime"].dtype == np.int8
    assert "_FillValue" not in ds["regime"].encoding
    assert (ds["regime"] >= 0).all()  # these maps are fully determined
    for name in FLAGS:
        np.testing.assert_array_equal(ds[name].attrs["flag_values"], FLAGS[name]["flag_values"])


def test_fig04_panels_combine_into_one_labelled_array(client):
    tree = run_study(reduced("fig04"), client=client, progress=False)  # nothing written
    assert isinstance(tree, xr.DataTree)
    panels = [tree[name].to_dataset() for name in tree.children]
    assert len(panels) == 4
    for ds in panels:
        assert_codes(ds)
        assert ds["regime"].dims == ("beta", "r")
        assert ds.attrs["design_quantities"] == "off"  # labels only, as the example asks
        assert not set(DESIGN_FIELDS) & set(ds.data_vars) and "mass" not in ds.dims
        assert ds["gamma"].dims == () and ds["kappa"].dims == ()
        assert (ds.attrs["contact"], ds.attrs["dof"], ds.attrs["contact_mass"]) == ("ground", 2, 1)
    # the four panels as one array, indexed by (gamma, kappa)
    both = xr.concat(panels, dim="panel").set_index(panel=["gamma", "kappa"])
    assert both["regime"].dims == ("panel", "beta", "r")
    np.testing.assert_array_equal(
        both["regime"].sel(gamma=2.0, kappa=2.0).values, tree["gamma2_kappa2"]["regime"].values
    )
    # panels differing in one ratio combine by coordinates along it
    gamma1 = [p.expand_dims(("gamma", "kappa")) for p in panels if float(p["gamma"]) == 1.0]
    sweep = xr.combine_by_coords(gamma1, combine_attrs="drop_conflicts")
    assert sweep["regime"].dims == ("gamma", "kappa", "beta", "r")
    assert sweep["kappa"].values.tolist() == [0.5, 1.0]
    assert sweep["regime"].dtype == np.int8


def test_fig03_file_opens_as_the_in_memory_result(client, tmp_path):
    study = reduced("fig03")
    memory = run_study(study, client=client, progress=False).to_dataset()
    run_study(study, tmp_path / "fig03.nc", client=client, progress=False)
    ds = xr.open_dataset(tmp_path / "fig03.nc")
    assert_codes(ds)
    assert "gamma" not in ds.coords  # SDOF: no ratios
    assert "regime_rest" not in ds  # rest is no start of fig03: nothing but -127 to write
    assert ds.attrs["design_quantities"] == memory.attrs["design_quantities"] == "off"
    assert not set(DESIGN_FIELDS) & set(ds.data_vars)  # absent, not NaN-filled
    for name in (n for n in FIELDS if n not in ("regime_rest", *DESIGN_FIELDS)):
        assert ds[name].dims == memory[name].dims
        np.testing.assert_array_equal(ds[name].values, memory[name].values, err_msg=name)
    artist = ds["regime"].plot()  # r along x
    assert artist.axes.get_xlabel().startswith("frequency ratio r_1")
    assert artist.axes.get_ylabel().startswith("friction ratio beta")


def test_fig17_multi_scene_root_says_what_it_holds(client, tmp_path):
    path = tmp_path / "fig17.nc"
    run_study(reduced("fig17", 8, 5, design=True), path, client=client, progress=False)
    root = xr.open_dataset(path)
    assert not root.data_vars
    names = root.attrs["groups"].split()
    assert names == ["gamma1_kappa1", "gamma0.5_kappa1", "gamma1_kappa0.5", "gamma2_kappa2"]
    assert "open_datatree" in root.attrs["how_to_open"]
    ds = xr.open_dataset(path, group=names[1])
    assert_codes(ds)
    assert float(ds["gamma"]) == 0.5 and ds.attrs["contact"] == "mass"
    for name in MASS_FIELDS:
        assert ds[name].dims == ("mass", "beta", "r")


def test_classify_result_to_dataset():
    scene = Scene("base", 2, 2, gamma=0.5, kappa=2.0)
    r, beta = np.linspace(0.2, 2.0, 5), np.linspace(0.0, 1.0, 3)
    res = classify(scene, *np.meshgrid(r, beta, indexing="ij"), design=True)
    ds = res.to_dataset(r, beta, scene)
    assert ds["regime"].dims == ("beta", "r") and ds["amplitude"].dims == ("mass", "beta", "r")
    assert float(ds["gamma"]) == 0.5 and float(ds["kappa"]) == 2.0
    assert_codes(ds)
    point = ds.sel(r=r[3], beta=beta[1])
    single = classify(scene, r[3], beta[1], design=True)
    assert int(point["regime"]) == int(single.regime)
    np.testing.assert_array_equal(point["amplitude"].values, single.amplitude)
    with pytest.raises(ValueError, match="r, beta"):
        res.to_dataset(beta, r)


@pytest.mark.parametrize("example", ["fig03", "fig17"])
def test_cf_compliance(client, tmp_path, example, capsys):
    """compliance-checker --test=cf:1.10 passes on single (fig03) and multi-scene (fig17) files."""
    pytest.importorskip("compliance_checker")
    from compliance_checker.runner import CheckSuite, ComplianceChecker

    path = tmp_path / f"{example}.nc"
    run_study(reduced(example, 6, 4), path, client=client, progress=False)
    CheckSuite.load_all_available_checkers()
    capsys.readouterr()
    ok, errors = ComplianceChecker.run_checker(str(path), ["cf:1.10"], 0, "normal", "-", "text")
    report = capsys.readouterr().out
    assert ok and not errors, report
    assert "All tests passed!" in report, report
