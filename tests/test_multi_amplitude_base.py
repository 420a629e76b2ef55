"""The absolute amplitude under a base load whose influence u_i is neither 0 nor 1.

The simulator's coordinates z are relative to the supports, which move as u cos tau;
the absolute displacement is z_i + u_i cos tau (docs/results.md). Against independent
truths: the linear forced response in closed form (numpy's solve of the complex
dynamic stiffness, no friction), and the exact trajectory of a sliding orbit sampled
densely (tasks.trajectory: every event, states from the closed-form phases, no design
pass), its absolute displacement formed there.
"""

from __future__ import annotations

import numpy as np
import pytest

from tasks import Scene, classify
from tasks.multicontact import reference as ref
from tasks.trajectory import trajectory

_M, _K, _ = ref.random_structure(np.random.default_rng(7), 3)
_U = np.array([1.0, 0.5, -0.25])  # a translation, and two fractions (rotations, say)
_RAYLEIGH = ("rayleigh", 0.02, 0.01)


def _scene(damping=None) -> Scene:
    return Scene.from_matrices(_M, _K, ("base", _U), ("ground", 1), damping=damping)


@pytest.mark.parametrize("damping", [None, _RAYLEIGH])
def test_linear_absolute_amplitude_is_the_closed_form(damping):
    """No friction: z = (K - r^2 M + i r C)^-1 r^2 M u, absolute |z_i + u_i|, to 1e-9."""
    scene = _scene(damping)
    r = np.array([0.7, 1.6])
    res = classify(scene, r, np.zeros(2), design=True)
    C = 0.02 * _M + 0.01 * _K if damping else np.zeros_like(_M)
    for j, rj in enumerate(r):
        z = np.linalg.solve(_K - rj**2 * _M + 1j * rj * C, rj**2 * _M @ _U)
        np.testing.assert_allclose(res.amplitude_relative[j], abs(z), rtol=1e-9)
        np.testing.assert_allclose(res.amplitude[j], abs(z + _U), rtol=1e-9)


@pytest.mark.parametrize("damping", [None, _RAYLEIGH])
def test_sliding_absolute_amplitude_is_the_sampled_motion(damping):
    """With friction, on a sliding orbit: half the range of z_i + u_i cos tau over
    20,000 samples of the exact trajectory, to 1e-6 (the samples' own error, about
    (2 pi / 20000)^2 / 8 of the amplitude, is 1e-8)."""
    scene = _scene(damping)
    r, beta = 1.3, 0.05
    res = classify(scene, r, beta, design=True)
    assert res.converged and res.regime >= 1
    traj = trajectory(scene, r, beta)
    tau = np.linspace(traj.tau[0], traj.tau[-1], 20001)
    z, _ = traj.sample(tau)
    absolute = z + np.outer(np.cos(tau), _U)
    want = 0.5 * (absolute.max(axis=0) - absolute.min(axis=0))
    np.testing.assert_allclose(res.amplitude, want, rtol=1e-6)
    np.testing.assert_allclose(res.amplitude_relative, 0.5 * np.ptp(z, axis=0), rtol=1e-6)
