"""The stability test of shooting (docs/simulator.md 5.2): spectral radius at most 1 + 1e-6.

:func:`tasks.kernel.acceptance.radius_within` decides it from norms of powers of the
Jacobian where they prove it and from the eigenvalues otherwise; its answer must
be the eigenvalues' (numpy's, an independent computation) on matrices of every
kind a fixed point can have: contracting and normal, contracting but strongly
non-normal (norm far above 1, so no low power proves it), a multiplier just
inside or just outside the bound, complex pairs, defective blocks, and random
spectra near the bound.
"""

from __future__ import annotations

import numpy as np
import pytest

from tasks.kernel.acceptance import STABLE_RADIUS, radius_within


def _with_spectrum(eigs: np.ndarray, rng: np.random.Generator, cond: float) -> np.ndarray:
    """A real matrix with the eigenvalues of ``eigs`` (real, or conjugate pairs given
    once as complex) in a random basis of condition number about ``cond``."""
    blocks = []
    for lam in eigs:
        if np.iscomplexobj(lam) and lam.imag != 0.0:
            a, b = lam.real, lam.imag
            blocks.append(np.array([[a, b], [-b, a]]))
        else:
            blocks.append(np.array([[float(np.real(lam))]]))
    dim = sum(b.shape[0] for b in blocks)
    D = np.zeros((dim, dim))
    i = 0
    for b in blocks:
        k = b.shape[0]
        D[i : i + k, i : i + k] = b
        i += k
    U, _ = np.linalg.qr(rng.normal(size=(dim, dim)))
    V, _ = np.linalg.qr(rng.normal(size=(dim, dim)))
    S = U @ np.diag(np.geomspace(1.0, cond, dim)) @ V
    return S @ D @ np.linalg.inv(S)


def _radius(A: np.ndarray) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(A))))


@pytest.mark.parametrize("cond", [1.0, 1e3])
@pytest.mark.parametrize(
    "eigs",
    [
        np.array([0.5, -0.3, 0.1, 0.0]),
        np.array([0.9 + 0.3j, 0.2, -0.7]),
        np.array([0.999, 0.5 + 0.5j, -0.2]),
        np.array([1.0 + 2e-6, 0.3, 0.1, -0.4]),  # just outside: unstable
        np.array([-(1.0 + 1e-4), 0.9, 0.2 + 0.1j]),
        np.array([1.0 + 1e-9, 0.5, 0.5j + 0.1]),  # just inside the bound
        np.array([0.0, 0.0, 0.0]),
        np.array([0.99999, 0.5, -0.3]),  # slow contraction: proved by a high power
        np.array([(1.0 + 1e-5) * np.exp(0.7j), 0.4]),  # complex pair just outside
        np.array([-(1.0 + 3e-6), 0.99, 0.2]),  # real, negative, just outside
    ],
)
def test_radius_within_agrees_with_the_eigenvalues(eigs, cond):
    # (a basis of condition number c moves the stored matrix's eigenvalues by about
    # c^2 1e-16: up to 1e3 that stays far below the margins of 1e-9 .. 1e-6 here)
    rng = np.random.default_rng(len(eigs) + int(cond))
    A = _with_spectrum(eigs, rng, cond)
    assert radius_within(A, STABLE_RADIUS) == (_radius(A) <= STABLE_RADIUS)


def test_radius_within_strongly_non_normal():
    """A contracting Jordan-like block with a huge off-diagonal part: its norm is
    about 1e8, its powers only fall below 1 late, and the answer stays right."""
    for lam, expected in ((0.95, True), (1.00001, False)):
        A = np.array([[lam, 1e8, 0.0], [0.0, lam, 1e8], [0.0, 0.0, lam]])
        assert radius_within(A, STABLE_RADIUS) is expected
        assert (_radius(A) <= STABLE_RADIUS) is expected


def test_radius_within_agrees_with_the_eigenvalues_near_the_bound():
    """Random spectra (real and complex, 3 to 10 dimensions, moderately non-normal)
    with the radius within 1e-3 of the bound but at least 1e-8 from it: the norm
    and trace bounds of the powers decide as the eigenvalues do."""
    rng = np.random.default_rng(19)
    for _ in range(60):
        dim = int(rng.integers(3, 11))
        radius = STABLE_RADIUS + rng.choice([-1.0, 1.0]) * 10.0 ** rng.uniform(-8, -3)
        eigs = list(rng.uniform(-0.9, 0.9, size=dim - 2))
        top = radius * np.exp(1j * rng.uniform(0.0, np.pi)) if rng.random() < 0.5 else radius
        eigs.append(top if np.iscomplexobj(top) else rng.choice([-1.0, 1.0]) * top)
        A = _with_spectrum(np.array(eigs, dtype=complex), rng, 10.0)
        assert radius_within(A, STABLE_RADIUS) == (_radius(A) <= STABLE_RADIUS)
