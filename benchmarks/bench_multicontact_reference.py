"""Per-contact regimes of the several-contact simulator against the independent
reference (tasks.multicontact.reference) on a fresh seeded draw of scenes and points.

Scenes and points: tasks.multicontact.reference.draw_scenes and draw_points
(chains with walls, a contact between masses, base excitation; random full M, K
of 2, 3 and 4 DOF with up to three contacts; r = w1 U(0.1, 2.5), beta
U(0.02, 1.2)). The simulator runs at the default fidelity (balanced) from the
held start; the reference from the same start. Prints per scene the regimes
compared and agreeing, every difference, and the CPU time of each side.

    python benchmarks/bench_multicontact_reference.py [points_per_scene]   (default 25)
    python benchmarks/bench_multicontact_reference.py 6 --damped

``--damped`` gives every scene of the draw Rayleigh damping C = 0.03 M + 0.01 K
(docs/contacts.md 7; the reference then integrates the damped state space).
"""

from __future__ import annotations

import sys
import time

from tasks.multicontact import MultiScene, classify_multi
from tasks.multicontact.reference import DRAW_SEED, agreement, draw_points, draw_scenes

#: The damping of ``--damped``.
DAMPING = ("rayleigh", 0.03, 0.01)


def damped(scene: MultiScene) -> MultiScene:
    """``scene`` with :data:`DAMPING`."""
    kw = scene.structures[0].kwargs()
    return MultiScene.from_matrices(
        kw["mass"], kw["stiffness"], kw["load"], list(scene.contacts),
        beta_ratio=list(scene.beta_ratio), damping=DAMPING,
    )  # fmt: skip


def main(per_scene: int = 25, with_damping: bool = False) -> None:
    total_c = total_a = 0
    rows = []
    all_misses = []
    for index, (name, scene) in enumerate(draw_scenes()):
        if with_damping:
            scene = damped(scene)
        r, beta = draw_points(scene, index, per_scene)
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
    print(
        f"seed {DRAW_SEED}, {per_scene} points per scene, simulator fidelity balanced, held start"
        + (f", damping {DAMPING}" if with_damping else "")
    )
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
    counts = [int(a) for a in sys.argv[1:] if a.isdigit()][:1]
    main(*counts, with_damping="--damped" in sys.argv)
