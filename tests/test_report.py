"""Report of small hand-made result files that follow the schema of study/netcdf.py."""

from __future__ import annotations

import json

import numpy as np
import pytest
import xarray as xr
from matplotlib.image import imread

from analysis import report
from analysis.report import write_report
from tasks import regimes
from tasks.result import FIELDS

C, S, N = regimes.CONTINUOUS, regimes.STICK_SLIP, regimes.NO_MOTION
NC, UB, NA = regimes.NOT_CONVERGED, regimes.UNBOUNDED, regimes.NOT_COMPUTED
INF = np.inf
STUDY_TEXT = '[study]\nname = "handmade"\nfidelity = "fast"\n'
SETTINGS = {"event_tol": 1e-9, "max_cycles": 150}


# --------------------------------------------------------------------------- builders
def _global_attrs() -> dict[str, str]:
    return {
        "title": "Motion regimes of chains with one Coulomb contact: study handmade",
        "Conventions": "CF-1.10",
        "history": "2026-01-01T00:00:00Z: study run handmade.toml",
        "study": STUDY_TEXT,
        "study_name": "handmade",
        "versions": json.dumps({"python": "3.11.9", "numpy": "2.4.6"}),
    }


def _scene_attrs(name: str, gamma: object = 1.0, mode: str = "grid") -> dict[str, object]:
    scene = {"contact": "ground", "dof": 2, "contact_mass": 1, "gamma": gamma, "kappa": 1.0}
    return {
        "scene": json.dumps(scene),
        "scene_name": name,
        "scene_label": f"2DOF ground m1 ({name})",
        "contact": "ground",
        "dof": 2,
        "contact_mass": 1,
        "mode": mode,
        "fidelity": "fast",
        "settings": json.dumps(SETTINGS, sort_keys=True),
    }


def _fields(regime: np.ndarray, dims: tuple[str, ...]) -> dict[str, xr.Variable]:
    """Every per-point field of tasks.result.FIELDS, with plausible values."""
    out = {}
    for name, (dtype, meaning) in FIELDS.items():
        if name == "regime":
            values = regime.astype(dtype)
            attrs = {"long_name": meaning, "units": "1", **regimes.cf_flag_attributes()}
        else:
            values = np.where(regime >= 0, 1, 0).astype(dtype)
            attrs = {"long_name": meaning, "units": "1"}
        out[name] = xr.Variable(dims, values, attrs)
    return out


def _bounds(dims: tuple[str, ...], **values: np.ndarray) -> dict[str, xr.Variable]:
    return {
        k: xr.Variable(dims, np.asarray(v, dtype=float), {"units": "1"}) for k, v in values.items()
    }


def _encoding(ds: xr.Dataset) -> dict[str, dict]:
    enc: dict[str, dict] = {name: {"_FillValue": None} for name in ds.coords}
    for name in ds.data_vars:
        if name == "regime":
            enc[name] = {"_FillValue": regimes.NOT_COMPUTED, "dtype": "int8", "zlib": True}
        elif ds[name].dtype.kind != "f":
            enc[name] = {"_FillValue": None}
    return enc


# gamma sweep: gamma = 0.5, 2; r = 0.5, 1, 1.5; beta = 0, 0.4, 0.8, 1.2.
SWEEP_REGIME = np.array(
    [
        [[C, C, S, N], [C, S, S, N], [C, C, S, S]],
        [[C, C, S, N], [C, NC, S, N], [C, C, NA, N]],
    ]
)
SWEEP_BOUNDS = {
    "beta_continuous_paper": [[0.6, 0.6, 0.6], [0.6, 0.6, 0.6]],
    "beta_motion_paper": [[1.0, 1.0, INF], [1.0, 1.0, 1.0]],
    "beta_continuous_exact": [[0.2, 0.6, 0.6], [0.6, 0.6, 0.6]],
    "beta_motion_exact": [[1.0, 1.0, INF], [1.0, 1.0, 1.0]],
}


def sweep_dataset() -> xr.Dataset:
    dims = ("gamma", "r", "beta")
    return xr.Dataset(
        {**_fields(SWEEP_REGIME, dims), **_bounds(("gamma", "r"), **SWEEP_BOUNDS)},
        coords={"gamma": [0.5, 2.0], "r": [0.5, 1.0, 1.5], "beta": [0.0, 0.4, 0.8, 1.2]},
        attrs={**_global_attrs(), **_scene_attrs("sweep", gamma=[0.5, 2.0])},
    )


def grid_dataset() -> xr.Dataset:
    regime = np.array([[C, N], [C, S]])
    return xr.Dataset(
        {
            **_fields(regime, ("r", "beta")),
            **_bounds(
                ("r",),
                beta_continuous_paper=[0.5, 0.5],
                beta_motion_paper=[1.0, 2.0],
                beta_continuous_exact=[0.5, 0.5],
                beta_motion_exact=[1.0, INF],
            ),
        },
        coords={"r": [1.0, 2.0], "beta": [0.0, 1.0]},
        attrs=_scene_attrs("grid"),
    )


def points_dataset() -> xr.Dataset:
    regime = np.array([C, S, N, C, UB])
    dims = ("point",)
    return xr.Dataset(
        {
            **_fields(regime, dims),
            **_bounds(
                dims,
                beta_continuous_paper=[0.3, 0.3, 0.3, 0.3, 0.3],
                beta_motion_paper=[0.8, 0.8, 0.8, 0.8, 0.8],
                beta_continuous_exact=[0.3, 0.3, 0.3, 0.35, 0.3],
                beta_motion_exact=[0.8, 0.8, 0.8, 0.8, 0.8],
            ),
        },
        coords={
            "point": ("point", np.arange(5)),
            "r": ("point", [0.5, 1.0, 1.5, 2.0, 2.5]),
            "beta": ("point", [0.1, 0.5, 0.9, 0.3, 0.7]),
            "gamma": ("point", [1.0, 1.0, 2.0, 2.0, 2.0]),
        },
        attrs=_scene_attrs("pts"),
    )


def trace_dataset() -> xr.Dataset:
    dims = ("r",)
    return xr.Dataset(
        _bounds(
            dims,
            beta_continuous_numerical=[0.5, 0.8, INF],
            beta_motion_numerical=[1.0, 2.0, 3.0],
            beta_continuous_paper=[0.4, 1.0, 2.0],
            beta_motion_paper=[1.0, INF, 2.0],
            beta_continuous_exact=[0.5, 0.9, 2.0],
            beta_motion_exact=[1.0, INF, 2.5],
        ),
        coords={"r": [0.5, 1.0, 2.0]},
        attrs={**_global_attrs(), **_scene_attrs("traced", mode="trace"), "beta_range": "[0, 4]"},
    )


@pytest.fixture
def sweep_file(tmp_path):
    ds = sweep_dataset()
    path = tmp_path / "sweep.nc"
    ds.to_netcdf(path, engine="netcdf4", format="NETCDF4", encoding=_encoding(ds))
    return path


@pytest.fixture
def tree_file(tmp_path):
    scenes = {"grid": grid_dataset(), "pts": points_dataset()}
    tree = xr.DataTree.from_dict(
        {"/": xr.Dataset(attrs=_global_attrs())} | {f"/{k}": v for k, v in scenes.items()}
    )
    path = tmp_path / "tree.nc"
    tree.to_netcdf(
        path,
        engine="netcdf4",
        format="NETCDF4",
        encoding={f"/{k}": _encoding(v) for k, v in scenes.items()},
    )
    return path


def _assert_png(path):
    assert path.is_file()
    image = imread(path)
    assert image.ndim == 3 and image.shape[0] > 100 and image.shape[1] > 100


# --------------------------------------------------------------------------- tests
def test_sweep_report_numbers(sweep_file, tmp_path):
    out = tmp_path / "out" / "nested"
    path = write_report(sweep_file, out)
    assert path == out / "report.md"
    text = path.read_text()
    # summary: 24 points, 22 determined, 1 not computed, 1 not converged
    assert "| `sweep` | grid | 24 | 22 | 1 | 1 (not_converged (-1): 1) |" in text
    # paper 21/22 (one S at r=1, gamma=0.5 predicted C); exact 20/22 (plus r=0.5, beta=0.4)
    assert "95.45 % (21/22)" in text and "90.91 % (20/22)" in text
    # paper confusion matrix, rows theory (N, S, C), columns simulation (N, S, C)
    assert "| no motion | 5 | 0 | 0 | 5 |" in text
    assert "| stick slip | 0 | 6 | 0 | 6 |" in text
    assert "| continuous | 0 | 1 | 10 | 11 |" in text
    # per-regime accuracy, paper: simulated stick-slip 6 of 7; predicted continuous 10 of 11
    assert "| paper | stick slip | 85.71 % (6/7) | 100.00 % (6/6) |" in text
    assert "| paper | continuous | 100.00 % (10/10) | 90.91 % (10/11) |" in text
    # boundary deviation by hand: continuous |dev| 0 0.4 0 | 0 0.2 0.2 (bc 0.6);
    # motion |dev| 0 0 (open) | 0 0 0.2 (bm 1); in beta steps of 0.4; relative deviations
    # only where the closed form is 10 steps (4.0) clear of zero: nowhere on this grid
    assert "| continuous | paper | 6 / 6 | 5 / 6 | 0.4 | 0.1 | 1 | 0.25 | n/a |" in text
    assert "| motion | paper | 5 / 6 | 6 / 6 | 0.2 | 0 | 0.5 | 0 | n/a |" in text
    # sweep planes
    assert "| 0.5 | 12 | 0 | 0 | 91.67 % (11/12) | 83.33 % (10/12) |" in text
    assert "| 2 | 12 | 1 | 1 | 100.00 % (10/10) | 100.00 % (10/10) |" in text
    # undetermined point listed with its indices and coordinates
    assert "| not_converged (-1) | (1, 1, 1) | 2 | 1 | 0.4 |" in text
    # provenance
    assert STUDY_TEXT.strip() in text and "handmade" in text
    assert '"max_cycles": 150' in text and "| numpy | 2.4.6 |" in text
    assert "study run handmade.toml" in text and "`fast`" in text
    for name in ("sweep_map.png", "sweep_deviation.png"):
        assert f"]({name})" in text
        _assert_png(out / name)
    assert not list(out.glob(".*tmp"))


def test_tree_report_with_point_list(tree_file, tmp_path):
    out = tmp_path / "rep"
    text = write_report(tree_file, out).read_text()
    assert "| `grid` | grid | 4 | 4 | 0 | 0 | 100.00 % (4/4) | 100.00 % (4/4) |" in text
    # points: predicted C S N S(exact: C) S; simulated C S N C UB
    assert "| `pts` | points | 5 | 4 | 0 | 1 (unbounded_growth (-2): 1) |" in text
    assert "75.00 % (3/4) | 100.00 % (4/4) |" in text
    assert "| unbounded_growth (-2) | (4,) | 2.5 | 0.7 | 2 |" in text
    assert "index (point)" in text
    assert "## Scene `grid`" in text and "## Scene `pts`" in text
    assert "study: `handmade`" in text and STUDY_TEXT.strip() in text
    for name in ("grid_map.png", "grid_deviation.png", "pts_map.png"):
        _assert_png(out / name)
    assert not (out / "pts_deviation.png").exists()


def test_trace_report(tmp_path):
    ds = trace_dataset()
    path = tmp_path / "trace.nc"
    ds.to_netcdf(path, engine="netcdf4", encoding=_encoding(ds))
    text = write_report(path, tmp_path / "t").read_text()
    assert "| `traced` | trace | 3 r values |" in text
    # continuous, paper: 0.5 - 0.4, 0.8 - 1.0 (inf not compared)
    assert "| continuous | paper | 2 / 3 | n/a (traced) | 0.2 | 0.15 | 0.25 |" in text
    assert "| motion | exact | 2 / 3 | n/a (traced) | 0.5 | 0.25 | 0.2 |" in text
    _assert_png(tmp_path / "t" / "traced_map.png")


def test_long_undetermined_lists_are_truncated_with_a_count(tmp_path, monkeypatch):
    ds = grid_dataset()
    ds["regime"][:] = NC
    path = tmp_path / "all_nc.nc"
    ds.to_netcdf(path, engine="netcdf4", encoding=_encoding(ds))
    monkeypatch.setattr(report, "MAX_LISTED", 3)
    text = write_report(path, tmp_path / "o").read_text()
    assert "4 point(s): not_converged (-1): 4." in text
    assert "... and 1 more not listed (total 4)." in text
    assert text.count("| not_converged (-1) | (") == 3


def test_failed_report_leaves_no_report(tmp_path):
    ds = grid_dataset()
    ds["regime"][0, 0] = 7  # not a regime code
    path = tmp_path / "bad.nc"
    ds.to_netcdf(path, engine="netcdf4", encoding=_encoding(ds))
    out = tmp_path / "o"
    out.mkdir()
    (out / "report.md").write_text("stale report of an earlier run")
    with pytest.raises(ValueError, match="unknown"):
        write_report(path, out)
    assert not (out / "report.md").exists()
    assert not list(out.glob(".*tmp"))


def test_cli_report(tree_file, tmp_path, run_cli):
    out = tmp_path / "cli_out"
    proc = run_cli("report", tree_file, "-o", out)
    assert proc.returncode == 0, proc.stderr
    assert (out / "report.md").is_file()
    _assert_png(out / "grid_map.png")


def adaptive_dataset() -> xr.Dataset:
    """A 4 x 4 adaptive map: the simulated points agree with the closed forms; two
    inferred points carry a label the closed forms contradict, one of them sampled by
    the verification and found wrong."""
    regime = np.array([[C, C, S, N], [C, S, S, N], [C, C, S, N], [C, C, S, N]])
    simulated = np.array([[1, 0, 1, 1], [1, 0, 1, 1], [1, 0, 1, 1], [1, 1, 1, 1]], dtype=bool)
    regime[0, 1] = N  # inferred, wrong, not sampled
    regime[1, 1] = N  # inferred, wrong, sampled: contradicted
    verification = np.zeros((4, 4), dtype=np.int8)
    verification[1, 1] = 2
    verification[2, 1] = 1  # inferred C, sampled, confirmed
    dims = ("r", "beta")
    bounds = {
        f"beta_{b}_{m}": [v] * 4
        for m in ("paper", "exact")
        for b, v in (("continuous", 0.5), ("motion", 1.0))
    }
    return xr.Dataset(
        {
            **_fields(regime, dims),
            "simulated": xr.Variable(dims, simulated),
            "verification": xr.Variable(dims, verification),
            **_bounds(("r",), **bounds),
        },
        coords={"r": [0.5, 1.0, 1.5, 2.0], "beta": [0.0, 0.4, 0.8, 1.2]},
        attrs={**_global_attrs(), **_scene_attrs("adaptive", mode="adaptive")},
    )


def test_adaptive_report_scores_simulated_points_and_reports_the_verification(tmp_path):
    ds = adaptive_dataset()
    path = tmp_path / "adaptive.nc"
    ds.to_netcdf(path, encoding=_encoding(ds))
    text = write_report(path, tmp_path / "rep").read_text()
    summary = next(line for line in text.splitlines() if line.startswith("| `adaptive`"))
    # 13 simulated points, all agreeing with the closed forms; the 3 inferred ones are
    # not scored as if they had been simulated
    assert "| adaptive | 13 simulated of 16 |" in summary, summary
    assert "100.00 % (13/13)" in summary
    assert "- simulated: 13 of 16 points (81.25 %" in text
    assert "- verification: 2 inferred points simulated, 1 agree (50.00 %" in text
    assert "all points (inferred included): 87.50 % (14/16)" in text
    assert "- layout: `adaptive grid`" in text and "grid" not in summary.split("|")[2]
