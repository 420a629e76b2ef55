"""``study plan`` estimates against measured chunk times (the calibration of study.cost).

    .venv/bin/python benchmarks/bench_plan.py                  # the example studies
    .venv/bin/python benchmarks/bench_plan.py --chunks 6 fig04 fig14
    .venv/bin/python benchmarks/bench_plan.py --chunks 2 cantilever check_pinned_beam

For every scene of the example studies, a few chunks evenly spread over the
scene (``--chunks`` per scene, whole chunks of the real plan, so every regime of
the map is represented as in a run) are computed in this process by
:func:`study.compute.compute_chunk`, timed in CPU seconds (``time.process_time``:
other processes on the machine do not inflate it). Printed: the cost model's
seconds per point (:func:`study.cost.seconds_per_point`, with the plan's work per
point and the scene's :func:`study.cost.scene_factor`), the measured ones, and
their ratio, with the two features of the factor: the contact count and the
fastest mode's :func:`study.cost.mode_rate` over the r range.
``study.cost.BASE_SECONDS``, ``DOF_SLOPE``, ``CONTACT_SLOPE``, ``MODE_SLOPE`` and
``MULTI_MODE_SLOPE``
are fitted to the rows of the example studies (ratios near 1); the ``check_*``
studies (:data:`CHECKS`, not among the examples) test the fit out of sample.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

EXAMPLES = (
    "quickstart",
    "fig03",
    "fig04",
    "fig10a",
    "fig10b",
    "fig14",
    "fig17",
    "cantilever",
    "two_contacts",
    "contacts_3dof",
    "beam_two_contacts",
    "check_pinned_beam",
    "check_chain_3contacts",
)
#: Scenes not in ``examples/`` (not fitted): the fit's out-of-sample check.
CHECKS = {
    "check_pinned_beam": {  # a pinned-pinned beam, contact at 1/4 span, 3 modes
        "study": {"name": "check_pinned_beam", "fidelity": "balanced"},
        "scene": [
            {
                "name": "pinned_quarter",
                "beam": {
                    "supports": "pinned",
                    "n_elements": 12,
                    "contact_node": 3,
                    "load": "distributed",
                    "modes": 3,
                },
                "damping": {"rayleigh": [0.02, 0.002]},
                "r": {"start": 0.2, "stop": 5.0, "num": 40},
                "beta": {"start": 0.0, "stop": 2.0, "num": 21},
            }
        ],
    },
    "check_chain_3contacts": {  # a 4DOF chain with three ground contacts
        "study": {"name": "check_chain_3contacts", "fidelity": "fast"},
        "scene": [
            {
                "name": "ground_m1_m2_m4",
                "contact": "ground",
                "dof": 4,
                "contact_mass": [1, 2, 4],
                "beta_ratio": [1.0, 0.7, 0.4],
                "r": {"start": 0.1, "stop": 2.5, "num": 16},
                "beta": {"start": 0.0, "stop": 1.2, "num": 10},
            }
        ],
    },
}


def load(name: str):
    """The study of an example (``examples/<name>.toml``) or of :data:`CHECKS`."""
    from study.definition import Study

    if name in CHECKS:
        return Study.from_dict(CHECKS[name], source=name)
    return Study.from_toml(REPO / "examples" / f"{name}.toml")


def measure(name: str, n_chunks: int) -> list[tuple]:
    """(study, scene, dof, contacts, mode rate, model s/point, measured s/point) for
    each scene of an example or check study."""
    from study.chunks import plan
    from study.compute import compute_chunk
    from study.cost import mode_rate, seconds_per_point, spec_factor

    study = load(name)
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
        spec = p.spec
        model = seconds_per_point(spec.dof, study.fidelity, spec_factor(spec)) * p.work_per_point
        contacts = int(getattr(spec.base_scene, "n_contacts", 1))
        rate = mode_rate(spec.base_scene, axes["r"])
        rows.append((name, spec.name, spec.dof, contacts, rate, model, cpu / points))
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
    print(
        "| study | scene | dof | contacts | mode rate | model ms/point | measured ms/point "
        "| measured / model |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for name in args.examples:
        for study, scene, dof, n, rate, model, measured in measure(name, args.chunks):
            print(
                f"| {study} | {scene} | {dof} | {n} | {rate:.1f} | {1e3 * model:.3f} | "
                f"{1e3 * measured:.3f} | {measured / model:.2f} |",
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
