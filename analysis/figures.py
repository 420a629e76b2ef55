"""Figures of regime maps, boundaries and their deviations (matplotlib, Agg, no pyplot).

Every function builds a :class:`matplotlib.figure.Figure` from data and
returns it; the ``save_*`` helpers write PNG files. Colours follow the paper:
continuous blue, stick-slip orange, no motion grey. Undetermined points get
one dark colour per reason (with a legend entry for each reason present);
not-computed points are white. Closed-form boundaries: "paper" dashed,
"exact" solid; traced numerical boundaries: dotted with markers. Infinite
bounds are clipped just outside the axes, so peaks run off the top.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import xarray as xr
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from numpy.typing import ArrayLike

from analysis.deviations import BOUNDARIES
from analysis.scoring import (
    Agreement,
    available_methods,
    regime_codes,
    regime_from_bounds,
    scene_kind,
    sweep_dims,
)
from tasks import regimes

#: Colour of each regime code (the paper's colours for the three regimes).
COLOURS: dict[int, str] = {
    regimes.CONTINUOUS: "#4a90d9",
    regimes.STICK_SLIP: "#f5a04a",
    regimes.NO_MOTION: "#a6a6a6",
    regimes.NOT_CONVERGED: "#000000",
    regimes.UNBOUNDED: "#8b0000",
    regimes.EVENT_LIMIT: "#6a1b9a",
    regimes.NUMERICAL_FAILURE: "#c2185b",
    regimes.NOT_COMPUTED: "#ffffff",
}
#: Colour of any other (unknown) negative code.
UNKNOWN_COLOUR = "#ff00ff"
#: Line style of each boundary method.
LINESTYLES: dict[str, str] = {"paper": "--", "exact": "-", "numerical": ":"}
#: Line colour of each boundary where no map is drawn beneath (traced scenes); on
#: regime maps both boundaries are black (their position tells them apart).
BOUNDARY_COLOURS: dict[str, str] = {"continuous": "#1f5fa8", "motion": "#000000"}
_MAP_LINE_COLOUR = "#000000"
#: Marker of each method in deviation plots (paper hollow squares, exact dots).
_METHOD_MARKERS: dict[str, dict[str, object]] = {
    "paper": {"marker": "s", "markersize": 6, "markerfacecolor": "none"},
    "exact": {"marker": "o", "markersize": 3.5},
}
_METHOD_COLOURS: dict[str, str] = {"paper": "#d62728", "exact": "#1f77b4"}
#: An amplitude at most this fraction of the largest one is 0 in the response figure
#: (a held mass has amplitude 0 up to rounding).
HELD_AMPLITUDE = 1e-12
_PAD = 0.03  # fraction of the axis range by which clipped values overshoot it
#: Axis names of the paper: r_1 = omega sqrt(m_1/k_1) (Eq. 7) and beta (Eq. 8).
R_LABEL = r"$r_1$"
BETA_LABEL = r"$\beta$"
#: Vertical marks: resonances of the frictionless chain and antiresonances of the contact.
_MARKS = {
    "resonance": {"color": "#7b1fa2", "linestyle": (0, (4, 2)), "linewidth": 0.9},
    "antiresonance": {"color": "#2e7d32", "linestyle": (0, (1, 1.5)), "linewidth": 1.2},
}
CONTACT_NAMES = {
    "ground": "ground-fixed wall",
    "base": "base-fixed wall",
    "mass": "contact between masses",
}


# --------------------------------------------------------------------------- helpers
def _colour(code: int) -> str:
    return COLOURS.get(int(code), UNKNOWN_COLOUR)


def _label(code: int) -> str:
    return regimes.name(int(code)).replace("_", " ")


def _edges(centres: np.ndarray) -> np.ndarray:
    """Cell edges around sorted cell centres (midpoints; half a step beyond the ends)."""
    c = np.asarray(centres, dtype=float)
    if c.size == 1:
        half = 0.5 * abs(c[0]) if c[0] != 0 else 0.5
        return np.array([c[0] - half, c[0] + half])
    mid = 0.5 * (c[1:] + c[:-1])
    return np.concatenate([[c[0] - (mid[0] - c[0])], mid, [c[-1] + (c[-1] - mid[-1])]])


def clip_to(values: ArrayLike, lo: float, hi: float) -> np.ndarray:
    """Values clipped just outside ``[lo, hi]`` (infinities included; NaN kept as gaps)."""
    pad = _PAD * (hi - lo if hi > lo else 1.0)
    return np.clip(np.asarray(values, dtype=float), lo - pad, hi + pad)


def new_figure(width: float, height: float) -> Figure:
    """A Figure with an Agg canvas and constrained layout (no pyplot state)."""
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def regime_handles(codes: Sequence[int]) -> list[Patch]:
    """Legend patches: the three regimes always, then each other code present."""
    present = set(int(c) for c in codes)
    shown = [regimes.CONTINUOUS, regimes.STICK_SLIP, regimes.NO_MOTION]
    shown += sorted((c for c in present if c not in shown), reverse=True)
    return [Patch(facecolor=_colour(c), edgecolor="0.3", label=_label(c)) for c in shown]


def boundary_handles(methods: Sequence[str], numerical: bool = False) -> list[Line2D]:
    """Legend lines for the boundary methods (line style) and the two boundaries (colour)."""
    out = [
        Line2D([], [], color="0.2", linestyle=LINESTYLES.get(m, "-"), label=f"{m} closed form")
        for m in methods
    ]
    if numerical:
        out.append(Line2D([], [], color="0.2", linestyle=":", marker=".", label="numerical"))
    return out


def _ratio_text(value: object) -> str:
    if isinstance(value, list | tuple):
        return "[" + ", ".join(f"{float(v):g}" for v in value) + "]"
    return f"{float(value):g}"


def r_label(ds: xr.Dataset) -> str:
    """The x label: the paper's r_1 (Eq. 7) for a chain; r of Eq. 1.1 of docs/structures.md
    for a structure (``omega / omega_1`` of the beam without contact for a beam, Eq. 2.3)."""
    if ds.attrs.get("contact") != "matrices":
        return R_LABEL
    if '"beam"' in str(ds.attrs.get("scene", "")):
        return r"$r = \omega / \omega_1$"
    return r"$r$"


def scene_title(ds: xr.Dataset, swept: bool = True) -> str:
    """``2DOF, ground-fixed wall on $m_{1}$, $\\gamma$ = 1, $\\kappa$ = 0.5`` (matplotlib
    mathtext) from a scene's attributes
    and its scalar gamma / kappa coordinates (swept ratios: ``gamma swept`` unless
    ``swept`` is False, for a figure whose panels name them)."""
    import json

    attrs = ds.attrs
    contact, dof, j = attrs.get("contact"), attrs.get("dof"), attrs.get("contact_mass")
    scene = json.loads(attrs["scene"]) if "scene" in attrs else {}
    contact = contact or scene.get("contact")
    dof = dof or scene.get("dof")
    j = j or scene.get("contact_mass", 1)
    if contact is None or dof is None:
        return str(attrs.get("scene_label") or attrs.get("scene_name", ""))
    if "description" in scene:  # a structure (study.structures.describe)
        return str(scene["description"])
    size = "SDOF" if int(dof) == 1 else f"{dof}DOF"
    if contact == "mass":
        where = f"contact between $m_{{{j}}}$ and $m_{{{int(j) + 1}}}$"
    else:
        where = f"{CONTACT_NAMES.get(contact, contact)} on $m_{{{j}}}$"
    parts = [f"{size}, {where}"]
    if int(dof) > 1:
        for name, sym in (("gamma", "$\\gamma$"), ("kappa", "$\\kappa$")):
            if name in ds.coords and ds[name].ndim == 0:
                parts.append(f"{sym} = {float(ds[name]):g}")
            elif name in ds.dims:
                if swept:
                    parts.append(f"{sym} swept")
            elif name in scene:
                parts.append(f"{sym} = {_ratio_text(scene[name])}")
    return ", ".join(parts)


def mark_frequencies(ax: Axes, ds: xr.Dataset) -> set[str]:
    """Vertical lines at the resonances and antiresonances within the r range of ``ax``
    (:func:`analysis.design.characteristic_r`); returns the kinds drawn."""
    from analysis.design import characteristic_r, scene_of

    scene = scene_of(ds)
    if scene is None:
        return set()
    lo, hi = ax.get_xlim()
    res, anti = characteristic_r(scene, hi)
    drawn = set()
    for kind, values in (("resonance", res), ("antiresonance", anti)):
        for x in values:
            if lo < x < hi:
                ax.axvline(x, zorder=1.5, **_MARKS[kind])
                drawn.add(kind)
    return drawn


def frequency_handles(kinds: set[str]) -> list[Line2D]:
    """Legend lines for :func:`mark_frequencies`."""
    names = {
        "resonance": "resonance (contact sliding freely)",
        "antiresonance": "antiresonance of the contact",
    }
    return [Line2D([], [], label=names[k], **_MARKS[k]) for k in _MARKS if k in kinds]


# --------------------------------------------------------------------------- drawing
def draw_regime_map(
    ax: Axes,
    regime: ArrayLike,
    r: ArrayLike,
    beta: ArrayLike,
) -> set[int]:
    """Draw an (r, beta) regime map into ``ax`` (r on x, beta on y).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    regime : array_like
        ``(n_r, n_beta)`` regime codes.
    r, beta : array_like
        Coordinates (any order; the map is sorted).

    Returns
    -------
    set of int
        Codes present in the map (for the legend).
    """
    regime = np.asarray(regime)
    r, beta = np.asarray(r, dtype=float), np.asarray(beta, dtype=float)
    ir, ib = np.argsort(r), np.argsort(beta)
    regime = regime[np.ix_(ir, ib)]
    codes = sorted(set(np.unique(regime).tolist()))
    index = np.searchsorted(codes, regime)
    cmap = ListedColormap([_colour(c) for c in codes])
    ax.pcolormesh(
        _edges(r[ir]),
        _edges(beta[ib]),
        index.T,
        cmap=cmap,
        vmin=-0.5,
        vmax=len(codes) - 0.5,
        shading="flat",
        rasterized=True,
    )
    ax.set_xlim(_edges(r[ir])[[0, -1]])
    ax.set_ylim(_edges(beta[ib])[[0, -1]])
    ax.set_xlabel(R_LABEL)
    ax.set_ylabel(BETA_LABEL)
    return set(codes)


def draw_boundaries(
    ax: Axes,
    r: ArrayLike,
    bounds: Mapping[str, tuple[ArrayLike, ArrayLike]],
    ylim: tuple[float, float] | None = None,
    colours: Mapping[str, str] | None = None,
) -> None:
    """Overlay boundaries ``{method: (beta_continuous, beta_motion)}`` along r.

    Values are clipped just outside ``ylim`` (default: the current y limits),
    which are kept; NaN values leave gaps. ``colours`` maps "continuous" and
    "motion" to line colours (default: black for both, as on a regime map).
    """
    colours = colours or dict.fromkeys(BOUNDARIES, _MAP_LINE_COLOUR)
    lo, hi = ylim if ylim is not None else ax.get_ylim()
    r = np.asarray(r, dtype=float)
    order = np.argsort(r)
    for method, pair in bounds.items():
        numerical = method == "numerical"
        for name, values in zip(BOUNDARIES, pair, strict=True):
            ax.plot(
                r[order],
                clip_to(np.asarray(values, dtype=float)[order], lo, hi),
                color=colours[name],
                linestyle=LINESTYLES.get(method, "-"),
                marker="." if numerical else None,
                markersize=3,
                linewidth=1.2,
            )
    ax.set_ylim(lo, hi)


def _bounds_of(ds: xr.Dataset, methods: Sequence[str]) -> dict[str, tuple[np.ndarray, ...]]:
    return {
        m: (
            ds[f"beta_continuous_{m}"].transpose("r").values,
            ds[f"beta_motion_{m}"].transpose("r").values,
        )
        for m in methods
    }


def _plane_title(coords: Mapping[str, float]) -> str:
    sym = {"gamma": r"$\gamma$", "kappa": r"$\kappa$"}
    return ", ".join(f"{sym.get(k, k)} = {v:g}" for k, v in coords.items())


def _beta_range(ds: xr.Dataset, values: Sequence[np.ndarray]) -> tuple[float, float]:
    """y range of a traced scene: its ``beta_range`` attribute, else the finite values."""
    if "beta_range" in ds.attrs:
        import json

        lo, hi = json.loads(ds.attrs["beta_range"])
        return float(lo), float(hi)
    finite = np.concatenate([v[np.isfinite(v)] for v in values] + [np.zeros(1)])
    hi = float(finite.max())
    return 0.0, hi if hi > 0 else 1.0


def _draw_plane(
    ax: Axes, plane: xr.Dataset, kind: str, methods: Sequence[str], marks: set[str] | None = None
) -> set[int]:
    """One panel: a regime map with bounds (grid) or the bounds alone (trace), with the
    resonances and antiresonances marked (their kinds added to ``marks``)."""
    marks = set() if marks is None else marks
    r = plane["r"].values
    bounds = _bounds_of(plane, methods)
    if kind == "trace":
        numerical = (
            plane["beta_continuous_numerical"].transpose("r").values,
            plane["beta_motion_numerical"].transpose("r").values,
        )
        bounds["numerical"] = numerical
        lo, hi = _beta_range(plane, [v for pair in bounds.values() for v in pair])
        ax.set_xlim(float(np.min(r)), float(np.max(r)))
        ax.set_xlabel(r_label(plane))
        ax.set_ylabel(BETA_LABEL)
        draw_boundaries(ax, r, bounds, (lo, hi), BOUNDARY_COLOURS)
        marks |= mark_frequencies(ax, plane)
        return set()
    codes = draw_regime_map(
        ax, regime_codes(plane["regime"].transpose("r", "beta")), r, plane["beta"].values
    )
    draw_boundaries(ax, r, bounds)
    marks |= mark_frequencies(ax, plane)
    ax.set_xlabel(r_label(plane))
    return codes


def _layout(sizes: Mapping[str, int]) -> tuple[int, int]:
    """(rows, columns) of small multiples: gamma x kappa, or a wrapped row for one sweep."""
    dims = list(sizes)
    if len(dims) == 2:
        return sizes[dims[0]], sizes[dims[1]]
    n = math.prod(sizes.values()) if sizes else 1
    ncols = min(n, 3)
    return math.ceil(n / ncols), ncols


def regime_map_figure(ds: xr.Dataset, title: str | None = None) -> Figure:
    """Regime map of one scene with the closed-form boundaries overlaid.

    Grid scenes: one panel per (gamma, kappa) plane (small multiples for
    sweeps). Traced scenes: the traced and closed-form boundaries. Point
    lists: :func:`points_figure`.

    Parameters
    ----------
    ds : xarray.Dataset
        One scene of a result file.
    title : str, optional
        Figure title (default: the scene label or name).

    Returns
    -------
    matplotlib.figure.Figure
    """
    kind = scene_kind(ds)
    if kind == "points":
        return points_figure(ds, title=title)
    methods = available_methods(ds)
    sweeps = sweep_dims(ds)
    sizes = {d: ds.sizes[d] for d in sweeps}
    nrows, ncols = _layout(sizes)
    fig = new_figure(3.6 * ncols + 1.6, 3.0 * nrows + 0.6)
    axes = fig.subplots(nrows, ncols, squeeze=False, sharex=True, sharey=True)
    codes: set[int] = set()
    marks: set[str] = set()
    planes = list(np.ndindex(*sizes.values())) if sweeps else [()]
    for n, idx in enumerate(planes):
        ax = axes.flat[n]
        sel = dict(zip(sweeps, idx, strict=True))
        plane = ds.isel(sel) if sel else ds
        codes |= _draw_plane(ax, plane, kind, methods, marks)
        if sel:
            ax.set_title(_plane_title({d: float(ds[d].values[i]) for d, i in sel.items()}))
        if not ax.get_subplotspec().is_first_col():
            ax.set_ylabel("")
    for ax in axes.flat[len(planes) :]:
        ax.set_visible(False)
    handles = (regime_handles(sorted(codes)) if kind != "trace" else []) + boundary_handles(
        methods, numerical=kind == "trace"
    )
    if kind == "trace":
        handles += [
            Line2D([], [], color=BOUNDARY_COLOURS[b], label=f"{b} boundary") for b in BOUNDARIES
        ]
    handles += frequency_handles(marks)
    fig.legend(handles=handles, loc="outside right center", fontsize="small")
    fig.suptitle(title or scene_title(ds, swept=False))
    return fig


def points_figure(
    ds: xr.Dataset, methods: Sequence[str] | None = None, title: str | None = None
) -> Figure:
    """Scatter of a point-list scene in the (r, beta) plane, one panel per method.

    Points are coloured by simulated regime (undetermined ones by reason);
    points where the method predicts another regime are ringed in red.

    Parameters
    ----------
    ds : xarray.Dataset
        A point-list scene (dim ``point``).
    methods : sequence of str, optional
        Closed-form methods (default: those in ``ds``).
    title : str, optional
        Figure title.

    Returns
    -------
    matplotlib.figure.Figure
    """
    methods = list(methods if methods is not None else available_methods(ds))
    regime = regime_codes(ds["regime"])
    r, beta = ds["r"].values.astype(float), ds["beta"].values.astype(float)
    n = max(len(methods), 1)
    fig = new_figure(3.8 * n + 1.6, 3.4)
    axes = fig.subplots(1, n, squeeze=False, sharey=True)[0]
    codes = sorted(set(regime.tolist()))
    for ax, method in zip(axes, methods or [None], strict=True):
        for c in codes:
            sel = regime == c
            marker = "o" if regimes.is_determined(c) else "X"
            ax.scatter(
                r[sel],
                beta[sel],
                s=22,
                c=_colour(c),
                marker=marker,
                edgecolors="0.3",
                linewidths=0.4,
                zorder=2,
            )
        if method is not None:
            predicted = regime_from_bounds(
                beta, ds[f"beta_continuous_{method}"].values, ds[f"beta_motion_{method}"].values
            )
            wrong = regimes.is_determined(regime) & (predicted != regime)
            wrong &= predicted != regimes.NOT_COMPUTED
            ax.scatter(
                r[wrong],
                beta[wrong],
                s=90,
                facecolors="none",
                edgecolors="red",
                linewidths=1.2,
                zorder=3,
            )
            ax.set_title(f"{method}: {int(wrong.sum())} misclassified")
        ax.set_xlabel(r_label(ds))
    axes[0].set_ylabel(BETA_LABEL)
    handles = regime_handles(codes) + [
        Line2D(
            [],
            [],
            linestyle="none",
            marker="o",
            markerfacecolor="none",
            markeredgecolor="red",
            markersize=9,
            label="misclassified",
        )
    ]
    fig.legend(handles=handles, loc="outside right center", fontsize="small")
    fig.suptitle(title or scene_title(ds))
    return fig


def deviation_figure(
    agreements: Mapping[str, Agreement],
    title: str | None = None,
    step: float | None = None,
    traced: bool = False,
    xlabel: str = R_LABEL,
) -> Figure:
    """Numerical minus closed-form boundary vs r, both boundaries, one line per method.

    With ``step`` (the beta step of the map) deviations are drawn in grid steps
    and the band of half a step, the resolution of a boundary read from the
    grid, is shaded. A column whose bracket contains the closed form agrees as
    far as the grid can tell and is drawn at 0 (its midpoint may be half a
    step away: a closed form on a grid node is the bracket's upper end); the
    others at the bracket midpoint minus the closed form, at least half a step.
    Columns without a finite deviation (open brackets, infinite bounds) leave
    gaps, never lines across them; pooled sweeps (r repeats) are markers only.
    The legend is outside the axes.

    Parameters
    ----------
    agreements : mapping of str to Agreement
        Per method, from :func:`analysis.scoring.score_dataset`.
    title : str, optional
        Figure title.
    step : float, optional
        Grid step of beta (grid maps) or tolerance unit of a traced boundary.
    traced : bool
        The numerical boundaries were traced by bisection (labels say so).

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig = new_figure(7.8, 5.6)
    axes = fig.subplots(2, 1, sharex=True)
    unit = step if step and step > 0 else 1.0
    handles: dict[str, Line2D] = {}
    numerical = "traced" if traced else "grid"
    for ax, name in zip(axes, BOUNDARIES, strict=True):
        counts: list[str] = []
        ax.axhline(0.0, color="0.6", linewidth=0.8)
        if step:
            ax.axhspan(-0.5, 0.5, color="0.9", zorder=0)
        for method, a in agreements.items():
            dev = a.deviations.get(name)
            if dev is None:
                continue
            r, d = dev.r, dev.deviation / unit
            if dev.consistent is not None:  # the bracket holds the closed form: agreement
                d = np.where(dev.consistent & np.isfinite(d), 0.0, d)
            repeated = np.unique(r).size < r.size
            order = np.argsort(r, kind="stable")
            (line,) = ax.plot(
                r[order],
                d[order],  # NaN where nothing is compared: a gap
                linestyle="none" if repeated else LINESTYLES.get(method, "-"),
                color=_METHOD_COLOURS.get(method, "0.2"),
                linewidth=0.9,
                **_METHOD_MARKERS.get(method, {"marker": "o", "markersize": 3.5}),
            )
            line.set_label(f"{method} closed form")
            handles.setdefault(method, line)
            counts.append(f"{method} {int(np.isfinite(d).sum())}/{d.size}")
        what = "steps of beta" if step else "beta"
        ax.set_ylabel(rf"$\Delta\beta_{{\mathrm{{{name}}}}}$ ({what})", fontsize="small")
        ax.set_title(
            f"{name} boundary: {numerical} $-$ closed form\n"
            f"(columns compared: {', '.join(counts)})",
            fontsize="small",
        )
    axes[-1].set_xlabel(xlabel)
    legend = list(handles.values())
    if step:
        legend.append(Patch(facecolor="0.9", label="within half a grid step"))
        legend.append(Line2D([], [], linestyle="none", label="0: closed form in the bracket"))
    if legend:
        fig.legend(handles=legend, loc="outside right center", fontsize="small")
    if title:
        fig.suptitle(title)
    return fig


def response_figure(
    ds: xr.Dataset,
    mass: int = 1,
    frame: str = "absolute",
    n_beta: int = 7,
    title: str | None = None,
) -> Figure:
    """Den Hartog's plot, generalised: the amplitude of one mass (a structure: of the DOF
    ``mass - 1``, numbered from 0 as its contact) against r for several beta,
    the smallest amplitude over the grid's beta, and the beta that gives it.

    Parameters
    ----------
    ds : xarray.Dataset
        One (gamma, kappa) plane of a grid scene with the design quantities
        (a swept scene: its first plane).
    mass : int
        The mass whose amplitude is shown (1 = the mass on spring k_1).
    frame : {"absolute", "relative"}
        Absolute displacement, or relative to the base.
    n_beta : int
        Number of beta values of the grid drawn as curves (evenly spread).
    title : str, optional
        Figure title (default: the scene).

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib import colormaps

    from analysis.design import optimal_beta, response

    ds = ds.isel({d: 0 for d in sweep_dims(ds)})
    structure = ds.attrs.get("contact") == "matrices"
    who = f"DOF $x_{{{mass - 1}}}$" if structure else f"$m_{{{mass}}}$"
    amp = response(ds, mass, frame).transpose("beta", "r")
    best = optimal_beta(ds, mass, frame)
    r = ds["r"].values
    beta = ds["beta"].values
    picks = np.unique(np.linspace(0, beta.size - 1, min(n_beta, beta.size)).round().astype(int))
    values = amp.values
    finite = np.isfinite(values)
    hi = float(values[finite].max()) if finite.any() and values[finite].max() > 0 else 1.0
    # a log axis has no 0: an amplitude of 0 (a held mass, or an antiresonance at
    # beta = 0) is drawn as no line, and the r where the smallest amplitude is 0 as a
    # bar along the bottom; smaller positive values run off the bottom of the axis
    zero = finite & (values <= HELD_AMPLITUDE * hi)
    positive = values[finite & ~zero]
    floor = max(float(positive.min()) if positive.size else 1e-3, 1e-4 * hi)
    shown = np.where(finite & ~zero, values, np.nan)
    minimum = best["amplitude_minimum"].values
    held = np.isfinite(minimum) & (minimum <= HELD_AMPLITUDE * hi)
    envelope = np.where(held, np.nan, minimum)
    fig = new_figure(7.6, 6.2)
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=[3, 2])
    cmap = colormaps["viridis"]
    handles = []
    for n, i in enumerate(picks):
        colour = cmap(n / max(1, len(picks) - 1))
        (line,) = top.plot(r, shown[i], color=colour, linewidth=1.1)
        line.set_label(rf"$\beta$ = {beta[i]:.3g}")
        handles.append(line)
    (env,) = top.plot(r, envelope, color="k", linewidth=2.2, alpha=0.55, zorder=1)
    env.set_label("smallest over the grid's $\\beta$")
    handles.append(env)
    if held.any():
        edges = _edges(r)
        runs = np.flatnonzero(np.diff(np.concatenate(([0], held.astype(int), [0]))))
        for k, (a, b) in enumerate(zip(runs[::2], runs[1::2], strict=True)):
            bar = top.axvspan(edges[a], edges[b], ymin=0.0, ymax=0.035, color="0.35", lw=0)
            if k == 0:
                bar.set_label(f"smallest amplitude of {who} is 0")
                handles.append(bar)
    top.set_yscale("log")
    top.set_ylim(0.7 * floor, 1.5 * hi)
    which = "absolute" if frame == "absolute" else "relative to the base"
    top.set_ylabel(f"amplitude of {who} / Y ({which})", fontsize="small")
    top.set_xlim(float(r.min()), float(r.max()))
    # where the smallest amplitude is 0 the "optimum" is only the smallest beta that
    # holds the mass, the motion bound (drawn below): not an optimum, so not drawn
    optimum = np.where(held, np.nan, best["beta_optimal"].values)
    bottom.plot(r, optimum, "k.-", linewidth=0.9, markersize=3)
    if held.all():
        bottom.text(
            0.02,
            0.96,
            f"{who} is held (amplitude 0) at every r from the motion bound up:\n"
            "the smallest amplitude is 0 there, so no optimal $\\beta$ is drawn",
            transform=bottom.transAxes,
            ha="left",
            va="top",
            fontsize="small",
            bbox={"facecolor": "white", "edgecolor": "0.7", "alpha": 0.9},
        )
    for m in available_methods(ds, ("exact",)):
        for name in BOUNDARIES:
            bottom.plot(
                r,
                clip_to(ds[f"beta_{name}_{m}"].values, float(beta.min()), float(beta.max())),
                color=BOUNDARY_COLOURS[name],
                linewidth=0.8,
                linestyle=LINESTYLES[m],
            )
    bottom.set_ylim(float(beta.min()), float(beta.max()))
    bottom.set_ylabel(r"$\beta$ of the smallest amplitude", fontsize="small")
    bottom.set_xlabel(r_label(ds))
    marks = mark_frequencies(top, ds) | mark_frequencies(bottom, ds)
    handles.append(Line2D([], [], color="k", marker=".", label=r"optimal $\beta$ (grid)"))
    handles += [
        Line2D([], [], color=BOUNDARY_COLOURS[b], linewidth=0.8, label=f"{b} boundary (exact)")
        for b in BOUNDARIES
    ]
    handles += frequency_handles(marks)
    fig.legend(handles=handles, loc="outside right center", fontsize="small")
    fig.suptitle(title or scene_title(ds))
    return fig


# --------------------------------------------------------------------------- saving
def save_figure(fig: Figure, path: str | os.PathLike, dpi: int = 110) -> Path:
    """Write ``fig`` as PNG to ``path`` (parent folders created) and return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, format="png", dpi=dpi)
    return path


def save_regime_map(ds: xr.Dataset, path: str | os.PathLike, dpi: int = 110) -> Path:
    """Write :func:`regime_map_figure` of a scene as PNG."""
    return save_figure(regime_map_figure(ds), path, dpi)


def save_response(ds: xr.Dataset, path: str | os.PathLike, dpi: int = 110, **kw) -> Path:
    """Write :func:`response_figure` of a scene as PNG."""
    return save_figure(response_figure(ds, **kw), path, dpi)


def save_deviation(
    agreements: Mapping[str, Agreement], path: str | os.PathLike, dpi: int = 110, **kw
) -> Path:
    """Write :func:`deviation_figure` as PNG."""
    return save_figure(deviation_figure(agreements, **kw), path, dpi)
