"""Agreement between a simulated regime map and the closed-form boundaries.

The closed forms (docs/theory.md section 4) give, at each r, two thresholds on beta:
``beta_continuous`` (continuous / stick-slip) and ``beta_motion`` (stick-slip /
no motion). :func:`regime_from_bounds` turns them into a predicted regime (the
paper's Tables 1-3); :func:`agreement` and :func:`agreement_points` compare the
prediction with a simulated map; :func:`score_dataset` does it for one scene
of a result file, for the methods "paper" and "exact".

Conventions
-----------
* Confusion matrices are indexed by :data:`REGIME_ORDER`: rows are the
  regime predicted by the closed form (theory), columns the simulated regime.
* Only *determined* simulated points (code >= 0) enter the confusion matrix.
  Undetermined points (negative codes other than ``NOT_COMPUTED``) are counted
  per reason and listed with their indices and coordinates; not-computed points
  (``NOT_COMPUTED``) are counted. Nothing is dropped silently.
* Numerical boundaries of a grid column are *brackets* ``(lower, upper]`` on
  beta, see :func:`column_boundaries`; their estimate is the bracket midpoint.

This module has no side effects on import and depends only on ``numpy`` and
``tasks.regimes`` (``analysis.closed_form`` imports :func:`regime_from_bounds`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from tasks import regimes

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

#: Order of the regimes in confusion matrices (rows: theory, columns: simulation).
REGIME_ORDER: tuple[int, ...] = tuple(sorted(regimes.REGIMES))
#: Closed-form methods scored by :func:`score_dataset`.
METHODS: tuple[str, ...] = ("paper", "exact")
#: The two boundaries, in the order (continuous / stick-slip, stick-slip / no motion).
BOUNDARIES: tuple[str, ...] = ("continuous", "motion")
#: Position of each regime along increasing beta (a column is monotone when it never decreases).
_RANK: dict[int, int] = {regimes.CONTINUOUS: 0, regimes.STICK_SLIP: 1, regimes.NO_MOTION: 2}


# --------------------------------------------------------------------------- the rule
def regime_from_bounds(
    beta: ArrayLike,
    beta_continuous: ArrayLike,
    beta_motion: ArrayLike,
) -> np.ndarray:
    """Regime predicted by the two closed-form bounds (the paper's Tables 1-3).

    Continuous for ``beta < beta_continuous``, no motion for
    ``beta >= beta_motion``, stick-slip otherwise. No motion wins where the
    bounds cross (``beta_continuous > beta_motion``). Infinite bounds are
    allowed. Where the answer depends on a NaN (``beta`` itself, or a bound
    that decides the point), there is no prediction: ``regimes.NOT_COMPUTED``.

    Parameters
    ----------
    beta, beta_continuous, beta_motion : array_like
        Broadcastable arrays.

    Returns
    -------
    numpy.ndarray
        ``int8`` regime codes (``tasks.regimes``), of the broadcast shape.
    """
    b, bc, bm = np.broadcast_arrays(
        *(np.asarray(a, dtype=float) for a in (beta, beta_continuous, beta_motion))
    )
    out = np.full(b.shape, regimes.STICK_SLIP, dtype=np.int8)
    no_motion = b >= bm
    undecided_motion = ~no_motion & np.isnan(bm)
    continuous = ~no_motion & ~undecided_motion & (b < bc)
    undecided_cont = ~no_motion & ~undecided_motion & ~continuous & np.isnan(bc)
    out[continuous] = regimes.CONTINUOUS
    out[no_motion] = regimes.NO_MOTION
    out[undecided_motion | undecided_cont | np.isnan(b)] = regimes.NOT_COMPUTED
    return out


# --------------------------------------------------------------------------- point lists
@dataclass(frozen=True, eq=False)
class PointList:
    """Points of a map, e.g. the undetermined ones: codes, indices and coordinates.

    Attributes
    ----------
    code : numpy.ndarray
        ``(n,)`` regime codes of the points.
    index : numpy.ndarray
        ``(n, len(dims))`` integer indices of the points in the scored array.
    dims : tuple of str
        Names of the index axes, e.g. ``("r", "beta")``, ``("gamma", "r", "beta")``
        or ``("point",)``.
    coords : dict of str to numpy.ndarray
        ``(n,)`` coordinates of the points (``r``, ``beta`` and any of ``gamma``, ``kappa``).
    """

    code: np.ndarray
    index: np.ndarray
    dims: tuple[str, ...]
    coords: dict[str, np.ndarray] = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.code.size)

    def counts(self) -> dict[int, int]:
        """Number of points per code, codes in decreasing order (``-1`` first)."""
        codes, counts = np.unique(self.code, return_counts=True)
        return {int(c): int(n) for c, n in sorted(zip(codes, counts, strict=True), reverse=True)}

    def rows(self) -> list[dict[str, object]]:
        """One dict per point: ``code``, ``reason``, ``index`` and the coordinates."""
        out = []
        for i in range(len(self)):
            row: dict[str, object] = {
                "code": int(self.code[i]),
                "reason": regimes.name(int(self.code[i])),
                "index": tuple(int(j) for j in self.index[i]),
            }
            row.update({k: float(v[i]) for k, v in self.coords.items()})
            out.append(row)
        return out

    @classmethod
    def empty(cls, dims: tuple[str, ...], coord_names: Sequence[str] = ()) -> PointList:
        """A list without points."""
        return cls(
            np.zeros(0, dtype=np.int16),
            np.zeros((0, len(dims)), dtype=np.int64),
            dims,
            {k: np.zeros(0) for k in coord_names},
        )

    @classmethod
    def concat(
        cls,
        parts: Sequence[PointList],
        prefixes: Sequence[tuple[int, ...]],
        prefix_dims: tuple[str, ...],
        prefix_coords: Sequence[Mapping[str, float]],
    ) -> PointList:
        """Join lists of several planes, prepending each plane's sweep index and coordinates."""
        dims = (*prefix_dims, *(parts[0].dims if parts else ()))
        names = list(prefix_dims) + [k for k in (parts[0].coords if parts else {})]
        if not parts:
            return cls.empty(dims, names)
        codes, indices, coords = [], [], {k: [] for k in names}
        for part, prefix, pc in zip(parts, prefixes, prefix_coords, strict=True):
            n = len(part)
            codes.append(part.code)
            pre = np.broadcast_to(np.asarray(prefix, dtype=np.int64), (n, len(prefix)))
            indices.append(np.concatenate([pre, part.index], axis=1))
            for k in names:
                coords[k].append(part.coords[k] if k in part.coords else np.full(n, float(pc[k])))
        return cls(
            np.concatenate(codes),
            np.concatenate(indices, axis=0),
            dims,
            {k: np.concatenate(v) for k, v in coords.items()},
        )


def _select_points(
    mask: np.ndarray,
    regime: np.ndarray,
    dims: tuple[str, ...],
    coords: Mapping[str, np.ndarray],
) -> PointList:
    """The points of ``mask`` as a :class:`PointList` (coords broadcast to ``regime``)."""
    idx = np.argwhere(mask)
    sel = tuple(idx.T)
    return PointList(
        regime[sel].astype(np.int16),
        idx.astype(np.int64),
        dims,
        {k: np.broadcast_to(v, regime.shape)[sel].astype(float) for k, v in coords.items()},
    )


# --------------------------------------------------------------------------- boundaries
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


# --------------------------------------------------------------------------- agreement
@dataclass(frozen=True, eq=False)
class Agreement:
    """Agreement of a simulated map with one closed-form method.

    Attributes
    ----------
    method : str
        ``"paper"`` or ``"exact"`` (or any label).
    kind : str
        ``"grid"``, ``"points"`` or ``"trace"`` (no regime map: only boundaries).
    confusion : numpy.ndarray
        ``(3, 3)`` counts over determined, predicted points; row = regime
        predicted by the closed form, column = simulated regime, both in
        :data:`REGIME_ORDER`.
    n_points : int
        All points of the map (for ``"trace"``: 0).
    n_not_computed : int
        Points with ``regimes.NOT_COMPUTED`` (not simulated).
    n_unpredicted : int
        Determined points without a closed-form prediction (a NaN bound decides them).
    undetermined : PointList
        Every point with an undetermined code (negative, not ``NOT_COMPUTED``).
    numerical : NumericalBoundaries or None
        Per-column numerical boundaries (grid and trace scenes).
    deviations : dict of str to BoundaryDeviation
        ``"continuous"`` and ``"motion"`` deviations (empty for point lists).
    planes : tuple of (dict, Agreement)
        For swept scenes, the agreement of every (gamma, kappa) plane with its
        sweep coordinates; this object is then their total.
    """

    method: str
    kind: str
    confusion: np.ndarray
    n_points: int
    n_not_computed: int
    n_unpredicted: int
    undetermined: PointList
    numerical: NumericalBoundaries | None = None
    deviations: dict[str, BoundaryDeviation] = field(default_factory=dict)
    planes: tuple[tuple[dict[str, float], Agreement], ...] = ()

    @property
    def n_scored(self) -> int:
        """Points in the confusion matrix."""
        return int(self.confusion.sum())

    @property
    def n_correct(self) -> int:
        """Points where theory and simulation agree."""
        return int(np.trace(self.confusion))

    @property
    def n_determined(self) -> int:
        """Points with a simulated regime (scored or unpredicted)."""
        return self.n_scored + self.n_unpredicted

    @property
    def n_undetermined(self) -> int:
        """Points with an undetermined code."""
        return len(self.undetermined)

    @property
    def undetermined_counts(self) -> dict[int, int]:
        """Undetermined points per reason code."""
        return self.undetermined.counts()

    @property
    def accuracy(self) -> float:
        """Fraction of scored points where theory and simulation agree (NaN if none)."""
        return self.n_correct / self.n_scored if self.n_scored else float("nan")

    @property
    def accuracy_by_simulated(self) -> dict[int, float]:
        """Per *simulated* regime k: the fraction of points simulated as k that theory predicts k.

        Diagonal over column sums of :attr:`confusion` (NaN for an absent regime).
        """
        return _ratios(np.diag(self.confusion), self.confusion.sum(axis=0))

    @property
    def accuracy_by_predicted(self) -> dict[int, float]:
        """Per *predicted* regime k: the fraction of points predicted as k that simulate as k.

        Diagonal over row sums of :attr:`confusion` (NaN for an absent regime).
        """
        return _ratios(np.diag(self.confusion), self.confusion.sum(axis=1))

    def count(self, predicted: int, simulated: int) -> int:
        """Entry of the confusion matrix for two regime codes."""
        return int(self.confusion[REGIME_ORDER.index(predicted), REGIME_ORDER.index(simulated)])


def _ratios(num: np.ndarray, den: np.ndarray) -> dict[int, float]:
    return {
        code: (float(n) / float(d) if d else float("nan"))
        for code, n, d in zip(REGIME_ORDER, num, den, strict=True)
    }


def _confusion(predicted: np.ndarray, simulated: np.ndarray) -> np.ndarray:
    """3x3 counts, rows ``predicted``, columns ``simulated`` (other codes ignored)."""
    out = np.zeros((len(REGIME_ORDER),) * 2, dtype=np.int64)
    for i, p in enumerate(REGIME_ORDER):
        for j, s in enumerate(REGIME_ORDER):
            out[i, j] = np.count_nonzero((predicted == p) & (simulated == s))
    return out


def _check_codes(regime: np.ndarray) -> np.ndarray:
    regime = np.asarray(regime)
    if regime.dtype.kind == "f":
        if np.any(np.isfinite(regime) & (regime != np.round(regime))):
            raise ValueError("regime codes must be integers")
        regime = np.where(np.isnan(regime), regimes.NOT_COMPUTED, regime)
    regime = regime.astype(np.int16)
    bad = regimes.is_determined(regime) & ~np.isin(regime, REGIME_ORDER)
    if bad.any():
        raise ValueError(f"unknown non-negative regime codes: {sorted(set(regime[bad].tolist()))}")
    return regime


def _score(
    method: str,
    kind: str,
    regime: np.ndarray,
    predicted: np.ndarray,
    dims: tuple[str, ...],
    coords: Mapping[str, np.ndarray],
) -> Agreement:
    """Counts shared by grid maps and point lists (``coords`` broadcast to ``regime``)."""
    determined = regimes.is_determined(regime)
    not_computed = regime == regimes.NOT_COMPUTED
    predicted_ok = predicted != regimes.NOT_COMPUTED
    return Agreement(
        method=method,
        kind=kind,
        confusion=_confusion(predicted[determined], regime[determined]),
        n_points=int(regime.size),
        n_not_computed=int(not_computed.sum()),
        n_unpredicted=int((determined & ~predicted_ok).sum()),
        undetermined=_select_points(~determined & ~not_computed, regime, dims, coords),
    )


def agreement(
    regime: ArrayLike,
    r: ArrayLike,
    beta: ArrayLike,
    beta_continuous: ArrayLike,
    beta_motion: ArrayLike,
    *,
    method: str = "",
) -> Agreement:
    """Agreement of an (r, beta) regime map with closed-form bounds.

    Parameters
    ----------
    regime : array_like
        ``(n_r, n_beta)`` simulated regime codes (float arrays with NaN for
        not-computed points, as decoded by xarray, are accepted).
    r : array_like
        ``(n_r,)`` frequency ratios.
    beta : array_like
        ``(n_beta,)`` friction ratios.
    beta_continuous, beta_motion : array_like
        ``(n_r,)`` closed-form bounds (may be infinite).
    method : str
        Label of the closed-form method.

    Returns
    -------
    Agreement
        With the confusion matrix, undetermined points (indices ``(i_r, i_beta)``),
        the per-column numerical boundaries and their deviations.
    """
    regime = _check_codes(regime)
    r = np.asarray(r, dtype=float).ravel()
    beta = np.asarray(beta, dtype=float).ravel()
    if regime.shape != (r.size, beta.size):
        raise ValueError(f"regime has shape {regime.shape}, expected {(r.size, beta.size)}")
    bc = np.asarray(beta_continuous, dtype=float).ravel()
    bm = np.asarray(beta_motion, dtype=float).ravel()
    predicted = regime_from_bounds(beta[None, :], bc[:, None], bm[:, None])
    base = _score(
        method, "grid", regime, predicted, ("r", "beta"), {"r": r[:, None], "beta": beta[None, :]}
    )
    numerical = column_boundaries(regime, r, beta)
    return _with(base, numerical=numerical, deviations=boundary_deviations(numerical, bc, bm))


def agreement_points(
    regime: ArrayLike,
    r: ArrayLike,
    beta: ArrayLike,
    beta_continuous: ArrayLike,
    beta_motion: ArrayLike,
    *,
    method: str = "",
    coords: Mapping[str, ArrayLike] | None = None,
) -> Agreement:
    """Agreement of a list of points with closed-form bounds given per point.

    Parameters
    ----------
    regime, r, beta, beta_continuous, beta_motion : array_like
        ``(n,)`` simulated codes, coordinates and closed-form bounds of each point.
    method : str
        Label of the closed-form method.
    coords : mapping, optional
        Further ``(n,)`` coordinates to list with undetermined points (gamma, kappa).

    Returns
    -------
    Agreement
        Undetermined points are indexed by ``("point",)``; no column boundaries.
    """
    regime = _check_codes(regime).ravel()
    cols = {"r": r, "beta": beta, **(coords or {})}
    cols = {k: np.asarray(v, dtype=float).ravel() for k, v in cols.items()}
    predicted = regime_from_bounds(cols["beta"], beta_continuous, beta_motion).ravel()
    if predicted.shape != regime.shape:
        raise ValueError(f"{regime.size} regimes but {predicted.size} points/bounds")
    return _score(method, "points", regime, predicted, ("point",), cols)


def agreement_trace(
    r: ArrayLike,
    beta_continuous_numerical: ArrayLike,
    beta_motion_numerical: ArrayLike,
    beta_continuous: ArrayLike,
    beta_motion: ArrayLike,
    *,
    method: str = "",
) -> Agreement:
    """Agreement of boundaries traced by simulation with the closed forms.

    There is no regime map: the confusion matrix is empty and only the
    boundary deviations are meaningful.

    Parameters
    ----------
    r : array_like
        ``(n_r,)`` frequency ratios.
    beta_continuous_numerical, beta_motion_numerical : array_like
        ``(n_r,)`` traced boundaries.
    beta_continuous, beta_motion : array_like
        ``(n_r,)`` closed-form bounds.
    method : str
        Label of the closed-form method.

    Returns
    -------
    Agreement
    """
    numerical = NumericalBoundaries.traced(r, beta_continuous_numerical, beta_motion_numerical)
    return Agreement(
        method=method,
        kind="trace",
        confusion=np.zeros((len(REGIME_ORDER),) * 2, dtype=np.int64),
        n_points=0,
        n_not_computed=0,
        n_unpredicted=0,
        undetermined=PointList.empty(("r",), ("r",)),
        numerical=numerical,
        deviations=boundary_deviations(numerical, beta_continuous, beta_motion, traced=True),
    )


def _with(a: Agreement, **changes) -> Agreement:
    from dataclasses import replace

    return replace(a, **changes)


def combine(
    planes: Sequence[Agreement],
    sweep_dims: tuple[str, ...],
    sweep_index: Sequence[tuple[int, ...]],
    sweep_coords: Sequence[Mapping[str, float]],
) -> Agreement:
    """Total agreement of the planes of a gamma/kappa sweep.

    Counts add up; undetermined points get the sweep indices prepended and the
    sweep coordinates added; numerical boundaries and deviations pool all columns.

    Parameters
    ----------
    planes : sequence of Agreement
        One per plane, same method and kind.
    sweep_dims : tuple of str
        Names of the sweep dimensions, e.g. ``("gamma", "kappa")``.
    sweep_index, sweep_coords : sequence
        Index tuple and ``{dim: value}`` of each plane.

    Returns
    -------
    Agreement
        The total, with ``planes`` holding ``(sweep_coords, plane)`` pairs.
    """
    if not planes:
        raise ValueError("no planes to combine")
    first = planes[0]
    numerical = (
        NumericalBoundaries.concat([p.numerical for p in planes])
        if all(p.numerical is not None for p in planes)
        else None
    )
    deviations = {
        k: BoundaryDeviation.concat([p.deviations[k] for p in planes]) for k in first.deviations
    }
    return Agreement(
        method=first.method,
        kind=first.kind,
        confusion=np.sum([p.confusion for p in planes], axis=0),
        n_points=sum(p.n_points for p in planes),
        n_not_computed=sum(p.n_not_computed for p in planes),
        n_unpredicted=sum(p.n_unpredicted for p in planes),
        undetermined=PointList.concat(
            [p.undetermined for p in planes], sweep_index, sweep_dims, sweep_coords
        ),
        numerical=numerical,
        deviations=deviations,
        planes=tuple((dict(c), p) for c, p in zip(sweep_coords, planes, strict=True)),
    )


# --------------------------------------------------------------------------- datasets
def scene_kind(ds: xr.Dataset) -> str:
    """``"trace"``, ``"points"`` or ``"grid"``: the layout of one scene's Dataset."""
    if ds.attrs.get("mode") == "trace" or "beta_continuous_numerical" in ds.data_vars:
        return "trace"
    if "point" in ds.dims:
        return "points"
    return "grid"


def is_adaptive(ds: xr.Dataset) -> bool:
    """An adaptive map (``mode = "adaptive"``): a grid whose points are simulated or
    inferred (variable ``simulated``)."""
    return ds.attrs.get("mode") == "adaptive" or "simulated" in ds.data_vars


def simulated_only(ds: xr.Dataset) -> xr.Dataset:
    """An adaptive map with every inferred point's ``regime`` set to ``not_computed``, so
    that scores count simulated points only (inferred points copy a simulated corner:
    scoring them would count those corners again; the verification sample measures them)."""
    regime = ds["regime"].where(ds["simulated"].astype(bool), regimes.NOT_COMPUTED)
    return ds.assign(regime=regime.astype(ds["regime"].dtype))


def sweep_dims(ds: xr.Dataset) -> tuple[str, ...]:
    """The swept ratios of a scene (dimensions among gamma, kappa), in file order."""
    return tuple(d for d in ds.dims if d in ("gamma", "kappa"))


def available_methods(ds: xr.Dataset, methods: Sequence[str] = METHODS) -> tuple[str, ...]:
    """Methods whose two closed-form bound variables are in ``ds``."""
    return tuple(
        m
        for m in methods
        if f"beta_continuous_{m}" in ds.variables and f"beta_motion_{m}" in ds.variables
    )


def regime_codes(da: xr.DataArray) -> np.ndarray:
    """Integer codes of a ``regime`` variable (fill values decoded to NaN become NOT_COMPUTED)."""
    return _check_codes(np.asarray(da.values))


def _score_plane(plane: xr.Dataset, kind: str, method: str) -> Agreement:
    r = plane["r"].values
    if kind == "trace":
        return agreement_trace(
            r,
            plane["beta_continuous_numerical"].transpose("r").values,
            plane["beta_motion_numerical"].transpose("r").values,
            plane[f"beta_continuous_{method}"].transpose("r").values,
            plane[f"beta_motion_{method}"].transpose("r").values,
            method=method,
        )
    regime = regime_codes(plane["regime"].transpose("r", "beta"))
    bc = plane[f"beta_continuous_{method}"].transpose("r").values
    bm = plane[f"beta_motion_{method}"].transpose("r").values
    return agreement(regime, r, plane["beta"].values, bc, bm, method=method)


def _score_points(ds: xr.Dataset, method: str) -> Agreement:
    extra = {k: ds[k].values for k in ("gamma", "kappa") if k in ds.coords}
    return agreement_points(
        regime_codes(ds["regime"]),
        ds["r"].values,
        ds["beta"].values,
        ds[f"beta_continuous_{method}"].values,
        ds[f"beta_motion_{method}"].values,
        method=method,
        coords=extra,
    )


def score_method(ds: xr.Dataset, method: str) -> Agreement:
    """Agreement of one scene's Dataset with one closed-form method (see :func:`score_dataset`)."""
    kind = scene_kind(ds)
    if kind == "points":
        return _score_points(ds, method)
    sweeps = sweep_dims(ds)
    if not sweeps:
        return _score_plane(ds, kind, method)
    shape = tuple(ds.sizes[d] for d in sweeps)
    parts, index, coords = [], [], []
    for idx in np.ndindex(*shape):
        sel = dict(zip(sweeps, idx, strict=True))
        parts.append(_score_plane(ds.isel(sel), kind, method))
        index.append(idx)
        coords.append({d: float(ds[d].values[i]) for d, i in sel.items()})
    return combine(parts, sweeps, index, coords)


def score_dataset(ds: xr.Dataset, methods: Sequence[str] = METHODS) -> dict[str, Agreement]:
    """Agreement of one scene of a result file with each closed-form method.

    Parameters
    ----------
    ds : xarray.Dataset
        One scene (the schema of ``study.netcdf``): a grid over (r, beta) with
        optional leading gamma/kappa sweeps, a point list (dim ``point``) or a
        traced scene (``mode = "trace"``).
    methods : sequence of str
        Methods to score; those without ``beta_continuous_<m>`` and
        ``beta_motion_<m>`` in ``ds`` are left out.

    Returns
    -------
    dict of str to Agreement
        One per method. For sweeps, the total over all planes, with each
        plane's agreement in ``Agreement.planes``.
    """
    return {m: score_method(ds, m) for m in available_methods(ds, methods)}
