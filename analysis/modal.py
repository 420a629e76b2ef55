"""Modal data of a scene for the closed-form boundaries (independent of r and beta).

Every configuration of :class:`tasks.scene.Scene` is written as (docs/theory.md 2;
a scene of matrices has a full symmetric ``Gamma``, docs/structures.md 1)

    M x'' + K x = p cos(tau) + F_c b,     M = r^2 Gamma,  Gamma = diag(gamma),

with contact direction ``b`` (``e_j`` for a ground or base wall, ``e_(j+1) - e_j``
for a contact between masses j and j + 1) and load ``p = r^alpha p_hat``
(``p_hat = e_1``, ``alpha = 0`` for ground and mass contacts; ``p_hat = Gamma 1``,
``alpha = 2`` for the base wall, Eq. 98).

**Sliding system.** ``K phi_i = lambda_i Gamma phi_i`` with ``phi_i^T Gamma phi_i = 1``.
The paper's mass-normalised modes (Eq. 26) are ``psi_i = phi_i / r`` and its
dimensionless natural frequencies (Eqs. 17, 40) are ``Omega_i = sqrt(lambda_i) / r
= 1 / R_i``: the eigenvectors do not depend on r, so they are computed once.
The contact sees mode i through ``b . psi_i = cb_i / r`` and the load excites it
through ``psi_i . p = p0_i r^(alpha - 1)``.

**Held system** (contact stuck, Sects. 2.5, 2.6.3, 3.3, 4.3): ``x = T q`` with
``b^T T = 0`` (:meth:`tasks.scene.Scene.stuck_basis`). Its modes
``(T^T K T) phis_k = lambdas_k (T^T Gamma T) phis_k`` are computed per connected
block (for a wall on mass j the held chain splits into the lower and the upper
subsystem of Fig. 7), so that every block has simple eigenvalues and each modal
residue is well defined. The force the contact must transmit is

    g_load . (p - K T Q) = r^alpha [F0 - sum_k z_k / (lambdas_k - r^2)],

with ``g_load = Gamma^-1 b / (b^T Gamma^-1 b)`` (``= e_j`` for a wall contact),
``F0 = g_load . p_hat`` and residues ``z_k = (g_load^T K T phis_k)(phis_k^T T^T p_hat)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.linalg import eigh
from scipy.sparse.csgraph import connected_components

from tasks.model import inverse_mass_times, scene_modes
from tasks.scene import Scene

NOISE = 1e-13
"""Modal projections below ``NOISE`` times their Cauchy-Schwarz bound are round-off
and are set to exactly zero (a mode the contact or the load cannot see)."""


@dataclass(frozen=True)
class ContactModes:
    """Modal data of one scene, all independent of r and beta.

    Attributes
    ----------
    lam : ndarray, shape (N,)
        Eigenvalues ``lambda_i`` of the sliding system, ascending;
        ``Omega_i = sqrt(lambda_i) / r``.
    phi : ndarray, shape (N, N)
        Eigenvectors (columns) with ``phi^T Gamma phi = I``.
    cb : ndarray, shape (N,)
        ``b . phi_i`` (exact zeros for modes the contact does not see).
    p0 : ndarray, shape (N,)
        ``phi_i . p_hat`` (exact zeros for modes the load does not excite).
    alpha : int
        The load is ``p = r^alpha p_hat`` (0 ground and mass contacts, 2 base wall).
    b_gamma_b : float
        ``B = b^T Gamma^-1 b = sum_i cb_i^2``; the effective contact mass is
        ``m_b = r^2 / B`` (``gamma_j r^2`` for a wall, ``G r^2`` for the 2DOF mass
        contact, G of Eq. 110).
    weights : ndarray, shape (N,)
        ``w_i = cb_i^2 / B``: the share of mode i in the contact flexibility
        (they sum to 1).
    lam_s : ndarray, shape (N - 1,)
        Eigenvalues of the held system (resonances at ``r = sqrt(lam_s)``).
    z_s : ndarray, shape (N - 1,)
        Residues of the held contact force (exact zeros: no resonance peak).
    F0 : float
        Quasi-static part ``g_load . p_hat`` of the held contact force.
    lam_absorb : ndarray
        Eigenvalues of the held modes the load does not reach but the contact feels
        (exact zeros of the load, non-zero force): at ``r = sqrt(lam_absorb)`` such
        a mode is a tuned absorber and the motion bound is 0 (docs/theory.md 3).
    """

    lam: np.ndarray
    phi: np.ndarray
    cb: np.ndarray
    p0: np.ndarray
    alpha: int
    b_gamma_b: float
    weights: np.ndarray
    lam_s: np.ndarray
    z_s: np.ndarray
    F0: float
    lam_absorb: np.ndarray


def _clean(values: np.ndarray, bound: np.ndarray | float) -> np.ndarray:
    """Set projections below ``NOISE * bound`` to exactly zero."""
    out = np.array(values, dtype=float)
    out[np.abs(out) <= NOISE * np.asarray(bound)] = 0.0
    return out


def _held_modes(
    K: np.ndarray, G: np.ndarray, T: np.ndarray, g_load: np.ndarray, p_hat: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eigenvalues and force residues of the held system, block by block
    (``G`` the mass matrix Gamma, diagonal for a chain, full for a structure), and
    the eigenvalues of its unloaded modes that load the contact (the absorbers)."""
    m = T.shape[1]
    if m == 0:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    Ks = T.T @ K @ T
    Gs = T.T @ G @ T
    a_row = g_load @ K @ T  # contact force per held coordinate (to be subtracted)
    p_s = T.T @ p_hat  # load on the held coordinates
    coupling = (np.abs(Ks) + np.abs(Gs)) > 0.0
    n_blocks, labels = connected_components(coupling, directed=False)
    lam_all, z_all, absorb = [], [], []
    for blk in range(n_blocks):
        idx = np.flatnonzero(labels == blk)
        lam_b, phi_b = eigh(Ks[np.ix_(idx, idx)], Gs[np.ix_(idx, idx)])
        norms = np.linalg.norm(phi_b, axis=0)
        a = _clean(a_row[idx] @ phi_b, np.linalg.norm(a_row[idx]) * norms)
        ps = _clean(phi_b.T @ p_s[idx], np.linalg.norm(p_s[idx]) * norms)
        lam_all.append(lam_b)
        z_all.append(a * ps)
        absorb.append(lam_b[(ps == 0.0) & (a != 0.0)])
    lam_s = np.concatenate(lam_all)
    order = np.argsort(lam_s, kind="stable")
    return lam_s[order], np.concatenate(z_all)[order], np.sort(np.concatenate(absorb))


@lru_cache(maxsize=256)
def contact_modes(scene: Scene) -> ContactModes:
    """Modal data of ``scene`` (cached per scene; see :class:`ContactModes`).

    Parameters
    ----------
    scene : tasks.scene.Scene
        Any configuration: ground, base or mass contact, any number of masses.

    Returns
    -------
    ContactModes
    """
    sliding = scene_modes(scene)  # the simulator's modal data: one home for the modes
    K, G, b = sliding.stiffness, sliding.mass, sliding.b
    p_hat = sliding.p0  # e_1, or Gamma 1 for the base wall (times r^2)
    alpha = 2 if sliding.load_scales_r2 else 0
    lam, phi = sliding.lam.copy(), sliding.phi.copy()
    b_gamma_b, g_load = sliding.b_gamma_b, sliding.g_load
    # |phi_i . v| <= ||Gamma^-1/2 v|| because phi_i has unit Gamma-norm.
    cb = _clean(b @ phi, np.sqrt(b_gamma_b))
    p0 = _clean(p_hat @ phi, np.sqrt(p_hat @ inverse_mass_times(G, p_hat)))
    T = sliding.T
    lam_s, z_s, lam_absorb = _held_modes(K, G, T, g_load, p_hat)
    for arr in (lam, phi, cb, p0, lam_s, z_s, lam_absorb):
        arr.setflags(write=False)
    weights = cb * cb / np.sum(cb * cb)
    weights.setflags(write=False)
    return ContactModes(
        lam=lam,
        phi=phi,
        cb=cb,
        p0=p0,
        alpha=alpha,
        b_gamma_b=b_gamma_b,
        weights=weights,
        lam_s=lam_s,
        z_s=z_s,
        F0=float(g_load @ p_hat),
        lam_absorb=lam_absorb,
    )
