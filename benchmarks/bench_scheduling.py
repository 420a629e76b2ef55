"""Scheduling overhead and client memory of ``study run`` (issue 4, "Measured").

Two measurements, printed as Markdown tables::

    .venv/bin/python benchmarks/bench_scheduling.py            # both
    .venv/bin/python benchmarks/bench_scheduling.py overhead   # (a) only
    .venv/bin/python benchmarks/bench_scheduling.py memory     # (b) only
    .venv/bin/python benchmarks/bench_scheduling.py calibrate  # seconds per point

(a) **Scheduling overhead**: a 25,000-point study (2-DOF, ground contact on
m_1, balanced preset, r x beta = 250 x 100 over the whole map) runs through
:func:`study.run_study` on a LocalCluster of 2 single-threaded worker processes
that is started (and its numba kernels loaded) beforehand. The ideal time is
the sum of the compute seconds every chunk reports (``compute_chunk`` times
itself on the worker) divided by the 2 workers; the overhead is

    compute_wall / (sum of chunk seconds / 2) - 1

where ``compute_wall`` runs from the first submitted chunk to the last one
saved by the client (scheduling, transfers, the client's saves, load
imbalance at the end: everything but the numerics). The result-file assembly
and cluster start-up are listed separately. Rows: the chunk size chosen by the
cost model (:mod:`study.cost`) and fixed ``chunk_points`` for comparison.

(b) **Client peak RSS**: for 10^4, 10^5 and 10^6 points, a fresh
``python -m study run --workers 2`` subprocess runs the full orchestration
(plan, LocalCluster, every chunk through Dask, work folder, netCDF assembly)
and reports its own peak RSS (``VmHWM``; the client process, which also hosts the
LocalCluster's scheduler and nannies; workers are separate processes). To keep
10^6 points affordable the study uses the fast preset and beta in [1.5, 3],
above the motion bound (1.0) of this scene, so every point is a no-motion
point decided at once (a few microseconds of numerics per point); the chunk
sizes are those of a real fast 2-DOF study (the cost model does not look at
beta), so the client handles as many chunks per point as in a real run.

(c) **Calibration** (``calibrate``): measured seconds per point of
``tasks.classify`` for each preset and 1-5 DOF on random points of a typical
map, next to the cost model's estimate (the source of ``study.cost``'s
constants).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

OVERHEAD_STUDY = """
[study]
name = "overhead"
fidelity = "balanced"
{extra}

[[scene]]
name = "ground_m1"
contact = "ground"
dof = 2
contact_mass = 1
r = {{start = 0.02, stop = 2.5, num = 250}}
beta = {{start = 0.0, stop = 1.5, num = 100}}
"""

MEMORY_STUDY = """
[study]
name = "memory"
fidelity = "fast"

[[scene]]
name = "no_motion"
contact = "ground"
dof = 2
contact_mass = 1
r = {{start = 0.05, stop = 2.5, num = {n_r}}}
beta = {{start = 1.5, stop = 3.0, num = {n_beta}}}
"""
MEMORY_SIZES = {
    10_000: (100, 100),
    100_000: (250, 400),
    1_000_000: (1000, 1000),
    10_000_000: (2500, 4000),  # optional: --sizes 10000000
}
DEFAULT_SIZES = [10_000, 100_000, 1_000_000]


def machine() -> str:
    return f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, " + (
        f"load average {os.getloadavg()[0]:.1f}" if hasattr(os, "getloadavg") else ""
    )


def _warm(_: object = None) -> float:
    """Load the numba kernels in this process (from the disk cache if present)."""
    import numpy as np

    from tasks import Scene, classify

    t0 = time.perf_counter()
    classify(Scene("ground", 2), np.array([1.0]), np.array([0.3]))
    return time.perf_counter() - t0


# --------------------------------------------------------------------------- (a)
def overhead(workers: int, repeats: int, chunk_points: list[int]) -> None:
    from distributed import Client, LocalCluster

    from study import Study
    from study.chunks import plan
    from study.run import run_study

    _warm()  # fill the disk cache before the workers look for it
    t0 = time.perf_counter()
    cluster = LocalCluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
        silence_logs=logging.ERROR,
    )
    client = Client(cluster)
    start = time.perf_counter() - t0
    client.run(_warm)
    rows = []
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for cp in [None, *chunk_points]:
                extra = f"chunk_points = {cp}" if cp else ""
                path = Path(tmp) / "overhead.toml"
                path.write_text(OVERHEAD_STUDY.format(extra=extra))
                study = Study.from_toml(path)
                (p,) = plan(study)
                runs = []
                for i in range(repeats):
                    out = Path(tmp) / f"overhead-{cp}-{i}.nc"
                    s = run_study(
                        study, out, client=client, progress=False, stream=open(os.devnull, "w")
                    )
                    ideal = s.compute_seconds / workers
                    runs.append((s.compute_wall_seconds / ideal - 1.0, s, ideal))
                    out.unlink()
                ratio, s, ideal = sorted(runs, key=lambda x: x[0])[len(runs) // 2]  # median
                rows.append(
                    (
                        f"{p.block[0] * p.block[1]}" + (" (cost model)" if cp is None else ""),
                        p.n_chunks,
                        s.compute_seconds / s.n_points * 1e3,
                        s.compute_seconds / p.n_chunks,
                        ideal,
                        s.compute_wall_seconds,
                        ratio,
                        [r[0] for r in runs],
                        s.write_seconds,
                    )
                )
    finally:
        client.close()
        cluster.close()
    print(f"\n### (a) Scheduling overhead: 25,000 points, LocalCluster of {workers} workers\n")
    print(f"Machine: {machine()}. Cluster start-up {start:.1f} s (not counted).")
    print(
        f"Median of {repeats} runs per row; overhead = compute wall / "
        f"(sum of chunk seconds / {workers}) - 1.\n"
    )
    print(
        "| points/chunk | chunks | ms/point | s/chunk | ideal s | compute wall s | "
        "overhead | all runs | netCDF write s |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---|---:|")
    for r in rows:
        print(
            f"| {r[0]} | {r[1]} | {r[2]:.3f} | {r[3]:.3f} | {r[4]:.2f} | {r[5]:.2f} | "
            f"{100 * r[6]:.1f}% | {', '.join(f'{100 * x:.1f}%' for x in r[7])} | {r[8]:.2f} |"
        )


# --------------------------------------------------------------------------- (b)
def _memory_child(study_path: str, out: str, workers: int) -> None:
    """Run in a fresh interpreter: the CLI's run, then print this process's peak RSS."""
    from study.cli import main

    t0 = time.perf_counter()
    code = main(["run", study_path, "-o", out, "--workers", str(workers), "--quiet"])
    wall = time.perf_counter() - t0
    print(json.dumps({"code": code, "peak_mib": peak_rss_mib(), "wall": wall}))


def peak_rss_mib() -> float:
    """Peak resident memory of this process since it started (exec), in MiB.

    ``VmHWM`` of /proc/self/status belongs to the process image, so it starts
    afresh at exec; ``ru_maxrss`` does not on Linux (a child started by a
    large parent inherits the parent's peak), so it is only the fallback.
    """
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024  # kB
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def memory(workers: int, sizes: list[int]) -> None:
    from study import Study
    from study.chunks import plan

    _warm()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            n_r, n_beta = MEMORY_SIZES[n]
            path = Path(tmp) / f"memory{n}.toml"
            path.write_text(MEMORY_STUDY.format(n_r=n_r, n_beta=n_beta))
            (p,) = plan(Study.from_toml(path))
            out = Path(tmp) / f"memory{n}.nc"
            env = dict(os.environ, PYTHONPATH=str(REPO))
            proc = subprocess.run(
                [sys.executable, __file__, "_memory_child", str(path), str(out), str(workers)],
                env=env,
                capture_output=True,
                text=True,
            )
            if proc.returncode:
                raise SystemExit(proc.stderr)
            res = json.loads(proc.stdout.strip().splitlines()[-1])
            if res["code"]:
                raise SystemExit(f"study run failed: {proc.stderr}")
            rows.append((n, p.n_chunks, res["peak_mib"], res["wall"], out.stat().st_size / 2**20))
            out.unlink()
    print(f"\n### (b) Client peak RSS (fresh `study run --workers {workers}` per size)\n")
    print(f"Machine: {machine()}. Fast preset, beta in [1.5, 3] (no motion, decided at once).\n")
    print("| points | grid r x beta | chunks | client peak RSS MiB | wall s | file MiB |")
    print("|---:|---|---:|---:|---:|---:|")
    for n, chunks, peak, wall, size in rows:
        n_r, n_beta = MEMORY_SIZES[n]
        print(f"| {n:,} | {n_r} x {n_beta} | {chunks:,} | {peak:.0f} | {wall:.1f} | {size:.1f} |")


# --------------------------------------------------------------------------- (c)
def calibrate_table(n: int) -> None:
    import numpy as np

    from study.cost import calibrate, seconds_per_point
    from tasks import Scene, resolve

    _warm()
    r = np.linspace(0.02, 2.5, 250)
    beta = np.linspace(0.0, 1.5, 100)
    scenes = [
        Scene("ground", 1),
        Scene("ground", 2),
        Scene("mass", 2),
        Scene("ground", 3, 2),
        Scene("base", 3, 1),
        Scene("ground", 4, 2),
        Scene("ground", 5, 4),
        Scene("mass", 5, 1),
    ]
    print(f"\n### (c) Seconds per point of tasks.classify ({n} random points of r x beta)\n")
    print(f"Machine: {machine()}.\n")
    print("| scene | preset | measured ms/point | cost model ms/point |")
    print("|---|---|---:|---:|")
    for sc in scenes:
        for fid in ("fast", "balanced", "exact"):
            t = calibrate(sc, resolve(fid), r, beta, n=n)
            model = seconds_per_point(sc.dof, fid)
            print(f"| {sc.label} | {fid} | {t * 1e3:.3f} | {model * 1e3:.3f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "part", nargs="?", default="all", choices=["all", "overhead", "memory", "calibrate"]
    )
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument(
        "--chunk-points",
        type=int,
        nargs="*",
        default=[100, 500, 2000],
        help="fixed chunk sizes compared with the cost model's (overhead)",
    )
    ap.add_argument(
        "--sizes", type=int, nargs="*", default=DEFAULT_SIZES, choices=list(MEMORY_SIZES)
    )
    ap.add_argument("--calibrate-points", type=int, default=400)
    args = ap.parse_args()
    if args.part in ("all", "overhead"):
        overhead(args.workers, args.repeats, args.chunk_points)
    if args.part in ("all", "memory"):
        memory(args.workers, args.sizes)
    if args.part in ("all", "calibrate"):
        calibrate_table(args.calibrate_points)


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "_memory_child":
        _memory_child(*sys.argv[2:4], int(sys.argv[4]))
    else:
        main()
