"""Small studies in this process against a local cluster of worker processes (issue 19).

    .venv/bin/python benchmarks/bench_small.py            # quickstart, 3 repeats

``study run`` of a small or medium study (``examples/quickstart.toml``: 1,000
points, about 0.4 CPU s; anything planned at most
:data:`study.drive.IN_PROCESS_SECONDS` per core) without ``--workers`` computes
in threads of the client's process, one per core (the simulator releases the
GIL; no worker processes to start, :func:`study.drive.local_threads`); with
``--workers 2`` it starts two worker processes first. Printed: the wall seconds
of each ``study run`` (a fresh process each; the numba cache is filled first),
best and median of the repeats, and the ratio.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def wall(study: Path, where: Path, *extra: str) -> float:
    out = where / "out.nc"
    out.unlink(missing_ok=True)
    t0 = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "study", "run", str(study), "-o", str(out), "--quiet", *extra],
        cwd=REPO,
        check=True,
        capture_output=True,
    )
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", type=Path, default=REPO / "examples" / "quickstart.toml")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    sys.path.insert(0, str(REPO))
    from tasks import Scene, classify

    classify(Scene("ground", 2), 1.0, 0.3)  # the kernels in the disk cache
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        for label, extra in (("in this process", ()), ("2 worker processes", ("--workers", "2"))):
            rows[label] = [wall(args.study, Path(tmp), *extra) for _ in range(args.repeats)]
    print(f"| {args.study.name} | best s | median s |")
    print("|---|---:|---:|")
    for label, times in rows.items():
        print(f"| {label} | {min(times):.1f} | {statistics.median(times):.1f} |")
    a, b = (statistics.median(t) for t in rows.values())
    print(f"\nworker processes / in this process (median): {b / a:.1f}x")


if __name__ == "__main__":
    main()
