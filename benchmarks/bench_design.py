"""Extra cost of the design quantities (amplitudes, contact force, dissipation).

``python benchmarks/bench_design.py [--quick]``: for a few scenes, the time of
``kernel.run_points`` (the classification) and of ``kernel.orbit_designs``
(replaying the converged orbit, sampling and refining its extrema) on the same
grid of points, in one process, compile time excluded. Prints a table with the
ratio (design time / classification time).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from tasks import Scene, kernel
from tasks.classifier import scene_modes_cached, settings_args
from tasks.fidelity import resolve

SCENES = {
    "SDOF ground": Scene("ground", 1),
    "2DOF ground m_1": Scene("ground", 2, 1),
    "2DOF base m_2": Scene("base", 2, 2),
    "2DOF mass contact": Scene("mass", 2, 1),
    "5DOF ground m_4": Scene("ground", 5, 4),
}


def measure(scene: Scene, n_r: int, n_beta: int) -> tuple[float, float, int]:
    r, beta = np.meshgrid(np.linspace(0.05, 2.5, n_r), np.linspace(0.0, 1.5, n_beta))
    r, beta = np.ascontiguousarray(r.ravel()), np.ascontiguousarray(beta.ravel())
    args = settings_args(resolve("balanced"))
    sargs = scene_modes_cached(scene).kernel_args()
    o, f = kernel.run_points(r[:2], beta[:2], sargs, args)  # compile / load
    kernel.orbit_designs(r[:2], beta[:2], sargs, args, o, f, kernel.DESIGN_SAMPLES)
    t0 = time.perf_counter()
    out, final = kernel.run_points(r, beta, sargs, args)
    t1 = time.perf_counter()
    kernel.orbit_designs(r, beta, sargs, args, out, final, kernel.DESIGN_SAMPLES)
    t2 = time.perf_counter()
    return t1 - t0, t2 - t1, r.size


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="40 x 20 points per scene")
    a = parser.parse_args()
    n_r, n_beta = (40, 20) if a.quick else (100, 40)
    print(f"| scene ({n_r} x {n_beta} points) | classify ms/point | design ms/point | ratio |")
    print("|---|---|---|---|")
    for name, scene in SCENES.items():
        t_cls, t_des, n = measure(scene, n_r, n_beta)
        print(f"| {name} | {1e3 * t_cls / n:.3f} | {1e3 * t_des / n:.3f} | {t_des / t_cls:.2f} |")


if __name__ == "__main__":
    main()
