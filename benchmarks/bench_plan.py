"""``study plan`` estimates against measured chunk times (the calibration of study.cost).

    .venv/bin/python benchmarks/bench_plan.py                  # the example studies
    .venv/bin/python benchmarks/bench_plan.py --chunks 6 fig04 fig14

For every scene of the example studies, a few chunks evenly spread over the
scene (``--chunks`` per scene, whole chunks of the real plan, so every regime of
the map is represented as in a run) are computed in this process by
:func:`study.compute.compute_chunk`, timed in CPU seconds (``time.process_time``:
other processes on the machine do not inflate it). Printed: the cost model's
seconds per point (:func:`study.cost.seconds_per_point`, with the plan's work per
point), the measured ones, and their ratio. ``study.cost.BASE_SECONDS`` and
``DOF_SLOPE`` are fitted to these rows (ratios near 1).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

EXAMPLES = ("quickstart", "fig03", "fig04", "fig10a", "fig14", "fig17")


def measure(name: str, n_chunks: int) -> list[tuple[str, str, int, float, float]]:
    """(study, scene, dof, model s/point, measured s/point) for each grid scene of an example."""
    from study.chunks import plan
    from study.compute import compute_chunk
    from study.cost import seconds_per_point
    from study.definition import Study

    study = Study.from_toml(REPO / "examples" / f"{name}.toml")
    rows = []
    for p in plan(study):
        chunks = list(p.chunks())
        picked = [
            chunks[round(i * (len(chunks) - 1) / max(1, n_chunks - 1))] for i in range(n_chunks)
        ]
        picked = list({c.key: c for c in picked}.values())
        axes = p.axes()
        cpu = points = 0.0
        for c in picked:
            t0 = time.process_time()
            compute_chunk(p.task(c, axes))
            cpu += time.process_time() - t0
            points += c.n_points
        model = seconds_per_point(p.spec.dof, study.fidelity) * p.work_per_point
        rows.append((name, p.spec.name, p.spec.dof, model, cpu / points))
    return rows


def startup_seconds(workers: int = 2) -> float:
    """Wall seconds to start the local cluster of ``study run`` and load the kernels."""
    import io

    from benchmarks.bench_scheduling import _warm
    from study.run import connect

    _warm()  # the disk cache is filled: workers load, not compile
    t0 = time.perf_counter()
    with connect(workers=workers, stream=io.StringIO()) as client:
        client.run(_warm)
        return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("examples", nargs="*", default=list(EXAMPLES))
    ap.add_argument("--chunks", type=int, default=4)
    ap.add_argument("--startup", action="store_true", help="also time a LocalCluster start")
    args = ap.parse_args()
    from tasks import Scene, classify

    classify(Scene("ground", 2), 1.0, 0.3)  # compile or load the kernels first
    print("| study | scene | dof | model ms/point | measured ms/point | measured / model |")
    print("|---|---|---:|---:|---:|---:|")
    for name in args.examples:
        for study, scene, dof, model, measured in measure(name, args.chunks):
            print(
                f"| {study} | {scene} | {dof} | {1e3 * model:.3f} | {1e3 * measured:.3f} | "
                f"{measured / model:.2f} |",
                flush=True,
            )
    if args.startup:
        runs = [startup_seconds() for _ in range(3)]
        print(
            f"\nLocalCluster of 2 workers started, kernels loaded: "
            f"{min(runs):.1f}-{max(runs):.1f} s"
        )


if __name__ == "__main__":
    main()
