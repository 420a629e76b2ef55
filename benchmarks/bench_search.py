"""Cost of the event search: points per second of ``classify`` on low-r and full-range samples.

Run the same file in two trees to compare (e.g. before / after a kernel change)::

    .venv/bin/python benchmarks/bench_search.py [--repeats 3]

Each row: one scene and preset on a fixed sample (seeded): a dense low-r grid
(r in [0.05, 0.4], beta up to past the no-motion bound) and a random full-range
sample (r in [0.05, 2.5], beta in [0, 1.2]); best of ``--repeats`` wall times
after a warm-up call (compile / cache load excluded).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tasks import Scene, classify  # noqa: E402

SCENES = {
    "sdof_ground": Scene("ground", 1),
    "2dof_ground_m1": Scene("ground", 2, 1),
    "2dof_base_m1": Scene("base", 2, 1),
    "2dof_mass": Scene("mass", 2, 1),
    "5dof_ground_m3": Scene("ground", 5, 3, gamma=[1.5, 0.7, 1.2, 0.9], kappa=[0.8, 1.3, 1.0, 0.6]),
}


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
    args = ap.parse_args()
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
