"""Warm starts and the optional design pass: per-point cost on whole panels, and the paper's method.

Run from the repository root::

    .venv/bin/python benchmarks/bench_warm.py            # 250 x 100 panels, ~4 min on 2 cores
    .venv/bin/python benchmarks/bench_warm.py --quick    # 100 x 40 panels, ~1 min
    .venv/bin/python benchmarks/bench_warm.py --quick --code ../main  # another checkout

In one process, on a 250 x 100 (r, beta) panel of Fig. 4 (2DOF, ground contact
on m_1, gamma = 1, kappa = 0.5) and of Fig. 10b (5DOF, ground contact on m_2):
``tasks.classify`` (balanced; each configuration run twice, in order and in
reverse order, the lesser CPU time kept) with warm starts (the default, ``warm=True``:
seeds from solved neighbours, moving orbits polished) and with every point
from the held start (``warm=False``), each with and without the design pass
(``design=False``), one call per panel in the study's order (r outer, beta
inner), compiled beforehand; then the points of each regime class (of the cold
run) alone, with and without the design pass, for the cost and cycles per
class.
The paper's method (``tasks.baseline.paper_method``: RK45 + events, 100
cycles from rest, scipy) runs on a seeded sample of the same points; the
ratio is its mean time per point over each configuration's.
Labels: the warm and cold panels must agree point for point (regime and
stops); the paper's labels are compared on the sample (it integrates a fixed
100 cycles, so slow transients can differ). Times are CPU times of this
process (``time.process_time``; both sides single-threaded), so that the other
processes of a shared machine inflate neither. Prints Markdown tables.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
# --code DIR: measure another checkout's tasks/ (e.g. main before a change)
_CODE = sys.argv[sys.argv.index("--code") + 1] if "--code" in sys.argv else str(REPO)
sys.path.insert(0, _CODE)
sys.path.insert(1, str(REPO))

from study.bench import machine  # noqa: E402
from tasks import Scene, classify  # noqa: E402
from tasks.baseline import paper_method  # noqa: E402

PANELS = {
    "Fig. 4 (2DOF, m_1, gamma 1, kappa 0.5)": (Scene("ground", 2, 1, gamma=1.0, kappa=0.5), 1.5),
    "Fig. 10b (5DOF, m_2)": (Scene("ground", 5, 2), 2.0),
}
CONFIGS = {
    "warm + design (default)": {"warm": True},
    "warm, no design": {"warm": True, "design": False},
    "cold + design": {"warm": False},
    "cold, no design": {"warm": False, "design": False},
}
SEED = 19
CLASSES = {0: "no motion", 1: "stick-slip", 2: "continuous"}


#: Fields compared between two groupings (relative to their largest value on the panel).
CONTINUOUS = ("slip_amplitude", "stick_fraction", "amplitude", "contact_force_amplitude")
CONTINUOUS += ("dissipation",)


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    """Largest difference relative to the largest magnitude (inf if NaN at other points)."""
    if not np.array_equal(np.isfinite(a), np.isfinite(b)):
        return np.inf
    fin = np.isfinite(a)
    return float(np.max(np.abs(a[fin] - b[fin]), initial=0.0) / max(np.abs(a[fin]).max(), 1e-300))


def table(header: list[str], rows: list[list[object]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    return "\n".join(lines + ["| " + " | ".join(str(c) for c in row) + " |" for row in rows])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="100 x 40 panels, 20 paper points")
    parser.add_argument("--paper-points", type=int, default=None, help="paper sample per panel")
    parser.add_argument("--code", default=None, help="import tasks from this checkout instead")
    args = parser.parse_args()
    n_r, n_beta = (100, 40) if args.quick else (250, 100)
    n_paper = args.paper_points or (20 if args.quick else 40)
    print("machine: " + "; ".join(f"{k} {v}" for k, v in machine().items()))
    classify(Scene("ground", 2), [0.5, 1.5], [0.1, 0.6], design=False)  # compile / load
    classify(Scene("ground", 2), [0.5, 1.5], [0.1, 0.6])
    timing_rows, label_rows, class_rows = [], [], []
    for title, (scene, beta_max) in PANELS.items():
        r, beta = np.meshgrid(
            np.linspace(0.02, 2.5, n_r), np.linspace(0.0, beta_max, n_beta), indexing="ij"
        )
        results, per_point = {}, {}
        # each configuration twice, in order and in reverse order: the lesser CPU time
        # (a loaded machine inflates CPU times too, unevenly over a run)
        names = list(CONFIGS)
        for name in names + names[::-1]:
            t0 = time.process_time()
            results[name] = classify(scene, r, beta, **CONFIGS[name])
            cpu = (time.process_time() - t0) / r.size
            per_point[name] = min(per_point.get(name, np.inf), cpu)
        cold, warm = results["cold + design"], results["warm + design (default)"]
        pick = np.random.default_rng(SEED).choice(r.size, n_paper, replace=False)
        t0 = time.process_time()
        paper = np.array([paper_method(scene, r.flat[i], beta.flat[i])[0] for i in pick])
        paper_s = (time.process_time() - t0) / n_paper
        moving = cold.regime > 0
        # another grouping of the same points: beta outer, r inner (warm, with design)
        other = classify(scene, r.T, beta.T, warm=True)
        spread = max(
            _rel(getattr(warm, f), np.swapaxes(getattr(other, f), 0, 1)) for f in CONTINUOUS
        )
        for code, klass in CLASSES.items():  # each regime class alone, from the held start
            m = cold.regime == code
            if not m.any():
                continue
            cost = []
            for kw in ({"warm": False}, {"warm": False, "design": False}):
                t0 = time.process_time()
                classify(scene, r[m], beta[m], **kw)
                cost.append((time.process_time() - t0) / m.sum())
            class_rows.append(
                [title, klass, int(m.sum()), f"{cold.cycles[m].mean():.1f}"]
                + [f"{c * 1e6:.0f}" for c in cost]
                + [f"{cost[0] * 1e6 / max(cold.cycles[m].mean(), 1.0):.1f}"]
            )
        timing_rows.append(
            [title, f"{n_r} x {n_beta}"]
            + [f"{per_point[n] * 1e3:.3f}" for n in CONFIGS]
            + [f"{paper_s:.3f} ({n_paper})"]
            + [f"{paper_s / per_point[n]:.0f}x" for n in CONFIGS]
        )
        label_rows.append(
            [
                title,
                f"{np.sum(warm.regime == cold.regime)} / {r.size}",
                f"{np.sum(warm.stops_per_cycle == cold.stops_per_cycle)} / {r.size}",
                f"{np.nanmax(np.abs(warm.stick_fraction - cold.stick_fraction)):.1e}",
                f"{cold.cycles[moving].mean():.1f} -> {warm.cycles[moving].mean():.1f}",
                f"{spread:.1e}",
                str(int(np.sum(other.regime.T != warm.regime))),
                f"{np.sum(paper == cold.regime.flat[pick])} / {n_paper}",
                f"{np.sum(paper == warm.regime.flat[pick])} / {n_paper}",
            ]
        )
    names = list(CONFIGS)
    print("\nCPU ms per point (one classify call per panel, balanced); speed-up over the paper")
    print(
        table(
            ["panel", "points", *[f"{n} ms" for n in names], "paper CPU s/pt (n)"]
            + [f"paper / {n}" for n in names],
            timing_rows,
        )
    )
    print("\nper regime class (cold, each class's points in one call): cycles and CPU us per point")
    print(
        table(
            ["panel", "class", "points", "cycles", "us/pt (design)", "us/pt (no design)"]
            + ["us/cycle (design)"],
            class_rows,
        )
    )
    print("\nlabels: warm vs cold on the whole panel, and the paper's method on its sample")
    print(
        table(
            [
                "panel",
                "regime warm = cold",
                "stops warm = cold",
                "max |stick fraction diff|",
                "cycles per moving point cold -> warm",
                "max rel field diff, warm in r order vs beta order",
                "labels differing between the two orders",
                "paper = cold",
                "paper = warm",
            ],
            label_rows,
        )
    )


if __name__ == "__main__":
    main()
