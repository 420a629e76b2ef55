"""Per-contact regimes of the several-contact simulator against the independent
reference (tasks.multicontact.reference) on a fresh seeded draw of scenes and points.

Scenes: chains (walls, walls and a contact between masses, a base-excited chain)
and random symmetric positive definite M, K (2, 3 and 4 DOF, up to three
contacts), random beta_ratio; points r = w1 U(0.1, 2.5) (w1 the lowest natural
frequency of the free structure), beta U(0.02, 1.2). The simulator runs at the
default fidelity (balanced) from the held start; the reference from the same
start. Prints per scene the regimes compared and agreeing, every difference,
and the CPU time of each side.

    python benchmarks/bench_multicontact_reference.py [points_per_scene]   (default 25)
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np
from scipy.linalg import eigh

from tasks.multicontact import MultiScene, classify_multi
from tasks.multicontact.reference import agreement, random_structure

SEED = 2026


def scenes(rng: np.random.Generator) -> list[tuple[str, MultiScene]]:
    def ratio(k):
        return list(rng.uniform(0.3, 1.5, k))

    def gk(n):
        return list(rng.uniform(0.5, 2.0, n - 1)), list(rng.uniform(0.5, 2.0, n - 1))

    out = []
    g, kp = gk(2)
    out.append(("chain 2dof walls m1 m2", MultiScene.chain("ground", 2, [1, 2], g, kp, ratio(2))))
    g, kp = gk(3)
    out.append(
        (
            "chain 3dof wall m1, m2-m3",
            MultiScene.chain(["ground", "mass"], 3, [1, 2], g, kp, ratio(2)),
        )
    )
    g, kp = gk(3)
    out.append(("chain 3dof base m1 m3", MultiScene.chain("base", 3, [1, 3], g, kp, ratio(2))))
    M, K, p = random_structure(rng, 2)
    out.append(
        (
            "random 2dof x0 x1",
            MultiScene.from_matrices(M, K, p, [("ground", 0), ("ground", 1)], beta_ratio=ratio(2)),
        )
    )
    M, K, p = random_structure(rng, 3)
    out.append(
        (
            "random 3dof x0, x1-x2",
            MultiScene.from_matrices(
                M, K, p, [("ground", 0), ("between", 1, 2)], beta_ratio=ratio(2)
            ),
        )
    )
    M, K, p = random_structure(rng, 4)
    out.append(
        (
            "random 4dof x0, x1-x2, x3",
            MultiScene.from_matrices(
                M, K, p, [("ground", 0), ("between", 1, 2), ("ground", 3)], beta_ratio=ratio(3)
            ),
        )
    )
    return out


def main(per_scene: int = 25) -> None:
    rng = np.random.default_rng(SEED)
    total_c = total_a = 0
    rows = []
    all_misses = []
    for name, scene in scenes(rng):
        G, K = scene.mass_matrix(1.0), scene.stiffness_matrix()
        w1 = math.sqrt(eigh(K, G, eigvals_only=True).min())
        r = w1 * rng.uniform(0.1, 2.5, per_scene)
        beta = rng.uniform(0.02, 1.2, per_scene)
        t0 = time.process_time()
        res = classify_multi(scene, r, beta)
        t_sim = time.process_time() - t0
        t0 = time.process_time()
        compared, agreed, misses, unconv = agreement(scene, r, beta, res.regime, res.converged)
        t_ref = time.process_time() - t0
        rows.append((name, per_scene, int((~res.converged).sum()), unconv, compared, agreed))
        rows[-1] += (t_sim, t_ref)
        all_misses += [(name, *m) for m in misses]
        total_c += compared
        total_a += agreed
    print(f"seed {SEED}, {per_scene} points per scene, simulator fidelity balanced, held start")
    head = f"{'scene':<28}{'points':>7}{'sim nc':>7}{'ref nc':>7}{'compared':>9}{'agree':>7}"
    print(head + f"{'sim s':>8}{'ref s':>8}")
    for name, pts, snc, rnc, comp, agr, ts, tr in rows:
        print(f"{name:<28}{pts:>7}{snc:>7}{rnc:>7}{comp:>9}{agr:>7}{ts:>8.2f}{tr:>8.1f}")
    print(
        f"per-contact regimes agreeing: {total_a} / {total_c} ({100.0 * total_a / total_c:.2f} %)"
    )
    for name, r, beta, c, sim, ref in all_misses:
        where = f"{name} r={r:.6g} beta={beta:.6g} contact {c}"
        print(f"  differs: {where}: simulator {sim}, reference {ref}")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:2]))
