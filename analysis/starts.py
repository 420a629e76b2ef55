"""Where the regime depends on the start: counts and a map for the report.

A result classified from several starts (``[settings] starts = ["held", "rest"]``,
``n_random``) holds ``start_dependent`` (two starts reached different regimes),
``regimes_reached`` (bit mask: 1 no motion, 2 stick-slip, 4 continuous, 8
undetermined) and ``asymptotic`` (no motion reached by a creep, docs/theory.md 3).
"""

from __future__ import annotations

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from analysis import figures

#: Variables of a result that describe the starts (``tasks.result.FIELDS``).
START_VARIABLES = ("start_dependent", "regimes_reached", "asymptotic", "regime_rest")


def start_counts(ds: xr.Dataset) -> dict[str, int]:
    """Points that depend on the start, reached no motion asymptotically, and in total.

    Returns an empty dict when the result has no start variables.
    """
    if "start_dependent" not in ds:
        return {}
    dep = np.asarray(ds["start_dependent"].values, dtype=bool)
    out = {"points": int(dep.size), "start_dependent": int(dep.sum())}
    if "asymptotic" in ds:
        out["asymptotic"] = int(np.asarray(ds["asymptotic"].values, dtype=bool).sum())
    if "regimes_reached" in ds:
        reached = np.asarray(ds["regimes_reached"].values, dtype=np.int64)
        out["undetermined_from_a_start"] = int(((reached & 8) > 0).sum())
    return out


def start_dependence_figure(ds: xr.Dataset, title: str | None = None) -> Figure | None:
    """Map over (r, beta) of the points whose regime depends on the start.

    Grey: every start reached the same regime; red: two starts reached different
    regimes; blue: no motion reached asymptotically (creep). Other dimensions
    (gamma, kappa sweeps) are reduced with "any". None for point lists and traces.
    """
    if "start_dependent" not in ds or not {"r", "beta"} <= set(ds["start_dependent"].dims):
        return None
    other = [d for d in ds["start_dependent"].dims if d not in ("r", "beta")]
    dep = ds["start_dependent"].astype(bool).any(other).transpose("r", "beta").values
    code = np.zeros(dep.shape)
    if "asymptotic" in ds:
        asym = ds["asymptotic"].astype(bool).any(other).transpose("r", "beta").values
        code[asym] = 1.0
    code[dep] = 2.0
    r = ds["r"].values
    beta = ds["beta"].values
    fig = figures.new_figure(6.0, 4.0)
    ax = fig.add_subplot(1, 1, 1)
    from matplotlib.colors import ListedColormap

    cmap = ListedColormap(["#dddddd", "#4477aa", "#cc3311"])
    ax.pcolormesh(r, beta, code.T, cmap=cmap, vmin=-0.5, vmax=2.5, shading="nearest")
    ax.set_xlabel("r")
    ax.set_ylabel("beta")
    n = int(dep.sum())
    ax.set_title(title or f"regime depends on the start at {n} point(s) (red); blue: creep")
    return fig
