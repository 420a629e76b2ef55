"""Figures and report tables a referee accepts: titles, axis names, marks, grid steps, gaps."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from analysis import figures
from analysis.design import characteristic_r, map_dataset, optimal_beta
from analysis.deviations import BoundaryDeviation
from analysis.report import _max_rel, percent
from analysis.scoring import score_dataset
from tasks import Scene


def scene_map(scene: Scene, r: np.ndarray, beta: np.ndarray) -> xr.Dataset:
    """A labelled in-memory map with the closed-form bounds and the scene attributes."""
    return map_dataset(scene, r, beta, design=True)  # the response figures need them


@pytest.fixture(scope="module")
def fig04_panel() -> xr.Dataset:
    """Fig. 4, gamma = 1, kappa = 0.5, coarse."""
    return scene_map(
        Scene("ground", 2, 1, gamma=1.0, kappa=0.5),
        np.linspace(0.05, 2.5, 50),
        np.linspace(0.0, 1.5, 21),
    )


def test_percent_never_rounds_a_miss_to_100():
    assert percent(24994, 24995) == "99.996 %"
    assert percent(7, 8) == "87.50 %"
    assert percent(5, 5) == "100.00 %" and percent(0, 5) == "0.00 %"
    assert percent(1, 3 * 10**9) != "0.00 %" and percent(3 * 10**9 - 1, 3 * 10**9) != "100.00 %"
    assert percent(0, 0) == "n/a"


def test_map_title_axis_names_and_marked_frequencies(fig04_panel):
    fig = figures.regime_map_figure(fig04_panel)
    title = fig._suptitle.get_text()
    for part in ("2DOF", "ground-fixed wall on $m_{1}$", r"$\gamma$ = 1", r"$\kappa$ = 0.5"):
        assert part in title, title
    assert "m_1" not in title.replace("$m_{1}$", "")  # no literal m_1: mathtext
    (ax,) = fig.axes
    assert ax.get_xlabel() == "$r_1$" and ax.get_ylabel() == r"$\beta$"
    # resonances of the frictionless chain: det(K - r^2 M) = 0, K = [[1.5, -0.5], [-0.5, 0.5]]
    lam = np.linalg.eigvals(np.array([[1.5, -0.5], [-0.5, 0.5]]))
    expected = sorted([*np.sqrt(lam), np.sqrt(0.5 / 1.0)])  # + antiresonance sqrt(kappa/gamma)
    vertical = sorted(
        line.get_xdata()[0]
        for line in ax.get_lines()
        if len(set(line.get_xdata())) == 1 and len(line.get_xdata()) == 2
    )
    np.testing.assert_allclose(vertical, expected, rtol=1e-9)
    assert ax.get_legend() is None and fig.legends  # the legend is outside the axes


def test_deviation_in_grid_steps_with_gaps(fig04_panel):
    step = 1.5 / 20
    ds = fig04_panel.copy(deep=True)
    ds["beta_continuous_exact"][10] = np.inf  # a column that cannot be compared
    scores = score_dataset(ds)
    fig = figures.deviation_figure(scores, step=step)
    top = fig.axes[0]
    dev = scores["exact"].deviations["continuous"]
    (line,) = [ln for ln in top.get_lines() if ln.get_color() == "#1f77b4"]
    y = np.asarray(line.get_ydata(), dtype=float)
    assert np.isnan(y[10]) and np.isfinite(y[9]) and np.isfinite(y[11])  # a gap, no line across
    # in grid steps; a column whose bracket holds the closed form agrees: drawn at 0
    inside = dev.consistent & np.isfinite(dev.deviation)
    assert inside.sum() > 10
    np.testing.assert_allclose(y, np.where(inside, 0.0, dev.deviation / step))
    assert np.all(np.abs(y[np.isfinite(y) & ~inside]) >= 0.5 - 1e-9)  # outside: half a step+
    assert all(ax.get_legend() is None for ax in fig.axes) and fig.legends


def test_a_closed_form_on_a_grid_node_is_drawn_as_agreement(fig04_panel):
    """beta = 0, 0.1, ..., 1.5 holds the motion bound 1 of a ground contact on m_1 as a
    node: the bracket (0.9, 1] contains it, its midpoint is half a step below; drawn at 0."""
    ds = scene_map(
        Scene("ground", 2, 1, gamma=1.0, kappa=0.5),
        np.linspace(0.05, 2.5, 12),
        np.linspace(0.0, 1.5, 16),
    )
    scores = score_dataset(ds)
    dev = scores["exact"].deviations["motion"]
    on_node = np.isclose(dev.closed_form, 1.0) & dev.consistent
    assert on_node.sum() >= 6
    np.testing.assert_allclose(dev.deviation[on_node] / 0.1, -0.5)  # the midpoint
    bottom = figures.deviation_figure(scores, step=0.1).axes[1]
    (line,) = [ln for ln in bottom.get_lines() if ln.get_color() == "#1f77b4"]
    np.testing.assert_allclose(np.asarray(line.get_ydata(), dtype=float)[on_node], 0.0)


def test_relative_deviation_only_where_the_closed_form_is_clear_of_zero():
    step = 0.015
    d = BoundaryDeviation(
        "continuous", np.array([0.1, 1.0]), np.array([0.0075, 0.51]), np.array([0.0001, 0.5])
    )
    assert d.max_rel > 70  # what the old table printed
    assert _max_rel(d, step) == "0.02"  # only the column clear of zero counts


def test_optimal_beta_and_response_figure():
    scene = Scene("ground", 1)
    r = np.array([0.5, 1.5, 2.0])
    beta = np.linspace(0.0, 1.5, 16)
    ds = scene_map(scene, r, beta)
    best = optimal_beta(ds, mass=1)
    # a ground wall holds the mass from the motion bound beta = 1 on (docs/theory.md 4.2):
    # the smallest amplitude (zero) is first reached there
    np.testing.assert_allclose(best["beta_optimal"].values, 1.0)
    np.testing.assert_allclose(best["amplitude_minimum"].values, 0.0, atol=1e-12)
    fig = figures.response_figure(ds, mass=1, n_beta=4)
    top, bottom = fig.axes
    assert bottom.get_xlabel() == "$r_1$"
    assert "SDOF" in fig._suptitle.get_text()
    # a held mass (amplitude 0) has no point on the log axis (no line at a floor value) ...
    held = beta >= 1.0
    for line in top.get_lines():
        y = np.asarray(line.get_ydata(), dtype=float)
        if y.size == r.size and line.get_label().startswith(r"$\beta$ = "):
            b = float(line.get_label().split("= ")[1])
            assert np.all(np.isnan(y)) == (b >= 1.0), (b, y)
    assert held.any() and any("is 0" in str(p.get_label()) for p in top.patches)
    # ... and where the smallest amplitude is 0 the "optimum" is only the motion bound:
    # not drawn, and the figure says why
    (opt,) = [ln for ln in bottom.get_lines() if ln.get_marker() == "."]
    assert np.all(np.isnan(np.asarray(opt.get_ydata(), dtype=float)))
    assert any("no optimal" in t.get_text() for t in bottom.texts)


def test_response_figure_draws_the_optimum_where_the_mass_moves():
    """A contact between masses: the mass keeps moving when the contact is stuck, so the
    smallest amplitude is positive and the optimal beta is drawn."""
    scene = Scene("mass", 2, 1, gamma=1.0, kappa=1.0)
    r = np.array([0.4, 1.4])
    ds = scene_map(scene, r, np.linspace(0.0, 1.5, 7))
    best = optimal_beta(ds, mass=1)
    assert np.all(best["amplitude_minimum"].values > 1e-3)
    (opt,) = [
        ln for ln in figures.response_figure(ds).axes[1].get_lines() if ln.get_marker() == "."
    ]
    np.testing.assert_allclose(opt.get_ydata(), best["beta_optimal"].values)


def test_characteristic_r_of_fig17_and_base_contacts():
    res, anti = characteristic_r(Scene("base", 2, 1, gamma=1.0, kappa=1.0), 3.0)
    np.testing.assert_allclose(anti, [np.sqrt(2.0)])  # docs/theory.md 5: sqrt(kappa(1+g)/g)
    np.testing.assert_allclose(res, [(np.sqrt(5) - 1) / 2, (np.sqrt(5) + 1) / 2])
