"""Numerical boundaries of a simulated map and their deviation from the closed forms.

A simulated column (one r, increasing beta) gives each boundary as a *bracket*
``(lower, upper]`` on beta (:func:`column_boundaries`); its estimate is the
bracket midpoint. :func:`boundary_deviations` measures how far the closed forms
(docs/theory.md section 4) lie from those brackets, in grid steps: a closed form
inside its bracket is an agreement (deviation 0). Used by
:mod:`analysis.scoring` and :mod:`analysis.figures`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from tasks import regimes

#: The two boundaries, in the order (continuous / stick-slip, stick-slip / no motion).
BOUNDARIES: tuple[str, ...] = ("continuous", "motion")
#: Position of each regime along increasing beta (a column is monotone when it never decreases).
_RANK: dict[int, int] = {regimes.CONTINUOUS: 0, regimes.STICK_SLIP: 1, regimes.NO_MOTION: 2}


@dataclass(frozen=True, eq=False)
class NumericalBoundaries:
    """Boundaries read from simulated columns (one per r), as brackets on beta.

    Attributes
    ----------
    r : numpy.ndarray
        ``(n,)`` frequency ratio of each column.
    continuous_bracket, motion_bracket : numpy.ndarray
        ``(n, 2)`` brackets ``(lower, upper]`` of the continuous / stick-slip and
        the stick-slip / no-motion boundary; ``-inf`` / ``inf`` when the
        transition lies below / above the simulated betas; NaN for a column
        without determined points. Traced boundaries have ``lower == upper``.
    non_monotone : numpy.ndarray
        ``(n,)`` True where the determined regimes of the column do not follow
        continuous -> stick-slip -> no motion with increasing beta.
    n_skipped : numpy.ndarray
        ``(n,)`` points of the column without a regime (undetermined or not computed).
    skipped_in_bracket : numpy.ndarray
        ``(n, 2)`` True where such a point lies strictly inside the bracket of
        the (continuous, motion) boundary, so the bracket was widened over it.
    """

    r: np.ndarray
    continuous_bracket: np.ndarray
    motion_bracket: np.ndarray
    non_monotone: np.ndarray
    n_skipped: np.ndarray
    skipped_in_bracket: np.ndarray

    @property
    def continuous(self) -> np.ndarray:
        """Estimate of the continuous / stick-slip boundary: bracket midpoint (NaN if open)."""
        return _midpoint(self.continuous_bracket)

    @property
    def motion(self) -> np.ndarray:
        """Estimate of the stick-slip / no-motion boundary: bracket midpoint (NaN if open)."""
        return _midpoint(self.motion_bracket)

    def bracket(self, boundary: str) -> np.ndarray:
        """The bracket of ``"continuous"`` or ``"motion"``."""
        return {"continuous": self.continuous_bracket, "motion": self.motion_bracket}[boundary]

    @classmethod
    def traced(cls, r: ArrayLike, continuous: ArrayLike, motion: ArrayLike) -> NumericalBoundaries:
        """Boundaries traced by simulation (``beta_*_numerical``): degenerate brackets."""
        r = np.asarray(r, dtype=float).ravel()
        cont = np.asarray(continuous, dtype=float).ravel()
        mot = np.asarray(motion, dtype=float).ravel()
        n = r.size
        return cls(
            r,
            np.stack([cont, cont], axis=1),
            np.stack([mot, mot], axis=1),
            np.zeros(n, dtype=bool),
            np.zeros(n, dtype=np.int64),
            np.zeros((n, 2), dtype=bool),
        )

    @classmethod
    def concat(cls, parts: Sequence[NumericalBoundaries]) -> NumericalBoundaries:
        """Columns of several planes one after the other (r repeats)."""
        names = (
            "r",
            "continuous_bracket",
            "motion_bracket",
            "non_monotone",
            "n_skipped",
            "skipped_in_bracket",
        )
        return cls(*(np.concatenate([getattr(p, k) for p in parts], axis=0) for k in names))


def _midpoint(bracket: np.ndarray) -> np.ndarray:
    lo, hi = bracket[:, 0], bracket[:, 1]
    ok = np.isfinite(lo) & np.isfinite(hi)
    return np.where(ok, 0.5 * (np.where(ok, lo, 0.0) + np.where(ok, hi, 0.0)), np.nan)


def _bracket(beta: np.ndarray, below: int) -> tuple[float, float]:
    """Bracket between determined points ``below - 1`` and ``below`` of a column."""
    lo = beta[below - 1] if below > 0 else -np.inf
    hi = beta[below] if below < beta.size else np.inf
    return float(lo), float(hi)


def _column(codes: np.ndarray, beta: np.ndarray) -> tuple[tuple[float, float], ...]:
    """Brackets (continuous, motion) of one column sorted by beta (determined points only)."""
    if codes.size == 0:
        return (np.nan, np.nan), (np.nan, np.nan)
    not_continuous = np.flatnonzero(codes != regimes.CONTINUOUS)
    k = int(not_continuous[0]) if not_continuous.size else codes.size
    moving = np.flatnonzero(codes != regimes.NO_MOTION)
    t = int(moving[-1]) + 1 if moving.size else 0
    return _bracket(beta, k), _bracket(beta, t)


def column_boundaries(regime: ArrayLike, r: ArrayLike, beta: ArrayLike) -> NumericalBoundaries:
    """Numerical boundaries of each r column of a simulated map.

    In each column, only determined points count; order them by beta.

    * Continuous / stick-slip: the *bottom run* is the longest run of continuous
      points starting at the smallest beta. The bracket is (last beta of the
      bottom run, next determined beta]. No continuous point at the bottom gives
      ``(-inf, first beta]``; an all-continuous column ``(last beta, inf)``.
    * Stick-slip / no motion: the *top run* is the longest run of no-motion
      points ending at the largest beta. The bracket is (last moving beta,
      first beta of the top run]. A column moving at its top gives
      ``(last beta, inf)``; an all-no-motion column ``(-inf, first beta]``.

    A column whose determined regimes are not ordered continuous -> stick-slip ->
    no motion is flagged ``non_monotone`` (its brackets are still those above).
    Undetermined or not-computed points are skipped and counted; a bracket that
    spans one of them is flagged in ``skipped_in_bracket``.

    Parameters
    ----------
    regime : array_like
        ``(n_r, n_beta)`` regime codes.
    r : array_like
        ``(n_r,)`` frequency ratios.
    beta : array_like
        ``(n_beta,)`` friction ratios (any order).

    Returns
    -------
    NumericalBoundaries
    """
    regime = np.asarray(regime)
    beta = np.asarray(beta, dtype=float)
    order = np.argsort(beta, kind="stable")
    beta, regime = beta[order], regime[:, order]
    n_r = regime.shape[0]
    brackets = np.full((n_r, 2, 2), np.nan)
    non_monotone = np.zeros(n_r, dtype=bool)
    skipped_in = np.zeros((n_r, 2), dtype=bool)
    det = regimes.is_determined(regime)
    for i in range(n_r):
        codes, b = regime[i, det[i]], beta[det[i]]
        brackets[i] = _column(codes, b)
        rank = np.array([_RANK[int(c)] for c in codes], dtype=int)
        non_monotone[i] = bool(np.any(np.diff(rank) < 0))
        skipped = beta[~det[i]]
        for j in range(2):
            lo, hi = brackets[i, j]
            skipped_in[i, j] = bool(np.any((skipped > lo) & (skipped < hi)))
    return NumericalBoundaries(
        np.asarray(r, dtype=float).ravel(),
        brackets[:, 0],
        brackets[:, 1],
        non_monotone,
        (~det).sum(axis=1).astype(np.int64),
        skipped_in,
    )


@dataclass(frozen=True, eq=False)
class BoundaryDeviation:
    """Deviation of a numerical boundary from a closed-form one, column by column.

    ``deviation = numerical - closed_form`` where both are finite (NaN
    elsewhere); relative deviation ``|deviation| / |closed_form|`` where the
    closed form is also non-zero. Statistics run over the finite values only;
    ``n_compared`` says how many.

    Attributes
    ----------
    boundary : str
        ``"continuous"`` or ``"motion"``.
    r, numerical, closed_form : numpy.ndarray
        ``(n,)`` per column (r may repeat when planes of a sweep are pooled).
    bracket : numpy.ndarray or None
        ``(n, 2)`` bracket of the numerical boundary (grid maps), None if traced.
    """

    boundary: str
    r: np.ndarray
    numerical: np.ndarray
    closed_form: np.ndarray
    bracket: np.ndarray | None = None

    @property
    def deviation(self) -> np.ndarray:
        """``numerical - closed_form`` where both are finite, else NaN."""
        ok = np.isfinite(self.numerical) & np.isfinite(self.closed_form)
        return np.where(ok, self.numerical - np.where(ok, self.closed_form, 0.0), np.nan)

    @property
    def relative(self) -> np.ndarray:
        """``|deviation| / |closed_form|`` (NaN where undefined)."""
        cf = np.abs(self.closed_form)
        ok = np.isfinite(self.deviation) & (cf > 0)
        return np.where(ok, np.abs(self.deviation) / np.where(ok, cf, 1.0), np.nan)

    @property
    def n_columns(self) -> int:
        """Number of columns."""
        return int(self.r.size)

    @property
    def n_compared(self) -> int:
        """Columns with a finite deviation."""
        return int(np.isfinite(self.deviation).sum())

    @property
    def n_consistent(self) -> int | None:
        """Columns whose bracket ``(lower, upper]`` contains the closed form (None if traced).

        Infinite closed forms count: ``inf`` is consistent with ``(b, inf)``.
        """
        inside = self.consistent
        return None if inside is None else int(inside.sum())

    @property
    def consistent(self) -> np.ndarray | None:
        """Per column: the bracket ``(lower, upper]`` contains the closed form (None if
        traced). Such a column agrees with the closed form as far as the grid can tell,
        wherever in the bracket the closed form lies (a closed form on a grid node sits
        at the upper end, half a step from the midpoint)."""
        if self.bracket is None:
            return None
        lo, hi = self.bracket[:, 0], self.bracket[:, 1]
        cf = self.closed_form
        return (lo < cf) & (cf <= hi)

    def _stat(self, values: np.ndarray, how) -> float:
        v = values[np.isfinite(values)]
        return float(how(v)) if v.size else float("nan")

    @property
    def max_abs(self) -> float:
        """Largest absolute deviation (NaN if nothing compared)."""
        return self._stat(np.abs(self.deviation), np.max)

    @property
    def median_abs(self) -> float:
        """Median absolute deviation (NaN if nothing compared)."""
        return self._stat(np.abs(self.deviation), np.median)

    @property
    def max_rel(self) -> float:
        """Largest relative deviation (NaN if nothing compared)."""
        return self._stat(self.relative, np.max)

    @property
    def median_rel(self) -> float:
        """Median relative deviation (NaN if nothing compared)."""
        return self._stat(self.relative, np.median)

    @classmethod
    def concat(cls, parts: Sequence[BoundaryDeviation]) -> BoundaryDeviation:
        """Pool the columns of several planes."""
        cat = lambda k: np.concatenate([getattr(p, k) for p in parts], axis=0)  # noqa: E731
        bracket = None if any(p.bracket is None for p in parts) else cat("bracket")
        return cls(parts[0].boundary, cat("r"), cat("numerical"), cat("closed_form"), bracket)


def boundary_deviations(
    numerical: NumericalBoundaries,
    beta_continuous: ArrayLike,
    beta_motion: ArrayLike,
    traced: bool = False,
) -> dict[str, BoundaryDeviation]:
    """Deviation of both numerical boundaries from the closed forms.

    Parameters
    ----------
    numerical : NumericalBoundaries
        Per-column boundaries (:func:`column_boundaries` or ``NumericalBoundaries.traced``).
    beta_continuous, beta_motion : array_like
        ``(n,)`` closed-form bounds at ``numerical.r``.
    traced : bool
        The numerical boundaries were traced (no brackets to check).

    Returns
    -------
    dict of str to BoundaryDeviation
        Keys ``"continuous"`` and ``"motion"``.
    """
    closed = {"continuous": beta_continuous, "motion": beta_motion}
    est = {"continuous": numerical.continuous_bracket, "motion": numerical.motion_bracket}
    out = {}
    for name in BOUNDARIES:
        values = est[name][:, 0] if traced else _midpoint(est[name])
        out[name] = BoundaryDeviation(
            name,
            numerical.r,
            values,
            np.asarray(closed[name], dtype=float).ravel(),
            None if traced else est[name],
        )
    return out
