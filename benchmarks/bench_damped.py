"""Cost of damping in the simulator, and undamped scenes against an older source tree.

Run from the repository root::

    .venv/bin/python benchmarks/bench_damped.py                     # ~1 min
    .venv/bin/python benchmarks/bench_damped.py --old /path/to/tree # + same-run old/new
    .venv/bin/python benchmarks/bench_damped.py --accuracy 12       # vs scipy, ~3 min

1. **Damped vs undamped** (same run, same points): each of a few scenes is
   classified undamped and with Rayleigh damping (``("rayleigh", a, b)``,
   docs/structures.md 4), or with a non-proportional dashpot (rows ``*_dashpot``,
   docs/structures.md 4.5), on the same seeded (r, beta) sample; points per second
   and the damped / undamped cost ratio (best of ``--repeats``).
2. **Undamped, old vs new** (``--old``: a checkout of the code before damping, e.g.
   ``git archive <commit> | tar -x -C DIR``): the same undamped sample is timed in a
   subprocess on each source tree (both kernels warmed up first), the ratio new / old
   printed, and the regime, cycles and slip amplitude arrays compared bit for bit.
3. **Accuracy** (``--accuracy N``): N random points of each of eight damped scenes
   (single masses, Rayleigh chains with every contact, random full M and K, a
   cantilever) against the damped scipy reference (200 cycles from rest).

Markdown tables on stdout. Wall times on a shared machine include its load.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SEED = 20261124

#: Undamped scenes of the paper (chains; old and new code both take them).
UNDAMPED = {
    "2dof_ground_m1": ("ground", 2, 1),
    "2dof_base_m2": ("base", 2, 2),
    "2dof_mass": ("mass", 2, 1),
    "5dof_ground_m4": ("ground", 5, 4),
}

#: Timing script run on a source tree (its path first on sys.path): prints JSON.
TIMER = textwrap.dedent(
    """
    import hashlib, json, sys, time
    import numpy as np
    from tasks import Scene, classify
    scenes = json.loads(sys.argv[1]); n = int(sys.argv[2]); repeats = int(sys.argv[3])
    rng = np.random.default_rng(int(sys.argv[4]))
    r = rng.uniform(0.2, 3.0, n); beta = rng.uniform(0.0, 1.5, n)
    classify(Scene("ground", 2), 1.0, 0.3)  # compile or load the kernel
    out = {}
    for name, args in scenes.items():
        scene = Scene(*args)
        best = float("inf")
        for _ in range(repeats):
            t = time.perf_counter()
            res = classify(scene, r, beta)
            best = min(best, time.perf_counter() - t)
        h = hashlib.sha256()
        for f in ("regime", "cycles", "slip_amplitude", "stick_fraction", "stops_per_cycle"):
            h.update(np.ascontiguousarray(getattr(res, f)).tobytes())
        out[name] = {"seconds": best, "hash": h.hexdigest()}
    print(json.dumps(out))
    """
)


def _sample(n: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(SEED)
    return rng.uniform(0.2, 3.0, n), rng.uniform(0.0, 1.5, n)


def _best(scene, r, beta, repeats: int) -> float:
    from tasks import classify

    best = float("inf")
    for _ in range(repeats):
        t = time.perf_counter()
        classify(scene, r, beta)
        best = min(best, time.perf_counter() - t)
    return best


def damped_vs_undamped(n: int, repeats: int) -> None:
    from tasks import Scene, classify
    from tasks.structures import beam

    r, beta = _sample(n)
    classify(Scene("ground", 2), 1.0, 0.3)  # compile or load the kernel
    rows = []
    chains = {name: Scene(*args) for name, args in UNDAMPED.items()}
    pairs = {}
    for name, chain in chains.items():
        kw = chain.matrices()
        pairs[name] = (
            Scene.from_matrices(**kw),
            Scene.from_matrices(**{**kw, "damping": ("rayleigh", 0.05, 0.01)}),
        )
    pairs["cantilever_3modes"] = (
        beam(12, contact_node=10, modes=3),
        beam(12, contact_node=10, modes=3, damping=("rayleigh", 0.02, 0.002)),
    )
    # non-proportional damping (pairs, docs/structures.md 4.5): a dashpot at one DOF
    kw = chains["5dof_ground_m4"].matrices()
    dashpot = np.zeros((5, 5))
    dashpot[2, 2] = 0.1
    pairs["5dof_ground_m4_dashpot"] = (
        Scene.from_matrices(**kw),
        Scene.from_matrices(**{**kw, "damping": dashpot}),
    )
    cant = beam(12, contact_node=10, modes=3).matrices()
    local = np.zeros_like(cant["mass"])
    local[0, 0] = 0.05  # a dashpot at the contact
    pairs["cantilever_3modes_dashpot"] = (
        Scene.from_matrices(**cant),
        Scene.from_matrices(**{**cant, "damping": local}),
    )
    for name, (plain, damped) in pairs.items():
        t0 = _best(plain, r, beta, repeats)
        t1 = _best(damped, r, beta, repeats)
        rows.append((name, n / t0, n / t1, t1 / t0))
    print(f"\n### Damped vs undamped ({n} points, best of {repeats})\n")
    print("| scene | undamped points/s | damped points/s | damped / undamped cost |")
    print("|---|---:|---:|---:|")
    for name, a, b, ratio in rows:
        print(f"| {name} | {a:,.0f} | {b:,.0f} | {ratio:.2f} |")


def _run_tree(tree: Path, n: int, repeats: int) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    cmd = [sys.executable, "-c", TIMER, json.dumps(UNDAMPED), str(n), str(repeats), str(SEED)]
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=tree, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def old_vs_new(old: Path, n: int, repeats: int) -> int:
    new_t = _run_tree(REPO, n, repeats)
    old_t = _run_tree(old, n, repeats)
    again = _run_tree(REPO, n, repeats)  # new twice around old: load drift shows
    print(f"\n### Undamped chains, new vs old source tree ({n} points, best of {repeats})\n")
    print("| scene | old s | new s (before, after) | new / old | results bit-identical |")
    print("|---|---:|---:|---:|:---:|")
    same_all = True
    for name in UNDAMPED:
        o, a, b = old_t[name], new_t[name], again[name]
        new_s = min(a["seconds"], b["seconds"])
        same = o["hash"] == a["hash"] == b["hash"]
        same_all &= same
        print(
            f"| {name} | {o['seconds']:.3f} | {a['seconds']:.3f}, {b['seconds']:.3f} | "
            f"{new_s / o['seconds']:.2f} | {'yes' if same else 'NO'} |"
        )
    return 0 if same_all else 1


def accuracy(n_per_scene: int, seed: int) -> None:
    """Regimes and slip amplitudes of the simulator against the damped scipy reference
    (tasks.baseline, 200 cycles from rest, atol 1e-9) on random points of damped scenes."""
    from analysis import closed_form
    from tasks import Scene, classify, regimes
    from tasks.baseline import paper_method
    from tasks.structures import beam

    rng = np.random.default_rng(seed)

    def spd(n):
        q, _ = np.linalg.qr(rng.standard_normal((n, n)))
        return q @ np.diag(np.exp(rng.uniform(0.0, np.log(10.0), n))) @ q.T

    def chain(args, a, b):
        return Scene.from_matrices(**{**Scene(*args).matrices(), "damping": ("rayleigh", a, b)})

    one = [[1.0]]
    scenes = {
        "mass zeta 0.05": Scene.from_matrices(
            one, one, [1.0], ("ground", 0), damping=("modal", 0.05)
        ),
        "mass base zeta 0.2": Scene.from_matrices(
            one, one, ("base", [1.0]), ("ground", 0), damping=("modal", 0.2)
        ),
        "3dof chain m2": chain(("ground", 3, 2), 0.1, 0.02),
        "2dof base m1": chain(("base", 2, 1), 0.1, 0.01),
        "2dof mass": chain(("mass", 2, 1), 0.15, 0.0),
        "full 3x3 wall": Scene.from_matrices(
            spd(3), spd(3), rng.standard_normal(3), ("ground", 1), damping=("rayleigh", 0.1, 0.02)
        ),
        "full 4x4 between": Scene.from_matrices(
            spd(4),
            spd(4),
            rng.standard_normal(4),
            ("between", 0, 3),
            damping=("rayleigh", 0.08, 0.03),
        ),
        "cantilever 3 modes": beam(12, contact_node=10, modes=3, damping=("rayleigh", 0.1, 0.004)),
    }
    print(f"\n### Accuracy against the damped scipy reference ({n_per_scene} points per scene)\n")
    print("| scene | points | same regime | moving | slip amplitude within 1e-4 |")
    print("|---|---:|---:|---:|---:|")
    totals = np.zeros(4, dtype=int)
    for name, scene in scenes.items():
        row = np.zeros(4, dtype=int)
        for _ in range(n_per_scene):
            r = float(rng.uniform(0.3, 3.0))
            bm = float(closed_form.motion_bound(scene, [r])[0])
            beta = float(rng.uniform(0.0, 1.2 * min(bm, 5.0)))
            res = classify(scene, r, beta)
            code, info = paper_method(scene, r, beta, cycles=200, atol=1e-9)
            row[0] += 1
            row[1] += int(res.regime) == code
            if code != regimes.NO_MOTION and int(res.regime) == code:
                row[2] += 1
                row[3] += abs(info["amplitude"] - res.slip_amplitude) <= 1e-4 * info["amplitude"]
        totals += row
        print(f"| {name} | {row[0]} | {row[1]} | {row[2]} | {row[3]} |")
    print(f"| **all** | {totals[0]} | {totals[1]} | {totals[2]} | {totals[3]} |")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=400)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--old", type=Path, help="source tree of the code before damping")
    ap.add_argument("--accuracy", type=int, default=0, help="random points per damped scene")
    args = ap.parse_args()
    sys.path.insert(0, str(REPO))
    if args.accuracy:
        accuracy(args.accuracy, SEED)
        return 0
    damped_vs_undamped(args.points, args.repeats)
    if args.old:
        return old_vs_new(args.old.resolve(), args.points, args.repeats)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
