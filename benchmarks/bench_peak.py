"""A peak of the exact motion bound at a held resonance, mapped adaptively.

The random audit's damped map (docs/benchmarks.md, Random audit, seed 18: a 2DOF
base chain with dashpots, contact on the first DOF) on its own axes, at the
audit's 25 x 17 (``coarse_step`` 4) and at ``--size`` (default 1000 x 500,
``coarse_step`` 16), hint exact: the refinement of this checkout (the hint and
its prediction, ``tasks.adaptive.Refinement``) and, with ``--code DIR``, that of
another checkout (its ``StreamRefinement``, e.g. main before the prediction: the
hint alone), each simulating the points it asks for with ``tasks.classify``
(cold starts, the verification sample included). Prints the points simulated,
then every point where the maps or the closed-form prediction differ, with
``classify`` there (the independent truth) and the motion bound at the point and
its two neighbours along r:

    python benchmarks/bench_peak.py --code ../main
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from bench_adaptive import _stream_class

from analysis.adaptive import closed_form_guide
from analysis.closed_form import motion_bound
from study.adaptive import VERIFY_SEED
from tasks import Scene, classify
from tasks.adaptive import DEFAULT_VERIFY_MIN, KEY_FIELDS
from tasks.result import FIELDS
from tasks.stream import StreamRefinement

M = np.diag([0.409519, 0.162999])
K = np.array([[3.662481, -3.227477], [-3.227477, 3.227477]])
C = np.diag([0.008974, 0.032267])
R_AXIS, BETA_TOP = (0.260045, 6.878044), 94.85256


def scene() -> Scene:
    return Scene.from_matrices(M, K, ("base", np.ones(2)), ("ground", 0), damping=C)


def refine_map(cls, sc, r, beta, step, hint, predicted):
    """The map of refinement class ``cls``: labels, simulated points, CPU seconds."""
    extra = {} if predicted is None else {"predicted": predicted}
    layout = {k: (FIELDS[k][0], 0) for k in KEY_FIELDS}
    ref = cls((r.size, beta.size), step, hint, fields=layout, **extra)
    t = time.process_time()

    def run(idx):
        i, j = np.unravel_index(idx, ref.shape)
        res = classify(sc, r[i], beta[j])
        return {k: np.asarray(getattr(res, k)) for k in KEY_FIELDS}

    while (idx := ref.take(256)).size:
        ref.accept(idx, run(idx))
    sample = ref.verification(0.005, DEFAULT_VERIFY_MIN, VERIFY_SEED)
    if sample.size:
        ref.accept_verification(sample, run(sample))
    out = ref.result()
    return out["regime"], out["simulated"], time.process_time() - t


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="1000x500", help="points along r x beta (1000x500)")
    ap.add_argument("--coarse-step", type=int, default=16)
    ap.add_argument("--code", type=Path, help="another checkout's refinement beside this one")
    args = ap.parse_args(argv)
    n_r, n_b = (int(v) for v in args.size.split("x"))
    sc = scene()
    for shape, step in (((25, 17), 4), ((n_r, n_b), args.coarse_step)):
        r, beta = np.linspace(*R_AXIS, shape[0]), np.linspace(0.0, BETA_TOP, shape[1])
        hint, predicted = closed_form_guide(sc, r, beta, "exact")
        runs = {"hint and prediction": (StreamRefinement, predicted)}
        if args.code is not None:
            runs = {"hint alone (--code)": (_stream_class(args.code), None)} | runs
        maps = {}
        for name, (cls, pred) in runs.items():
            maps[name] = refine_map(cls, sc, r, beta, step, hint, pred)
            print(
                f"{shape[0]} x {shape[1]}, coarse_step {step}, {name}: "
                f"{int(maps[name][1].sum()):,} points simulated ({maps[name][2]:.1f} CPU s)"
            )
        differ = predicted != next(iter(maps.values()))[0]
        for regime, _, _ in maps.values():
            differ |= regime != predicted
        ij = np.argwhere(differ)
        truth = classify(sc, r[ij[:, 0]], beta[ij[:, 1]]).regime
        bound = motion_bound(sc, r)
        print(f"points where a map or the prediction differ: {ij.shape[0]}")
        print("| i_r | i_beta | r | beta | " + " | ".join(maps) + " | predicted | classify "
              "| motion bound at i_r - 1, i_r, i_r + 1 |")  # fmt: skip
        print("|" + "---|" * (7 + len(maps)))
        for (i, j), code in zip(ij, truth, strict=True):
            labels = " | ".join(
                f"{int(g[i, j])}{'' if s[i, j] else ' (inferred)'}" for g, s, _ in maps.values()
            )
            near = ", ".join(f"{b:.4g}" for b in bound[max(i - 1, 0) : i + 2])
            print(
                f"| {i} | {j} | {r[i]:.4f} | {beta[j]:.3f} | {labels} | {predicted[i, j]} "
                f"| {int(code)} | {near} |"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
