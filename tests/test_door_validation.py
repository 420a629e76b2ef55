"""One validation for every door, bounded doors, a CLI that says what it did (issues 22, 18).

* the Python door: ``Study``, ``SceneSpec``, ``Axis``, ``Points`` built directly
  refuse what a study file refuses, with a one-line ``StudyError`` naming the
  field; numpy scalars are accepted wherever Python numbers are, bools never;
  ``run_study`` and ``analysis.boundaries`` refuse a wrong type in one line;
* bounded doors: a FIFO, a device, a directory, an oversized file as the study
  file; sweeps of 10^8 values and ``num = 2**63 - 1``: refused in well under a
  second without allocating (the CLI: exit 2, one line, nothing written);
* the CLI: ``study report`` prints what it wrote, refuses a study file as input
  and a file at ``-o`` in one line (exit 2) without creating anything; the help
  has no RST markup, describes every argument, and the synopsis lists every option.

The seeded fuzz of the Python API is in ``test_reliability_validation.py``, beside
the fuzz of study files.
"""

from __future__ import annotations

import argparse
import os
import re
import time
import tracemalloc

import numpy as np
import pytest
from test_report import _encoding, grid_dataset

from analysis import boundaries, predict
from study import Axis, Points, SceneSpec, Study, StudyError
from study.cli import SYNOPSIS, build_parser
from study.limits import MAX_AXIS, MAX_STUDY_BYTES
from study.run import run_study

GOOD = """
[study]
name = "t"
fidelity = "fast"

[[scene]]
contact = "ground"
dof = 2
r = {start = 0.5, stop = 1.5, num = 4}
beta = {start = 0.0, stop = 1.0, num = 3}
"""
R = Axis(start=0.5, stop=1.5, num=4)
BETA = Axis(start=0.0, stop=1.0, num=3)


def spec(**kw) -> SceneSpec:
    return SceneSpec(**{"name": "s", "contact": "ground", "dof": 2, "r": R, "beta": BETA, **kw})


def _one_line(exc: BaseException) -> str:
    text = str(exc)
    assert text and "\n" not in text, repr(text)
    return text


# --------------------------------------------------------------------------- the Python door
@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda: spec(dof=0), "dof"),
        (lambda: spec(dof=True), "dof"),
        (lambda: spec(dof=2.0), "dof"),
        (lambda: spec(contact="wall"), "contact"),
        (lambda: spec(name="a/b"), "name"),
        (lambda: spec(name="n" * 101), "name"),
        (lambda: spec(mode="bogus"), "mode"),
        (lambda: spec(mode="adaptive", coarse_step=0), "coarse_step"),
        (lambda: spec(mode="adaptive", verify_fraction=5), "verify_fraction"),
        (lambda: spec(hint="closest"), "hint"),
        (lambda: spec(gamma=-1.0), "gamma"),
        (lambda: spec(gamma=True), "gamma"),
        (lambda: spec(kappa=1e300), "kappa"),
        (lambda: spec(gamma=[1.0, 2.0]), "gamma"),
        (lambda: spec(dof=1, kappa=Axis(values=[1.0, 2.0])), "kappa"),
        (lambda: spec(r=None), "r"),
        (lambda: spec(r=Axis(values=[-1.0, 2.0])), "r.values[0]"),
        (lambda: spec(beta=[0.5, 0.1]), "beta.values"),
        (lambda: spec(r=Axis(start=1e-300, stop=1.0, num=3)), "r"),
        (lambda: spec(mode="trace", beta=[0.3]), "beta"),
        (lambda: spec(r=None, beta=None, points=[[1.0, 0.1]], mode="trace"), "points"),
        (lambda: spec(points=[[1.0, 0.1]]), "points"),
        (lambda: spec(r=None, beta=None, points=[[1.0]]), "points[0]"),
        (lambda: spec(r=None, beta=None, points={"r": [1.0, 2.0], "beta": [0.1]}), "points.beta"),
        (lambda: Axis(start=0.0, stop=1.0, num=0), "num"),
        (lambda: Axis(start=0.0, stop=1.0, num=np.float64(3)), "num"),
        (lambda: Axis(start=1.0, stop=0.5, num=3), "stop"),
        (lambda: Axis(start=0.0, stop=1.0, num=3, spacing="log"), "start"),
        (lambda: Axis(values=[0.1, float("nan")]), "values[1]"),
        (lambda: Axis(values=[0.1], start=0.0), ""),
        (lambda: Points(r=[1.0], beta=[True]), "beta[0]"),
        (lambda: Study("t", [spec()], fidelity="ultra"), "study.fidelity"),
        (lambda: Study("t", [spec()], max_points=0), "study.max_points"),
        (lambda: Study("t", [spec()], max_points=2**64), "study.max_points"),
        (lambda: Study("t", [spec()], task_seconds=1e9), "study.task_seconds"),
        (lambda: Study("t", [spec()], chunk_points=True), "study.chunk_points"),
        (lambda: Study("t", [spec(), spec()]), "scene[1].name"),
        (lambda: Study("t", ["not a scene"]), "scene[0]"),
        (lambda: Study("t", []), "scene"),
        (lambda: Study("t/x", [spec()]), "study.name"),
        (lambda: Study("t", [spec()], overrides={"max_cycles": "5"}), "settings.max_cycles"),
        (lambda: Study("t", [spec()], overrides={"bogus": 1}), "settings"),
        (lambda: Study("t", [spec()], max_points=11), "study.max_points"),
    ],
)
def test_classes_validate_on_construction(call, field):
    t0 = time.perf_counter()
    with pytest.raises(StudyError) as info:
        call()
    assert info.value.field == field or info.value.field.startswith(field + "."), str(info.value)
    _one_line(info.value)
    assert time.perf_counter() - t0 < 1.0


def test_study_file_and_python_doors_give_the_same_error(study_file):
    text = GOOD.replace("dof = 2", 'dof = 2\nmode = "bogus"')
    with pytest.raises(StudyError) as from_file:
        Study.from_toml(study_file(text))
    with pytest.raises(StudyError) as from_python:
        spec(mode="bogus")
    assert from_file.value.field == "scene[0]." + from_python.value.field
    assert from_file.value.message == from_python.value.message


def test_numpy_scalars_are_numbers_bools_are_not(study_file):
    data = {
        "study": {"name": "t", "fidelity": "fast", "max_points": np.int64(100)},
        "settings": {"max_cycles": np.int32(100)},
        "scene": [
            {
                "contact": "ground",
                "dof": np.int64(3),
                "contact_mass": np.int8(2),
                "gamma": np.float32(2.0),
                "kappa": {"values": [np.float64(0.5), np.float64(2.0)]},
                "r": {"start": np.float64(0.5), "stop": 1.5, "num": np.int64(4)},
                "beta": [np.float16(0.25)],
            }
        ],
    }
    study = Study.from_dict(data)
    scene = study.scenes[0]
    assert (scene.dof, scene.contact_mass, scene.gamma) == (3, 2, 2.0)
    assert type(scene.dof) is int and type(scene.r.num) is int and type(scene.gamma) is float
    assert study.settings.max_cycles == 100 and study.max_points == 100
    assert study.n_points == 2 * 4 * 1
    plain = Study.from_toml(study_file(GOOD))
    again = Study(plain.name, plain.scenes, fidelity="fast", max_points=np.int64(10**6))
    assert again == plain.__class__(plain.name, plain.scenes, fidelity="fast", max_points=10**6)
    for bad in ({"dof": True}, {"gamma": np.bool_(True)}, {"contact_mass": False}):
        broken = {**data, "scene": [{**data["scene"][0], **bad}]}
        with pytest.raises(StudyError, match=rf"^scene\[0\]\.{next(iter(bad))}: "):
            Study.from_dict(broken)


def test_run_study_and_boundaries_refuse_a_wrong_type_in_one_line(tmp_path):
    with pytest.raises(TypeError, match=r"^study: must be a Study") as info:
        run_study("not a study", tmp_path / "o.nc")
    _one_line(info.value)
    assert not list(tmp_path.iterdir())
    for call in (lambda: boundaries("ground", 1.0), lambda: predict("ground", 1.0, 0.3)):
        with pytest.raises(TypeError, match=r"^scene: must be a tasks\.Scene") as info:
            call()
        _one_line(info.value)


# --------------------------------------------------------------------------- bounded doors
BIG = 2**63 - 1
HUGE = [
    ("gamma-1e8", "gamma = {start = 1.0, stop = 2.0, num = 100000000}", "scene[0].gamma.num"),
    ("kappa-1e8", "kappa = {start = 1.0, stop = 2.0, num = 100000000}", "scene[0].kappa.num"),
    ("kappa-2^63-1", f"kappa = {{start = 1.0, stop = 2.0, num = {BIG}}}", "scene[0].kappa.num"),
    (
        "gamma-2^63-1-log",
        f'gamma = {{start = 1.0, stop = 2.0, num = {BIG}, spacing = "log"}}',
        "scene[0].gamma.num",
    ),
    ("r-2^63-1", f"r = {{start = 0.5, stop = 1.5, num = {BIG}}}", "scene[0].r.num"),
    ("beta-1e8", "beta = {start = 0.0, stop = 1.0, num = 100000000}", "scene[0].beta.num"),
]


def _huge(line: str) -> str:
    """GOOD with ``line`` replacing its own key (r, beta) or added (gamma, kappa)."""
    key = line.split(" ")[0]
    kept = [ln for ln in GOOD.splitlines() if not ln.startswith(f"{key} =")]
    return "\n".join(kept) + f"\n{line}\n"


@pytest.mark.parametrize(("line", "field"), [c[1:] for c in HUGE], ids=[c[0] for c in HUGE])
def test_huge_axes_and_sweeps_refused_before_allocation(study_file, line, field):
    path = study_file(_huge(line))
    tracemalloc.start()
    t0 = time.perf_counter()
    try:
        with pytest.raises(StudyError) as info:
            Study.from_toml(path)
        took = time.perf_counter() - t0
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert info.value.field == field, str(info.value)
    assert f"at most {MAX_AXIS:,} values" in _one_line(info.value)
    assert took < 1.0 and peak < 20e6, (took, peak)


def test_huge_sweeps_refused_from_python():
    for call in (
        lambda: Axis(start=1.0, stop=2.0, num=10**8),
        lambda: spec(kappa={"start": 1.0, "stop": 2.0, "num": 2**63 - 1}),
        lambda: spec(gamma={"values": np.geomspace(1.0, 2.0, MAX_AXIS + 1)}),
    ):
        with pytest.raises(StudyError, match="at most 1,000,000 values"):
            call()
    with pytest.raises(StudyError, match=r"^values: holds at most 1,000,000 values"):
        Axis(values=np.arange(1, MAX_AXIS + 2, dtype=float))


def _unreadable_studies(tmp_path):
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    big = tmp_path / "big.toml"
    with open(big, "wb") as f:
        f.truncate(MAX_STUDY_BYTES + 1)  # sparse: costs no disk
    return [
        (fifo, "a FIFO"),
        ("/dev/zero", "a character device"),
        (tmp_path, "a directory"),
        (big, f"at most {MAX_STUDY_BYTES:,} bytes"),
    ]


def test_study_file_must_be_a_bounded_regular_file(tmp_path):
    for path, why in _unreadable_studies(tmp_path):
        t0 = time.perf_counter()
        with pytest.raises(StudyError) as info:
            Study.from_toml(path)
        assert why in _one_line(info.value), str(info.value)
        assert time.perf_counter() - t0 < 1.0


@pytest.mark.parametrize("command", ["run", "plan"])
def test_cli_unreadable_study_exit_2_one_line(tmp_path, run_cli, command):
    for path, why in _unreadable_studies(tmp_path):
        before = sorted(os.listdir(tmp_path))
        t0 = time.monotonic()
        proc = run_cli(command, path, timeout=60)
        assert proc.returncode == 2, proc.stderr
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("study: error: ") and why in lines[0]
        assert time.monotonic() - t0 < 30
        assert sorted(os.listdir(tmp_path)) == before  # nothing written


@pytest.mark.parametrize("case", ["kappa-1e8", "r-2^63-1"])
def test_cli_huge_sweep_exit_2_one_line(study_file, run_cli, tmp_path, case):
    study_file(_huge(dict((c[0], c[1]) for c in HUGE)[case]))
    proc = run_cli("run", "study.toml", "-o", "o.nc", timeout=60)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "at most 1,000,000 values" in lines[0], proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["study.toml"]


# --------------------------------------------------------------------------- the CLI
@pytest.fixture
def result_file(tmp_path):
    ds = grid_dataset()
    path = tmp_path / "grid.nc"
    ds.to_netcdf(path, engine="netcdf4", format="NETCDF4", encoding=_encoding(ds))
    return path


def test_cli_report_says_what_it_wrote(result_file, tmp_path, run_cli):
    proc = run_cli("report", result_file, "-o", "rep")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "rep" / "report.md").is_file()
    n_png = len(list((tmp_path / "rep").glob("*.png")))
    assert proc.stderr.strip() == f"study: wrote rep/report.md and {n_png} figures in rep"


def test_cli_report_refuses_a_file_at_o_unless_overwrite(result_file, tmp_path, run_cli):
    (tmp_path / "rep").write_text("precious")
    proc = run_cli("report", result_file, "-o", "rep")
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("study: error: -o: rep exists"), proc.stderr
    assert (tmp_path / "rep").read_text() == "precious"
    proc = run_cli("report", result_file, "-o", "rep", "--overwrite")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "rep" / "report.md").is_file()


@pytest.mark.parametrize("what", ["study", "garbage", "directory"])
def test_cli_report_refuses_what_is_not_a_result(study_file, tmp_path, run_cli, what):
    given = {
        "study": lambda: study_file(GOOD),
        "garbage": lambda: study_file("CDF not really", name="fake.nc"),
        "directory": lambda: tmp_path,
    }[what]()
    before = sorted(os.listdir(tmp_path))
    proc = run_cli("report", given, "-o", "rep")
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("study: error: result: "), proc.stderr
    if what == "study":
        assert "study run" in lines[0]
    assert sorted(os.listdir(tmp_path)) == before  # no output folder created


def test_cli_report_on_a_netcdf_that_is_no_result_creates_nothing(tmp_path, run_cli):
    import xarray as xr

    xr.Dataset({"x": ("n", np.arange(3.0))}).to_netcdf(tmp_path / "other.nc", engine="netcdf4")
    proc = run_cli("report", "other.nc", "-o", "rep")
    assert proc.returncode == 2, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert not (tmp_path / "rep").exists()


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def test_cli_help_describes_every_argument_and_the_synopsis_lists_every_option():
    parser = build_parser()
    top = parser.format_help()
    assert "``" not in top and ":mod:" not in top
    for name, sub in _subparsers(parser).items():
        lines = [ln for ln in SYNOPSIS.splitlines()]
        start = next(i for i, ln in enumerate(lines) if ln.startswith(f"study {name}"))
        block = lines[start]
        for ln in lines[start + 1 :]:
            if not ln.startswith(" "):
                break
            block += ln
        for action in sub._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            assert action.help, f"study {name} {action.dest}: no help"
            flags = action.option_strings
            if flags and "--version" not in flags:
                assert any(re.search(rf"{o}\b", block) for o in flags), f"{name} lacks {flags}"
    assert "--fidelity" in SYNOPSIS.splitlines()[3] and "--worker-timeout" in SYNOPSIS
