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
from tasks import Scene, classify, regimes
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


# ------------------------------------------------------------ the damped simulator
def _rayleigh(name: str, a: float, b: float) -> Scene:
    return Scene.from_matrices(**{**CONFIGURATIONS[name].matrices(), "damping": ("rayleigh", a, b)})


@pytest.mark.parametrize("zeta", [0.05, 0.3])
def test_simulator_gives_den_hartogs_damped_amplitude(zeta):
    """Continuous points of a damped mass: the simulator's slip amplitude is Eq. 3.8."""
    scene = _sdof(zeta)
    r = np.array([0.5, 0.9, 1.0, 1.6, 3.0])
    beta = 0.5 * closed_form.continuous_bound(scene, r, "exact")
    res = classify(scene, r, beta)
    assert np.all(res.regime == regimes.CONTINUOUS) and np.all(res.converged)
    expected = [
        damped.den_hartog_amplitude(float(a), float(b), zeta) for a, b in zip(r, beta, strict=True)
    ]
    np.testing.assert_allclose(res.slip_amplitude, expected, rtol=1e-7)
    # and the regimes of the closed forms just beyond each bound
    bc, bm = closed_form.boundaries(scene, r, "exact")
    assert np.all(classify(scene, r, 1.02 * bc).regime == regimes.STICK_SLIP)
    assert np.all(classify(scene, r, 1.02 * bm).regime == regimes.NO_MOTION)


def _random_damped_scenes(rng: np.random.Generator) -> list[Scene]:
    from tasks.structures import beam

    return [
        _sdof(0.1),
        _rayleigh("2dof_ground_m2", 0.2, 0.05),
        _rayleigh("2dof_base_m1", 0.2, 0.02),
        _rayleigh("2dof_mass", 0.25, 0.0),
        Scene.from_matrices(
            _spd(3, rng),
            _spd(3, rng),
            rng.standard_normal(3),
            ("ground", 1),
            damping=("rayleigh", 0.2, 0.03),
        ),
        Scene.from_matrices(
            _spd(3, rng),
            _spd(3, rng),
            rng.standard_normal(3),
            ("between", 0, 2),
            damping=("rayleigh", 0.15, 0.05),
        ),
        beam(10, contact_node=8, modes=2, damping=("rayleigh", 0.2, 0.005)),
    ]


def test_simulator_against_the_damped_scipy_reference():
    """Random points of damped scenes (single mass, Rayleigh chains with every contact,
    random full M and K, a cantilever): the regimes of the scipy reference on every
    point, the slip amplitude within 1e-4 where it is above the reference's absolute
    tolerance (1e-6) by a factor 100."""
    rng = np.random.default_rng(7)
    total = agree = moving = close = 0
    for scene in _random_damped_scenes(rng):
        for _ in range(3):
            r = float(rng.uniform(0.4, 3.0))
            bm = float(closed_form.motion_bound(scene, [r])[0])
            beta = float(rng.uniform(0.0, 1.2 * min(bm, 5.0)))
            res = classify(scene, r, beta)
            code, info = paper_method(scene, r, beta, cycles=120)
            total += 1
            agree += int(res.regime) == code
            if code != regimes.NO_MOTION and info["amplitude"] > 1e-4:
                moving += 1
                close += abs(info["amplitude"] - res.slip_amplitude) <= 1e-4 * info["amplitude"]
    assert agree == total, (agree, total)
    assert moving >= 8 and close >= 0.98 * moving, (close, moving)


def test_light_damping_tends_to_the_undamped_simulator():
    """Rayleigh damping 1e-7: the same regimes as the undamped chain, and continuous
    amplitudes within 1e-5 (the damped formulas have the undamped limit)."""
    chain = CONFIGURATIONS["2dof_ground_m1"]
    light = _rayleigh("2dof_ground_m1", 1e-7, 0.0)
    r, beta = np.meshgrid([0.4, 1.3, 2.2], [0.05, 0.3, 0.9], indexing="ij")
    a, b = classify(chain, r, beta), classify(light, r, beta)
    assert np.array_equal(a.regime, b.regime)
    cont = a.regime == regimes.CONTINUOUS
    assert cont.any()
    np.testing.assert_allclose(b.slip_amplitude[cont], a.slip_amplitude[cont], rtol=1e-5)


def test_energy_balance_per_period():
    """On the converged orbit of a damped stick-slip point and a continuous one: the
    work of the load over a period equals the friction plus the viscous dissipation
    (sampled exactly from the closed-form phases, Simpson's rule)."""
    from tasks import trajectory

    scene = _rayleigh("2dof_ground_m1", 0.1, 0.02)
    C, p, b = scene.damping_matrix, scene.load_vector, scene.contact_vector()
    for r, where, code in ((1.3, 0.5, regimes.STICK_SLIP), (2.2, -0.5, regimes.CONTINUOUS)):
        bc, bm = (float(v[0]) for v in closed_form.boundaries(scene, [r], "exact"))
        beta = bc + where * (bm - bc) if where > 0 else -where * bc
        tr = trajectory(scene, r, beta)
        assert tr.result is not None and tr.result.regime == code
        t0 = tr.tau[0]
        tau = t0 + np.linspace(0.0, 2 * np.pi, 20001)
        x, xd = tr.sample(tau)
        load = (xd @ p(r)) * np.cos(tau)
        viscous = np.einsum("ti,ij,tj->t", xd, C(r), xd)
        friction = beta * np.abs(xd @ b)
        w = np.ones(tau.size)
        w[1:-1:2], w[2:-1:2] = 4.0, 2.0
        h = (tau[1] - tau[0]) / 3.0
        w_load, w_visc, w_fric = (h * np.sum(w * f) for f in (load, viscous, friction))
        assert w_fric > 0.0 and w_visc > 0.0
        assert w_load == pytest.approx(w_visc + w_fric, rel=1e-6)


def test_repeated_damped_eigenvalues_are_refused_by_the_simulator_only():
    """Non-proportional damping is simulated through the pairs of docs/structures.md
    4.5 (tests/test_general_damping.py), except when two damped eigenvalues coincide:
    here the held system (DOFs 0, 1) is M = K = I, C = 0.1 I."""
    K = np.array([[1.0, 0.0, 0.3], [0.0, 1.0, 0.2], [0.3, 0.2, 2.0]])
    scene = Scene.from_matrices(
        np.eye(3), K, [1.0, 0.0, 0.0], ("ground", 2), damping=np.diag([0.1, 0.1, 0.5])
    )
    with pytest.raises(ValueError, match="^damping: two damped eigenvalues coincide"):
        classify(scene, 1.0, 0.1)
    assert np.isfinite(closed_form.motion_bound(scene, [1.0])[0])  # closed forms take it


@pytest.mark.parametrize(
    ("w", "sigma"),
    [(2.0, 0.1), (1.0, 0.01), (1.0, 3.0), (2.0, 2.0), (0.5, 0.0), (3.7, 0.4)],
)
def test_damped_modal_propagation_and_its_bounds(w, sigma):
    """One mode of Eq. 4.1 (under-, over-, critically and un-damped, at resonance):
    the closed form against scipy's ODE solver, and the derivative bounds (Eq. 4.4)
    and the stick-force bound (Eq. 4.5) above the sampled values."""
    from scipy.integrate import solve_ivp

    from tasks import kernel
    from tasks.kernel import damping, layout

    seg = np.zeros((layout.N_ROWS, 1))
    sc = np.zeros(layout.N_SCALARS)
    tau0, e0, v0, a, c, alpha, delta, amp = 0.7, 0.3, -1.1, 0.8, 0.25, 1.5, -0.6, 0.4
    seg[layout.OMEGA, 0], seg[layout.DAMP, 0] = w, sigma
    seg[layout.ETA0, 0], seg[layout.ETAD0, 0] = e0, v0
    seg[layout.LOAD_COS, 0], seg[layout.LOAD_CONST, 0] = a, c
    seg[layout.ALPHA, 0], seg[layout.DELTA, 0] = alpha, delta
    sc[layout.COS_TAU0], sc[layout.SIN_TAU0] = np.cos(tau0), np.sin(tau0)
    sc[layout.OBS_COS], sc[layout.OBS0] = amp, amp * np.cos(tau0) + alpha * e0 + delta * v0
    sc[layout.DAMPED] = 1.0
    t_end = 12.0
    ts = np.linspace(0.0, t_end, 1201)

    def rhs(t, y):
        return [y[1], a * np.cos(tau0 + t) + c - 2 * sigma * y[1] - w * w * y[0]]

    ref = solve_ivp(rhs, (0, t_end), [e0, v0], t_eval=ts, rtol=1e-12, atol=1e-13).y
    eta, etad = np.zeros(1), np.zeros(1)
    ys, dys = np.empty(ts.size), np.empty(ts.size)
    for i, t in enumerate(ts):
        ys[i], dys[i] = kernel.evaluate(seg, sc, t, eta, etad)
        assert eta[0] == pytest.approx(ref[0, i], abs=1e-9)
        assert etad[0] == pytest.approx(ref[1, i], abs=1e-9)
        y_ref = amp * np.cos(tau0 + t) + alpha * ref[0, i] + delta * ref[1, i]
        assert ys[i] == pytest.approx(y_ref, abs=1e-8)
    d1, d2 = kernel.derivative_bounds(seg, sc, t_end)
    assert np.max(np.abs(dys)) <= d1
    assert np.max(np.abs(np.gradient(dys, ts))) <= d2 * 1.001  # finite differences
    if sigma > 0.0:
        assert np.max(np.abs(ys)) <= damping.stick_force_bound_damped(seg, sc) * (1 + 1e-12)
    if sigma == 0.0:  # the damped formulas at sigma = 0 are the undamped ones
        sc[layout.DAMPED] = 0.0
        for t in (1e-9, 0.3, 5.0):
            y0, dy0 = kernel.evaluate(seg, sc, t, eta, etad)
            sc[layout.DAMPED] = 1.0
            y1, dy1 = kernel.evaluate(seg, sc, t, eta, etad)
            sc[layout.DAMPED] = 0.0
            assert y1 == pytest.approx(y0, abs=1e-13) and dy1 == pytest.approx(dy0, abs=1e-12)
