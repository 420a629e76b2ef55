"""Orbit invariant on a dense low-r sweep: every converged orbit is a solution.

For every configuration and preset, classify a dense grid of low r (and beta
from near zero to past the stick-slip / no-motion boundary), re-run each
converged orbit with :func:`tasks.trajectory` and sample the exact state
densely: through every stick phase ``|g| <= beta`` and through every slip phase
the contact velocity keeps its sign. Prints the number of converged orbits and
of violations per configuration and preset, and the worst ``max |g| / beta``.

    .venv/bin/python benchmarks/sweep_invariant.py [--nr 40 --nb 12] [--presets fast,balanced,exact]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tasks import Scene, classify  # noqa: E402
from tasks.classifier import scene_modes_cached
from tasks.scene import CONFIGURATIONS  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_orbit_invariant import invariant  # noqa: E402

CONFIGS = {
    **CONFIGURATIONS,
    "5dof_ground_m3": Scene("ground", 5, 3, gamma=[1.5, 0.7, 1.2, 0.9], kappa=[0.8, 1.3, 1.0, 0.6]),
}


def orbit_violation(scene: Scene, r: float, beta: float, fidelity: str, samples: int = 4000):
    """``(max |g| / beta over stick phases, slip phases whose velocity changes sign)``:
    the independent check of ``tests/test_orbit_invariant.py`` (one home)."""
    return invariant(scene, r, beta, fidelity, samples)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--nr", type=int, default=40)
    ap.add_argument("--nb", type=int, default=12)
    ap.add_argument("--presets", default="fast,balanced,exact")
    ap.add_argument("--configs", default=",".join(CONFIGS))
    ap.add_argument("--gtol", type=float, default=1e-6)
    args = ap.parse_args()
    r = np.linspace(0.05, 0.4, args.nr)
    print(
        "| config | preset | points | converged | violations | worst max|g|/beta "
        "| classify s | check s |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name in args.configs.split(","):
        scene = CONFIGS[name]
        for fid in args.presets.split(","):
            rr, bb = [], []
            for ri in r:
                # beta from near 0 to a bit past the static bound of the held contact
                # (the stick-slip / no-motion boundary is near beta ~ g amplitude)
                bmax = 1.2 * _g_amp(scene, ri)
                for bi in np.geomspace(bmax * 1e-3, bmax, args.nb):
                    rr.append(ri)
                    bb.append(bi)
            rr = np.array(rr)
            bb = np.array(bb)
            t0 = time.perf_counter()
            res = classify(scene, rr, bb, fidelity=fid)
            t1 = time.perf_counter()
            bad = 0
            worst = 0.0
            conv = res.converged.astype(bool)
            for ri, bi in zip(rr[conv], bb[conv], strict=True):
                w, f = orbit_violation(scene, ri, bi, fid)
                worst = max(worst, w)
                if w > 1.0 + args.gtol or f:
                    bad += 1
            t2 = time.perf_counter()
            print(
                f"| {name} | {fid} | {rr.size} | {int(conv.sum())} | {bad} | {worst:.4f} | "
                f"{t1 - t0:.2f} | {t2 - t1:.1f} |",
                flush=True,
            )


def _g_amp(scene: Scene, r: float) -> float:
    """Amplitude of the contact force on the held forced response (no-motion bound scale)."""
    from tasks import trajectory as _tr

    tr = _tr(scene, r, 1e9, start="held", cycles=1)
    tau = np.linspace(0, 2 * np.pi, 400)
    modes = scene_modes_cached(scene)
    x, _ = tr.sample(tau)
    g = (
        modes.load(r)[None, :] * np.cos(tau)[:, None] - x @ scene.stiffness_matrix().T
    ) @ modes.g_load
    return float(np.max(np.abs(g)))


if __name__ == "__main__":
    main()
