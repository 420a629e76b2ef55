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

``--tiles``: the path a study takes first (``study.tiles``): the plane cut into
the tiles of two worker threads (``study.tiles.tile_layout``), each refined by
``tasks.tiles.refine_tile`` (every round's ready points in one call, seeded by
the tile's orbits). Prints the same columns, and where the excess lies: the
coarse lattice's cycles seeded / dense, and the points costing more than
``OUTLIER`` periods over their dense cost (count, their share of the excess):

    .venv/bin/python benchmarks/bench_refine_seeded.py --tiles --cache .bench_adaptive_cache

``--cache DIR`` keeps each scene's dense cycles (computed once, then read; the
dense CPU seconds are those of the run that computed them).
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
if not (Path(_CODE) / "tasks" / "__init__.py").is_file():  # else this checkout's, silently
    print(f"bench_refine_seeded.py: error: --code: {_CODE} holds no tasks package", file=sys.stderr)
    sys.exit(2)
sys.path.insert(0, _CODE)
sys.path.insert(1, str(REPO))
sys.path.insert(2, str(REPO / "benchmarks"))

from bench_adaptive import cluster_scenes  # noqa: E402
from bench_warm import table  # noqa: E402

from study.adaptive import MIN_LIST  # noqa: E402
from study.tiles import tile_layout  # noqa: E402
from tasks import Scene, classify  # noqa: E402
from tasks.classifier import classify_given  # noqa: E402
from tasks.orbits import Orbits  # noqa: E402
from tasks.stream import StreamRefinement  # noqa: E402
from tasks.tiles import refine_tile  # noqa: E402

#: Fields the refinement needs from a point list.
KEYS = ("regime", "converged", "start_dependent", "cycles")
#: ``--tiles``: a simulated point costing more than this many periods over its dense
#: cost is counted apart (no solved neighbour seeded it: the held start settled it).
OUTLIER = 10


def dense_grid(sc: dict, scene, r, beta, cache: Path | None) -> tuple[np.ndarray, float]:
    """The dense grid's cycles (flat) and CPU seconds, from ``cache`` where saved."""
    path = None
    if cache is not None:
        path = cache / f"refine_seeded_{sc['name']}_{r.size}x{beta.size}.npz"
        if path.exists():
            with np.load(path) as saved:
                return saved["cycles"], float(saved["cpu"])
    R, B = np.meshgrid(r, beta, indexing="ij")
    t0 = time.process_time()
    cycles = np.asarray(classify(scene, R, B).cycles, dtype=float).ravel()
    cpu = time.process_time() - t0
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, cycles=cycles, cpu=cpu)
    return cycles, cpu


def run(sc: dict, n_r: int, n_beta: int, tiles: bool, cache: Path | None) -> list[object]:
    """One table row: the dense grid and the seeded refinement of scene ``sc``."""
    from analysis.adaptive import closed_form_hint

    scene = Scene(sc["contact"], sc["dof"], sc["cm"], gamma=sc["gamma"], kappa=sc["kappa"])
    r = np.linspace(sc["r_start"], sc["r_stop"], n_r)
    beta = np.linspace(sc["b_start"], sc["b_stop"], n_beta)
    small = classify(scene, r[:3], beta[1:4])  # compiled / loaded
    classify_given(scene, r[:3], beta[1:4], None)
    cycles, dense_s = dense_grid(sc, scene, r, beta, cache)
    hint = closed_form_hint(scene, r, beta, "exact")
    if tiles:
        return tiled(sc, scene, r, beta, hint, cycles, dense_s)
    layout = {k: (str(np.asarray(getattr(small, k)).dtype), 0) for k in KEYS}
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


def tiled(sc: dict, scene, r, beta, hint, cycles, dense_s) -> list[object]:
    """The ``--tiles`` row of scene ``sc`` (``cycles``: the dense grid's, flat)."""
    n_r, n_beta = r.size, beta.size
    cpu = [0.0]

    def simulate(rr: np.ndarray, bb: np.ndarray, given: tuple) -> dict[str, np.ndarray]:
        t0 = time.process_time()
        res, final = classify_given(scene, rr, bb, given)
        cpu[0] += time.process_time() - t0
        return {k: np.asarray(getattr(res, k)) for k in KEYS} | {"final": final}

    sims, spent = [], []
    for i0, i1 in tile_layout(n_r, 16, 2):  # a point on two tiles' shared row counts twice
        idx, arrays, _ = refine_tile(simulate, r[i0 : i1 + 1], beta, 16, hint[i0 : i1 + 1])
        sims.append(idx + i0 * n_beta)
        spent.append(np.asarray(arrays["cycles"], dtype=float))
    sim, seeded = np.concatenate(sims), np.concatenate(spent)
    i_r, i_b = np.unravel_index(sim, (n_r, n_beta))
    cold = classify(scene, r[i_r], beta[i_b], warm=False).cycles.sum()
    dense = cycles[sim]
    coarse = (i_r % 16 == 0) & (i_b % 16 == 0)  # (the lattice's last nodes aside)
    excess = seeded - dense
    out = excess > OUTLIER
    return [
        sc["name"],
        f"{sim.size:,} ({100 * sim.size / cycles.size:.2f} %)",
        f"{seeded.sum():,.0f}",
        f"{dense.sum():,.0f} ({100 * dense.sum() / cycles.sum():.2f} %)",
        f"{cold:,.0f}",
        f"{seeded.sum() / dense.sum():.2f}",
        f"{seeded[coarse].sum() / dense[coarse].sum():.2f}",
        f"{out.sum():,} ({100 * excess[out].sum() / max(excess.sum(), 1):.0f} %)",
        f"{cycles.sum():,.0f}",
        f"{dense_s:.2f} / {cpu[0]:.2f} ({dense_s / cpu[0]:.1f})",
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="*", default=["dof3_mass_m2_m3", "dof6_ground_m5"])
    parser.add_argument("--size", default="1000x500", help="n_r x n_beta")
    parser.add_argument("--code", default=None, help="import tasks from this checkout instead")
    parser.add_argument("--tiles", action="store_true", help="the tiles of two worker threads")
    parser.add_argument("--cache", type=Path, default=None, help="keep the dense cycles here")
    args = parser.parse_args()
    n_r, n_beta = (int(v) for v in args.size.split("x"))
    rows = [run(sc, n_r, n_beta, args.tiles, args.cache) for sc in cluster_scenes(args.scenes)]
    header = ["scene", "simulated", "their cycles, seeded by corners"]
    header += ["their cycles in the dense grid (% of its cycles)"]
    header += ["their cycles from the held start", "seeded / dense"]
    if args.tiles:
        header += ["coarse lattice seeded / dense", f"points > {OUTLIER} over dense (% of excess)"]
    header += ["dense grid cycles", "CPU s dense / seeded (ratio)"]
    how = "tiles of 2 threads" if args.tiles else f"point lists of {MIN_LIST}"
    print(f"{n_r} x {n_beta}, balanced, coarse step 16, exact hint, {how}")
    print(table(header, rows))


if __name__ == "__main__":
    main()
