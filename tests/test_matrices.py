"""Scenes from matrices (tasks.Scene.from_matrices, docs/structures.md 1).

Independent truths: the chain itself (a chain given by its own matrices must
classify and bound identically), invariance under a change of coordinates that
keeps the contact coordinate (full, non-diagonal M and K describing the same
chain must give the same regimes and contact amplitudes), and the scipy
integrator of tasks.baseline on full matrices.
"""

from __future__ import annotations

import numpy as np
import pytest

from analysis import closed_form
from tasks import Scene, classify, regimes
from tasks.baseline import paper_method
from tasks.model import scene_modes
from tasks.scene import CONFIGURATIONS

R = np.array([0.35, 0.8, 1.3, 2.2])
BETA = np.array([0.05, 0.3, 0.9])


def _chain_kwargs(n: int = 2) -> dict:
    return Scene("ground", n, 1, gamma=1.5, kappa=0.7).matrices()


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"mass": [[1.0, 0.2], [0.0, 1.0]]}, "mass: must be symmetric"),
        ({"mass": [[1.0, 2.0], [2.0, 1.0]]}, "mass: must be positive definite"),
        ({"mass": np.eye(3)}, "stiffness: expected shape \\(3, 3\\)"),
        ({"mass": [1.0, 2.0]}, "mass: expected a square matrix"),
        ({"stiffness": [[1.0, 0.0], [0.0, -1.0]]}, "stiffness: must be positive definite"),
        ({"stiffness": [[1.0, np.nan], [np.nan, 1.0]]}, "stiffness: every entry must be finite"),
        ({"stiffness": [[1e13, 0.0], [0.0, 1.0]]}, "stiffness: the eigenvalues"),
        ({"load": [1.0, 0.0, 0.0]}, "load: expected 2 numbers"),
        ({"load": [0.0, 0.0]}, "load: must not be zero"),
        ({"load": ("base", [0.0, 0.0])}, "load: the influence vector"),
        ({"contact": ("ground", 2)}, "contact: DOF index 2 is outside the DOFs 0..1"),
        ({"contact": ("between", 1, 1)}, "contact: 'between' needs two different DOFs"),
        ({"contact": ("wall", 0)}, "contact: expected"),
        ({"contact": ("ground", True)}, "contact: expected"),
        ({"damping": [[1.0, 0.0], [0.0, -0.5]]}, "damping: must be positive semidefinite"),
        ({"damping": ("rayleigh", -0.1, 0.0)}, "damping: Rayleigh coefficients"),
        ({"damping": ("modal", [0.1, 0.2, 0.3])}, "damping: expected 2 numbers"),
        ({"damping": ("viscous", 1.0)}, "damping: expected a matrix"),
        ({"damping": "0.1"}, "damping: expected an array of numbers"),
    ],
)
def test_bad_matrices_get_one_error_naming_the_argument(change, field):
    kwargs = {**_chain_kwargs(), **change}
    with pytest.raises(ValueError, match=f"^{field}") as err:
        Scene.from_matrices(**kwargs)
    assert "\n" not in str(err.value)


def test_a_scene_of_matrices_cannot_be_made_by_hand():
    with pytest.raises(ValueError, match="^contact: a scene of matrices"):
        Scene("matrices", 2)


def test_round_trip_hash_and_damping_forms():
    kw = _chain_kwargs(3)
    kw.pop("damping")
    a = Scene.from_matrices(**kw)
    b = Scene.from_matrices(**a.matrices())
    assert a == b and hash(a) == hash(b) and a.label == "3dof_matrices_ground_x0"
    # zero damping of any form is no damping: the same scene
    for none in (("rayleigh", 0.0, 0.0), ("modal", 0.0), np.zeros((3, 3))):
        assert Scene.from_matrices(**kw, damping=none) == a
    M, K = kw["mass"], kw["stiffness"]
    ray = Scene.from_matrices(**kw, damping=("rayleigh", 0.1, 0.02))
    assert ray.damped and ray != a and ray.label.endswith("_damped")
    np.testing.assert_allclose(ray.damping_matrix(2.0), 2.0 * (0.1 * M + 0.02 * K))
    # modal damping ratios: Phi^T C Phi = diag(2 zeta_i omega_i) on the modes of (K, M)
    zeta = np.array([0.01, 0.05, 0.2])
    modal = Scene.from_matrices(**kw, damping=("modal", zeta))
    lam, phi = scene_modes(a).lam, scene_modes(a).phi
    np.testing.assert_allclose(
        phi.T @ modal.damping_matrix() @ phi, np.diag(2 * zeta * np.sqrt(lam)), atol=1e-12
    )
    assert Scene.from_matrices(**modal.matrices()) == modal
    d = modal.to_dict()
    assert d["contact"] == "matrices" and d["damping"][0] == "modal" and len(d["mass"]) == 3


@pytest.mark.parametrize("name", list(CONFIGURATIONS))
def test_chain_from_its_matrices_is_the_chain(name):
    """Same kernel arrays bit for bit, same regimes and diagnostics, same closed forms."""
    chain = CONFIGURATIONS[name]
    scene = Scene.from_matrices(**chain.matrices())
    assert not scene.damped
    a, b = scene_modes(chain).kernel_args(), scene_modes(scene).kernel_args()
    for x, y in zip(a, b, strict=True):
        assert np.array_equal(x, y)
    r, beta = np.meshgrid(R, BETA, indexing="ij")
    ra, rb = classify(chain, r, beta, fidelity="fast"), classify(scene, r, beta, fidelity="fast")
    for field in ("regime", "cycles", "slip_amplitude", "stick_fraction", "stops_per_cycle"):
        assert np.array_equal(getattr(ra, field), getattr(rb, field), equal_nan=True), field
    assert len(set(ra.regime.ravel()) & {0, 1, 2}) >= 2
    for method in ("paper", "exact"):
        for f in (closed_form.continuous_bound, closed_form.motion_bound):
            args = (method,) if f is closed_form.continuous_bound else ()
            assert np.array_equal(f(chain, R, *args), f(scene, R, *args), equal_nan=True)


def _mixed(chain: Scene, seed: int) -> Scene:
    """The chain in coordinates y with x = P y and P^T b = b (the contact coordinate
    b . x = b . y kept): full M_y = P^T M P, K_y = P^T K P, p_y = P^T p, b_y = b."""
    kw = chain.matrices()
    n = chain.dof
    rng = np.random.default_rng(seed)
    P = np.eye(n) + 0.4 * rng.standard_normal((n, n))
    kw_b = chain.contact_vector()
    shared = 0.4 * rng.standard_normal(n)  # rows of the contact DOFs: e_i + shared
    for j in np.flatnonzero(kw_b):
        P[j] = np.eye(n)[j] + (shared if kw_b.sum() == 0 else 0.0)
    assert np.allclose(P.T @ kw_b, kw_b)
    load = kw["load"]
    if isinstance(load, tuple):  # base: p = r^2 M u, u_y = P^-1 u
        load = ("base", np.linalg.solve(P, load[1]))
    else:
        load = P.T @ load
    M, K = P.T @ kw["mass"] @ P, P.T @ kw["stiffness"] @ P
    return Scene.from_matrices(0.5 * (M + M.T), 0.5 * (K + K.T), load, kw["contact"])


@pytest.mark.parametrize("name", ["2dof_ground_m2", "2dof_base_m1", "2dof_mass"])
def test_full_matrices_of_the_same_chain_give_its_regimes(name):
    chain = CONFIGURATIONS[name]
    scene = _mixed(chain, 3)
    assert np.count_nonzero(scene.mass_matrix() - np.diag(np.diag(scene.mass_matrix()))) > 0
    r, beta = np.meshgrid(R, BETA, indexing="ij")
    ra, rb = classify(chain, r, beta), classify(scene, r, beta)
    assert np.array_equal(ra.regime, rb.regime)
    moving = ra.regime != regimes.NO_MOTION
    np.testing.assert_allclose(rb.slip_amplitude[moving], ra.slip_amplitude[moving], rtol=1e-6)
    for method in ("paper", "exact"):
        np.testing.assert_allclose(
            closed_form.continuous_bound(scene, R, method),
            closed_form.continuous_bound(chain, R, method),
            rtol=1e-9,
        )
    np.testing.assert_allclose(
        closed_form.motion_bound(scene, R), closed_form.motion_bound(chain, R), rtol=1e-9
    )


@pytest.mark.parametrize(
    ("r", "beta", "code"),
    [(2.2, 0.3, regimes.CONTINUOUS), (0.8, 0.3, regimes.STICK_SLIP), (0.8, 0.9, regimes.NO_MOTION)],
)
def test_scipy_reference_on_full_matrices(r, beta, code):
    """The scipy integrator on the full matrices, from rest (400 cycles: the
    undamped transients decay slowly), agrees with the simulator. (Undamped
    stick-slip from rest keeps the free vibration of the held masses, so only its
    regime is compared: docs/theory.md 3.)"""
    scene = _mixed(Scene("ground", 3, 2, gamma=0.8, kappa=1.3), 5)
    ref, info = paper_method(scene, r, beta, cycles=400)
    res = classify(scene, r, beta)
    assert ref == res.regime == code
    if code != regimes.STICK_SLIP:
        assert abs(info["amplitude"] - res.slip_amplitude) <= 1e-3 * max(res.slip_amplitude, 1e-12)
