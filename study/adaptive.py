"""``mode = "adaptive"``: a grid scene simulated by refinement waves (:class:`AdaptivePlan`).

The refinement logic is :class:`tasks.adaptive.Refinement` (pure numerics);
this plan hands out each of its levels as units of work (:mod:`study.chunks`
describes the interface every plan shares): the points of a wave are cut into
point lists of about ``task_seconds`` of work, each keyed by a hash of (scene
physics, settings, the points' r and beta values) and saved in the work folder
as it arrives, like the chunks of a grid. The refinement is deterministic, so a
rerun after an interruption replays the waves, finds every saved point list on
disk and computes only the missing ones. When a plane (one combination of the
swept ratios) is complete, its assembled fields are saved in the work folder
too (one plane in client memory at a time) and the netCDF writer
(:mod:`study.netcdf`) copies them into the result. Saved planes and point lists
are verified before any computing (:meth:`AdaptivePlan.prepare`; the exact
length of a point list when its wave asks for it): a damaged one is discarded,
named and computed again in the same run.

The result has the layout of a grid scene (dims ``(gamma, kappa, beta, r)``,
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
from dataclasses import dataclass, field
from typing import TextIO

import numpy as np

from study.cost import chunk_target
from study.definition import SceneSpec, Study
from study.plans import CHUNK_FORMAT, SECONDS, WAIT, ScenePlan
from study.verify import Expected
from tasks.adaptive import (
    ADAPTIVE_FIELDS,
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
#: Planes refined at the same time (in memory at once): the waves of one fill the
#: workers while another waits for the last points of its wave.
PLANES_AT_ONCE = 2
#: Fraction of the points an adaptive scene is expected to simulate (planning only).
ADAPTIVE_SIMULATED_FRACTION = 0.05


@dataclass(frozen=True)
class PointList:
    """One unit of work of an adaptive scene: points ``sl`` of the current wave."""

    scene: str
    key: str
    sl: slice
    task: dict = field(repr=False, compare=False)
    sweep: tuple[int, ...] = ()  # the plane it belongs to

    @property
    def n_points(self) -> int:
        return self.sl.stop - self.sl.start


@dataclass
class _Plane:
    """The refinement of one (r, beta) plane while it runs."""

    sweep: tuple[int, ...]
    ref: Refinement
    ident: dict
    t0: float
    phase: str = "refine"  # then "verify"
    idx: np.ndarray | None = None  # points of the wave (or sample) being simulated
    out: dict = field(default_factory=dict)  # their results
    pending: list = field(default_factory=list)  # point lists not handed out yet
    outstanding: set = field(default_factory=set)  # keys handed out, not arrived
    waves: int = 0
    reused: int = 0
    computed: int = 0
    shown: float = field(default_factory=time.monotonic)


class AdaptivePlan(ScenePlan):
    """A grid scene whose points are simulated where refinement asks (tasks.adaptive)."""

    kind = "adaptive"
    planar = True
    work_per_point = ADAPTIVE_SIMULATED_FRACTION
    unit_noun = "adaptive planes"
    stream: TextIO | None = None  # where the planes' lines go (set by the run)
    verbose: bool = True

    @classmethod
    def build(cls, spec: SceneSpec, study: Study) -> AdaptivePlan:
        target = study.chunk_points or chunk_target(
            spec.dof, study.fidelity, study.task_seconds, spec.n_points // 20
        )
        return cls(spec, study.fidelity, study.settings.to_dict(), (target, 1))

    def variables(self) -> dict[str, str]:
        return super().variables() | {k: dt for k, (dt, _) in ADAPTIVE_FIELDS.items()}

    @property
    def n_chunks(self) -> int:  # an estimate: the waves decide
        return max(1, -(-int(self.work_per_point * self.spec.n_points) // self.block[0]))

    # ------------------------------------------------------------ keys and layouts
    def planes(self) -> Iterator[tuple[int, ...]]:
        """The sweep indices of every (r, beta) plane of the scene."""
        return itertools.product(*(range(n) for n in self.spec.sweep_shape))

    def _ident(self, sweep: tuple[int, ...], axes: dict) -> dict:
        return {
            "format": CHUNK_FORMAT,
            "scene": self.spec.name,
            "physics": self.scene_dict(sweep, axes),
            "fidelity": self.fidelity,
            "settings": self.settings,
        }

    def plane_key(self, sweep: tuple[int, ...], axes: dict | None = None) -> str:
        """Work-folder key of a finished plane: physics, settings, axes, refinement settings."""
        axes = self.axes() if axes is None else axes
        spec = self.spec
        ident = self._ident(sweep, axes) | {
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

    def plane_expected(self) -> Expected:
        """What a saved plane holds: every field at every point, and its counts."""
        shape = self.spec.plane_shape
        out = {k: (dt, field_shape(k, shape, self.spec.dof)) for k, dt in self.variables().items()}
        return out | {"levels": ("int64", None)} | {k: ("int64", ()) for k in STAT_NAMES[1:]}

    def expected(self, unit: PointList | None) -> Expected:
        """What a point list holds (any length when ``unit`` is None)."""
        n = None if unit is None else unit.n_points
        dof = self.spec.dof
        out = {
            k: (dt, None if n is None else field_shape(k, (n,), dof))
            for k, (dt, _) in FIELDS.items()
        }
        return out | SECONDS

    # ------------------------------------------------------------ driving (study.drive)
    def prepare(self, work) -> tuple[int, int, int]:
        """Verify the saved planes and point lists (discarding damaged ones); the planes to do."""
        axes = self._axes = self.axes()
        keys = {self.plane_key(s, axes): s for s in self.planes()}
        self._missing = []
        reused = 0
        for key, sweep in keys.items():
            if work.reuse(self.spec.name, key, self.plane_expected()):
                reused += 1
            else:
                self._missing.append(sweep)
        for key in work.keys(self.spec.name):
            if key not in keys:  # a point list: its fields and dtypes now, its length when used
                work.reuse(self.spec.name, key, self.expected(None))
        self._active: dict[tuple[int, ...], _Plane] = {}
        self.finished_points = reused * int(np.prod(self.spec.plane_shape))
        return len(keys), reused, self.finished_points

    def next_unit(self, work):
        """A point list of any plane in refinement: while one plane waits for the last
        points of its wave, the next plane's waves run (at most :data:`PLANES_AT_ONCE`
        planes in memory)."""
        while True:
            waiting = False
            for pl in list(self._active.values()):
                unit = self._next_of(pl, work)
                if unit is not None and unit is not WAIT:
                    return unit
                waiting |= unit is WAIT
            if self._missing and len(self._active) < PLANES_AT_ONCE:
                sweep = self._missing.pop(0)
                self._active[sweep] = self._start(sweep)
                continue
            return WAIT if waiting else None

    def _next_of(self, pl: _Plane, work):
        """The next point list of one plane, WAIT, or None when the plane is saved."""
        while pl.sweep in self._active:
            if pl.pending:
                unit = pl.pending.pop()
                if work.reuse(unit.scene, unit.key, self.expected(unit)):
                    self._take(pl, unit, work.load(unit.scene, unit.key))
                    pl.reused += 1
                    continue
                pl.outstanding.add(unit.key)
                return unit
            if pl.outstanding:
                return WAIT
            self._advance(pl, work)
        return None

    def task(self, unit: PointList, axes=None) -> dict:
        return unit.task

    def accept(self, unit: PointList, arrays: dict[str, np.ndarray], work) -> None:
        pl = self._active[unit.sweep]
        pl.outstanding.discard(unit.key)
        pl.computed += 1
        self._take(pl, unit, arrays)

    @staticmethod
    def _take(pl: _Plane, unit: PointList, arrays: dict[str, np.ndarray]) -> None:
        for k in pl.out:
            pl.out[k][unit.sl] = arrays[k]

    def _start(self, sweep: tuple[int, ...]) -> _Plane:
        axes, spec = self._axes, self.spec
        ref = Refinement(spec.plane_shape, spec.coarse_step, self._hint(sweep, axes), dof=spec.dof)
        return _Plane(sweep, ref, self._ident(sweep, axes), time.perf_counter())

    def _hint(self, sweep: tuple[int, ...], axes: dict) -> np.ndarray | None:
        if self.spec.hint == "none":
            return None
        from analysis.adaptive import closed_form_hint

        ratios = {k: float(axes[k][i]) for k, i in zip(self.spec.sweeps, sweep, strict=True)}
        scene = self.spec.scene_at(**ratios)
        return closed_form_hint(scene, axes["r"], axes["beta"], self.spec.hint)

    def _advance(self, pl: _Plane, work) -> None:
        """Every point of the current wave arrived: the next wave, the sample, or the end."""
        ref = pl.ref
        if pl.idx is not None:
            if pl.phase == "verify":
                self._finish(pl, ref.accept_verification(pl.idx, pl.out), work)
                return
            ref.accept(pl.idx, pl.out)
            pl.waves += 1
            if self.verbose and time.monotonic() - pl.shown > PRINT_EVERY:
                pl.shown = time.monotonic()
                self._say(
                    f"{self._where(pl)}: wave {pl.waves}: {pl.idx.size:,} points "
                    f"({int(ref.simulated.sum()):,} of {ref.n_points:,} simulated so far)"
                )
            pl.idx = None
        idx = ref.wave()
        if not idx.size:
            pl.phase = "verify"
            idx = ref.verification(self.spec.verify_fraction, DEFAULT_VERIFY_MIN, VERIFY_SEED)
            if not idx.size:
                self._finish(pl, ref.accept_verification(idx, _empty(self.spec.dof)), work)
                return
        pl.idx = idx
        pl.out = _empty(self.spec.dof, idx.size)
        pl.pending = self._point_lists(pl, idx)[::-1]  # popped from the end: in order

    def _point_lists(self, pl: _Plane, idx: np.ndarray) -> list[PointList]:
        """Cut the points ``idx`` of a wave into keyed point lists of about one task each."""
        r, beta = self._axes["r"], self._axes["beta"]
        size = max(1, self.block[0])
        i_r, i_b = np.unravel_index(idx, (r.size, beta.size))
        head = hashlib.sha256(json.dumps(pl.ident | {"kind": "adaptive"}, sort_keys=True).encode())
        out = []
        for start in range(0, idx.size, size):
            sl = slice(start, min(start + size, idx.size))
            rr, bb = r[i_r[sl]], beta[i_b[sl]]
            h = head.copy()
            h.update(np.ascontiguousarray(rr).tobytes())
            h.update(np.ascontiguousarray(bb).tobytes())
            key = f"{self.spec.name}-pts-{h.hexdigest()[:24]}"
            task = {
                "kind": "adaptive",
                "scene": pl.ident["physics"],
                "settings": self.settings,
                "r": rr,
                "beta": bb,
            }
            out.append(PointList(self.spec.name, key, sl, task, pl.sweep))
        return out

    def _finish(self, pl: _Plane, summary: VerificationSummary, work) -> None:
        """Save the finished plane (its fields and counts) and say so in one line."""
        ref = pl.ref
        fields = ref.result()
        n_sim = int(fields["simulated"].sum())
        self._say(  # the plane's line with its verification estimate is always printed
            f"{self._where(pl)}: {n_sim:,} of {ref.n_points:,} points simulated "
            f"({100 * n_sim / ref.n_points:.2f} %, verification included) in "
            f"{len(ref.levels)} waves, {time.perf_counter() - pl.t0:.1f} s; point lists "
            f"{pl.computed} computed, {pl.reused} reused; {summary.line()}",
            always=True,
        )
        fields["levels"] = np.asarray(ref.levels, dtype=np.int64)
        fields["n_points"] = np.int64(ref.n_points)
        fields["verify_inferred"] = np.int64(summary.inferred)
        fields["verify_sampled"] = np.int64(summary.sampled)
        fields["verify_agree"] = np.int64(summary.agree)
        work.save(self.spec.name, self.plane_key(pl.sweep, self._axes), fields)
        self.finished_points += ref.n_points
        del self._active[pl.sweep]

    def _where(self, pl: _Plane) -> str:
        return f"study: {self.spec.name}{list(pl.sweep) if pl.sweep else ''}"

    def _say(self, line: str, always: bool = False) -> None:
        if always or self.verbose:
            print(line, file=self.stream if self.stream is not None else sys.stderr)

    # ------------------------------------------------------------ writing (study.netcdf)
    def writes(self, work):
        """``(variable, index, values)`` of every saved plane (one plane in memory at a
        time); their counts are kept for :meth:`result_attrs`.

        Planes are saved as ``(r, beta[, mass])`` arrays; the stored layout is
        ``(..., [mass,] beta, r)`` (:mod:`study.netcdf`).
        """
        axes = self.axes()
        self._stats = []
        for sweep in self.planes():
            arrays = work.load(self.spec.name, self.plane_key(sweep, axes), self.plane_expected())
            for name in self.variables():
                extra = (slice(None),) if name in MASS_FIELDS else ()
                yield name, (*sweep, *extra, slice(None), slice(None)), np.asarray(arrays[name]).T
            self._stats.append(plane_stats(arrays))

    def result_attrs(self, work) -> dict[str, object]:
        """Scene attributes summed over its planes (after :meth:`writes`)."""
        return result_attrs(self, self._stats)


def _empty(dof: int, n: int = 0) -> dict[str, np.ndarray]:
    return {k: np.zeros(field_shape(k, (n,), dof), dtype=dt) for k, (dt, _) in FIELDS.items()}


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


def result_attrs(plan: AdaptivePlan, stats: list[dict[str, int]]) -> dict[str, object]:
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
