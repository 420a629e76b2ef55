"""Report sections and figures of a scene with several contacts (docs/contacts.md).

A result of several contacts has per-contact fields on a dim ``contact`` and a
per-point ``regime_combined`` (``sum_c regime_c 3^c``, docs/results.md). No
closed form gives the regimes of several contacts in general; the closed forms
of one contact with the other contacts held (:mod:`analysis.contact_bounds`)
are drawn where they mean something: on each contact's map (its regime where
every other contact is in no motion) and on the combined map (the boundary of
every contact stuck). Each section says what they bound and counts the points
where they apply and agree.
"""

from __future__ import annotations

import itertools
from collections import Counter
from pathlib import Path

import numpy as np
import xarray as xr
from matplotlib import colormaps
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from analysis import contact_bounds, figures
from tasks import regimes
from tasks.multicontact import MultiScene

#: What the drawn closed forms bound, in every several-contact section.
DAMPED_NOTE = (
    "A **damped** structure (viscous damping in every stuck set, docs/contacts.md 7): the "
    "closed forms of one contact drawn for undamped scenes are not drawn here. The energy "
    "dissipated per excitation cycle by the contacts' friction (`dissipation`, per "
    "contact) and by the damping (`dissipation_viscous`) add up to the work of the load."
)
BOUNDS_NOTE = (
    "Closed forms of one contact (docs/theory.md 4, exact method) with the **other "
    "contacts held** (frictionless ones free) are drawn on each contact's map (dashed: "
    "continuous bound, solid: motion bound, in units of beta, i.e. divided by the "
    "contact's beta_ratio) only where every other contact with friction is in no motion: "
    "there the motion is the held structure's and they give that contact's regime; "
    "elsewhere they bound nothing. On the combined map, the largest held motion bound is "
    "the exact boundary of every contact with friction stuck (the held margin of "
    "docs/contacts.md 4). With the other contacts **free** (removed) the closed forms bound "
    "nothing unless the others are frictionless (a sliding contact still carries its "
    "friction): they are not drawn (docs/contacts.md 8)."
)
#: Planes of a swept result drawn (one figure each); the others are counted only.
MAX_PLANES = 4
#: r values of the drawn closed-form curves (over the map's r range).
CURVE_POINTS = 300


def is_multi(ds: xr.Dataset) -> bool:
    """A result of several contacts (a dim ``contact``)."""
    return "contact" in ds.dims


def combined_name(code: int, k: int) -> str:
    """``c0 stick slip, c1 no motion`` for a combined code (an undetermined code's name)."""
    if code < 0:
        return regimes.name(int(code)).replace("_", " ")
    digits = [(code // 3**c) % 3 for c in range(k)]
    return ", ".join(f"c{c} {regimes.REGIMES[d].replace('_', ' ')}" for c, d in enumerate(digits))


def _where(ds: xr.Dataset) -> list[str]:
    where = ds["contact_where"].values if "contact_where" in ds.coords else ds["contact"].values
    ratio = ds["beta_ratio"].values if "beta_ratio" in ds.coords else np.ones(ds.sizes["contact"])
    return [f"{w} (beta_ratio {float(b):g})" for w, b in zip(where, ratio, strict=True)]


def _colours(codes: list[int], k: int) -> list:
    """One discrete colour per combined code present (undetermined codes: their regime colour)."""
    cmap = colormaps["tab20"] if 3**k > 10 else colormaps["tab10"]
    return [figures._colour(c) if c < 0 else cmap(c % cmap.N) for c in codes]


def contacts_figure(ds: xr.Dataset, title: str = "", scene: MultiScene | None = None) -> Figure:
    """The combined map (one colour per combined label present) and each contact's
    regime map of one (r, beta) plane; with ``scene``, the closed forms of each contact
    with the others held and the all-stuck boundary (:mod:`analysis.contact_bounds`)."""
    k = ds.sizes["contact"]
    fig = figures.new_figure(4.2 * (k + 1), 4.4)
    axes = fig.subplots(1, k + 1, sharey=True)
    r, beta = ds["r"].values, ds["beta"].values
    combined = ds["regime_combined"].transpose("r", "beta").values
    codes = sorted(set(np.unique(combined).tolist()))
    colours = _colours(codes, k)
    ax = axes[0]
    ir, ib = np.argsort(r), np.argsort(beta)
    index = np.searchsorted(codes, combined[np.ix_(ir, ib)])
    ax.pcolormesh(
        figures._edges(r[ir]),
        figures._edges(beta[ib]),
        index.T,
        cmap=ListedColormap(colours),
        vmin=-0.5,
        vmax=len(codes) - 0.5,
        shading="flat",
        rasterized=True,
    )
    ax.set_xlim(figures._edges(r[ir])[[0, -1]])
    ax.set_ylim(figures._edges(beta[ib])[[0, -1]])
    ax.set_xlabel(figures.R_LABEL)
    ax.set_ylabel(figures.BETA_LABEL)
    ax.set_title("combined")
    handles = [
        Patch(facecolor=col, edgecolor="0.3", label=combined_name(c, k))
        for c, col in zip(codes, colours, strict=True)
    ]
    present: set[int] = set()
    where = _where(ds)
    for c in range(k):
        regime = ds["regime"].isel(contact=c).transpose("r", "beta").values
        present |= figures.draw_regime_map(axes[c + 1], regime, r, beta)
        axes[c + 1].set_title(f"contact {c}: {where[c]}", fontsize=9)
        axes[c + 1].set_ylabel("")
    lines = []
    if scene is not None:
        rc = np.linspace(r.min(), r.max(), CURVE_POINTS)
        cont, motion = contact_bounds.held_bounds(scene, rc)
        lim = figures._edges(beta[ib])[[0, -1]]
        curves = [(axes[0], contact_bounds.all_stuck_bound(motion), "-")]
        for c in range(k):  # only where every other contact is in no motion
            for values, style in ((cont[c], "--"), (motion[c], "-")):
                inside = figures.clip_to(values, *lim)
                curves.append((axes[c + 1], contact_bounds.where_held(ds, c, rc, inside), style))
        for ax_c, values, style in curves:
            ax_c.plot(rc, figures.clip_to(values, *lim), color="k", linestyle=style, lw=1.2)
            ax_c.set_ylim(*lim)
        lines = [
            Line2D([], [], color="k", linestyle="--", label="continuous, others held"),
            Line2D([], [], color="k", label="no motion, others held (combined: all stuck)"),
        ]
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2, fontsize=7)
    axes[-1].legend(
        handles=figures.regime_handles(sorted(present)) + lines,
        loc="upper center",
        bbox_to_anchor=(0.5, -0.14),
        ncol=2,
        fontsize=7,
    )
    if title:
        fig.suptitle(title)
    return fig


def _counts_table(values: np.ndarray, name_of) -> list[str]:
    counts = Counter(np.asarray(values).ravel().tolist())
    total = sum(counts.values())
    rows = ["| label | points | share |", "|---|---|---|"]
    for code in sorted(counts, reverse=True):
        rows.append(f"| {name_of(code)} | {counts[code]} | {100.0 * counts[code] / total:.1f} % |")
    return rows + [""]


def planes(ds: xr.Dataset):
    """(label, plane) of each (r, beta) plane of a grid result: one per combination of
    the swept ratios (``gamma = 0.5, kappa = 1.4``), or the result itself."""
    sweeps = [d for d in ds["regime_combined"].dims if d not in ("beta", "r")]
    for idx in itertools.product(*(range(ds.sizes[d]) for d in sweeps)):
        plane = ds.isel(dict(zip(sweeps, idx, strict=True)))
        label = ", ".join(f"{d} = {float(plane[d]):g}" for d in sweeps)
        yield label, plane


def _agreement_rows(counts: list[tuple[int, int]], where: list[str]) -> list[str]:
    rows = [
        "| contact | points where every other contact is in no motion | agree with the held "
        "closed forms | share |",
        "|---|---|---|---|",
    ]
    for c, (n, agree) in enumerate(counts):
        share = f"{100.0 * agree / n:.1f} %" if n else "-"
        rows.append(f"| {c}: {where[c]} | {n} | {agree} | {share} |")
    return rows + [""]


def adaptive_line(ds: xr.Dataset) -> str:
    """``- adaptive: ...`` of an adaptive map refined on the combined label."""
    n, sim = int(ds["simulated"].size), int(ds["simulated"].values.sum())
    line = (
        f"- adaptive: {sim} of {n} points simulated ({100.0 * sim / n:.1f} %), refined on "
        "`regime_combined`"
    )
    sampled = int(ds.attrs.get("verification_sampled", 0))
    if sampled:
        agree = int(ds.attrs["verification_agree"])
        line += f"; verification: {agree} of {sampled} inferred labels confirmed by simulation"
    return line


def _viscous_rows(ds: xr.Dataset) -> list[str]:
    """The energy dissipated per excitation cycle, friction (every contact) and viscous,
    over the converged points of a damped scene (docs/contacts.md 7)."""
    if "dissipation_viscous" not in ds:
        return []
    ok = ds["regime_combined"].values >= 0  # every contact's regime determined
    if not ok.any():
        return []
    friction = ds["dissipation"].sum("contact").values[ok]
    viscous = ds["dissipation_viscous"].values[ok]
    total = friction + viscous
    share = np.divide(viscous, total, out=np.zeros_like(total), where=total > 0.0)
    return [
        "| per excitation cycle (converged points) | median | max |",
        "|---|---|---|",
        f"| friction, all contacts | {np.median(friction):.4g} | {friction.max():.4g} |",
        f"| viscous | {np.median(viscous):.4g} | {viscous.max():.4g} |",
        f"| viscous share of the total | {np.median(share):.3g} | {share.max():.3g} |",
        "",
    ]


def section(name: str, ds: xr.Dataset, out_dir: Path, stem: str) -> tuple[list[str], list[Path]]:
    """The report section of a several-contact scene and its figures."""
    k = ds.sizes["contact"]
    images: list[Path] = []
    where = _where(ds)
    grid = "beta" in ds.dims and "r" in ds.dims and set(ds["regime"].dims) >= {"contact", "r"}
    counts = [(0, 0)] * k
    n_planes = 0
    title = ds.attrs.get("scene_name", name)
    damped = "damping_matrix" in ds  # the closed forms of contact_bounds are undamped
    for label, plane in planes(ds) if grid else ():
        scene = None if damped else contact_bounds.scene_of(plane)
        if scene is not None:
            found = contact_bounds.held_agreement(plane, scene)
            counts = [(a + n, b + m) for (a, b), (n, m) in zip(counts, found, strict=True)]
        if n_planes < MAX_PLANES:
            fig = contacts_figure(
                plane,
                title=f"{title}: {k} contacts" + (f" ({label})" if label else ""),
                scene=scene,
            )
            suffix = f"_{n_planes}" if label else ""
            images.append(figures.save_figure(fig, out_dir / f"{stem}_contacts{suffix}.png"))
        n_planes += 1
    lines = [f"## Scene `{name}`", ""]
    lines += [f"- {key}: `{ds.attrs[key]}`" for key in ("dof", "mode", "scene") if key in ds.attrs]
    if "simulated" in ds:  # an adaptive map (docs/adaptive.md): refined on regime_combined
        lines.append(adaptive_line(ds))
    lines += [""] + [f"![{p.stem}]({p.name})" for p in images] + [""]
    if n_planes > MAX_PLANES:
        lines += [f"Figures of the first {MAX_PLANES} of {n_planes} planes.", ""]
    if damped:
        lines += [DAMPED_NOTE, ""]
        lines += _viscous_rows(ds)
    else:
        lines += [BOUNDS_NOTE, ""]
    if grid and not damped:
        lines += ["### Closed forms with the other contacts held", ""]
        lines += _agreement_rows(counts, where)
    lines += [
        "### Combined regimes",
        "",
        "`regime_combined` = sum over contacts c of regime_c * 3^c when every contact's "
        "regime is determined, else the most severe undetermined code.",
        "",
    ]
    lines += _counts_table(ds["regime_combined"].values, lambda c: combined_name(int(c), k))
    for c, label in enumerate(where):
        lines += [f"### Contact {c}: {label}", ""]
        lines += _counts_table(
            ds["regime"].isel(contact=c).values,
            lambda code: regimes.name(int(code)).replace("_", " "),
        )
    return lines, images
