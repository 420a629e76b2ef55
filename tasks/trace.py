"""Boundary tracing: the numerical regime boundaries along r, by bisection in beta.

A regime map spends most of its points far from the boundaries it is about.
For each r, :func:`trace_boundaries` instead finds

* ``beta_continuous``: the continuous / stick-slip boundary (continuous below),
* ``beta_motion``: the stick-slip / no-motion boundary (no motion at and above),

by bracketing around a starting estimate (the closed forms, supplied by the
caller) and bisecting to a requested tolerance. Every step classifies one beta
per r for all r at once (:func:`tasks.classify` is vectorised), so the cost is
``O(log(range / tol))`` simulations per r instead of ``range / tol``.

Bisection assumes the regime does not increase with beta (continuous, then
stick-slip, then no motion). Every column is also probed on a coarse uniform
scan; a column whose probes contradict that order is *non-monotone* and gets a
dense column scan instead, and its boundaries are the first transitions from
the bottom (continuous) and from the top (no motion).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tasks import regimes
from tasks.classifier import classify
from tasks.scene import Scene


@dataclass
class TraceResult:
    """Numerical boundaries along r (arrays shaped like ``r``).

    ``beta_continuous`` / ``beta_motion`` are the midpoints of the final
    brackets ``[lower, upper]`` (also returned: a bracket wider than the
    tolerance means bisection stopped at an undetermined point), NaN where no
    bracket exists (the scan found no determined point on one side); a
    boundary outside ``beta_range`` is reported as the range end it lies
    beyond, with ``*_open`` set.
    ``monotone`` is False where the column needed a scan; ``points`` counts the
    simulations spent per r.
    """

    r: np.ndarray
    beta_continuous: np.ndarray
    beta_motion: np.ndarray
    continuous_bracket: np.ndarray  # (n_r, 2)
    motion_bracket: np.ndarray  # (n_r, 2)
    continuous_open: np.ndarray
    motion_open: np.ndarray
    monotone: np.ndarray
    points: np.ndarray


def _bisect(
    scene: Scene,
    r: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    below: callable,
    tol: float,
    atol: float,
    count: np.ndarray,
    classify_kw: dict,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Shrink brackets ``[lo, hi]`` (``below(regime)`` true at lo, false at hi) to tol.

    An undetermined probe (slow transients right at a boundary) is retried a
    tenth of the bracket above; if that fails too the column stops there with
    its current, wider bracket (``failed``). Returns (lo, hi, failed).
    """
    lo = lo.copy()
    hi = hi.copy()
    failed = np.zeros(r.shape, bool)
    for _ in range(200):
        width = hi - lo
        active = ~failed & (width > np.maximum(tol * np.abs(hi), atol))
        if not active.any():
            break
        idx = np.flatnonzero(active)
        mid = 0.5 * (lo[idx] + hi[idx])
        reg = classify(scene, r[idx], mid, **classify_kw).regime
        count[idx] += 1
        bad = reg < 0
        if bad.any():  # nudge undetermined probes by a tenth of the bracket
            mid2 = mid[bad] + 0.1 * (hi[idx][bad] - lo[idx][bad])
            reg2 = classify(scene, r[idx][bad], mid2, **classify_kw).regime
            count[idx[bad]] += 1
            mid[bad] = mid2
            reg[bad] = reg2
        still = reg < 0
        failed[idx[still]] = True
        ok = ~still
        go_up = np.zeros(idx.shape, bool)
        go_up[ok] = below(reg[ok])
        lo[idx[ok & go_up]] = mid[ok & go_up]
        hi[idx[ok & ~go_up]] = mid[ok & ~go_up]
    return lo, hi, failed


def trace_boundaries(
    scene: Scene,
    r: np.ndarray,
    beta_range: tuple[float, float] = (0.0, 2.0),
    guess_continuous: np.ndarray | None = None,
    guess_motion: np.ndarray | None = None,
    rtol: float = 1e-3,
    atol: float = 1e-6,
    scan_points: int = 9,
    dense_points: int = 200,
    guess_width: float = 0.02,
    fidelity: str = "balanced",
    **settings: object,
) -> TraceResult:
    """Numerical continuous / stick-slip and stick-slip / no-motion boundaries along r.

    Parameters
    ----------
    scene : Scene
    r : array_like
        Frequency ratios (1-D).
    beta_range : (float, float)
        Search interval of beta; boundaries beyond it are reported open.
    guess_continuous, guess_motion : array_like, optional
        Starting estimates per r (e.g. ``analysis.boundaries(scene, r, "exact")``);
        brackets are grown geometrically around them. Default: a coarse scan.
    rtol, atol : float
        Bisection stops when a bracket is narrower than ``max(rtol * beta, atol)``.
    scan_points : int
        Uniform probes per column for the monotonicity check (and brackets).
    dense_points : int
        Column scan of a non-monotone column.
    guess_width : float
        Relative distance of the two probes around each guess.
    fidelity, **settings
        Passed to :func:`tasks.classify` (here with ``warm=True`` and
        ``design=False`` unless given: only the regimes are used).
    """
    r = np.atleast_1d(np.asarray(r, dtype=float))
    lo_range, hi_range = float(beta_range[0]), float(beta_range[1])
    if not (0.0 <= lo_range < hi_range and np.isfinite(hi_range)):
        raise ValueError(f"beta_range: must satisfy 0 <= min < max < inf, got {beta_range!r}")
    # only the labels are used: warm starts along the columns, no design pass
    kw = {"fidelity": fidelity, "warm": True, "design": False, **settings}
    n = r.size
    count = np.zeros(n, dtype=np.int64)
    # coarse scan: brackets and the monotonicity check
    scan = np.linspace(lo_range, hi_range, scan_points)
    R, B = np.meshgrid(r, scan, indexing="ij")
    reg = classify(scene, R, B, **kw).regime
    count += scan_points
    determined = reg >= 0
    monotone = np.ones(n, bool)
    for i in range(n):
        seq = reg[i][determined[i]]
        monotone[i] = bool(np.all(np.diff(seq) <= 0))

    def brackets(guess, is_below):
        """[lo, hi] per column from the scan, tightened around the guess if given."""
        lo = np.full(n, np.nan)
        hi = np.full(n, np.nan)
        for i in range(n):
            ok = determined[i]
            below = ok & is_below(reg[i])
            above = ok & ~is_below(reg[i])
            if not above.any():
                lo[i], hi[i] = hi_range, np.inf  # boundary beyond the range
                continue
            if not below.any():
                lo[i], hi[i] = -np.inf, lo_range
                continue
            j_hi = np.flatnonzero(above)[0]
            j_lo = np.flatnonzero(below[:j_hi])[-1] if below[:j_hi].any() else None
            if j_lo is None:
                lo[i], hi[i] = -np.inf, scan[j_hi]
                continue
            lo[i], hi[i] = scan[j_lo], scan[j_hi]
        if guess is not None:
            # probe 2 % either side of the guess: when it is close (the closed
            # forms usually are), bisection starts from a bracket of 4 %
            g = np.asarray(guess, dtype=float)
            for probe in (g * (1.0 - guess_width), g * (1.0 + guess_width)):
                inside = np.isfinite(lo) & np.isfinite(hi) & (probe > lo) & (probe < hi)
                if not inside.any():
                    continue
                idx = np.flatnonzero(inside)
                rg = classify(scene, r[idx], probe[idx], **kw).regime
                count[idx] += 1
                okg = rg >= 0
                up = okg & is_below(rg)
                lo[idx[up]] = probe[idx[up]]
                hi[idx[okg & ~up]] = probe[idx[okg & ~up]]
        return lo, hi

    out = {}
    for name, guess, is_below in (
        ("continuous", guess_continuous, lambda x: x == regimes.CONTINUOUS),
        ("motion", guess_motion, lambda x: x != regimes.NO_MOTION),
    ):
        lo, hi = brackets(guess, is_below)
        closed = np.isfinite(lo) & np.isfinite(hi) & monotone
        lo_b, hi_b, failed = lo.copy(), hi.copy(), np.zeros(n, bool)
        if closed.any():
            idx = np.flatnonzero(closed)
            sub = np.zeros(idx.size, np.int64)
            lo_b[idx], hi_b[idx], failed[idx] = _bisect(
                scene, r[idx], lo[idx], hi[idx], is_below, rtol, atol, sub, kw
            )
            count[idx] += sub
        out[name] = (lo_b, hi_b, failed)

    # non-monotone columns: dense scan, first transitions from bottom and top
    for i in np.flatnonzero(~monotone):
        col = np.linspace(lo_range, hi_range, dense_points)
        rc = classify(scene, np.full(dense_points, r[i]), col, **kw).regime
        count[i] += dense_points
        ok = rc >= 0
        for name, is_below in (
            ("continuous", lambda x: x == regimes.CONTINUOUS),
            ("motion", lambda x: x != regimes.NO_MOTION),
        ):
            lo_b, hi_b, failed = out[name]
            below = ok & is_below(rc)
            above = ok & ~is_below(rc)
            if name == "continuous":
                first_above = np.flatnonzero(above)
                if first_above.size == 0:
                    lo_b[i], hi_b[i] = hi_range, np.inf
                else:
                    j = first_above[0]
                    lo_b[i] = col[j - 1] if j > 0 else -np.inf
                    hi_b[i] = col[j]
            else:
                last_below = np.flatnonzero(below)
                if last_below.size == 0:
                    lo_b[i], hi_b[i] = -np.inf, lo_range
                else:
                    j = last_below[-1]
                    lo_b[i] = col[j]
                    hi_b[i] = col[j + 1] if j + 1 < dense_points else np.inf

    def finish(lo_b, hi_b, failed):
        open_ = ~np.isfinite(lo_b) | ~np.isfinite(hi_b)
        value = 0.5 * (lo_b + hi_b)
        value = np.where(np.isposinf(hi_b), hi_range, value)
        value = np.where(np.isneginf(lo_b), lo_range, value)
        value = np.where(np.isnan(lo_b) | np.isnan(hi_b), np.nan, value)
        return value, np.stack([lo_b, hi_b], axis=-1), open_

    bc, bc_br, bc_open = finish(*out["continuous"])
    bm, bm_br, bm_open = finish(*out["motion"])
    return TraceResult(
        r=r,
        beta_continuous=bc,
        beta_motion=bm,
        continuous_bracket=bc_br,
        motion_bracket=bm_br,
        continuous_open=bc_open,
        motion_open=bm_open,
        monotone=monotone,
        points=count,
    )
