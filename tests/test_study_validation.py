"""Malformed studies: one clear line naming the field, exit code 2, nothing written."""

from __future__ import annotations

import pytest

from study import Study, StudyError

GOOD = """
[study]
name = "t"

[[scene]]
contact = "ground"
dof = 2
r = {start = 0.1, stop = 2.0, num = 5}
beta = {start = 0.0, stop = 1.0, num = 4}
"""

SCENE_HEAD = '[study]\nname = "t"\n\n[[scene]]\n'
GRID = "r = {start = 0.1, stop = 2.0, num = 5}\nbeta = {start = 0.0, stop = 1.0, num = 4}\n"


def scene(body: str, grid: bool = True) -> str:
    return SCENE_HEAD + body + ("\n" + GRID if grid else "\n")


# (id, study text, field the message must name)
CASES = [
    ("unknown-top-key", "foo = 1\n" + GOOD, "foo"),
    ("unknown-study-key", GOOD.replace('name = "t"', 'name = "t"\nnme = "x"'), "study.nme"),
    ("unknown-scene-key", scene('contact = "ground"\ndof = 2\ncontcat = 1'), "scene[0].contcat"),
    (
        "unknown-axis-key",
        scene(
            'contact = "ground"\ndof = 2\nr = {start = 0.1, stop = 2, num = 5, step = 0.1}\n'
            "beta = [0.1]",
            grid=False,
        ),
        "scene[0].r.step",
    ),
    (
        "negative-num",
        GOOD.replace(
            "r = {start = 0.1, stop = 2.0, num = 5}", "r = {start = 0.1, stop = 2.0, num = -3}"
        ),
        "scene[0].r.num",
    ),
    ("float-num", GOOD.replace("num = 4", "num = 2.5"), "scene[0].beta.num"),
    ("r-start-zero", GOOD.replace("start = 0.1", "start = 0.0"), "scene[0].r.start"),
    (
        "r-negative-value",
        scene('contact = "ground"\ndof = 2\nr = [-1.0, 2.0]\nbeta = [0.1]', grid=False),
        "scene[0].r.values[0]",
    ),
    ("beta-negative", GOOD.replace("start = 0.0", "start = -0.1"), "scene[0].beta.start"),
    (
        "beta-nan",
        scene('contact = "ground"\ndof = 2\nr = [1.0]\nbeta = {values = [0.1, nan]}', grid=False),
        "scene[0].beta.values[1]",
    ),
    ("gamma-negative", scene('contact = "ground"\ndof = 2\ngamma = -1'), "scene[0].gamma"),
    ("kappa-infinite", scene('contact = "ground"\ndof = 2\nkappa = inf'), "scene[0].kappa"),
    (
        "gamma-sweep-negative",
        scene('contact = "ground"\ndof = 2\ngamma = {values = [1.0, -2.0]}'),
        "scene[0].gamma.values[1]",
    ),
    (
        "contact-mass-range",
        scene('contact = "ground"\ndof = 2\ncontact_mass = 3'),
        "scene[0].contact_mass",
    ),
    ("mass-with-dof-1", scene('contact = "mass"\ndof = 1'), "scene[0].dof"),
    ("unknown-contact", scene('contact = "wall"\ndof = 2'), "scene[0].contact"),
    ("dof-string", scene('contact = "ground"\ndof = "2"'), "scene[0].dof"),
    (
        "empty-grid",
        scene('contact = "ground"\ndof = 2\nr = {values = []}\nbeta = [0.1]', grid=False),
        "scene[0].r.values",
    ),
    (
        "huge-grid",
        scene(
            'contact = "ground"\ndof = 2\nr = {start = 0.1, stop = 2, num = 100000}\n'
            "beta = {start = 0.0, stop = 1.0, num = 1000}",
            grid=False,
        ),
        "study.max_points",
    ),
    (
        "max-points-override",
        GOOD.replace('name = "t"', 'name = "t"\nmax_points = 10'),
        "study.max_points",
    ),
    (
        "duplicate-names",
        GOOD + '\n[[scene]]\ncontact = "ground"\ndof = 2\n' + GRID,
        "scene[1].name",
    ),
    (
        "grid-and-points",
        scene('contact = "ground"\ndof = 2\npoints = [[1.0, 0.2]]'),
        "scene[0].points",
    ),
    ("no-scene", '[study]\nname = "t"\n', "scene"),
    ("unknown-setting", GOOD + "\n[settings]\nfoo = 1\n", "settings.foo"),
    ("setting-type", GOOD + '\n[settings]\nmax_cycles = "many"\n', "settings.max_cycles"),
    ("setting-range", GOOD + "\n[settings]\nevent_tol = 1.0\n", "settings.event_tol"),
    (
        "unknown-fidelity",
        GOOD.replace('name = "t"', 'name = "t"\nfidelity = "ultra"'),
        "study.fidelity",
    ),
    ("unknown-mode", scene('contact = "ground"\ndof = 2\nmode = "sweep"'), "scene[0].mode"),
    (
        "point-not-a-pair",
        scene('contact = "ground"\ndof = 2\npoints = [[1.0]]', grid=False),
        "scene[0].points[0]",
    ),
    (
        "point-r-zero",
        scene('contact = "ground"\ndof = 2\npoints = [[1.0, 0.1], [0.0, 0.1]]', grid=False),
        "scene[0].points[1][0]",
    ),
    ("gamma-list-length", scene('contact = "ground"\ndof = 3\ngamma = [1.0]'), "scene[0].gamma"),
    ("stop-below-start", GOOD.replace("stop = 2.0", "stop = 0.05"), "scene[0].r.stop"),
    (
        "log-from-zero",
        GOOD.replace(
            "start = 0.0, stop = 1.0, num = 4", 'start = 0.0, stop = 1.0, num = 4, spacing = "log"'
        ),
        "scene[0].beta.start",
    ),
    (
        "sweep-with-dof-1",
        scene('contact = "ground"\ndof = 1\ngamma = {values = [1.0, 2.0]}'),
        "scene[0].gamma",
    ),
    ("missing-r", scene('contact = "ground"\ndof = 2\nbeta = [0.1]', grid=False), "scene[0].r"),
    ("study-not-table", "study = 3\n" + GOOD.split("\n", 3)[3], "study"),
    ("bad-scene-name", scene('name = "a/b"\ncontact = "ground"\ndof = 2'), "scene[0].name"),
    (
        "values-not-increasing",
        scene('contact = "ground"\ndof = 2\nr = [2.0, 1.0]\nbeta = [0.1]', grid=False),
        "scene[0].r.values",
    ),
    (
        "points-sweep",
        scene(
            'contact = "ground"\ndof = 2\ngamma = {values = [1.0, 2.0]}\npoints = [[1.0, 0.2]]',
            grid=False,
        ),
        "scene[0].gamma",
    ),
    (
        "points-column-length",
        scene('contact = "ground"\ndof = 2\npoints = {r = [1.0, 2.0], beta = [0.1]}', grid=False),
        "scene[0].points.beta",
    ),
    ("missing-contact", scene("dof = 2"), "scene[0].contact"),
]


@pytest.mark.parametrize(("text", "field"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_malformed_study_names_the_field(study_file, tmp_path, text, field):
    path = study_file(text)
    with pytest.raises(StudyError) as info:
        Study.from_toml(path)
    line = str(info.value)
    assert "\n" not in line
    assert line.startswith(f"study.toml: {field}: "), line
    assert info.value.field == field
    assert sorted(p.name for p in tmp_path.iterdir()) == ["study.toml"]


def test_good_study_is_accepted(study_file):
    """The base of the table is valid, so each case fails for its own reason."""
    study = Study.from_toml(study_file(GOOD))
    assert study.n_points == 20


def test_toml_syntax_error(study_file):
    with pytest.raises(StudyError) as info:
        Study.from_toml(study_file(GOOD + "\n[[scene]\n"))
    assert str(info.value).startswith("study.toml: TOML syntax error")


def test_missing_file(tmp_path):
    with pytest.raises(StudyError, match="no such study file"):
        Study.from_toml(tmp_path / "nope.toml")


CLI_CASES = ["negative-num", "mass-with-dof-1", "huge-grid", "unknown-setting", "grid-and-points"]


@pytest.mark.parametrize("case", CLI_CASES)
def test_cli_bad_study_exit_2(case, study_file, run_cli, tmp_path):
    _, text, field = next(c for c in CASES if c[0] == case)
    study_file(text)
    proc = run_cli("run", "study.toml", "-o", "out.nc", "--workers", "1")
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert f"study.toml: {field}: " in lines[0]
    assert proc.stdout == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["study.toml"]


@pytest.mark.parametrize(
    ("args", "field"),
    [
        (("run", "missing.toml"), "no such study file"),
        (("run", "study.toml", "-o", "nodir/out.nc"), "-o: output directory does not exist"),
        (("run", "study.toml", "--workers", "0"), "--workers"),
        (("run", "study.toml", "--fidelity", "ultra"), "--fidelity: must be one of"),
        (("plan", "study.toml", "--fidelity", "ultra"), "--fidelity: must be one of"),
        (("report", "missing.nc", "-o", "rep"), "no such file"),
    ],
)
def test_cli_bad_arguments_exit_2(args, field, study_file, run_cli, tmp_path):
    study_file(GOOD)
    proc = run_cli(*args)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and field in lines[0], proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["study.toml"]
