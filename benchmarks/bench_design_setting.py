"""What ``design = false`` (the default) saves against ``design = true``: ``study run`` here.

``python benchmarks/bench_design_setting.py [--quick] [--repeats N]``: the Fig. 4
example (``examples/fig04.toml``: four 2DOF panels of 250 x 100 points; ``--quick``:
125 x 50) run through ``study.cli.main`` with the design pass on (``design = true``)
and off (the default, written out), alternately, ``N`` times each; small enough to
compute in this process (threads), so the CPU time of this process
(``time.process_time``) is the whole
study's. Prints the CPU time of every run, the best of each setting and their
ratio, the result files' sizes, and checks that the labels are equal.
"""

from __future__ import annotations

import argparse
import io
import tempfile
import time
from contextlib import redirect_stderr
from pathlib import Path

import numpy as np
import xarray as xr

from study.cli import main

ROOT = Path(__file__).resolve().parents[1]
LABELS = ("regime", "stops_per_cycle", "cycles")


def study_text(design: bool, quick: bool) -> str:
    text = (ROOT / "examples" / "fig04.toml").read_text(encoding="utf-8")
    if quick:
        text = text.replace("num = 250", "num = 125").replace("num = 100}", "num = 50}")
    head = 'fidelity = "balanced"\n'
    setting = f"\n[settings]\ndesign = {'true' if design else 'false'}\n"
    return text.replace(head, head + setting, 1)


def run(where: Path, design: bool, quick: bool) -> tuple[float, Path]:
    """CPU seconds of one ``study run`` in this process, and its result file."""
    name = f"design_{'on' if design else 'off'}"
    (where / f"{name}.toml").write_text(study_text(design, quick), encoding="utf-8")
    out = where / f"{name}.nc"
    out.unlink(missing_ok=True)
    err = io.StringIO()
    t0 = time.process_time()
    with redirect_stderr(err):
        code = main(["run", str(where / f"{name}.toml"), "-o", str(out), "--quiet"])
    cpu = time.process_time() - t0
    if code != 0 or "in this process" not in err.getvalue():
        raise SystemExit(f"study run failed or did not run in this process:\n{err.getvalue()}")
    return cpu, out


def same_labels(on: Path, off: Path) -> bool:
    with xr.open_datatree(on) as a, xr.open_datatree(off) as b:
        return all(
            np.array_equal(a[s][v].values, b[s][v].values) for s in a.children for v in LABELS
        )


def main_bench() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="125 x 50 points per panel")
    parser.add_argument("--repeats", type=int, default=3, help="runs of each setting")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        where = Path(tmp)
        run(where, False, True)  # compile and warm up (not counted)
        cpu: dict[bool, list[float]] = {True: [], False: []}
        files: dict[bool, Path] = {}
        for i in range(args.repeats):
            for design in (True, False):
                seconds, files[design] = run(where, design, args.quick)
                cpu[design].append(seconds)
                print(f"run {i + 1}, design = {str(design).lower()}: CPU {seconds:.2f} s")
        on, off = min(cpu[True]), min(cpu[False])
        print()
        print("| design | CPU s (best) | result file MB |")
        print("|---|---|---|")
        for design, best in ((True, on), (False, off)):
            size = files[design].stat().st_size / 1e6
            print(f"| {str(design).lower()} | {best:.2f} | {size:.2f} |")
        print(f"\noff / on: {off / on:.3f} of the CPU time ({100 * (1 - off / on):.1f} % saved)")
        print(f"labels equal ({', '.join(LABELS)}): {same_labels(files[True], files[False])}")


if __name__ == "__main__":
    main_bench()
