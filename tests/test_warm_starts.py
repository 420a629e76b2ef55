"""Warm starts along a map (tasks.kernel.batch.run_points_seeded) change the cost, never
the labels, and the other fields only far below the steady-state tolerance.

Every periodic steady state of a point has the same regime, stops and stick
fraction (docs/theory.md 3, "One regime per point"), so a point seeded by its
neighbour's orbit must reach the regime the held start reaches. Whole panels
are classified cold (``warm=False``: every point from the held start) and warm
(the default), in grid order, shuffled and cut into other chunks; moving orbits
are polished to the fixed point of their map, so the fields agree to 1e-9
whatever the grouping, and a recomputed call is identical to the bit.
"""

from __future__ import annotations

import numpy as np
import pytest

from tasks import Scene, classify, regimes
from tasks.fidelity import resolve
from tasks.result import DESIGN_FIELDS, FIELDS
from tasks.seeds import warm_seeds

#: (scene, beta_max, n_r, n_beta), r in [0.02, 2.5]: Fig. 4 (gamma = 1, kappa = 0.5;
#: beta = 1, its motion bound at large r, is a grid row), Fig. 10b (5DOF, contact
#: on m_2) and two scenes beyond the paper.
PANELS = {
    "fig04_gamma1_kappa0.5": (Scene("ground", 2, 1, gamma=1.0, kappa=0.5), 1.5, 100, 34),
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
    warm = classify(scene, r, beta, warm=True, design=False)
    assert (cold.regime >= 0).mean() > 0.99  # a determined panel
    assert set(np.unique(cold.regime)) >= {regimes.STICK_SLIP, regimes.CONTINUOUS}
    np.testing.assert_array_equal(warm.regime, cold.regime)
    np.testing.assert_array_equal(warm.converged, cold.converged)
    np.testing.assert_array_equal(warm.stops_per_cycle, cold.stops_per_cycle)
    np.testing.assert_array_equal(warm.period, cold.period)
    np.testing.assert_array_equal(warm.asymptotic, cold.asymptotic)
    # the cold fields hold to section_rtol (slow points: a few 1e-6 in the stick
    # fraction), the warm ones are polished to the fixed point (exact's values)
    np.testing.assert_allclose(warm.stick_fraction, cold.stick_fraction, rtol=0, atol=1e-5)
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
    grid = classify(scene, r, beta, warm=True, design=False)
    order = np.random.default_rng(19).permutation(r.size)
    shuffled = classify(scene, r[order], beta[order], warm=True, design=False)
    reverse = classify(scene, r[::-1], beta[::-1], warm=True, design=False)
    for other, index in ((shuffled, order), (reverse, np.arange(r.size)[::-1])):
        np.testing.assert_array_equal(other.regime, grid.regime[index])
        np.testing.assert_array_equal(other.stops_per_cycle, grid.stops_per_cycle[index])
        np.testing.assert_allclose(other.stick_fraction, grid.stick_fraction[index], atol=1e-6)


def test_other_starts_are_never_warm():
    """``starts`` compares starts: only the held start is seeded."""
    scene, r, beta = _panel("fig04_gamma1_kappa0.5")
    r, beta = r[::5, ::4], beta[::5, ::4]
    both = classify(scene, r, beta, starts=("held", "rest"), warm=True, design=False)
    rest = classify(scene, r, beta, initial_condition="rest", warm=False, design=False)
    np.testing.assert_array_equal(both.regime_rest, rest.regime)
    assert not both.start_dependent.any()


def test_design_quantities_only_when_asked():
    scene = PANELS["base_3dof_m2"][0]
    r_axis, beta_axis = np.linspace(0.3, 2.5, 12), np.linspace(0.0, 2.0, 6)
    r, beta = np.meshgrid(r_axis, beta_axis, indexing="ij")
    assert resolve("balanced").design is False  # off unless asked for
    full = classify(scene, r, beta, design=True)
    bare = classify(scene, r, beta)  # the default
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


#: Fields that may differ between groupings only by the polish's residual: every
#: field but ``cycles`` (the periods the search took, which depend on its seed).
CONTINUOUS_FIELDS = ("slip_amplitude", "stick_fraction", *DESIGN_FIELDS)


def _fields_agree(a, b, rtol):
    """Labels equal point for point, every other field (but cycles) to ``rtol`` of
    its largest magnitude on the panel, NaN at the same points."""
    for name in FIELDS:
        if name == "cycles":
            continue
        x, y = np.asarray(getattr(a, name)), np.asarray(getattr(b, name))
        if name not in CONTINUOUS_FIELDS:
            np.testing.assert_array_equal(x, y, err_msg=name)
            continue
        np.testing.assert_array_equal(np.isfinite(x), np.isfinite(y), err_msg=name)
        fin = np.isfinite(x)
        scale = max(np.abs(x[fin]).max(), 1e-300) if fin.any() else 1.0
        np.testing.assert_allclose(x[fin], y[fin], rtol=0, atol=rtol * scale, err_msg=name)


def test_default_is_warm_and_warm_off_is_settable():
    assert resolve("balanced").warm is True
    assert resolve("fast", warm=False).warm is False
    with pytest.raises(ValueError, match="warm: must be true or false"):
        resolve("balanced", warm="no")


def test_seeds_are_earlier_close_points_nearest_first():
    r = np.array([1.0, 1.0, 1.0, 1.02, 0.2, 1.0])
    beta = np.array([0.5, 0.56, 0.0, 0.5, 0.5, 0.51])
    seeds = warm_seeds(r, beta, lambda_max=2.6)
    assert (seeds[0] == -1).all()  # nothing before it
    assert seeds[1, 0] == 0 and (seeds[1, 1:] == -1).all()
    assert (seeds[2] == -1).all()  # beta = 0: linear, never seeded nor a seed
    assert list(seeds[3, :2]) == [0, 1]  # both close (0.2 and 0.57); the nearer first
    assert (seeds[4] == -1).all()  # r far away: the fastest mode's phase moves too much
    assert list(seeds[5, :3]) == [0, 3, 1]  # never point 2 (beta = 0) nor 4 (far)
    assert (warm_seeds(r[:4], beta[:4], lambda_max=200.0)[3] == -1).all()  # faster mode


def test_fields_do_not_depend_on_the_grouping_of_the_points():
    """Two groupings of one panel (the grid in one call; the shuffled points in three
    calls) agree to 1e-9 in every field but cycles, with the design quantities; a
    call repeated gives the same result to the bit (a chunk recomputed on resume)."""
    scene = Scene("base", 3, 2, gamma=0.8, kappa=1.3)
    r, beta = np.meshgrid(np.linspace(0.3, 2.5, 40), np.linspace(0.0, 2.0, 10), indexing="ij")
    r, beta = r.ravel(), beta.ravel()
    whole = classify(scene, r, beta, design=True)
    assert set(np.unique(whole.regime)) >= {regimes.STICK_SLIP, regimes.CONTINUOUS}
    order = np.random.default_rng(3).permutation(r.size)
    parts = [classify(scene, r[p], beta[p], design=True) for p in np.array_split(order, 3)]
    regrouped = whole.reshape((-1,)).as_dict()
    joined = {k: np.concatenate([np.asarray(getattr(p, k)) for p in parts]) for k in regrouped}
    back = np.argsort(order)
    other = type(whole)(**{k: v[back] for k, v in joined.items()})
    assert not np.array_equal(other.cycles, whole.cycles)  # other seeds were used
    _fields_agree(whole, other, 1e-9)
    again = classify(scene, r, beta, design=True)
    for name, value in whole.as_dict().items():
        np.testing.assert_array_equal(getattr(again, name), value, err_msg=name)


STUDY = """[study]
name = "{name}"
fidelity = "fast"
{settings}
[[scene]]
name = "grid"
contact = "ground"
dof = 2
contact_mass = 1
gamma = 1.0
kappa = 0.5
r = {{start = 0.2, stop = 2.5, num = 24}}
beta = {{start = 0.0, stop = 1.5, num = 12}}

[[scene]]
name = "adaptive"
contact = "base"
dof = 2
contact_mass = 2
mode = "adaptive"
coarse_step = 4
verify_fraction = 0.1
r = {{start = 0.1, stop = 2.5, num = 33}}
beta = {{start = 0.0, stop = 1.5, num = 17}}
"""


def test_study_labels_equal_with_warm_starts_on_and_off(tmp_path, monkeypatch):
    """Through the CLI (small studies run in this process): the default (warm starts)
    and ``warm = false`` give the same labels, simulated points included."""
    import xarray as xr

    from study.cli import main

    monkeypatch.chdir(tmp_path)
    for name, settings in (("on", ""), ("off", "\n[settings]\nwarm = false\n")):
        (tmp_path / f"{name}.toml").write_text(STUDY.format(name=name, settings=settings))
        assert main(["run", f"{name}.toml", "-o", f"{name}.nc", "--quiet"]) == 0
    with xr.open_datatree(tmp_path / "on.nc") as on, xr.open_datatree(tmp_path / "off.nc") as off:
        for scene in ("grid", "adaptive"):
            a, b = on[scene].to_dataset().load(), off[scene].to_dataset().load()
            assert set(a.data_vars) == set(b.data_vars), scene
            for label in ("regime", "stops_per_cycle", "period", "converged", "asymptotic"):
                np.testing.assert_array_equal(a[label], b[label], err_msg=f"{scene} {label}")
            moving = (a["regime"] > regimes.NO_MOTION).values
            np.testing.assert_allclose(
                a["slip_amplitude"].values[moving], b["slip_amplitude"].values[moving], rtol=1e-3
            )
            assert len(np.unique(a["regime"])) >= 2, scene
        np.testing.assert_array_equal(on["adaptive"]["simulated"], off["adaptive"]["simulated"])
        assert on["grid"].attrs["settings"] != off["grid"].attrs["settings"]
