"""numba's on-disk cache of the kernel is keyed by every kernel module (tasks.numba_cache).

numba checks only the source file a compiled function is defined in, but a
caller's cached machine code contains its callees from other modules. These
tests run a copy of the package in subprocesses: an edit of a constant in one
callee module must reach a caller compiled and cached before the edit (with
the cache key fixed, as numba alone would do, the caller stays stale), and an
unchanged package must load everything from the cache.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

from tasks import numba_cache

REPO = Path(__file__).resolve().parents[1]

# The entry function lives in tasks/kernel/events.py, its callee ``evaluate`` in
# tasks/kernel/propagation.py. A phase with no modes and the observable
# A cos(tau) + y0 from tau0 = 0: y(t) = y0 - 2 A sin(t / 2)^2 (the constant edited).
PROBE = """
import json, sys
import numpy as np
import tasks
from tasks.kernel import events, layout
assert tasks.__file__.startswith(sys.argv[1]), tasks.__file__
seg = np.zeros((layout.N_ROWS, 0))
sc = np.zeros(layout.N_SCALARS)
sc[layout.COS_TAU0] = 1.0
sc[layout.OBS_COS] = 1.0
sc[layout.OBS0] = 0.25
y, _ = events._observe(seg, sc, 1.0, np.zeros(0), np.zeros(0))
stats = getattr(events._observe, "stats", None)
hits = sum(stats.cache_hits.values()) if stats else 0
misses = sum(stats.cache_misses.values()) if stats else 0
print(json.dumps({"y": y, "hits": hits, "misses": misses}))
"""
CONSTANT = "y = sc[OBS0] - 2.0 * amp"
EDITED = "y = sc[OBS0] - 4.0 * amp"


def _copy(tmp_path: Path) -> Path:
    root = tmp_path / "site"
    shutil.copytree(REPO / "tasks", root / "tasks", ignore=shutil.ignore_patterns("__pycache__"))
    return root


def _probe(root: Path) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env["PYTHONPATH"] = str(root)
    proc = subprocess.run(
        [sys.executable, "-c", PROBE, str(root)],
        env=env,
        cwd=root,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert text.count(old) == 1, f"{old!r} not found once in {path}"
    path.write_text(text.replace(old, new))


def test_an_edited_callee_module_recompiles_its_callers(tmp_path):
    root = _copy(tmp_path)
    first = _probe(root)
    assert first["y"] == math.fsum([0.25, -2.0 * math.sin(0.5) ** 2])
    assert first["misses"] == 1 and first["hits"] == 0  # compiled, then saved
    again = _probe(root)
    assert again == {"y": first["y"], "hits": 1, "misses": 0}  # unchanged: loaded
    _edit(root / "tasks" / "kernel" / "propagation.py", CONSTANT, EDITED)
    edited = _probe(root)
    truth = math.fsum([0.25, -4.0 * math.sin(0.5) ** 2])  # the edited constant's y
    assert edited["y"] == truth != first["y"]
    assert edited["misses"] == 1 and edited["hits"] == 0


def test_without_the_key_the_caller_would_stay_stale(tmp_path):
    """The control: numba's own per-file check misses the edit (so the test above can fail)."""
    root = _copy(tmp_path)
    hashing = "    digest = hashlib.sha256()\n"
    _edit(root / "tasks" / "numba_cache.py", hashing, '    return "fixed"\n' + hashing)
    first = _probe(root)
    _edit(root / "tasks" / "kernel" / "propagation.py", CONSTANT, EDITED)
    stale = _probe(root)
    assert stale == {"y": first["y"], "hits": 1, "misses": 0}


def test_the_key_covers_the_kernel_and_the_regime_constants_only(tmp_path):
    root = _copy(tmp_path) / "tasks"
    key = numba_cache.kernel_key(root)
    assert numba_cache.kernel_key(root) == key
    assert numba_cache.kernel_key(REPO / "tasks") == key  # same sources, same key
    for name in ("kernel/layout.py", "kernel/design.py", "regimes.py"):
        path = root / name
        text = path.read_text()
        path.write_text(text + "\n")
        assert numba_cache.kernel_key(root) != key, name
        path.write_text(text)
    assert numba_cache.kernel_key(root) == key
    (root / "scene.py").write_text((root / "scene.py").read_text() + "\n")
    assert numba_cache.kernel_key(root) == key  # not compiled into the kernel


def test_classify_announces_a_first_compile_once_and_a_cached_one_never(monkeypatch, capsys):
    from tasks import Scene, classify

    classify(Scene("ground", 2), 0.8, 0.3)  # compiled or loaded in this process
    capsys.readouterr()
    monkeypatch.setattr(numba_cache, "_announced", False)
    monkeypatch.setattr(numba_cache, "is_compiled", lambda: False)  # as with a cold cache
    classify(Scene("ground", 2), 0.8, 0.3)
    classify(Scene("ground", 2), 0.9, 0.3)
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith(
        f"tasks: compiling the simulator once ({numba_cache.COMPILE_TIME})"
    )
    assert numba_cache.cache_dir() in err[0]
    monkeypatch.setattr(numba_cache, "_announced", False)
    monkeypatch.setattr(numba_cache, "is_compiled", lambda: True)  # cached: silent
    classify(Scene("ground", 2), 0.8, 0.3)
    assert capsys.readouterr().err == ""


def test_is_compiled_reads_the_entry_point_that_classify_calls(monkeypatch):
    """is_compiled() reads the cache index of the kernel function classify calls (else a
    cached simulator is announced as compiling at every run, and an adaptive study's
    client never computes its short point lists, study.adaptive)."""
    from types import SimpleNamespace

    from tasks import Scene, classify, kernel

    real, called = kernel.run_points_given, []

    def spy(*args):
        called.append(True)
        return real(*args)

    monkeypatch.setattr(kernel, "run_points_given", spy)
    classify(Scene("ground", 2), 0.8, 0.3)
    assert called
    for index, want in (({}, False), ({("sig",): "entry"}, True)):
        cache_file = SimpleNamespace(_load_index=lambda index=index: index)
        fake = SimpleNamespace(_cache=SimpleNamespace(_cache_file=cache_file))
        monkeypatch.setattr(kernel, "run_points_given", fake)
        assert numba_cache.is_compiled() is want


def test_a_fresh_cache_folder_is_detected_as_cold(tmp_path):
    """is_compiled() reads the index of the keyed folder: an empty base has none."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env.update(NUMBA_CACHE_DIR=str(tmp_path / "empty"), PYTHONPATH=str(REPO))
    code = (
        "from tasks import numba_cache; print(numba_cache.is_compiled(), numba_cache.cache_dir())"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], env=env, cwd=tmp_path, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr
    compiled, folder = proc.stdout.split()
    assert compiled == "False"
    assert Path(folder).is_relative_to(tmp_path / "empty" / f"kernel-{numba_cache.kernel_key()}")


def test_every_subpackage_is_in_the_wheel():
    """setuptools installs only the packages listed: the kernel package must be one."""
    import tomllib

    listed = set(
        tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]
    )
    found = {
        ".".join(init.parent.relative_to(REPO).parts)
        for top in ("tasks", "analysis", "study")
        for init in (REPO / top).rglob("__init__.py")
    }
    assert "tasks.kernel" in found
    assert found <= listed


def test_a_constant_argument_compiles_the_callee_for_its_type_not_its_value():
    """numba compiles a callee once per combination of constant arguments (typed as
    literals) of the calls between compiled functions; the kernel's functions are
    compiled once per argument type instead (numba_cache.compile_per_type), the types a
    call from Python gives them too."""
    from numba import njit, types

    def make():
        @njit
        def callee(x, k, flag):
            return x * k if flag else x

        @njit
        def caller(x):
            return callee(x, 2, True) + callee(x, 3, False)

        return callee, caller

    callee, caller = make()
    assert caller(1.0) == 3.0
    assert any(isinstance(t, types.Literal) for sig in callee.signatures for t in sig)  # control
    callee, caller = make()
    numba_cache.compile_per_type(callee)
    assert caller(1.0) == 3.0
    assert callee.signatures == [(types.float64, types.int64, types.boolean)]
    callee(1.0, 2, True)  # from Python: the same signature, nothing more compiled
    assert len(callee.signatures) == 1


def test_every_compiled_function_of_both_simulators_is_compiled_per_type():
    import tasks.multicontact
    from tasks import kernel

    for package in (kernel, tasks.multicontact):
        prefix = package.__name__ + "."
        found = [
            value
            for name, module in list(sys.modules.items())
            if name.startswith(prefix)
            for value in vars(module).values()
            if getattr(getattr(value, "py_func", None), "__module__", None) == name
        ]
        assert len(found) > 20, package.__name__
        assert all(getattr(d.get_call_template, "per_type", False) for d in found)
