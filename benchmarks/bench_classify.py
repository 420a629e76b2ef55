"""Speed and accuracy of ``tasks.classify`` against the paper's method (``tasks.baseline``).

Run from the repository root::

    .venv/bin/python benchmarks/bench_classify.py            # ~2-3 min
    .venv/bin/python benchmarks/bench_classify.py --quick    # ~30 s
    .venv/bin/python benchmarks/bench_classify.py --output bench_classify.md

In one process, on the same points of a 2DOF ground-fixed scene (contact on m_1,
gamma = kappa = 1; a seeded random sample, r in [0.05, 2.5], beta in [0, 1.2]):

1. ``tasks.classify`` (every preset; compile / cache-load time of the first call
   reported apart, then the best of several repeats) and the baseline (the
   paper's RK45 + events, 100 cycles from rest, pure scipy): points per second,
   the speed ratio, and their agreement on the sample;
2. agreement with the reference labels of ``tests/data/reference_cases.json``
   (``reference_regime``): all 170 cases for ``classify``, as many as
   ``--baseline-cases`` says for the baseline (default: all);
3. a 250 x 100 (r, beta) panel of the scene with ``classify`` on one core, and
   with two worker processes (``concurrent.futures``, fork, warmed up);
4. what numba buys: the same ``classify`` on a few points with
   ``NUMBA_DISABLE_JIT=1`` in a subprocess (the kernel as plain Python) vs compiled,
   and the cold compile time (subprocess with an empty numba cache).

Everything is printed as Markdown tables with the machine description. Wall
times on a shared machine include the other processes' load (reported).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from study.bench import machine  # noqa: E402
from tasks import PRESETS, Scene, classify, regimes  # noqa: E402
from tasks.baseline import paper_method  # noqa: E402

PUBLIC = REPO / "tests" / "data" / "reference_cases.json"
SCENE = Scene("ground", 2, 1, gamma=1.0, kappa=1.0)
CONFIG = "2dof_ground_m1"
R_RANGE = (0.05, 2.5)
BETA_RANGE = (0.0, 1.2)
SEED = 20210406


# ----------------------------------------------------------------------------- helpers
def table(header: list[str], rows: list[list[object]]) -> str:
    """A Markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def fmt(x: float, digits: int = 3) -> str:
    """A number with ``digits`` significant digits, no exponent for ordinary sizes."""
    if x == 0 or not math.isfinite(x):
        return str(x)
    if 1e-3 <= abs(x) < 1e6:
        return f"{x:.{max(0, digits - 1 - int(math.floor(math.log10(abs(x)))))}f}"
    return f"{x:.{digits - 1}e}"


def scene_of(case: dict) -> Scene:
    """The Scene of a public reference case."""
    n = case["N"]
    ratios = {"gamma": tuple(case["g"][1:]), "kappa": tuple(case["k"][1:])} if n > 1 else {}
    return Scene(case["contact"], n, case["j"], **ratios)


def sample_points(n: int, seed: int = SEED) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.uniform(*R_RANGE, n), rng.uniform(*BETA_RANGE, n)


def best_time(fn, min_total: float = 0.5, max_repeats: int = 50) -> float:
    """Best wall time of ``fn()`` over repeats (at least 3, about ``min_total`` s in all)."""
    times = []
    start = time.perf_counter()
    while len(times) < 3 or (time.perf_counter() - start < min_total and len(times) < max_repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def run_baseline(scene: Scene, r: np.ndarray, beta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Baseline codes and wall time per point."""
    codes = np.empty(r.size, dtype=int)
    walls = np.empty(r.size)
    for i, (ri, bi) in enumerate(zip(r, beta, strict=True)):
        t0 = time.perf_counter()
        codes[i], _ = paper_method(scene, float(ri), float(bi))
        walls[i] = time.perf_counter() - t0
    return codes, walls


def classify_cases(cases: list[dict], fidelity: str) -> np.ndarray:
    """Regime codes of ``classify`` on reference cases, one call per scene."""
    codes = np.empty(len(cases), dtype=int)
    groups: dict[Scene, list[int]] = {}
    for i, c in enumerate(cases):
        groups.setdefault(scene_of(c), []).append(i)
    for scene, idx in groups.items():
        r = np.array([cases[i]["r"] for i in idx])
        b = np.array([cases[i]["b"] for i in idx])
        codes[idx] = classify(scene, r, b, fidelity).regime
    return codes


def agreement(codes: np.ndarray, labels: list[str]) -> tuple[int, int, int]:
    """(agreeing, total, undetermined) of regime codes against regime names."""
    names = [regimes.name(c) for c in codes]
    return (
        sum(a == b for a, b in zip(names, labels, strict=True)),
        len(labels),
        int(np.sum(codes < 0)),
    )


def _panel_chunk(args: tuple) -> float:
    """Worker: classify one block of the panel; returns its wall time."""
    r, beta = args
    t0 = time.perf_counter()
    classify(SCENE, r, beta)
    return time.perf_counter() - t0


def _warm(_: int) -> int:
    classify(SCENE, 1.3, 0.4)
    return os.getpid()


_CHILD = """
import json, sys, time
import numpy as np
t0 = time.perf_counter()
from tasks import Scene, classify
r, beta = (np.array(v) for v in json.loads(sys.argv[1]))
scene = Scene("ground", 2, 1, gamma=1.0, kappa=1.0)
t1 = time.perf_counter()
first = classify(scene, r[:1], beta[:1]).regime
t2 = time.perf_counter()
res = classify(scene, r, beta)
t3 = time.perf_counter()
print(json.dumps({"import": t1 - t0, "first": t2 - t1, "run": t3 - t2,
                  "regime": res.regime.tolist()}))
"""


def run_child(r: np.ndarray, beta: np.ndarray, env_extra: dict[str, str]) -> dict:
    """Run ``classify`` on the points in a fresh interpreter with extra env vars."""
    env = dict(os.environ)
    env.update(env_extra)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO), env.get("PYTHONPATH")) if p)
    out = subprocess.run(
        [sys.executable, "-c", _CHILD, json.dumps([r.tolist(), beta.tolist()])],
        env=env,
        capture_output=True,
        text=True,
        check=True,
        cwd=REPO,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


# ----------------------------------------------------------------------------- main
def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--points", type=int, default=40, help="random sample size (baseline)")
    ap.add_argument(
        "--baseline-cases",
        default="all",
        help="reference cases for the baseline: 'all', 'config' (2dof_ground_m1 only), "
        "or a number (the first N)",
    )
    ap.add_argument("--panel", default="250x100", help="panel size NRxNBETA")
    ap.add_argument("--nojit-points", type=int, default=4)
    ap.add_argument("--quick", action="store_true", help="small sizes (~30 s)")
    ap.add_argument("--output", type=Path, help="also write the Markdown here")
    args = ap.parse_args(argv)
    if args.quick:
        args.points, args.baseline_cases, args.panel, args.nojit_points = 8, "config", "50x40", 2
    n_r, n_b = (int(v) for v in args.panel.lower().split("x"))

    out: list[str] = []

    def emit(text: str = "") -> None:
        print(text, flush=True)
        out.append(text)

    info = machine()
    emit("# bench_classify: tasks.classify vs the paper's method\n")
    emit(table(["machine", ""], [[k, v] for k, v in info.items()]))
    emit(
        f"\nScene: `{SCENE.label}`, gamma = kappa = 1; sample: {args.points} points, "
        f"r ~ U{R_RANGE}, beta ~ U{BETA_RANGE}, seed {SEED}.\n"
    )

    # --- first call: compile or cache load ---------------------------------------
    r, beta = sample_points(args.points)
    t0 = time.perf_counter()
    classify(SCENE, r[:1], beta[:1])
    first_call = time.perf_counter() - t0

    # --- 1. speed on the sample ----------------------------------------------------
    speed_rows = []
    cls_codes = {}
    per_point = {}
    for fid in PRESETS:
        classify(SCENE, r[:1], beta[:1], fid)  # warm-up
        dt = best_time(lambda fid=fid: classify(SCENE, r, beta, fid))
        per_point[fid] = dt / r.size
        cls_codes[fid] = classify(SCENE, r, beta, fid).regime.astype(int)
    t0 = time.perf_counter()
    base_codes, base_walls = run_baseline(SCENE, r, beta)
    base_total = time.perf_counter() - t0
    base_pp = base_total / r.size
    for fid in PRESETS:
        agree = int(np.sum(cls_codes[fid] == base_codes))
        speed_rows.append(
            [
                f"classify `{fid}`",
                fmt(1.0 / per_point[fid]),
                fmt(per_point[fid] * 1e3),
                fmt(base_pp / per_point[fid]),
                f"{agree}/{r.size}",
            ]
        )
    speed_rows.append(
        [
            "baseline (RK45 + events, 100 cycles)",
            fmt(1.0 / base_pp),
            fmt(base_pp * 1e3),
            "1",
            f"{r.size}/{r.size}",
        ]
    )
    emit("## Speed on the sample (same points, one process)\n")
    emit(
        table(
            ["method", "points/s", "ms/point", "speed-up vs baseline", "same regime as baseline"],
            speed_rows,
        )
    )
    ratio = base_pp / per_point["balanced"]
    emit(
        f"\nclassify (`balanced`, the default) is **{fmt(ratio)}x** faster than the baseline "
        f"(target >= 300x: {'met' if ratio >= 300 else 'NOT met'}). Baseline per point: "
        f"median {fmt(np.median(base_walls))} s, max {fmt(base_walls.max())} s. "
        f"First classify call in this process (numba cache load or compile): "
        f"{fmt(first_call)} s, excluded above.\n"
    )
    differ = np.flatnonzero(cls_codes["exact"] != base_codes)
    if differ.size:
        emit("Sample points where the baseline and classify `exact` differ:\n")
        emit(
            table(
                ["r", "beta", "classify exact", "baseline"],
                [
                    [
                        fmt(r[i], 4),
                        fmt(beta[i], 4),
                        regimes.name(cls_codes["exact"][i]),
                        regimes.name(base_codes[i]),
                    ]
                    for i in differ
                ],
            )
        )
        emit()

    # --- 2. agreement with the reference labels -------------------------------------
    cases = json.loads(PUBLIC.read_text())["cases"]
    labels = [c["reference_regime"] for c in cases]
    acc_rows = []
    for fid in PRESETS:
        t0 = time.perf_counter()
        codes = classify_cases(cases, fid)
        dt = time.perf_counter() - t0
        ok, n, und = agreement(codes, labels)
        conf = [i for i, c in enumerate(cases) if c["config"] == CONFIG]
        ok_c, n_c, _ = agreement(codes[conf], [labels[i] for i in conf])
        acc_rows.append(
            [f"classify `{fid}`", f"{ok}/{n} ({100 * ok / n:.1f} %)", f"{ok_c}/{n_c}", und, fmt(dt)]
        )
    if args.baseline_cases == "all":
        chosen = list(range(len(cases)))
    elif args.baseline_cases == "config":
        chosen = [i for i, c in enumerate(cases) if c["config"] == CONFIG]
    else:
        chosen = list(range(min(len(cases), int(args.baseline_cases))))
    t0 = time.perf_counter()
    bcodes = np.array(
        [paper_method(scene_of(cases[i]), cases[i]["r"], cases[i]["b"])[0] for i in chosen]
    )
    dt = time.perf_counter() - t0
    ok, n, und = agreement(bcodes, [labels[i] for i in chosen])
    conf = [k for k, i in enumerate(chosen) if cases[i]["config"] == CONFIG]
    ok_c, n_c, _ = agreement(bcodes[conf], [labels[chosen[k]] for k in conf])
    acc_rows.append(
        [
            "baseline (this implementation)",
            f"{ok}/{n} ({100 * ok / n:.1f} %)",
            f"{ok_c}/{n_c}",
            und,
            fmt(dt),
        ]
    )
    pub = [c["baseline_regime"] for c in (cases[i] for i in chosen)]
    ok_p, _, _ = agreement(np.array([regimes.code(p) for p in pub]), [labels[i] for i in chosen])
    same_pub = sum(regimes.name(c) == p for c, p in zip(bcodes, pub, strict=True))
    acc_rows.append(
        [
            "published `baseline_regime`",
            f"{ok_p}/{n} ({100 * ok_p / n:.1f} %)",
            "",
            0,
            "",
        ]
    )
    emit(
        "## Agreement with the reference labels "
        "(`tests/data/reference_cases.json`, `reference_regime`)\n"
    )
    emit(
        table(
            ["method", "all cases run", f"`{CONFIG}` cases", "undetermined", "wall s"],
            acc_rows,
        )
    )
    by_cat = Counter(
        (cases[i]["category"], regimes.name(bcodes[k]) == labels[i]) for k, i in enumerate(chosen)
    )
    emit(
        f"\nThe baseline ran on {len(chosen)} of {len(cases)} cases "
        f"({'all' if len(chosen) == len(cases) else args.baseline_cases}); it reproduces the "
        f"published `baseline_regime` on {same_pub}/{len(chosen)}. Baseline misses by category: "
        + ", ".join(
            f"{cat} {by_cat[(cat, False)]}/{by_cat[(cat, False)] + by_cat[(cat, True)]}"
            for cat in sorted({k[0] for k in by_cat})
        )
        + ".\n"
    )

    # --- 3. panel, 1 core and 2 processes -------------------------------------------
    rg = np.linspace(*R_RANGE, n_r)
    bg = np.linspace(*BETA_RANGE, n_b)
    R, B = np.meshgrid(rg, bg, indexing="ij")
    t0 = time.perf_counter()
    panel = classify(SCENE, R, B)
    t_one = time.perf_counter() - t0
    counts = Counter(regimes.name(c) for c in panel.regime.ravel())
    workers = 2
    blocks = [(R[i::16].ravel(), B[i::16].ravel()) for i in range(16)]  # interleaved rows
    t0 = time.perf_counter()
    with ProcessPoolExecutor(workers, mp_context=get_context("fork")) as pool:
        pids = set(pool.map(_warm, range(4 * workers)))
        t_start = time.perf_counter() - t0
        t1 = time.perf_counter()
        busy = sum(pool.map(_panel_chunk, blocks))
        t_two = time.perf_counter() - t1
    emit(f"## Panel {n_r} x {n_b} = {R.size} points of `{SCENE.label}` (`balanced`)\n")
    emit(
        table(
            ["run", "wall s", "points/s", "speed-up"],
            [
                ["1 core (one classify call)", fmt(t_one), fmt(R.size / t_one), "1"],
                ["2 cores, extrapolated (ideal)", fmt(t_one / 2), fmt(2 * R.size / t_one), "2"],
                [
                    f"2 processes, measured ({len(blocks)} blocks; pool start "
                    f"{fmt(t_start)} s not included)",
                    fmt(t_two),
                    fmt(R.size / t_two),
                    fmt(t_one / t_two),
                ],
            ],
        )
    )
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    emit(
        f"\nRegimes in the panel: {dict(counts)}. Worker busy time {fmt(busy)} s "
        f"({len(pids)} worker processes); load average after the run: {load} (with other "
        f"users' processes on the machine the 2-process speed-up stays below 2).\n"
    )

    # --- 3b. every preset on the panel (and a proposed 'fast') ------------------------
    variants = [(fid, {}) for fid in PRESETS] + [("fast", {"max_cycles": 1000})]
    ref_panel = None
    prow = []
    for fid, over in variants:
        t0 = time.perf_counter()
        res = classify(SCENE, R, B, fid, **over)
        dt = time.perf_counter() - t0
        if fid == "exact" and not over:
            ref_panel = res.regime
        prow.append([fid, over, dt, res.regime, float(res.cycles.mean()), int(res.cycles.max())])
    emit(f"## Every preset on the panel ({R.size} points, 1 core)\n")
    emit(
        table(
            [
                "preset",
                "wall s",
                "ms/point",
                "undetermined",
                "differ from `exact`",
                "mean / max cycles",
            ],
            [
                [
                    f"`{fid}`"
                    + (f" with {', '.join(f'{k}={v}' for k, v in over.items())}" if over else ""),
                    fmt(dt),
                    fmt(dt / R.size * 1e3),
                    int(np.sum(reg < 0)),
                    int(np.sum(reg != ref_panel)),
                    f"{mean_c:.1f} / {max_c}",
                ]
                for fid, over, dt, reg, mean_c, max_c in prow
            ],
        )
    )
    emit()

    # --- 4. numba vs plain Python, cold compile ---------------------------------------
    k = args.nojit_points
    rn, bn = r[:k], beta[:k]
    compiled = best_time(lambda: classify(SCENE, rn, bn)) / k
    nojit = run_child(rn, bn, {"NUMBA_DISABLE_JIT": "1"})
    with tempfile.TemporaryDirectory() as cache:
        cold = run_child(rn, bn, {"NUMBA_CACHE_DIR": cache})
    warm = run_child(rn, bn, {})
    same = nojit["regime"] == classify(SCENE, rn, bn).regime.tolist()
    emit(f"## What numba buys (`balanced`, {k} sample points)\n")
    emit(
        table(
            ["run", "s/point", "ratio to compiled"],
            [
                ["compiled (numba), warm", fmt(compiled), "1"],
                [
                    "NUMBA_DISABLE_JIT=1 (plain Python, same code)",
                    fmt(nojit["run"] / k),
                    fmt(nojit["run"] / k / compiled),
                ],
                [
                    "baseline (scipy RK45), same points",
                    fmt(float(np.mean(base_walls[:k]))),
                    fmt(float(np.mean(base_walls[:k])) / compiled),
                ],
            ],
        )
    )
    emit(
        f"\nSame regimes with and without JIT: {same}. First call in a fresh process: "
        f"{fmt(cold['first'])} s with an empty numba cache (cold compile), "
        f"{fmt(warm['first'])} s from the on-disk cache; `import tasks` {fmt(warm['import'])} s.\n"
    )
    if args.output:
        args.output.write_text("\n".join(out) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
