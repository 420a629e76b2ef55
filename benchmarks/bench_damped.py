"""Cost of damping in the simulator, and undamped scenes against an older source tree.

Run from the repository root::

    .venv/bin/python benchmarks/bench_damped.py                     # ~1 min
    .venv/bin/python benchmarks/bench_damped.py --old /path/to/tree # + same-run old/new

1. **Damped vs undamped** (same run, same points): each of a few scenes is
   classified undamped and with Rayleigh damping (``("rayleigh", a, b)``,
   docs/structures.md 4) on the same seeded (r, beta) sample; points per second
   and the damped / undamped cost ratio (best of ``--repeats``).
2. **Undamped, old vs new** (``--old``: a checkout of the code before damping, e.g.
   ``git archive <commit> | tar -x -C DIR``): the same undamped sample is timed in a
   subprocess on each source tree (both kernels warmed up first), the ratio new / old
   printed, and the regime, cycles and slip amplitude arrays compared bit for bit.

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


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=400)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--old", type=Path, help="source tree of the code before damping")
    args = ap.parse_args()
    sys.path.insert(0, str(REPO))
    damped_vs_undamped(args.points, args.repeats)
    if args.old:
        return old_vs_new(args.old.resolve(), args.points, args.repeats)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
