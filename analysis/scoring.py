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
  beta (:mod:`analysis.deviations`, re-exported here); their estimate is the
  bracket midpoint.

This module has no side effects on import and depends only on ``numpy`` and
``tasks.regimes`` (``analysis.closed_form`` imports :func:`regime_from_bounds`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from analysis.deviations import (
    BoundaryDeviation,
    NumericalBoundaries,
    boundary_deviations,
    column_boundaries,
)
from tasks import regimes

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

#: Order of the regimes in confusion matrices (rows: theory, columns: simulation).
REGIME_ORDER: tuple[int, ...] = tuple(sorted(regimes.REGIMES))
#: Closed-form methods scored by :func:`score_dataset`.
METHODS: tuple[str, ...] = ("paper", "exact")


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
