"""The ``design`` setting of a study: off by default (no ``design`` key, or
``design = false``) the design quantities are not computed, and absent from the
work folder and the result (docs/results.md); ``design = true`` gives them at every
determined point; in every scene kind, through the CLI (in this process: small
studies use threads)."""

from __future__ import annotations

import io
import os
import re
import tomllib
from contextlib import contextmanager, redirect_stderr
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from study.chunks import plan
from study.cli import main
from study.compute import compute_chunk
from study.definition import Study
from study.errors import StudyError
from study.store import WorkDir
from tasks.result import DESIGN_FIELDS

SCENES = """
[[scene]]
name = "grid"
contact = "ground"
dof = 2
contact_mass = 1
gamma = {values = [0.5, 2.0]}
kappa = 1.0
r = {start = 0.2, stop = 2.0, num = 7}
beta = {start = 0.0, stop = 1.2, num = 6}

[[scene]]
name = "pts"
contact = "base"
dof = 2
contact_mass = 2
points = {r = [0.4, 0.9, 1.3], beta = [0.1, 0.05, 0.5], gamma = [1.0, 2.0, 2.0]}

[[scene]]
name = "adaptive"
contact = "ground"
dof = 2
mode = "adaptive"
coarse_step = 4
verify_fraction = 0.1
r = {start = 0.1, stop = 2.5, num = 33}
beta = {start = 0.0, stop = 1.5, num = 17}

[[scene]]
name = "traced"
contact = "ground"
dof = 2
mode = "trace"
r = {start = 0.3, stop = 2.0, num = 4}
beta = {start = 0.0, stop = 1.5, num = 61}
"""
#: The study asking for the design quantities, and the same study with the default
#: (no ``design`` key: off).
ON = '[study]\nname = "on"\nfidelity = "fast"\n\n[settings]\ndesign = true\n' + SCENES
OFF = '[study]\nname = "off"\nfidelity = "fast"\n' + SCENES
#: Scenes whose results hold design quantities when they are on.
WITH_DESIGN = ("grid", "pts", "adaptive")
LABELS = ("regime", "stops_per_cycle", "cycles")


@contextmanager
def inside(path: Path):
    old = Path.cwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(old)


def study(where: Path, *args: str) -> tuple[int, str]:
    """``study ARGS`` in this process, in ``where``: exit code and stderr."""
    err = io.StringIO()
    with inside(where), redirect_stderr(err):
        code = main(list(args))
    return code, err.getvalue()


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> Path:
    where = tmp_path_factory.mktemp("design")
    for name, text in (("on", ON), ("off", OFF)):
        (where / f"{name}.toml").write_text(text, encoding="utf-8")
        code, err = study(where, "run", f"{name}.toml", "-o", f"{name}.nc", "--quiet")
        assert code == 0, err
    return where


def assert_same_run(name: str, var: str, a: np.ndarray, b: np.ndarray) -> None:
    """``var`` of scene ``name`` equal in two runs of one study. In an adaptive map
    the orbits that seed a point list depend on the order in which lists arrive
    (docs/adaptive.md, warm starts): labels and counts are equal, the polished fields
    agree to about 1e-9, and ``cycles`` (the periods the seeds cost) may differ."""
    if name != "adaptive" or a.dtype.kind in "biu" and var != "cycles":
        np.testing.assert_array_equal(a, b, err_msg=f"{name} {var}")
    elif var != "cycles":
        np.testing.assert_allclose(a, b, rtol=1e-7, atol=1e-9, err_msg=f"{name} {var}")


def scenes(path: Path) -> dict[str, xr.Dataset]:
    with xr.open_datatree(path) as tree:
        return {str(k): v.to_dataset().load() for k, v in tree.children.items()}


def test_design_off_leaves_design_variables_out_and_labels_equal(runs):
    on, off = scenes(runs / "on.nc"), scenes(runs / "off.nc")
    assert set(on) == set(off) == {*WITH_DESIGN, "traced"}
    for name in WITH_DESIGN:
        a, b = on[name], off[name]
        assert a.attrs["design_quantities"] == "on", name  # asked for
        assert b.attrs["design_quantities"] == "off", name  # the default
        assert set(DESIGN_FIELDS) <= set(a.data_vars), name
        assert not set(DESIGN_FIELDS) & set(b.data_vars), name
        assert "mass" in a.coords and "mass" not in b.coords, name
        assert set(a.data_vars) - set(b.data_vars) == set(DESIGN_FIELDS), name
        for label in LABELS:
            assert b[label].dims == a[label].dims, (name, label)
        for var in b.data_vars:  # every variable (floats: NaN where none)
            assert_same_run(name, var, b[var].values, a[var].values)
    assert off["grid"]["regime"].dims == ("gamma", "beta", "r")
    assert off["pts"]["regime"].dims == ("point",)
    assert bool(off["adaptive"]["simulated"].any())
    # a traced scene never holds design quantities: the same either way, no attribute
    assert "design_quantities" not in off["traced"].attrs
    for var in on["traced"].data_vars:
        np.testing.assert_array_equal(off["traced"][var].values, on["traced"][var].values)


def test_design_true_gives_them_at_every_determined_point(runs):
    """A result that promised the design quantities holds them: finite wherever a
    point was simulated to a steady state, NaN only where it has none."""
    on = scenes(runs / "on.nc")
    for name in WITH_DESIGN:
        ds = on[name]
        done = ds["regime"] >= 0
        if "simulated" in ds:  # an adaptive map: the simulated points
            done = done & ds["simulated"]
        assert int(done.sum()) >= 3, name
        for var in DESIGN_FIELDS:
            values = ds[var].where(done)
            assert bool(np.isfinite(values).sum() == done.sum() * ds[var].sizes.get("mass", 1)), (
                name,
                var,
            )
        moving = done & (ds["regime"] > 0) & (ds["beta"] > 0)
        assert float(ds["dissipation"].where(moving).min()) > 0, name  # friction that slides
        assert float(ds["amplitude"].where(done).max()) > 0, name


def test_adaptive_map_in_python_holds_the_design_quantities_only_when_asked():
    """analysis.adaptive.adaptive_map (this process): absent by default, never NaN-filled;
    with design=True finite at every simulated determined point."""
    from analysis.adaptive import adaptive_map
    from tasks import Scene

    scene, r, beta = Scene("ground", 2), np.linspace(0.2, 2.4, 33), np.linspace(0.0, 1.5, 17)
    bare = adaptive_map(scene, r, beta, coarse_step=8, fidelity="fast")
    full = adaptive_map(scene, r, beta, coarse_step=8, fidelity="fast", design=True)
    assert not set(DESIGN_FIELDS) & set(bare.fields) and set(DESIGN_FIELDS) <= set(full.fields)
    for name, values in bare.fields.items():
        np.testing.assert_array_equal(values, full.fields[name], err_msg=name)
    done = full.fields["simulated"] & (full.fields["regime"] >= 0)
    assert done.sum() > 20
    for name in DESIGN_FIELDS:
        assert np.isfinite(full.fields[name][done]).all(), name


def test_design_default_and_false_are_the_same_settings():
    default = Study.from_dict(tomllib.loads(OFF)).settings
    explicit = Study.from_dict(
        tomllib.loads(OFF.replace("[[scene]]", "[settings]\ndesign = false\n\n[[scene]]", 1))
    ).settings
    asked = Study.from_dict(tomllib.loads(ON)).settings
    assert default.design is False and explicit == default
    assert asked.design is True


def test_report_on_a_result_without_design_quantities(runs):
    out = runs / "report_off"
    code, err = study(runs, "report", "off.nc", "-o", str(out))
    assert code == 0, err
    text = (out / "report.md").read_text(encoding="utf-8")
    assert not list(out.glob("*_response.png"))  # needs the amplitudes
    assert list(out.glob("grid_map.png")) and list(out.glob("adaptive_map.png"))
    reason = "No response figure: the design quantities (amplitudes, contact force,"
    assert text.count(reason) == 2  # the grid and the adaptive map
    assert text.count("add `design = true` to the study's `[settings]`") == 2
    assert not re.search(r"\bnan\b", text, re.I)  # nothing printed as if it were data


def test_report_on_a_result_with_design_quantities(runs):
    out = runs / "report_on"
    code, err = study(runs, "report", "on.nc", "-o", str(out))
    assert code == 0, err
    assert list(out.glob("grid_*response.png")), sorted(p.name for p in out.iterdir())
    assert "No response figure" not in (out / "report.md").read_text(encoding="utf-8")


def test_resume_of_a_run_with_design_off(runs, tmp_path):
    """A unit saved by an earlier run (the worker's own arrays, without design
    fields) is verified against the layout and reused, not discarded."""
    (tmp_path / "off.toml").write_text(OFF, encoding="utf-8")
    grid = next(p for p in plan(Study.from_toml(tmp_path / "off.toml")) if p.spec.name == "grid")
    first = next(grid.chunks())
    arrays = compute_chunk(grid.task(first))
    assert not set(DESIGN_FIELDS) & set(arrays)
    WorkDir(tmp_path / "off.nc").save("grid", first.key, arrays)
    code, err = study(tmp_path, "run", "off.toml", "-o", "off.nc", "--quiet")
    assert code == 0, err
    assert "reusing 1 chunks" in err, err
    assert "discarded" not in err, err
    resumed, whole = scenes(tmp_path / "off.nc"), scenes(runs / "off.nc")
    for name in WITH_DESIGN:
        assert set(resumed[name].data_vars) == set(whole[name].data_vars), name
        for label in LABELS:
            assert_same_run(name, label, resumed[name][label].values, whole[name][label].values)


def test_design_must_be_a_bool():
    bad = ON.replace("design = true", 'design = "no"')
    with pytest.raises(StudyError, match=r"settings\.design.*true or false"):
        Study.from_dict(tomllib.loads(bad)).settings  # noqa: B018
