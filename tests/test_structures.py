"""Euler-Bernoulli beams by finite elements (tasks.structures, docs/structures.md 2).

Independent truths: the textbook natural frequencies of beams (cantilever roots
of cos x cosh x = -1, pinned-pinned (n pi)^2, free-free roots of cos x cosh x = 1),
the h^4 convergence of Hermite cubic elements, the exact static condensation of
Craig-Bampton at its boundary DOF, and the scipy integrator of tasks.baseline.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import eigh
from scipy.optimize import brentq

from analysis import closed_form
from tasks import classify, regimes
from tasks.baseline import paper_method
from tasks.structures import beam, beam_model, craig_bampton


def _roots(f, ks):
    """The roots of f near (k + 1/2) pi, k in ks (bracketed within 1.5)."""
    return np.array([brentq(f, (k + 0.5) * np.pi - 1.5, (k + 0.5) * np.pi + 1.5) for k in ks])


CANTILEVER = _roots(lambda x: np.cos(x) * np.cosh(x) + 1.0, range(4))  # 1.8751, 4.6941, 7.8548, ...
FREE = _roots(lambda x: np.cos(x) * np.cosh(x) - 1.0, range(1, 4))  # 4.7300, 7.8532, 10.9956


def test_textbook_roots():
    np.testing.assert_allclose(CANTILEVER[:3], [1.8751, 4.6941, 7.8548], atol=1e-4)
    np.testing.assert_allclose(FREE[:2], [4.7300, 7.8532], atol=1e-4)


@pytest.mark.parametrize(
    ("supports", "exact", "extra"),
    [
        ("cantilever", CANTILEVER**2, {}),
        ("pinned", (np.arange(1, 5) * np.pi) ** 2, {}),
        ("free", FREE**2, {"support_stiffness": 1e-6}),
    ],
)
def test_natural_frequencies_match_the_textbook(supports, exact, extra):
    """omega_i sqrt(m L^4 / EI) with 20 elements: the first two within 2e-5, the
    next two within 2e-4 (free-free: after the two suspension modes on the soft springs)."""
    w = beam_model(20, supports, **extra).natural_frequencies()
    if supports == "free":
        assert w[1] < 1e-2  # two suspension modes
        w = w[2:]
    np.testing.assert_allclose(w[:2], exact[:2], rtol=2e-5)
    np.testing.assert_allclose(w[: exact.size], exact, rtol=2e-4)


def test_frequencies_converge_as_h4():
    err = [abs(beam_model(n).natural_frequencies()[1] / CANTILEVER[1] ** 2 - 1) for n in (4, 8, 16)]
    assert err[0] > err[1] > err[2] > 0
    rates = np.log2(np.array(err[:-1]) / np.array(err[1:]))
    assert np.all(rates > 3.7), rates  # Hermite cubics: O(h^4) for the frequencies


def test_scene_refers_r_to_the_first_frequency_and_reduction_keeps_the_contact():
    full = beam(20, contact_node=16)
    lam = eigh(full.stiffness_matrix(), full.mass_matrix(), eigvals_only=True)
    assert lam[0] == pytest.approx(1.0, rel=1e-8)  # eigh rounding: spread 5e7 times eps
    assert lam[1] == pytest.approx((CANTILEVER[1] / CANTILEVER[0]) ** 4, rel=1e-4)
    red = beam(20, contact_node=16, modes=4)
    assert red.dof == 5 and np.array_equal(red.contact_vector(), np.eye(5)[0])
    lam_r = eigh(red.stiffness_matrix(), red.mass_matrix(), eigvals_only=True)
    np.testing.assert_allclose(lam_r[:3], lam[:3], rtol=1e-3)
    assert np.all(lam_r >= lam[:5] * (1 - 1e-12))  # Rayleigh-Ritz: from above
    # Craig-Bampton condenses statically exactly at its boundary: same contact compliance
    b, br = full.contact_vector(), red.contact_vector()
    c_full = b @ np.linalg.solve(full.stiffness_matrix(), b)
    c_red = br @ np.linalg.solve(red.stiffness_matrix(), br)
    assert c_red == pytest.approx(c_full, rel=1e-10)
    # and the static response at the contact to the (tip) load
    p, pr = full.load_vector(), red.load_vector()
    assert br @ np.linalg.solve(red.stiffness_matrix(), pr) == pytest.approx(
        b @ np.linalg.solve(full.stiffness_matrix(), p), rel=1e-10
    )


def test_craig_bampton_boundary_rows_are_physical():
    m = beam_model(6)
    V = craig_bampton(m.mass, m.stiffness, [4], 3)
    np.testing.assert_array_equal(V[4], [1.0, 0.0, 0.0, 0.0])


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"supports": "clamped"}, "supports"),
        ({"n_elements": 0}, "n_elements"),
        ({"contact_node": 0}, "contact_node: node 0 is held"),
        ({"contact_node": 99}, "contact_node: must be in"),
        ({"load": "moment"}, "load"),
        ({"modes": 0}, "modes"),
        ({"supports": "free"}, "support_stiffness"),
    ],
)
def test_bad_beams_name_the_argument(kwargs, field):
    with pytest.raises(ValueError, match=f"^{field}"):
        beam(**{"n_elements": 8, **kwargs})


def test_base_load_of_a_reduced_beam_keeps_the_inertial_load():
    full, red = beam(12, load="base"), beam(12, load="base", modes=5)
    assert full.load_scales_r2 and red.load_scales_r2
    # the static contact response to the inertial load r^2 M u: exact after reduction
    for s in (full, red):
        assert s.label.startswith(f"{s.dof}dof_matrices_ground")
    b, br = full.contact_vector(), red.contact_vector()
    x = b @ np.linalg.solve(full.stiffness_matrix(), full.load_vector(2.0))
    xr = br @ np.linalg.solve(red.stiffness_matrix(), red.load_vector(2.0))
    assert xr == pytest.approx(x, rel=1e-10)


@pytest.mark.parametrize(("r", "beta"), [(1.5, 0.3), (3.0, 0.05), (3.0, 0.9)])
def test_cantilever_regimes_agree_with_scipy_and_closed_forms(r, beta):
    """A cantilever reduced to its contact DOF and 3 modes, contact at 0.8 L: the
    simulator, the scipy integrator (from rest) and the closed forms agree."""
    scene = beam(20, contact_node=16, modes=3)
    res = classify(scene, r, beta)
    code, info = paper_method(scene, r, beta, cycles=150)
    assert res.regime == code
    expected = closed_form.predict(scene, np.array([r]), np.array([beta]), method="exact")
    assert res.regime == expected[0]
    if code == regimes.CONTINUOUS:  # Den Hartog's amplitude (docs/theory.md 4.3)
        V, U, _ = closed_form.response_functions(scene, np.array([r]))
        amplitude = np.sqrt(V[0] ** 2 - (beta * U[0]) ** 2)
        assert res.slip_amplitude == pytest.approx(amplitude, rel=1e-6)
        assert abs(info["amplitude"] - amplitude) <= 1e-2 * amplitude  # from rest: transients


def test_traced_boundaries_of_a_damped_cantilever_match_the_damped_closed_forms():
    """The simulator's traced boundaries (bisection on classify) of a Rayleigh-damped
    cantilever equal the damped closed forms of docs/structures.md 3 (exact method)."""
    from tasks import trace_boundaries

    scene = beam(12, contact_node=10, modes=3, damping=("rayleigh", 0.05, 0.004))
    r = np.array([0.6, 1.4, 2.5])
    bc, bm = closed_form.boundaries(scene, r, "exact")
    tb = trace_boundaries(scene, r, (0.0, 3.0), guess_continuous=bc, guess_motion=bm)
    np.testing.assert_allclose(tb.beta_continuous, bc, rtol=2e-3)
    np.testing.assert_allclose(tb.beta_motion, bm, rtol=2e-3)
