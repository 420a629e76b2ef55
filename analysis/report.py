"""Markdown report of a result file: agreement scores, figures and provenance.

``write_report(result, out_dir)`` reads one netCDF4 result (a single scene at
the root, or one group per scene), scores every scene against the closed forms
("paper" and "exact", :mod:`analysis.scoring`), draws its figures
(:mod:`analysis.figures`) as PNG files in ``out_dir`` and writes
``out_dir/report.md`` linking them. The markdown is written last, to a
temporary name replaced into place, so an interrupted run never leaves a
``report.md`` that looks complete.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Iterable, Mapping, Sequence
from datetime import UTC, datetime
from pathlib import Path

import netCDF4
import numpy as np
import xarray as xr

from analysis import contacts, figures, starts
from analysis.scoring import (
    REGIME_ORDER,
    Agreement,
    is_adaptive,
    scene_kind,
    score_dataset,
    simulated_only,
    sweep_dims,
)
from tasks import regimes
from tasks.adaptive import VERIFY_AGREE, VERIFY_NONE, disagreement_upper_bound

#: At most this many undetermined points (or non-monotone columns) are listed per scene.
MAX_LISTED = 50
REPORT_NAME = "report.md"


# --------------------------------------------------------------------------- reading
def open_result(path: str | os.PathLike) -> tuple[dict[str, xr.Dataset], dict[str, object]]:
    """Scenes of a result file, loaded into memory, and its global attributes.

    Parameters
    ----------
    path : path-like
        A netCDF4 result: one scene at the root, or one group per scene.

    Returns
    -------
    scenes : dict of str to xarray.Dataset
        Scene name -> Dataset with the variables the report reads (``regime``
        and the ``beta_*`` boundaries) in memory; a root scene keeps the global
        attributes too.
    attrs : dict
        Global attributes (``study``, ``study_name``, ``history``, ``versions``, ...).
    """
    with netCDF4.Dataset(path) as nc:
        grouped = bool(nc.groups)
    if not grouped:
        with xr.open_dataset(path, engine="netcdf4") as ds:
            ds = _needed(ds).load()
        name = str(ds.attrs.get("scene_name") or Path(path).stem)
        return {name: ds}, dict(ds.attrs)
    tree = xr.open_datatree(path, engine="netcdf4")
    try:
        scenes = {
            str(name): _needed(node.to_dataset(inherit=False)).load()
            for name, node in tree.children.items()
        }
        return scenes, dict(tree.attrs)
    finally:
        tree.close()


def _needed(ds: xr.Dataset) -> xr.Dataset:
    """The variables the report reads (regime and boundaries), attributes kept."""
    wanted = (
        "regime",
        "regime_combined",
        "amplitude",
        "amplitude_relative",
        "simulated",
        "verification",
    )
    if "damping_matrix" in ds and "contact" in ds.dims:  # several damped contacts
        wanted += ("dissipation", "dissipation_viscous")  # analysis.contacts: energy table
    keep = [v for v in ds.data_vars if v in wanted or str(v).startswith("beta_")]
    keep += [v for v in ds.data_vars if v in starts.START_VARIABLES]
    keep += [v for v in ds.data_vars if "dof" in ds[v].dims]  # a structure's matrices
    return ds[keep].assign_attrs(ds.attrs)


# --------------------------------------------------------------------------- formatting
def _num(x: float, digits: int = 4) -> str:
    """A number for a table: ``n/a`` for NaN, ``inf`` for infinities."""
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "n/a"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return f"{x:.{digits}g}"


def percent(num: int, den: int, digits: int = 2) -> str:
    """``num / den`` in percent, never rounded to 100 % (or 0 %) unless exactly so.

    ``percent(7, 8) == "87.50 %"``, ``percent(24994, 24995) == "99.996 %"``; more
    digits are shown until a miss (or a hit) is visible, up to 6 decimals, then
    ``"> 99.999999 %"`` (``"< 0.000001 %"``).
    """
    if den == 0:
        return "n/a"
    value = 100.0 * num / den
    for d in range(digits, 7):
        text = f"{value:.{d}f}"
        if (num == den or float(text) < 100.0) and (num == 0 or float(text) > 0.0):
            return f"{text} %"
    return f"> {100 - 1e-6:.6f} %" if num < den and num > 0 and value > 50 else f"< {1e-6:.6f} %"


def _pct(num: int, den: int) -> str:
    """``87.50 % (7/8)``, or ``n/a (0/0)``."""
    return f"{percent(num, den)} ({num}/{den})"


def _table(header: Sequence[str], rows: Iterable[Sequence[object]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return lines + [""]


def _label(code: int) -> str:
    return regimes.name(code).replace("_", " ")


def _by_reason(counts: Mapping[int, int]) -> str:
    """``not_converged (-1): 3, event_limit (-3): 1`` or ``0``."""
    if not counts:
        return "0"
    return ", ".join(f"{regimes.name(c)} ({c}): {n}" for c, n in counts.items())


def _fence(text: str, lang: str = "") -> list[str]:
    fence = "~~~~" if "```" in text else "```"
    return [fence + lang, text.rstrip("\n"), fence, ""]


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name) or "scene"


# --------------------------------------------------------------------------- sections
def _summary(scores: Mapping[str, Mapping[str, Agreement]], kinds: Mapping[str, str]) -> list[str]:
    methods = sorted({m for s in scores.values() for m in s}, key=("paper", "exact").index)
    header = ["scene", "kind", "points", "determined", "not computed", "undetermined by reason"]
    header += [f"accuracy {m}" for m in methods]
    rows = []
    for name, by_method in scores.items():
        if not by_method:
            rows.append([f"`{name}`", kinds[name], "", "", "", "several contacts: its section"])
            continue
        a = next(iter(by_method.values()))
        if a.kind == "trace":
            n = a.numerical.r.size if a.numerical is not None else 0
            row = [f"`{name}`", "trace", f"{n} r values", "n/a", "n/a", "n/a"]
        elif kinds[name] == "adaptive":  # scored on the simulated points only
            n_sim = a.n_points - a.n_not_computed
            row = [f"`{name}`", "adaptive", f"{n_sim} simulated of {a.n_points}"]
            row += [a.n_determined, "0"]
            n = a.n_undetermined
            row.append(f"{n} ({_by_reason(a.undetermined_counts)})" if n else "0")
        else:
            row = [f"`{name}`", a.kind, a.n_points, a.n_determined, a.n_not_computed]
            n = a.n_undetermined
            row.append(f"{n} ({_by_reason(a.undetermined_counts)})" if n else "0")
        for m in methods:
            b = by_method.get(m)
            row.append("n/a" if b is None or b.kind == "trace" else _pct(b.n_correct, b.n_scored))
        rows.append(row)
    return ["## Summary", ""] + _table(header, rows)


def _scene_header(name: str, ds: xr.Dataset) -> list[str]:
    attrs = ds.attrs
    lines = [f"## Scene `{name}`", ""]
    title = figures.scene_title(ds)
    if title:
        lines += [title, ""]
    facts = [
        ("contact", attrs.get("contact")),
        ("dof", attrs.get("dof")),
        ("contact mass", attrs.get("contact_mass")),
        ("mode", attrs.get("mode")),
        ("layout", "adaptive grid" if is_adaptive(ds) else scene_kind(ds)),
        ("sweeps", ", ".join(f"{d} ({ds.sizes[d]})" for d in sweep_dims(ds)) or "none"),
        ("scene", attrs.get("scene")),
    ]
    lines += [f"- {k}: `{v}`" for k, v in facts if v is not None and v != ""]
    return lines + [""]


def _confusion(a: Agreement) -> list[str]:
    header = ["theory \\ simulation", *(_label(c) for c in REGIME_ORDER), "total"]
    rows = []
    for i, p in enumerate(REGIME_ORDER):
        rows.append([_label(p), *(int(v) for v in a.confusion[i]), int(a.confusion[i].sum())])
    rows.append(["total", *(int(v) for v in a.confusion.sum(axis=0)), a.n_scored])
    lines = [f"**{a.method}** (rows: closed form, columns: simulation): "]
    lines[0] += f"accuracy {_pct(a.n_correct, a.n_scored)}"
    if a.n_unpredicted:
        lines[0] += f"; {a.n_unpredicted} determined points without a prediction (NaN bound)"
    return lines + [""] + _table(header, rows)


def _per_regime(by_method: Mapping[str, Agreement]) -> list[str]:
    header = [
        "method",
        "regime",
        "by simulated regime (agree / simulated as)",
        "by predicted regime (agree / predicted as)",
    ]
    rows = []
    for m, a in by_method.items():
        col, row = a.confusion.sum(axis=0), a.confusion.sum(axis=1)
        for i, c in enumerate(REGIME_ORDER):
            diag = int(a.confusion[i, i])
            rows.append([m, _label(c), _pct(diag, int(col[i])), _pct(diag, int(row[i]))])
    return ["### Per-regime accuracy", ""] + _table(header, rows)


#: Relative deviations are shown only over columns whose closed form is at
#: least this many grid steps above zero (near zero they only measure the grid).
REL_MIN_STEPS = 10


def _max_rel(d, step: float | None) -> str:
    """Largest relative deviation over the columns where it means something."""
    cf = np.abs(d.closed_form)
    ok = np.isfinite(d.relative) & (cf >= REL_MIN_STEPS * step if step else cf > 0)
    return _num(float(np.max(d.relative[ok]))) if ok.any() else "n/a"


def grid_step(ds: xr.Dataset) -> float | None:
    """The beta step of a grid scene (None for traced scenes and point lists)."""
    if "beta" not in ds.dims or ds.sizes["beta"] < 2:
        return None
    return float(np.median(np.diff(np.sort(ds["beta"].values))))


def _deviations(by_method: Mapping[str, Agreement], step: float | None = None) -> list[str]:
    header = [
        "boundary",
        "method",
        "compared / columns",
        "closed form inside bracket",
        "max abs",
        "median abs",
    ]
    if step:
        header += ["max abs (grid steps)", "median abs (grid steps)"]
    header += [f"max rel (closed form >= {REL_MIN_STEPS} steps)" if step else "max rel"]
    rows = []
    for m, a in by_method.items():
        for name, d in a.deviations.items():
            cons = d.n_consistent
            row = [
                name,
                m,
                f"{d.n_compared} / {d.n_columns}",
                "n/a (traced)" if cons is None else f"{cons} / {d.n_columns}",
                _num(d.max_abs),
                _num(d.median_abs),
            ]
            if step:
                row += [_num(d.max_abs / step, 3), _num(d.median_abs / step, 3)]
            rows.append([*row, _max_rel(d, step)])
    if not rows:
        return []
    lines = ["### Boundary deviation (numerical - closed form)", ""]
    lines += [
        "Numerical boundary per r column: midpoint of the bracket between the last beta "
        "of the bottom run of continuous points and the next determined beta "
        "(continuous / stick-slip), and between the last moving beta and the first beta "
        "of the top run of no-motion points (stick-slip / no motion). Columns with an open "
        "bracket or an infinite closed form are not compared; relative = |deviation| / "
        "|closed form|, only where the closed form is clear of zero. A grid locates a "
        "boundary to half a beta step: deviations below 0.5 steps are grid resolution.",
        "",
    ]
    lines += _table(header, rows)
    a = next(iter(by_method.values()))
    if a.numerical is not None and a.kind != "trace":
        bad = a.numerical.non_monotone
        r = a.numerical.r[bad]
        shown = ", ".join(_num(float(x)) for x in r[:MAX_LISTED])
        more = f" ... and {r.size - MAX_LISTED} more" if r.size > MAX_LISTED else ""
        lines += [
            f"- non-monotone columns: {int(bad.sum())} of {bad.size}"
            + (f" (r = {shown}{more})" if r.size else ""),
            f"- columns with skipped (undetermined or not computed) points: "
            f"{int((a.numerical.n_skipped > 0).sum())}; brackets widened over them: "
            f"continuous {int(a.numerical.skipped_in_bracket[:, 0].sum())}, "
            f"motion {int(a.numerical.skipped_in_bracket[:, 1].sum())}",
            "",
        ]
    return lines


def _planes(by_method: Mapping[str, Agreement]) -> list[str]:
    first = next(iter(by_method.values()))
    if not first.planes:
        return []
    dims = list(first.planes[0][0])
    header = [*dims, "points", "undetermined", "not computed"]
    header += [f"accuracy {m}" for m in by_method]
    rows = []
    for k, (coords, plane) in enumerate(first.planes):
        row = [_num(coords[d]) for d in dims]
        if plane.kind == "trace":
            row += [plane.numerical.r.size, "n/a", "n/a"]
            row += ["n/a" for _ in by_method]
        else:
            row += [plane.n_points, plane.n_undetermined, plane.n_not_computed]
            for a in by_method.values():
                p = a.planes[k][1]
                row.append(_pct(p.n_correct, p.n_scored))
        rows.append(row)
    return ["### Sweep planes", ""] + _table(header, rows)


def _undetermined(a: Agreement) -> list[str]:
    pts = a.undetermined
    lines = ["### Undetermined points", ""]
    if not len(pts):
        return lines + ["None.", ""]
    lines += [f"{len(pts)} point(s): {_by_reason(pts.counts())}.", ""]
    names = list(pts.coords)
    header = ["reason (code)", f"index ({', '.join(pts.dims)})", *names]
    rows = [
        [f"{row['reason']} ({row['code']})", str(row["index"]), *(_num(row[k]) for k in names)]
        for row in pts.rows()[:MAX_LISTED]
    ]
    lines += _table(header, rows)
    if len(pts) > MAX_LISTED:
        lines += [f"... and {len(pts) - MAX_LISTED} more not listed (total {len(pts)}).", ""]
    return lines


def _adaptive(ds: xr.Dataset, whole: Mapping[str, Agreement] | None) -> list[str]:
    """Simulated fraction, verification sample and whole-map agreement of an adaptive map."""
    simulated = ds["simulated"].values.astype(bool)
    lines = ["### Adaptive map", ""]
    lines += [
        f"- simulated: {int(simulated.sum())} of {simulated.size} points "
        f"({percent(int(simulated.sum()), simulated.size)}, verification included); "
        "the others copy every field from the nearest simulated corner of a uniform cell"
    ]
    if "verification" in ds:
        v = ds["verification"].values
        sampled = int((v != VERIFY_NONE).sum())
        agree = int((v == VERIFY_AGREE).sum())
        if sampled:
            bound = disagreement_upper_bound(sampled, sampled - agree)
            lines += [
                f"- verification: {sampled} inferred points simulated, {agree} agree "
                f"({percent(agree, sampled)}; disagreement below {100 * bound:.2f} % at 95 % "
                "confidence)"
            ]
        else:
            lines += ["- verification: no inferred point was sampled"]
    for m, a in (whole or {}).items():
        if a.kind != "trace":
            lines += [
                f"- {m} closed form, all points (inferred included): "
                f"{_pct(a.n_correct, a.n_scored)}"
            ]
    return lines + [""]


def _scene_section(
    name: str,
    ds: xr.Dataset,
    by_method: Mapping[str, Agreement],
    images: Sequence[Path],
    whole: Mapping[str, Agreement] | None = None,
) -> list[str]:
    lines = _scene_header(name, ds)
    lines += [f"![{p.stem}]({p.name})" for p in images] + [""]
    if ds.attrs.get("design_quantities") == "off" and scene_kind(ds) == "grid":
        lines += [
            "No response figure: the design quantities (amplitudes, contact force, dissipation)"
            " were not computed, as by default; add `design = true` to the study's `[settings]`"
            " to compute them.",
            "",
        ]
    if not by_method:
        return lines + ["No closed-form bounds in this scene: nothing scored.", ""] + _starts(ds)
    first = next(iter(by_method.values()))
    if is_adaptive(ds):
        lines += _adaptive(ds, whole)
    if first.kind != "trace":
        lines += ["### Confusion matrices", ""]
        if is_adaptive(ds):
            lines += ["Simulated points only (inferred points: the verification sample above).", ""]
        for a in by_method.values():
            lines += _confusion(a)
        lines += _per_regime(by_method)
    # the boundaries of an adaptive map are read from the whole map (resolved to a step)
    lines += _deviations(whole if whole and is_adaptive(ds) else by_method, grid_step(ds))
    lines += _planes(by_method)
    if first.kind != "trace":
        lines += _undetermined(first)
    lines += _starts(ds)
    return lines


def _starts(ds: xr.Dataset) -> list[str]:
    """Where the regime depends on the start (results classified from several starts)."""
    counts = starts.start_counts(ds)
    if not counts:
        return []
    lines = ["### Dependence on the start", ""]
    lines += [
        f"{counts['start_dependent']} of {counts['points']} points reach different regimes "
        "from different starts (`start_dependent`)"
        + (
            f"; {counts['asymptotic']} reach no motion asymptotically (`asymptotic`, a creep)"
            if "asymptotic" in counts
            else ""
        )
        + (
            f"; {counts['undetermined_from_a_start']} are undetermined from at least one start"
            if "undetermined_from_a_start" in counts
            else ""
        )
        + ".",
        "",
    ]
    return lines


def _provenance(attrs: Mapping[str, object], scenes: Mapping[str, xr.Dataset]) -> list[str]:
    lines = ["## Provenance", ""]
    lines += [f"- study: `{attrs.get('study_name', 'unknown')}`"]
    if attrs.get("title"):
        lines += [f"- title: {attrs['title']}"]
    fid = sorted(
        {str(ds.attrs.get("fidelity")) for ds in scenes.values() if "fidelity" in ds.attrs}
    )
    lines += [f"- fidelity: {', '.join(f'`{f}`' for f in fid) or 'unknown'}", ""]
    settings = {str(ds.attrs["settings"]) for ds in scenes.values() if "settings" in ds.attrs}
    lines += ["### Resolved settings", ""]
    for text in sorted(settings) or ["{}"]:
        try:
            text = json.dumps(json.loads(text), indent=2, sort_keys=True)
        except json.JSONDecodeError:
            pass
        lines += _fence(text, "json")
    lines += ["### Package versions", ""]
    try:
        versions = json.loads(str(attrs.get("versions", "{}")))
    except json.JSONDecodeError:
        versions = {"versions": str(attrs.get("versions"))}
    lines += _table(["package", "version"], sorted(versions.items())) if versions else ["n/a", ""]
    lines += ["### History", ""] + _fence(str(attrs.get("history", "n/a")))
    lines += ["### Study", ""] + _fence(str(attrs.get("study", "n/a")), "toml")
    return lines


# --------------------------------------------------------------------------- figures
def _scene_figures(
    name: str, ds: xr.Dataset, by_method: Mapping[str, Agreement], out_dir: Path
) -> list[Path]:
    stem = _safe(name)
    paths = [figures.save_regime_map(ds, out_dir / f"{stem}_map.png")]
    fig = starts.start_dependence_figure(ds, title=None)
    if fig is not None and starts.start_counts(ds)["start_dependent"] > 0:
        paths.append(figures.save_figure(fig, out_dir / f"{stem}_starts.png"))
    if by_method and any(a.deviations for a in by_method.values()):
        title = f"{figures.scene_title(ds)}: boundary deviation"
        paths.append(
            figures.save_deviation(
                by_method,
                out_dir / f"{stem}_deviation.png",
                title=title,
                step=grid_step(ds),
                traced=scene_kind(ds) == "trace",
                xlabel=figures.r_label(ds),
            )
        )
    if scene_kind(ds) == "grid" and "mass" in ds.get("amplitude", xr.DataArray()).dims:
        paths.append(figures.save_response(ds, out_dir / f"{stem}_response.png"))
    return paths


# --------------------------------------------------------------------------- entry point
def build_report(
    result_path: str | os.PathLike, out_dir: str | os.PathLike
) -> tuple[str, list[Path]]:
    """Score every scene, write its figures into ``out_dir`` and return the markdown text.

    Parameters
    ----------
    result_path : path-like
        The netCDF4 result file.
    out_dir : path-like
        Existing folder for the PNG files.

    Returns
    -------
    text : str
        The markdown report.
    images : list of pathlib.Path
        The PNG files written.
    """
    out_dir = Path(out_dir)
    scenes, attrs = open_result(result_path)
    # several contacts: no closed form bounds them, nothing scored (analysis.contacts)
    whole = {
        name: {} if contacts.is_multi(ds) else score_dataset(ds) for name, ds in scenes.items()
    }
    # an adaptive map is scored on its simulated points (the map itself for boundaries)
    scores = {
        name: score_dataset(simulated_only(ds))
        if is_adaptive(ds) and not contacts.is_multi(ds)
        else whole[name]
        for name, ds in scenes.items()
    }
    kinds = {name: "adaptive" if is_adaptive(ds) else scene_kind(ds) for name, ds in scenes.items()}
    stamp = datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    lines = [
        f"# Report: study `{attrs.get('study_name', Path(result_path).stem)}`",
        "",
        f"Result file `{Path(result_path).name}`, {len(scenes)} scene(s); report written {stamp}.",
        'Theory = closed-form boundaries ("paper": Marino & Cicirello 2021, Eqs. 13 and 53 '
        'with S = 1 and the motion bounds, docs/theory.md 4.1-4.2; "exact": docs/theory.md 4.3); '
        "predicted continuous for beta < beta_continuous, no motion for beta >= beta_motion, "
        "stick-slip otherwise (regime codes: docs/regimes.md). Accuracy counts determined "
        "points only.",
        "",
    ]
    lines += _summary(scores, kinds)
    images: list[Path] = []
    for name, ds in scenes.items():
        if contacts.is_multi(ds):
            more, paths = contacts.section(name, ds, out_dir, _safe(name))
            images += paths
            lines += more
            continue
        paths = _scene_figures(name, ds, whole[name], out_dir)
        images += paths
        lines += _scene_section(name, ds, scores[name], paths, whole[name])
    lines += _provenance(attrs, scenes)
    return "\n".join(lines), images


def write_report(result_path: str | os.PathLike, out_dir: str | os.PathLike) -> Path:
    """Write ``out_dir/report.md`` and its PNG figures for a result file.

    Parameters
    ----------
    result_path : path-like
        The netCDF4 result file (``study run`` output).
    out_dir : path-like
        Output folder, created if needed.

    Returns
    -------
    pathlib.Path
        The path of ``report.md``. Any earlier ``report.md`` in ``out_dir`` is
        removed first; the new one is written to a temporary name and moved
        into place only when complete.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / REPORT_NAME
    target.unlink(missing_ok=True)  # a failed run must not leave an older report looking current
    text, _ = build_report(result_path, out_dir)
    tmp = out_dir / f".{REPORT_NAME}.{os.getpid()}.tmp"
    try:
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, target)
    finally:
        if tmp.exists():
            tmp.unlink()
    return target
