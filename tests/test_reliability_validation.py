"""Bad input stops at the door (issue 13): every case of the reliability audit that can
be checked before compute is refused before compute, with one line naming the field.

* study files out of the ranges the numerics support (r = 1e-308 / 1e308, kappa =
  1e300 / 1e308, step_fraction = 1e-17), a trace with one beta value, names of 256+
  characters, a 1000-deep TOML table, integers of 2^64, ``num = 1e9`` with
  ``max_points`` raised: ``Study.from_toml`` raises ``StudyError`` naming the field
  (and ``study plan`` exits 2 with one line, no traceback);
* run options: ``-o`` a FIFO, a device, a directory, a path in a read-only file
  system; a garbage ``--scheduler-file``; ``--workers`` above 4 per core;
  ``--retries`` negative: ``run_study`` raises ``StudyError`` before any cluster
  starts and writes nothing;
* the API: strings, booleans and out-of-range values are refused with a
  ``ValueError`` naming the field; the closed forms never warn;
* a seeded fuzz test: 300 mutations of a valid study file all end in a validated
  study or one ``StudyError`` line (never another exception), fast;
* a seeded fuzz of the Python API: 600 calls of ``Study``, ``SceneSpec``, ``Axis``,
  ``Points``, ``Scene`` and 100 of ``classify`` with keyword arguments of wrong types
  and values each validate or raise ``StudyError``/``ValueError``/``TypeError`` in
  one line naming a field, never another exception.
"""

from __future__ import annotations

import math
import os
import random
import re
import time
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pytest

from analysis import boundaries, predict
from study import Axis, Points, SceneSpec, Study, StudyError
from study.chunks import plan
from study.limits import MAX_AXIS, MAX_NAME
from study.preflight import MAX_WORKERS_PER_CORE
from study.run import default_workers, run_study
from tasks import Scene, classify
from tasks.fidelity import LIMITS, resolve

GOOD = """
[study]
name = "t"
fidelity = "fast"

[settings]
max_cycles = 100

[[scene]]
contact = "ground"
dof = 2
r = {start = 0.5, stop = 1.5, num = 4}
beta = {start = 0.0, stop = 1.0, num = 3}
"""
DEEP = "\n[x]\nv = " + "{a = " * 1000 + "1" + "}" * 1000 + "\n"
BIG = 2**64

# (id, study text, field the one-line message must name)
STUDY_CASES = [
    ("r-1e-308", GOOD.replace("start = 0.5", "start = 1e-308"), "scene[0].r"),
    ("r-1e308", GOOD.replace("stop = 1.5", "stop = 1e308"), "scene[0].r"),
    ("kappa-1e300", GOOD + "kappa = 1e300\n", "scene[0].kappa"),
    ("kappa-1e308", GOOD + "kappa = 1e308\n", "scene[0].kappa"),
    ("kappa-sweep-1e300", GOOD + "kappa = {values = [1.0, 1e300]}\n", "scene[0].kappa"),
    ("gamma-1e-300", GOOD + "gamma = [1e-300]\n", "scene[0].gamma"),
    ("beta-1e300", GOOD.replace("stop = 1.0", "stop = 1e300"), "scene[0].beta"),
    (
        "points-r-1e-308",
        GOOD.replace("r = {start = 0.5, stop = 1.5, num = 4}\n", "").replace(
            "beta = {start = 0.0, stop = 1.0, num = 3}", "points = [[1e-308, 0.1]]"
        ),
        "scene[0].points",
    ),
    (
        "step_fraction-1e-17",
        GOOD.replace("max_cycles = 100", "step_fraction = 1e-17"),
        "settings.step_fraction",
    ),
    ("event_tol-0", GOOD.replace("max_cycles = 100", "event_tol = 1e-30"), "settings.event_tol"),
    ("max_cycles-2^64", GOOD.replace("100", str(BIG)), "settings.max_cycles"),
    ("max_work-2^64", GOOD.replace("max_cycles = 100", f"max_work = {BIG}"), "settings.max_work"),
    ("max_cycles-string", GOOD.replace("100", '"5"'), "settings.max_cycles"),
    ("dof-2^64", GOOD.replace("dof = 2", f"dof = {BIG}"), "scene[0].dof"),
    ("num-2^64", GOOD.replace("num = 4", f"num = {BIG}"), "scene[0].r.num"),
    ("max_points-2^64", GOOD.replace('fidelity = "fast"', f"max_points = {BIG}"), "max_points"),
    (
        "num-1e9-max_points-raised",
        GOOD.replace("num = 4", "num = 1000000000").replace(
            'fidelity = "fast"', "max_points = 10000000000"
        ),
        "scene[0].r.num",
    ),
    (
        "trace-one-beta",
        GOOD.replace("beta = {start = 0.0, stop = 1.0, num = 3}", 'beta = [0.3]\nmode = "trace"'),
        "scene[0].beta",
    ),
    ("scene-name-256", GOOD + f'name = "{"a" * 256}"\n', "scene[0].name"),
    ("study-name-256", GOOD.replace('name = "t"', f'name = "{"s" * 256}"'), "study.name"),
    ("deep-toml", GOOD + DEEP, ""),
    ("task_seconds-huge", GOOD.replace('fidelity = "fast"', "task_seconds = 1e9"), "task_seconds"),
]


@pytest.mark.parametrize(
    ("text", "field"), [c[1:] for c in STUDY_CASES], ids=[c[0] for c in STUDY_CASES]
)
def test_out_of_range_study_is_refused_naming_the_field(study_file, text, field):
    path = study_file(text)
    t0 = time.perf_counter()
    with pytest.raises(StudyError) as info:
        Study.from_toml(path)
    assert time.perf_counter() - t0 < 5.0  # refused before any large allocation
    line = str(info.value)
    assert "\n" not in line and line.startswith("study.toml")
    assert field in line, line


@pytest.mark.parametrize("case", ["r-1e308", "deep-toml"])
def test_cli_plan_refuses_with_one_line(case, study_file, run_cli):
    text = dict((c[0], c[1]) for c in STUDY_CASES)[case]
    study_file(text)
    proc = run_cli("plan", "study.toml")
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("study: error: study.toml"), proc.stderr


def test_limits_accept_the_documented_extremes(study_file):
    """The ends of every documented range are accepted (the limits are not too tight)."""
    text = GOOD.replace("start = 0.5, stop = 1.5", "start = 1e-4, stop = 1e4")
    text = text.replace("stop = 1.0", "stop = 1e6")
    text += "gamma = 1e-6\nkappa = 1e6\n"
    settings = "\n".join(f"{k} = {hi!r}" for k, (_, hi) in LIMITS.items() if k != "min_cycles")
    text = text.replace("max_cycles = 100", settings)
    study = Study.from_toml(study_file(text))
    assert study.settings.step_fraction == 1.0
    name = "n" * MAX_NAME
    assert Study.from_toml(study_file(GOOD.replace('name = "t"', f'name = "{name}"'))).name == name
    assert MAX_AXIS >= 100_000  # a 1e5-point axis is an ordinary study


# --------------------------------------------------------------------------- run options
@pytest.fixture
def small_study(study_file) -> Study:
    return Study.from_toml(study_file(GOOD))


def _refused(study: Study, output, **kw) -> str:
    with pytest.raises(StudyError) as info:
        run_study(study, output, progress=False, **kw)
    line = str(info.value)
    assert "\n" not in line
    return line


def test_output_fifo_device_directory_refused(small_study, tmp_path):
    fifo = tmp_path / "pipe.nc"
    os.mkfifo(fifo)
    assert "FIFO" in _refused(small_study, fifo)
    assert "character device" in _refused(small_study, "/dev/null")
    assert Path("/dev/null").is_char_device()  # still a device, never replaced
    assert "directory" in _refused(small_study, tmp_path)
    assert not list(tmp_path.glob("*.work")), "nothing may be written"


def test_output_in_unwritable_directory_refused(small_study, tmp_path):
    """/proc is read-only even for root: the write probe catches what permission bits miss."""
    line = _refused(small_study, "/proc/result.nc")
    assert line.startswith("-o: cannot write in the output directory /proc"), line


def test_output_name_too_long_refused(small_study, tmp_path):
    assert "too long" in _refused(small_study, tmp_path / ("x" * 250 + ".nc"))


def test_garbage_scheduler_file_refused(small_study, tmp_path):
    garbage = tmp_path / "sched.json"
    garbage.write_bytes(b"\x00not json {")
    assert _refused(small_study, tmp_path / "o.nc", scheduler_file=str(garbage)).startswith(
        "--scheduler-file: not a scheduler file"
    )
    garbage.write_text('{"address": 12}')
    assert "no scheduler address" in _refused(
        small_study, tmp_path / "o.nc", scheduler_file=str(garbage)
    )


def test_workers_retries_timeout_bounds(small_study, tmp_path):
    out = tmp_path / "o.nc"
    top = MAX_WORKERS_PER_CORE * default_workers()
    assert _refused(small_study, out, workers=top + 1).startswith("--workers")
    assert _refused(small_study, out, workers=1000).startswith("--workers")
    assert _refused(small_study, out, retries=-3).startswith("--retries")
    assert _refused(small_study, out, worker_timeout=0).startswith("--worker-timeout")
    assert not out.exists() and not out.with_name("o.nc.work").exists()


@pytest.mark.parametrize(
    "args",
    [("--workers", "1000"), ("-o", "/dev/null")],
)
def test_cli_run_options_exit_2_one_line(args, study_file, run_cli):
    study_file(GOOD)
    proc = run_cli("run", "study.toml", *args)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"study: error: {args[0]}"), proc.stderr


# --------------------------------------------------------------------------- the API
@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda: Scene("ground", 3, gamma="12"), "gamma"),
        (lambda: Scene("ground", 3, kappa=["1", 2.0]), "kappa"),
        (lambda: Scene("ground", 2, gamma=True), "gamma"),
        (lambda: Scene("ground", 2, kappa=1e300), "kappa"),
        (lambda: Scene("ground", BIG), "dof"),
        (lambda: classify(Scene("ground", 2), "1.0", 0.3), "r"),
        (lambda: classify(Scene("ground", 2), 1.0, True), "beta"),
        (lambda: classify(Scene("ground", 2), [1.0, "2"], 0.3), "r"),
        (lambda: classify(Scene("ground", 2), 1e-300, 0.3), "r"),
        (lambda: classify(Scene("ground", 2), 1e308, 0.3), "r"),
        (lambda: classify(Scene("ground", 2), 1.0, 1e300), "beta"),
        (lambda: classify(Scene("ground", 2), 1.0, 0.3, max_cycles="5"), "max_cycles"),
        (lambda: classify(Scene("ground", 2), 1.0, 0.3, max_cycles=True), "max_cycles"),
        (lambda: classify(Scene("ground", 2), 1.0, 0.3, step_fraction=1e-17), "step_fraction"),
        (lambda: classify(Scene("ground", 2), 1.0, 0.3, shooting=1), "shooting"),
        (lambda: resolve("fast", event_tol="1e-9"), "event_tol"),
        (lambda: boundaries(Scene("ground", 2), 1e300), "r"),
        (lambda: boundaries(Scene("ground", 2), 1e-300), "r"),
        (lambda: boundaries(Scene("ground", 2), "1.0"), "r"),
        (lambda: predict(Scene("ground", 2), 1.0, "0.3"), "beta"),
    ],
)
def test_api_refuses_wrong_types_and_ranges(call, field):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match=rf"^{field}: "):
            call()


def test_settings_checked_once_still_refuse_equal_values_of_another_type():
    """classify resolves each settings combination once per process: 1, 1.0 and True are
    equal (and hash alike) but not the same override."""
    scene = Scene("ground", 2)
    classify(scene, 1.0, 0.3, seed=1)
    classify(scene, 1.0, 0.3, shooting=True)
    assert classify(scene, 1.0, 0.3, seed=1.0).regime.shape == ()  # an integer still
    with pytest.raises(ValueError, match="seed"):
        classify(scene, 1.0, 0.3, seed=True)
    with pytest.raises(ValueError, match="shooting"):
        classify(scene, 1.0, 0.3, shooting=1)


def test_closed_forms_never_warn_over_their_range():
    """From r = 1e-100 to 1e100 the bounds are finite or inf, never NaN, and silent."""
    r = np.logspace(-100, 100, 101)
    scenes = [
        Scene("ground", 1),
        Scene("base", 1),
        Scene("ground", 2),
        Scene("base", 2, 2),
        Scene("mass", 2),
        Scene("mass", 3, 2, gamma=[1e-6, 1e6], kappa=[1e6, 1e-6]),
    ]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for scene in scenes:
            for method in ("paper", "exact"):
                cont, motion = boundaries(scene, r, method)
                assert not np.isnan(cont).any() and not np.isnan(motion).any(), scene
                assert (cont >= 0).all() and (motion >= 0).all()
            predict(scene, r, 0.5)
    # SDOF ground wall: the motion bound is 1 at every r (Eq. 60), far out too
    np.testing.assert_allclose(boundaries(Scene("ground", 1), [1e-100, 1e100])[1], 1.0)


# --------------------------------------------------------------------------- fuzz
_NUMBERS = [0, -1, 1, 2, 0.0, -0.5, 1e-308, 1e308, 2**63, 2**64, 1e-17, math.pi, 1e9, 3]
_VALUES = [*_NUMBERS, "x", "", True, [], [1.0], {}, {"values": []}, float("nan"), float("inf")]


def _mutate(data, rng: random.Random, depth: int = 0):
    """One random change somewhere in the TOML data: a value replaced, a key added or removed."""
    if isinstance(data, dict) and data:
        key = rng.choice(sorted(data))
        roll = rng.random()
        if roll < 0.15:
            data.pop(key)
        elif roll < 0.25:
            data[rng.choice(["num", "name", "dof", "foo", "values", "mode", key])] = rng.choice(
                _VALUES
            )
        elif roll < 0.7 or depth > 4:
            data[key] = rng.choice(_VALUES)
        else:
            data[key] = _mutate(data[key], rng, depth + 1)
        return data
    if isinstance(data, list) and data:
        i = rng.randrange(len(data))
        data[i] = _mutate(data[i], rng, depth + 1) if rng.random() < 0.5 else rng.choice(_VALUES)
        return data
    return rng.choice(_VALUES)


FUZZ_BASE = (
    GOOD
    + """
kappa = {values = [0.5, 2.0]}

[[scene]]
name = "pts"
contact = "mass"
dof = 3
points = {r = [0.4, 0.9], beta = [0.1, 0.2], gamma = [1.0, 2.0]}

[[scene]]
name = "tr"
contact = "base"
dof = 2
contact_mass = 2
mode = "trace"
r = {start = 0.1, stop = 3.0, num = 5}
beta = {start = 0.0, stop = 3.0, num = 31}
"""
)


def test_fuzzed_studies_fail_fast_with_one_line():
    """300 seeded mutations: each is a valid study (whose chunks can be planned) or one
    StudyError line; never another exception; all within a few seconds."""
    base = tomllib.loads(FUZZ_BASE)
    rng = random.Random(13)
    refused = accepted = 0
    t0 = time.perf_counter()
    for _ in range(300):
        data = _mutate(tomllib.loads(FUZZ_BASE), rng)
        for _ in range(rng.randrange(3)):
            data = _mutate(data, rng)
        try:
            study = Study.from_dict(data, source="fuzz.toml")
        except StudyError as exc:
            assert "\n" not in str(exc) and re.match(r"^fuzz\.toml: ", str(exc)), str(exc)
            refused += 1
            continue
        accepted += 1
        for p in plan(study):  # an accepted study can be cut into chunks
            assert p.n_chunks >= 1
            next(iter(p.chunks()))
    assert Study.from_dict(base).n_points > 0
    assert refused >= 150, (refused, accepted)  # most mutations break a rule
    assert time.perf_counter() - t0 < 60


# --------------------------------------------------------------------------- fuzz of the API
R = Axis(start=0.5, stop=1.5, num=4)
BETA = Axis(start=0.0, stop=1.0, num=3)


def spec(**kw) -> SceneSpec:
    return SceneSpec(**{"name": "s", "contact": "ground", "dof": 2, "r": R, "beta": BETA, **kw})


def _api_values(rng: random.Random) -> object:
    pool = [
        0, -1, 1, 2, 3, 0.0, -0.5, 0.5, 1.5, 1e-308, 1e308, 2**63, 2**64, float("nan"),
        float("inf"), True, False, np.int64(2), np.int8(-3), np.float32(0.7), np.bool_(True),
        "x", "", "ground", "grid", "adaptive", None, [], [1.0], [0.5, 1.0], [[1.0, 0.2]],
        ["1", 2], {}, {"values": [0.5, 1.0]}, {"start": 0.5, "stop": 1.5, "num": 3},
        {"num": 2**63 - 1, "start": 1.0, "stop": 2.0}, {"foo": 1}, np.array([0.5, 1.0]),
        np.zeros((2, 2)), (1.0, 2.0), object(), R, BETA, Points((1.0,), (0.1,)), b"bytes",
        1j, {"r": [1.0], "beta": [0.1]}, [R], [spec()],
    ]  # fmt: skip
    return rng.choice(pool)


FUZZ_TARGETS = {
    SceneSpec: (
        {"name": "s", "contact": "ground", "dof": 2, "r": R, "beta": BETA},
        [
            *("contact_mass", "gamma", "kappa", "points", "mode"),
            *("coarse_step", "verify_fraction", "hint"),
        ],
    ),
    Axis: ({"start": 0.5, "stop": 1.5, "num": 3}, ["spacing", "values"]),
    Points: ({"r": (1.0, 2.0), "beta": (0.1, 0.2)}, ["gamma", "kappa"]),
    Study: (
        {"name": "t", "scenes": (spec(),)},
        ["description", "fidelity", "overrides", "max_points", "task_seconds", "chunk_points"],
    ),
    Scene: ({"contact": "ground", "dof": 2}, ["contact_mass", "gamma", "kappa"]),
}  # fmt: skip


def _one_line(exc: BaseException) -> str:
    text = str(exc)
    assert text and "\n" not in text, repr(text)
    return text


def _names_a_field(exc: BaseException, names: set[str]) -> bool:
    field = getattr(exc, "field", None)
    head, _, rest = str(exc).partition(": ")
    text = f"{field} {getattr(exc, 'message', '')}" if field is not None else f"{head} {rest}"
    tokens = set(re.findall(r"[A-Za-z_]+", text))
    aliases = {"scene": "scenes", "settings": "overrides"}
    tokens |= {aliases[t] for t in tokens if t in aliases}
    return bool(tokens & names) or any(f"'{n}'" in str(exc) for n in names)


def test_fuzzed_python_api_fails_with_one_line_naming_a_field():
    """600 seeded calls with wrong types and values: each validates or raises
    StudyError/ValueError/TypeError in one line naming a field; never anything else."""
    rng = random.Random(22)
    outcomes = {"accepted": 0, "refused": 0}
    t0 = time.perf_counter()
    for _ in range(600):
        cls = rng.choice(list(FUZZ_TARGETS))
        base, optional = FUZZ_TARGETS[cls]
        kw = dict(base)
        keys = list(base) + optional
        for _ in range(rng.randrange(1, 4)):
            kw[rng.choice(keys)] = _api_values(rng)
        if rng.random() < 0.1:
            kw.pop(rng.choice(list(base)))
        if rng.random() < 0.05:
            kw["bogus"] = 1
        try:
            cls(**kw)
        except (StudyError, ValueError, TypeError) as exc:
            text = _one_line(exc)
            assert _names_a_field(exc, set(keys) | {"bogus"}), (cls.__name__, kw, text)
            outcomes["refused"] += 1
            continue
        outcomes["accepted"] += 1
    for _ in range(100):  # classify: the numerics' door (valid calls compute one point)
        kw = {"r": rng.choice([1.0, _api_values(rng)]), "beta": rng.choice([0.3, _api_values(rng)])}
        if rng.random() < 0.5:
            kw[rng.choice(["max_cycles", "step_fraction", "fidelity"])] = _api_values(rng)
        try:
            classify(Scene("ground", 2), fidelity=kw.pop("fidelity", "fast"), **kw)
        except (ValueError, TypeError) as exc:
            _one_line(exc)
            assert _names_a_field(exc, {"r", "beta", "max_cycles", "step_fraction", "fidelity"})
            outcomes["refused"] += 1
            continue
        outcomes["accepted"] += 1
    assert outcomes["refused"] > 300 and outcomes["accepted"] > 20, outcomes
    assert time.perf_counter() - t0 < 120
