"""The first compile of each simulator is announced before the wait, for exactly the
simulators a study needs (study.firstrun, tasks.numba_cache).

* a study's scenes name the simulators it compiles: the one-contact kernel, the
  several-contact one, or both; a scene with nothing missing names none;
* :func:`study.firstrun.compile_once` announces and compiles those not cached,
  each in one line naming it, and nothing else (a one-contact study never compiles
  the several-contact simulator);
* ``study run`` (the CLI) and :func:`study.run_study` (the Python API) of a
  several-contact study announce the several-contact simulator before its compile;
  :func:`tasks.multicontact.classify_multi` announces it once per process, apart
  from the one-contact kernel's announcement;
* :func:`tasks.numba_cache.is_compiled` reads the index of the several-contact
  entry point, and a fresh cache folder holds none;
* the several-contact cache key changes with every module of tasks/multicontact,
  which leaves the one-contact key alone.

No test here compiles anything: the compiles are replaced by recorders (the
measured first and second runs are in docs/simulator.md).
"""

from __future__ import annotations

import io
import os
import shutil
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from study import Study
from study.chunks import plan
from study.firstrun import compile_once, kernels_for
from tasks import numba_cache

REPO = Path(__file__).resolve().parents[1]
ONE, SEVERAL = numba_cache.ONE_CONTACT, numba_cache.SEVERAL_CONTACTS

HEADER = """
[study]
name = "first"
fidelity = "fast"
"""
ONE_CONTACT = """
[[scene]]
name = "ground_m1"
contact = "ground"
dof = 2
contact_mass = 1
r = {start = 0.1, stop = 2.5, num = 6}
beta = {start = 0.0, stop = 1.2, num = 5}
"""
TWO_CONTACTS = """
[[scene]]
name = "ground_m1_m2"
contact = "ground"
dof = 2
contact_mass = [1, 2]
beta_ratio = [1.0, 0.5]
r = {start = 0.1, stop = 2.5, num = 6}
beta = {start = 0.0, stop = 1.2, num = 5}
"""


def _study(tmp_path: Path, scenes: str) -> Study:
    path = tmp_path / "study.toml"
    path.write_text(HEADER + scenes, encoding="utf-8")
    return Study.from_toml(path)


def _several(tmp_path: Path) -> Study:
    return _study(tmp_path, TWO_CONTACTS)


class Compiled(list):
    """The names of the simulators compiled; ``stop``: Ctrl-C at the first compile."""

    stop = False


@pytest.fixture
def cold(monkeypatch):
    """Every simulator counts as not cached; compiling records its name (and, for the
    runs, stops them there with Ctrl-C: nothing is computed)."""
    compiled = Compiled()

    def fake_compile(kernel: str = ONE) -> float:
        compiled.append(kernel)
        if compiled.stop:
            raise KeyboardInterrupt
        return 2.0

    monkeypatch.setattr(numba_cache, "is_compiled", lambda kernel=ONE: False)
    monkeypatch.setattr(numba_cache, "compile_simulator", fake_compile)
    return compiled


# ------------------------------------------------------------------ which simulators
def test_a_study_needs_the_simulators_of_its_scenes(tmp_path):
    assert kernels_for(plan(_study(tmp_path, ONE_CONTACT))) == (ONE,)
    assert kernels_for(plan(_several(tmp_path))) == (SEVERAL,)
    both = _study(tmp_path, ONE_CONTACT + TWO_CONTACTS)
    assert kernels_for(plan(both)) == (ONE, SEVERAL)
    beam = Study.from_toml(REPO / "examples" / "beam_two_contacts_damped.toml")
    assert kernels_for(plan(beam)) == (SEVERAL,)
    cantilever = Study.from_toml(REPO / "examples" / "cantilever.toml")  # a damped beam
    assert kernels_for(plan(cantilever)) == (ONE,)


def test_a_scene_with_nothing_missing_needs_no_simulator(tmp_path):
    one, several = plan(_study(tmp_path, ONE_CONTACT + TWO_CONTACTS))
    done = SimpleNamespace(spec=several.spec, missing_points=lambda work: 0)
    left = SimpleNamespace(spec=one.spec, missing_points=lambda work: 3)
    assert kernels_for([left, done], work=object()) == (ONE,)
    assert kernels_for([done], work=object()) == ()


# ------------------------------------------------------------------ compile_once
def test_compile_once_announces_and_compiles_exactly_what_it_is_given(cold):
    out = io.StringIO()
    assert compile_once(out, (SEVERAL,)) == 2.0
    assert cold == [SEVERAL]
    lines = out.getvalue().splitlines()
    assert len(lines) == 2
    assert lines[0].startswith(
        f"study: compiling the several-contact simulator once ({numba_cache.COMPILE_TIME})"
    )
    assert (
        f"{SEVERAL}-{numba_cache.kernel_key(sources=numba_cache.MULTICONTACT_SOURCES)}"
        in (lines[0])
    )
    assert lines[1] == "study: compiled in 2 s"

    cold.clear()
    out = io.StringIO()
    assert compile_once(out, (ONE,)) == 2.0
    assert cold == [ONE] and "several" not in out.getvalue()
    assert out.getvalue().startswith("study: compiling the simulator once (")

    cold.clear()
    out = io.StringIO()
    assert compile_once(out, (ONE, SEVERAL)) == 4.0
    assert cold == [ONE, SEVERAL]
    assert [ln.split(" once")[0] for ln in out.getvalue().splitlines()[::2]] == [
        "study: compiling the simulator",
        "study: compiling the several-contact simulator",
    ]


def test_compile_once_skips_a_cached_simulator(monkeypatch, cold):
    monkeypatch.setattr(numba_cache, "is_compiled", lambda kernel=ONE: kernel == ONE)
    out = io.StringIO()
    assert compile_once(out, (ONE, SEVERAL)) == 2.0
    assert cold == [SEVERAL] and out.getvalue().count("compiling") == 1


# ------------------------------------------------------------------ the front doors
def _announced_then_stopped(text: str, compiled: list[str]) -> None:
    """The announcement of ``text`` (stderr of a run stopped at its first compile)."""
    lines = [ln for ln in text.splitlines() if "compiling" in ln]
    assert compiled == [SEVERAL], text
    assert len(lines) == 1 and "compiling the several-contact simulator once" in lines[0], text


def test_study_run_of_several_contacts_announces_their_simulator(tmp_path, cold, capsys):
    from study.cli import EXIT_INTERRUPTED, main

    _several(tmp_path)
    cold.stop = True
    out = str(tmp_path / "out.nc")
    assert main(["run", str(tmp_path / "study.toml"), "-o", out, "--quiet"]) == EXIT_INTERRUPTED
    _announced_then_stopped(capsys.readouterr().err, cold)
    assert not os.path.exists(out)


def test_study_plan_calibrate_announces_the_simulators_it_times(
    tmp_path, cold, capsys, monkeypatch
):
    from study.cli import EXIT_INTERRUPTED, main

    def compile_then_stop(kernel: str = ONE) -> float:  # both announced, then Ctrl-C
        cold.append(kernel)
        if kernel == SEVERAL:
            raise KeyboardInterrupt
        return 2.0

    monkeypatch.setattr(numba_cache, "compile_simulator", compile_then_stop)
    _study(tmp_path, ONE_CONTACT + TWO_CONTACTS)
    assert main(["plan", str(tmp_path / "study.toml"), "--calibrate"]) == EXIT_INTERRUPTED
    err = [ln for ln in capsys.readouterr().err.splitlines() if "compiling" in ln]
    assert cold == [ONE, SEVERAL] and len(err) == 2
    assert "the simulator once" in err[0] and "the several-contact simulator once" in err[1]


def test_run_study_of_several_contacts_announces_their_simulator(tmp_path, cold):
    from study import run_study
    from study.errors import StudyInterrupted

    study = _several(tmp_path)
    cold.stop = True
    log = io.StringIO()
    with pytest.raises((StudyInterrupted, KeyboardInterrupt)):
        run_study(study, tmp_path / "out.nc", progress=False, stream=log)
    _announced_then_stopped(log.getvalue(), cold)


def test_classify_multi_announces_its_simulator_once(monkeypatch, capsys):
    from tasks.multicontact import MultiScene, classify_multi, steady

    class Stop(Exception):
        pass

    def stop(*args):
        raise Stop

    monkeypatch.setattr(numba_cache, "_announced_others", set())
    monkeypatch.setattr(numba_cache, "_announced", False)
    monkeypatch.setattr(numba_cache, "is_compiled", lambda kernel=ONE: False)
    monkeypatch.setattr(steady, "run_points", stop)  # nothing is simulated
    scene = MultiScene.chain("ground", 2, [1, 2])
    for _ in range(2):
        with pytest.raises(Stop):
            classify_multi(scene, 0.8, 0.3)
    err = capsys.readouterr().err.splitlines()
    assert err == [numba_cache.compile_message("tasks", SEVERAL)]
    assert numba_cache.cache_dir(SEVERAL) in err[0]
    assert numba_cache.announce_compile()  # the one-contact kernel's: still to come
    assert "compiling the simulator once" in capsys.readouterr().err


def test_is_compiled_reads_the_several_contact_entry_point(monkeypatch):
    from tasks.multicontact import steady

    for index, want in (({}, False), ({("sig",): "entry"}, True)):
        cache_file = SimpleNamespace(_load_index=lambda index=index: index)
        fake = SimpleNamespace(_cache=SimpleNamespace(_cache_file=cache_file))
        monkeypatch.setattr(steady, "run_points", fake)
        assert numba_cache.is_compiled(SEVERAL) is want
    with pytest.raises(ValueError, match="^kernel: one of kernel, multicontact"):
        numba_cache.is_compiled("several")


def test_a_fresh_cache_folder_holds_no_several_contact_simulator(tmp_path):
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env.update(NUMBA_CACHE_DIR=str(tmp_path / "empty"), PYTHONPATH=str(REPO))
    code = (
        "from tasks import numba_cache as n; "
        "print(n.is_compiled('multicontact'), n.cache_dir('multicontact'))"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], env=env, cwd=tmp_path, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr
    compiled, folder = proc.stdout.split()
    assert compiled == "False"
    key = numba_cache.kernel_key(sources=numba_cache.MULTICONTACT_SOURCES)
    assert Path(folder).is_relative_to(tmp_path / "empty" / f"multicontact-{key}")


def test_every_several_contact_module_is_in_its_key_and_none_in_the_kernels(tmp_path):
    root = tmp_path / "tasks"
    shutil.copytree(REPO / "tasks", root, ignore=shutil.ignore_patterns("__pycache__"))
    sources = numba_cache.MULTICONTACT_SOURCES
    key, one = numba_cache.kernel_key(root, sources), numba_cache.kernel_key(root)
    modules = sorted((root / "multicontact").glob("*.py"))
    assert {"cycle.py", "decide.py", "steady.py", "viscous.py"} <= {p.name for p in modules}
    for path in modules:
        text = path.read_text()
        path.write_text(text + "\n")
        assert numba_cache.kernel_key(root, sources) != key, path.name
        assert numba_cache.kernel_key(root) == one, path.name
        path.write_text(text)
    assert numba_cache.kernel_key(root, sources) == key
