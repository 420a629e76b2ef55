"""Cost of a two-contact map against the one-contact map of the same chain (same run).

A 2DOF ground-fixed chain (gamma = kappa = 1): one contact on m1 (the single-
contact kernel) against a contact on each mass (beta_ratio 1 and 0.5,
tasks.multicontact), on the same grid of r x beta, each timed after a warm-up
(compiled code loaded), in CPU seconds (the simulators run on one thread); then
the same two contacts with Rayleigh damping C = 0.02 M + 0.01 K (docs/contacts.md 7)
where the checkout has it. Prints the table and the ratio; the target is at most 3.

    python benchmarks/bench_multicontact.py [n_r n_beta]     (default 250 100)
    python benchmarks/bench_multicontact.py [n_r n_beta] --code ../main [--repeat 2]

``--code DIR`` measures this checkout and DIR (e.g. main before a change) in
alternating child processes (``--repeat`` rounds; the best CPU time of each), and
checks that the undamped scenes give identical arrays in both.
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
DAMPING = ("rayleigh", 0.02, 0.01)


def _grid(n_r: int, n_beta: int):
    return np.meshgrid(np.linspace(0.2, 3.0, n_r), np.linspace(0.02, 1.5, n_beta), indexing="ij")


def measure(n_r: int, n_beta: int, arrays: str | None = None) -> list[tuple[str, float, float]]:
    """``(scene, CPU s, converged share)`` per scene; the results into ``arrays`` (.npz)."""
    from tasks import Scene, classify

    r, beta = _grid(n_r, n_beta)
    scenes = [
        ("one contact (m1)", Scene("ground", 2, 1)),
        ("two contacts (m1, m2)", Scene("ground", 2, contact_mass=[1, 2], beta_ratio=[1.0, 0.5])),
    ]
    try:
        two = scenes[1][1]
        kw = two.structures[0].kwargs()
        damped = Scene.from_matrices(
            kw["mass"], kw["stiffness"], kw["load"], list(two.contacts),
            beta_ratio=[1.0, 0.5], damping=DAMPING,
        )  # fmt: skip
        scenes.append(("two contacts, damped", damped))
    except ValueError:  # a checkout without damping for several contacts
        pass
    for _, scene in scenes:
        classify(scene, r[:2, :2], beta[:2, :2])
    rows = []
    saved = {}
    for i, (name, scene) in enumerate(scenes):
        t0 = time.process_time()
        res = classify(scene, r, beta)
        dt = time.process_time() - t0
        rows.append((name, dt, float(np.mean(res.converged))))
        if i < 2:
            for field, value in res.as_dict().items():
                if value is not None and field != "dissipation_viscous":
                    saved[f"{i}:{field}"] = np.asarray(value)
    if arrays:
        np.savez(arrays, **saved)
    return rows


def _table(rows, n_r, n_beta, label=""):
    print(f"map {n_r} x {n_beta} = {n_r * n_beta} points, 2DOF ground chain, balanced {label}")
    print(f"{'scene':<24}{'CPU s':>10}{'ms/point':>10}{'converged':>11}")
    for name, dt, conv in rows:
        print(f"{name:<24}{dt:>10.2f}{1e3 * dt / (n_r * n_beta):>10.3f}{conv:>11.4f}")
    print(f"ratio two / one: {rows[1][1] / rows[0][1]:.2f} (target <= 3)")
    if len(rows) > 2:
        print(f"ratio damped / undamped two contacts: {rows[2][1] / rows[1][1]:.2f}")


def compare(n_r: int, n_beta: int, code: str, repeat: int) -> None:
    """This checkout against ``code`` in alternating child processes."""
    best: dict[str, dict[str, float]] = {"this": {}, "code": {}}
    files = {}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(repeat):
            for label, root in (("this", REPO), ("code", Path(code).resolve())):
                out = Path(tmp) / f"{label}.npz"
                env = {**os.environ, "PYTHONPATH": str(root)}
                cmd = [sys.executable, __file__, str(n_r), str(n_beta), "--child", str(out)]
                proc = subprocess.run(cmd, env=env, cwd=root, capture_output=True, text=True)
                if proc.returncode != 0:
                    raise SystemExit(proc.stderr[-2000:])
                for name, dt, _ in json.loads(proc.stdout.strip().splitlines()[-1]):
                    best[label][name] = min(best[label].get(name, np.inf), dt)
                files[label] = dict(np.load(out))
        this, other = files["this"], files["code"]
        same = this.keys() == other.keys() and all(
            np.array_equal(this[k], other[k], equal_nan=True) for k in this
        )
    print(f"map {n_r} x {n_beta}, best CPU s of {repeat}: this checkout vs {code}")
    print(f"{'scene':<24}{'this':>10}{'code':>10}{'ratio':>8}")
    for name, dt in best["this"].items():
        other = best["code"].get(name)
        ratio = f"{dt / other:>8.3f}" if other else f"{'-':>8}"
        print(f"{name:<24}{dt:>10.2f}{other or float('nan'):>10.2f}{ratio}")
    print(f"undamped arrays identical: {same}")


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    if "--child" in sys.argv:
        n_r, n_beta = int(sys.argv[1]), int(sys.argv[2])
        sys.path.insert(0, os.environ["PYTHONPATH"])
        rows = measure(n_r, n_beta, sys.argv[sys.argv.index("--child") + 1])
        print(json.dumps(rows))
    elif "--code" in sys.argv:
        code = sys.argv[sys.argv.index("--code") + 1]
        repeat = int(sys.argv[sys.argv.index("--repeat") + 1]) if "--repeat" in sys.argv else 2
        nums = [int(a) for a in args if a.isdigit()][:2] or [250, 100]
        compare(*nums, code, repeat)
    else:
        nums = [int(a) for a in args[:2]] or [250, 100]
        _table(measure(*nums), *nums)
