"""An adaptive map's simulated points seeded by solved corners, against the dense grid.

Run from the repository root::

    .venv/bin/python benchmarks/bench_refine_seeded.py --scenes dof3_mass_m2_m3 dof6_ground_m5
    .venv/bin/python benchmarks/bench_refine_seeded.py --code ../main  # another checkout

For each scene of ``bench_adaptive.py --cluster`` (``--scenes``, its names), at
``--size`` (1000 x 500): the dense grid (``tasks.classify``, warm starts, one
call) and the refinement of ``tasks.adaptive.StreamRefinement`` (coarse step 16,
exact hint, no verification sample) run in this process with real simulation:
each point list (``study.adaptive.MIN_LIST`` points, in the order the
refinement hands them out) is classified by ``tasks.classifier.classify_given``
seeded by the orbits of the solved points nearest to its points
(``tasks.orbits``' ``GIVEN_PER_POINT`` per point), as a study does. Prints the
simulated points, the cycles they cost seeded this way against their cycles in
the dense grid (the same points seeded by their grid neighbours) and from the
held start alone (``warm=False``), and the CPU seconds of both maps' ``classify``
calls (``time.process_time``; the refinement's own bookkeeping excluded).
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
sys.path.insert(2, str(REPO / "benchmarks"))

from bench_adaptive import cluster_scenes  # noqa: E402
from bench_warm import table  # noqa: E402

from study.adaptive import MIN_LIST  # noqa: E402
from tasks import Scene, classify  # noqa: E402
from tasks.classifier import classify_given  # noqa: E402
from tasks.orbits import Orbits  # noqa: E402
from tasks.stream import StreamRefinement  # noqa: E402

#: Fields the refinement needs from a point list.
KEYS = ("regime", "converged", "start_dependent", "cycles")


def run(sc: dict, n_r: int, n_beta: int) -> list[object]:
    """One table row: the dense grid and the seeded refinement of scene ``sc``."""
    from analysis.adaptive import closed_form_hint

    scene = Scene(sc["contact"], sc["dof"], sc["cm"], gamma=sc["gamma"], kappa=sc["kappa"])
    r = np.linspace(sc["r_start"], sc["r_stop"], n_r)
    beta = np.linspace(sc["b_start"], sc["b_stop"], n_beta)
    R, B = np.meshgrid(r, beta, indexing="ij")
    classify(scene, R[:1, :3], B[:1, :3])  # compiled / loaded
    t0 = time.process_time()
    dense = classify(scene, R, B)
    dense_s = time.process_time() - t0
    layout = {k: (str(np.asarray(getattr(dense, k)).dtype), 0) for k in KEYS}
    hint = closed_form_hint(scene, r, beta, "exact")
    ref = StreamRefinement((n_r, n_beta), 16, hint, fields=layout)
    orbits = Orbits((n_r, n_beta), 16)
    seeded_s, seeded_cycles, simulated = 0.0, 0.0, []
    while (idx := ref.take(MIN_LIST)).size:
        i_r, i_b = np.unravel_index(idx, ref.shape)
        given = orbits.given(idx, r, beta)
        t0 = time.process_time()
        res, final = classify_given(scene, r[i_r], beta[i_b], given)
        seeded_s += time.process_time() - t0
        orbits.add(idx, final)
        ref.accept(idx, {k: np.asarray(getattr(res, k)) for k in KEYS})
        seeded_cycles += float(res.cycles.sum())
        simulated.append(idx)
    sim = np.concatenate(simulated)
    i_r, i_b = np.unravel_index(sim, ref.shape)
    cold = classify(scene, r[i_r], beta[i_b], warm=False, design=False).cycles.sum()
    cycles = dense.cycles.ravel()
    return [
        sc["name"],
        f"{sim.size:,} ({100 * sim.size / cycles.size:.2f} %)",
        f"{seeded_cycles:,.0f}",
        f"{cycles[sim].sum():,.0f} ({100 * cycles[sim].sum() / cycles.sum():.2f} %)",
        f"{cold:,.0f}",
        f"{seeded_cycles / cycles[sim].sum():.2f}",
        f"{cycles.sum():,.0f}",
        f"{dense_s:.2f} / {seeded_s:.2f} ({dense_s / seeded_s:.1f})",
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="*", default=["dof3_mass_m2_m3", "dof6_ground_m5"])
    parser.add_argument("--size", default="1000x500", help="n_r x n_beta")
    parser.add_argument("--code", default=None, help="import tasks from this checkout instead")
    args = parser.parse_args()
    n_r, n_beta = (int(v) for v in args.size.split("x"))
    rows = [run(sc, n_r, n_beta) for sc in cluster_scenes(args.scenes)]
    header = ["scene", "simulated", "their cycles, seeded by corners"]
    header += ["their cycles in the dense grid (% of its cycles)"]
    header += ["their cycles from the held start"]
    header += ["seeded / dense", "dense grid cycles", "CPU s dense / seeded (ratio)"]
    print(f"{n_r} x {n_beta}, balanced, coarse step 16, exact hint, point lists of {MIN_LIST}")
    print(table(header, rows))


if __name__ == "__main__":
    main()
