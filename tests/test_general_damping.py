"""The simulator with non-proportional damping (pairs of docs/structures.md 4.5)
against independent truths: the scipy event-driven reference (tasks.baseline,
which integrates the physical equations and shares no code with the pairs), and
the proportional code path (a Rayleigh C forced through the pairs classifies as
the modal kernel does)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from analysis import closed_form
from tasks import Scene, classifier, classify, regimes
from tasks.baseline import paper_method
from tasks.model import _pairs_args, scene_modes
from tasks.scene import CONFIGURATIONS
from tasks.structures import beam


def _spd(n: int, rng: np.random.Generator, cond: float = 10.0) -> np.ndarray:
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return Q @ np.diag(np.exp(rng.uniform(0.0, np.log(cond), n))) @ Q.T


def _dashpot_cantilever(c: float) -> Scene:
    """A cantilever reduced to 3 modes with a dashpot at the contact DOF (0)."""
    kw = beam(n_elements=6, modes=3).matrices()
    C = np.zeros_like(kw["mass"])
    C[0, 0] = c
    return Scene.from_matrices(**{**kw, "damping": C})


def _random_scenes(rng: np.random.Generator) -> list[Scene]:
    scenes = [_dashpot_cantilever(0.3)]
    for kind in range(5):
        n = 2 + kind % 3
        M, K = _spd(n, rng), _spd(n, rng)
        damping = ("modal", rng.uniform(0.02, 0.2, n)) if kind in (1, 4) else 0.15 * _spd(n, rng)
        contact = ("between", 0, n - 1) if kind == 3 else ("ground", int(rng.integers(n)))
        load = ("base", np.ones(n)) if kind == 4 else rng.standard_normal(n)
        scenes.append(Scene.from_matrices(M, K, load, contact, damping=damping))
    return scenes


def test_the_scenes_are_not_proportional():
    for scene in _random_scenes(np.random.default_rng(11)):
        assert not scene_modes(scene).proportional


def test_general_damping_against_scipy():
    """Regimes on >= 99 % of the points, slip amplitude within 1e-4 (relative) on
    >= 98 % of the moving points (random r, beta inside each regime's band)."""
    rng = np.random.default_rng(11)
    agree = total = moving = close = 0
    for scene in _random_scenes(rng):
        r = rng.uniform(0.3, 2.5, 3)
        bc, bm = closed_form.boundaries(scene, r, "exact")
        for frac in (0.5, 1.5, 3.0):  # continuous, stick-slip, no motion (mostly)
            beta = np.where(frac < 1, frac * bc, np.where(frac < 2, 0.5 * (bc + bm), 1.3 * bm))
            res = classify(scene, r, beta)
            for i in range(r.size):
                code, info = paper_method(scene, float(r[i]), float(beta[i]), cycles=100)
                total += 1
                agree += int(res.regime[i]) == code
                if code != regimes.NO_MOTION and info["amplitude"] > 1e-6:
                    moving += 1
                    close += (
                        abs(info["amplitude"] - res.slip_amplitude[i]) <= 1e-4 * info["amplitude"]
                    )
    assert total == 54 and agree >= 0.99 * total, (agree, total)
    assert moving >= 20 and close >= 0.98 * moving, (close, moving)


def _through_pairs(scene: Scene):
    m = scene_modes(scene)
    return replace(m, pairs=_pairs_args(m, np.array(scene.structure.damping)))


@pytest.mark.parametrize("name", ["2dof_ground_m1", "2dof_mass", "2dof_base_m2"])
def test_pairs_of_rayleigh_damping_classify_like_the_modes(name, monkeypatch):
    """Rayleigh C forced through the pairs (the general code path) classifies as
    the modal kernel does: same regimes, slip amplitudes to 1e-7."""
    scene = Scene.from_matrices(
        **{**CONFIGURATIONS[name].matrices(), "damping": ("rayleigh", 0.1, 0.02)}
    )
    r, beta = np.meshgrid([0.5, 0.9, 1.4, 2.3], [0.05, 0.3, 0.7, 1.5], indexing="ij")
    modal = classify(scene, r, beta)
    assert scene_modes(scene).pairs is None
    monkeypatch.setattr(classifier, "scene_modes_cached", _through_pairs)
    general = classify(scene, r, beta)
    assert np.array_equal(general.regime, modal.regime)
    moving = modal.regime != regimes.NO_MOTION
    assert moving.sum() >= 8
    np.testing.assert_allclose(
        general.slip_amplitude[moving], modal.slip_amplitude[moving], rtol=1e-7
    )


@pytest.mark.parametrize(("name", "r"), [("2dof_ground_m1", 30.0), ("2dof_base_m2", 12.0)])
def test_pairs_take_the_creep_threshold_of_the_modes_above_the_natural_frequencies(
    name, r, monkeypatch
):
    """Just below the motion bound, above both natural frequencies, the slips are tiny
    (about (1 - beta / bound)^2 of the inertial deflection) and the creep threshold
    decides them; forced through the pairs the same Rayleigh C gives the modal kernel's
    labels: stick-slip below the bound (docs/structures.md 3.1: no stuck steady state
    there), no motion above. The pairs took the static compliance, r^2 / lambda times
    the compliance at the excitation frequency, and called the slips no motion."""
    scene = Scene.from_matrices(
        **{**CONFIGURATIONS[name].matrices(), "damping": ("rayleigh", 0.1, 0.02)}
    )
    mb = float(closed_form.motion_bound(scene, np.array([r]))[0])
    beta = mb * np.array([0.99, 0.995, 0.999, 1.001])
    rr = np.full(beta.size, r)
    modal = classify(scene, rr, beta)
    assert modal.regime.tolist() == [regimes.STICK_SLIP] * 3 + [regimes.NO_MOTION]
    monkeypatch.setattr(classifier, "scene_modes_cached", _through_pairs)
    general = classify(scene, rr, beta)
    assert general.converged.all()
    np.testing.assert_array_equal(general.regime, modal.regime)
    np.testing.assert_allclose(general.slip_amplitude, modal.slip_amplitude, rtol=1e-6)


def test_full_matrix_rayleigh_classifies_as_rayleigh():
    """A proportional C given as a full matrix takes the modal path and classifies
    exactly as the same C given by its Rayleigh coefficients."""
    kw = CONFIGURATIONS["2dof_ground_m1"].matrices()
    a = Scene.from_matrices(**{**kw, "damping": ("rayleigh", 0.1, 0.02)})
    C = 0.1 * np.asarray(kw["mass"]) + 0.02 * np.asarray(kw["stiffness"])
    b = Scene.from_matrices(**{**kw, "damping": C})
    assert scene_modes(b).pairs is None
    r, beta = np.meshgrid([0.5, 1.1, 2.3], [0.05, 0.4, 1.2], indexing="ij")
    ra, rb = classify(a, r, beta), classify(b, r, beta)
    assert np.array_equal(ra.regime, rb.regime)
    np.testing.assert_allclose(rb.slip_amplitude, ra.slip_amplitude, rtol=1e-9, atol=1e-14)


def test_heavy_damping_with_real_eigenvalues_against_scipy():
    """Overdamped pairs (real damped eigenvalues, cosh / sinh propagation) in the
    simulator: regimes and slip amplitudes (1e-4) of the scipy reference."""
    rng = np.random.default_rng(5)
    M, K = _spd(3, rng), _spd(3, rng)
    B = rng.standard_normal((3, 3))
    scene = Scene.from_matrices(M, K, rng.standard_normal(3), ("ground", 1), damping=3.0 * B @ B.T)
    nu = np.linalg.eigvals(
        np.block(
            [
                [np.zeros((3, 3)), np.eye(3)],
                [-np.linalg.solve(M, K), -np.linalg.solve(M, 3.0 * B @ B.T)],
            ]
        )
    )
    assert np.sum(np.abs(nu.imag) < 1e-9) >= 2  # some real eigenvalues
    r = np.array([0.4, 1.0, 2.0])
    bc, bm = closed_form.boundaries(scene, r, "exact")
    for beta in (0.5 * bc, 0.5 * (bc + bm), 1.3 * bm):
        res = classify(scene, r, beta)
        for i in range(r.size):
            code, info = paper_method(scene, float(r[i]), float(beta[i]), cycles=60)
            assert int(res.regime[i]) == code, (r[i], beta[i])
            if code != regimes.NO_MOTION:
                assert res.slip_amplitude[i] == pytest.approx(info["amplitude"], rel=1e-4)
