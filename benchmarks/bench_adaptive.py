"""Adaptive maps against the dense grid of the same resolution, on the paper's panels.

For every panel (scene) of the figure studies ``examples/fig*.toml``, the map is
computed twice at the requested resolution, in this process on one core:
(a) densely (``tasks.classify`` on every point; computed once and cached in
``--cache`` so a rerun does not pay for it again) and (b) adaptively
(``analysis.adaptive.adaptive_map``: coarse lattice, refinement, closed-form
hints, verification sample). Prints per panel: points simulated (verification
included), wall seconds of both, label agreement with the dense grid (all
points; the differing points, and how many of them have a regime in the dense
grid: the others are points the dense grid left undetermined, e.g. isolated
``not_converged`` points the adaptive map inferred from agreeing neighbours),
and the verification sample's own estimate.

    python benchmarks/bench_adaptive.py                                # all panels, 1000 x 500
    python benchmarks/bench_adaptive.py --size 500x250                 # all panels, smaller
    python benchmarks/bench_adaptive.py --panels fig03 fig04:gamma1_kappa1 fig17:gamma1_kappa1

A dense 1000 x 500 panel is ~2-3 min of one core (2DOF, balanced).
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from analysis.adaptive import adaptive_map
from analysis.report import percent
from study.definition import Study
from tasks import classify

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def panels(selection: list[str] | None):
    """(label, SceneSpec) of the figure studies, filtered by ``study`` or ``study:scene``."""
    out = []
    for path in sorted(EXAMPLES.glob("fig*.toml")):
        study = Study.from_toml(path)
        for spec in study.scenes:
            label = f"{study.name}:{spec.name}"
            if selection and not any(label == s or study.name == s for s in selection):
                continue
            out.append((label, spec))
    return out


def axes(spec, n_r: int, n_beta: int) -> tuple[np.ndarray, np.ndarray]:
    """The panel's r and beta ranges at the requested resolution (rounded like a study)."""
    r = replace(spec.r, num=n_r).values_array() if spec.r.values is None else None
    b = replace(spec.beta, num=n_beta).values_array() if spec.beta.values is None else None
    if r is None or b is None:
        raise SystemExit(f"{spec.name}: panels need start/stop axes")
    return r, b


def dense_regime(scene, r, beta, cache: Path | None, fidelity: str) -> tuple[np.ndarray, float]:
    """Regime codes of the dense grid, from the cache or computed (seconds; nan if cached)."""
    h = hashlib.sha256(
        repr((scene.to_dict(), fidelity)).encode() + r.tobytes() + beta.tobytes()
    ).hexdigest()[:16]
    path = cache / f"dense-{h}.npz" if cache else None
    if path is not None and path.is_file():
        with np.load(path) as z:
            return z["regime"], float(z["seconds"])
    t = time.perf_counter()
    R, B = np.meshgrid(r, beta, indexing="ij")
    regime = classify(scene, R, B, fidelity=fidelity).regime
    seconds = time.perf_counter() - t
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, regime=regime, seconds=seconds)
    return regime, seconds


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="1000x500", help="points along r x beta (1000x500)")
    ap.add_argument("--panels", nargs="*", help="fig04 or fig04:gamma1_kappa1 (default: all)")
    ap.add_argument("--coarse-step", type=int, default=16)
    ap.add_argument("--hint", default="exact", choices=("exact", "paper", "none"))
    ap.add_argument("--fidelity", default="balanced")
    ap.add_argument("--cache", type=Path, default=Path(".bench_adaptive_cache"))
    args = ap.parse_args(argv)
    n_r, n_beta = (int(x) for x in args.size.lower().split("x"))
    chosen = panels(args.panels)
    if not chosen:
        raise SystemExit("no panel matches --panels")
    classify(chosen[0][1].base_scene, 1.0, 0.1)  # compile / load the kernel outside the timings
    print(
        f"adaptive vs dense, {n_r} x {n_beta} = {n_r * n_beta:,} points per panel, "
        f"coarse_step {args.coarse_step}, hint {args.hint}, fidelity {args.fidelity}, "
        "one process"
    )
    head = (
        "| panel | simulated | % simulated | waves | adaptive s | dense s | speed-up "
        "| labels equal to dense | differing | of which determined in the dense grid "
        "| dense undetermined | verification (agree / sampled) |"
    )
    print(head)
    print("|" + "---|" * 12)
    tot_sim = tot_pts = tot_diff = tot_det = 0
    for label, spec in chosen:
        scene = spec.base_scene
        r, beta = axes(spec, n_r, n_beta)
        dense, dense_s = dense_regime(scene, r, beta, args.cache, args.fidelity)
        t = time.perf_counter()
        res = adaptive_map(
            scene,
            r,
            beta,
            coarse_step=args.coarse_step,
            hint=None if args.hint == "none" else args.hint,
            fidelity=args.fidelity,
        )
        ad_s = time.perf_counter() - t
        differ = res.fields["regime"] != dense
        diff = int(differ.sum())
        det = int((differ & (dense >= 0)).sum())  # the dense grid has a regime there
        n = dense.size
        v = res.verification
        tot_sim += res.simulated_points
        tot_pts += n
        tot_diff += diff
        tot_det += det
        print(
            f"| {label} | {res.simulated_points:,} | {100 * res.simulated_fraction:.2f} "
            f"| {len(res.levels)} | {ad_s:.1f} | {dense_s:.1f} | {dense_s / ad_s:.1f} "
            f"| {percent(n - diff, n, 3)} | {diff} | {det} | {int((dense < 0).sum())} "
            f"| {v.agree} / {v.sampled} |",
            flush=True,
        )
    print(
        f"| all {len(chosen)} panels | {tot_sim:,} | {100 * tot_sim / tot_pts:.2f} | | | | "
        f"| {percent(tot_pts - tot_diff, tot_pts, 3)} | {tot_diff} | {tot_det} | | |"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
