"""Wall time of ``study run examples/adaptive.toml`` (the Fig. 4 example) and where it goes.

Each run is the CLI in a fresh process (the compiled kernel in numba's disk
cache; a small study computes in threads of that process,
:func:`study.drive.local_threads`). Prints, per code version (this checkout,
and with ``--code DIR`` another checkout, e.g. ``git archive main | tar -x -C
DIR``; the versions alternate, run after run, so both see the same load):

* wall and CPU seconds (all threads) of the whole process, best and median;
* the run's own phases from its log: start (interpreter and imports, before the
  run's first line), refinement (the plane's line: coarse lattice to verified
  plane), the rest (survey, result file, work folder removed);
* whether the result's variables equal those of the first version, bit for bit.

Then one run of this checkout, timed inside (``--no-breakdown`` skips it): the
imports of ``study.run``; the closed-form hint; the client's handling of the
point lists (the refinement's bookkeeping, thread CPU seconds of the client);
the background writer (thread CPU and wall seconds, files written, point lists
in them); the compute (CPU seconds of the compute threads); the result file.

    python benchmarks/bench_example.py --runs 3
    python benchmarks/bench_example.py --runs 3 --code /tmp/main-checkout

Measure at nice 0 on a quiet machine: this is about wall time (the load average
is printed with each table).
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = "examples/adaptive.toml"


def load() -> str:
    return f"{os.getloadavg()[0]:.1f}" if hasattr(os, "getloadavg") else "?"


def cli_run(code: Path, out: Path) -> dict[str, float]:
    """One ``study run`` of ``code``'s example: wall, CPU and the phases of its log."""
    env = dict(os.environ, PYTHONPATH=str(code))
    out.unlink(missing_ok=True)
    cmd = [sys.executable, "-m", "study", "run", EXAMPLE, "-o", str(out), "--quiet"]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=code, env=env, capture_output=True, text=True, timeout=600)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode:
        raise SystemExit(f"{code}: study run failed:\n{proc.stderr}")
    run = float(re.search(r"reused\) in ([\d.]+) s", proc.stderr).group(1))
    plane = float(re.search(r"levels, ([\d.]+) s;", proc.stderr).group(1))
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    return {"wall": wall, "cpu": cpu, "start": wall - run, "refine": plane, "rest": run - plane}


def same_result(a: Path, b: Path) -> bool:
    """Every variable and coordinate of two results equal, bit for bit."""
    import numpy as np
    import xarray as xr

    with xr.open_dataset(a) as x, xr.open_dataset(b) as y:
        if set(x.variables) != set(y.variables):
            return False
        return all(
            np.array_equal(x[k].values, y[k].values, equal_nan=x[k].dtype.kind == "f")
            for k in x.variables
        )


def compare(codes: list[Path], runs: int) -> None:
    rows: dict[Path, list[dict[str, float]]] = {c: [] for c in codes}
    equal: dict[Path, bool] = {}
    loads = [load()]
    with tempfile.TemporaryDirectory() as tmp:
        outs = {c: Path(tmp) / f"{i}.nc" for i, c in enumerate(codes)}
        for _ in range(runs):
            for c in codes:
                rows[c].append(cli_run(c, outs[c]))
                loads.append(load())
        for c in codes:
            equal[c] = same_result(outs[codes[0]], outs[c])
    print(f"study run {EXAMPLE} -o x.nc, {runs} runs each, load average {', '.join(loads)}\n")
    print(
        "| code | wall s best | wall s median | CPU s median | start | refinement | rest "
        "| result equal |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---|")
    for c in codes:
        r = rows[c]

        def med(k: str, r=r) -> float:
            return statistics.median(x[k] for x in r)

        name = "this checkout" if c == ROOT else str(c)
        print(
            f"| {name} | {min(x['wall'] for x in r):.2f} | {med('wall'):.2f} | {med('cpu'):.2f} "
            f"| {med('start'):.2f} | {med('refine'):.2f} | {med('rest'):.2f} "
            f"| {'yes' if equal[c] else 'NO'} |"
        )
    if len(codes) == 2:
        a, b = (statistics.median(x["wall"] for x in rows[c]) for c in codes)
        print(f"\nwall time, {codes[1]} / this checkout (medians): {b / a:.2f}x")


BREAKDOWN = r"""
import io, sys, threading, time
t0 = time.perf_counter()
import study.run
imports = time.perf_counter() - t0
from study import adaptive, netcdf, saving
from study.definition import Study

timers = {}

def timed(owner, name, label):
    real = getattr(owner, name)
    def wrapper(*args, **kwargs):
        c, w = time.thread_time(), time.perf_counter()
        try:
            return real(*args, **kwargs)
        finally:
            t = timers.setdefault(label, [0.0, 0.0, 0])
            t[0] += time.thread_time() - c
            t[1] += time.perf_counter() - w
            t[2] += 1
    setattr(owner, name, wrapper)

timed(adaptive.AdaptivePlan, "_hint", "hint")
timed(adaptive.AdaptivePlan, "next_unit", "lists")
timed(adaptive.AdaptivePlan, "accept", "lists")
timed(saving.Saver, "_write", "save")
timed(netcdf, "write_result", "write")
study.run.write_result = netcdf.write_result
files = []
real_save = saving.Saver._write
def count(self, items):
    before = self.done.saved
    real_save(self, items)
    files.append(self.done.saved - before)
saving.Saver._write = count
cpu0 = time.process_time()
s = study.run.run_study(Study.from_toml(sys.argv[1]), sys.argv[2], progress=False,
                        overwrite=True, stream=io.StringIO())
total_cpu = time.process_time() - cpu0
for i in (0, 1):  # the hint is computed inside the hand-out of the first point lists
    timers["lists"][i] -= timers.get("hint", [0.0, 0.0])[i]
client = sum(timers[k][0] for k in ("hint", "lists", "write") if k in timers)
print(f"imports|{imports:.2f}|")
for k in ("hint", "lists", "save", "write"):
    c, w, n = timers.get(k, [0.0, 0.0, 0])
    print(f"{k}|{w:.2f}|{c:.2f}|{n}")
print(f"files|{len(files)}|{sum(files)}")
print(f"compute|{s.compute_wall_seconds:.2f}|{total_cpu - client - timers['save'][0]:.2f}")
print(f"run|{s.wall_seconds:.2f}|{total_cpu:.2f}")
"""


def breakdown() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        proc = subprocess.run(
            [sys.executable, "-c", BREAKDOWN, EXAMPLE, str(Path(tmp) / "x.nc")],
            cwd=ROOT,
            env=dict(os.environ, PYTHONPATH=str(ROOT)),
            capture_output=True,
            text=True,
            timeout=600,
        )
    if proc.returncode:
        raise SystemExit(f"breakdown failed:\n{proc.stderr}")
    t = {ln.split("|")[0]: ln.split("|")[1:] for ln in proc.stdout.splitlines() if "|" in ln}
    print(f"\nOne run of this checkout, timed inside (load average {load()}):\n")
    print("| phase | wall s | CPU s | calls |")
    print("|---|---:|---:|---:|")
    print(f"| imports of study.run (this process's start) | {t['imports'][0]} | | |")
    print(
        f"| closed-form hint (client thread) | {t['hint'][0]} | {t['hint'][1]} | {t['hint'][2]} |"
    )
    print(
        f"| point lists in the client: refinement, hand-out | {t['lists'][0]} | "
        f"{t['lists'][1]} | {t['lists'][2]} |"
    )
    print(
        f"| saving (background thread): {t['files'][1]} point lists in {t['files'][0]} "
        f"files | {t['save'][0]} | {t['save'][1]} | {t['save'][2]} |"
    )
    print(
        f"| compute: submit to last result (wall); CPU of the other threads | "
        f"{t['compute'][0]} | {t['compute'][1]} | |"
    )
    print(f"| result file (netCDF) | {t['write'][0]} | {t['write'][1]} | |")
    print(f"| run_study in all | {t['run'][0]} | {t['run'][1]} | |")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3, help="runs of each version")
    ap.add_argument("--code", type=Path, help="another checkout to compare with (e.g. main)")
    ap.add_argument("--no-breakdown", action="store_true", help="skip the timed-inside run")
    args = ap.parse_args(argv)
    codes = [ROOT] + ([args.code.resolve()] if args.code else [])
    for c in codes:  # the kernel compiled and in the disk cache before any timing
        warm = "from tasks import classify, Scene; classify(Scene('ground', 2), 1.0, 0.3)"
        env = dict(os.environ, PYTHONPATH=str(c))
        subprocess.run([sys.executable, "-c", warm], cwd=c, env=env, check=True)
    compare(codes, args.runs)
    if not args.no_breakdown:
        breakdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
