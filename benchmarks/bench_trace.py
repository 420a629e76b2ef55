"""Boundary tracing vs a dense beta grid that resolves the same tolerance.

For each scene, the numerical boundaries along r are found (a) by
``tasks.trace.trace_boundaries`` (bisection to an absolute tolerance ``step``
in beta, with and without the closed-form starting guesses) and (b) from a
dense uniform beta column per r with that step. Prints, per scene and method:
points simulated, seconds, and the largest difference between the traced and
the dense boundaries in units of the step (both locate a boundary to within
half a step of the truth, so agreement means a difference of at most 1).

    python benchmarks/bench_trace.py            # ~1-2 min on one core
    python benchmarks/bench_trace.py --quick
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from analysis import boundaries
from study.bench import machine
from tasks import Scene, classify, regimes
from tasks.trace import trace_boundaries

SCENES = {
    "2dof ground m1": Scene("ground", 2, 1),
    "2dof mass": Scene("mass", 2, 1),
    "sdof base": Scene("base", 1),
}


def dense_boundaries(scene, r, beta):
    """First transitions of a dense column: continuous -> other, moving -> no motion (top run)."""
    R, B = np.meshgrid(r, beta, indexing="ij")
    reg = classify(scene, R, B).regime
    bc = np.full(r.size, np.nan)
    bm = np.full(r.size, np.nan)
    undetermined = 0
    for i in range(r.size):
        ok = reg[i] >= 0  # undetermined points (slow, right at a boundary) are skipped
        undetermined += int((~ok).sum())
        col, b = reg[i][ok], beta[ok]
        not_cont = np.flatnonzero(col != regimes.CONTINUOUS)
        if not_cont.size and not_cont[0] > 0:
            bc[i] = 0.5 * (b[not_cont[0] - 1] + b[not_cont[0]])
        moving = np.flatnonzero(col != regimes.NO_MOTION)
        if moving.size and moving[-1] + 1 < b.size:
            bm[i] = 0.5 * (b[moving[-1]] + b[moving[-1] + 1])
    return bc, bm, reg.size, undetermined


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    n_r = 8 if args.quick else 24
    step = 4e-3 if args.quick else 1e-3
    classify(Scene("ground", 1), 1.3, 0.2)  # compile outside the timings
    print("| machine | |\n|---|---|")
    for key, value in machine().items():
        print(f"| {key} | {value} |")
    print("\none process")
    print(f"tolerance: beta step {step:g}, {n_r} values of r per scene\n")
    print("| scene | method | points | seconds | max diff / grid step (cont., motion) |")
    print("|---|---|---|---|---|")
    for name, scene in SCENES.items():
        r = np.linspace(0.35, 2.4, n_r)
        gc, gm = boundaries(scene, r, method="exact")
        finite = np.where(np.isfinite(gm), gm, np.nan)
        top = min(1.25 * float(np.nanmax(np.concatenate([finite, gc]))), 3.0)
        beta = np.arange(0.0, top + step, step)
        t0 = time.perf_counter()
        dc, dm, n_dense, n_undet = dense_boundaries(scene, r, beta)
        t_dense = time.perf_counter() - t0
        rows = [(f"dense grid ({n_undet} undetermined)", n_dense, t_dense, dc, dm)]
        for label, guesses in (
            ("trace, closed-form start", (gc, gm)),
            ("trace, blind", (None, None)),
        ):
            t0 = time.perf_counter()
            tr = trace_boundaries(scene, r, (0.0, top), *guesses, rtol=1e-12, atol=step / 2)
            rows.append(
                (
                    label,
                    int(tr.points.sum()),
                    time.perf_counter() - t0,
                    tr.beta_continuous,
                    tr.beta_motion,
                )
            )
        for label, points, seconds, bc, bm in rows:
            dev_c = np.nanmax(np.abs(bc - dc)) / step
            dev_m = np.nanmax(np.abs(bm - dm)) / step if np.isfinite(dm).any() else float("nan")
            print(f"| {name} | {label} | {points:,} | {seconds:.2f} | {dev_c:.2f}, {dev_m:.2f} |")


if __name__ == "__main__":
    main()
