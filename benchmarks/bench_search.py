"""Cost of the event search: per cycle by regime class, and points per second of ``classify``.

Run from the repository root::

    .venv/bin/python benchmarks/bench_search.py --cycles [--quick]   # per cycle, ~2 min
    .venv/bin/python benchmarks/bench_search.py [--repeats 3]        # points per second

``--cycles``: on a 250 x 100 (r, beta) panel (``--quick``: 100 x 40) of Fig. 4
(2DOF, ground contact on m_1, gamma = 1, kappa = 0.5) and of Fig. 10b (5DOF,
ground contact on m_2), ``tasks.kernel.run_points`` (balanced, held start, no
design pass) classifies every point; then every determined point with beta > 0
runs ``--replay`` (20) more periods of its converged orbit, timed per regime
class: CPU microseconds per cycle, mode evaluations per cycle (the work counter
``sc[EVALS]`` of docs/simulator.md 3 without its per-event charge: one unit per
mode per evaluation of a phase) and events per cycle. The classify cost per
point of the whole panel is set against the paper's method
(``tasks.baseline.paper_method``: RK45 + events, 100 cycles from rest) on a
seeded sample of the same points, in the same run. Times are CPU times of this
process (``time.process_time``), so other jobs on a shared machine inflate
neither side. Compare two trees by running the same command in each.

Without ``--cycles``: each row is one scene and preset on a fixed sample
(seeded): a dense low-r grid (r in [0.05, 0.4], beta up to past the no-motion
bound) and a random full-range sample (r in [0.05, 2.5], beta in [0, 1.2]);
best of ``--repeats`` wall times after a warm-up call (compile / cache load
excluded).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tasks import Scene, classify, kernel  # noqa: E402
from tasks.baseline import paper_method  # noqa: E402
from tasks.classifier import settings_args  # noqa: E402
from tasks.fidelity import resolve  # noqa: E402
from tasks.kernel.context import _context  # noqa: E402
from tasks.kernel.cycle import EVENT_WORK, _cycle  # noqa: E402
from tasks.kernel.layout import (  # noqa: E402
    CTX_SC,
    EVALS,
    N_STATS,
    OUT_CYCLES,
    OUT_REGIME,
    ST_EVENTS,
    WORK_CAP,
)
from tasks.model import scene_modes  # noqa: E402
from tasks.regimes import CONTINUOUS, NO_MOTION, STICK_SLIP  # noqa: E402

SCENES = {
    "sdof_ground": Scene("ground", 1),
    "2dof_ground_m1": Scene("ground", 2, 1),
    "2dof_base_m1": Scene("base", 2, 1),
    "2dof_mass": Scene("mass", 2, 1),
    "5dof_ground_m3": Scene("ground", 5, 3, gamma=[1.5, 0.7, 1.2, 0.9], kappa=[0.8, 1.3, 1.0, 0.6]),
}
#: Panels of the per-cycle table: scene and the largest beta (r in [0.02, 2.5]).
PANELS = {
    "Fig. 4 (2DOF, m_1, gamma 1, kappa 0.5)": (Scene("ground", 2, 1, gamma=1.0, kappa=0.5), 1.5),
    "Fig. 10b (5DOF, m_2)": (Scene("ground", 5, 2), 2.0),
}
CLASSES = {"continuous": CONTINUOUS, "stick-slip": STICK_SLIP, "no motion": NO_MOTION}
SEED = 19


@njit(cache=False)
def replay(r, beta, scene, settings, final, n_cycles):
    """Run ``n_cycles`` periods of each point's converged orbit (``final`` of
    ``run_points``); returns the work units and events of all of them."""
    n = scene[0].shape[0]
    work_units = 0.0
    events = 0.0
    for i in range(r.shape[0]):
        ctx, work, _, _, _ = _context(r[i], beta[i], scene, settings)
        sc = ctx[CTX_SC]
        sc[WORK_CAP] = np.inf
        X = final[i, : 2 * n].copy()
        mode = int(final[i, 2 * n])
        theta = final[i, 2 * n + 1]
        stats = np.zeros(N_STATS)
        stick_start = theta
        for _ in range(n_cycles):
            X, mode, stick_start = _cycle(X, mode, stick_start, stats, ctx, work, theta)
            events += stats[ST_EVENTS]
        work_units += sc[EVALS]
    return work_units, events


def per_cycle(quick: bool, n_replay: int, paper_points: int) -> None:
    nr, nb = (100, 40) if quick else (250, 100)
    settings = settings_args(resolve("balanced"))
    print(f"Per cycle: {nr} x {nb} panels, balanced, held start; CPU time of this process\n")
    print(
        "| panel | class | points | us / cycle | mode evaluations / cycle | events / cycle |"
        " classify cycles / point |"
    )
    print("|---|---|---|---|---|---|---|")
    ratios = []
    for name, (scene, beta_max) in PANELS.items():
        r, beta = np.meshgrid(np.linspace(0.02, 2.5, nr), np.linspace(0.0, beta_max, nb))
        r, beta = r.ravel(), beta.ravel()
        args = scene_modes(scene).kernel_args()
        n = scene.dof
        c0 = time.process_time()
        out, final = kernel.run_points(r, beta, args, settings)
        classify_s = time.process_time() - c0
        for label, code in CLASSES.items():
            sel = (out[:, OUT_REGIME] == code) & (beta > 0.0)
            if not sel.any():
                continue
            rs, bs, fs = r[sel].copy(), beta[sel].copy(), final[sel].copy()
            replay(rs[:1], bs[:1], args, settings, fs[:1], 1)  # compile first
            c0 = time.process_time()
            base_units, _ = replay(rs, bs, args, settings, fs, 0)  # contexts alone
            c1 = time.process_time()
            units, events = replay(rs, bs, args, settings, fs, n_replay)
            c2 = time.process_time()
            cycles = sel.sum() * n_replay
            us = 1e6 * ((c2 - c1) - (c1 - c0)) / cycles
            evals = (units - base_units - EVENT_WORK * n * n * events) / cycles
            mean_cycles = out[sel, OUT_CYCLES].mean()
            print(
                f"| {name} | {label} | {sel.sum()} | {us:.2f} | {evals:.0f} | "
                f"{events / cycles:.2f} | {mean_cycles:.1f} |",
                flush=True,
            )
        rng = np.random.default_rng(SEED)
        pick = rng.choice(r.size, paper_points, replace=False)
        c0 = time.process_time()
        for i in pick:
            paper_method(scene, float(r[i]), float(beta[i]))
        paper_s = (time.process_time() - c0) / paper_points
        ours = classify_s / r.size
        ratios.append((name, ours, 1e6 * classify_s / out[:, OUT_CYCLES].sum(), paper_s))
    print(
        "\n| panel | classify ms / point (whole panel) | classify us / cycle (all its cycles) |"
        " paper's method ms / point | speed-up |"
    )
    print("|---|---|---|---|---|")
    for name, ours, us_cycle, paper_s in ratios:
        print(
            f"| {name} | {1e3 * ours:.3f} | {us_cycle:.1f} | {1e3 * paper_s:.0f} | "
            f"{paper_s / ours:.0f} |"
        )


def samples() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(20210406)
    r_low, b_low = np.meshgrid(np.linspace(0.05, 0.4, 30), np.geomspace(1e-3, 1.2, 10))
    r_all = rng.uniform(0.05, 2.5, 300)
    b_all = rng.uniform(0.0, 1.2, 300)
    return {"low_r": (r_low.ravel(), b_low.ravel()), "full": (r_all, b_all)}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--presets", default="fast,balanced,exact")
    ap.add_argument("--cycles", action="store_true", help="the per-cycle table by regime class")
    ap.add_argument("--quick", action="store_true", help="--cycles on 100 x 40 panels")
    ap.add_argument("--replay", type=int, default=20, help="periods replayed per point")
    ap.add_argument("--paper-points", type=int, default=8, help="paper's method sample per panel")
    args = ap.parse_args()
    if args.cycles:
        classify(SCENES["sdof_ground"], 0.3, 0.1)  # compile / load the cache
        per_cycle(args.quick, args.replay, args.paper_points)
        return
    classify(SCENES["sdof_ground"], 0.3, 0.1)  # compile / load the cache
    print("| scene | sample | preset | points | best s | points/s |")
    print("|---|---|---|---|---|---|")
    for name, scene in SCENES.items():
        for sample, (r, beta) in samples().items():
            for fid in args.presets.split(","):
                best = np.inf
                for _ in range(args.repeats):
                    t0 = time.perf_counter()
                    classify(scene, r, beta, fidelity=fid)
                    best = min(best, time.perf_counter() - t0)
                print(
                    f"| {name} | {sample} | {fid} | {r.size} | {best:.3f} | {r.size / best:.0f} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
