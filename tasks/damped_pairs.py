"""Real oscillator coordinates of a non-proportionally damped linear phase
(docs/structures.md 4.5).

For ``r^2 M x'' + r C x' + K x = p cos(tau) + q`` (M, K symmetric positive
definite, C symmetric positive semidefinite, q constant) the eigenvalues of the
quadratic problem ``(nu^2 M + nu C + K) v = 0`` do not depend on r; in the time
tau they are ``mu = nu / r``. They come in conjugate pairs and an even number of
real ones, all with ``Re nu <= 0``. A *pair* is a conjugate pair, or two real
eigenvalues. With ``w_i = rho_i v_i`` (i = 1, 2 the members of the pair; for a
conjugate pair ``w_2 = conj(w_1)``) the real coordinate

    eta = sum_i w_i^T (nu_i M + C) x + r w_i^T M x'                        (4.8)

obeys exactly (``j`` the other member)

    eta'' + 2 sigma eta' + Omega^2 eta = a cos(tau) + c,
    2 sigma = -(nu_1 + nu_2) / r,  Omega^2 = nu_1 nu_2 / r^2,               (4.9)
    a = -sum_i nu_j w_i . p / r^2,  c = -sum_i nu_j w_i . q / r^2,

provided ``sum_i w_i . p = 0`` (``rho`` is chosen so), and its derivative is

    eta' = xi + o,  xi = sum_i nu_i (w_i^T (nu_i M + C) x / r + w_i^T M x'),
    o = sum_i w_i . q / r.                                                  (4.10)

In the scaled state ``(x, r x')`` the map to ``(eta, r xi)`` of all pairs is the
r-independent real ``2n x 2n`` matrix ``L`` returned here (``V = L^-1`` maps
back). So each pair propagates by the damped modal closed form of
:mod:`tasks.kernel.damping` (Eqs. 4.1-4.3), whose energy bounds (4.4) hold
because ``sigma >= 0`` and ``Omega^2 > 0`` for every pair.

Refused (``ValueError``): repeated or defective eigenvalues (the eigenvectors
do not span the state space), an odd number of real eigenvalues, and a pair
of real eigenvalues whose coordinate (4.8) cannot both avoid the harmonic load
in ``eta'`` and stay independent of ``xi``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import eig

#: Smallest separation of two eigenvalues, relative to the larger of the two (else:
#: repeated, refused). Well above sqrt(machine epsilon) = 1.5e-8: rounding splits a
#: defective double eigenvalue (a critically damped mode of a non-proportional C) by
#: about that much, with an eigenvector matrix of condition about 1e8 only, which
#: MAX_CONDITION lets through.
SEPARATION_RTOL = 1e-6
#: Largest condition number of the eigenvector matrix (else: defective, refused).
MAX_CONDITION = 1e10
#: Largest ratio of the largest to the smallest |nu| (else: refused): phases spanning
#: more cannot be propagated together in double precision.
MAX_SPREAD = 1e12
#: Smallest tolerance of a load participation ``v . p`` relative to ``|v| |p|`` (below
#: it a member counts as unloaded whatever the eigenvectors' accuracy): rounding of the
#: sum alone is about n eps.
PARTICIPATION_RTOL = 1e-12


@dataclass(frozen=True)
class DampedPairs:
    """The pairs of one linear phase (see the module notes).

    Attributes
    ----------
    lam : ndarray (n,)
        ``nu_1 nu_2`` of every pair (``Omega = sqrt(lam) / r``).
    damp : ndarray (n,)
        ``-(nu_1 + nu_2)`` (``sigma = damp / (2 r)``), ``>= 0``.
    L : ndarray (2n, 2n)
        Rows ``[0, n)``: ``eta``, rows ``[n, 2n)``: ``r xi``, of ``(x, r x')``.
    V : ndarray (2n, 2n)
        ``L^-1``.
    load_w : ndarray (n, n)
        ``sum_i w_i`` (real): ``o = load_w @ q / r`` (Eq. 4.10).
    load_nu : ndarray (n, n)
        ``-sum_i nu_j w_i`` (real): ``a = load_nu @ p / r^2``, ``c = load_nu @ q / r^2``.
    """

    lam: np.ndarray
    damp: np.ndarray
    L: np.ndarray
    V: np.ndarray
    load_w: np.ndarray
    load_nu: np.ndarray


def _eigen(
    M: np.ndarray, C: np.ndarray, K: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eigenvalues ``nu`` and eigenvectors ``v`` of ``(nu^2 M + nu C + K) v = 0``, and
    the relative accuracy of each ``v`` (:func:`_participation_tol`)."""
    n = M.shape[0]
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -np.linalg.solve(M, K)
    A[n:, n:] = -np.linalg.solve(M, C)
    nu, Y = eig(A)
    if np.linalg.cond(Y) > MAX_CONDITION:
        raise ValueError(
            "damping: the damped eigenvectors are (nearly) dependent (a defective or "
            "repeated eigenvalue); the simulator cannot propagate this structure exactly"
        )
    mag = np.abs(nu)
    if not np.min(mag) > np.max(mag) / MAX_SPREAD:
        raise ValueError(
            f"damping: the damped eigenvalues spread over more than {MAX_SPREAD:g} (a damping "
            "far too large for the stiffness); the simulator cannot propagate this structure"
        )
    # each gap relative to its own pair's magnitude: a structure's spectrum may span
    # 1e6 and more, so a gap relative to the largest |nu| would refuse a slow mode's
    # conjugate pair, however distinct
    size = np.maximum(np.abs(nu)[:, None], np.abs(nu)[None, :])
    close = np.abs(nu[:, None] - nu[None, :]) <= SEPARATION_RTOL * size  # no 0 / 0
    np.fill_diagonal(close, False)
    if np.any(close):
        raise ValueError(
            "damping: two damped eigenvalues coincide (repeated, or defective as of a "
            "critically damped mode); the simulator cannot propagate this structure exactly"
        )
    gap = np.where(np.eye(2 * n, dtype=bool), np.inf, np.abs(nu[:, None] - nu[None, :]))
    return nu, Y[:n], _participation_tol(nu, gap.min(axis=1), np.linalg.norm(A, 2))


def _participation_tol(nu: np.ndarray, gap: np.ndarray, norm_a: float) -> np.ndarray:
    """Relative accuracy of the computed ``v`` of each eigenvalue, in ``|v|``.

    ``eig`` is backward stable: its eigenpairs are exact for ``A + E`` with
    ``|E| <~ p(N) eps |A|`` (N = 2n, p(N) ~ N), so the unit eigenvector
    ``y = (v, nu v) / |(v, nu v)|`` of a simple eigenvalue is off by about
    ``N eps |A| / gap`` (first-order perturbation; ``gap`` the distance to the
    nearest other eigenvalue). ``v`` is the first half of ``y``, of norm
    ``1 / sqrt(1 + |nu|^2)``: relative to ``|v|`` the error is
    ``N eps |A| sqrt(1 + |nu|^2) / gap``, and a participation ``v . p`` is off by
    that times ``|v| |p|`` (Cauchy-Schwarz) however much its terms cancel. Never
    below :data:`PARTICIPATION_RTOL`.
    """
    eps = np.finfo(float).eps
    err = nu.size * eps * norm_a * np.sqrt(1.0 + np.abs(nu) ** 2) / gap
    return np.maximum(err, PARTICIPATION_RTOL)


def _pairs_of(nu: np.ndarray) -> list[tuple[int, int]]:
    """Index pairs: conjugate pairs (upper member first), then real eigenvalues by size."""
    scale = np.max(np.abs(nu))
    real = np.abs(nu.imag) <= 1e-12 * scale
    upper = [i for i in np.argsort(np.abs(nu)) if not real[i] and nu[i].imag > 0.0]
    pairs = []
    used = set()
    for i in upper:
        j = min(
            (k for k in range(nu.size) if k not in used and not real[k] and nu[k].imag < 0.0),
            key=lambda k: abs(nu[k] - np.conj(nu[i])),
        )
        used.update((i, j))
        pairs.append((int(i), int(j)))
    reals = sorted((i for i in range(nu.size) if real[i]), key=lambda i: -nu[i].real)
    if len(reals) % 2:
        raise ValueError("damping: an odd number of real damped eigenvalues (refused)")
    # pair the slowest real eigenvalue with the fastest, and so on inwards
    for k in range(len(reals) // 2):
        pairs.append((reals[k], reals[-1 - k]))
    return pairs


def damped_pairs(M: np.ndarray, C: np.ndarray, K: np.ndarray, p: np.ndarray) -> DampedPairs:
    """The pairs of ``r^2 M x'' + r C x' + K x = p cos(tau) + q`` (module notes).

    ``p`` is the direction of the harmonic load (any r: a base load scales it by
    r^2). Pairs are sorted by ``lam`` (slowest first).
    """
    n = M.shape[0]
    nu, v, tol = _eigen(M, C, K)
    norm_p = np.linalg.norm(p)
    nu = np.where(np.abs(nu.imag) <= 1e-12 * np.max(np.abs(nu)), nu.real + 0j, nu)
    rows = []
    for i, j in _pairs_of(nu):
        vi, vj = v[:, i], v[:, j]
        if nu[i].imag != 0.0:  # conjugate: w_j = conj(w_i), Re(w_i . p) = 0
            vi = vi / np.sqrt(abs(vi.conj() @ M @ vi))
            vp = vi @ p
            rho = -1j * (np.exp(-1j * np.angle(vp)) if abs(vp) > 0.0 else 1.0) / abs(nu[i])
            wi = rho * vi
            wj = np.conj(wi)
            vj_nu = np.conj(nu[i])
        else:  # two real eigenvalues: a_i vi . p + a_j vj . p = 0
            vi = vi.real / np.sqrt(vi.real @ M @ vi.real)
            vj = vj.real / np.sqrt(vj.real @ M @ vj.real)
            pi_, pj = vi @ p, vj @ p
            # unloaded: a participation within what the eigenvector's accuracy allows
            # (its terms may cancel far below |v| |p|, e.g. a mode localised on a
            # light mass under a base load, where v . M u = k_1 v_0 / omega^2)
            free_i = abs(pi_) <= tol[i] * np.linalg.norm(vi) * norm_p
            free_j = abs(pj) <= tol[j] * np.linalg.norm(vj) * norm_p
            if free_i and free_j:
                ai, aj = 1.0, 1.0
            elif free_i or free_j:
                raise ValueError(
                    "damping: an overdamped pair with one member unloaded cannot be "
                    "written as one oscillator (refused)"
                )
            else:
                ai, aj = pj, -pi_
            wi = (ai * vi).astype(complex)
            wj = (aj * vj).astype(complex)
            vj_nu = nu[j]
        nui = nu[i]
        ex = wi @ (nui * M + C) + wj @ (vj_nu * M + C)
        ev = wi @ M + wj @ M
        fx = nui * (wi @ (nui * M + C)) + vj_nu * (wj @ (vj_nu * M + C))
        fv = nui * (wi @ M) + vj_nu * (wj @ M)
        lam = (nui * vj_nu).real
        damp = -(nui + vj_nu).real
        rows.append(
            (
                lam,
                damp,
                np.concatenate([ex, ev]).real,
                np.concatenate([fx, fv]).real,
                (wi + wj).real,
                -(vj_nu * wi + nui * wj).real,
            )
        )
    rows.sort(key=lambda row: row[0])
    L = np.vstack([row[2] for row in rows] + [row[3] for row in rows])
    return DampedPairs(
        lam=np.array([row[0] for row in rows]),
        damp=np.maximum(np.array([row[1] for row in rows]), 0.0),
        L=L,
        V=np.linalg.inv(L),
        load_w=np.vstack([row[4] for row in rows]) if n else np.zeros((0, 0)),
        load_nu=np.vstack([row[5] for row in rows]) if n else np.zeros((0, 0)),
    )
