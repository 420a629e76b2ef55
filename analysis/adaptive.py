"""Closed-form hints for adaptive maps (:mod:`tasks.adaptive`).

The closed-form boundaries (:func:`analysis.boundaries`) say where a boundary is
expected; an adaptive map splits every cell they cross down to a few grid steps
(tasks.adaptive.HINT_CELL), so that a thin feature that follows them (a strip
at an antiresonance, a peak at a natural frequency) is not lost between coarse
nodes, and cuts a cell on the hinted grid line nearest its middle
(tasks.cells.split_at), so that a boundary where the closed forms put it is
reached in one or two cuts instead of halvings. Their prediction (the label
:func:`analysis.predict` gives every grid point) keeps a uniform cell open while
it gives a point of the cell another label than the one its corners share and
the prediction gives them too: the cell is split towards that point down to one
step, so a feature narrower than the cells (the tip of a peak of the motion
bound at a held resonance) gets a simulated point. They never decide a label:
every label of the map comes from a simulation (or is inferred from simulated
corners that agree).
"""

from __future__ import annotations

import numpy as np

from tasks.adaptive import (
    DEFAULT_COARSE_STEP,
    DEFAULT_VERIFY_FRACTION,
    DEFAULT_VERIFY_MIN,
    AdaptiveResult,
)
from tasks.adaptive import adaptive_map as _adaptive_map
from tasks.scene import Scene


def curve_hint(beta_axis: np.ndarray, curve: np.ndarray) -> np.ndarray:
    """Points of the grid ``(curve.size, beta_axis.size)`` on either side of ``beta = curve(r)``.

    Per r index, the two beta indices around the curve; between neighbouring r
    indices, the beta indices the curve sweeps (steep parts stay connected).
    Non-finite values (an infinite bound) mark nothing.
    """
    beta_axis = np.asarray(beta_axis, dtype=float)
    curve = np.asarray(curve, dtype=float)
    n_r, n_b = curve.size, beta_axis.size
    hint = np.zeros((n_r, n_b), dtype=bool)
    finite = np.isfinite(curve) & (curve >= beta_axis[0]) & (curve <= beta_axis[-1])
    j = np.searchsorted(beta_axis, np.where(finite, curve, 0.0))  # first index >= curve
    for i in np.flatnonzero(finite):
        lo, hi = max(j[i] - 1, 0), min(j[i], n_b - 1)
        if i + 1 < n_r and finite[i + 1]:  # the curve's sweep to the next column
            lo = min(lo, max(j[i + 1] - 1, 0))
            hi = max(hi, min(j[i + 1], n_b - 1))
        hint[i, lo : hi + 1] = True
    return hint


def closed_form_hint(
    scene: Scene, r: np.ndarray, beta: np.ndarray, method: str = "exact"
) -> np.ndarray:
    """Grid points next to the closed-form boundaries (both curves) of ``scene``.

    Parameters
    ----------
    scene : tasks.Scene
    r, beta : 1-D arrays
        The axes of the map.
    method : {"exact", "paper"}
        :func:`analysis.boundaries` method (docs/theory.md 4.1-4.3).

    Returns
    -------
    numpy.ndarray of bool, shape ``(r.size, beta.size)``
    """
    return closed_form_guide(scene, r, beta, method)[0]


def closed_form_guide(
    scene: Scene, r: np.ndarray, beta: np.ndarray, method: str = "exact"
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`closed_form_hint` and the closed-form prediction of every grid point.

    Returns
    -------
    hint : numpy.ndarray of bool, shape ``(r.size, beta.size)``
    predicted : numpy.ndarray of int8, shape ``(r.size, beta.size)``
        :func:`analysis.predict` of every point (the regime codes the closed forms
        give), from the same curves.
    """
    from analysis.closed_form import boundaries_along
    from tasks.regimes import CONTINUOUS, NO_MOTION, STICK_SLIP

    # the same curves the result file stores (study.netcdf): computed once per plane
    cont, motion = boundaries_along(scene, np.asarray(r, dtype=float), method=method)
    n = np.asarray(r).size
    cont = np.broadcast_to(np.asarray(cont, dtype=float), (n,))
    motion = np.broadcast_to(np.asarray(motion, dtype=float), (n,))
    hint = curve_hint(beta, cont) | curve_hint(beta, motion)
    b = np.asarray(beta, dtype=float)[None, :]
    predicted = np.where(  # as analysis.predict
        b >= motion[:, None], NO_MOTION, np.where(b < cont[:, None], CONTINUOUS, STICK_SLIP)
    )
    return hint, predicted.astype(np.int8)


def adaptive_map(
    scene: Scene,
    r: np.ndarray,
    beta: np.ndarray,
    coarse_step: int = DEFAULT_COARSE_STEP,
    hint: str | None = "exact",
    verify_fraction: float = DEFAULT_VERIFY_FRACTION,
    verify_min: int = DEFAULT_VERIFY_MIN,
    seed: int = 0,
    classify_fn=None,
    fidelity: str = "balanced",
    **settings: object,
) -> AdaptiveResult:
    """:func:`tasks.adaptive.adaptive_map` with the closed-form boundaries as refinement hints.

    ``hint`` is the :func:`analysis.boundaries` method whose curves are refined
    down to tasks.adaptive.HINT_CELL grid steps ("exact" or "paper"), and whose
    prediction keeps cells open (:func:`closed_form_guide`), or None for no hint.
    """
    mask = predicted = None
    if hint is not None:
        mask, predicted = closed_form_guide(scene, r, beta, hint)
    return _adaptive_map(
        scene,
        r,
        beta,
        coarse_step=coarse_step,
        hint=mask,
        verify_fraction=verify_fraction,
        verify_min=verify_min,
        seed=seed,
        classify_fn=classify_fn,
        fidelity=fidelity,
        predicted=predicted,
        **settings,
    )
