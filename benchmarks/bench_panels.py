"""Every panel of the paper's figures from the held and the rest start: counts and time.

Run from the repository root (one core, ~6-10 min on an idle machine)::

    .venv/bin/python benchmarks/bench_panels.py --output panels.json [--label after]
    .venv/bin/python benchmarks/bench_panels.py --compare before.json after.json

For every scene of ``examples/fig*.toml`` (23 panels of 25,000 points) it runs
``tasks.classify`` (preset ``balanced``) once from the held start and once from
rest (the same two calls before and after a change, so the seconds compare like
for like) and records per panel and start: the seconds, the undetermined points,
the points called stick-slip with a slip amplitude below the creep threshold
(:func:`creep_threshold`, docs/theory.md 3), and the points where the two starts
give different determined regimes. ``--compare`` prints both files side by side
with the speed ratio.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
# --code DIR: measure another checkout's tasks/ (e.g. the commit before a change)
_CODE = sys.argv[sys.argv.index("--code") + 1] if "--code" in sys.argv else str(REPO)
sys.path.insert(0, _CODE)

from study.bench import machine  # noqa: E402
from study.definition import Study  # noqa: E402
from tasks import Scene, classify, regimes  # noqa: E402

#: Relative slip threshold used for the counts (tasks.regimes.SLIP_RTOL; the
#: same number in both runs, also when --code measures an older checkout).
SLIP_RTOL = getattr(regimes, "SLIP_RTOL", 1e-7)


def creep_threshold(scene: Scene, r: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """``SLIP_RTOL * beta * c``: c = sum_i (b . psi_i)^2 / max(lambda_i, r^2), the
    compliance the contact sees at the excitation frequency (tasks.regimes.SLIP_RTOL)."""
    from scipy.linalg import eigh

    b = scene.contact_vector()
    lam, psi = eigh(scene.stiffness_matrix(), scene.mass_matrix(1.0))
    r2 = np.asarray(r, dtype=float)[..., None] ** 2
    c = ((b @ psi) ** 2 / np.maximum(lam, r2)).sum(axis=-1)
    return SLIP_RTOL * beta * c


def panels() -> list[tuple[str, Scene, np.ndarray, np.ndarray]]:
    out = []
    for path in sorted((REPO / "examples").glob("fig*.toml")):
        study = Study.from_toml(path)
        for spec in study.scenes:
            r, beta = np.meshgrid(spec.r.values_array(), spec.beta.values_array(), indexing="ij")
            out.append((f"{path.stem}/{spec.name}", spec.base_scene, r, beta))
    return out


def run(
    label: str,
    output: Path,
    only: str | None,
    save: Path | None,
    starts: list[str],
    n_random: int = 0,
) -> None:
    rows = []
    raw: dict[str, np.ndarray] | None = {} if save else None
    classify(Scene("ground", dof=2), 0.5, 0.3)  # compile / load the cache
    for name, scene, r, beta in panels():
        if only and only not in name:
            continue
        row: dict[str, object] = {"panel": name, "points": int(r.size)}
        regime = {}
        for start in starts:
            t0, c0 = time.perf_counter(), time.process_time()
            res = classify(scene, r, beta, initial_condition=start)
            row[f"seconds_{start}"] = time.perf_counter() - t0
            row[f"cpu_seconds_{start}"] = time.process_time() - c0
            regime[start] = res.regime
            if raw is not None:
                for field in ("regime", "slip_amplitude", "cycles", "stops_per_cycle"):
                    raw[f"{name}|{start}|{field}"] = np.asarray(getattr(res, field))
            row[f"undetermined_{start}"] = int((res.regime < 0).sum())
            creep = (res.regime == regimes.STICK_SLIP) & (
                res.slip_amplitude < creep_threshold(scene, r, beta)
            )
            row[f"creep_stick_slip_{start}"] = int(creep.sum())
            if hasattr(res, "start_dependent"):
                row[f"start_dependent_flag_{start}"] = int(np.asarray(res.start_dependent).sum())
        if len(regime) == 2:
            both = (regime["held"] >= 0) & (regime["rest"] >= 0)
            row["held_rest_differ"] = int((both & (regime["held"] != regime["rest"])).sum())
        if n_random:
            # held, rest and n_random seeded random starts on every 2nd r and beta
            sub = (slice(None, None, 2), slice(None, None, 2))
            t0 = time.perf_counter()
            res = classify(
                scene, r[sub], beta[sub], starts=("held", "rest"), n_random=n_random, seed=1
            )
            row["random_points"] = int(r[sub].size)
            row["random_seconds"] = time.perf_counter() - t0
            row["random_start_dependent"] = int(np.asarray(res.start_dependent).sum())
            undetermined_bit = 1 << 3
            row["random_undetermined_some_start"] = int(
                ((np.asarray(res.regimes_reached) & undetermined_bit) > 0).sum()
            )
        rows.append(row)
        print(json.dumps(row), flush=True)
    output.write_text(json.dumps({"label": label, "machine": machine(), "rows": rows}, indent=1))
    if save:
        np.savez_compressed(save, **raw)


def compare(before: Path, after: Path) -> None:
    a = {r["panel"]: r for r in json.loads(before.read_text())["rows"]}
    b = {r["panel"]: r for r in json.loads(after.read_text())["rows"]}
    keys = ["undetermined_held", "undetermined_rest", "creep_stick_slip_held"]
    keys += ["creep_stick_slip_rest", "held_rest_differ"]
    print("| panel | " + " | ".join(f"{k} (before / after)" for k in keys) + " | seconds |")
    print("|---" * (len(keys) + 2) + "|")
    ta = tb = 0.0
    for name in a:
        if name not in b:
            continue
        sa = a[name]["seconds_held"] + a[name]["seconds_rest"]
        sb = b[name]["seconds_held"] + b[name]["seconds_rest"]
        ta, tb = ta + sa, tb + sb
        cells = [f"{a[name][k]} / {b[name][k]}" for k in keys]
        print(f"| {name} | " + " | ".join(cells) + f" | {sa:.1f} / {sb:.1f} |")
    print(f"\ntotal seconds before {ta:.1f}, after {tb:.1f}, speed ratio {ta / tb:.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--output", type=Path, default=Path("panels.json"))
    ap.add_argument("--label", default="")
    ap.add_argument("--only", default=None, help="run only panels whose name contains this")
    ap.add_argument("--save", type=Path, default=None, help="also save the raw maps (.npz)")
    ap.add_argument("--starts", default="held,rest", help="comma-separated: held,rest")
    ap.add_argument(
        "--random", type=int, default=0, help="also count start dependence with K random starts"
    )
    ap.add_argument("--code", default=None, help="import tasks from this checkout instead")
    ap.add_argument("--compare", nargs=2, type=Path, metavar=("BEFORE", "AFTER"))
    args = ap.parse_args()
    if args.compare:
        compare(*args.compare)
    else:
        run(args.label, args.output, args.only, args.save, args.starts.split(","), args.random)


if __name__ == "__main__":
    main()
