"""Cost of the design pass under base loads, this checkout against another one.

``python benchmarks/bench_design_frames.py --code DIR [--repeat 2]``: for a chain
with a base-fixed wall, a 5DOF ground chain (force load) and a random 3DOF structure
under a base load with influence u = (1, 0.5, -0.25) (undamped and Rayleigh damped),
the CPU time of ``kernel.orbit_designs`` on a 100 x 40 grid (best of 3 in a process;
classification and compilation excluded), in alternating child processes of this
checkout and ``DIR`` (``--repeat`` rounds, the best of each), and which design
columns differ between the two.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def _scenes():
    from tasks import Scene
    from tasks.multicontact import reference as ref

    M, K, _ = ref.random_structure(np.random.default_rng(7), 3)
    u = ("base", np.array([1.0, 0.5, -0.25]))
    return {
        "2DOF base m_2": Scene("base", 2, 2),
        "5DOF ground m_4": Scene("ground", 5, 4),
        "3DOF base u=(1,.5,-.25)": Scene.from_matrices(M, K, u, ("ground", 1)),
        "3DOF base u, damped": Scene.from_matrices(
            M, K, u, ("ground", 1), damping=("rayleigh", 0.02, 0.01)
        ),
    }


def child(out: str) -> None:
    from tasks import kernel
    from tasks.classifier import scene_modes_cached, settings_args
    from tasks.fidelity import resolve

    saved, rows = {}, []
    for name, scene in _scenes().items():
        r, beta = np.meshgrid(np.linspace(0.05, 2.5, 100), np.linspace(0.0, 1.5, 40))
        r, beta = np.ascontiguousarray(r.ravel()), np.ascontiguousarray(beta.ravel())
        args = settings_args(resolve("balanced"))
        sargs = scene_modes_cached(scene).kernel_args()
        o, f = kernel.run_points(r[:2], beta[:2], sargs, args)  # compile / load
        kernel.orbit_designs(r[:2], beta[:2], sargs, args, o, f, kernel.DESIGN_SAMPLES)
        res, final = kernel.run_points(r, beta, sargs, args)
        best = np.inf
        for _ in range(3):
            t0 = time.process_time()
            d, _ = kernel.orbit_designs(r, beta, sargs, args, res, final, kernel.DESIGN_SAMPLES)
            best = min(best, time.process_time() - t0)
        saved[name] = d
        rows.append((name, best))
    np.savez(out, **saved)
    print(json.dumps(rows))


def compare(code: str, repeat: int) -> None:
    best: dict[str, dict[str, float]] = {"this": {}, "code": {}}
    files = {}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(repeat):
            for label, root in (("this", REPO), ("code", Path(code).resolve())):
                out = Path(tmp) / f"{label}.npz"
                env = {**os.environ, "PYTHONPATH": str(root)}
                cmd = [sys.executable, __file__, "--child", str(out)]
                proc = subprocess.run(cmd, env=env, cwd=root, capture_output=True, text=True)
                if proc.returncode != 0:
                    raise SystemExit(proc.stderr[-2000:])
                for name, dt in json.loads(proc.stdout.strip().splitlines()[-1]):
                    best[label][name] = min(best[label].get(name, np.inf), dt)
                files[label] = dict(np.load(out))
    print(f"orbit_designs, 4000 points, best CPU s of {repeat}: this checkout vs {code}")
    print(f"{'scene':<26}{'this':>8}{'code':>8}{'ratio':>7}  columns that differ")
    for name, dt in best["this"].items():
        a, b = files["this"][name], files["code"][name]
        cols = [
            j for j in range(a.shape[1]) if not np.array_equal(a[:, j], b[:, j], equal_nan=True)
        ]
        other = best["code"][name]
        print(f"{name:<26}{dt:>8.3f}{other:>8.3f}{dt / other:>7.3f}  {cols or 'none'}")


if __name__ == "__main__":
    if "--child" in sys.argv:
        sys.path.insert(0, os.environ["PYTHONPATH"])
        child(sys.argv[sys.argv.index("--child") + 1])
    elif "--code" in sys.argv:
        n = int(sys.argv[sys.argv.index("--repeat") + 1]) if "--repeat" in sys.argv else 2
        compare(sys.argv[sys.argv.index("--code") + 1], n)
    else:
        raise SystemExit(__doc__)
