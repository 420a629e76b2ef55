"""Viscous damping: closed forms (analysis.damped) against independent truths.

Truths: the undamped closed forms of docs/theory.md 4 (zero damping), Den
Hartog's single-mass solution in closed form (docs/structures.md 3.3), and the
scipy event-driven integrator with damping (tasks.baseline), which shares no
code with the closed forms (damped transients decay, so 60-80 cycles from rest
reach the steady state).
"""

from __future__ import annotations

import numpy as np
import pytest

from analysis import closed_form, damped
from tasks import Scene, regimes
from tasks.baseline import paper_method
from tasks.scene import CONFIGURATIONS

R = np.array([0.4, 0.7, 1.3, 2.5])


def _sdof(zeta: float, base: bool = False) -> Scene:
    load = ("base", [1.0]) if base else [1.0]
    return Scene.from_matrices([[1.0]], [[1.0]], load, ("ground", 0), damping=("modal", zeta))


def _spd(n: int, rng: np.random.Generator, cond: float = 10.0) -> np.ndarray:
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return Q @ np.diag(np.exp(rng.uniform(0.0, np.log(cond), n))) @ Q.T


@pytest.mark.parametrize("name", list(CONFIGURATIONS))
def test_zero_damping_gives_the_undamped_closed_forms(name):
    """The state-space half-period solution (Eq. 3.6) with C = 0 is docs/theory.md 4.3."""
    scene = Scene.from_matrices(**CONFIGURATIONS[name].matrices())
    for method in ("paper", "exact"):
        np.testing.assert_allclose(
            damped.continuous_bound(scene, R, method),
            closed_form.continuous_bound(scene, R, method),
            rtol=1e-11,
        )
    np.testing.assert_allclose(
        damped.motion_bound(scene, R), closed_form.motion_bound(scene, R), rtol=1e-12
    )


@pytest.mark.parametrize("zeta", [0.02, 0.1, 0.4])
@pytest.mark.parametrize("r", [0.4, 1.0, 2.5])
def test_general_solution_is_den_hartogs_for_one_mass(zeta, r):
    t = damped.half_period_terms(_sdof(zeta), r)
    D, u, c = damped.den_hartog_sdof_terms(r, zeta)
    assert t["Zb"] == pytest.approx(D, rel=1e-12)
    assert abs(t["u"]) == pytest.approx(abs(u), rel=1e-10)
    assert t["c_b"] == pytest.approx(c, rel=1e-10, abs=1e-12)


def test_damping_lowers_the_resonant_peak_and_keeps_the_single_mass_motion_bound():
    """At r = 1 the undamped continuous bound is Den Hartog's pi/4 limit; with damping
    the bound exists at every r, and for one mass on a ground wall the held contact
    carries the whole load: beta_motion = 1 for any damping."""
    for zeta in (0.05, 0.2):
        np.testing.assert_allclose(damped.motion_bound(_sdof(zeta), R), 1.0, rtol=1e-14)
    assert closed_form.continuous_bound(_sdof(0.05), [1.0])[0] < np.pi / 4
    # base load: the held mass carries r^2 cos(tau)
    np.testing.assert_allclose(damped.motion_bound(_sdof(0.1, base=True), R), R**2, rtol=1e-14)


@pytest.mark.parametrize("r", [0.5, 0.9, 1.6, 3.0])
def test_damped_single_mass_against_scipy(r):
    """Regimes on both sides of both boundaries and Den Hartog's amplitude (1e-5)."""
    zeta = 0.1
    scene = _sdof(zeta)
    bc = closed_form.continuous_bound(scene, [r], "exact")[0]
    bm = closed_form.motion_bound(scene, [r])[0]
    assert bc < bm
    cases = [
        (0.5 * bc, regimes.CONTINUOUS),
        (0.98 * bc, regimes.CONTINUOUS),
        (1.02 * bc, regimes.STICK_SLIP),
        (0.98 * bm, regimes.STICK_SLIP),
        (1.02 * bm, regimes.NO_MOTION),
    ]
    for beta, expected in cases:
        code, info = paper_method(scene, r, beta, cycles=60)
        assert code == expected, (r, beta)
        if code == regimes.CONTINUOUS:
            amp = damped.den_hartog_amplitude(r, beta, zeta)
            assert info["amplitude"] == pytest.approx(amp, rel=1e-5)
            assert damped.continuous_amplitude(scene, r, beta) == pytest.approx(amp, rel=1e-10)


@pytest.mark.parametrize("seed", [1, 2])
def test_damped_structures_closed_forms_against_scipy(seed):
    """Random full M, K (3 DOFs), Rayleigh / modal / full C, wall or between contact:
    the damped closed forms predict the scipy integrator at 0.8 x and 1.2 x the bounds."""
    rng = np.random.default_rng(seed)
    checked = 0
    for kind in range(3):
        n = 3
        M, K = _spd(n, rng), _spd(n, rng)
        damping = [("rayleigh", 0.05, 0.02), ("modal", 0.05), 0.1 * _spd(n, rng)][kind]
        contact = ("ground", int(rng.integers(n))) if kind != 1 else ("between", 0, 2)
        scene = Scene.from_matrices(M, K, rng.standard_normal(n), contact, damping=damping)
        for r in rng.uniform(0.3, 3.0, 2):
            bc, bm = closed_form.boundaries(scene, [r], "exact")
            points = [(0.8 * bc[0], regimes.CONTINUOUS), (1.2 * bm[0], regimes.NO_MOTION)]
            if 1.2 * bc[0] < 0.9 * bm[0]:
                points.append((1.2 * bc[0], regimes.STICK_SLIP))
            for beta, expected in points:
                code, _ = paper_method(scene, r, beta, cycles=80)
                assert code == expected, (kind, r, beta)
                checked += 1
    assert checked >= 12
