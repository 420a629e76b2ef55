"""Adaptive maps against the dense grid of the same resolution, on the paper's panels.

For every panel (scene) of the figure studies ``examples/fig*.toml``, the map is
computed twice at the requested resolution, in this process on one core:
(a) densely (``tasks.classify`` on every point; computed once and cached in
``--cache`` so a rerun does not pay for it again) and (b) adaptively
(``analysis.adaptive.adaptive_map``: coarse lattice, refinement, closed-form
hints, verification sample). Prints per panel: points simulated (verification
included), wall seconds of both, label agreement with the dense grid (all
points; the differing points, and how many of them have a regime in the dense
grid: the others are points the dense grid left undetermined, e.g. isolated
``not_converged`` points the adaptive map inferred from agreeing neighbours),
and the verification sample's own estimate.

    python benchmarks/bench_adaptive.py                                # all panels, 1000 x 500
    python benchmarks/bench_adaptive.py --size 500x250                 # all panels, smaller
    python benchmarks/bench_adaptive.py --panels fig03 fig04:gamma1_kappa1 fig17:gamma1_kappa1

A dense 1000 x 500 panel is ~2-3 min of one core (2DOF, balanced).

``--cluster``: refinement without barriers against the old wave-by-wave
refinement (``study.adaptive.AdaptivePlan.barriers``), both as studies on one
LocalCluster of ``--workers`` single-threaded processes (started and warmed up
before the timings), on the Fig. 4 example (``examples/adaptive.toml``) and the
3DOF contact between masses 2 and 3; ``--dense`` adds the dense grid study of
the same scenes on the same cluster. Prints levels, point lists, simulated
fraction, wall seconds and whether the labels are equal:

    python benchmarks/bench_adaptive.py --cluster --size 1000x500 --workers 2 --dense
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from analysis.adaptive import adaptive_map
from analysis.report import percent
from study.definition import Study
from tasks import classify

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def panels(selection: list[str] | None):
    """(label, SceneSpec) of the figure studies, filtered by ``study`` or ``study:scene``."""
    out = []
    for path in sorted(EXAMPLES.glob("fig*.toml")):
        study = Study.from_toml(path)
        for spec in study.scenes:
            label = f"{study.name}:{spec.name}"
            if selection and not any(label == s or study.name == s for s in selection):
                continue
            out.append((label, spec))
    return out


def axes(spec, n_r: int, n_beta: int) -> tuple[np.ndarray, np.ndarray]:
    """The panel's r and beta ranges at the requested resolution (rounded like a study)."""
    r = replace(spec.r, num=n_r).values_array() if spec.r.values is None else None
    b = replace(spec.beta, num=n_beta).values_array() if spec.beta.values is None else None
    if r is None or b is None:
        raise SystemExit(f"{spec.name}: panels need start/stop axes")
    return r, b


def dense_regime(scene, r, beta, cache: Path | None, fidelity: str) -> tuple[np.ndarray, float]:
    """Regime codes of the dense grid, from the cache or computed (seconds; nan if cached)."""
    h = hashlib.sha256(
        repr((scene.to_dict(), fidelity)).encode() + r.tobytes() + beta.tobytes()
    ).hexdigest()[:16]
    path = cache / f"dense-{h}.npz" if cache else None
    if path is not None and path.is_file():
        with np.load(path) as z:
            return z["regime"], float(z["seconds"])
    t = time.perf_counter()
    R, B = np.meshgrid(r, beta, indexing="ij")
    regime = classify(scene, R, B, fidelity=fidelity).regime
    seconds = time.perf_counter() - t
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, regime=regime, seconds=seconds)
    return regime, seconds


#: Scenes of ``--cluster``: (name, contact, dof, contact_mass, r stop).
CLUSTER_SCENES = (
    ("fig04_gamma1_kappa1", "ground", 2, 1, 2.5),
    ("dof3_mass_m2_m3", "mass", 3, 2, 3.0),
)
STUDY = """
[study]
name = "bench"
fidelity = "{fidelity}"

[[scene]]
name = "{name}"
contact = "{contact}"
dof = {dof}
contact_mass = {cm}
gamma = 1.0
kappa = 1.0
{mode}
r = {{start = 0.02, stop = {r_stop}, num = {n_r}}}
beta = {{start = 0.0, stop = 1.5, num = {n_beta}}}
"""
ADAPTIVE_MODE = 'mode = "adaptive"\ncoarse_step = {step}\nverify_fraction = 0.005\nhint = "exact"'


def _run(text: str, folder: Path, client, barriers: bool) -> tuple[float, object, str]:
    """Wall seconds, regime and simulated arrays, and the log of one study run."""
    import io

    import xarray as xr

    from study import run_study
    from study.adaptive import AdaptivePlan

    path = folder / "bench.toml"
    path.write_text(text, encoding="utf-8")
    out = folder / f"bench-{time.monotonic_ns()}.nc"
    log = io.StringIO()
    AdaptivePlan.barriers = barriers
    try:
        t = time.perf_counter()
        run_study(Study.from_toml(path), out, client=client, progress=False, stream=log)
        seconds = time.perf_counter() - t
    finally:
        AdaptivePlan.barriers = False
    with xr.open_dataset(out) as ds:
        arrays = {k: ds[k].values for k in ("regime", "simulated") if k in ds}
        arrays["attrs"] = dict(ds.attrs)
    out.unlink()
    return seconds, arrays, log.getvalue()


def cluster_main(args, n_r: int, n_beta: int) -> int:
    """Without barriers vs with barriers (and the dense grid) on one LocalCluster."""
    import re
    import tempfile

    from distributed import Client, LocalCluster

    from tasks import Scene

    classify(Scene("mass", 3, 2), 1.0, 0.1)  # compile / load the kernel before the workers
    with (
        LocalCluster(
            n_workers=args.workers,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
        ) as cluster,
        Client(cluster) as client,
        tempfile.TemporaryDirectory() as tmp,
    ):
        folder = Path(tmp)

        def text(name, contact, dof, cm, r_stop, size, mode):
            return STUDY.format(
                fidelity=args.fidelity, name=name, contact=contact, dof=dof, cm=cm,
                r_stop=r_stop, n_r=size[0], n_beta=size[1], mode=mode,
            )  # fmt: skip

        mode = ADAPTIVE_MODE.format(step=args.coarse_step)
        for scene in CLUSTER_SCENES:  # warm up the workers (kernel loaded) outside the timings
            _run(text(*scene, (40, 20), mode), folder, client, False)
        print(
            f"adaptive studies with and without barriers, {n_r} x {n_beta}, "
            f"{args.workers} workers of one thread, fidelity {args.fidelity}, "
            f"coarse_step {args.coarse_step}, same cluster and run"
        )
        print(
            "| scene | refinement | levels | point lists | % simulated | wall s "
            "| vs barriers | vs dense | labels equal to barriers | to dense |"
        )
        print("|" + "---|" * 10)
        for scene in CLUSTER_SCENES:
            rows, dense = {}, None
            for barriers in (True, False):
                rows[barriers] = _run(text(*scene, (n_r, n_beta), mode), folder, client, barriers)
            if args.dense:
                dense = _run(text(*scene, (n_r, n_beta), ""), folder, client, False)
            for barriers in (True, False):
                sec, arr, log = rows[barriers]
                lists = sum(int(m) for m in re.findall(r"(\d+) point lists computed", log))
                levels = json.loads(arr["attrs"]["adaptive_waves_per_plane"])[0]
                frac = 100 * float(arr["attrs"]["adaptive_simulated_fraction"])
                same = np.array_equal(arr["regime"], rows[True][1]["regime"]) and np.array_equal(
                    arr["simulated"], rows[True][1]["simulated"]
                )
                vs_dense = f"{dense[0] / sec:.1f}" if dense else "-"
                eq_dense = (
                    percent(int((arr["regime"] == dense[1]["regime"]).sum()), n_r * n_beta, 4)
                    if dense
                    else "-"
                )
                print(
                    f"| {scene[0]} | {'waves' if barriers else 'no barriers'} | {levels} "
                    f"| {lists} | {frac:.2f} | {sec:.1f} | {rows[True][0] / sec:.2f} "
                    f"| {vs_dense} | {same} | {eq_dense} |",
                    flush=True,
                )
            if dense:
                print(f"| {scene[0]} | dense grid | | | 100 | {dense[0]:.1f} | | 1.0 | | |")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="1000x500", help="points along r x beta (1000x500)")
    ap.add_argument("--panels", nargs="*", help="fig04 or fig04:gamma1_kappa1 (default: all)")
    ap.add_argument("--coarse-step", type=int, default=16)
    ap.add_argument("--hint", default="exact", choices=("exact", "paper", "none"))
    ap.add_argument("--fidelity", default="balanced")
    ap.add_argument("--cache", type=Path, default=Path(".bench_adaptive_cache"))
    ap.add_argument("--cluster", action="store_true", help="waves vs no barriers on Dask")
    ap.add_argument("--workers", type=int, default=2, help="--cluster: worker processes")
    ap.add_argument("--dense", action="store_true", help="--cluster: the dense grid too")
    args = ap.parse_args(argv)
    n_r, n_beta = (int(x) for x in args.size.lower().split("x"))
    if args.cluster:
        return cluster_main(args, n_r, n_beta)
    chosen = panels(args.panels)
    if not chosen:
        raise SystemExit("no panel matches --panels")
    classify(chosen[0][1].base_scene, 1.0, 0.1)  # compile / load the kernel outside the timings
    print(
        f"adaptive vs dense, {n_r} x {n_beta} = {n_r * n_beta:,} points per panel, "
        f"coarse_step {args.coarse_step}, hint {args.hint}, fidelity {args.fidelity}, "
        "one process"
    )
    head = (
        "| panel | simulated | % simulated | levels | adaptive s | dense s | speed-up "
        "| labels equal to dense | differing | of which determined in the dense grid "
        "| dense undetermined | verification (agree / sampled) |"
    )
    print(head)
    print("|" + "---|" * 12)
    tot_sim = tot_pts = tot_diff = tot_det = 0
    for label, spec in chosen:
        scene = spec.base_scene
        r, beta = axes(spec, n_r, n_beta)
        dense, dense_s = dense_regime(scene, r, beta, args.cache, args.fidelity)
        t = time.perf_counter()
        res = adaptive_map(
            scene,
            r,
            beta,
            coarse_step=args.coarse_step,
            hint=None if args.hint == "none" else args.hint,
            fidelity=args.fidelity,
        )
        ad_s = time.perf_counter() - t
        differ = res.fields["regime"] != dense
        diff = int(differ.sum())
        det = int((differ & (dense >= 0)).sum())  # the dense grid has a regime there
        n = dense.size
        v = res.verification
        tot_sim += res.simulated_points
        tot_pts += n
        tot_diff += diff
        tot_det += det
        print(
            f"| {label} | {res.simulated_points:,} | {100 * res.simulated_fraction:.2f} "
            f"| {len(res.levels)} | {ad_s:.1f} | {dense_s:.1f} | {dense_s / ad_s:.1f} "
            f"| {percent(n - diff, n, 3)} | {diff} | {det} | {int((dense < 0).sum())} "
            f"| {v.agree} / {v.sampled} |",
            flush=True,
        )
    print(
        f"| all {len(chosen)} panels | {tot_sim:,} | {100 * tot_sim / tot_pts:.2f} | | | | "
        f"| {percent(tot_pts - tot_diff, tot_pts, 3)} | {tot_diff} | {tot_det} | | |"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
