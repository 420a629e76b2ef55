"""The settling rule of a creep in progress with several contacts (docs/contacts.md 4).

Against independent truths: the one-contact kernel (a partner without friction), the
scipy reference (tasks.multicontact.reference) run on the creeping point and on the
structure with the creeping contact held, and the force swing that certifies the rule
recomputed from the reference's own stuck forces.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tasks import Scene, classify, regimes
from tasks.classifier import settings_args
from tasks.fidelity import resolve
from tasks.multicontact import MultiScene, creep, layout, steady
from tasks.multicontact import reference as ref
from tasks.multicontact.classify import stuck_sets_cached
from tasks.regimes import CREEP_FORCE_RTOL

# The 2DOF ground chain of benchmarks/bench_multicontact.py (contacts on m1 and m2,
# beta_ratio 1 and 0.5): at these points m2's contact creeps towards sticking (slips
# of 1e-6 of its static deflection, one way, shrinking about as 1 / n^2) while m1's
# slides; before the rule they ran to max_cycles, not_converged.
CHAIN = Scene("ground", 2, contact_mass=[1, 2], beta_ratio=[1.0, 0.5])
CREEP_R = np.array([2.876305220883534, 2.943775100401606])
CREEP_BETA = np.array([0.28909090909090907, 0.27414141414141413])


def test_creeping_contact_settles_as_no_motion():
    """The creeping contact is no motion, reached asymptotically; the sliding one
    keeps its regime; the point converged within the budget (flag and label of the
    one-contact rule: ``asymptotic``, no stops)."""
    res = classify(CHAIN, CREEP_R, CREEP_BETA)
    assert np.all(res.converged) and np.all(res.asymptotic)
    assert np.all(res.regime[:, 1] == regimes.NO_MOTION)
    assert np.all(res.regime[:, 0] == regimes.CONTINUOUS)
    assert np.all(res.stops_per_cycle[:, 1] == 0)
    assert np.all(res.cycles < resolve("balanced").max_cycles)
    # the slip kept as a diagnostic is that of a creep: below CREEP_SLIP_RTOL beta_c c_c
    c1 = float(np.linalg.solve(CHAIN.stiffness_matrix(), [0.0, 1.0])[1])  # b^T K^-1 b of m2
    assert np.all(res.slip_amplitude[:, 1] < regimes.CREEP_SLIP_RTOL * 0.5 * CREEP_BETA * c1)


def _reference_cycles(scene: MultiScene, r: float, beta: float, cycles: int):
    """Per cycle of the reference from the held start: the slip distance and the signed
    drift of each contact's relative displacement over the cycle."""
    sys_ = ref._System(scene, r, beta)
    y = sys_.held()
    n = sys_.n
    active = [c for c in range(sys_.k) if sys_.betas[c] > 0.0]
    stuck, signs = sys_.decide(0.0, y[:n], y[n:], active, {})
    signs = {c: signs.get(c, 0.0) for c in range(sys_.k)}
    drift = []
    for _ in range(cycles):
        stats = [{"stuck": 0.0, "sticks": 0} for _ in range(sys_.k)]
        y1, stuck, signs = ref._cycle(sys_, y.copy(), tuple(stuck), dict(signs), stats)
        drift.append(sys_.B.T @ (y1[:n] - y[:n]))
        y = y1
    return np.array(drift)


def test_reference_creeps_towards_the_settled_label():
    """The scipy reference on the first creeping point: m2's contact drifts one way
    with shrinking steps (a creep towards sticking, no periodic slip), and the
    reference on the chain with m2 held (beta_ratio 1e5: the orbit the rule continues
    with) converges to m1 continuous, with the simulator's slip amplitude of m1 (1e-6)."""
    r, beta = float(CREEP_R[0]), float(CREEP_BETA[0])
    drift = _reference_cycles(CHAIN, r, beta, 160)[:, 1]
    late = drift[40:]
    assert np.all(late > 0.0) or np.all(late < 0.0)  # one way: no periodic orbit
    assert abs(late[-20:]).mean() < 0.5 * abs(late[:20]).mean()  # shrinking
    held = MultiScene.from_matrices(
        CHAIN.mass_matrix(1.0), CHAIN.stiffness_matrix(), CHAIN.load_vector(r),
        [("ground", 0), ("ground", 1)], beta_ratio=[1.0, 1e5],
    )  # fmt: skip
    regime, amp, ok = ref.reference_point(held, r, beta, max_cycles=200)
    assert ok
    res = classify(CHAIN, r, beta)
    assert regime[0] == res.regime[0] == regimes.CONTINUOUS
    assert regime[1] == res.regime[1] == regimes.NO_MOTION
    assert amp[0] == pytest.approx(res.slip_amplitude[0], rel=1e-6)


def _held_orbit(r: float, beta: float):
    """The simulator's section state of the point (the held continuation's orbit)."""
    st = settings_args(resolve("balanced"))
    args = stuck_sets_cached(CHAIN).kernel_args()
    out_g = np.zeros(layout.N_OG)
    out_c = np.zeros((2, layout.N_OC))
    X, stuck, signs, _ = steady.simulate_point(r, beta, args, st, out_g, out_c)
    ctx = steady.point_context(r, beta, args, st)
    return X, stuck, signs, ctx, out_g, out_c


def _reference_swing(r: float, beta: float, X: np.ndarray) -> float:
    """Half the swing of m2's stuck force over one period of the reference with m2
    held, from the simulator's section state (the reference's own forces, sampled)."""
    held = MultiScene.from_matrices(
        CHAIN.mass_matrix(1.0), CHAIN.stiffness_matrix(), CHAIN.load_vector(r),
        [("ground", 0), ("ground", 1)], beta_ratio=[1.0, 1e5],
    )  # fmt: skip
    sys_ = ref._System(held, r, beta)
    n = sys_.n
    y = X.copy()
    free = {0: 1.0 if sys_.B[:, 0] @ X[n:] > 0.0 else -1.0}
    stuck, signs = sys_.decide(0.0, y[:n], y[n:], [1], free)
    tau, forces = 0.0, []
    for _ in range(50):
        t1, y1, fired = ref._phase(sys_, tau, 2 * math.pi, y, stuck, signs)
        A, E = ref._operator(sys_, stuck, signs)[:2]
        z0 = np.concatenate([y, [math.cos(tau), math.sin(tau), 1.0]])
        for t in np.linspace(0.0, t1 - tau, 200):
            forces.append((E @ (ref.expm(A * t) @ z0))[1])
        if not fired or t1 >= 2 * math.pi - 1e-12:
            break
        cand = sorted(set(stuck) | set(fired))
        rest = {c: signs[c] for c in range(2) if c not in cand}
        stuck, signs = sys_.decide(t1, y1[:n], y1[n:], cand, rest)
        signs = {c: signs.get(c, 0.0) for c in range(2)}
        y, tau = y1, t1
    forces = np.array(forces)
    return 0.5 * (forces.max() - forces.min())


def test_force_swing_certifies_and_an_uncertified_creep_stays_flagged():
    """The certificate (tasks.multicontact.creep.swing_certified) against the swing of
    the held contact's force recomputed by the reference: it holds with the contact's
    own limit, fails for a limit just below swing / (1 - CREEP_FORCE_RTOL); and a
    creep whose certificate fails is not_converged, never a regime."""
    r, beta = float(CREEP_R[0]), float(CREEP_BETA[0])
    X, stuck, signs, ctx, out_g, out_c = _held_orbit(r, beta)
    assert out_g[layout.OG_ASYMPTOTIC] == 1.0
    swing = _reference_swing(r, beta, X)
    hctx = creep.held_context(ctx, 2)
    limit = swing / (1.0 - CREEP_FORCE_RTOL)
    assert 0.5 * beta > limit  # the margin that settled the point
    ok = np.array([1.0, 0.5]) * beta
    assert creep.swing_certified(X, stuck, signs, hctx, 2, ok, 1, 2e7)
    assert creep.swing_certified(X, stuck, signs, hctx, 2, np.array([beta, 1.002 * limit]), 1, 2e7)
    low = np.array([beta, 0.998 * limit])
    assert not creep.swing_certified(X, stuck, signs, hctx, 2, low, 1, 2e7)
    # the same settled point with that limit: flagged not_converged, no regime
    g, c = out_g.copy(), out_c.copy()
    steady._settle(X, stuck, signs, hctx, 2, low, 1, 500, 0, g, c, np.zeros(2), 2e7)
    assert g[layout.OG_CONVERGED] == 0.0
    assert np.all(c[:, layout.OC_REGIME] == regimes.NOT_CONVERGED)


def test_frictionless_partner_gives_the_one_contact_creep_labels():
    """A random 3 DOF structure, contact at DOF 0, a partner between DOFs 1 and 2 with
    beta_ratio 0: at points just below the motion bound (1e-5 of it) the one-contact
    kernel's creep rule labels every point no motion, ``asymptotic`` (its slips below
    the creep threshold); the two-contact scene gives the same labels and flags."""
    rng = np.random.default_rng(103)
    M, K, p = ref.random_structure(rng, 3)
    one = Scene.from_matrices(M, K, p, ("ground", 0))
    two = MultiScene.from_matrices(M, K, p, [("ground", 0), ("between", 1, 2)], beta_ratio=[1, 0])
    r = np.array([1.2267355480870903, 1.5672946815042565, 0.994657508811901, 2.586138709699109])
    beta = np.array([5.4072853696262, 0.5468438466827155, 1.2342639917422158, 0.2564370290764144])
    kern = classify(one, r, beta)
    res = classify(two, r, beta)
    assert np.all(kern.regime == regimes.NO_MOTION) and np.all(kern.asymptotic)
    np.testing.assert_array_equal(res.regime[:, 0], kern.regime)
    np.testing.assert_array_equal(res.asymptotic, kern.asymptotic)
    np.testing.assert_array_equal(res.converged, kern.converged)
    assert np.all(res.regime[:, 1] == regimes.CONTINUOUS)


# A damped 3 DOF structure nobody tuned (reference.random_structure, seed 103, Rayleigh
# C = 0.02 M + 0.01 K), a contact at DOF 2 at its motion bound (5e-10 above it: the held
# margin leaves it to the simulation) and a frictionless partner at DOF 0, from rest.
_RNG_M, _RNG_K, _RNG_P = ref.random_structure(np.random.default_rng(103), 3)
_RAYLEIGH = ("rayleigh", 0.02, 0.01)
_AT_BOUND_R = np.array([0.5, 1.3])


def _at_bound():
    from analysis import damped

    one = Scene.from_matrices(_RNG_M, _RNG_K, _RNG_P, ("ground", 2), damping=_RAYLEIGH)
    two = MultiScene.from_matrices(
        _RNG_M, _RNG_K, _RNG_P, [("ground", 0), ("ground", 2)], beta_ratio=[0.0, 1.0],
        damping=_RAYLEIGH,
    )  # fmt: skip
    beta = damped.motion_bound(one, _AT_BOUND_R) * (1.0 + 5e-10)
    return one, two, beta


def test_every_contact_creeping_settles_by_the_stuck_structure():
    """The stuck structure's rule (docs/contacts.md 4) when every contact with friction
    creeps: from rest the contact's stuck offset slips at every force peak, one way,
    by amounts shrinking as 1 / n^2, with the stuck structure's force bound within
    (1 + 1e-3) beta from cycle 17 on. Waiting for cycles without events never settled
    it (not_converged at the 2000-cycle budget); now no motion, ``asymptotic``, as the
    one-contact kernel labels the scene without the partner, and as the energy
    argument says above the bound; the frictionless partner continuous. The scipy
    reference from rest creeps the same way (one way, shrinking), and from the held
    start it is no motion."""
    one, two, beta = _at_bound()
    res = classify(two, _AT_BOUND_R, beta, initial_condition="rest")
    kern = classify(one, _AT_BOUND_R, beta, initial_condition="rest")
    assert np.all(res.converged) and np.all(res.asymptotic)
    assert np.all(kern.regime == regimes.NO_MOTION)
    np.testing.assert_array_equal(res.regime[:, 1], kern.regime)
    assert np.all(res.regime[:, 0] == regimes.CONTINUOUS)
    assert np.all(res.cycles < 200)
    r, b = float(_AT_BOUND_R[0]), float(beta[0])
    regime, _, ok = ref.reference_point(two, r, b, max_cycles=20)
    assert ok and regime[1] == regimes.NO_MOTION
    sys_ = ref._System(two, r, b)
    n = sys_.n
    y = np.zeros(2 * n)
    stuck, signs = sys_.decide(0.0, y[:n], y[n:], [1], {0: 0.0})
    signs = {c: signs.get(c, 0.0) for c in range(2)}
    drift = []
    for _ in range(60):
        stats = [{"stuck": 0.0, "sticks": 0} for _ in range(2)]
        y1, stuck, signs = ref._cycle(sys_, y.copy(), tuple(stuck), dict(signs), stats)
        drift.append((sys_.B.T @ (y1[:n] - y[:n]))[1])
        y = y1
    late = np.array(drift[25:])
    assert np.all(late > 0.0) or np.all(late < 0.0)  # one way: no periodic orbit
    assert abs(late[-10:]).mean() < 0.5 * abs(late[:10]).mean()  # shrinking


def test_the_recorded_orbit_is_the_accepted_one():
    """``steady.record_orbit`` of a point the creep rule settled with its contact held
    (the first point above) records the period the rule accepted: the contact stuck
    throughout. It replayed the period with the contact released, where it slips
    (1.2e-6 in that period: the stuck structure's bound exceeds beta slightly)."""
    _, two, beta = _at_bound()
    st = settings_args(resolve("balanced"), regimes.IC_REST)
    args = stuck_sets_cached(two).kernel_args()
    og, oc, rec, rows = steady.record_orbit(float(_AT_BOUND_R[0]), float(beta[0]), args, st, 400)
    assert og[layout.OG_CONVERGED] == 1.0 and oc[1, layout.OC_REGIME] == regimes.NO_MOTION
    assert rows >= 2 and np.all(rec[:rows, 1].astype(int) == 2)
