"""Report sections and figures of a scene with several contacts (docs/contacts.md).

A result of several contacts has per-contact fields on a dim ``contact`` and a
per-point ``regime_combined`` (``sum_c regime_c 3^c``, docs/results.md). No
closed form bounds the regimes of several contacts: the closed forms of one
contact (docs/theory.md 4) assume the other contacts absent, and a second
contact changes both the load path and the dynamic stiffness seen by the
first. The report therefore scores nothing here and draws no boundaries.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import xarray as xr
from matplotlib import colormaps
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from analysis import figures
from tasks import regimes

#: The note every several-contact section carries.
NO_BOUNDS = (
    "No closed form bounds the regimes of several contacts: the closed forms of one "
    "contact (docs/theory.md 4) assume the other contacts absent, and another contact's "
    "friction changes the load path and the dynamic stiffness the first contact sees. "
    "Nothing is scored and no boundary is drawn (docs/contacts.md)."
)


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


def contacts_figure(ds: xr.Dataset, title: str = "") -> Figure:
    """The combined map (one colour per combined label present) and each contact's
    regime map, for an (r, beta) grid without sweeps."""
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
    ax.set_xlabel(figures.R_LABEL)
    ax.set_ylabel(figures.BETA_LABEL)
    ax.set_title("combined")
    handles = [
        Patch(facecolor=col, edgecolor="0.3", label=combined_name(c, k))
        for c, col in zip(codes, colours, strict=True)
    ]
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2, fontsize=7)
    present: set[int] = set()
    where = _where(ds)
    for c in range(k):
        regime = ds["regime"].isel(contact=c).transpose("r", "beta").values
        present |= figures.draw_regime_map(axes[c + 1], regime, r, beta)
        axes[c + 1].set_title(f"contact {c}: {where[c]}", fontsize=9)
        axes[c + 1].set_ylabel("")
    axes[-1].legend(handles=figures.regime_handles(sorted(present)), loc="upper left", fontsize=8)
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


def section(name: str, ds: xr.Dataset, out_dir: Path, stem: str) -> tuple[list[str], list[Path]]:
    """The report section of a several-contact scene and its figures."""
    k = ds.sizes["contact"]
    images: list[Path] = []
    grid = (
        "beta" in ds.dims and "r" in ds.dims and set(ds["regime"].dims) == {"contact", "beta", "r"}
    )
    if grid:
        title = ds.attrs.get("scene_name", name)
        fig = contacts_figure(ds, title=f"{title}: {k} contacts")
        images.append(figures.save_figure(fig, out_dir / f"{stem}_contacts.png"))
    lines = [f"## Scene `{name}`", ""]
    lines += [f"- {key}: `{ds.attrs[key]}`" for key in ("dof", "mode", "scene") if key in ds.attrs]
    lines += [""] + [f"![{p.stem}]({p.name})" for p in images] + [""]
    lines += [NO_BOUNDS, ""]
    lines += [
        "### Combined regimes",
        "",
        "`regime_combined` = sum over contacts c of regime_c * 3^c when every contact's "
        "regime is determined, else the most severe undetermined code.",
        "",
    ]
    lines += _counts_table(ds["regime_combined"].values, lambda c: combined_name(int(c), k))
    for c, where in enumerate(_where(ds)):
        lines += [f"### Contact {c}: {where}", ""]
        lines += _counts_table(
            ds["regime"].isel(contact=c).values,
            lambda code: regimes.name(int(code)).replace("_", " "),
        )
    return lines, images
