"""The viscous part of the dissipation (``dissipation_viscous``) against independent truths.

Truths: the energy balance over a converged period (work of the load = friction
+ viscous dissipation), with the load's work and the viscous power integrated by
Simpson's rule on a fine exact sampling of the orbit (code independent of the
design pass's Gauss-Legendre quadrature in the sliding modes), and, without
friction, the harmonic response ``(K - r^2 M + i r C) X = p`` solved by numpy
(dissipation ``pi r X^H C X`` per cycle).
"""

from __future__ import annotations

import numpy as np
import pytest

from analysis import closed_form
from tasks import Scene, classify, regimes, trajectory
from tasks.scene import CONFIGURATIONS
from tasks.structures import beam


def _rayleigh(name: str, a: float, b: float) -> Scene:
    return Scene.from_matrices(**{**CONFIGURATIONS[name].matrices(), "damping": ("rayleigh", a, b)})


def _simpson(tau: np.ndarray, f: np.ndarray) -> float:
    w = np.ones(tau.size)
    w[1:-1:2], w[2:-1:2] = 4.0, 2.0
    return float((tau[1] - tau[0]) / 3.0 * np.sum(w * f))


SCENES = {
    "rayleigh_2dof": lambda: _rayleigh("2dof_ground_m1", 0.1, 0.02),
    "rayleigh_base": lambda: _rayleigh("2dof_base_m1", 0.2, 0.02),
    "beam": lambda: beam(n_elements=6, modes=3, damping=("rayleigh", 0.05, 0.002)),
    "general": lambda: _general(),
}


def _general() -> Scene:
    """Full M, K and a non-proportional C (docs/structures.md 4.5)."""
    M = np.array([[2.0, 0.4, 0.1], [0.4, 1.5, 0.3], [0.1, 0.3, 1.0]])
    K = np.array([[3.0, -1.0, 0.2], [-1.0, 2.5, -0.8], [0.2, -0.8, 1.8]])
    C = np.array([[0.3, 0.1, 0.0], [0.1, 0.05, 0.0], [0.0, 0.0, 0.02]])
    return Scene.from_matrices(M, K, [1.0, 0.5, 0.0], ("ground", 2), damping=C)


@pytest.mark.parametrize("name", list(SCENES))
@pytest.mark.parametrize(("r", "where"), [(0.8, 0.5), (1.3, 0.5), (2.2, -0.5)])
def test_energy_balance_per_period(name, r, where):
    """Work of the load per cycle = ``dissipation`` + ``dissipation_viscous`` (rtol 1e-6),
    and ``dissipation_viscous`` equals the viscous power integrated independently."""
    scene = SCENES[name]()
    C, p = scene.damping_matrix(r), scene.load_vector(r)
    bc, bm = (float(v[0]) for v in closed_form.boundaries(scene, [r], "exact"))
    beta = bc + where * (bm - bc) if where > 0 else -where * bc
    tr = trajectory(scene, r, beta)
    res = tr.result
    assert res is not None and res.converged and res.regime != regimes.NO_MOTION
    period = int(res.period)
    tau = tr.tau[0] + np.linspace(0.0, 2 * np.pi * period, 40000 * period + 1)
    x, xd = tr.sample(tau)
    w_load = _simpson(tau, (xd @ p) * np.cos(tau)) / period
    w_visc = _simpson(tau, np.einsum("ti,ij,tj->t", xd, C, xd)) / period
    assert res.dissipation > 0.0 and res.dissipation_viscous > 0.0
    assert float(res.dissipation_viscous) == pytest.approx(w_visc, rel=1e-6)
    assert float(res.dissipation + res.dissipation_viscous) == pytest.approx(w_load, rel=1e-6)


@pytest.mark.parametrize("name", list(SCENES))
def test_viscous_dissipation_without_friction_is_the_harmonic_one(name):
    scene = SCENES[name]()
    M, K = scene.mass_matrix(1.0), scene.stiffness_matrix()
    for r in (0.5, 1.0, 1.7):
        C = scene.damping_matrix(r)  # r C of Eq. 1.1
        X = np.linalg.solve(K - r * r * M + 1j * C, scene.load_vector(r))
        expected = np.pi * float(np.real(X.conj() @ C @ X))
        res = classify(scene, r, 0.0, design=True)
        assert float(res.dissipation_viscous) == pytest.approx(expected, rel=1e-10)
        # and the amplitudes of the same harmonic response
        b = scene.contact_vector()
        assert float(res.slip_amplitude) == pytest.approx(abs(b @ X), rel=1e-10)
        own = res.amplitude_relative if scene.load_scales_r2 else res.amplitude
        np.testing.assert_allclose(own, np.abs(X), rtol=1e-10)


def test_undamped_scenes_report_zero_viscous_dissipation():
    scene = CONFIGURATIONS["2dof_ground_m1"]
    res = classify(scene, np.array([0.7, 1.3, 0.7]), np.array([0.3, 0.3, 0.0]), design=True)
    assert np.all(res.dissipation_viscous == 0.0)
    assert np.all(res.dissipation[:2] > 0.0)
