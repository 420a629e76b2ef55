"""``study bench``: cost and accuracy of every fidelity preset and of the paper's method.

On a fixed mixed set of scenes (:data:`SCENES`) and a fixed, seeded set of
points per scene (:func:`bench_points`: half spread over r in [0.1, 3] and beta
in [0, 1.2 beta_motion(r)], half 2-15 % below or above one of the closed-form
boundaries of ``analysis.boundaries(scene, r, method="exact")``), every preset
of :mod:`tasks.fidelity` and the baseline (:func:`tasks.baseline.paper_method`:
RK45 + events, 100 cycles from rest, pure scipy) are measured for

* **time per point**: wall time of one vectorised ``classify`` call per scene
  (best of a few repeats, after a warm-up call, so compile time is excluded), or
  of the baseline's loop over the points;
* **disagreement** with the highest-fidelity result (the ``exact`` preset):
  fraction of all points with another regime code (undetermined counts as
  disagreement);
* **undetermined** points (negative regime codes);
* **wrong side**: fraction of the near-boundary points classified on the wrong
  side of the closed-form boundary they are near (continuous below / not
  continuous above the continuous bound; motion below / no motion above the
  motion bound);
* **boundary error**: at a few r per scene, each boundary located by bisection
  in beta (bracket 0.7-1.3 times the closed-form value) with the method, and
  compared with the one located by the ``exact`` preset (relative error).

The two closed-form predictions (``analysis.predict``, S = 1 and exact S) are
listed too, as zero-simulation methods. Results: ``bench.md`` (Markdown tables
with the machine) and ``pareto.png`` (time per point vs disagreement, log axes)
in the output directory. Entry point: :func:`main_bench`.
"""

from __future__ import annotations

import math
import os
import platform
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tasks import PRESETS, Scene, classify, regimes
from tasks.baseline import paper_method

__all__ = ["SCENES", "BenchResult", "bench_points", "main_bench", "run_bench", "write_bench"]

#: The fixed mixed set of scenes (label -> Scene).
SCENES: dict[str, Scene] = {
    "sdof_ground": Scene("ground", 1),
    "sdof_base": Scene("base", 1),
    "2dof_ground_m1": Scene("ground", 2, 1, gamma=1.0, kappa=1.0),
    "2dof_ground_m2": Scene("ground", 2, 2, gamma=0.8, kappa=1.5),
    "2dof_base_m1": Scene("base", 2, 1, gamma=1.5, kappa=0.8),
    "2dof_base_m2": Scene("base", 2, 2, gamma=1.0, kappa=1.0),
    "2dof_mass": Scene("mass", 2, 1, gamma=0.8, kappa=1.5),
    "5dof_ground_m4": Scene("ground", 5, 4),
}
SEED = 2021_0104
R_RANGE = (0.1, 3.0)
BETA_FACTOR = 1.2
"""Spread points: beta in [0, BETA_FACTOR * min(beta_motion, BETA_CAP)]."""
BETA_CAP = 5.0
NEAR_OFFSET = (0.02, 0.15)
"""Near-boundary points: relative distance from the boundary (as in the reference cases)."""
SEPARATION = 0.7
"""Near-boundary points need beta_continuous < SEPARATION * beta_motion (distinct sides)."""
BRACKET = (0.7, 1.33)
"""Bisection bracket in units of the closed-form boundary."""
BASELINE = "baseline"
REFERENCE = "exact"
CLOSED_FORMS = ("closed form, S = 1", "closed form, exact S")

#: Sizes of the full and the quick benchmark.
SIZES = {
    False: {"points": 32, "bisect_r": 2, "bisect_steps": 10, "baseline_bisect": True},
    True: {"points": 3, "bisect_r": 1, "bisect_steps": 6, "baseline_bisect": False},
}


# ----------------------------------------------------------------------------- points
@dataclass
class ScenePoints:
    """The benchmark points of one scene.

    ``near`` is 0 for a spread point, 1 near the continuous bound, 2 near the
    motion bound; ``side`` is -1 below / +1 above that bound (0 for spread).
    """

    r: np.ndarray
    beta: np.ndarray
    near: np.ndarray
    side: np.ndarray
    bisect_r: np.ndarray
    b_cont: np.ndarray  # closed-form exact bounds at bisect_r
    b_motion: np.ndarray


def _bounds(scene: Scene, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    from analysis.closed_form import boundaries

    return boundaries(scene, r, method="exact")


def _separated(scene: Scene, r: np.ndarray) -> np.ndarray:
    """Where both boundaries are finite, non-trivial and well apart."""
    bc, bm = _bounds(scene, r)
    return (bc > 1e-3) & np.isfinite(bm) & (bm < BETA_CAP) & (bc < SEPARATION * bm)


def bench_points(scene: Scene, n: int, n_bisect: int, seed: int) -> ScenePoints:
    """Fixed, seeded points of one scene (see the module docstring)."""
    rng = np.random.default_rng(seed)
    n_spread = (n + 1) // 2
    r_s = rng.uniform(*R_RANGE, n_spread)
    _, bm = _bounds(scene, r_s)
    beta_s = rng.uniform(0.0, 1.0, n_spread) * BETA_FACTOR * np.minimum(bm, BETA_CAP)
    # near-boundary points: r where the two sides are distinct, by rejection
    cand = rng.uniform(*R_RANGE, 512)
    cand = cand[_separated(scene, cand)]
    n_near = n - n_spread
    if cand.size < n_near:
        raise RuntimeError(f"{scene.label}: too few r with separated boundaries")
    r_n = cand[:n_near]
    bc, bm = _bounds(scene, r_n)
    near = np.where(np.arange(n_near) % 2 == 0, 1, 2)
    side = np.where(rng.uniform(size=n_near) < 0.5, -1, 1)
    offset = rng.uniform(*NEAR_OFFSET, n_near)
    beta_n = np.where(near == 1, bc, bm) * (1.0 + side * offset)
    # bisection r: evenly spaced candidates with separated boundaries
    grid = np.linspace(0.3, 2.9, 27)
    ok = grid[_separated(scene, grid)]
    quantiles = (np.arange(n_bisect) + 0.5) / max(n_bisect, 1)
    pick = ok[(quantiles * ok.size).astype(int)] if ok.size else ok
    bcb, bmb = _bounds(scene, pick)
    return ScenePoints(
        r=np.concatenate((r_s, r_n)),
        beta=np.concatenate((beta_s, beta_n)),
        near=np.concatenate((np.zeros(n_spread, int), near)),
        side=np.concatenate((np.zeros(n_spread, int), side)),
        bisect_r=pick,
        b_cont=bcb,
        b_motion=bmb,
    )


# ----------------------------------------------------------------------------- methods
Method = Callable[[Scene, np.ndarray, np.ndarray], np.ndarray]


def _classify_method(fidelity: str) -> Method:
    def run(scene: Scene, r: np.ndarray, beta: np.ndarray) -> np.ndarray:
        return classify(scene, r, beta, fidelity).regime.astype(int)

    return run


def _baseline(scene: Scene, r: np.ndarray, beta: np.ndarray) -> np.ndarray:
    return np.array(
        [paper_method(scene, float(a), float(b))[0] for a, b in zip(r, beta, strict=True)],
        dtype=int,
    )


def _closed_form(method: str) -> Method:
    def run(scene: Scene, r: np.ndarray, beta: np.ndarray) -> np.ndarray:
        from analysis.closed_form import predict

        return predict(scene, r, beta, method=method).astype(int)

    return run


def _right_side(codes: np.ndarray, near: np.ndarray, side: np.ndarray) -> np.ndarray:
    """Near-boundary points classified on the side of the boundary they lie on."""
    motion = (codes >= 0) & (codes != regimes.NO_MOTION)
    cont = codes == regimes.CONTINUOUS
    right_cont = np.where(side < 0, cont, (codes >= 0) & ~cont)
    right_motion = np.where(side < 0, motion, codes == regimes.NO_MOTION)
    return np.where(near == 1, right_cont, right_motion)


def _timed(fn: Method, scene: Scene, r, beta, repeats: int) -> tuple[np.ndarray, float]:
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        codes = fn(scene, r, beta)
        best = min(best, time.perf_counter() - t0)
    return codes, best


def bisect(
    fn: Method, scene: Scene, r: np.ndarray, bound: np.ndarray, which: str, steps: int
) -> np.ndarray:
    """Boundary in beta at each r by bisection in ``BRACKET * bound`` (NaN if not bracketed).

    ``which="continuous"``: the largest beta with continuous motion;
    ``"motion"``: the largest beta with motion (regime >= 0 and not no motion).
    """

    def below(codes: np.ndarray) -> np.ndarray:
        if which == "continuous":
            return codes == regimes.CONTINUOUS
        return (codes >= 0) & (codes != regimes.NO_MOTION)

    lo, hi = BRACKET[0] * bound, BRACKET[1] * bound
    ends = fn(scene, np.concatenate((r, r)), np.concatenate((lo, hi)))
    ok = below(ends[: r.size]) & ~below(ends[r.size :])
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        b = below(fn(scene, r, mid))
        lo = np.where(b, mid, lo)
        hi = np.where(b, hi, mid)
    return np.where(ok, 0.5 * (lo + hi), np.nan)


# ----------------------------------------------------------------------------- result
@dataclass
class MethodStats:
    """Per-method totals over all scenes (see the module docstring)."""

    name: str
    seconds: float = 0.0
    points: int = 0
    disagree: int = 0
    undetermined: int = 0
    near_wrong: int = 0
    near_total: int = 0
    boundary_errors: list[float] = field(default_factory=list)
    unbracketed: int = 0
    per_scene: dict[str, tuple[float, int, int]] = field(default_factory=dict)

    @property
    def seconds_per_point(self) -> float:
        return self.seconds / max(self.points, 1)

    @property
    def disagreement(self) -> float:
        return self.disagree / max(self.points, 1)


@dataclass
class BenchResult:
    """Everything :func:`write_bench` needs."""

    methods: dict[str, MethodStats]
    machine: dict[str, str]
    quick: bool
    n_points: int
    n_scenes: int
    bisect_steps: int
    closed_form_boundary_errors: list[float]
    wall: float


def machine() -> dict[str, str]:
    """Platform, CPUs, library versions and load average."""
    import numba
    import scipy

    cpu = platform.processor() or ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count() or 1
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg()) if hasattr(os, "getloadavg") else "?"
    return {
        "platform": platform.platform(),
        "cpu": f"{cpu} ({os.cpu_count()} logical CPUs, {usable} usable)",
        "python": platform.python_version(),
        "numpy / scipy / numba": f"{np.__version__} / {scipy.__version__} / {numba.__version__}",
        "load average at start (1, 5, 15 min)": load,
    }


def run_bench(quick: bool = False, log: Callable[[str], None] | None = None) -> BenchResult:
    """Measure every method on the benchmark points (see the module docstring)."""
    log = log or (lambda msg: None)
    size = SIZES[bool(quick)]
    info = machine()
    start = time.perf_counter()
    methods: dict[str, Method] = {f: _classify_method(f) for f in PRESETS}
    methods[BASELINE] = _baseline
    methods[CLOSED_FORMS[0]] = _closed_form("paper")
    methods[CLOSED_FORMS[1]] = _closed_form("exact")
    stats = {name: MethodStats(name) for name in methods}
    cf_errors: list[float] = []
    n_total = 0
    for k, (label, scene) in enumerate(SCENES.items()):
        pts = bench_points(scene, size["points"], size["bisect_r"], SEED + k)
        n_total += pts.r.size
        for f in PRESETS:  # warm-up: compile / cache load outside the timings
            classify(scene, pts.r[:1], pts.beta[:1], f)
        codes = {}
        for name, fn in methods.items():
            repeats = 1 if name == BASELINE else 3
            codes[name], dt = _timed(fn, scene, pts.r, pts.beta, repeats)
            s = stats[name]
            s.seconds += dt
            s.points += pts.r.size
            s.undetermined += int(np.sum(codes[name] < 0))
            right = _right_side(codes[name], pts.near, pts.side)
            s.near_wrong += int(np.sum((pts.near > 0) & ~right))
            s.near_total += int(np.sum(pts.near > 0))
            s.per_scene[label] = (dt / pts.r.size, 0, int(np.sum(codes[name] < 0)))
        for name, s in stats.items():
            diff = int(np.sum(codes[name] != codes[REFERENCE]))
            s.disagree += diff
            s.per_scene[label] = (s.per_scene[label][0], diff, s.per_scene[label][2])
        # bisection of both boundaries at a few r
        located: dict[str, list[np.ndarray]] = {}
        for name, fn in methods.items():
            if name in CLOSED_FORMS:
                continue
            if name == BASELINE and not size["baseline_bisect"]:
                continue
            located[name] = [
                bisect(fn, scene, pts.bisect_r, pts.b_cont, "continuous", size["bisect_steps"]),
                bisect(fn, scene, pts.bisect_r, pts.b_motion, "motion", size["bisect_steps"]),
            ]
        ref_b = located[REFERENCE]
        for name, (bc, bm) in located.items():
            for found, truth in ((bc, ref_b[0]), (bm, ref_b[1])):
                good = np.isfinite(found) & np.isfinite(truth)
                stats[name].boundary_errors += list(np.abs(found[good] / truth[good] - 1.0))
                stats[name].unbracketed += int(np.sum(~good))
        for found, cf in ((ref_b[0], pts.b_cont), (ref_b[1], pts.b_motion)):
            good = np.isfinite(found)
            cf_errors += list(np.abs(found[good] / cf[good] - 1.0))
        log(f"{label}: {pts.r.size} points, {pts.bisect_r.size} bisection r")
    return BenchResult(
        methods=stats,
        machine=info,
        quick=bool(quick),
        n_points=n_total,
        n_scenes=len(SCENES),
        bisect_steps=size["bisect_steps"],
        closed_form_boundary_errors=cf_errors,
        wall=time.perf_counter() - start,
    )


# ----------------------------------------------------------------------------- output
def _fmt(x: float, digits: int = 3) -> str:
    if not math.isfinite(x):
        return "-"
    if x == 0:
        return "0"
    if 1e-3 <= abs(x) < 1e5:
        return f"{x:.{max(0, digits - 1 - int(math.floor(math.log10(abs(x)))))}f}"
    return f"{x:.{digits - 1}e}"


def _table(header: list[str], rows: list[list[object]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def _label(name: str) -> str:
    if name in PRESETS:
        return f"classify `{name}`"
    if name == BASELINE:
        return "baseline (paper: RK45 + events, 100 cycles)"
    return name


def bench_markdown(res: BenchResult) -> str:
    """The Markdown report of a :class:`BenchResult`."""
    base = res.methods[BASELINE].seconds_per_point
    rows = []
    for name, s in res.methods.items():
        errs = np.array(s.boundary_errors)
        simulated = name not in CLOSED_FORMS
        located = (
            f"{_fmt(float(np.median(errs)))} / {_fmt(float(errs.max()))} "
            f"({errs.size}/{errs.size + s.unbracketed})"
            if errs.size
            else ("-" if not simulated or name == BASELINE else "none located")
        )
        rows.append(
            [
                _label(name),
                _fmt(s.seconds_per_point * 1e3),
                _fmt(base / s.seconds_per_point) if s.seconds > 0 else "-",
                f"{100 * s.disagreement:.1f} % ({s.disagree}/{s.points})",
                s.undetermined if simulated else "-",
                f"{s.near_wrong}/{s.near_total}",
                located,
            ]
        )
    cf = np.array(res.closed_form_boundary_errors)
    parts = [
        "# study bench: fidelity presets vs the paper's method",
        "",
        _table(["machine", ""], [[k, v] for k, v in res.machine.items()]),
        "",
        f"{res.n_scenes} scenes ({', '.join(f'`{k}`' for k in SCENES)}), {res.n_points} points "
        f"({'quick' if res.quick else 'full'} set, seed {SEED}): half spread over r in "
        f"{list(R_RANGE)} and beta in [0, {BETA_FACTOR} beta_motion], half "
        f"{int(100 * NEAR_OFFSET[0])}-{int(100 * NEAR_OFFSET[1])} % from a closed-form boundary "
        f"(`analysis.boundaries(method='exact')`). Reference: the `{REFERENCE}` preset. "
        f"Wall time of the whole benchmark: {_fmt(res.wall)} s.",
        "",
        _table(
            [
                "method",
                "ms / point",
                "speed-up vs baseline",
                f"disagreement with `{REFERENCE}`",
                "undetermined",
                "near-boundary wrong side",
                f"boundary error vs `{REFERENCE}`: median / max (located/tried)",
            ],
            rows,
        ),
        "",
        "- *ms / point*: one vectorised `classify` call per scene, best of 3, compile "
        "excluded; the baseline loops over the points in Python; the closed forms are "
        "`analysis.predict`.",
        "- *near-boundary wrong side*: points 2-15 % below/above a closed-form boundary "
        "classified on the other side (undetermined counts as wrong).",
        f"- *boundary error*: both boundaries located by bisection in beta "
        f"({res.bisect_steps} steps in [{BRACKET[0]}, {BRACKET[1]}] x the closed-form value) "
        f"at a few r per scene, relative to the `{REFERENCE}` preset's (not located: "
        f"the method's regimes at the bracket ends do not bracket the boundary); "
        f"bracket resolution {_fmt((BRACKET[1] - BRACKET[0]) / 2 ** (res.bisect_steps + 1))}. "
        + (
            f"The `{REFERENCE}` preset's boundaries differ from the closed-form (exact S) "
            f"ones by median {_fmt(float(np.median(cf)))}, max {_fmt(float(cf.max()))} "
            f"({cf.size} boundaries)."
            if cf.size
            else ""
        ),
        "",
        "## Per scene: ms / point (points differing from `exact`, undetermined)",
        "",
    ]
    sim = [n for n in res.methods if n not in CLOSED_FORMS]
    scene_rows = []
    for label in SCENES:
        row: list[object] = [f"`{label}`"]
        for name in sim:
            spp, diff, und = res.methods[name].per_scene[label]
            row.append(f"{_fmt(spp * 1e3)} ({diff}, {und})")
        scene_rows.append(row)
    parts.append(_table(["scene", *[_label(n) for n in sim]], scene_rows))
    return "\n".join(parts) + "\n"


def pareto_figure(res: BenchResult):
    """Time per point vs disagreement with the reference preset (log axes, Agg)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.4, 4.4), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    floor = 0.5 / max(res.n_points, 1)
    markers = {"fast": "o", "balanced": "s", "exact": "D", BASELINE: "^"}
    for name, s in res.methods.items():
        if s.seconds <= 0:
            continue
        y = max(s.disagreement, floor)
        ax.scatter(
            s.seconds_per_point,
            y,
            marker=markers.get(name, "x"),
            s=60,
            label=f"{_label(name).replace('`', '')}: {100 * s.disagreement:.1f} %",
            zorder=3,
        )
    ax.axhline(floor, color="0.6", lw=0.8, ls="--")
    ax.text(
        0.01,
        floor,
        " 0 (no disagreement)",
        transform=ax.get_yaxis_transform(),
        va="bottom",
        fontsize=8,
        color="0.4",
    )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time per point [s] (one core)")
    ax.set_ylabel(f"fraction of points disagreeing with '{REFERENCE}'")
    ax.set_title(f"study bench: {res.n_points} points, {res.n_scenes} scenes", fontsize=10)
    ax.grid(True, which="both", lw=0.3, alpha=0.5)
    ax.legend(fontsize=7, loc="best")
    return fig


def write_bench(res: BenchResult, output_dir: Path) -> Path:
    """Write ``bench.md`` and ``pareto.png`` into ``output_dir``; return the ``bench.md`` path."""
    output_dir = Path(output_dir)
    output_dir.mkdir(parents=True, exist_ok=True)
    md = output_dir / "bench.md"
    md.write_text(bench_markdown(res), encoding="utf-8")
    pareto_figure(res).savefig(output_dir / "pareto.png", dpi=120)
    return md


def main_bench(
    output_dir: Path, quick: bool = False, log: Callable[[str], None] | None = None
) -> Path:
    """``study bench``: run the benchmark and write ``bench.md`` and ``pareto.png``.

    Parameters
    ----------
    output_dir : Path
        Directory for the two files (created if missing).
    quick : bool
        A small point set (3 points per scene, no bisection with the baseline):
        a minute or two instead of several minutes.
    log : callable, optional
        Receives one progress line per scene (e.g. ``print``).

    Returns
    -------
    Path
        The written ``bench.md``.
    """
    return write_bench(run_bench(quick=quick, log=log), output_dir)
