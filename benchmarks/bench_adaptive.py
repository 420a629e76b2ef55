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

``--cluster``: the adaptive study and the dense grid study of the same
resolution, both on one LocalCluster of ``--workers`` single-threaded worker
processes (started and warmed up before the timings), one scene after the
other in the same run: the Fig. 4 example's panel (``examples/adaptive.toml``)
and three scenes beyond the paper (3DOF contact between masses 2 and 3, 4DOF
base contact on m3, 6DOF ground contact on m5), or ``--scenes`` (also
``dof3_base_m2``: 3DOF base contact on m2, ``dof5_ground_m3_kappa2``: 5DOF
ground contact on m3 with kappa 2; :data:`OTHER_SCENES`). Prints the
simulated fraction, levels, point lists, wall seconds of both and their ratio,
the CPU seconds of both (the client, the scheduler and the workers: a busy
machine stretches the wall seconds of one run more than the other's, not the CPU
seconds), the adaptive study's client process alone (refinement, Dask client,
saving, the result file) and the ratio, the labels equal to the dense grid's and
the verification sample;
``--tile-sample`` adds the study with the verification sample simulated inside
the tiles (``study.adaptive.AdaptivePlan.sample_in_tiles``),
``--barriers`` adds the old wave-by-wave refinement
(``study.adaptive.AdaptivePlan.barriers``), ``--before`` the adaptive study as it
was before its point lists were seeded from the solved orbits of their cells'
corners and cut at 256 points rather than 64 (:data:`BEFORE`; run just before the
current one, under the same load; "same map" compares the labels and simulated
points, and where these differ whether the refinement is the same: its simulated
points and the labels outside both verification samples, as against a checkout
that drew its sample otherwise), ``--no-dense`` skips the dense grids:

    python benchmarks/bench_adaptive.py --cluster --size 1000x500 --scenes fig04:gamma1_kappa1

``--code DIR`` (e.g. ``../main``) adds the adaptive study run by that
checkout's ``study`` and ``tasks`` (its client: refinement, point lists,
saving, the result file; the workers run this checkout's tasks). Every study
client runs in a process of its own (``study_runner.py``, started before the
timings), this checkout's too, so "of which client" is the client process alone
(the scheduler runs in the benchmark's process; "adaptive CPU s" counts the
client, the scheduler and the workers). ``--repeat N`` runs each adaptive study
N times, alternating (in turned order every other time: a study run right
after another measured 10-15 % slower, the same code in both columns), keeping
the least wall and CPU seconds (the load of other users comes and goes):

    python benchmarks/bench_adaptive.py --cluster --code ../main --repeat 3

``--replay``: the refinement alone on the ``--cluster`` scenes, replayed on the
dense grid's fields (each point's regime, flags and ``cycles`` from the dense
grid, computed once in this process and cached in ``--cache``; no simulation,
seconds once cached). A point's classification does not depend on the other
points of its call (cold starts), so the simulated points, the labels and the
verification sample are those of a study run. Prints the simulated fraction,
the share of the dense grid's simulated cycles the simulated points hold, and
its inverse (the CPU ratio a study would reach if a point cost its cycles and
nothing else cost anything), the labels equal to the dense grid's and the
verification sample. The last column is the bound of any refinement: the
points next to a change of the refinement's key (regime and flags) in the
dense grid must be simulated by every map that gets them right, so the
inverse of their share of the dense cycles caps the CPU ratio of a map whose
points cost their dense cycles:

    python benchmarks/bench_adaptive.py --replay --size 1000x500 --scenes fig04:gamma1_kappa1

``--timeline``: where the wall time of each ``--cluster`` scene's adaptive study
goes (same cluster and study clients as ``--cluster``, ``--code`` too, the
fastest of ``--repeat`` runs): the workers' busy seconds (the task stream), the
wall beyond an even split of them, when the last tile ends and the wall after
it, the client's CPU (its main thread's), then the workers' tasks and the
client's steps (arrivals, refinement calls, the sample, the inferred fill, the
result file) with their start and seconds:

    python benchmarks/bench_adaptive.py --timeline --scenes fig04:gamma1_kappa1 --code ../main

``--tasks``: what the adaptive study's own tasks cost against the dense grid, in this
process (no Dask between them): each ``--cluster`` scene's adaptive study is run
once in this process to collect its tiles and point lists (the verification
sample), which are then computed again (the least of ``--repeat`` runs, at least
2), and the dense grid of the same resolution as chunks of 10 r rows; CPU seconds
of each, and of the compiled simulator (``tasks.kernel.run_points_given``) within
them, and the ratios dense / adaptive: that of the tasks, the most a study on
any cluster can reach while its client and Dask cost nothing, and that of the
simulator alone, the most it can reach with no Python in the tasks either:

    python benchmarks/bench_adaptive.py --tasks --scenes fig04:gamma1_kappa1

``--periods``: where the periods go (``cycles``, the excitation periods simulated per
point), for each ``--cluster`` scene: its adaptive study run once in this process to
collect its tiles and point lists, which are computed again with each point's periods
recorded, against the same points' periods in the dense grid (cached, as ``--replay``):
the totals and their ratio, the points costing over 10 periods more than in the dense
grid (the tail), and the mean periods and share by part (each tile's coarse lattice,
its refinement, the point lists: the verification sample, and the cells where the
tiles meet), by grid steps to the nearest change of
the refinement's key in the dense grid, and by the dense grid's regime:

    python benchmarks/bench_adaptive.py --periods --scenes dof3_mass_m2_m3 dof6_ground_m5

``--example N``: ``study run examples/adaptive.toml`` through the CLI N times
(a fresh process each, the compiled kernel cached; small studies compute in
threads of that process, :func:`study.drive.local_threads`), wall and CPU seconds:

    python benchmarks/bench_adaptive.py --example 3
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


#: Scenes of ``--cluster`` beyond the paper (none is in ``examples/``):
#: (name, contact, dof, contact_mass, kappa, r stop).
OTHER_SCENES = (
    ("dof3_mass_m2_m3", "mass", 3, 2, 1.0, 3.0),
    ("dof4_base_m3", "base", 4, 3, 1.0, 3.0),
    ("dof6_ground_m5", "ground", 6, 5, 1.0, 3.0),
    ("dof3_base_m2", "base", 3, 2, 1.0, 3.0),
    ("dof5_ground_m3_kappa2", "ground", 5, 3, 2.0, 3.0),
)
#: The scenes of ``--cluster`` by default (the others by ``--scenes``).
DEFAULT_CLUSTER_SCENES = (
    "fig04:gamma1_kappa1",
    "dof3_mass_m2_m3",
    "dof4_base_m3",
    "dof6_ground_m5",
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
gamma = {gamma}
kappa = {kappa}
{mode}
r = {{start = {r_start}, stop = {r_stop}, num = {n_r}}}
beta = {{start = {b_start}, stop = {b_stop}, num = {n_beta}}}
"""
ADAPTIVE_MODE = 'mode = "adaptive"\ncoarse_step = {step}\nverify_fraction = 0.005\nhint = "exact"'


def cluster_scenes(names: list[str] | None) -> list[dict]:
    """The scenes of ``--cluster``: Fig. 4 (1, 1) and :data:`OTHER_SCENES` by default,
    or those named (``fig04:gamma1_kappa1`` for a paper panel, a name of OTHER_SCENES)."""
    names = names or list(DEFAULT_CLUSTER_SCENES)
    other = {s[0]: s for s in OTHER_SCENES}
    out = []
    for name in names:
        if name in other:
            _, contact, dof, cm, kappa, r_stop = other[name]
            out.append(
                dict(name=name, contact=contact, dof=dof, cm=cm, gamma=1.0, kappa=kappa,
                     r_start=0.02, r_stop=r_stop, b_start=0.0, b_stop=1.5)
            )  # fmt: skip
            continue
        found = panels([name])
        if not found or ":" not in name:
            raise SystemExit(f"--scenes: unknown scene {name!r}")
        spec = found[0][1]
        sc = spec.base_scene
        out.append(
            dict(name=name.replace(":", "_"), contact=sc.contact, dof=sc.dof,
                 cm=sc.contact_mass, gamma=sc.gamma, kappa=sc.kappa,
                 r_start=spec.r.start, r_stop=spec.r.stop,
                 b_start=spec.beta.start, b_stop=spec.beta.stop)
        )  # fmt: skip
    return out


def _cpu(client) -> float:
    """CPU seconds used so far by this process (the scheduler) and the cluster's workers."""
    workers = client.run(time.process_time) if client is not None else {}
    return time.process_time() + sum(workers.values())


#: ``--before``: the adaptive study as it was before its point lists were seeded from
#: the solved orbits of their cells' corners and cut at 256 points (64).
BEFORE = [
    ["study.adaptive", "AdaptivePlan.seed_lists", False],
    ["study.adaptive", "AdaptivePlan.min_list", 64],
]
#: ``--untiled``: the adaptive study without tiles (study.tiles): the coarse lattice as
#: point lists.
UNTILED = [["study.adaptive", "AdaptivePlan.tiles", False]]
#: ``--tile-sample``: each tile also simulates its share of the verification sample.
TILE_SAMPLE = [["study.adaptive", "AdaptivePlan.sample_in_tiles", True]]
#: ``--barriers``: the old wave-by-wave refinement.
BARRIERS = [["study.adaptive", "AdaptivePlan.barriers", True]]
RUNNER = Path(__file__).resolve().parent / "study_runner.py"


class Runner:
    """A study client in a process of its own (``study_runner.py``) with the code of a
    checkout, connected to the benchmark's scheduler: the same process layout for this
    checkout and another (``--code``), started before the timings."""

    def __init__(self, checkout: Path, address: str) -> None:
        import subprocess

        self.proc = subprocess.Popen(
            [sys.executable, str(RUNNER), str(checkout), address],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        ready = json.loads(self.proc.stdout.readline() or "{}")
        if not ready.get("ready"):
            raise SystemExit(f"the study client of {checkout} did not start")
        self.module = ready["module"]

    def run(self, toml: Path, out: Path, patch: list, timeline: bool = False) -> dict:
        req = {"toml": str(toml), "out": str(out), "patch": patch, "timeline": timeline}
        self.proc.stdin.write(json.dumps(req))
        self.proc.stdin.write("\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            raise SystemExit("a study client stopped (its error is above)")
        return json.loads(line)

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait(timeout=60)


def _run(text: str, folder: Path, client, runner: Runner, patch: list | None = None):
    """Wall seconds, regime and simulated arrays (and attributes, ``cpu``: the CPU
    seconds of the client, the scheduler and the workers, ``client_cpu``: the client's
    own), and the log of one study run by ``runner``; ``patch``: ``[module,
    "Class.attribute", value]`` set for this run only (:data:`BEFORE`, :data:`BARRIERS`)."""
    import xarray as xr

    path = folder / "bench.toml"
    path.write_text(text, encoding="utf-8")
    out = folder / f"bench-{time.monotonic_ns()}.nc"
    cpu = _cpu(client)
    answer = runner.run(path, out, patch or [])
    cpu = _cpu(client) - cpu + answer["client_cpu"]
    with xr.open_dataset(out) as ds:
        arrays = {k: ds[k].values for k in ("regime", "simulated", "verification") if k in ds}
        arrays["attrs"] = dict(ds.attrs)
    arrays["cpu"] = cpu
    arrays["client_cpu"] = answer["client_cpu"]
    out.unlink()
    return answer["wall"], arrays, answer["log"]


def same_map(a: dict, b: dict) -> str:
    """ "True" when two results have the same labels and simulated points; else whether
    they have the same refinement: the same points simulated by it (``simulated``
    outside the verification sample) and the same labels outside both samples (a
    sample drawn otherwise, e.g. by an older checkout, ``--code``)."""
    if np.array_equal(a["regime"], b["regime"]) and np.array_equal(a["simulated"], b["simulated"]):
        return "True"
    va, vb = a.get("verification"), b.get("verification")
    if va is None or vb is None:
        return "False"
    refined = np.array_equal(a["simulated"] & (va == 0), b["simulated"] & (vb == 0))
    outside = (va == 0) & (vb == 0)
    labels = np.array_equal(a["regime"][outside], b["regime"][outside])
    return f"False; same refinement: {refined and labels} (another sample)"


def _best(runs: list[tuple[float, dict, str]]) -> tuple[float, dict, str]:
    """Of repeated runs of one study (``--repeat``): the least wall seconds, and the
    least CPU seconds and client CPU seconds (each over the runs), with the arrays and
    log of the fastest run."""
    fastest = min(runs, key=lambda run: run[0])
    arrays = dict(fastest[1])
    arrays["cpu"] = min(run[1]["cpu"] for run in runs)
    arrays["client_cpu"] = min(run[1]["client_cpu"] for run in runs)
    return fastest[0], arrays, fastest[2]


def _local_cluster(workers: int):
    """The benchmark's cluster: ``workers`` single-threaded worker processes, loopback."""
    from distributed import LocalCluster

    return LocalCluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
    )


def cluster_main(args, n_r: int, n_beta: int) -> int:
    """Adaptive and dense studies of each scene on one LocalCluster, same run."""
    import re
    import tempfile

    from distributed import Client

    from tasks import Scene

    scenes = cluster_scenes(args.scenes)
    classify(Scene("mass", 3, 2), 1.0, 0.1)  # compile / load the kernel before the workers
    mode = ADAPTIVE_MODE.format(step=args.coarse_step)

    def text(sc: dict, size: tuple[int, int], mode: str) -> str:
        return STUDY.format(fidelity=args.fidelity, mode=mode, n_r=size[0], n_beta=size[1], **sc)

    with (
        _local_cluster(args.workers) as cluster,
        Client(cluster) as client,
        tempfile.TemporaryDirectory() as tmp,
    ):
        folder = Path(tmp)
        here = Runner(Path(__file__).resolve().parent.parent, cluster.scheduler_address)
        other = Runner(args.code, cluster.scheduler_address) if args.code else None
        for sc in scenes:  # warm up the workers and clients (kernel loaded), untimed
            for runner in (here, other) if other else (here,):
                _run(text(sc, (40, 20), mode), folder, client, runner)
        print(
            f"adaptive vs dense studies, {n_r} x {n_beta}, one LocalCluster of "
            f"{args.workers} single-threaded worker processes (started and warmed up "
            f"before the timings), fidelity {args.fidelity}, coarse_step "
            f"{args.coarse_step}, hint exact, verify_fraction 0.005; same run; study clients "
            f"in processes of their own: {here.module}"
            + (f", --code {other.module}" if other else "")
        )
        print(
            "| scene | points | % simulated | levels | point lists | adaptive s "
            "| dense s | dense / adaptive | adaptive CPU s | of which client | dense CPU s "
            "| CPU ratio | labels equal to dense | verification |"
        )
        print("|" + "---|" * 14)
        # (label, client, patch) run just before the current study: the same load
        befores: list[tuple[str, Runner, list | None]] = []
        if args.before:
            befores.append(("before", here, BEFORE))
        if args.untiled:
            befores.append(("untiled", here, UNTILED))
        if args.tile_sample:
            befores.append(("sample in tiles", here, TILE_SAMPLE))
        if other is not None:
            befores.append((f"{args.code}", other, None))
        for sc in scenes:
            runs: dict[str, list] = {label: [] for label, _, _ in [*befores, ("", here, None)]}
            order = [*befores, ("", here, None)]
            for i in range(args.repeat):  # alternating: a change of load hits all alike,
                # in turned order every other time (the run after another runs slower)
                for label, runner, patch in order if i % 2 == 0 else order[::-1]:
                    runs[label].append(
                        _run(text(sc, (n_r, n_beta), mode), folder, client, runner, patch)
                    )
            earlier = [(label, _best(runs[label])) for label, _, _ in befores]
            sec, arr, log = _best(runs[""])
            at = arr["attrs"]
            lists = sum(int(m) for m in re.findall(r"(\d+) point lists computed", log))
            levels = json.loads(at["adaptive_waves_per_plane"])[0]
            frac = 100 * float(at["adaptive_simulated_fraction"])
            verify = f"{at['verification_agree']} / {at['verification_sampled']}"
            dense_s = ratio = equal = dense_cpu = cpu_ratio = "-"
            if not args.no_dense:
                d_sec, d_arr, _ = _run(text(sc, (n_r, n_beta), ""), folder, client, here)
                n = d_arr["regime"].size
                same = int((arr["regime"] == d_arr["regime"]).sum())
                dense_s, ratio = f"{d_sec:.1f}", f"{d_sec / sec:.1f}"
                dense_cpu, cpu_ratio = f"{d_arr['cpu']:.1f}", f"{d_arr['cpu'] / arr['cpu']:.1f}"
                equal = f"{percent(same, n, 4)} ({n - same} differ)"
            print(
                f"| {sc['name']} | {n_r * n_beta:,} | {frac:.2f} | {levels} | {lists} "
                f"| {sec:.2f} | {dense_s} | {ratio} | {arr['cpu']:.2f} "
                f"| {arr['client_cpu']:.2f} | {dense_cpu} "
                f"| {cpu_ratio} | {equal} | {verify} |",
                flush=True,
            )
            for label, (b_sec, b_arr, b_log) in earlier:
                b_lists = sum(int(m) for m in re.findall(r"(\d+) point lists computed", b_log))
                same = same_map(b_arr, arr)
                waves = "adaptive_waves_per_plane"
                same += f"; levels equal: {b_arr['attrs'].get(waves) == at.get(waves)}"
                b_ratio = b_cpu_ratio = "-"
                if not args.no_dense:
                    b_ratio = f"{d_sec / b_sec:.1f}"
                    b_cpu_ratio = f"{d_arr['cpu'] / b_arr['cpu']:.1f}"
                print(
                    f"| {sc['name']}, {label} | | | | {b_lists} | {b_sec:.2f} | | {b_ratio} "
                    f"| {b_arr['cpu']:.2f} | {b_arr['client_cpu']:.2f} | | {b_cpu_ratio} "
                    f"| same map: {same} | |",
                    flush=True,
                )
            if args.barriers:
                b_sec, b_arr, _ = _run(
                    text(sc, (n_r, n_beta), mode), folder, client, here, BARRIERS
                )
                same = same_map(b_arr, arr)
                print(
                    f"| {sc['name']}, waves | | | | | {b_sec:.1f} | | | {b_arr['cpu']:.1f} "
                    f"| {b_arr['client_cpu']:.2f} | | | same map: {same} | |"
                )
        for runner in (here, other) if other else (here,):
            runner.close()
    return 0


def timeline_main(args, n_r: int, n_beta: int) -> int:
    """Where each adaptive study's wall time goes (``--timeline``): the workers' busy
    seconds, the wall beyond an even split of them, the end of the last tile and what
    follows it, the client's CPU, and the client's steps of the fastest run."""
    import tempfile

    from tasks import Scene

    scenes = cluster_scenes(args.scenes)
    classify(Scene("mass", 3, 2), 1.0, 0.1)
    best_runs: dict[tuple[str, str], dict] = {}
    mode = ADAPTIVE_MODE.format(step=args.coarse_step)
    with (
        _local_cluster(args.workers) as cluster,
        tempfile.TemporaryDirectory() as tmp,
    ):
        folder = Path(tmp)
        runners = [
            (
                "this checkout",
                Runner(Path(__file__).resolve().parent.parent, cluster.scheduler_address),
            )
        ]
        if args.code:
            runners.append((str(args.code), Runner(args.code, cluster.scheduler_address)))
        print(
            "| scene | code | wall s | workers busy s | wall beyond busy / workers "
            "| last tile ends | after it | client CPU s (main thread) |\n|" + "---|" * 8
        )
        for sc in scenes:
            path = folder / "bench.toml"
            for size, timed in (((40, 20), False), ((n_r, n_beta), False), ((n_r, n_beta), True)):
                path.write_text(STUDY.format(fidelity=args.fidelity, mode=mode, n_r=size[0],
                                             n_beta=size[1], **sc), encoding="utf-8")  # fmt: skip
                runs: dict[str, list] = {label: [] for label, _ in runners}
                for i in range(args.repeat if timed else 1):
                    for label, runner in runners if i % 2 == 0 else runners[::-1]:
                        out = folder / f"t-{time.monotonic_ns()}.nc"
                        runs[label].append(runner.run(path, out, [], timeline=timed))
                        out.unlink(missing_ok=True)
            for label, _ in runners:
                best = min(runs[label], key=lambda a: a["wall"])
                tl = best["timeline"]
                wall, busy = best["wall"], tl["busy"]
                beyond = wall - sum(busy) / max(1, len(busy))
                print(
                    f"| {sc['name']} | {label} | {wall:.3f} "
                    f"| {' + '.join(f'{b:.3f}' for b in busy)} "
                    f"| {beyond:.3f} ({100 * beyond / wall:.0f} %) | {tl['tile_end']:.3f} "
                    f"| {wall - tl['tile_end']:.3f} "
                    f"| {best['client_cpu']:.3f} ({tl['main_cpu']:.3f}) |",
                    flush=True,
                )
                best_runs[(sc["name"], label)] = tl
        for (name, label), tl in best_runs.items():
            print(f"\n{name}, {label}: workers' tasks (start, end, worker, key) and client steps")
            for start, stop, worker, key in tl["tasks"]:
                print(f"  {start:6.3f} {stop:6.3f} {worker} {key}")
            for step, t, dt, detail in tl["steps"]:
                if dt >= 0.002 or step in ("arrival", "sample drawn", "plane finished"):
                    print(f"  {t:6.3f} +{dt:.3f} {step} {detail}")
        for _, runner in runners:
            runner.close()
    return 0


#: Dense-grid fields the replay needs (the refinement's key fields and the cost).
REPLAY_FIELDS = ("regime", "converged", "start_dependent", "cycles")


def dense_fields(sc: dict, n_r: int, n_beta: int, cache: Path, fidelity: str):
    """Scene, axes and :data:`REPLAY_FIELDS` of the dense grid of a ``--cluster`` scene
    (from the cache, or computed in this process and cached)."""
    import tempfile

    text = STUDY.format(fidelity=fidelity, mode="", n_r=n_r, n_beta=n_beta, **sc)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "s.toml"
        path.write_text(text, encoding="utf-8")
        spec = Study.from_toml(path).scenes[0]
    scene, r, beta = spec.base_scene, spec.r.values_array(), spec.beta.values_array()
    h = hashlib.sha256(
        repr((scene.to_dict(), fidelity, REPLAY_FIELDS)).encode() + r.tobytes() + beta.tobytes()
    ).hexdigest()[:16]
    path = cache / f"fields-{h}.npz"
    if path.is_file():
        with np.load(path) as z:
            return scene, r, beta, {k: z[k] for k in REPLAY_FIELDS}
    R, B = np.meshgrid(r, beta, indexing="ij")
    res = classify(scene, R, B, fidelity=fidelity)
    fields = {k: np.asarray(getattr(res, k)) for k in REPLAY_FIELDS}
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, **fields)
    return scene, r, beta, fields


def replay_main(args, n_r: int, n_beta: int) -> int:
    """The refinement of each ``--cluster`` scene replayed on its dense grid's fields."""
    from analysis.adaptive import closed_form_guide
    from tasks.stream import StreamRefinement

    print(
        f"refinement replayed on the dense grid's fields, {n_r} x {n_beta}, fidelity "
        f"{args.fidelity}, coarse_step {args.coarse_step}, hint {args.hint}, "
        "verify_fraction 0.005"
    )
    print(
        "| scene | points | % simulated | % of the dense grid's cycles | cycles ratio "
        "| labels equal to dense | of the differing, determined in the dense grid "
        "| verification | refinement CPU s | bound: points next to a label change, "
        "% of the dense cycles (cycles ratio) |"
    )
    print("|" + "---|" * 10)
    composition = {}
    for sc in cluster_scenes(args.scenes):
        scene, r, beta, dense = dense_fields(sc, n_r, n_beta, args.cache, args.fidelity)
        hint = predicted = None
        if args.hint != "none":
            hint, predicted = closed_form_guide(scene, r, beta, args.hint)
        if args.no_predicted:
            predicted = None
        runs = {"": (StreamRefinement, predicted)}
        if args.code is not None:  # another checkout's refinement: its own hint only
            runs = {", before": (_stream_class(args.code), None)} | runs
        maps = {}
        for label, (cls, pred) in runs.items():
            out, v, cpu = _replay(cls, (n_r, n_beta), args.coarse_step, hint, dense, pred)
            maps[label] = out
            sim = out["simulated"]
            cycles = dense["cycles"].astype(float)
            share = cycles[sim].sum() / cycles.sum()
            differ = out["regime"] != dense["regime"]
            n = sim.size
            edge = next_to_change(dense)
            bound = cycles[edge].sum() / cycles.sum()
            print(
                f"| {sc['name']}{label} | {n:,} | {100 * sim.mean():.2f} ({int(sim.sum()):,}) "
                f"| {100 * share:.2f} "
                f"| {1 / share:.1f} | {percent(n - int(differ.sum()), n, 4)} "
                f"({int(differ.sum())} differ) | {int((differ & (dense['regime'] >= 0)).sum())} "
                f"| {v.agree} / {v.sampled} | {cpu:.3f} | {int(edge.sum()):,}, "
                f"{100 * bound:.2f} ({1 / bound:.1f}) |",
                flush=True,
            )
        if len(maps) > 1:
            a, b = maps.values()
            same = all(np.array_equal(a[k], b[k]) for k in a)
            print(f"| {sc['name']}: same map (every field, simulated, verification) | {same} |")
        composition[sc["name"]] = _composition(maps[""], dense, args.coarse_step)
    print()
    print(
        "where the simulated points lie (their dense cycles, % of the dense grid's): the "
        "coarse lattice, the verification sample, the points next to a label change "
        "(edge), the others (the refinement's points between); the cycles ratio of the "
        "map without the others, and of the edge points it simulates alone"
    )
    print(
        "| scene | lattice | sample | edge (of all edge points) | others | cycles ratio "
        "without the others | edge only |"
    )
    print("|" + "---|" * 7)
    for name, c in composition.items():
        parts = " | ".join(
            f"{c[k][0]:,}, {100 * c[k][1]:.2f}" for k in ("lattice", "sample", "edge", "other")
        )
        parts = parts.replace(f"{c['edge'][0]:,},", f"{c['edge'][0]:,} of {c['edges']:,},", 1)
        without = c["lattice"][1] + c["sample"][1] + c["edge"][1]
        print(f"| {name} | {parts} | {1 / without:.1f} | {1 / c['edge'][1]:.1f} |")
    return 0


def _composition(out: dict, dense: dict, coarse_step: int) -> dict:
    """The simulated points of a replayed map by kind (lattice, verification sample,
    next to a label change of the dense grid, others), each as (points, share of the
    dense grid's cycles)."""
    from tasks.adaptive import coarse_nodes

    sim = out["simulated"]
    lattice = np.zeros(sim.shape, dtype=bool)
    lattice[np.ix_(*(coarse_nodes(n, coarse_step) for n in sim.shape))] = True
    sample = (out["verification"] > 0) & ~lattice
    edge = next_to_change(dense)
    kinds = {
        "lattice": sim & lattice,
        "sample": sample,
        "edge": sim & edge & ~lattice & ~sample,
        "other": sim & ~edge & ~lattice & ~sample,
    }
    cycles = dense["cycles"].astype(float)
    total = cycles.sum()
    c = {k: (int(m.sum()), float(cycles[m].sum() / total)) for k, m in kinds.items()}
    c["edges"] = int(edge.sum())
    return c


def next_to_change(dense: dict[str, np.ndarray]) -> np.ndarray:
    """Points of the dense grid with a 4-neighbour of another refinement key
    (:data:`tasks.adaptive.KEY_FIELDS`): those every correct map simulates."""
    from tasks.adaptive import KEY_FIELDS

    key = np.zeros(dense["regime"].shape, dtype=np.int64)
    for name in KEY_FIELDS:
        key = key * 1024 + (dense[name].astype(np.int64) + 512)
    edge = np.zeros(key.shape, dtype=bool)
    for axis in (0, 1):
        a = [slice(None)] * 2
        b = [slice(None)] * 2
        a[axis], b[axis] = slice(1, None), slice(None, -1)
        change = key[tuple(a)] != key[tuple(b)]
        edge[tuple(a)] |= change
        edge[tuple(b)] |= change
    return edge


def _replay(cls, shape, coarse_step, hint, dense, predicted=None):
    """One refinement (class ``cls``) on the dense fields, point lists of 64: its result,
    verification summary and CPU seconds (the hint and the prediction excluded)."""
    from study.adaptive import VERIFY_SEED
    from tasks.adaptive import DEFAULT_VERIFY_MIN

    t = time.process_time()
    layout = {k: (str(v.dtype), 0) for k, v in dense.items()}
    extra = {} if predicted is None else {"predicted": predicted}
    ref = cls(shape, coarse_step, hint, fields=layout, **extra)
    while (idx := ref.take(64)).size:
        ij = np.unravel_index(idx, ref.shape)
        ref.accept(idx, {k: v[ij] for k, v in dense.items()})
    sample = ref.verification(0.005, DEFAULT_VERIFY_MIN, VERIFY_SEED)
    ij = np.unravel_index(sample, ref.shape)
    v = ref.accept_verification(sample, {k: f[ij] for k, f in dense.items()})
    out = ref.result()
    out["levels"] = np.asarray(ref.level_sizes())
    return out, v, time.process_time() - t


def _stream_class(code: Path):
    """The ``StreamRefinement`` of another checkout (``tasks/stream.py``, or
    ``tasks/adaptive.py`` where it was before it moved); the per-cell helpers it
    calls (:mod:`tasks.cells`, :class:`tasks.adaptive.Refinement`) come from this one,
    ``tasks.cells.halves`` cutting at the middle when no hint table is passed."""
    path = "tasks/stream.py" if (code / "tasks/stream.py").is_file() else "tasks/adaptive.py"
    return _module(code, path).StreamRefinement


def _module(code: Path, path: str):
    """The module ``path`` of another checkout ``code`` (e.g. ``../main``), loaded under
    a name of its own (its imports come from this checkout)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(f"before_{Path(path).stem}", code / path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def study_units(args, sc: dict, n_r: int, n_beta: int) -> dict[str, list]:
    """The tasks of the adaptive study of the ``--cluster`` scene ``sc``, run once in this
    process: its ``tiles`` (``study.tiles.tile_chunk``) and point ``lists`` (the sample)."""
    import tempfile

    import study.compute as compute
    import study.tiles as tiles
    from study.cli import main as study_main

    units: dict[str, list] = {"tiles": [], "lists": []}
    tile_chunk, point_list = tiles.tile_chunk, compute.KINDS["adaptive"]
    tiles.tile_chunk = lambda task: units["tiles"].append(task) or tile_chunk(task)
    compute.KINDS["adaptive"] = lambda task: units["lists"].append(task) or point_list(task)
    mode = ADAPTIVE_MODE.format(step=args.coarse_step)
    text = STUDY.format(fidelity=args.fidelity, mode=mode, n_r=n_r, n_beta=n_beta, **sc)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            (Path(tmp) / "s.toml").write_text(text)
            study_main(["run", str(Path(tmp) / "s.toml"), "-o", str(Path(tmp) / "s.nc"), "--quiet"])
    finally:
        tiles.tile_chunk, compute.KINDS["adaptive"] = tile_chunk, point_list
    return units


def recorded_periods(units: dict[str, list], r: np.ndarray, beta: np.ndarray):
    """Compute an adaptive study's tasks (:func:`study_units`) again, recording each
    simulated point: its flat index on the plane ``r`` x ``beta``, its periods
    (``cycles``) and its part (a tile's coarse lattice, its refinement, the point lists:
    the verification sample, and the cells where the tiles meet)."""
    import study.compute as compute
    import study.tiles as tiles

    got: list[tuple[np.ndarray, np.ndarray, str]] = []
    part = [""]
    classify_unit = compute._classify

    def recorded(scene, settings, rr, bb, given=None):
        out = classify_unit(scene, settings, rr, bb, given)
        i = np.clip(np.searchsorted(r, rr - 1e-12 * np.abs(rr)), 0, r.size - 1)
        j = np.clip(np.searchsorted(beta, bb - 1e-12), 0, beta.size - 1)
        got.append((i * beta.size + j, out["cycles"].astype(float), part[0]))
        part[0] = "refinement"
        return out

    compute._classify = recorded
    try:
        for unit in units["tiles"]:
            part[0] = "coarse lattice"  # a tile's first round
            tiles.tile_chunk(unit)
        for unit in units["lists"]:
            part[0] = "point lists"  # the sample, and the cells where tiles meet
            compute.KINDS["adaptive"](unit)
    finally:
        compute._classify = classify_unit
    flat = np.concatenate([g[0] for g in got])
    periods = np.concatenate([g[1] for g in got])
    parts = np.concatenate([np.full(g[0].size, g[2]) for g in got])
    return flat, periods, parts


def periods_main(args, n_r: int, n_beta: int) -> int:
    """``--periods``: where the simulated periods (``cycles``) of each ``--cluster`` scene's
    adaptive study go, against the same points in the dense grid (cached, as ``--replay``)."""
    from scipy import ndimage

    print(
        f"periods of the adaptive study's points against the dense grid's, {n_r} x {n_beta}, "
        f"fidelity {args.fidelity}, coarse_step {args.coarse_step}, hint exact"
    )
    for sc in cluster_scenes(args.scenes):
        scene, r, beta, dense = dense_fields(sc, n_r, n_beta, args.cache, args.fidelity)
        units = study_units(args, sc, n_r, n_beta)
        flat, ad, parts = recorded_periods(units, r, beta)
        dc = dense["cycles"].astype(float).ravel()
        de = dc[flat]
        edge = next_to_change(dense)
        dist = ndimage.distance_transform_cdt(~edge, metric="chessboard").ravel()[flat]
        regime = dense["regime"].ravel()[flat]
        print(
            f"\n{sc['name']}: {flat.size:,} points simulated ({100 * flat.size / dc.size:.2f} %), "
            f"{ad.sum():,.0f} periods, {de.sum():,.0f} in the dense grid at the same points "
            f"(x {ad.sum() / de.sum():.2f}); dense grid {dc.sum():,.0f} periods: ratio "
            f"{dc.sum() / ad.sum():.1f} (at the dense cost {dc.sum() / de.sum():.1f})"
        )
        tail = ad - de > 10
        print(
            f"points costing over 10 periods more than in the dense grid: {int(tail.sum())} "
            f"({100 * tail.mean():.1f} %), {100 * (ad - de)[tail].sum() / (ad - de).sum():.0f} % "
            "of the excess"
        )
        print("| points | n | periods (mean) | dense periods there (mean) | share of the periods |")
        print("|---|---|---|---|---|")
        groups = [(f"part: {p}", parts == p) for p in dict.fromkeys(parts)]
        for lo, hi in ((0, 0), (1, 1), (2, 3), (4, 7), (8, None)):
            name = f"{lo}" if lo == hi else f"{lo}-{hi}" if hi else f"{lo}+"
            upper = dist.max() if hi is None else hi
            groups.append((f"steps to a change: {name}", (dist >= lo) & (dist <= upper)))
        groups += [(f"dense regime {int(g)}", regime == g) for g in np.unique(regime)]
        for name, m in groups:
            if m.any():
                print(
                    f"| {name} | {int(m.sum()):,} | {ad[m].mean():.2f} | {de[m].mean():.2f} "
                    f"| {ad[m].sum() / ad.sum():.3f} |",
                    flush=True,
                )
    return 0


def tasks_main(args, n_r: int, n_beta: int) -> int:
    """``--tasks``: the adaptive study's tiles and point lists against the dense grid's
    chunks, CPU seconds in this process, in all and in the compiled simulator."""
    import study.compute as compute
    import study.tiles as tiles
    from tasks import kernel

    spent = [0.0]
    simulator = kernel.run_points_given

    def timed(*a):  # the simulator's CPU seconds (tasks.classifier calls kernel.<name>)
        t0 = time.process_time()
        try:
            return simulator(*a)
        finally:
            spent[0] += time.process_time() - t0

    def cpu(run, units: list) -> tuple[float, float]:
        spent[0] = 0.0
        t0 = time.process_time()
        for unit in units:
            run(unit)
        return time.process_time() - t0, spent[0]

    load = Path("/proc/loadavg").read_text().split()[0] if Path("/proc/loadavg").exists() else "?"
    print(
        f"the adaptive study's tasks against the dense grid, {n_r} x {n_beta}, one process, "
        f"fidelity {args.fidelity}, coarse_step {args.coarse_step}, hint exact; CPU s "
        f"(of which the compiled simulator); load average {load} at the start"
    )
    print(
        "| scene | dense grid | tiles | point lists (the sample) | dense / tasks "
        "| dense / simulator in the tasks |"
    )
    print("|---|---|---|---|---|---|")
    point_list = compute.KINDS["adaptive"]
    for sc in cluster_scenes(args.scenes):
        units = study_units(args, sc, n_r, n_beta)
        kernel.run_points_given = timed
        try:
            first = units["tiles"][0] if units["tiles"] else units["lists"][0]
            grid = {"kind": "grid", "scene": first["scene"], "settings": first["settings"]}
            r = np.linspace(sc["r_start"], sc["r_stop"], n_r)
            beta = np.linspace(sc["b_start"], sc["b_stop"], n_beta)
            blocks = [grid | {"r": r[i : i + 10], "beta": beta} for i in range(0, n_r, 10)]
            dense = cpu(compute.compute_chunk, blocks)
            runs = max(2, args.repeat)
            tile = min(cpu(tiles.tile_chunk, units["tiles"]) for _ in range(runs))
            lists = min(cpu(point_list, units["lists"]) for _ in range(runs))
        finally:
            kernel.run_points_given = simulator
        total, inner = tile[0] + lists[0], tile[1] + lists[1]
        print(
            f"| {sc['name']} | {dense[0]:.2f} ({dense[1]:.2f}) | {tile[0]:.3f} ({tile[1]:.3f}) "
            f"| {lists[0]:.3f} ({lists[1]:.3f}) | {dense[0] / total:.1f} "
            f"| {dense[0] / inner:.1f} |",
            flush=True,
        )
    return 0


def example_main(args) -> int:
    """``study run examples/adaptive.toml`` (the CLI, a fresh process each time, the
    compiled kernel in its cache): wall seconds and the CPU seconds of the process."""
    import resource
    import statistics
    import subprocess
    import tempfile

    from tasks import Scene

    classify(Scene("ground", 2), 1.0, 0.3)  # the kernel in the disk cache
    example = EXAMPLES / "adaptive.toml"
    walls, cpus = [], []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "x.nc"
        for _ in range(args.example):
            out.unlink(missing_ok=True)
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            t = time.perf_counter()
            cmd = [sys.executable, "-m", "study", "run", str(example), "-o", str(out), "--quiet"]
            subprocess.run(cmd, check=True, capture_output=True)
            walls.append(time.perf_counter() - t)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpus.append(after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime)
    load = Path("/proc/loadavg").read_text().split()[0] if Path("/proc/loadavg").exists() else "?"
    print(f"study run examples/adaptive.toml -o x.nc, {args.example} runs, load average {load}")
    print("| | best | median |")
    print("|---|---:|---:|")
    print(f"| wall s | {min(walls):.1f} | {statistics.median(walls):.1f} |")
    print(f"| CPU s (all threads) | {min(cpus):.1f} | {statistics.median(cpus):.1f} |")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="1000x500", help="points along r x beta (1000x500)")
    ap.add_argument("--panels", nargs="*", help="fig04 or fig04:gamma1_kappa1 (default: all)")
    ap.add_argument("--coarse-step", type=int, default=16)
    ap.add_argument("--hint", default="exact", choices=("exact", "paper", "none"))
    ap.add_argument("--fidelity", default="balanced")
    ap.add_argument("--cache", type=Path, default=Path(".bench_adaptive_cache"))
    ap.add_argument("--cluster", action="store_true", help="adaptive vs dense studies on Dask")
    ap.add_argument("--replay", action="store_true", help="refinement on cached dense fields")
    ap.add_argument(
        "--no-predicted",
        action="store_true",
        help="--replay: the hint without its prediction (tasks.adaptive.Refinement)",
    )
    ap.add_argument("--workers", type=int, default=2, help="--cluster: worker processes")
    ap.add_argument(
        "--scenes", nargs="*", help="--cluster, --replay: fig04:gamma1_kappa1, dof3_mass_m2_m3"
    )
    ap.add_argument("--no-dense", action="store_true", help="--cluster: adaptive studies only")
    ap.add_argument("--barriers", action="store_true", help="--cluster: the old waves too")
    ap.add_argument(
        "--repeat",
        type=int,
        default=1,
        help="--cluster: adaptive studies run N times each (alternating), the best kept",
    )
    ap.add_argument(
        "--before",
        action="store_true",
        help="--cluster: also the adaptive study without corner seeds, lists of 64",
    )
    ap.add_argument(
        "--untiled",
        action="store_true",
        help="--cluster: also the adaptive study without tiles (study.tiles), same run",
    )
    ap.add_argument("--timeline", action="store_true", help="where the wall time goes")
    ap.add_argument(
        "--tile-sample", action="store_true", help="--cluster: the sample inside the tiles too"
    )
    ap.add_argument("--tasks", action="store_true", help="the adaptive tasks' CPU, one process")
    ap.add_argument("--periods", action="store_true", help="where the adaptive study's periods go")
    ap.add_argument("--example", type=int, default=0, help="time the CLI on the example N times")
    ap.add_argument(
        "--code",
        type=Path,
        help="--replay: also the refinement of this checkout (e.g. ../main); --cluster: "
        "also the adaptive study run by its client (study and tasks); same run",
    )
    args = ap.parse_args(argv)
    if args.code and not (Path(args.code) / "study" / "__init__.py").is_file():
        ap.error(f"--code: {args.code} holds no study package (its runner would import this one)")
    n_r, n_beta = (int(x) for x in args.size.lower().split("x"))
    if args.example:
        return example_main(args)
    if args.replay:
        return replay_main(args, n_r, n_beta)
    if args.tasks:
        return tasks_main(args, n_r, n_beta)
    if args.periods:
        return periods_main(args, n_r, n_beta)
    if args.timeline:
        return timeline_main(args, n_r, n_beta)
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
