"""``mode = "adaptive"``: a grid scene simulated by refinement waves on Dask.

The refinement logic is :class:`tasks.adaptive.Refinement` (pure numerics);
this module runs each of its levels as a wave of Dask tasks: the points of a
wave are cut into point lists of about ``task_seconds`` of work, each keyed by
a hash of (scene physics, settings, the points' r and beta values) and saved
in the work folder as it arrives, like the chunks of a grid. The refinement is
deterministic, so a rerun after an interruption replays the waves, finds every
saved point list on disk and computes only the missing ones. When a plane (one
combination of the swept ratios) is complete, its assembled fields are saved
in the work folder too (one plane in client memory at a time) and the netCDF
writer (:mod:`study.netcdf`) copies them into the result.

The result has the layout of a grid scene (dims ``(gamma, kappa, r, beta)``,
every variable of :data:`tasks.result.FIELDS`) plus ``simulated`` and
``verification`` (:data:`tasks.adaptive.ADAPTIVE_FIELDS`) and attributes with
the verification sample's agreement.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import sys
import time
from collections.abc import Iterator
from concurrent.futures import CancelledError
from typing import TextIO

import numpy as np

from study.chunks import CHUNK_FORMAT, ScenePlan
from study.compute import compute_chunk
from study.errors import StudyFailed
from study.store import WorkDir
from study.watchdog import watched_batches, watched_gather
from tasks.adaptive import (
    DEFAULT_VERIFY_MIN,
    Refinement,
    VerificationSummary,
    disagreement_upper_bound,
)
from tasks.result import FIELDS, MASS_FIELDS, field_shape

#: Seed of the verification sample (fixed: a rerun draws the same sample).
VERIFY_SEED = 0
#: Seconds between two progress lines of the waves of one plane.
PRINT_EVERY = 10.0
#: Plane statistics saved with each plane (0-d or 1-d arrays in the plane file).
STAT_NAMES = ("levels", "n_points", "verify_inferred", "verify_sampled", "verify_agree")


def planes(plan: ScenePlan) -> Iterator[tuple[int, ...]]:
    """The sweep indices of every (r, beta) plane of the scene."""
    return itertools.product(*(range(n) for n in plan.spec.sweep_shape))


def _ident(plan: ScenePlan, sweep: tuple[int, ...], axes: dict) -> dict:
    return {
        "format": CHUNK_FORMAT,
        "scene": plan.spec.name,
        "physics": plan.scene_dict(sweep, axes),
        "fidelity": plan.fidelity,
        "settings": plan.settings,
    }


def plane_key(plan: ScenePlan, sweep: tuple[int, ...], axes: dict | None = None) -> str:
    """Work-folder key of a finished plane: the physics, settings, axes and refinement settings."""
    axes = plan.axes() if axes is None else axes
    spec = plan.spec
    ident = _ident(plan, sweep, axes) | {
        "kind": "adaptive-plane",
        "coarse_step": spec.coarse_step,
        "verify_fraction": spec.verify_fraction,
        "verify_min": DEFAULT_VERIFY_MIN,
        "hint": spec.hint,
        "seed": VERIFY_SEED,
    }
    h = hashlib.sha256(json.dumps(ident, sort_keys=True).encode())
    h.update(np.ascontiguousarray(axes["r"]).tobytes())
    h.update(np.ascontiguousarray(axes["beta"]).tobytes())
    index = "-".join(str(i) for i in sweep) or "0"
    return f"{spec.name}-plane-{index}-{h.hexdigest()[:20]}"


def missing_planes(plan: ScenePlan, work: WorkDir) -> list[tuple[int, ...]]:
    """Planes of an adaptive scene not yet saved in the work folder."""
    axes = plan.axes()
    return [s for s in planes(plan) if not work.has(plan.spec.name, plane_key(plan, s, axes))]


def _hint(plan: ScenePlan, sweep: tuple[int, ...], axes: dict) -> np.ndarray | None:
    if plan.spec.hint == "none":
        return None
    from analysis.adaptive import closed_form_hint

    ratios = {k: float(axes[k][i]) for k, i in zip(plan.spec.sweeps, sweep, strict=True)}
    return closed_form_hint(plan.spec.scene_at(**ratios), axes["r"], axes["beta"], plan.spec.hint)


def run_adaptive(
    client,
    plan: ScenePlan,
    work: WorkDir,
    retries: int = 3,
    stream: TextIO | None = None,
    verbose: bool = True,
    saved: list[int] | None = None,
    bar=None,
    watchdog=None,
) -> list[VerificationSummary]:
    """Refine every missing plane of an adaptive scene, one wave of Dask tasks per level.

    ``saved[0]`` is incremented for every point list saved (for the message of
    an interrupted run); ``bar`` (a :class:`study.progress.Progress`) advances by a
    plane's points when the plane is done; ``watchdog`` (a
    :class:`study.watchdog.Watchdog`) stops a wave that waits on a lost scheduler or
    on no worker. Returns the verification summaries of the planes computed.
    """
    stream = stream if stream is not None else sys.stderr
    saved = saved if saved is not None else [0]
    spec = plan.spec
    axes = plan.axes()
    r, beta = axes["r"], axes["beta"]
    summaries = []
    for sweep in missing_planes(plan, work):
        t0 = time.perf_counter()
        ident = _ident(plan, sweep, axes)
        ref = Refinement(
            (r.size, beta.size), spec.coarse_step, _hint(plan, sweep, axes), dof=spec.dof
        )
        counts = [0, 0]  # point lists reused, computed

        def simulate(idx: np.ndarray, ident: dict = ident, counts: list = counts) -> dict:
            out, n_reused, n_computed = _wave(
                client, plan, ident, r, beta, idx, work, retries, saved, watchdog
            )
            counts[0] += n_reused
            counts[1] += n_computed
            return out

        wave = 0
        shown = time.monotonic()
        while (idx := ref.wave()).size:
            ref.accept(idx, simulate(idx))
            wave += 1
            if verbose and time.monotonic() - shown > PRINT_EVERY:
                shown = time.monotonic()
                print(
                    f"study: {spec.name}{list(sweep) if sweep else ''}: wave {wave}: "
                    f"{idx.size:,} points ({int(ref.simulated.sum()):,} of {ref.n_points:,} "
                    "simulated so far)",
                    file=stream,
                )
        sample = ref.verification(spec.verify_fraction, DEFAULT_VERIFY_MIN, VERIFY_SEED)
        summary = ref.accept_verification(
            sample, simulate(sample) if sample.size else _empty(spec.dof)
        )
        fields = ref.result()
        n_sim = int(fields["simulated"].sum())
        # the plane's line with its verification estimate is always printed
        print(
            f"study: {spec.name}{list(sweep) if sweep else ''}: {n_sim:,} of "
            f"{ref.n_points:,} points simulated ({100 * n_sim / ref.n_points:.2f} %, "
            f"verification included) in {len(ref.levels)} waves, "
            f"{time.perf_counter() - t0:.1f} s; point lists {counts[1]} computed, "
            f"{counts[0]} reused; {summary.line()}",
            file=stream,
        )
        fields["levels"] = np.asarray(ref.levels, dtype=np.int64)
        fields["n_points"] = np.int64(ref.n_points)
        fields["verify_inferred"] = np.int64(summary.inferred)
        fields["verify_sampled"] = np.int64(summary.sampled)
        fields["verify_agree"] = np.int64(summary.agree)
        work.save(spec.name, plane_key(plan, sweep, axes), fields)
        summaries.append(summary)
        if bar is not None:
            bar.update(ref.n_points)
    return summaries


def _empty(dof: int) -> dict[str, np.ndarray]:
    return {k: np.zeros(field_shape(k, (0,), dof), dtype=dt) for k, (dt, _) in FIELDS.items()}


def _point_lists(plan, ident, r, beta, idx) -> list[tuple[str, slice, dict]]:
    """Cut the points ``idx`` of a wave into keyed point lists of about one task each."""
    size = max(1, plan.block[0])
    i_r, i_b = np.unravel_index(idx, (r.size, beta.size))
    head = hashlib.sha256(json.dumps(ident | {"kind": "adaptive"}, sort_keys=True).encode())
    out = []
    for start in range(0, idx.size, size):
        sl = slice(start, min(start + size, idx.size))
        rr, bb = r[i_r[sl]], beta[i_b[sl]]
        h = head.copy()
        h.update(np.ascontiguousarray(rr).tobytes())
        h.update(np.ascontiguousarray(bb).tobytes())
        key = f"{plan.spec.name}-pts-{h.hexdigest()[:24]}"
        task = {
            "kind": "adaptive",
            "scene": ident["physics"],
            "settings": plan.settings,
            "r": rr,
            "beta": bb,
        }
        out.append((key, sl, task))
    return out


def _wave(client, plan, ident, r, beta, idx, work, retries, saved, watchdog=None):
    """Simulate the points ``idx`` (reusing saved point lists); their FIELDS arrays."""
    from distributed import as_completed

    name = plan.spec.name
    lists = _point_lists(plan, ident, r, beta, idx)
    dof = plan.spec.dof
    out = {k: np.zeros(field_shape(k, (idx.size,), dof), dtype=dt) for k, (dt, _) in FIELDS.items()}
    todo = []
    n_reused = 0
    for key, sl, task in lists:
        if work.has(name, key):
            arrays = work.load(name, key)
            for k in out:
                out[k][sl] = arrays[k]
            n_reused += 1
        else:
            todo.append((key, sl, task))
    if not todo:
        return out, n_reused, 0
    futures = client.map(
        compute_chunk,
        [t for _, _, t in todo],
        key=[f"study-{k}" for k, _, _ in todo],
        retries=retries,
        pure=False,
    )
    where = {f.key: (k, sl) for f, (k, sl, _) in zip(futures, todo, strict=True)}
    try:
        for fut in (f for batch in watched_batches(as_completed(futures), watchdog) for f in batch):
            key, sl = where[fut.key]
            try:
                arrays = watched_gather(client, [fut], watchdog)[0]
            except (KeyboardInterrupt, StudyFailed):  # StudyFailed: the watchdog's verdict
                raise
            except BaseException as exc:  # CancelledError is not an Exception
                why = (
                    "was cancelled by the scheduler"
                    if isinstance(exc, CancelledError)
                    else f"failed after {retries} retries: {type(exc).__name__}: {exc}"
                )
                raise StudyFailed(
                    f"point list {key} of scene {name} {why}; finished work is kept in "
                    f"{work.path}, rerun to resume"
                ) from None
            work.save(name, key, arrays)
            saved[0] += 1
            for k in out:
                out[k][sl] = arrays[k]
            fut.release()
    except BaseException:
        client.cancel(futures)
        raise
    return out, n_reused, len(todo)


def plane_stats(arrays: dict[str, np.ndarray]) -> dict[str, int]:
    """The counts saved with a plane (for the result's attributes)."""
    return {
        "points": int(arrays["n_points"]),
        "simulated": int(np.asarray(arrays["simulated"]).sum()),
        "waves": int(np.asarray(arrays["levels"]).size),
        "verify_inferred": int(arrays["verify_inferred"]),
        "verify_sampled": int(arrays["verify_sampled"]),
        "verify_agree": int(arrays["verify_agree"]),
    }


def result_attrs(plan: ScenePlan, stats: list[dict[str, int]]) -> dict[str, object]:
    """Scene attributes of an adaptive result, summed over its planes."""
    spec = plan.spec
    tot = {k: sum(s[k] for s in stats) for k in stats[0]} if stats else {}
    sampled, agree = tot.get("verify_sampled", 0), tot.get("verify_agree", 0)
    return {
        "adaptive_coarse_step": spec.coarse_step,
        "adaptive_coarse_step_note": (
            "coarsest spacing in grid steps: a region containing a square of this many grid "
            "steps is sure to be found; narrower features may be missed (tasks.adaptive)"
        ),
        "adaptive_hint": spec.hint,
        "adaptive_points": tot.get("points", 0),
        "adaptive_points_simulated": tot.get("simulated", 0),
        "adaptive_simulated_fraction": tot.get("simulated", 0) / max(1, tot.get("points", 0)),
        "adaptive_waves_per_plane": json.dumps([s["waves"] for s in stats]),
        "verification_fraction": spec.verify_fraction,
        "verification_seed": VERIFY_SEED,
        "verification_inferred_points": tot.get("verify_inferred", 0),
        "verification_sampled": sampled,
        "verification_agree": agree,
        "verification_agreement": agree / sampled if sampled else float("nan"),
        "verification_disagreement_upper_95": disagreement_upper_bound(sampled, sampled - agree),
    }


def plane_writes(plan: ScenePlan, work, variables: dict[str, str]):
    """``(variable, index, values)`` of every saved plane of an adaptive scene (one plane
    in memory at a time), then ``(None, None, stats)`` with the planes' counts.

    Planes are saved as ``(r, beta[, mass])`` arrays; the stored layout is
    ``(..., [mass,] beta, r)`` (:mod:`study.netcdf`).
    """
    axes = plan.axes()
    stats = []
    for sweep in planes(plan):
        arrays = work.load(plan.spec.name, plane_key(plan, sweep, axes))
        for name in variables:
            index = (*sweep, slice(None), slice(None))
            if name in MASS_FIELDS:
                index = (*sweep, slice(None), slice(None), slice(None))
            yield name, index, np.asarray(arrays[name]).T
        stats.append(plane_stats(arrays))
    yield None, None, stats


def fill_adaptive(group, plan: ScenePlan, work: WorkDir, variables: dict[str, str]) -> None:
    """Write every saved plane of an adaptive scene into its netCDF group (one plane in memory),
    then the scene's adaptive and verification attributes."""
    for name, index, values in plane_writes(plan, work, variables):
        if name is None:
            for k, v in result_attrs(plan, values).items():
                group.setncattr(k, v)
            continue
        var = group.variables[name]
        var[index] = values.astype(var.dtype, copy=False)
