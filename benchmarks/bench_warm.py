"""Every paper figure example's dense panels: defaults, design pass, cold starts, the paper.

Run from the repository root (at low priority on a shared machine)::

    nice -n 10 .venv/bin/python benchmarks/bench_warm.py          # 23 panels of 250 x 100, ~10 min
    .venv/bin/python benchmarks/bench_warm.py --quick             # 100 x 40 panels, ~2 min
    .venv/bin/python benchmarks/bench_warm.py --only fig04 fig10b # some figure files only
    .venv/bin/python benchmarks/bench_warm.py --detail            # + per regime class, two panels
    .venv/bin/python benchmarks/bench_warm.py --quick --code ../main  # another checkout's tasks/

Panels: EVERY scene of ``examples/fig03.toml`` ... ``fig17.toml`` (23 panels: one
each for Figs. 3, 10a and 10b, four (gamma, kappa) pairs for Figs. 4, 5, 14, 15
and 17), read from the files themselves (contact, dof, contact mass, gamma, kappa,
the r and beta ranges) at 250 x 100 points, the examples' own resolution. All
panels, not one per figure: a panel costs a few CPU seconds per configuration, and
the four panels of one figure differ in cost by up to 1.5 times.

Per panel, in one process, one ``tasks.classify`` call per configuration (balanced,
the points in a study's order: r outer, beta inner), compiled beforehand:

- **default**: warm starts, no design pass (``classify``'s defaults; timed twice,
  before and after the others, the lesser CPU time kept);
- **design**: warm starts and ``design=True`` (the design quantities);
- **cold**: ``warm=False``, every point from the held start, no design pass: the
  labels of the search without seeds, the reference for "warm = cold".

The paper's method (``tasks.baseline.paper_method``: scipy RK45 + events, 100
cycles from rest) runs on a seeded sample of each panel's points (``--paper-points``,
default 16 per panel, 368 in all; its cost per point varies 0.1-1 s with the
point, so a panel's own ratio is indicative and the ratio over all panels, mean
time against mean time, is the figure to quote). Labels: regime and stops of the
default equal the cold run's point for point, and the design run's (the design pass
changes no label); the paper's labels are compared on its sample (100 cycles from
rest do not reach the steady state of slow points). Times are CPU times of this
process (``time.process_time``; both sides single-threaded), so that other
processes on a shared machine inflate neither. Prints Markdown tables.

``--detail`` adds the earlier per-class table (cycles and cost of each regime
class, cold) and the check that another grouping of the points (beta outer)
gives every field to the polish, on Fig. 4 (1, 0.5) and Fig. 10b.
"""

from __future__ import annotations

import argparse
import sys
import time
import tomllib
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

FIGURES = ("fig03", "fig04", "fig05", "fig10a", "fig10b", "fig14", "fig15", "fig17")
CONFIGS = {
    "default": {"warm": True, "design": False},
    "design": {"warm": True, "design": True},
    "cold": {"warm": False, "design": False},
}
SEED = 19
CLASSES = {0: "no motion", 1: "stick-slip", 2: "continuous"}
#: The two panels of ``--detail`` (the ones measured before every panel was).
DETAIL = ("fig04:gamma1_kappa0.5", "fig10b:5dof_ground_m2")
#: Fields compared between two groupings (relative to their largest value on the panel).
CONTINUOUS = ("slip_amplitude", "stick_fraction", "amplitude", "contact_force_amplitude")
CONTINUOUS += ("dissipation",)


def panels(figures: tuple[str, ...], size: tuple[int, int] | None) -> list[tuple]:
    """(figure, scene name, Scene, r axis, beta axis) of every scene of the figure
    files, at ``size`` (n_r, n_beta) or the file's own resolution."""
    out = []
    for fig in figures:
        data = tomllib.loads((REPO / "examples" / f"{fig}.toml").read_text(encoding="utf-8"))
        for s in data["scene"]:
            ratios = {k: s[k] for k in ("gamma", "kappa") if k in s}
            scene = Scene(s["contact"], s["dof"], s.get("contact_mass", 1), **ratios)
            axes = []
            for name, n in zip(("r", "beta"), size or (None, None), strict=True):
                ax = s[name]
                axes.append(np.linspace(ax["start"], ax["stop"], n or ax["num"]))
            out.append((fig, s["name"], scene, *axes))
    return out


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    """Largest difference relative to the largest magnitude (inf if NaN at other points)."""
    if not np.array_equal(np.isfinite(a), np.isfinite(b)):
        return np.inf
    fin = np.isfinite(a)
    return float(np.max(np.abs(a[fin] - b[fin]), initial=0.0) / max(np.abs(a[fin]).max(), 1e-300))


def table(header: list[str], rows: list[list[object]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    return "\n".join(lines + ["| " + " | ".join(str(c) for c in row) + " |" for row in rows])


def cpu_per_point(scene: Scene, r: np.ndarray, beta: np.ndarray, **kw):
    """The result of one call and its CPU seconds per point."""
    t0 = time.process_time()
    res = classify(scene, r, beta, **kw)
    return res, (time.process_time() - t0) / r.size


def measure(scene: Scene, r: np.ndarray, beta: np.ndarray, n_paper: int, seed: int) -> dict:
    """Every configuration on one panel, the paper's method on its sample."""
    results, cost = {}, {}
    for name in [*CONFIGS, "default"]:  # the default before and after the others
        res, cpu = cpu_per_point(scene, r, beta, **CONFIGS[name])
        results[name] = res
        cost[name] = min(cost.get(name, np.inf), cpu)
    pick = np.random.default_rng(seed).choice(r.size, n_paper, replace=False)
    t0 = time.process_time()
    paper = np.array([paper_method(scene, r.flat[i], beta.flat[i])[0] for i in pick])
    return {
        "results": results,
        "cost": cost,
        "paper_cpu": time.process_time() - t0,
        "paper_agree": int(np.sum(paper == results["cold"].regime.flat[pick])),
    }


def detail(scene: Scene, r: np.ndarray, beta: np.ndarray, title: str) -> tuple[list, list]:
    """Per regime class (cold, each class's points in one call) and another grouping."""
    cold = classify(scene, r, beta, warm=False)
    class_rows = []
    for code, klass in CLASSES.items():
        m = cold.regime == code
        if not m.any():
            continue
        cost = [cpu_per_point(scene, r[m], beta[m], warm=False, design=d)[1] for d in (True, False)]
        cycles = cold.cycles[m].mean()
        class_rows.append(
            [title, klass, int(m.sum()), f"{cycles:.1f}"]
            + [f"{c * 1e6:.0f}" for c in cost]
            + [f"{cost[0] * 1e6 / max(cycles, 1.0):.1f}"]
        )
    warm = classify(scene, r, beta, design=True)
    other = classify(scene, r.T, beta.T, design=True)  # beta outer, r inner: other seeds
    spread = max(_rel(getattr(warm, f), np.swapaxes(getattr(other, f), 0, 1)) for f in CONTINUOUS)
    moving = cold.regime > 0
    grouping = [
        title,
        f"{cold.cycles[moving].mean():.1f} -> {warm.cycles[moving].mean():.1f}",
        f"{spread:.1e}",
        str(int(np.sum(other.regime.T != warm.regime))),
    ]
    return class_rows, [grouping]


def summary_row(title: str, size: str, t: dict) -> list[str]:
    """A row of the main table from CPU totals (seconds) and counts."""
    cost = {n: t[f"cpu_{n}"] / t["points"] for n in CONFIGS}
    paper_s = t["paper_cpu"] / t["paper_n"]
    return (
        [title, size]
        + [f"{cost[n] * 1e3:.3f}" for n in CONFIGS]
        + [f"{paper_s * 1e3:.0f}"]
        + [f"{paper_s / cost[n]:.0f}x" for n in CONFIGS]
        + [f"{cost['design'] / cost['default'] - 1:.0%}"]
        + [f"{t[k]} / {t['points']}" for k in ("same", "same_design")]
        + [f"{t['agree']} / {t['paper_n']}"]
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="100 x 40 panels, 4 paper points")
    parser.add_argument("--paper-points", type=int, default=None, help="paper sample per panel")
    parser.add_argument("--only", nargs="+", choices=FIGURES, help="these figure files only")
    parser.add_argument("--detail", action="store_true", help="per class, two panels")
    parser.add_argument("--code", default=None, help="import tasks from this checkout instead")
    args = parser.parse_args()
    size = (100, 40) if args.quick else None
    n_paper = args.paper_points or (4 if args.quick else 16)
    print("machine: " + "; ".join(f"{k} {v}" for k, v in machine().items()))
    classify(Scene("ground", 2), [0.5, 1.5], [0.1, 0.6])  # compile / load
    classify(Scene("ground", 2), [0.5, 1.5], [0.1, 0.6], design=True)
    rows, totals = [], {"points": 0, "paper_cpu": 0.0, "paper_n": 0, "agree": 0}
    totals |= {"same": 0, "same_design": 0} | {f"cpu_{n}": 0.0 for n in CONFIGS}
    start = time.perf_counter()
    todo = panels(tuple(args.only or FIGURES), size)
    for k, (fig, name, scene, r_axis, beta_axis) in enumerate(todo):
        r, beta = np.meshgrid(r_axis, beta_axis, indexing="ij")
        m = measure(scene, r, beta, n_paper, SEED + k)
        default = m["results"]["default"]
        panel = {"points": r.size, "paper_cpu": m["paper_cpu"], "paper_n": n_paper}
        panel |= {"agree": m["paper_agree"]}
        panel |= {f"cpu_{n}": m["cost"][n] * r.size for n in CONFIGS}
        for key, other in (("same", "cold"), ("same_design", "design")):
            x = m["results"][other]
            same = (default.regime == x.regime) & (default.stops_per_cycle == x.stops_per_cycle)
            panel[key] = int(same.sum())
        rows.append(summary_row(f"{fig}:{name}", f"{r.shape[0]} x {r.shape[1]}", panel))
        totals = {key: totals[key] + panel[key] for key in totals}
        print(f"[{time.perf_counter() - start:.0f} s] {fig}:{name} done", file=sys.stderr)
    rows.append(summary_row(f"all {len(todo)} panels", f"{totals['points']:,}", totals))
    print("\nCPU ms per point (one classify call per panel, balanced); paper's method on a sample")
    print(
        table(
            ["panel", "points", "default (warm, no design) ms", "design=True ms", "cold ms"]
            + ["paper ms", "paper / default", "paper / design", "paper / cold"]
            + ["design pass adds", "labels default = cold", "labels default = design"]
            + ["paper = cold (sample)"],
            rows,
        )
    )
    print(f"\n(wall {time.perf_counter() - start:.0f} s)")
    if args.detail:
        class_rows, group_rows = [], []
        for fig, name, scene, r_axis, beta_axis in panels(("fig04", "fig10b"), size):
            if f"{fig}:{name}" in DETAIL:
                r, beta = np.meshgrid(r_axis, beta_axis, indexing="ij")
                c, g = detail(scene, r, beta, f"{fig}:{name}")
                class_rows += c
                group_rows += g
        print("\nper regime class (cold, each class's points in one call): cycles, CPU us/point")
        print(
            table(
                ["panel", "class", "points", "cycles", "us/pt (design)", "us/pt (no design)"]
                + ["us/cycle (design)"],
                class_rows,
            )
        )
        print("\nwarm starts: cycles per moving point, and another grouping (beta outer)")
        print(
            table(
                ["panel", "cycles per moving point cold -> warm", "max rel field diff"]
                + ["labels differing between the two orders"],
                group_rows,
            )
        )


if __name__ == "__main__":
    main()
