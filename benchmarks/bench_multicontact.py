"""Cost of a two-contact map against the one-contact map of the same chain (same run).

A 2DOF ground-fixed chain (gamma = kappa = 1): one contact on m1 (the single-
contact kernel) against a contact on each mass (beta_ratio 1 and 0.5,
tasks.multicontact), on the same grid of r x beta, each timed after a warm-up
(compiled code loaded), in CPU seconds (the simulators run on one thread). Prints
the table and the ratio; the target is at most 3.

    python benchmarks/bench_multicontact.py [n_r n_beta]     (default 250 100)
"""

from __future__ import annotations

import sys
import time

import numpy as np

from tasks import Scene, classify


def main(n_r: int = 250, n_beta: int = 100) -> None:
    r, beta = np.meshgrid(np.linspace(0.2, 3.0, n_r), np.linspace(0.02, 1.5, n_beta), indexing="ij")
    one = Scene("ground", 2, 1)
    two = Scene("ground", 2, contact_mass=[1, 2], beta_ratio=[1.0, 0.5])
    classify(one, r[:2, :2], beta[:2, :2])
    classify(two, r[:2, :2], beta[:2, :2])
    rows = []
    for name, scene in (("one contact (m1)", one), ("two contacts (m1, m2)", two)):
        t0 = time.process_time()
        res = classify(scene, r, beta)
        dt = time.process_time() - t0
        rows.append((name, dt, float(np.mean(res.converged))))
    print(f"map {n_r} x {n_beta} = {r.size} points, 2DOF ground chain, fidelity balanced")
    print(f"{'scene':<24}{'CPU s':>10}{'ms/point':>10}{'converged':>11}")
    for name, dt, conv in rows:
        print(f"{name:<24}{dt:>10.2f}{1e3 * dt / r.size:>10.3f}{conv:>11.4f}")
    print(f"ratio two / one: {rows[1][1] / rows[0][1]:.2f} (target <= 3)")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
