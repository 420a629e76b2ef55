"""Writing the result file scales with the number of scenes (issue 22).

    .venv/bin/python benchmarks/bench_write.py                 # 10, 100, 1000 scenes
    .venv/bin/python benchmarks/bench_write.py --scenes 10 100 --baseline-max 100

A study of N small scenes (2-DOF ground contact, 5 x 10 points each: the
audit's "600 scenes of 50 points") has its work folder filled with valid chunks
(every field, dtype and shape its plan expects; the numerics are not what is
measured), then the result file is assembled by :func:`study.netcdf.write_result`
in a fresh subprocess, which reports its wall time and its peak RSS (``VmHWM``,
the client's memory). The baseline, in the same run, is the former assembly:
every scene's Dataset built first and the whole tree written by one
``xarray.DataTree.to_netcdf`` (then the same fill), measured for N up to
``--baseline-max`` scenes (it grows superlinearly: 600 scenes took 218 s).
Printed: a Markdown table with write seconds, seconds per scene and peak RSS.

``--encoding FILE``: the per-point variables of a result file written again with
netCDF4 (same dims and chunks) under each compression setting; the CPU seconds
of the writes (best of 3) and the file size (:data:`study.netcdf.COMPRESSION`):

    .venv/bin/python benchmarks/bench_write.py --encoding adaptive.nc
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

SCENE = """
[[scene]]
name = "s{i:04d}"
contact = "ground"
dof = 2
gamma = {gamma}
r = {{start = 0.2, stop = 2.0, num = 5}}
beta = {{start = 0.0, stop = 1.2, num = 10}}
"""


def study_text(n: int) -> str:
    head = '[study]\nname = "many"\nfidelity = "fast"\n'
    return head + "".join(SCENE.format(i=i, gamma=1.0 + 0.001 * i) for i in range(n))


def _fill(study, work) -> None:
    """Valid chunks for every unit of every plan (zeros of the expected dtypes)."""
    import numpy as np

    from study.chunks import plan

    for p in plan(study):
        for c in p.chunks():
            arrays = {k: np.zeros(shape, dtype=dt) for k, (dt, shape) in p.expected(c).items()}
            work.save(c.scene, c.key, arrays)


def _baseline_write(study, plans, work, output: Path) -> None:
    """The former assembly: one DataTree.to_netcdf of every scene, then the fill."""
    import dask
    import netCDF4
    import xarray as xr

    from study.netcdf import global_attrs, root_attrs, scene_dataset

    built = {p.spec.name: scene_dataset(p, study) for p in plans}
    tree = xr.DataTree.from_dict(
        {"/": xr.Dataset(attrs=root_attrs(global_attrs(study), list(built)))}
        | {f"/{n}": ds for n, (ds, _) in built.items()}
    )
    with dask.config.set(scheduler="synchronous"):
        tree.to_netcdf(
            output,
            engine="netcdf4",
            format="NETCDF4",
            encoding={f"/{n}": enc for n, (_, enc) in built.items()},
        )
    with netCDF4.Dataset(output, "a") as nc:
        nc.set_auto_maskandscale(False)
        for p in plans:
            group = nc.groups[p.spec.name]
            for name, index, values in p.writes(work):
                var = group.variables[name]
                var[index] = values.astype(var.dtype, copy=False)


def child(n: int, how: str, where: Path) -> dict:
    """Fill a work folder and time one assembly (in this fresh process)."""
    from study.chunks import plan
    from study.definition import Study
    from study.netcdf import write_result
    from study.store import WorkDir

    study = Study.from_dict(__import__("tomllib").loads(study_text(n)))
    out = where / f"{how}-{n}.nc"
    work = WorkDir(out)
    _fill(study, work)
    plans = plan(study)
    t0 = time.perf_counter()
    if how == "new":
        write_result(study, plans, work, out)
    else:
        _baseline_write(study, plans, work, out)
    seconds = time.perf_counter() - t0
    rss = 0
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                rss = int(line.split()[1]) * 1024
    return {"seconds": seconds, "rss": rss, "bytes": out.stat().st_size}


def run(n: int, how: str, where: Path) -> dict:
    code = (
        "import json, sys; from pathlib import Path; sys.path.insert(0, sys.argv[4]); "
        "from benchmarks.bench_write import child; "
        "print(json.dumps(child(int(sys.argv[1]), sys.argv[2], Path(sys.argv[3]))))"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code, str(n), how, str(where), str(REPO)],
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(proc.stdout.strip().splitlines()[-1])


#: ``--encoding``: the settings compared (the first: before level 1).
ENCODINGS = {
    "zlib 4, shuffle": {"zlib": True, "complevel": 4, "shuffle": True},
    "zlib 4": {"zlib": True, "complevel": 4, "shuffle": False},
    "zlib 1, shuffle": {"zlib": True, "complevel": 1, "shuffle": True},
    "zlib 1": {"zlib": True, "complevel": 1, "shuffle": False},
    "none": {"zlib": False},
}


def encoding_main(path: Path) -> None:
    """Rewrite the per-point variables of ``path`` under each of :data:`ENCODINGS`."""
    import netCDF4

    with netCDF4.Dataset(path) as src:
        src.set_auto_maskandscale(False)
        dims = {d: len(v) for d, v in src.dimensions.items()}
        per_point = {
            k: (v[...], v.dimensions, v.dtype, v.chunking())
            for k, v in src.variables.items()
            if v.ndim >= 2 or (v.ndim == 1 and v.dimensions[0] == "point")
        }
    print(f"{path.name}: {len(per_point)} per-point variables, dims {dims}")
    print("| encoding | write CPU s | file MB |")
    print("|---|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "e.nc"
        for label, enc in ENCODINGS.items():
            best = float("inf")
            for _ in range(3):
                t = time.process_time()
                with netCDF4.Dataset(out, "w") as nc:
                    for d, n in dims.items():
                        nc.createDimension(d, n)
                    for k, (a, vdims, dt, chunks) in per_point.items():
                        chunks = None if chunks == "contiguous" else chunks
                        var = nc.createVariable(k, dt, vdims, chunksizes=chunks, **enc)
                        var.set_auto_maskandscale(False)
                        var[...] = a
                best = min(best, time.process_time() - t)
            print(f"| {label} | {best:.3f} | {out.stat().st_size / 1e6:.2f} |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, nargs="+", default=[10, 100, 1000])
    ap.add_argument("--baseline-max", type=int, default=100)
    ap.add_argument("--encoding", type=Path, help="a result file: compression settings")
    args = ap.parse_args()
    if args.encoding is not None:
        encoding_main(args.encoding)
        return
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}"
    )
    print()
    print("| scenes | assembly | write s | s per scene | peak RSS MB | file MB |")
    print("|---:|---|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.scenes:
            for how in ("new", "baseline"):
                if how == "baseline" and n > args.baseline_max:
                    continue
                r = run(n, how, Path(tmp))
                label = "group by group (mode a)" if how == "new" else "DataTree.to_netcdf"
                print(
                    f"| {n:,} | {label} | {r['seconds']:.1f} | {r['seconds'] / n:.3f} | "
                    f"{r['rss'] / 2**20:.0f} | {r['bytes'] / 2**20:.1f} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
