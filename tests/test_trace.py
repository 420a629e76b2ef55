"""Boundary tracing: numerical boundaries by bisection against the exact closed forms.

The continuous / stick-slip boundary of docs/theory.md 4.3 ("exact") and the motion
bound (Eqs. 13, 63) are derived without simulation; the traced boundaries are
found by simulation only. Agreement to the bisection tolerance checks both.
"""

from __future__ import annotations

import numpy as np
import pytest

from analysis import boundaries
from tasks import Scene
from tasks.trace import trace_boundaries

RTOL = 1e-3


@pytest.mark.parametrize(
    ("scene", "r"),
    [
        (Scene("ground", 1), np.array([0.45, 0.8, 1.4, 2.3])),
        (Scene("ground", 2, 2, gamma=1.0, kappa=1.0), np.array([0.3, 0.9, 1.3, 2.2])),
        (Scene("base", 2, 1, gamma=1.0, kappa=1.0), np.array([0.5, 1.2, 1.8])),
        (Scene("mass", 2, 1, gamma=1.0, kappa=1.0), np.array([0.9, 1.5, 2.4])),
    ],
    ids=lambda v: v.label if isinstance(v, Scene) else "",
)
def test_traced_boundaries_match_exact_closed_forms(scene, r):
    bc, bm = boundaries(scene, r, method="exact")
    top = float(np.max(np.where(np.isfinite(bm), bm, bc)) * 1.3)
    tr = trace_boundaries(scene, r, (0.0, top), rtol=RTOL)  # no guesses: found by simulation
    assert tr.monotone.all()
    for num, exact, bracket in (
        (tr.beta_continuous, bc, tr.continuous_bracket),
        (tr.beta_motion, bm, tr.motion_bracket),
    ):
        width = bracket[:, 1] - bracket[:, 0]
        assert np.all(width <= 2 * RTOL * np.abs(bracket[:, 1]) + 1e-6)
        # the closed form lies in (or within a tolerance of) the simulated bracket
        assert np.all(np.abs(num - exact) <= width + RTOL * exact), (num, exact)


def test_guesses_save_work():
    scene = Scene("ground", 2, 1)
    r = np.linspace(0.3, 2.4, 8)
    bc, bm = boundaries(scene, r, method="exact")
    blind = trace_boundaries(scene, r, (0.0, 1.5), rtol=RTOL)
    guided = trace_boundaries(scene, r, (0.0, 1.5), bc, bm, rtol=RTOL)
    np.testing.assert_allclose(guided.beta_continuous, blind.beta_continuous, rtol=3 * RTOL)
    assert guided.points.sum() < blind.points.sum()
    # a dense column resolving the same tolerance needs range / (tol * beta) points
    assert blind.points.max() < 0.1 * 1.5 / (RTOL * 0.2)


def test_antiresonance_column_is_monotone_once_creep_is_no_motion():
    """At the antiresonance (ground, m_1, gamma = kappa = 1, r = 1) the contact is
    held at small beta; the "stick-slip" found near beta = 1 had slips of 1e-9 of
    the static deflection, below the creep threshold (tasks.regimes.SLIP_RTOL): it
    is no motion, and the column is monotone (no motion from beta = 0)."""
    from tasks import classify, regimes

    scene = Scene("ground", 2, 1)
    beta = np.linspace(0.74, 0.99, 6)
    res = classify(scene, 1.0, beta)
    assert np.all(res.regime == regimes.NO_MOTION)
    assert np.all(res.slip_amplitude < regimes.SLIP_RTOL * beta)  # c = 1 here
    tr = trace_boundaries(scene, np.array([1.0, 1.5]), (0.0, 1.5), dense_points=60)
    assert list(tr.monotone) == [True, True]


def test_range_validation():
    with pytest.raises(ValueError, match="^beta_range"):
        trace_boundaries(Scene("ground", 1), [1.0], (1.0, 0.5))
