"""Design quantities of the converged orbit against independent truths.

- Den Hartog's exact amplitude of continuous SDOF motion, X = sqrt(V^2 - beta^2 U^2)
  (docs/theory.md 4.3), for ground- and base-fixed walls;
- the energy balance of a periodic orbit: the energy the contact dissipates per
  cycle equals the work the excitation does, integrated here by quadrature of
  the exact trajectory (``tasks.trajectory``), not from the slip distance;
- amplitudes of every mass against a dense sampling of that trajectory;
- the force a contact stuck for ever transmits: the motion bound of the held
  system (docs/theory.md 4.2), the amplitude of the load on the held contact.

They are computed only when asked for (``design=True``; None by default).
"""

from __future__ import annotations

import numpy as np
import pytest

from analysis import boundaries
from tasks import Scene, classify, regimes, trajectory


def den_hartog(r: np.ndarray, beta: np.ndarray, load: np.ndarray) -> np.ndarray:
    """X = sqrt(V^2 - beta^2 U^2), V = load / (1 - r^2), U = tan(pi / (2 r)) / r."""
    v = load / (1.0 - r**2)
    u = np.tan(np.pi / (2.0 * r)) / r
    return np.sqrt(v**2 - beta**2 * u**2)


@pytest.mark.parametrize("contact", ["ground", "base"])
def test_sdof_amplitude_is_den_hartogs(contact):
    scene = Scene(contact, dof=1)
    r = np.array([0.3, 0.55, 0.8, 0.95, 1.2, 1.7, 2.5, 3.5])
    bc, _ = boundaries(scene, r, method="exact")
    beta = 0.6 * bc
    res = classify(scene, r, beta, design=True)
    assert (res.regime == regimes.CONTINUOUS).all(), res.regime
    load = r**2 if contact == "base" else np.ones_like(r)  # base: z = x - y is loaded by r^2
    expected = den_hartog(r, beta, load)
    frame = res.amplitude_relative if contact == "base" else res.amplitude
    np.testing.assert_allclose(frame[:, 0], expected, rtol=1e-6)
    np.testing.assert_allclose(res.contact_force_amplitude, beta, rtol=0, atol=0)


POINTS = [  # (scene, r, beta): continuous and stick-slip, every contact
    (Scene("ground", 1), 0.5, 0.3),
    (Scene("ground", 2, 1), 0.7, 0.2),
    (Scene("ground", 2, 1), 1.6, 0.3),
    (Scene("ground", 2, 2, gamma=0.5, kappa=2.0), 1.1, 0.4),
    (Scene("base", 2, 2), 0.9, 0.3),
    (Scene("base", 2, 1, gamma=0.7, kappa=1.5), 1.8, 1.0),
    (Scene("mass", 2, 1), 0.6, 0.15),
    (Scene("mass", 3, 2), 1.3, 0.2),
]


def _work_of_excitation(scene: Scene, r: float, traj, period: int) -> float:
    """Work of the harmonic load p cos(tau) per cycle: integral of cos(tau) p . x'."""
    tau = np.linspace(traj.tau[0], traj.tau[-1], 40001 * period)
    _, xd = traj.sample(tau)
    power = np.cos(tau) * (xd @ scene.load_vector(r))
    return float(np.trapezoid(power, tau)) / period


@pytest.mark.parametrize(("scene", "r", "beta"), POINTS)
def test_dissipation_balances_the_work_of_the_excitation(scene, r, beta):
    res = classify(scene, np.array([r]), np.array([beta]), design=True)
    assert res.regime[0] in (regimes.CONTINUOUS, regimes.STICK_SLIP)
    traj = trajectory(scene, r, beta)
    work = _work_of_excitation(scene, r, traj, int(res.period[0]))
    assert work > 0
    np.testing.assert_allclose(res.dissipation[0], work, rtol=1e-6)


@pytest.mark.parametrize(("scene", "r", "beta"), POINTS)
def test_amplitudes_match_dense_sampling(scene, r, beta):
    res = classify(scene, np.array([r]), np.array([beta]), design=True)
    traj = trajectory(scene, r, beta)
    tau = np.linspace(traj.tau[0], traj.tau[-1], 200001)
    x, _ = traj.sample(tau)
    y = np.cos(tau)[:, None]  # the base motion
    own = 0.5 * (x.max(axis=0) - x.min(axis=0))
    other = x + y if scene.contact == "base" else x - y  # base: x = z + y
    other = 0.5 * (other.max(axis=0) - other.min(axis=0))
    absolute, relative = (other, own) if scene.contact == "base" else (own, other)
    np.testing.assert_allclose(res.amplitude[0], absolute, rtol=1e-6)
    np.testing.assert_allclose(res.amplitude_relative[0], relative, rtol=1e-6)


@pytest.mark.parametrize(
    ("scene", "r"),
    [(Scene("ground", 1), 0.7), (Scene("ground", 2, 2, kappa=1.5), 0.8), (Scene("mass", 2), 1.5)],
)
def test_force_of_a_contact_stuck_for_ever_is_the_motion_bound(scene, r):
    _, bm = boundaries(scene, np.array([r]), method="paper")
    res = classify(scene, np.array([r]), 1.5 * bm, design=True)
    assert res.regime[0] == regimes.NO_MOTION
    np.testing.assert_allclose(res.contact_force_amplitude[0], bm[0], rtol=1e-6)
    assert res.dissipation[0] == 0.0


def test_undetermined_points_have_no_design_quantities():
    res = classify(Scene("ground", 1), np.array([1.0]), np.array([0.5]), design=True)  # unbounded
    assert res.regime[0] == regimes.UNBOUNDED
    assert np.isnan(res.amplitude).all() and np.isnan(res.dissipation).all()


@pytest.mark.parametrize(
    ("scene", "r"), [(Scene("ground", 2, 1, gamma=1.0, kappa=0.5), 0.6), (Scene("base", 3, 2), 1.4)]
)
def test_held_steady_state_design_in_closed_form_equals_its_replay(scene, r):
    """A point stuck for ever from the held start gets its design quantities in closed
    form; the same orbit replayed from the next period's section (tau = 2 pi, the same
    state) goes through the sampled replay: both agree to 1e-12."""
    from tasks import kernel
    from tasks.classifier import scene_modes_cached, settings_args
    from tasks.fidelity import resolve

    args = scene_modes_cached(scene).kernel_args()
    settings = settings_args(resolve("balanced"))
    _, bm = boundaries(scene, np.array([r]), method="paper")
    beta = 1.5 * float(bm[0])  # above the motion bound: stuck for ever from tau = 0
    rr, bb = np.array([r]), np.array([beta])
    out, final = kernel.run_points(rr, bb, args, settings)
    assert out[0, kernel.OUT_REGIME] == regimes.NO_MOTION and out[0, kernel.OUT_CYCLES] == 1
    closed = np.full(final.shape[1] + 1, np.nan)
    replayed = closed.copy()
    assert kernel.orbit_design(r, beta, args, settings, final[0], 1, 32, closed) == 0
    shifted = final[0].copy()
    shifted[-1] = 2.0 * np.pi
    assert kernel.orbit_design(r, beta, args, settings, shifted, 1, 32, replayed) > 0
    np.testing.assert_allclose(closed, replayed, rtol=1e-12, atol=1e-12 * np.abs(replayed).max())
    assert closed[-2] == 0.0 and closed[-1] == 0.0  # no slip, no damping: no dissipation


def test_design_on_the_orbit_checks_replay_equals_its_own_replay():
    """run_points_design takes the design quantities from the orbit check's records;
    orbit_designs replays every orbit itself: the same numbers, bit for bit."""
    from tasks import kernel
    from tasks.classifier import scene_modes_cached, settings_args
    from tasks.fidelity import resolve

    scene = Scene("ground", 2, 1, gamma=1.0, kappa=0.5)
    r = np.array([0.3, 0.6, 0.9, 1.3, 1.9, 0.8])
    beta = np.array([0.1, 0.5, 0.2, 0.6, 0.3, 0.0])
    args = scene_modes_cached(scene).kernel_args()
    settings = settings_args(resolve("balanced"))
    out, final, design = kernel.run_points_design(r, beta, args, settings, kernel.DESIGN_SAMPLES)
    assert set(out[:, kernel.OUT_REGIME]) >= {regimes.STICK_SLIP, regimes.CONTINUOUS}
    again, _ = kernel.orbit_designs(r, beta, args, settings, out, final, kernel.DESIGN_SAMPLES)
    np.testing.assert_array_equal(design, again)
