"""Amplitudes of sliding orbits (tasks.kernel.extrema) against the exact trajectory.

The truth is independent of the design pass: the recorded exact trajectory
(``tasks.trajectory``, closed form between events) sampled densely, events
included, and its largest and smallest value refined by a root search on its
exact velocity (scipy's brentq) where the velocity changes sign next to the
best sample. The design pass must match it to 1e-10 of each coordinate's scale
(the cubic Hermite search refined only at its best point, before, erred by up
to 1e-8) and never exceed it (its values are values of the motion).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from tasks import Scene, classify, regimes, trajectory

POINTS = [  # (scene, r, beta): sliding orbits, undamped, every contact
    (Scene("ground", 1), 0.5, 0.3),
    (Scene("ground", 2, 1, gamma=1.0, kappa=0.5), 0.2, 0.65),
    (Scene("ground", 2, 1, gamma=1.0, kappa=0.5), 1.3, 0.2),
    (Scene("ground", 2, 1), 1.6, 0.3),
    (Scene("base", 2, 2), 0.9, 0.3),
    (Scene("base", 3, 2), 1.4, 0.6),
    (Scene("mass", 2, 1), 0.6, 0.15),
    (Scene("ground", 5, 2), 1.3, 0.56),
    (Scene("ground", 5, 4), 0.45, 0.3),
]


def _extreme(traj, column, sign: float, tau: np.ndarray, y: np.ndarray) -> float:
    """The largest of ``sign * y`` on the trajectory (``y = column(x)`` sampled at ``tau``)."""
    k = int(np.argmax(sign * y))
    best = float(sign * y[k])

    def velocity(t: float) -> float:
        x, xd = traj.sample(np.array([t]))
        return float(column(x, xd, np.array([t]), 1)[0])

    for a, b in ((k - 1, k), (k, k + 1)):
        if 0 <= a and b < tau.size:
            va, vb = velocity(tau[a]), velocity(tau[b])
            if va * vb < 0.0:
                root = brentq(velocity, tau[a], tau[b], xtol=1e-15, rtol=1e-15)
                x, xd = traj.sample(np.array([root]))
                best = max(best, float(sign * column(x, xd, np.array([root]), 0)[0]))
    return best


@pytest.mark.parametrize(("scene", "r", "beta"), POINTS)
def test_amplitudes_equal_the_exact_trajectorys(scene, r, beta):
    res = classify(scene, np.array([r]), np.array([beta]), design=True)
    assert res.regime[0] in (regimes.CONTINUOUS, regimes.STICK_SLIP)
    traj = trajectory(scene, r, beta)
    period = int(res.period[0])
    grid = np.linspace(traj.tau[0], traj.tau[-1], 4000 * period + 1)
    tau = np.unique(np.concatenate((grid, traj.tau)))
    x, xd = traj.sample(tau)
    c = -1.0 if scene.contact == "base" else 1.0  # the other frame: q - c cos tau
    for i in range(scene.dof):
        for frame, shift in ((0, 0.0), (1, c)):

            def column(x, xd, t, order, i=i, shift=shift):
                if order == 0:
                    return x[:, i] - shift * np.cos(t)
                return xd[:, i] + shift * np.sin(t)

            y = column(x, xd, tau, 0)
            hi = _extreme(traj, column, 1.0, tau, y)
            lo = -_extreme(traj, column, -1.0, tau, y)
            truth = 0.5 * (hi - lo)
            own, other = res.amplitude[0], res.amplitude_relative[0]
            if scene.contact == "base":  # the kernel's own coordinate is z = x - y
                own, other = other, own
            value = (own if frame == 0 else other)[i]
            scale = max(abs(hi), abs(lo))
            assert abs(value - truth) <= 1e-10 * scale, (i, frame, value, truth)
            assert value <= truth + 1e-13 * scale
