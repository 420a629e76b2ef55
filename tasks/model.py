"""Modal data of a scene, computed once per scene and independent of r and beta.

With ``M = r^2 Gamma`` (Gamma = diag(gamma), Eq. 68) the eigenproblem
``K phi = Omega^2 M phi`` (Eq. 18) has eigenvectors that do not depend on r:
``K phi_i = lambda_i Gamma phi_i`` with ``phi_i^T Gamma phi_i = 1`` and
``Omega_i = sqrt(lambda_i) / r`` in dimensionless time (Eqs. 17, 40). The
mass-normalised modes of the paper are ``psi_i = phi_i / r`` (Eq. 26).

Two linear systems describe every phase of the motion (MODEL.md section 2):

* **slip** (all N coordinates move): ``M x'' + K x = p cos tau - beta s b``;
* **stick** (N - 1 coordinates): with ``x = T q + d0 w`` (``b^T T = 0``,
  ``b^T w = 1``), ``T^T M T q'' + T^T K T q = T^T (p cos tau - d0 K w)``
  (Eqs. 131-135).

While stuck, the force that would accelerate the contact (the friction force
the wall must supply, Eqs. 11b, 12b, 79b, 103b in one formula) is

    g = b^T M^-1 (p cos tau - K x) / (b^T M^-1 b),

and the contact stays stuck while ``|g| <= beta``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import eigh

from tasks.scene import Scene


@dataclass(frozen=True)
class SceneModes:
    """Arrays the simulator needs, for one scene (all independent of r, beta).

    Attributes follow the module docstring; ``p0`` is the load vector at r = 1
    and ``load_scales_r2`` says whether p scales with r^2 (base-fixed wall).
    """

    n: int
    lam: np.ndarray  # (n,) slip-system eigenvalues lambda_i
    phi: np.ndarray  # (n, n) slip modes, columns, phi^T Gamma phi = I
    phi_t_gamma: np.ndarray  # (n, n) phi^T Gamma: modal coordinates of x
    w_slip: np.ndarray  # (n,) b^T phi_i: contact velocity of each slip mode
    f_slip: np.ndarray  # (n,) phi_i^T b: modal friction load per unit force
    lam_s: np.ndarray  # (n-1,) stuck-system eigenvalues
    phi_s: np.ndarray  # (n-1, n-1) stuck modes (q = phi_s zeta)
    phi_s_t_gamma_s: np.ndarray  # (n-1, n-1)
    phi_s_t_tt: np.ndarray  # (n-1, n) phi_s^T T^T: modal load of the stuck system
    d_static: np.ndarray  # (n-1,) phi_s^T T^T K w: modal load per unit d0 (with minus sign)
    T: np.ndarray  # (n, n-1)
    w: np.ndarray  # (n,)
    proj: np.ndarray  # (n-1, n) (T^T Gamma T)^-1 T^T Gamma: q from x - d0 w
    b: np.ndarray  # (n,)
    inv_gamma_b: np.ndarray  # (n,) Gamma^-1 b / (b^T Gamma^-1 b)
    b_gamma_b: float  # b^T Gamma^-1 b
    g_load: np.ndarray  # (n,) b^T Gamma^-1 / (b^T Gamma^-1 b): g = g_load . (p cos tau - K x)
    g_x: np.ndarray  # (n,) g_load^T K
    g_modes_s: np.ndarray  # (n-1,) (g_x T) phi_s_i: g per stuck modal coordinate
    g_d0: float  # g_x . w: g per unit d0
    p0: np.ndarray  # (n,) load vector at r = 1
    load_scales_r2: bool
    stiffness: np.ndarray  # (n, n) K


def _modes(K: np.ndarray, G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenpairs of K phi = lambda G phi, phi^T G phi = 1, ascending lambda."""
    if K.shape[0] == 0:
        return np.zeros(0), np.zeros((0, 0))
    lam, phi = eigh(K, G)
    return lam, phi


def scene_modes(scene: Scene) -> SceneModes:
    """Modal data of ``scene`` (see :class:`SceneModes`)."""
    K = scene.stiffness_matrix()
    gam = scene.mass_ratios
    G = np.diag(gam)
    b = scene.contact_vector()
    T, w = scene.stuck_basis()
    lam, phi = _modes(K, G)
    Gs = T.T @ G @ T
    Ks = T.T @ K @ T
    lam_s, phi_s = _modes(Ks, Gs)
    inv_g = 1.0 / gam
    b_gamma_b = float(b @ (inv_g * b))
    g_load = inv_g * b / b_gamma_b
    g_x = g_load @ K
    proj = np.linalg.solve(Gs, T.T @ G) if T.shape[1] else np.zeros((0, scene.dof))
    return SceneModes(
        n=scene.dof,
        lam=lam,
        phi=phi,
        phi_t_gamma=phi.T @ G,
        w_slip=b @ phi,
        f_slip=phi.T @ b,
        lam_s=lam_s,
        phi_s=phi_s,
        phi_s_t_gamma_s=phi_s.T @ Gs,
        phi_s_t_tt=phi_s.T @ T.T,
        d_static=phi_s.T @ (T.T @ (K @ w)),
        T=T,
        w=w,
        proj=proj,
        b=b,
        inv_gamma_b=inv_g * b / b_gamma_b,
        b_gamma_b=b_gamma_b,
        g_load=g_load,
        g_x=g_x,
        g_modes_s=(g_x @ T) @ phi_s if T.shape[1] else np.zeros(0),
        g_d0=float(g_x @ w),
        p0=scene.load_vector(1.0),
        load_scales_r2=scene.contact == "base",
        stiffness=K,
    )


def kernel_args(m: SceneModes) -> tuple:
    """The modal data as the flat tuple of arrays the compiled kernel takes."""
    c = np.ascontiguousarray
    return (
        c(m.lam),
        c(m.phi),
        c(m.phi_t_gamma),
        c(m.w_slip),
        c(m.f_slip),
        c(m.lam_s),
        c(m.phi_s),
        c(m.phi_s_t_gamma_s),
        c(m.phi_s_t_tt),
        c(m.d_static),
        c(m.T),
        c(m.w),
        c(m.proj),
        c(m.b),
        c(m.inv_gamma_b),
        float(m.b_gamma_b),
        c(m.g_load),
        c(m.g_x),
        c(m.g_modes_s),
        float(m.g_d0),
        c(m.p0),
        bool(m.load_scales_r2),
        c(m.stiffness),
    )
