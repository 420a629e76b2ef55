"""Regenerate the figures of the README and docs/ (125 r x 61 beta values per panel).

Run from the repository root: ``python docs/figures/regenerate.py`` (about a minute
on one core). It prints, per boundary, the columns whose grid bracket does not
contain the closed form (the numbers docs/results.md quotes).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from analysis import figures
from analysis.design import map_dataset
from analysis.scoring import score_dataset
from tasks import Scene

OUT = Path(__file__).resolve().parent
R = np.linspace(0.02, 2.5, 125)
BETA = np.linspace(0.0, 1.5, 61)


def scene_map(scene: Scene):
    """The map of one panel with the closed-form boundaries, as a stored scene."""
    return map_dataset(scene, R, BETA, design=True)  # the response figure needs them


def main() -> None:
    step = BETA[1] - BETA[0]
    fig04_11 = scene_map(Scene("ground", 2, 1, gamma=1.0, kappa=1.0))
    scores = score_dataset(fig04_11)
    title = f"{figures.scene_title(fig04_11)}: boundary deviation"
    figures.save_deviation(
        scores, OUT / "deviation_fig04_gamma1_kappa1.png", step=step, title=title
    )
    for method, agreement in scores.items():
        for name, dev in agreement.deviations.items():
            steps = dev.deviation / step
            outside = np.isfinite(steps) & ~dev.consistent
            print(
                f"{method} {name}: {int(outside.sum())} of {int(np.isfinite(steps).sum())} columns "
                f"outside the bracket, r = {np.round(dev.r[outside], 3).tolist()}, "
                f"steps = {np.round(steps[outside], 2).tolist()}"
            )
    fig04_105 = scene_map(Scene("ground", 2, 1, gamma=1.0, kappa=0.5))
    figures.save_regime_map(fig04_105, OUT / "map_fig04_gamma1_kappa0.5.png")
    fig = Figure(figsize=(6.4, 4.8))  # the README's labelled plot, the same lines
    plot = fig04_105.regime.plot(
        ax=fig.subplots(),
        levels=[-0.5, 0.5, 1.5, 2.5],
        colors=["#a6a6a6", "#f5a04a", "#4a90d9"],
        cbar_kwargs={"ticks": [0, 1, 2], "label": "regime"},
    )
    plot.colorbar.set_ticklabels(["no motion", "stick-slip", "continuous"])
    fig.savefig(OUT / "xarray_regime_plot.png", dpi=80)
    fig17 = scene_map(Scene("mass", 2, 1, gamma=1.0, kappa=1.0))
    figures.save_response(fig17, OUT / "response_fig17_gamma1_kappa1.png")


if __name__ == "__main__":
    main()
