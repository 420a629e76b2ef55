"""Closed-form regime boundaries (analysis.closed_form) against independent truths.

Independent truths used here: the paper's explicit 2DOF formulas (Eqs. 22-24,
46-47, 55-59, 63, 84-85, 89, 94, 118, 121-123, 128), direct linear solves of the
forced and held systems, per-r eigen-decompositions of (K, M(r)), a brute-force
dense-grid evaluation of Den Hartog's S (Eq. 16), an antisymmetric
continuous-motion solver built from matrix exponentials (no modal algebra) and the
reference data of tests/data (computed by an independent code).
"""

from __future__ import annotations

import itertools
import json
import warnings

import numpy as np
import pytest
from scipy.linalg import eigh, expm, null_space

from analysis import boundaries, predict
from analysis.closed_form import (
    continuous_bound,
    generalised_S,
    held_resonances,
    motion_bound,
    response_functions,
    sliding_resonances,
    slip_velocity,
)
from analysis.modal import contact_modes
from tasks.regimes import CONTINUOUS, NO_MOTION, STICK_SLIP
from tasks.scene import Scene

RNG_SEED = 20210104
PAIRS = [(0.5, 0.5), (0.5, 2.0), (1.0, 1.0), (2.0, 0.5), (1.5, 0.8)]


# --------------------------------------------------------------------------- helpers
def _u(R: np.ndarray) -> np.ndarray:
    """Eq. 48, written exactly as printed."""
    return np.sin(np.pi / R) / (R * (1.0 + np.cos(np.pi / R)))


def paper_2dof(contact: str, j: int, gamma: float, kappa: float, r: np.ndarray):
    """Tables 1-3 from the paper's explicit 2DOF formulas (Table 2 misprint fixed).

    Returns (beta_continuous, beta_motion, misprinted Table 2 bound or None).
    """
    r = np.asarray(r, dtype=float)
    s = gamma + kappa + gamma * kappa
    root = np.sqrt(s * s - 4.0 * gamma * kappa)
    Om = np.array([np.sqrt(s - root), np.sqrt(s + root)])[:, None] / (r * np.sqrt(2.0 * gamma))
    Om = Om.reshape((2, *r.shape))  # Eq. 22
    R = 1.0 / Om  # Eq. 40
    amp = (R / r) ** 2
    v = 1.0 / (1.0 - R**2)  # Eq. 43
    if contact == "mass":
        G = gamma / (1.0 + gamma)  # Eq. 110
        ph = 1.0 / (1.0 - (1.0 + gamma) * Om**2 * r**2)  # Eq. 118
        Vd = np.sum((1.0 + gamma) * ph * r**2 / (1.0 + gamma * ph**2) * amp * v, axis=0)  # 121
        Ud = np.sum(1.0 / (1.0 + gamma * ph**2) * amp * _u(R), axis=0)  # Eq. 122
        cont = G * np.sqrt(Vd**2 / (Ud**2 + 1.0 / r**4))  # Eq. 123
        motion = gamma * r**2 / np.abs(1.0 - (1.0 + gamma) * r**2)  # Eq. 128
        return cont, motion, None
    ph = 1.0 / (1.0 - gamma / kappa * Om**2 * r**2)  # Eq. 24
    norm = 1.0 + gamma * ph**2
    if j == 1:
        V = np.sum(1.0 / norm * amp * v, axis=0)  # Eq. 46
        Vz = np.sum((1.0 + gamma * ph) * r**2 / norm * amp * v, axis=0)  # Eq. 84
        U = np.sum(1.0 / norm * amp * _u(R), axis=0)  # Eq. 55
        m = r**2
    else:
        V = np.sum(ph / norm * amp * v, axis=0)  # Eq. 47
        Vz = np.sum((1.0 + gamma * ph) * ph * r**2 / norm * amp * v, axis=0)  # Eq. 85
        U = np.sum(ph**2 / norm * amp * _u(R), axis=0)  # Eq. 58
        m = gamma * r**2
    if contact == "ground":
        cont = np.sqrt(V**2 / (U**2 + 1.0 / m**2))  # Eqs. 56, 59
        motion = np.ones_like(r) if j == 1 else kappa / np.abs(1.0 + kappa - r**2)  # Eq. 63
        return cont, motion, None
    cont = np.sqrt(Vz**2 / (U**2 + 1.0 / m**2))  # Table 2 with V_z (docs/theory.md 6)
    misprint = np.sqrt(V**2 / (U**2 + 1.0 / m**2))  # Table 2 as printed
    if j == 1:
        motion = np.abs(kappa * (1 + gamma) * r**2 - gamma * r**4) / np.abs(kappa - gamma * r**2)
    else:
        motion = np.abs((gamma + gamma * kappa + kappa) * r**2 - gamma * r**4) / np.abs(
            1 + kappa - r**2
        )  # Eqs. 89, 94
    return cont, motion, misprint


def direct_V_U(scene: Scene, r: float) -> tuple[float, float, float]:
    """V_b by a linear solve; U_b from a fresh eigen-decomposition of (K, M(r)) (Eqs. 40-54)."""
    K = scene.stiffness_matrix()
    M = scene.mass_matrix(r)
    p = scene.load_vector(r)
    b = scene.contact_vector()
    V = b @ np.linalg.solve(K - M, p)
    lam, psi = eigh(K, M)  # psi^T M psi = I, lam = Omega_i^2
    R = 1.0 / np.sqrt(lam)
    U = np.sum((b @ psi) ** 2 * R**2 * np.tan(np.pi / (2 * R)) / R)
    m_b = 1.0 / (b @ np.linalg.solve(M, b))
    return V, U, m_b


def subsystem_motion_bound(scene: Scene, r: float) -> float:
    """Sect. 2.6.3 literally: load on m_j plus spring forces of the lower/upper subsystems."""
    K = scene.stiffness_matrix()
    M = scene.mass_matrix(r)
    p = scene.load_vector(r)
    kap = scene.stiffness_ratios
    j = scene.contact_mass - 1
    force = p[j]
    lower = slice(0, j)
    upper = slice(j + 1, scene.dof)
    if j > 0:  # masses 1..j-1, m_j replaced by a wall
        X = np.linalg.solve((K - M)[lower, lower], p[lower])
        force += kap[j] * X[-1]
    if j + 1 < scene.dof:  # masses j+1..N on the wall m_j
        X = np.linalg.solve((K - M)[upper, upper], p[upper])
        force += kap[j + 1] * X[0]
    return abs(force)


def merged_motion_bound(scene: Scene, r: float) -> float:
    """Mass contact: masses j, j+1 move as one; force the contact carries (Eqs. 103-104)."""
    K = scene.stiffness_matrix()
    gam = scene.mass_ratios
    n, j = scene.dof, scene.contact_mass - 1
    T = np.zeros((n, n - 1))
    col = 0
    for i in range(n):
        T[i, col] = 1.0
        if i != j:
            col += 1
    p = scene.load_vector(r)
    M = scene.mass_matrix(r)
    X = T @ np.linalg.solve(T.T @ (K - M) @ T, T.T @ p)
    # equations of masses j and j+1 with the contact force F on m_(j+1) and -F on m_j:
    # m a = (p - K X)_i +- F with a_j = a_(j+1)
    f = p - K @ X
    F = (gam[j] * f[j + 1] - gam[j + 1] * f[j]) / (gam[j] + gam[j + 1])
    return abs(F)


def antisymmetric_boundary(scene: Scene, r: float, beta_hi: float, n_tau: int = 4000) -> float:
    """Largest beta with a continuous antisymmetric motion, from matrix exponentials.

    State (x, v, cos(tau + phi), sin(tau + phi), beta) of
    M x'' + K x = p cos(tau + phi) + beta b on (0, pi); unknowns x(0), v(0),
    cos phi, sin phi from x(pi) = -x(0), v(pi) = -v(0), b.v(0) = 0 and
    cos^2 + sin^2 = 1 (branch b.x(0) > 0); continuous iff b.v < 0 on (0, pi).
    Bisection on beta. Independent of the modal formulas of docs/theory.md 4.3.
    """
    K = scene.stiffness_matrix()
    M = scene.mass_matrix(r)
    p = scene.load_vector(r)
    b = scene.contact_vector()
    n = scene.dof
    d = 2 * n + 3
    A = np.zeros((d, d))
    A[:n, n : 2 * n] = np.eye(n)
    Minv = np.linalg.inv(M)
    A[n : 2 * n, :n] = -Minv @ K
    A[n : 2 * n, 2 * n] = Minv @ p
    A[n : 2 * n, 2 * n + 2] = Minv @ b
    A[2 * n, 2 * n + 1] = -1.0
    A[2 * n + 1, 2 * n] = 1.0
    taus = np.linspace(0.0, np.pi, n_tau + 1)
    step = expm((taus[1] - taus[0]) * A)
    prop = np.empty((n_tau + 1, d, d))
    prop[0] = np.eye(d)
    for k in range(n_tau):
        prop[k + 1] = step @ prop[k]
    E = prop[-1]
    lhs = np.zeros((2 * n + 1, 2 * n + 2))
    lhs[: 2 * n, : 2 * n] = E[: 2 * n, : 2 * n] + np.eye(2 * n)
    lhs[: 2 * n, 2 * n :] = E[: 2 * n, 2 * n : 2 * n + 2]
    lhs[2 * n, n : 2 * n] = b
    rhs1 = np.zeros(2 * n + 1)
    rhs1[: 2 * n] = -E[: 2 * n, 2 * n + 2]
    u1 = np.linalg.lstsq(lhs, rhs1, rcond=None)[0]
    uh = null_space(lhs)[:, 0]

    def continuous(beta: float) -> bool:
        up = beta * u1
        c0, s0, ch, sh = up[2 * n], up[2 * n + 1], uh[2 * n], uh[2 * n + 1]
        roots = np.roots([ch * ch + sh * sh, 2 * (c0 * ch + s0 * sh), c0 * c0 + s0 * s0 - 1.0])
        roots = roots[np.abs(roots.imag) < 1e-12].real
        for t in roots:
            u = up + t * uh
            if b @ u[:n] > 0:
                Y0 = np.concatenate([u, [beta]])
                acc0 = b @ (A @ Y0)[n : 2 * n]  # contact acceleration just after tau = 0
                vel = (prop[1:-1] @ Y0)[:, n : 2 * n] @ b
                return bool(acc0 < 0.0 and np.all(vel < 0.0))
        return False

    lo, hi = 0.0, beta_hi
    assert continuous(1e-9 * beta_hi) and not continuous(hi)
    for _ in range(45):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if continuous(mid) else (lo, mid)
    return 0.5 * (lo + hi)


def eq16_S(r: float, n_tau: int = 400_001) -> float:
    """Den Hartog's S (Eq. 16) by brute force on a dense grid of (0, pi)."""
    tau = np.linspace(0.0, np.pi, n_tau)[1:-1]
    U = np.sin(np.pi / r) / (r * (1.0 + np.cos(np.pi / r)))  # Eq. 15
    f = r * (np.sin(tau / r) + U * r * (np.cos(tau) - np.cos(tau / r))) / np.sin(tau)
    return max(1.0, float(f.max()))


def sdof_beta(r: float, S: float) -> float:
    """Eq. 13 with Eqs. 14-15."""
    V = 1.0 / (1.0 - r * r)
    U = np.sin(np.pi / r) / (r * (1.0 + np.cos(np.pi / r)))
    return float(np.sqrt(V * V / (U * U + (S / r**2) ** 2)))


def all_scenes(dofs=(1, 2, 3, 5, 20), ratios=(1e-6, 1.0, 1e6)):
    for contact, dof, g, k in itertools.product(("ground", "base", "mass"), dofs, ratios, ratios):
        if contact == "mass" and dof < 2:
            continue
        last = dof - 1 if contact == "mass" else dof
        for j in sorted({1, max(1, dof // 2), last}):
            yield Scene(contact, dof, j, gamma=g, kappa=k)


def singular_r(scene: Scene) -> np.ndarray:
    """Extremes, resonances of both systems, Omega_i = 3, 5, 7 and the section-5 points."""
    modes = contact_modes(scene)
    sq = np.sqrt(modes.lam)
    rs = [1e-3, 1e-2, 1 / 3, 1 / 2, 1.0, 10.0, 1e3, *sq, *np.sqrt(modes.lam_s)]
    for n in (3, 5, 7):
        rs += list(sq / n)
    if scene.dof == 2:
        g, k = scene.gammas[1], scene.kappas[1]
        rs += [
            np.sqrt(k / g),
            np.sqrt(k * (1 + g) / g),
            np.sqrt(1 + k),
            np.sqrt((g + g * k + k) / g),
            np.sqrt(1 / (1 + g)),
        ]
    return np.array(rs)


# ---------------------------------------------------------------------- docs/theory.md 5
@pytest.mark.parametrize(("gamma", "kappa"), PAIRS)
def test_ground_m1_antiresonance(gamma, kappa):
    s = Scene("ground", 2, 1, gamma=gamma, kappa=kappa)
    r0 = np.sqrt(kappa / gamma)  # Eq. 57
    V, _, _ = response_functions(s, r0)
    assert abs(V) < 1e-9
    for method in ("paper", "exact"):
        # no motion there (the paper, after Eq. 57): m2 is a tuned absorber and the
        # contact needs no force (docs/theory.md 3); 1e-6 away the bound is 1
        bc, bm = boundaries(s, r0, method)
        assert bc < 1e-9 and bm == 0.0
        assert np.all(predict(s, r0, np.array([1e-6, 0.5, 0.99]), method) == NO_MOTION)
        _, near = boundaries(s, r0 * (1 + np.array([-1e-6, 1e-6])), method)
        np.testing.assert_allclose(near, 1.0, rtol=1e-5)
    # not an antiresonance 1 % away
    assert continuous_bound(s, 1.01 * r0) > 1e-3


@pytest.mark.parametrize(("gamma", "kappa"), PAIRS)
def test_ground_m2_motion_bound(gamma, kappa):
    s = Scene("ground", 2, 2, gamma=gamma, kappa=kappa)
    assert motion_bound(s, 1e-7) == pytest.approx(kappa / (1 + kappa), rel=1e-6)
    assert np.isinf(motion_bound(s, np.sqrt(1 + kappa)))
    assert held_resonances(s) == pytest.approx([np.sqrt(1 + kappa)], rel=1e-12)
    near = motion_bound(s, np.sqrt(1 + kappa) * (1 + np.array([-1e-7, 1e-7])))
    assert np.all(near > 1e6) and np.all(np.isfinite(near))


@pytest.mark.parametrize(("gamma", "kappa"), PAIRS)
def test_base_motion_peaks_and_zeros(gamma, kappa):
    s1 = Scene("base", 2, 1, gamma=gamma, kappa=kappa)
    s2 = Scene("base", 2, 2, gamma=gamma, kappa=kappa)
    assert np.isinf(motion_bound(s1, np.sqrt(kappa / gamma)))
    assert motion_bound(s1, np.sqrt(kappa * (1 + gamma) / gamma)) < 1e-9  # Eq. 90
    assert np.isinf(motion_bound(s2, np.sqrt(1 + kappa)))
    assert motion_bound(s2, np.sqrt((gamma + gamma * kappa + kappa) / gamma)) < 1e-9  # Eq. 95
    assert held_resonances(s1) == pytest.approx([np.sqrt(kappa / gamma)], rel=1e-12)
    assert held_resonances(s2) == pytest.approx([np.sqrt(1 + kappa)], rel=1e-12)


@pytest.mark.parametrize(("gamma", "kappa"), PAIRS)
def test_mass_contact_motion_bound(gamma, kappa):
    s = Scene("mass", 2, 1, gamma=gamma, kappa=kappa)
    assert np.isinf(motion_bound(s, np.sqrt(1 / (1 + gamma))))  # Eq. 129
    assert motion_bound(s, 1e5) == pytest.approx(gamma / (1 + gamma), rel=1e-6)  # Eq. 130
    assert held_resonances(s) == pytest.approx([np.sqrt(1 / (1 + gamma))], rel=1e-12)


def test_5dof_peaks():
    r = np.linspace(0.05, 3.0, 29_501)
    s4 = Scene("ground", 5, 4)
    exact = 2.0 * np.sin(np.arange(1, 4) * np.pi / 8)  # 3-mass fixed-fixed chain
    assert exact == pytest.approx([0.7654, 1.4142, 1.8478], abs=5e-5)  # Sect. 2.6.4
    assert held_resonances(s4) == pytest.approx(exact, abs=1e-6)
    assert np.all(np.isinf(motion_bound(s4, exact)) | (motion_bound(s4, exact) > 1e12))
    s2 = Scene("ground", 5, 2)
    assert held_resonances(s2) == pytest.approx([np.sqrt(2.0)], abs=1e-6)
    for s, peaks in ((s4, exact), (s2, [np.sqrt(2.0)])):
        bm = motion_bound(s, r)
        assert np.all(np.isfinite(bm))
        # every large value lies next to a predicted peak, and every peak shows up
        big = r[bm > 1e3]
        assert np.min(np.abs(big[:, None] - np.asarray(peaks)[None, :]), axis=1).max() < 1e-3
        for pk in peaks:
            assert bm[np.argmin(np.abs(r - pk))] > 1e3


def test_motion_bound_independent_of_gamma_or_kappa():
    """docs/theory.md 5 (2DOF): no gamma in the ground bound, no kappa in the mass-contact bound.

    For longer chains this holds for a ground wall on m_1 or m_2 only (the lower
    subsystem is m_1 alone, the upper one is unloaded); on m_j, j >= 3, the lower
    subsystem's masses matter. For a mass contact the bound does not depend on
    the spring in parallel with the contact.
    """
    rng = np.random.default_rng(RNG_SEED)
    r = rng.uniform(0.05, 3.0, 200)
    for dof, j in ((2, 1), (2, 2), (5, 1), (5, 2)):
        ref = motion_bound(Scene("ground", dof, j, gamma=1.0, kappa=0.7), r)
        for g in (0.3, 2.0, tuple(rng.uniform(0.2, 3.0, dof - 1))):
            other = motion_bound(Scene("ground", dof, j, gamma=g, kappa=0.7), r)
            np.testing.assert_allclose(other, ref, rtol=1e-9)
    ref = motion_bound(Scene("ground", 5, 4, gamma=1.0, kappa=0.7), r)
    other = motion_bound(Scene("ground", 5, 4, gamma=(1.0, 2.0, 1.0, 1.0), kappa=0.7), r)
    assert np.max(np.abs(other / ref - 1)) > 0.1
    ref = motion_bound(Scene("mass", 2, 1, gamma=0.8, kappa=1.0), r)
    for k in (0.1, 3.0, 1e3):
        other = motion_bound(Scene("mass", 2, 1, gamma=0.8, kappa=k), r)
        np.testing.assert_allclose(other, ref, rtol=1e-9)
    ref = motion_bound(Scene("mass", 4, 2, gamma=0.8, kappa=(1.0, 1.0, 1.0)), r)
    other = motion_bound(Scene("mass", 4, 2, gamma=0.8, kappa=(1.0, 5.0, 1.0)), r)
    np.testing.assert_allclose(other, ref, rtol=1e-9)


def test_motion_bound_sdof():
    r = np.array([0.1, 0.9, 1.0, 2.5])
    np.testing.assert_array_equal(motion_bound(Scene("ground", 1), r), 1.0)
    np.testing.assert_allclose(motion_bound(Scene("base", 1), r), r**2, rtol=1e-15)


# ---------------------------------------------------------------------- docs/theory.md 6
def test_table2_misprint_example():
    s = Scene("base", 2, 1, gamma=1.0, kappa=1.0)
    bc = continuous_bound(s, 2.5)
    assert bc == pytest.approx(3.147, abs=5e-4)
    cont, _, misprint = paper_2dof("base", 1, 1.0, 1.0, np.array(2.5))
    assert misprint == pytest.approx(0.622, abs=5e-4)
    assert cont == pytest.approx(bc, rel=1e-12)
    assert predict(s, 2.5, 1.88) == CONTINUOUS  # the simulated point of docs/theory.md 6


# ------------------------------------------------------- paper formulas, independently
@pytest.mark.parametrize(
    ("contact", "j"), [("ground", 1), ("ground", 2), ("base", 1), ("base", 2), ("mass", 1)]
)
@pytest.mark.parametrize(("gamma", "kappa"), PAIRS)
def test_paper_equals_explicit_2dof_formulas(contact, j, gamma, kappa):
    rng = np.random.default_rng(RNG_SEED)
    r = rng.uniform(0.05, 3.0, 300)
    cont, motion, _ = paper_2dof(contact, j, gamma, kappa, r)
    bc, bm = boundaries(Scene(contact, 2, j, gamma=gamma, kappa=kappa), r, "paper")
    np.testing.assert_allclose(bc, cont, rtol=1e-9)
    np.testing.assert_allclose(bm, motion, rtol=1e-9)


def test_mass_contact_equivalent_system_quantities():
    """V_d (Eq. 121) equals V_b and U_d (Eq. 122) equals G U_b."""
    gamma, kappa = 0.7, 1.9
    G = gamma / (1 + gamma)
    r = np.random.default_rng(RNG_SEED).uniform(0.1, 2.5, 50)
    s = Scene("mass", 2, 1, gamma=gamma, kappa=kappa)
    V, U, m_b = response_functions(s, r)
    Kd = np.array([[kappa / G + G, -G], [-G, G]])  # Eq. 116
    for i, ri in enumerate(r):
        M = ri**2 * np.diag([1.0, gamma])
        Vd = np.linalg.solve(Kd - M, [0.0, (1 + gamma) * ri**2])[0]  # Eq. 119
        lam, psi = eigh(Kd, M)
        R = 1 / np.sqrt(lam)
        Ud = np.sum(psi[0] ** 2 * R**2 * _u(R))  # Eq. 54
        assert V[i] == pytest.approx(Vd, rel=1e-9)
        assert G * U[i] == pytest.approx(Ud, rel=1e-9)
    np.testing.assert_allclose(m_b, G * r**2, rtol=1e-14)


@pytest.mark.parametrize(
    ("contact", "dof"),
    [(c, n) for c in ("ground", "base", "mass") for n in (1, 2, 3, 5, 8) if (c, n) != ("mass", 1)],
)
def test_generic_against_direct_evaluation(contact, dof):
    rng = np.random.default_rng(RNG_SEED + dof)
    gam = tuple(rng.uniform(0.3, 3.0, dof - 1))
    kap = tuple(rng.uniform(0.3, 3.0, dof - 1))
    last = dof - 1 if contact == "mass" else dof
    for j in range(1, last + 1):
        s = Scene(contact, dof, j, gamma=gam if dof > 1 else 1.0, kappa=kap if dof > 1 else 1.0)
        r = rng.uniform(0.05, 3.0, 25)
        V, U, m_b = response_functions(s, r)
        bc, bm = boundaries(s, r, "paper")
        for i, ri in enumerate(r):
            Vd, Ud, md = direct_V_U(s, ri)
            assert V[i] == pytest.approx(Vd, rel=1e-9)
            assert U[i] == pytest.approx(Ud, rel=1e-9)
            assert m_b[i] == pytest.approx(md, rel=1e-12)
            assert bc[i] == pytest.approx(np.sqrt(Vd**2 / (Ud**2 + 1 / md**2)), rel=1e-9)  # Eq. 53
            held_fn = merged_motion_bound if contact == "mass" else subsystem_motion_bound
            held = held_fn(s, ri)
            assert bm[i] == pytest.approx(held, rel=1e-9, abs=1e-12)


# ------------------------------------------------------------------- exact (MODEL 4.3)
def test_exact_sdof_equals_eq16():
    rs = [0.21, 0.27, 0.3, 0.37, 0.45, 0.55, 0.7, 0.9, 1.3, 2.0, 3.0]
    rs += list(np.random.default_rng(RNG_SEED).uniform(0.2, 3.0, 8))
    s = Scene("ground", 1)
    exact = continuous_bound(s, rs, "exact")
    S = generalised_S(s, rs)
    n_active = 0
    for i, r in enumerate(rs):
        S16 = eq16_S(r)
        n_active += S16 > 1.0
        assert S[i] == pytest.approx(S16, rel=1e-7)
        assert exact[i] == pytest.approx(sdof_beta(r, S16), rel=1e-7)
        # base wall: V = r^2 / (1 - r^2), same U and S (docs/theory.md 2)
        base = continuous_bound(Scene("base", 1), r, "exact")
        assert base == pytest.approx(r**2 * sdof_beta(r, S16), rel=1e-7)
    assert n_active >= 5  # the check (c) is really exercised


@pytest.mark.parametrize(
    ("contact", "dof", "j", "gamma", "kappa", "r"),
    [
        ("ground", 1, 1, 1.0, 1.0, 0.3),
        ("ground", 2, 1, 1.0, 1.0, 0.6),
        ("ground", 2, 2, 0.5, 2.0, 1.05),
        ("base", 2, 1, 1.5, 0.8, 0.7),
        ("base", 2, 2, 1.0, 1.0, 0.5),
        ("mass", 2, 1, 0.8, 1.5, 0.5),
        ("mass", 3, 2, (1.3, 0.7), (0.9, 1.6), 0.8),
        ("ground", 5, 4, 1.0, 1.0, 1.3),
        ("ground", 2, 1, 1.0, 1.0, 1.7),
        ("base", 2, 1, 1.5, 0.8, 0.45),
        ("mass", 2, 1, 0.8, 1.5, 0.62),
        ("ground", 5, 4, 1.0, 1.0, 0.7),
        ("base", 3, 2, (0.7, 1.4), (1.2, 0.6), 0.6),
    ],
)
def test_exact_matches_antisymmetric_solver(contact, dof, j, gamma, kappa, r):
    s = Scene(contact, dof, j, gamma=gamma, kappa=kappa)
    paper = float(continuous_bound(s, r, "paper"))
    exact = float(continuous_bound(s, r, "exact"))
    truth = antisymmetric_boundary(s, r, beta_hi=paper * (1 + 1e-9))
    assert exact == pytest.approx(truth, rel=2e-6)
    S = float(generalised_S(s, r))
    if S > 1.0 + 1e-9:
        assert exact < paper * (1 - 1e-6)
    else:
        assert exact == paper


def test_slip_velocity_matches_matrix_exponential():
    s = Scene("mass", 3, 2, gamma=(1.3, 0.7), kappa=(0.9, 1.6))
    r = 0.8
    beta = 0.5 * float(continuous_bound(s, r, "exact"))
    K, M, p, b = s.stiffness_matrix(), s.mass_matrix(r), s.load_vector(r), s.contact_vector()
    V, U, _ = response_functions(s, r)
    sin_phi = -beta * U / V
    cos_phi = np.sign(V) * np.sqrt(1 - sin_phi**2)
    Vvec = np.linalg.solve(K - M, p)
    x0 = Vvec * cos_phi  # docs/theory.md 4.3: x(0) = V cos(phi), x'(0) = ... from the ODE
    # velocity at 0 from the modal solution is -V sin(phi) + beta sum ... ; build it by
    # solving the antisymmetry conditions directly instead:
    n = s.dof
    A = np.zeros((2 * n + 3, 2 * n + 3))
    A[:n, n : 2 * n] = np.eye(n)
    A[n : 2 * n, :n] = -np.linalg.solve(M, K)
    A[n : 2 * n, 2 * n] = np.linalg.solve(M, p)
    A[n : 2 * n, 2 * n + 2] = np.linalg.solve(M, b)
    A[2 * n, 2 * n + 1] = -1.0
    A[2 * n + 1, 2 * n] = 1.0
    E = expm(np.pi * A)
    # unknown v0 from v(pi) = -v(0) with x0, phi known
    lhs = E[n : 2 * n, n : 2 * n] + np.eye(n)
    rhs = -(E[n : 2 * n, :n] @ x0 + E[n : 2 * n, 2 * n :] @ np.array([cos_phi, sin_phi, beta]))
    v0 = np.linalg.solve(lhs, rhs)
    Y0 = np.concatenate([x0, v0, [cos_phi, sin_phi, beta]])
    assert b @ v0 == pytest.approx(0.0, abs=1e-9)
    assert np.allclose((E @ Y0)[:n], -x0, atol=1e-9)
    tau = np.linspace(0.0, np.pi, 41)
    vel = np.array([b @ (expm(t * A) @ Y0)[n : 2 * n] for t in tau])
    np.testing.assert_allclose(slip_velocity(s, r, beta, tau), vel, atol=1e-8)


def test_h_is_odd_about_half_period():
    """h(pi - tau) = -h(tau): the sup over (0, pi) is the sup of |.| over (0, pi/2]."""
    s = Scene("ground", 3, 2, gamma=(0.6, 1.7), kappa=(1.4, 0.5))
    r = 0.43
    V, U, _ = response_functions(s, r)
    tau = np.linspace(0.01, np.pi / 2, 50)
    beta = 0.3 * float(continuous_bound(s, r))
    amp = np.sqrt(V**2 - (beta * U) ** 2)
    h = (slip_velocity(s, r, beta, tau) + amp * np.sin(tau)) / beta
    h_mirror = (slip_velocity(s, r, beta, np.pi - tau) + amp * np.sin(tau)) / beta
    np.testing.assert_allclose(h_mirror, -h, atol=1e-10 * np.abs(h).max())


def _dense_sup(scene: Scene, r: float, n_tau: int = 200_001) -> float:
    """sup of m_b h / sin on a dense grid from an independent modal sum (docs/theory.md 4.3)."""
    K, M, b = scene.stiffness_matrix(), scene.mass_matrix(r), scene.contact_vector()
    lam, psi = eigh(K, M)
    Om = np.sqrt(lam)
    c2 = (b @ psi) ** 2
    t = np.tan(Om * np.pi / 2)
    U = np.sum(c2 / Om * t)
    m_b = 1.0 / np.sum(c2)
    tau = np.linspace(0, np.pi, n_tau)[1:-1, None]
    h = U * np.cos(tau[:, 0]) + np.sum(c2 / Om * (np.sin(Om * tau) - t * np.cos(Om * tau)), axis=1)
    return float(np.max(m_b * h / np.sin(tau[:, 0])))


@pytest.mark.parametrize(
    ("contact", "dof", "j"), [("ground", 2, 1), ("ground", 2, 2), ("base", 3, 2), ("mass", 2, 1)]
)
def test_exact_below_paper_and_equal_where_c_inactive(contact, dof, j):
    rng = np.random.default_rng(RNG_SEED)
    for gamma, kappa in PAIRS[:3]:
        s = Scene(contact, dof, j, gamma=gamma, kappa=kappa)
        r = np.linspace(0.05, 3.0, 250)
        paper = continuous_bound(s, r, "paper")
        exact = continuous_bound(s, r, "exact")
        S = generalised_S(s, r)
        assert np.all(exact <= paper)
        same = S == 1.0
        np.testing.assert_array_equal(exact[same], paper[same])
        assert np.all(exact[~same] < paper[~same])
        assert same.any() and (~same).any()
        for i in rng.choice(r.size, 4, replace=False):
            dense = _dense_sup(s, r[i])
            assert max(1.0, dense) == pytest.approx(S[i], rel=1e-6)


def test_exact_removes_the_crossing():
    """docs/theory.md 7: the paper's bounds cross at r = 0.554-0.586.

    2DOF ground m1, gamma = kappa = 1.
    """
    s = Scene("ground", 2, 1)
    r = np.linspace(0.556, 0.584, 15)
    bc, bm = boundaries(s, r, "paper")
    assert np.all(bc > bm)
    assert np.all(predict(s, r, 0.5 * (bc + bm), "paper") == NO_MOTION)
    be, _ = boundaries(s, r, "exact")
    assert np.all(be < bm)


# ------------------------------------------------------------------ singular points
def test_limits_at_singular_points():
    s = Scene("ground", 1)
    for method in ("paper", "exact"):
        # r = 1: Den Hartog's pi/4 from both sides
        vals = continuous_bound(s, [1.0, 1 - 1e-7, 1 + 1e-7], method)
        np.testing.assert_allclose(vals, np.pi / 4, rtol=1e-6)
        # Omega = 3: no antisymmetric solution, the bound goes to zero from both sides
        vals = continuous_bound(s, [1 / 3, (1 - 1e-9) / 3, (1 + 1e-9) / 3], method)
        assert vals[0] == 0.0 and np.all(vals[1:] < 1e-8)
    V, U, _ = response_functions(s, 1.0)
    assert np.isinf(V) and np.isinf(U)
    assert np.isfinite(generalised_S(s, 1.0)) and np.isinf(generalised_S(s, 1 / 3))
    # 2DOF: resonance of the sliding system, limit pi |psi.p| / (4 |b.psi|)
    s2 = Scene("ground", 2, 2, gamma=0.7, kappa=1.3)
    r_res = sliding_resonances(s2)
    K, gam = s2.stiffness_matrix(), s2.mass_ratios
    lam, phi = eigh(K, np.diag(gam))
    for i, r0 in enumerate(r_res):
        expect = np.pi * abs(phi[0, i]) / (4 * abs(phi[1, i]))
        for method in ("paper", "exact"):
            vals = continuous_bound(s2, r0 * (1 + np.array([0.0, -1e-8, 1e-8])), method)
            np.testing.assert_allclose(vals, expect, rtol=1e-6)
        # S is finite and continuous through the resonance (Omega_i = 1 exactly at r0)
        assert np.sqrt(contact_modes(s2).lam[i]) / r0 == 1.0
        S = generalised_S(s2, r0 * (1 + np.array([0.0, -1e-8, 1e-8])))
        np.testing.assert_allclose(S, S[1], rtol=1e-6)
        # (the brute-force sum cancels badly closer to the pole than this)
        assert S[0] == pytest.approx(max(1.0, _dense_sup(s2, r0 * (1 + 1e-6))), rel=1e-5)


def test_sweeps_have_no_nan_and_no_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for s in all_scenes():
            r = singular_r(s)
            with np.errstate(all="raise"):
                bc, bm = boundaries(s, r, "paper")
                V, U, m_b = response_functions(s, r)
                codes = predict(s, r[:, None], np.array([0.0, 0.5, 2.0])[None, :])
            for arr in (bc, bm, V, U, m_b):
                assert not np.isnan(arr).any(), s
            assert np.all(bc >= 0) and np.all(bm >= 0) and np.all(np.isfinite(bc))
            assert set(np.unique(codes)) <= {NO_MOTION, STICK_SLIP, CONTINUOUS}


def test_exact_sweeps_have_no_nan_and_no_warnings():
    scenes = list(all_scenes(dofs=(1, 2)))
    scenes += [s for s in all_scenes(dofs=(3,), ratios=(1e-6, 1e6)) if s.gamma != s.kappa]
    scenes += [
        Scene("ground", 5, 4, gamma=1e-6, kappa=1e6),
        Scene("mass", 5, 2, gamma=1e6, kappa=1e-6),
        Scene("ground", 20, 7),
        Scene("mass", 20, 19),
        Scene("base", 20, 20, gamma=1e-6),
    ]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for s in scenes:
            r = singular_r(s)
            if s.dof > 5:  # keep the extremes, thin out the resonances (time)
                r = np.concatenate([r[:7], r[7::5]])
            with np.errstate(all="raise"):
                paper = continuous_bound(s, r, "paper")
                exact = continuous_bound(s, r, "exact")
                S = generalised_S(s, r) if s.dof <= 2 else np.ones(1)
            assert not np.isnan(exact).any() and not np.isnan(S).any(), s
            assert np.all(np.isfinite(exact)) and np.all(S >= 1.0)
            assert np.all(exact <= paper), s


# ------------------------------------------------------------------------ predict
def test_predict_hand_picked_points():
    sdof = Scene("ground", 1)
    # r = 2: V = -1/3, U = 1/2, m = 4 -> beta_cont = 0.5963 (Eq. 13 with S = 1); motion 1
    assert continuous_bound(sdof, 2.0) == pytest.approx((1 / 3) / np.sqrt(0.25 + 1 / 16))
    codes = predict(sdof, 2.0, [0.1, 0.59, 0.6, 0.99, 1.0, 3.0])
    np.testing.assert_array_equal(
        codes, [CONTINUOUS, CONTINUOUS, STICK_SLIP, STICK_SLIP, NO_MOTION, NO_MOTION]
    )
    assert codes.dtype == np.int8
    # Table 1, m2: no motion above kappa/|1 + kappa - r^2|
    s = Scene("ground", 2, 2, gamma=1.0, kappa=1.0)
    r = 0.5
    bm = 1.0 / abs(2.0 - r**2)
    bc = float(continuous_bound(s, r))
    assert bc < bm
    np.testing.assert_array_equal(
        predict(s, r, [0.5 * bc, 0.5 * (bc + bm), bm, 2 * bm]),
        [CONTINUOUS, STICK_SLIP, NO_MOTION, NO_MOTION],
    )
    # Table 3 (mass contact) at r -> large: motion bound gamma/(1+gamma)
    s = Scene("mass", 2, 1, gamma=1.0, kappa=1.0)
    assert predict(s, 50.0, 0.51) == NO_MOTION
    assert predict(s, 50.0, 0.49) != NO_MOTION
    # held resonance: motion for every beta
    assert predict(Scene("ground", 2, 2), np.sqrt(2.0), 1e9) != NO_MOTION


def test_predict_broadcasting_and_shapes():
    s = Scene("base", 2, 2, gamma=1.5, kappa=0.8)
    r = np.linspace(0.2, 2.5, 7)[:, None]
    beta = np.linspace(0.0, 2.0, 5)[None, :]
    codes = predict(s, r, beta, "exact")
    assert codes.shape == (7, 5) and codes.dtype == np.int8
    bc, bm = boundaries(s, r[:, 0], "exact")
    for i, j in itertools.product(range(7), range(5)):
        b = beta[0, j]
        want = NO_MOTION if b >= bm[i] else (CONTINUOUS if b < bc[i] else STICK_SLIP)
        assert codes[i, j] == want
    bc0, bm0 = boundaries(s, 1.2)
    assert bc0.shape == () and bm0.shape == ()
    assert boundaries(s, np.ones((2, 3)))[0].shape == (2, 3)
    with pytest.raises(ValueError, match="method"):
        boundaries(s, 1.0, method="hong-liu")
    with pytest.raises(ValueError, match="r"):
        boundaries(s, [1.0, 0.0])
    with pytest.raises(ValueError, match="beta"):
        predict(s, 1.0, [0.1, -0.1])
    with pytest.raises(ValueError, match="beta"):
        predict(s, 1.0, np.nan)


# -------------------------------------------------------------------- reference data
def _reference_cases(path):
    data = json.loads(path.read_text())
    return data["cases"]


def test_reference_data(reference_cases_path):
    cases = _reference_cases(reference_cases_path)
    assert len(cases) == 170
    dev = {"paper": 0.0, "motion": 0.0, "exact": 0.0}
    for c in cases:
        n = c["N"]
        s = Scene(
            c["contact"],
            n,
            c["j"],
            gamma=tuple(c["g"][1:]) if n > 1 else 1.0,
            kappa=tuple(c["k"][1:]) if n > 1 else 1.0,
        )
        bc, bm = boundaries(s, c["r"], "paper")
        be, _ = boundaries(s, c["r"], "exact")
        for key, mine, ref in (
            ("paper", bc, c["b_cont"]),
            ("motion", bm, c["b_motion"]),
            ("exact", be, c["b_cont_S_diagnostic"]),
        ):
            dev[key] = max(dev[key], abs(float(mine) - ref) / abs(ref))
        assert (
            predict(s, c["r"], c["b"], "paper")
            == {
                "continuous": CONTINUOUS,
                "stick_slip": STICK_SLIP,
                "no_motion": NO_MOTION,
            }[c["closed_form_regime"]]
        )
    assert dev["paper"] < 1e-6, dev
    assert dev["motion"] < 1e-6, dev
    assert dev["exact"] < 1e-6, dev


@pytest.mark.parametrize("method", ["paper", "exact"])
@pytest.mark.parametrize(
    "scene", [Scene("ground", 2), Scene("mass", 3, 2), Scene("base", 4, 3, gamma=2.0)]
)
def test_boundaries_along_equal_boundaries_and_remembered(scene, method, monkeypatch):
    """The block-wise, remembered curves (an adaptive map's hint and its result file)
    are bit for bit those of one call of ``boundaries`` on the whole axis; a second
    call computes nothing and hands out arrays of its own."""
    from analysis import closed_form

    r = np.linspace(0.02, 3.0, 2 * closed_form.BOUNDARY_BLOCK + 37)  # blocks + a remainder
    whole = boundaries(scene, r, method=method)
    closed_form._remembered.clear()
    first = closed_form.boundaries_along(scene, r, method)
    for got, want in zip(first, whole, strict=True):
        np.testing.assert_array_equal(got, want)
    first[0][:] = -1.0  # the caller's copy: the remembered curve stays
    calls, real = [], closed_form.boundaries
    monkeypatch.setattr(closed_form, "boundaries", lambda *a, **k: calls.append(a) or real(*a, **k))
    again = closed_form.boundaries_along(scene, r, method)
    assert not calls
    for got, want in zip(again, whole, strict=True):
        np.testing.assert_array_equal(got, want)
    other = closed_form.boundaries_along(scene, r[:5], method)  # other r: computed
    assert calls and other[0].shape == (5,)
