"""Several contacts with viscous damping (docs/contacts.md 7) against independent truths.

* (a) a scene of several contacts with ONE contact and damping is the single-contact
  damped kernel (regimes, slip amplitude, dissipations), and so is a damped pair whose
  partner has no friction;
* (b) zero damping is the undamped simulator bit for bit, and a vanishing Rayleigh
  damping tends to it;
* (c) the energy balance per period: the load's work equals the contacts' friction
  dissipation plus the viscous dissipation, both integrated by Gauss quadrature of
  the motion propagated by the reference's matrix exponential (damping included)
  from every recorded phase start; the viscous part equals ``dissipation_viscous``;
* (d) the damped scipy reference (:mod:`tasks.multicontact.reference`) on scattered
  points: same regimes, slip amplitudes to 1e-6;
* (e) a contact that never slides (beta_ratio 1e5) is the damped structure held
  there, written out by hand, classified by the single-contact kernel;
* modal ratios and a general C, which couple the stuck sets' modes (their damped
  pairs): one contact is the kernel's pairs path, and (c) and (d) hold;
* one steady state from every start (damping makes it unique);
* the damping a scene of several contacts refuses, one line naming ``damping``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm

from tasks import Scene, classify, regimes
from tasks.classifier import settings_args
from tasks.fidelity import resolve
from tasks.multicontact import MultiScene, classify_multi, steady
from tasks.multicontact import reference as ref
from tasks.multicontact.classify import stuck_sets_cached
from tasks.multicontact.layout import OG_VISCOUS

RAYLEIGH = ("rayleigh", 0.04, 0.015)
IDENTITY_RTOL = 1e-9
IDENTITY_ATOL = 1e-12
KERNEL_TIGHT = {"section_rtol": 1e-13, "design": True}


def structure(seed: int, n: int):
    """Seeded full M, K and load no one tuned the code on (the reference's draw)."""
    return ref.random_structure(np.random.default_rng(seed), n)


def grid(M, K, count_r: int, betas) -> tuple[np.ndarray, np.ndarray]:
    """A grid of r around the first natural frequencies times the given betas."""
    w1 = math.sqrt(np.linalg.eigvalsh(np.linalg.solve(M, K)).min())
    r, beta = np.meshgrid(w1 * np.linspace(0.4, 2.2, count_r), betas)
    return r.ravel(), beta.ravel()


def _assert_same(multi, c, single, fields=("slip_amplitude", "dissipation")):
    both = multi.converged & single.converged
    assert both.mean() > 0.9
    np.testing.assert_array_equal(multi.regime[both, c], single.regime[both])
    for name in fields:
        np.testing.assert_allclose(
            getattr(multi, name)[both, c],
            getattr(single, name)[both],
            rtol=IDENTITY_RTOL,
            atol=IDENTITY_ATOL,
            err_msg=name,
        )
    return both


@pytest.mark.parametrize(("n", "contact"), [(2, ("ground", 1)), (3, ("between", 0, 2))])
def test_one_damped_contact_is_the_damped_kernel(n, contact):
    """(a) One contact: the several-contact simulator against the kernel's damped path,
    on a grid that crosses stick-slip, continuous and no motion."""
    M, K, p = structure(100 + n, n)
    r, beta = grid(M, K, 6, [0.05, 0.2, 0.5, 1.0])
    multi = classify_multi(
        MultiScene.from_matrices(M, K, p, [contact], damping=RAYLEIGH), r, beta, "exact"
    )
    single = classify(
        Scene.from_matrices(M, K, p, contact, damping=RAYLEIGH), r, beta, "exact", **KERNEL_TIGHT
    )
    both = _assert_same(multi, 0, single)
    seen = set(single.regime[both].tolist())
    assert {regimes.STICK_SLIP, regimes.CONTINUOUS} <= seen, seen
    np.testing.assert_allclose(
        multi.dissipation_viscous[both], single.dissipation_viscous[both], rtol=1e-9, atol=1e-12
    )
    assert np.all(multi.dissipation_viscous[both] > 0.0)


def test_a_damped_partner_without_friction_is_the_damped_scene_without_it():
    """(a) Two contacts, the second frictionless: the single damped contact alone."""
    M, K, p = structure(207, 3)
    contacts = [("ground", 0), ("between", 1, 2)]
    r, beta = grid(M, K, 5, [0.1, 0.4, 0.9])
    multi = classify_multi(
        MultiScene.from_matrices(M, K, p, contacts, beta_ratio=[1.0, 0.0], damping=RAYLEIGH),
        r,
        beta,
        "exact",
    )
    single = classify(
        Scene.from_matrices(M, K, p, contacts[0], damping=RAYLEIGH),
        r,
        beta,
        "exact",
        **KERNEL_TIGHT,
    )
    both = _assert_same(multi, 0, single)
    assert np.all(multi.regime[both, 1] == regimes.CONTINUOUS)
    np.testing.assert_allclose(
        multi.dissipation_viscous[both], single.dissipation_viscous[both], rtol=1e-9, atol=1e-12
    )


def test_zero_damping_is_the_undamped_simulator():
    """(b) ``("rayleigh", 0, 0)`` is no damping: identical arrays; a Rayleigh damping of
    1e-10 runs the damped path and lands on the undamped results."""
    M, K, p = structure(301, 3)
    contacts = [("ground", 0), ("between", 1, 2)]
    r, beta = grid(M, K, 5, [0.1, 0.4, 0.9])
    undamped = classify_multi(
        MultiScene.from_matrices(M, K, p, contacts, beta_ratio=[1.0, 0.6]), r, beta, "exact"
    )
    zero = MultiScene.from_matrices(
        M, K, p, contacts, beta_ratio=[1.0, 0.6], damping=("rayleigh", 0.0, 0.0)
    )
    assert not zero.damped
    same = classify_multi(zero, r, beta, "exact")
    for name, value in undamped.as_dict().items():
        np.testing.assert_array_equal(getattr(same, name), value, err_msg=name)
    assert np.all(undamped.dissipation_viscous[undamped.converged] == 0.0)
    tiny = MultiScene.from_matrices(
        M, K, p, contacts, beta_ratio=[1.0, 0.6], damping=("rayleigh", 1e-10, 1e-10)
    )
    assert tiny.damped
    near = classify_multi(tiny, r, beta, "exact")
    both = near.converged & undamped.converged
    assert both.mean() > 0.9
    np.testing.assert_array_equal(near.regime[both], undamped.regime[both])
    for name in ("slip_amplitude", "dissipation"):
        np.testing.assert_allclose(
            getattr(near, name)[both], getattr(undamped, name)[both], rtol=1e-6, atol=1e-9
        )
    assert np.all(near.dissipation_viscous[both] < 1e-7)


def _balance(scene, r, beta):
    """``(load work, friction, viscous quadrature, simulator's viscous, mismatch)`` per
    excitation cycle of the recorded steady period: Gauss-Legendre quadrature (40 nodes
    per phase) of the motion propagated exactly from every recorded phase start by the
    reference's state-space matrix (damping and Lagrange multipliers included)."""
    st = settings_args(resolve("exact"))
    args = stuck_sets_cached(scene).kernel_args()
    og, oc, rec, rows = steady.record_orbit(r, beta, args, st, 400)
    assert og[0] == 1.0 and rows < 400
    sys = ref._System(scene, r, beta)
    n, k = sys.n, sys.k
    nodes, weights = np.polynomial.legendre.leggauss(40)
    work = viscous = mismatch = 0.0
    for i in range(rows - 1):
        tau0, tau1 = rec[i, 0], rec[i + 1, 0]
        if tau1 <= tau0:
            continue
        stuck = tuple(c for c in range(k) if int(rec[i, 1]) >> c & 1)
        signs = {c: rec[i, 2 + c] for c in range(k)}
        A, _, _, _ = ref._operator(sys, stuck, signs)
        z0 = np.concatenate([rec[i, 2 + k :], [math.cos(tau0), math.sin(tau0), 1.0]])
        pieces = max(1, int(math.ceil((tau1 - tau0) / 0.5)))
        edges = np.linspace(0.0, tau1 - tau0, pieces + 1)
        for a, b in zip(edges[:-1], edges[1:], strict=True):
            half = 0.5 * (b - a)
            for u, w in zip(nodes, weights, strict=True):
                t = a + half * (u + 1.0)
                xd = (expm(A * t) @ z0)[n : 2 * n]
                work += w * half * math.cos(tau0 + t) * (sys.p @ xd)
                viscous += w * half * (xd @ sys.rC @ xd)
        z1 = expm(A * (tau1 - tau0)) @ z0
        scale = 1.0 + np.abs(rec[i + 1, 2 + k :]).max()
        mismatch = max(mismatch, np.abs(z1[: 2 * n] - rec[i + 1, 2 + k :]).max() / scale)
    period = og[2]
    return work / period, oc[:, 4].sum(), viscous / period, og[OG_VISCOUS], mismatch


@pytest.mark.parametrize("seed", [41, 42])
def test_energy_balance_with_damping(seed):
    """(c) Load's work = friction + viscous dissipation per cycle, to 1e-9."""
    M, K, p = structure(seed, 3)
    scene = MultiScene.from_matrices(
        M, K, p, [("ground", 0), ("between", 1, 2)], beta_ratio=[1.0, 0.6], damping=RAYLEIGH
    )
    rng = np.random.default_rng(seed)
    w1 = math.sqrt(np.linalg.eigvalsh(np.linalg.solve(M, K)).min())
    slipping = 0
    for _ in range(5):
        r, beta = w1 * rng.uniform(0.4, 2.0), rng.uniform(0.05, 0.6)
        work, friction, viscous, simulated, mismatch = _balance(scene, r, beta)
        assert mismatch < 1e-9
        assert viscous > 0.0
        slipping += friction > 0.0
        assert abs(simulated - viscous) <= 1e-9 * max(viscous, 1e-3), (r, beta)
        assert abs(work - friction - viscous) <= 1e-9 * max(work, 1e-3), (r, beta)
    assert slipping >= 3


def test_damped_reference_agrees():
    """(d) The damped scipy reference on scattered points of two scenes: same regimes,
    slip amplitudes to 1e-6 of the larger of the amplitude and the static deflection."""
    rng = np.random.default_rng(2027)
    M, K, p = structure(501, 3)
    scenes = [
        MultiScene.from_matrices(
            M, K, p, [("ground", 0), ("between", 1, 2)], beta_ratio=[1.0, 0.7], damping=RAYLEIGH
        ),
        MultiScene.chain(
            "ground", 3, [1, 3], gamma=[0.8, 1.3], kappa=[1.2, 0.7], beta_ratio=[1.0, 0.5]
        ),
    ]
    kw = scenes[1].structures[0].kwargs()
    scenes[1] = MultiScene.from_matrices(
        kw["mass"],
        kw["stiffness"],
        kw["load"],
        list(scenes[1].contacts),
        beta_ratio=[1.0, 0.5],
        damping=("rayleigh", 0.08, 0.01),
    )
    compared = 0
    kinds = set()
    for scene in scenes:
        G, Kg = scene.mass_matrix(1.0), scene.stiffness_matrix()
        w1 = math.sqrt(np.linalg.eigvalsh(np.linalg.solve(G, Kg)).min())
        r = w1 * rng.uniform(0.3, 2.3, 6)
        beta = rng.uniform(0.03, 1.0, 6)
        res = classify_multi(scene, r, beta, "exact")
        static = np.abs(np.linalg.solve(Kg, scene.load_vector(1.0))).max()
        for i in range(r.size):
            regime, amp, ok = ref.reference_point(scene, float(r[i]), float(beta[i]), 400)
            if not (ok and res.converged[i]):
                continue
            compared += 1
            np.testing.assert_array_equal(res.regime[i], regime, err_msg=f"{r[i]}, {beta[i]}")
            kinds |= set(regime.tolist())
            scale = np.maximum(amp, 0.1 * static)
            assert np.all(np.abs(res.slip_amplitude[i] - amp) <= 1e-6 * scale), (r[i], beta[i])
    assert compared >= 10
    assert len(kinds) >= 2, kinds


@pytest.mark.parametrize(
    "contacts", [[("ground", 0), ("between", 1, 2)], [("ground", 2), ("ground", 0)]]
)
def test_a_damped_contact_that_never_slides_is_the_damped_held_structure(contacts):
    """(e) beta_ratio 1e5 on contact 1: the structure with it held (row and column
    removed, or the pair merged; Rayleigh damping of the held M and K) and damped."""
    M, K, p = structure(600 + len(contacts[1]), 3)
    r, beta = grid(M, K, 5, [0.05, 0.3, 0.8])
    multi = classify_multi(
        MultiScene.from_matrices(M, K, p, contacts, beta_ratio=[1.0, 1e5], damping=RAYLEIGH),
        r,
        beta,
        "exact",
    )
    Mh, Kh, ph, index = ref.held_structure(M, K, p, contacts[1])
    free = (contacts[0][0], *(int(index[i]) for i in contacts[0][1:]))
    held = classify(
        Scene.from_matrices(Mh, Kh, ph, free, damping=RAYLEIGH), r, beta, "exact", **KERNEL_TIGHT
    )
    both = _assert_same(multi, 0, held)
    assert np.all(multi.regime[both, 1] == regimes.NO_MOTION)
    np.testing.assert_allclose(
        multi.dissipation_viscous[both], held.dissipation_viscous[both], rtol=1e-9, atol=1e-12
    )


def test_damping_refused_with_several_contacts_names_the_field():
    """Bad damping: one line naming ``damping``; modal ratios and a general C that
    couple a stuck set's modes are taken (the set's damped pairs)."""
    M, K, p = structure(700, 3)
    contacts = [("ground", 0), ("between", 1, 2)]
    for bad, message in [
        (("modal", -0.05), "^damping: modal damping ratios must be finite and >= 0"),
        (("rayleigh", -0.1, 0.0), "^damping: Rayleigh coefficients must be finite and >= 0"),
        (("viscous", 0.1), "^damping: expected a matrix"),
        (-np.eye(3), "^damping: must be positive semidefinite"),
    ]:
        with pytest.raises(ValueError, match=message):
            MultiScene.from_matrices(M, K, p, contacts, damping=bad)
    # Rayleigh given as its full matrix is proportional, and the same scene
    a, b = RAYLEIGH[1:]
    full = MultiScene.from_matrices(M, K, p, contacts, damping=a * M + b * K)
    coeffs = MultiScene.from_matrices(M, K, p, contacts, damping=RAYLEIGH)
    assert full.damped and coeffs.damped
    np.testing.assert_allclose(full.damping_matrix(1.3), coeffs.damping_matrix(1.3), rtol=1e-15)
    again = MultiScene.from_dict(coeffs.to_dict())
    assert again == coeffs
    for coupling in (("modal", 0.05), np.diag([0.1, 0.0, 0.0])):
        scene = MultiScene.from_matrices(M, K, p, contacts, damping=coupling)
        assert scene.damped and stuck_sets_cached(scene).general.any()


def test_damped_starts_reach_one_steady_state():
    """With C definite the steady state is unique (docs/structures.md 4.6): held, rest
    and two seeded random starts reach the same regimes and slip amplitudes."""
    M, K, p = structure(800, 3)
    scene = MultiScene.from_matrices(
        M, K, p, [("ground", 0), ("between", 1, 2)], beta_ratio=[1.0, 0.6], damping=RAYLEIGH
    )
    r, beta = grid(M, K, 5, [0.05, 0.3, 0.8])
    res = classify_multi(scene, r, beta, "exact", starts=("held", "rest"), n_random=2)
    both = res.converged & np.all(res.regime_rest >= 0, axis=-1)
    assert both.mean() > 0.9
    np.testing.assert_array_equal(res.regime[both], res.regime_rest[both])
    assert not res.start_dependent.any()
    rest = classify_multi(scene, r, beta, "exact", initial_condition="rest")
    ok = res.converged & rest.converged
    np.testing.assert_allclose(
        rest.slip_amplitude[ok], res.slip_amplitude[ok], rtol=1e-7, atol=1e-10
    )
    np.testing.assert_allclose(
        rest.dissipation_viscous[ok], res.dissipation_viscous[ok], rtol=1e-7, atol=1e-10
    )


#: A general (non-proportional) C on the random 3 DOF structures: a dashpot between
#: DOFs 0 and 1 and one to ground at DOF 2 (docs/structures.md 4.5 per stuck set).
GENERAL = np.array([[0.12, -0.12, 0.0], [-0.12, 0.12, 0.0], [0.0, 0.0, 0.05]])


def test_general_damping_one_contact_is_the_kernels_pairs():
    """(a) with a C that couples the modes: the kernel's damped pairs (one contact)."""
    M, K, p = structure(901, 3)
    r, beta = grid(M, K, 6, [0.05, 0.3, 0.9])
    multi = classify_multi(
        MultiScene.from_matrices(M, K, p, [("ground", 2)], damping=GENERAL), r, beta, "exact"
    )
    assert stuck_sets_cached(
        MultiScene.from_matrices(M, K, p, [("ground", 2)], damping=GENERAL)
    ).general.all()
    single = classify(
        Scene.from_matrices(M, K, p, ("ground", 2), damping=GENERAL),
        r,
        beta,
        "exact",
        **KERNEL_TIGHT,
    )
    both = _assert_same(multi, 0, single)
    assert {regimes.STICK_SLIP, regimes.CONTINUOUS} <= set(single.regime[both].tolist())
    np.testing.assert_allclose(
        multi.dissipation_viscous[both], single.dissipation_viscous[both], rtol=1e-9, atol=1e-12
    )


@pytest.mark.parametrize("damping", [GENERAL, ("modal", 0.03)], ids=["matrix", "modal"])
def test_general_damping_energy_and_reference(damping):
    """(c) and (d) with a C that couples the modes of the stuck sets: the energy balance
    per period to 1e-9 and the damped scipy reference (regimes, slip amplitudes)."""
    M, K, p = structure(902, 3)
    scene = MultiScene.from_matrices(
        M, K, p, [("ground", 0), ("between", 1, 2)], beta_ratio=[1.0, 0.6], damping=damping
    )
    assert stuck_sets_cached(scene).general.any()
    rng = np.random.default_rng(903)
    w1 = math.sqrt(np.linalg.eigvalsh(np.linalg.solve(M, K)).min())
    r = w1 * rng.uniform(0.4, 2.0, 5)
    beta = rng.uniform(0.05, 0.6, 5)
    res = classify_multi(scene, r, beta, "exact")
    static = np.abs(np.linalg.solve(K, scene.load_vector(1.0))).max()
    compared = 0
    for i in range(r.size):
        work, friction, viscous, simulated, mismatch = _balance(scene, r[i], beta[i])
        assert mismatch < 1e-9
        assert abs(simulated - viscous) <= 1e-9 * max(viscous, 1e-3), (r[i], beta[i])
        assert abs(work - friction - viscous) <= 1e-9 * max(work, 1e-3), (r[i], beta[i])
        regime, amp, ok = ref.reference_point(scene, float(r[i]), float(beta[i]), 400)
        if ok and res.converged[i]:
            compared += 1
            np.testing.assert_array_equal(res.regime[i], regime)
            scale = np.maximum(amp, 0.1 * static)
            assert np.all(np.abs(res.slip_amplitude[i] - amp) <= 1e-6 * scale)
    assert compared >= 4
