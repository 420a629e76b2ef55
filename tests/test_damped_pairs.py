"""Real oscillator coordinates of non-proportional damping (tasks.damped_pairs,
docs/structures.md 4.5) against an independent truth: scipy's ODE solver of the
state-space system, and the undamped / proportional limits (the modes of (K, M))."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from tasks.damped_pairs import damped_pairs
from tasks.kernel import damping, layout


def _spd(n: int, rng: np.random.Generator, cond: float = 10.0) -> np.ndarray:
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return Q @ np.diag(np.exp(rng.uniform(0.0, np.log(cond), n))) @ Q.T


def _psd(n: int, rng: np.random.Generator, rank: int) -> np.ndarray:
    B = rng.standard_normal((n, rank))
    return B @ B.T


def _propagate_pairs(pairs, M, r, p, q, x0, xd0, tau0, taus):
    """States at ``taus`` by the kernel's damped modal closed form, pair by pair."""
    n = M.shape[0]
    y = np.concatenate([x0, r * xd0])
    coords = pairs.L @ y
    eta0, rxi0 = coords[:n], coords[n:]
    offset = pairs.load_w @ q / r
    seg = np.zeros((layout.N_ROWS, n))
    sc = np.zeros(layout.N_SCALARS)
    seg[layout.OMEGA] = np.sqrt(pairs.lam) / r
    seg[layout.DAMP] = 0.5 * pairs.damp / r
    seg[layout.LOAD_COS] = pairs.load_nu @ p / r**2
    seg[layout.LOAD_CONST] = pairs.load_nu @ q / r**2
    seg[layout.ETA0] = eta0
    seg[layout.ETAD0] = rxi0 / r + offset
    sc[layout.COS_TAU0], sc[layout.SIN_TAU0] = np.cos(tau0), np.sin(tau0)
    out = []
    eta, etad = np.zeros(n), np.zeros(n)
    for tau in taus:
        damping.evaluate_damped(seg, sc, tau - tau0, eta, etad)
        y = pairs.V @ np.concatenate([eta, r * (etad - offset)])
        out.append(np.concatenate([y[:n], y[n:] / r]))
    return np.array(out)


def _reference(M, C, K, r, p, q, x0, xd0, tau0, taus):
    n = M.shape[0]
    Mi = np.linalg.inv(r * r * M)

    def rhs(t, y):
        return np.concatenate([y[n:], Mi @ (p * np.cos(t) + q - K @ y[:n] - r * C @ y[n:])])

    sol = solve_ivp(
        rhs,
        (tau0, taus[-1]),
        np.concatenate([x0, xd0]),
        t_eval=taus,
        method="DOP853",
        rtol=1e-12,
        atol=1e-13,
    )
    return sol.y.T


@pytest.mark.parametrize("seed", range(6))
def test_pairs_propagate_like_the_state_space_system(seed):
    """Random full M, K, non-proportional C (full rank, a local dashpot, heavy damping
    with real eigenvalues): the pairs' closed form equals scipy to 1e-8."""
    rng = np.random.default_rng(seed)
    n = 2 + seed % 3
    M, K = _spd(n, rng), _spd(n, rng)
    if seed % 3 == 0:
        C = 0.2 * _spd(n, rng)
    elif seed % 3 == 1:  # a local dashpot between DOF 0 and ground
        C = np.zeros((n, n))
        C[0, 0] = 0.3
    else:  # heavy: some eigenvalues real (overdamped pairs)
        C = 3.0 * _psd(n, rng, n)
    p, q = rng.standard_normal(n), rng.standard_normal(n)
    pairs = damped_pairs(M, C, K, p)
    assert np.all(pairs.damp >= 0.0) and np.all(pairs.lam > 0.0)
    for r in (0.6, 1.7):
        x0, xd0 = rng.standard_normal(n), rng.standard_normal(n)
        taus = np.linspace(0.4, 0.4 + 12.0, 25)
        got = _propagate_pairs(pairs, M, r, p, q, x0, xd0, 0.4, taus)
        want = _reference(M, C, K, r, p, q, x0, xd0, 0.4, taus)
        np.testing.assert_allclose(got, want, atol=1e-8 * np.max(np.abs(want)))


def test_undamped_pairs_are_the_modes():
    rng = np.random.default_rng(7)
    M, K = _spd(3, rng), _spd(3, rng)
    pairs = damped_pairs(M, np.zeros((3, 3)), K, rng.standard_normal(3))
    lam = np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real)
    np.testing.assert_allclose(pairs.lam, lam, rtol=1e-10)
    np.testing.assert_allclose(pairs.damp, 0.0, atol=1e-10 * lam[-1])


def test_repeated_eigenvalues_are_refused():
    M = np.eye(2)
    with pytest.raises(ValueError, match="^damping: two damped eigenvalues coincide"):
        damped_pairs(M, 0.1 * np.eye(2), np.eye(2), np.array([1.0, 0.0]))
    # critical damping of one DOF: a defective double eigenvalue
    with pytest.raises(ValueError, match="^damping: the damped eigenvectors"):
        damped_pairs(np.eye(1), 2.0 * np.eye(1), np.eye(1), np.array([1.0]))


def test_an_overdamped_pair_with_one_member_really_unloaded_is_refused():
    """M = I, C = [[10, 1], [1, 3]], K = [[1, 1], [1, 2]] (both SPD): v = (0, 1) is an
    eigenvector of nu = -1 exactly (the second column of nu^2 M + nu C + K vanishes),
    unloaded by p = (1, 0); the other eigenvalues, roots of nu^3 + 12 nu^2 + 20 nu + 1,
    are real (-0.052, -1.94, -10.01) and -1 pairs with -1.94, a loaded member: no
    coordinate (4.8) avoids the harmonic load in eta' (docs/structures.md 4.5)."""
    M, C, K = np.eye(2), np.array([[10.0, 1.0], [1.0, 3.0]]), np.array([[1.0, 1.0], [1.0, 2.0]])
    with pytest.raises(ValueError, match="^damping: an overdamped pair with one member unloaded"):
        damped_pairs(M, C, K, np.array([1.0, 0.0]))
    # the control: both members loaded (p on both DOFs), a valid oscillator
    pairs = damped_pairs(M, C, K, np.array([1.0, 1.0]))
    assert np.all(pairs.lam > 0.0) and np.all(pairs.damp > 0.0)
