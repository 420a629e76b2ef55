"""Several contacts (tasks.multicontact, docs/contacts.md) against independent truths.

* a contact that never slides equals the structure with that DOF held (row and
  column removed, or the pair merged), classified by the single-contact kernel;
* a contact with beta_ratio 0 equals the scene without it (single-contact kernel);
  both identities to 1e-9 in slip amplitude, dissipation and force amplitude;
* two identical contacts on a mirror-symmetric structure give mirror-equal results;
* the energy balance per period: the load's work (Gauss quadrature of the motion
  propagated by the reference's matrix exponential from each recorded phase
  start) equals the contacts' dissipation, and each recorded phase ends where
  the next begins;
* the scene constructors and their errors.

Scenes are random (seeded) full M and K that no one tuned the code on.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import eigh, expm

from tasks import Scene, classify, regimes
from tasks.classifier import settings_args
from tasks.fidelity import resolve
from tasks.multicontact import MultiScene, classify_multi, combined_label, steady
from tasks.multicontact import reference as ref
from tasks.multicontact.classify import run_raw, stuck_sets_cached
from tasks.multicontact.layout import OC_REGIME, OG_CONVERGED, OG_CYCLES, OG_IC


def random_structure(seed: int, n: int):
    """Random symmetric positive definite M (full) and K, and a random load."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    M = np.eye(n) + 0.2 * (A @ A.T) / n
    C = rng.normal(size=(n, n))
    K = C @ C.T + n * np.eye(n)
    p = rng.normal(size=n)
    return M, K, p


def points(seed: int, count: int, scene_k: np.ndarray, scene_m: np.ndarray):
    """Random (r, beta) around the structure's first natural frequencies."""
    rng = np.random.default_rng(seed)
    w1 = math.sqrt(eigh(scene_k, scene_m, eigvals_only=True).min())
    r = w1 * rng.uniform(0.3, 2.5, count)
    beta = rng.uniform(0.02, 1.2, count)
    return r, beta


#: The identities hold to this (relative; absolute 1e-12 for amplitudes next to 0):
#: the converged orbit is polished to a residual of 1e-14 (tasks.multicontact.steady).
IDENTITY_RTOL = 1e-9
IDENTITY_ATOL = 1e-12
#: The single-contact kernel's orbit is as accurate as its section_rtol: tightened so
#: that the comparison measures the several-contact simulator, not the kernel's tolerance.
KERNEL_TIGHT = {"section_rtol": 1e-13, "design": True}  # force and dissipation compared


def identity_scene(name: str):
    """``(M, K, p, contacts)`` of a seeded scene no one tuned the code on: random full
    M and K with 2, 3, 4 DOF (walls, a contact between DOFs) and a random chain."""
    rng = np.random.default_rng(7000 + sum(map(ord, name)))
    if name == "chain3":
        chain = MultiScene.chain(
            ["ground", "mass"],
            3,
            [1, 2],
            gamma=list(rng.uniform(0.5, 2.0, 2)),
            kappa=list(rng.uniform(0.5, 2.0, 2)),
        )
        kw = chain.structures[0].kwargs()
        return kw["mass"], kw["stiffness"], kw["load"], list(chain.contacts)
    n, contacts = {
        "random2": (2, [("ground", 0), ("ground", 1)]),
        "random3": (3, [("ground", 0), ("between", 1, 2)]),
        "random4": (4, [("between", 0, 1), ("ground", 3)]),
    }[name]
    return (*ref.random_structure(rng, n), contacts)


IDENTITY_SCENES = ["random2", "random3", "random4", "chain3"]


def _assert_same(multi, c, single):
    both = multi.converged & single.converged
    assert both.mean() > 0.9
    np.testing.assert_array_equal(multi.regime[both, c], single.regime[both])
    for name in ("slip_amplitude", "dissipation", "contact_force_amplitude"):
        np.testing.assert_allclose(
            getattr(multi, name)[both, c],
            getattr(single, name)[both],
            rtol=IDENTITY_RTOL,
            atol=IDENTITY_ATOL,
            err_msg=name,
        )


@pytest.mark.parametrize("name", IDENTITY_SCENES)
def test_a_contact_without_friction_is_the_scene_without_it(name):
    M, K, p, contacts = identity_scene(name)
    r, beta = points(len(name), 10, K, M)
    for c in range(2):
        ratio = [0.0, 0.0]
        ratio[c] = 1.0
        multi = classify_multi(
            MultiScene.from_matrices(M, K, p, contacts, beta_ratio=ratio), r, beta, "exact"
        )
        single = classify(
            Scene.from_matrices(M, K, p, contacts[c]), r, beta, "exact", **KERNEL_TIGHT
        )
        _assert_same(multi, c, single)
        assert np.all(multi.regime[multi.converged, 1 - c] == regimes.CONTINUOUS)


@pytest.mark.parametrize("name", IDENTITY_SCENES)
def test_a_contact_that_never_slides_is_the_held_structure(name):
    """Contact 1 with beta_ratio 1e5 (never slides here) against the structure with
    it held, written out by hand (row and column removed, or the pair merged)."""
    M, K, p, contacts = identity_scene(name)
    r, beta = points(len(name) + 1, 10, K, M)
    multi = classify_multi(
        MultiScene.from_matrices(M, K, p, contacts, beta_ratio=[1.0, 1e5]), r, beta, "exact"
    )
    Mh, Kh, ph, index = ref.held_structure(M, K, p, contacts[1])
    free = (contacts[0][0], *(int(index[i]) for i in contacts[0][1:]))
    held = classify(Scene.from_matrices(Mh, Kh, ph, free), r, beta, "exact", **KERNEL_TIGHT)
    _assert_same(multi, 0, held)
    assert np.all(multi.regime[multi.converged, 1] == regimes.NO_MOTION)


@pytest.mark.parametrize("load", [[1.0, 1.0], [1.0, -1.0]])
def test_identical_contacts_on_a_symmetric_structure_are_mirror_equal(load):
    # two masses between two walls, joined by a spring; a ground contact on each
    M = np.diag([1.3, 1.3])
    K = np.array([[1.7, -0.6], [-0.6, 1.7]])
    scene = MultiScene.from_matrices(M, K, load, [("ground", 0), ("ground", 1)])
    rng = np.random.default_rng(3)
    r = rng.uniform(0.3, 2.0, 40)
    beta = rng.uniform(0.05, 1.5, 40)
    res = classify_multi(scene, r, beta, "exact")
    ok = res.converged
    assert ok.mean() > 0.9
    np.testing.assert_array_equal(res.regime[ok, 0], res.regime[ok, 1])
    for name in ("slip_amplitude", "dissipation", "stick_fraction", "contact_force_amplitude"):
        v = getattr(res, name)[ok]
        np.testing.assert_allclose(v[:, 0], v[:, 1], rtol=1e-9, atol=1e-12, err_msg=name)
    # and the mirror image of the scene (contacts listed the other way) gives the same
    swapped = MultiScene.from_matrices(M, K, load[::-1], [("ground", 1), ("ground", 0)])
    res2 = classify_multi(swapped, r, beta, "exact")
    np.testing.assert_array_equal(res2.regime, res.regime)


def _work_and_dissipation(scene, r, beta):
    """The load's work over the recorded period by Gauss-Legendre quadrature of the
    motion propagated exactly (matrix exponential) from each phase start, the
    largest mismatch between a propagated phase end and the next phase start, and
    the simulator's dissipation."""
    st = settings_args(resolve("exact"))
    args = stuck_sets_cached(scene).kernel_args()
    og, oc, rec, rows = steady.record_orbit(r, beta, args, st, 400)
    assert og[0] == 1.0 and rows < 400
    sys = ref._System(scene, r, beta)
    n, k = sys.n, sys.k
    nodes, weights = np.polynomial.legendre.leggauss(40)
    work = 0.0
    mismatch = 0.0
    for i in range(rows - 1):
        tau0, tau1 = rec[i, 0], rec[i + 1, 0]
        if tau1 <= tau0:
            continue  # the end of one cycle and the start of the next
        stuck = tuple(c for c in range(k) if int(rec[i, 1]) >> c & 1)
        signs = {c: rec[i, 2 + c] for c in range(k)}
        A, _, _, _ = ref._operator(sys, stuck, signs)
        z0 = np.concatenate([rec[i, 2 + k :], [math.cos(tau0), math.sin(tau0), 1.0]])
        half = 0.5 * (tau1 - tau0)
        for u, w in zip(nodes, weights, strict=True):
            t = half * (u + 1.0)
            z = expm(A * t) @ z0
            work += w * half * math.cos(tau0 + t) * (sys.p @ z[n : 2 * n])
        z1 = expm(A * (tau1 - tau0)) @ z0
        scale = 1.0 + np.abs(rec[i + 1, 2 + k :]).max()
        mismatch = max(mismatch, np.abs(z1[: 2 * n] - rec[i + 1, 2 + k :]).max() / scale)
    period = og[2]
    return work / period, oc[:, 4].sum(), mismatch


@pytest.mark.parametrize("seed", [31, 32, 33])
def test_energy_balance_per_period(seed):
    M, K, p = random_structure(seed, 3)
    scene = MultiScene.from_matrices(
        M, K, p, [("ground", 0), ("between", 1, 2)], beta_ratio=[1.0, 0.6]
    )
    rng = np.random.default_rng(seed)
    w1 = math.sqrt(np.linalg.eigvalsh(np.linalg.solve(M, K)).min())
    checked = 0
    for _ in range(6):
        r, beta = w1 * rng.uniform(0.4, 2.0), rng.uniform(0.05, 0.8)
        work, dissipation, mismatch = _work_and_dissipation(scene, r, beta)
        assert mismatch < 1e-9
        if dissipation > 0.0:
            checked += 1
        assert abs(work - dissipation) <= 1e-9 * max(dissipation, 1.0), (r, beta)
    assert checked >= 3


def test_combined_label_encoding():
    reg = np.array([[0, 0], [1, 0], [2, 2], [2, -1], [0, -3]])
    np.testing.assert_array_equal(combined_label(reg), [0, 1, 8, -1, -3])


def test_constructors_and_errors():
    M, K, p = random_structure(5, 3)
    scene = Scene.from_matrices(M, K, p, [("ground", 0), ("between", 1, 2)], beta_ratio=[1, 0.5])
    assert isinstance(scene, MultiScene) and scene.n_contacts == 2
    assert scene.beta_ratio == (1.0, 0.5)
    chain = Scene("ground", 2, contact_mass=[1, 2])
    assert isinstance(chain, MultiScene) and chain.contacts == (("ground", 0), ("ground", 1))
    mixed = Scene(["ground", "mass"], 3, contact_mass=[1, 2])
    assert mixed.contacts == (("ground", 0), ("between", 1, 2))
    assert isinstance(Scene("ground", 2, 1), Scene)  # one contact: unchanged
    with pytest.raises(ValueError, match="^beta_ratio: expected one number per contact"):
        MultiScene.from_matrices(M, K, p, [("ground", 0), ("ground", 1)], beta_ratio=[1.0])
    with pytest.raises(ValueError, match="^beta_ratio: every entry must be finite and >= 0"):
        MultiScene.from_matrices(M, K, p, [("ground", 0), ("ground", 1)], beta_ratio=[1, -1])
    with pytest.raises(ValueError, match="^contact: the contact directions must be linearly"):
        MultiScene.from_matrices(
            M, K, p, [("ground", 0), ("ground", 1), ("between", 0, 1)], beta_ratio=[1, 1, 1]
        )
    with pytest.raises(ValueError, match="^contact: DOF index 5"):
        MultiScene.from_matrices(M, K, p, [("ground", 0), ("ground", 5)])
    with pytest.raises(ValueError, match="^damping: modal damping ratios must be finite"):
        MultiScene.from_matrices(M, K, p, [("ground", 0), ("ground", 1)], damping=("modal", -0.1))
    with pytest.raises(ValueError, match="^contact: walls of one chain"):
        Scene(["ground", "base"], 2, contact_mass=[1, 2])
    res = classify(chain, [0.8, 1.5], 0.4)  # tasks.classify dispatches
    assert res.regime.shape == (2, 2) and res.combined.shape == (2,)


def test_held_rest_and_random_starts_reach_the_same_regimes():
    """One regime per point (docs/theory.md 3, the sum over contacts of docs/contacts.md 4):
    the monotonicity of friction makes coexisting periodic motions share their
    stick and slip intervals, so the start cannot change a contact's regime."""
    M, K, p = random_structure(41, 3)
    scene = MultiScene.from_matrices(
        M, K, p, [("ground", 0), ("between", 1, 2)], beta_ratio=[1.0, 0.6]
    )
    r, beta = points(41, 60, K, M)
    res = classify_multi(scene, r, beta, starts=("held", "rest"), n_random=2)
    both = res.converged & np.all(res.regime_rest >= 0, axis=-1)
    assert both.mean() > 0.9
    np.testing.assert_array_equal(res.regime[both], res.regime_rest[both])
    assert not res.start_dependent.any()
    # a random start is a start of its own (seeded), and reaches the same regimes
    st = settings_args(resolve("balanced", seed=5), regimes.IC_RANDOM + 1)
    out_g, out_c = run_raw(scene, r, beta, st)
    np.testing.assert_array_equal(out_g[:, OG_IC], regimes.IC_RANDOM + 1)
    again = run_raw(scene, r, beta, st)[0]
    np.testing.assert_array_equal(out_g, again)
    ok = (out_g[:, OG_CONVERGED] == 1.0) & res.converged
    assert ok.mean() > 0.9
    assert np.any(out_g[ok, OG_CYCLES] != res.cycles[ok])  # not the held run again
    np.testing.assert_array_equal(out_c[ok, :, OC_REGIME], res.regime[ok])
