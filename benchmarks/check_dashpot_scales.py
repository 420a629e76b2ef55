"""The scales of damped-pair scenes (creep threshold, motion floor) against an older tree.

Run from the repository root::

    .venv/bin/python benchmarks/check_dashpot_scales.py bound [--code DIR]
    .venv/bin/python benchmarks/check_dashpot_scales.py save new.npz [--code DIR]
    .venv/bin/python benchmarks/check_dashpot_scales.py compare old.npz new.npz
    .venv/bin/python benchmarks/check_dashpot_scales.py unchanged --code DIR [--repeat 5] [--design]

Chains with dashpots (non-proportional damping: damped pairs, docs/structures.md
4.5) are drawn as the random audit draws them (``benchmarks/audit_random.py``,
``draw_dashpot``), seed ``s`` from ``default_rng([s, 101])``.

``bound``: seeds 30-41, r at half the lowest natural frequency, the geometric mean
of the lowest and highest, 1.3 and 4 times the highest; beta at 0.9, 0.99, 0.999 and
1.001 of the damped motion bound (``balanced``). Below the bound no steady state is
stuck (docs/structures.md 3.1): a ``no_motion`` there, or a label other than
``no_motion`` above it, is counted against the bound.

``save``: seeds 0-39, 24 points each (``draw_points`` with the damped bound, seed
``[s, 201]``), at ``fast``, ``balanced`` and ``exact``; every label, cycle count and
slip amplitude into an .npz. ``compare`` prints, per preset, the ``not_converged``
points, the ``no_motion`` labels below the bound and the periods of both files, and
every point whose label differs.

``unchanged``: scenes whose phases run on real modes (undamped chains, chains as
matrices with Rayleigh or modal damping, a damped cantilever, two contacts), 600 to
2,000 random points each, classified by this checkout and by ``--code DIR`` in
alternating child processes (best CPU time of ``--repeat`` each): the result arrays
must be identical (with ``--design``, the design quantities too); the new / old time
per scene.

``--code DIR`` imports ``tasks`` from another checkout (e.g. main before a change).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
PRESETS = ("fast", "balanced", "exact")
FRACTIONS = np.array([0.9, 0.99, 0.999, 1.001])


def _audit():
    sys.path.insert(0, str(REPO / "benchmarks"))
    import audit_random

    return audit_random


def _dashpot_chain(seed: int):
    return _audit().draw_dashpot(np.random.default_rng([seed, 101]))


def bound() -> None:
    from analysis.closed_form import motion_bound
    from tasks import classify, regimes

    audit = _audit()
    against = total = 0
    for seed in range(30, 42):
        scene = _dashpot_chain(seed)
        w = audit.free_frequencies(scene)
        for r in (0.5 * w[0], float(np.sqrt(w[0] * w[-1])), 1.3 * w[-1], 4.0 * w[-1]):
            mb = float(motion_bound(scene, np.array([r]))[0])
            res = classify(scene, np.full(FRACTIONS.size, r), mb * FRACTIONS)
            below = res.regime[:3] == regimes.NO_MOTION
            above = res.regime[3] != regimes.NO_MOTION
            against += int(below.sum()) + int(above)
            total += FRACTIONS.size
            labels = " ".join(regimes.ALL_CODES[c] for c in res.regime)
            print(f"seed {seed} r = {r:.4g} (bound {mb:.4g}): {labels}", flush=True)
    print(f"against the motion bound: {against} of {total}")


def save(path: str) -> None:
    from analysis.closed_form import motion_bound
    from tasks import classify

    audit = _audit()
    data = {}
    for seed in range(40):
        scene = _dashpot_chain(seed)
        pts = audit.draw_points(np.random.default_rng([seed, 201]), scene, 24, damped_bound=True)
        r = np.array([p[0] for p in pts])
        beta = np.array([p[1] for p in pts])
        data.update({f"{seed}:r": r, f"{seed}:beta": beta, f"{seed}:bound": motion_bound(scene, r)})
        for preset in PRESETS:
            res = classify(scene, r, beta, fidelity=preset)
            for field in ("regime", "cycles", "slip_amplitude"):
                data[f"{seed}:{preset}:{field}"] = np.asarray(getattr(res, field))
        print(f"seed {seed} done", flush=True)
    np.savez(path, **data)


def compare(old_path: str, new_path: str) -> None:
    from tasks import regimes

    old, new = np.load(old_path), np.load(new_path)
    seeds = sorted({int(k.split(":")[0]) for k in old.files if k.endswith(":r")})
    for preset in PRESETS:
        counts = {"not_converged": [0, 0], "no_motion below the bound": [0, 0], "periods": [0, 0]}
        changed = []
        for s in seeds:
            below = old[f"{s}:beta"] < old[f"{s}:bound"] * (1.0 - 1e-9)
            for i, f in enumerate((old, new)):
                reg = f[f"{s}:{preset}:regime"]
                counts["not_converged"][i] += int((reg < 0).sum())
                counts["no_motion below the bound"][i] += int(((reg == 0) & below).sum())
                counts["periods"][i] += int(f[f"{s}:{preset}:cycles"].sum())
            a, b = old[f"{s}:{preset}:regime"], new[f"{s}:{preset}:regime"]
            for i in np.flatnonzero(a != b):
                frac = old[f"{s}:beta"][i] / old[f"{s}:bound"][i]
                changed.append(
                    f"  seed {s} r = {old[f'{s}:r'][i]:.5g}, beta / bound = {frac:.6f}: "
                    f"{regimes.ALL_CODES[a[i]]} -> {regimes.ALL_CODES[b[i]]}"
                )
        print(f"{preset}: " + ", ".join(f"{k} {o} -> {n}" for k, (o, n) in counts.items()))
        print("\n".join(changed))


#: Run by ``unchanged`` in a child process on one source tree: prints JSON.
UNCHANGED = """
import json, sys, time
import numpy as np
from tasks import Scene, classify
from tasks.structures import beam
chain = Scene("ground", 3, 2, gamma=[0.5, 2.0], kappa=[1.5, 0.7]).matrices()
chain["damping"] = ("rayleigh", 0.05, 0.01)
pair = Scene("ground", 2, 1, gamma=[0.5], kappa=[1.5]).matrices()
pair["damping"] = ("modal", 0.02)
scenes = [
    ("2dof ground m1", Scene("ground", 2, 1), 2000),
    ("3dof mass", Scene("mass", 3, 2, gamma=[0.5, 2.0], kappa=[1.5, 0.7]), 2000),
    ("5dof base m4", Scene("base", 5, 4, gamma=[0.00733, 492.0, 0.0743, 0.347],
                           kappa=[92.5, 0.285, 1.98, 0.00146]), 600),
    ("3dof matrices, Rayleigh", Scene.from_matrices(**chain), 2000),
    ("2dof matrices, modal", Scene.from_matrices(**pair), 2000),
    ("cantilever, Rayleigh", beam(8, "cantilever", contact_node=6, modes=3,
                                  damping=("rayleigh", 0.0, 0.01)), 600),
    ("two contacts", Scene("ground", 2, contact_mass=[1, 2], beta_ratio=[1.0, 0.5]), 600),
]
rng = np.random.default_rng(7)
saved, times = {}, {}
for i, (name, scene, n) in enumerate(scenes):
    r = np.exp(rng.uniform(np.log(0.1), np.log(5.0), n))
    beta = np.exp(rng.uniform(np.log(0.01), np.log(3.0), n))
    classify(scene, r[:2], beta[:2])  # (the compiled kernels loaded)
    t = time.process_time()
    res = classify(scene, r, beta, design=sys.argv[2] == "design")
    times[name] = time.process_time() - t
    saved.update({f"{i}:{k}": np.asarray(v) for k, v in res.as_dict().items() if v is not None})
np.savez(sys.argv[1], **saved)
print(json.dumps(times))
"""  # fmt: skip


def unchanged(code: str, repeat: int, design: bool) -> None:
    trees = {"old": str(Path(code).resolve()), "new": str(REPO)}
    best: dict[str, dict[str, float]] = {"old": {}, "new": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(repeat):
            for which in ("old", "new") if k % 2 == 0 else ("new", "old"):
                env = dict(os.environ, PYTHONPATH=trees[which])
                mode = "design" if design else "labels"
                proc = subprocess.run(
                    [sys.executable, "-c", UNCHANGED, f"{tmp}/{which}.npz", mode],
                    env=env, cwd=trees[which], capture_output=True, text=True, check=True,
                )  # fmt: skip
                for name, t in json.loads(proc.stdout.strip().splitlines()[-1]).items():
                    best[which][name] = min(best[which].get(name, np.inf), t)
        old, new = np.load(f"{tmp}/old.npz"), np.load(f"{tmp}/new.npz")
        differ = [f for f in old.files if not np.array_equal(old[f], new[f], equal_nan=True)]
        print(f"arrays: {len(old.files)}, differing: {differ or 'none'}")
    print("| scene | old CPU s | new CPU s | new / old |\n|---|---:|---:|---:|")
    for name, t_old in best["old"].items():
        t_new = best["new"][name]
        print(f"| {name} | {t_old:.3f} | {t_new:.3f} | {t_new / t_old:.2f} |")
    t_old, t_new = sum(best["old"].values()), sum(best["new"].values())
    print(f"| total | {t_old:.3f} | {t_new:.3f} | {t_new / t_old:.2f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("what", choices=("bound", "save", "compare", "unchanged"))
    ap.add_argument("files", nargs="*")
    ap.add_argument("--code", help="import tasks from this checkout (unchanged: the old tree)")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--design", action="store_true", help="unchanged: with the design quantities")
    args = ap.parse_args()
    if args.what == "unchanged":
        if not args.code:
            ap.error("unchanged needs --code DIR")
        unchanged(args.code, args.repeat, args.design)
        return
    if args.code:
        sys.path.insert(0, str(Path(args.code).resolve()))
    start = time.process_time()
    if args.what == "bound":
        bound()
    elif args.what == "save":
        save(args.files[0])
    else:
        compare(*args.files)
    print(f"CPU {time.process_time() - start:.1f} s")


if __name__ == "__main__":
    main()
