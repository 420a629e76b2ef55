"""Warm starts along a map (tasks.kernel.point.run_points) change the cost, never the labels.

Every periodic steady state of a point has the same regime, stops and stick
fraction (docs/theory.md 3, "One regime per point"), so a point seeded by its
neighbour's orbit must reach the regime the held start reaches. Whole panels
are classified cold (``warm=False``: every point from the held start, the
path before warm starts existed) and warm, in grid order and shuffled.
"""

from __future__ import annotations

import numpy as np
import pytest

from tasks import Scene, classify, regimes
from tasks.result import DESIGN_FIELDS, FIELDS

#: (scene, r range, beta range, n_r, n_beta): Fig. 4 (gamma = 1, kappa = 0.5),
#: Fig. 10b (5DOF, contact on m_2) and two scenes beyond the paper.
PANELS = {
    "fig04_gamma1_kappa0.5": (Scene("ground", 2, 1, gamma=1.0, kappa=0.5), 1.5, 100, 50),
    "fig10b": (Scene("ground", 5, 2), 2.0, 100, 12),
    "base_3dof_m2": (Scene("base", 3, 2, gamma=0.8, kappa=1.3), 2.0, 100, 12),
    "mass_3dof_m2": (Scene("mass", 3, 2, gamma=1.2, kappa=0.7), 2.0, 100, 12),
}


def _panel(name):
    scene, beta_max, n_r, n_beta = PANELS[name]
    r, beta = np.meshgrid(np.linspace(0.02, 2.5, n_r), np.linspace(0.0, beta_max, n_beta))
    return scene, r, beta


@pytest.mark.parametrize("name", list(PANELS))
def test_warm_and_cold_panels_have_the_same_labels(name):
    scene, r, beta = _panel(name)
    cold = classify(scene, r, beta, warm=False, design=False)
    warm = classify(scene, r, beta, design=False)
    assert (cold.regime >= 0).mean() > 0.99  # a determined panel
    assert set(np.unique(cold.regime)) >= {regimes.STICK_SLIP, regimes.CONTINUOUS}
    np.testing.assert_array_equal(warm.regime, cold.regime)
    np.testing.assert_array_equal(warm.converged, cold.converged)
    np.testing.assert_array_equal(warm.stops_per_cycle, cold.stops_per_cycle)
    np.testing.assert_array_equal(warm.period, cold.period)
    np.testing.assert_allclose(warm.stick_fraction, cold.stick_fraction, rtol=0, atol=1e-6)
    moving = cold.regime > regimes.NO_MOTION
    np.testing.assert_allclose(warm.slip_amplitude[moving], cold.slip_amplitude[moving], rtol=1e-4)
    # the held start stays the reference of the steady state
    np.testing.assert_array_equal(warm.initial_condition, cold.initial_condition)
    # the warm starts were used: some points settled in fewer periods
    assert np.sum(warm.cycles < cold.cycles) > 0.05 * moving.sum()
    if name.startswith("fig04"):  # in all, about a quarter fewer periods on this panel
        assert np.sum(warm.cycles[moving]) < 0.85 * np.sum(cold.cycles[moving])


def test_labels_do_not_depend_on_the_order_of_the_points():
    scene, r, beta = _panel("fig04_gamma1_kappa0.5")
    r, beta = r.ravel(), beta.ravel()
    grid = classify(scene, r, beta, design=False)
    order = np.random.default_rng(19).permutation(r.size)
    shuffled = classify(scene, r[order], beta[order], design=False)
    reverse = classify(scene, r[::-1], beta[::-1], design=False)
    for other, index in ((shuffled, order), (reverse, np.arange(r.size)[::-1])):
        np.testing.assert_array_equal(other.regime, grid.regime[index])
        np.testing.assert_array_equal(other.stops_per_cycle, grid.stops_per_cycle[index])
        np.testing.assert_allclose(other.stick_fraction, grid.stick_fraction[index], atol=1e-6)


def test_other_starts_are_never_warm():
    """``starts`` compares starts: only the held start is seeded."""
    scene, r, beta = _panel("fig04_gamma1_kappa0.5")
    r, beta = r[::5, ::4], beta[::5, ::4]
    both = classify(scene, r, beta, starts=("held", "rest"), design=False)
    rest = classify(scene, r, beta, initial_condition="rest", warm=False, design=False)
    np.testing.assert_array_equal(both.regime_rest, rest.regime)
    assert not both.start_dependent.any()


def test_design_quantities_only_when_asked():
    scene = PANELS["base_3dof_m2"][0]
    r_axis, beta_axis = np.linspace(0.3, 2.5, 12), np.linspace(0.0, 2.0, 6)
    r, beta = np.meshgrid(r_axis, beta_axis, indexing="ij")
    full = classify(scene, r, beta)
    bare = classify(scene, r, beta, design=False)
    for name in DESIGN_FIELDS:
        assert getattr(bare, name) is None  # not computed: absent, never NaN posing as values
        assert name not in bare.as_dict()
        assert getattr(full, name) is not None
    assert np.isfinite(full.contact_force_amplitude[full.regime >= 0]).all()
    for name, value in bare.as_dict().items():
        np.testing.assert_array_equal(value, getattr(full, name), err_msg=name)
    assert set(full.as_dict()) == set(FIELDS)
    assert set(bare.reshape((-1,)).as_dict()) == set(FIELDS) - set(DESIGN_FIELDS)
    ds = bare.to_dataset(r_axis, beta_axis, scene)
    assert set(ds.data_vars) == set(FIELDS) - set(DESIGN_FIELDS)
    np.testing.assert_array_equal(ds.regime.values, bare.regime.T)
