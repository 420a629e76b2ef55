"""Studies of a damped structure with several contacts (docs/contacts.md 7) through the CLI.

* ``examples/beam_two_contacts_damped.toml`` runs end to end (``study run``, ``study
  report``); the netCDF holds the damping matrix (``a M + b K`` of the stored matrices),
  ``dissipation_viscous``, and the values ``classify_multi`` gives on the beam built
  directly by :func:`tasks.structures.beam`;
* the TOML ``damping`` key of several contacts round-trips through the provenance;
* bad damping with several contacts stops the run with one line naming the field,
  exit code 2, nothing written.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from study.definition import Study
from tasks.multicontact import classify_multi
from tasks.structures import beam

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "beam_two_contacts_damped.toml"


@pytest.fixture(scope="module")
def example_run(tmp_path_factory):
    """``study run`` and ``study report`` of the example, once."""
    import subprocess
    import sys

    from conftest import docs_env

    where = tmp_path_factory.mktemp("damped_example")
    procs = [
        subprocess.run(
            [sys.executable, "-m", "study", *args],
            cwd=where,
            env=docs_env(),
            capture_output=True,
            text=True,
            timeout=900,
        )
        for args in (
            ["run", str(EXAMPLE), "-o", "damped.nc", "--workers", "2"],
            ["report", "damped.nc", "-o", "rep"],
        )
    ]
    return where, procs


def test_the_damped_example_runs_and_equals_classify(example_run):
    where, procs = example_run
    for proc in procs:
        assert proc.returncode == 0, proc.stderr[-3000:]
    spec = tomllib.loads(EXAMPLE.read_text())["scene"][0]
    a, b = spec["damping"]["rayleigh"]
    with xr.open_dataset(where / "damped.nc") as ds:
        M, K = ds["mass_matrix"].values, ds["stiffness_matrix"].values
        np.testing.assert_allclose(ds["damping_matrix"].values, a * M + b * K, rtol=1e-14)
        assert ds["damping_matrix"].attrs["damping"] == f"rayleigh {a!r} {b!r}"
        assert '"damping": "rayleigh"' in ds.attrs["scene"]
        assert ds["dissipation_viscous"].dims == ("beta", "r")
        ok = ds["regime_combined"].values >= 0
        assert ok.mean() > 0.95
        viscous = ds["dissipation_viscous"].values
        assert np.all(viscous[ok] >= 0.0)
        # a contact moves: the beam moves (held at both contacts the tip load, on a
        # contact DOF, moves nothing: no motion dissipates nothing here)
        assert np.all(viscous[ok & (ds["regime_combined"].values > 0)] > 0.0)
        # a few points against the simulator on the beam built directly
        scene = beam(
            **{k: v for k, v in spec["beam"].items() if k != "supports"},
            supports=spec["beam"]["supports"],
            damping=("rayleigh", a, b),
            beta_ratio=spec["beta_ratio"],
        )
        ib, ir = np.array([1, 4, 6, 9]), np.array([2, 5, 8, 12])
        r, beta = ds["r"].values[ir], ds["beta"].values[ib]
        res = classify_multi(scene, r, beta, spec.get("fidelity", "fast"))
        stored = ds.isel(beta=xr.DataArray(ib, dims="p"), r=xr.DataArray(ir, dims="p"))
        np.testing.assert_array_equal(stored["regime"].transpose("p", "contact").values, res.regime)
        np.testing.assert_allclose(
            stored["dissipation_viscous"].values, res.dissipation_viscous, rtol=1e-12
        )
        np.testing.assert_allclose(
            stored["slip_amplitude"].transpose("p", "contact").values,
            res.slip_amplitude,
            rtol=1e-12,
            atol=1e-15,
        )
    report = (where / "rep" / "report.md").read_text()
    assert "A **damped** structure" in report
    assert "| viscous |" in report


def test_the_damping_key_of_several_contacts_round_trips():
    study = Study.from_toml(EXAMPLE)
    again = Study.from_dict(tomllib.loads(study.to_toml()))
    assert again == study
    assert again.scenes[0].structure == study.scenes[0].structure
    assert again.scenes[0].structure.damped


BAD = {
    "modal": ("damping = {modal = -0.02}", "scene[0].damping.modal"),
    "negative": ("damping = {rayleigh = [-0.1, 0.0]}", "scene[0].damping.rayleigh"),
    "kind": ("damping = {viscous = 0.1}", "scene[0].damping"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_damping_with_several_contacts_exit_2_one_line(tmp_path, run_cli, case):
    line, why = BAD[case]
    text = EXAMPLE.read_text().replace("damping = {rayleigh = [0.02, 0.002]}", line)
    assert line in text
    (tmp_path / "study.toml").write_text(text)
    proc = run_cli("run", "study.toml", "-o", "o.nc", timeout=120)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("study: error: "), proc.stderr
    assert why in lines[0], lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["study.toml"]


def test_adaptive_and_points_modes_of_the_damped_beam(tmp_path, run_cli):
    """The other scene modes with damping and several contacts, through the CLI: an
    adaptive map (its simulated points are the simulator's) and a point list."""
    text = EXAMPLE.read_text()
    spec = tomllib.loads(text)["scene"][0]
    adaptive = text.replace(
        "r = {start = 0.1, stop = 3.0, num = 16}", "r = {start = 0.1, stop = 3.0, num = 17}"
    ).replace(
        "beta = {start = 0.0, stop = 2.6, num = 12}",
        'beta = {start = 0.0, stop = 2.6, num = 9}\nmode = "adaptive"',
    )
    points = text.split("r = {start")[0] + "points = [[0.6, 0.3], [1.1, 0.9], [2.4, 0.2]]\n"
    scene = beam(
        **{k: v for k, v in spec["beam"].items() if k != "supports"},
        supports=spec["beam"]["supports"],
        damping=tuple(["rayleigh", *spec["damping"]["rayleigh"]]),
        beta_ratio=spec["beta_ratio"],
    )
    for name, body in (("adaptive", adaptive), ("points", points)):
        (tmp_path / f"{name}.toml").write_text(body)
        proc = run_cli("run", f"{name}.toml", "-o", f"{name}.nc", "--workers", "1", timeout=600)
        assert proc.returncode == 0, proc.stderr[-3000:]
        with xr.open_dataset(tmp_path / f"{name}.nc") as ds:
            assert "dissipation_viscous" in ds and "damping_matrix" in ds
            if name == "adaptive":
                sim = ds["simulated"].values.astype(bool)
                ib, ir = np.nonzero(sim)
                r, beta = ds["r"].values[ir], ds["beta"].values[ib]
                stored = ds["regime"].values[:, ib, ir].T
                viscous = ds["dissipation_viscous"].values[ib, ir]
            else:
                r, beta = ds["r"].values, ds["beta"].values
                stored = ds["regime"].transpose("point", "contact").values
                viscous = ds["dissipation_viscous"].values
        res = classify_multi(scene, r, beta, spec.get("fidelity", "fast"))
        np.testing.assert_array_equal(stored, res.regime, err_msg=name)
        np.testing.assert_allclose(viscous, res.dissipation_viscous, rtol=1e-12, err_msg=name)
