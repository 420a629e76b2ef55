"""Modal data of a scene, computed once per scene and independent of r and beta.

With ``M = r^2 Gamma`` (Gamma = diag(gamma), Eq. 68) the eigenproblem
``K phi = Omega^2 M phi`` (Eq. 18) has eigenvectors that do not depend on r:
``K phi_i = lambda_i Gamma phi_i`` with ``phi_i^T Gamma phi_i = 1`` and
``Omega_i = sqrt(lambda_i) / r`` in dimensionless time (Eqs. 17, 40). The
mass-normalised modes of the paper are ``psi_i = phi_i / r`` (Eq. 26).

Two linear systems describe every phase of the motion (docs/theory.md section 2):

* **slip** (all N coordinates move, contact sliding with sign s):
  ``M x'' + K x = p cos tau - beta s b``;
* **stick** (N - 1 coordinates): with ``x = T q + d0 w`` (``b^T T = 0``,
  ``b^T w = 1``), ``T^T M T q'' + T^T K T q = T^T (p cos tau - d0 K w)``
  (Eqs. 131-135): the stuck mass leaves the state (ground, base) or the pair
  merges into one mass (mass contact).

While stuck, the force the contact must transmit (Eqs. 11b, 12b, 79b, 103b in
one formula) is

    g = b^T Gamma^-1 (p cos tau - K x) / (b^T Gamma^-1 b),

and the contact stays stuck while ``|g| <= beta``. While sliding, the contact
acceleration is ``b . x'' = (b^T Gamma^-1 b / r^2) (g - beta s)``.

A scene of matrices (:meth:`tasks.scene.Scene.from_matrices`) has a full
symmetric positive definite ``Gamma`` (its ``M``, docs/structures.md 1): every
formula above holds as written with ``Gamma^-1`` a matrix inverse; a diagonal
``Gamma`` (a chain, or a chain given by its matrices) takes the chain's own
arithmetic, so both give bit-identical arrays. With damping, ``damping`` holds
``C`` (the viscous term ``r C x'``, Eq. 1.1 of docs/structures.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.linalg import eigh

from tasks.damped_pairs import damped_pairs
from tasks.scene import Scene


@dataclass(frozen=True)
class SceneModes:
    """Arrays the simulator needs for one scene (all independent of r and beta).

    Slip system (n coordinates): ``lam``, ``phi`` (columns, ``phi^T Gamma phi = I``),
    ``phi_t_gamma`` (``phi^T Gamma``: modal coordinates of x), ``w_slip``
    (``b^T phi``: contact velocity per modal velocity), ``f_slip`` (``phi^T b``:
    modal load per unit contact force).

    Stuck system (m = n - 1 coordinates q, ``x = T q + d0 w``): ``lam_s``,
    ``phi_s``, ``phi_s_t_gamma_s``, ``load_s`` (``phi_s^T T^T``: modal load of a
    physical load), ``d_static`` (``phi_s^T T^T K w``: modal load per unit d0,
    to be subtracted), ``proj`` (``(T^T Gamma T)^-1 T^T Gamma``: q from x, the
    momentum-conserving projection).

    Contact force: ``g_load`` (``Gamma^-1 b / (b^T Gamma^-1 b)``, so that
    ``g = g_load . (p cos tau - K x)``), ``g_modes_s`` (g per stuck modal
    coordinate, ``g_load^T K T phi_s``), ``g_d0`` (``g_load^T K w``) and
    ``b_gamma_b`` (``b^T Gamma^-1 b``).

    ``proportional`` is False for damping that is not diagonal in the modes of both
    phases; :meth:`kernel_args` then gives the pairs of :mod:`tasks.damped_pairs`
    (docs/structures.md 4.5). ``pairs``, if set, replaces :meth:`kernel_args`
    (e.g. :func:`_pairs_args` of a proportional C, to test the general path).
    """

    n: int
    gamma: np.ndarray
    mass: np.ndarray
    stiffness: np.ndarray
    b: np.ndarray
    p0: np.ndarray
    load_scales_r2: bool
    lam: np.ndarray
    phi: np.ndarray
    phi_t_gamma: np.ndarray
    w_slip: np.ndarray
    f_slip: np.ndarray
    T: np.ndarray
    w: np.ndarray
    lam_s: np.ndarray
    phi_s: np.ndarray
    phi_s_t_gamma_s: np.ndarray
    load_s: np.ndarray
    d_static: np.ndarray
    proj: np.ndarray
    g_load: np.ndarray
    g_modes_s: np.ndarray
    g_d0: float
    b_gamma_b: float
    damping: np.ndarray | None = None
    damping_kind: str = "none"
    damp_slip: np.ndarray | None = None
    damp_stick: np.ndarray | None = None
    g_c: np.ndarray | None = None
    g_c_s: np.ndarray | None = None
    proportional: bool = True
    pairs: tuple | None = None

    @cached_property
    def _general_args(self) -> tuple:
        """:func:`_pairs_args` of a non-proportionally damped scene, computed once, in
        C order (an F-ordered ``T`` made numba compile the whole kernel a second time)."""
        args = _pairs_args(self, self.damping)
        return tuple(np.ascontiguousarray(a) if isinstance(a, np.ndarray) else a for a in args)

    def load(self, r: float) -> np.ndarray:
        """Amplitude p of the harmonic load at frequency ratio r."""
        return self.p0 * (r * r) if self.load_scales_r2 else self.p0

    def kernel_args(self) -> tuple:
        """The arrays in the order :func:`tasks.kernel.run_points` takes them.

        ``gamma`` is the diagonal of the mass matrix: the kernel uses it only for
        the energy scale of seeded random starts (exact for a diagonal mass).
        Then come the damping data (zeros when undamped): ``damp_slip``
        and ``damp_stick`` (``c_k = phi_k^T C phi_k`` of both phases), ``g_c``
        (``C^T g_load``) and ``g_c_s`` (``g_load^T C T phi_s``), docs/structures.md 4,
        and four arrays that are empty unless the damping is not proportional:
        ``C``, the slip pairs' load matrix, and ``lam`` and ``phi`` of the undamped
        modes of ``(K, Gamma)`` (their place is taken by the pairs), from which the
        contact's compliance at the excitation frequency and the motion floor are
        computed as for real modes (docs/simulator.md 5, 7).

        Non-proportional damping (docs/structures.md 4.5) replaces the modal
        arrays by those of the pairs of :mod:`tasks.damped_pairs` (``pairs``):
        ``phi`` and ``phi_t_gamma`` become ``V`` and ``L`` (2n x 2n, on the scaled
        state ``(x, r x')``), ``f_slip`` holds (constant load, offset of eta', alpha
        times r) per unit friction force, ``d_static`` (constant load, offset) per
        unit d0, ``g_modes_s`` and ``g_c_s`` the contact force's ``-alpha`` and
        ``-delta / r`` of the stuck pairs; the kernel tells them apart by shape.
        """
        if self.pairs is None and not self.proportional:
            return self._general_args
        if self.pairs is not None:
            return tuple(
                np.ascontiguousarray(a) if isinstance(a, np.ndarray) else a for a in self.pairs
            )
        c = np.ascontiguousarray
        zeros_n, zeros_m = np.zeros(self.n), np.zeros(self.lam_s.shape[0])
        damping_arrays = (
            c(zeros_n if self.damp_slip is None else self.damp_slip),
            c(zeros_m if self.damp_stick is None else self.damp_stick),
            c(zeros_n if self.g_c is None else self.g_c),
            c(zeros_m if self.g_c_s is None else self.g_c_s),
        )
        return (
            c(self.gamma),
            c(self.stiffness),
            c(self.b),
            c(self.p0),
            bool(self.load_scales_r2),
            c(self.lam),
            c(self.phi),
            c(self.phi_t_gamma),
            c(self.w_slip),
            c(self.f_slip),
            c(self.T),
            c(self.w),
            c(self.lam_s),
            c(self.phi_s),
            c(self.phi_s_t_gamma_s),
            c(self.load_s),
            c(self.d_static),
            c(self.proj),
            c(self.g_load),
            c(self.g_modes_s),
            float(self.g_d0),
            *damping_arrays,
            np.zeros((0, 0)),
            np.zeros((0, 0)),
            np.zeros(0),
            np.zeros((0, 0)),
        )


def generalized_modes(K: np.ndarray, G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenpairs of ``K phi = lambda G phi`` with ``phi^T G phi = I``, ascending lambda."""
    if K.shape[0] == 0:
        return np.zeros(0), np.zeros((0, 0))
    lam, phi = eigh(K, G)
    return lam, phi


def inverse_mass_times(G: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``Gamma^-1 v``: elementwise for a diagonal ``Gamma`` (the chain's arithmetic)."""
    d = np.diag(G)
    if np.array_equal(G, np.diag(d)):
        return v / d
    return np.linalg.solve(G, v)


def scene_modes(scene: Scene) -> SceneModes:
    """Modal data of ``scene`` (see :class:`SceneModes`)."""
    K = scene.stiffness_matrix()
    G = scene.mass_matrix(1.0)
    gam = np.diag(G).copy()
    b = scene.contact_vector()
    T, w = scene.stuck_basis()
    lam, phi = generalized_modes(K, G)
    Gs = T.T @ G @ T
    Ks = T.T @ K @ T
    lam_s, phi_s = generalized_modes(Ks, Gs)
    g_b = inverse_mass_times(G, b)
    b_gamma_b = float(b @ g_b)
    g_load = g_b / b_gamma_b
    m = T.shape[1]
    proj = np.linalg.solve(Gs, T.T @ G) if m else np.zeros((0, scene.dof))
    s = scene.structure
    damping = {}
    if s is not None and s.damping is not None:
        rayleigh = s.damping_kind == "rayleigh"
        damping = _modal_damping(np.array(s.damping), phi, phi_s, T, g_load, rayleigh)
    return SceneModes(
        n=scene.dof,
        gamma=gam,
        mass=G,
        stiffness=K,
        b=b,
        p0=scene.load_vector(1.0),
        load_scales_r2=scene.load_scales_r2,
        lam=lam,
        phi=phi,
        phi_t_gamma=phi.T @ G,
        w_slip=b @ phi,
        f_slip=phi.T @ b,
        T=T,
        w=w,
        lam_s=lam_s,
        phi_s=phi_s,
        phi_s_t_gamma_s=phi_s.T @ Gs,
        load_s=phi_s.T @ T.T,
        d_static=phi_s.T @ (T.T @ (K @ w)),
        proj=proj,
        g_load=g_load,
        g_modes_s=(g_load @ K @ T) @ phi_s if m else np.zeros(0),
        g_d0=float(g_load @ K @ w),
        b_gamma_b=b_gamma_b,
        damping=None if s is None or s.damping is None else np.array(s.damping),
        damping_kind="none" if s is None else s.damping_kind,
        **damping,
    )


def _pairs_args(modes: SceneModes, C: np.ndarray) -> tuple:
    """:meth:`SceneModes.kernel_args` of a non-proportionally damped scene: the pairs of
    :mod:`tasks.damped_pairs` of the sliding and the held system (docs/structures.md 4.5).
    ``ValueError`` (one line, ``damping:``) for repeated or defective eigenvalues."""
    n, M, K, b, T, w = modes.n, modes.mass, modes.stiffness, modes.b, modes.T, modes.w
    m = T.shape[1]
    slip = damped_pairs(M, C, K, modes.p0)
    held = damped_pairs(T.T @ M @ T, T.T @ C @ T, T.T @ K @ T, T.T @ modes.p0)
    V, Vs = slip.V, held.V
    tkw = T.T @ (K @ w)
    gkt = modes.g_load @ K @ T
    gct = modes.g_load @ C @ T
    return (
        modes.gamma,
        modes.stiffness,
        modes.b,
        modes.p0,
        bool(modes.load_scales_r2),
        slip.lam,
        V,
        slip.L,
        b @ V[n:, n:],
        np.concatenate([slip.load_nu @ b, slip.load_w @ b, b @ V[n:, :n]]),
        T,
        w,
        held.lam,
        Vs,
        held.L,
        held.load_nu @ T.T,
        np.concatenate([held.load_nu @ tkw, held.load_w @ tkw]),
        modes.proj,
        modes.g_load,
        gkt @ Vs[:m, :m] + gct @ Vs[m:, :m],
        float(modes.g_d0),
        slip.damp,
        held.damp,
        C.T @ modes.g_load,
        gkt @ Vs[:m, m:] + gct @ Vs[m:, m:],
        C,
        slip.load_nu,
        modes.lam,
        modes.phi,
    )


#: Largest off-diagonal entry of ``Phi^T C Phi`` (relative to its diagonal scale)
#: for the damping to count as proportional.
PROPORTIONAL_RTOL = 1e-9
#: ... or at the rounding of forming ``Phi^T C Phi``: this many units of roundoff of
#: its largest entry per DOF (:func:`modal_diagonal`).
ROUNDING_ULPS = 64


def modal_diagonal(A: np.ndarray) -> bool:
    """Whether damping in modal coordinates, ``A = Phi^T C Phi``, is diagonal: every
    off-diagonal entry within ``PROPORTIONAL_RTOL`` of ``sqrt(A_ii A_jj)`` (negligible
    against the two modes' own damping), or at the rounding of ``A`` itself,
    ``ROUNDING_ULPS n eps max|A|`` (an exact ``a M + b K`` formed in floating point
    leaves entries of 1e-11 beside slow modes damped 5e-4 and 1e-3 when its fast modes
    carry 1e3: not a coupling, the roundoff of the product; the random audit's seed 26,
    an 8DOF Rayleigh chain, was refused for it)."""
    if not A.size:
        return True
    d = np.sqrt(np.abs(np.diag(A)))
    off = np.abs(A - np.diag(np.diag(A)))
    floor = ROUNDING_ULPS * A.shape[0] * np.finfo(float).eps * np.abs(A).max()
    return bool(np.all(off <= PROPORTIONAL_RTOL * np.outer(d, d) + floor))


def _modal_damping(C, phi, phi_s, T, g_load, rayleigh=False) -> dict[str, object]:
    """Modal damping of both phases (docs/structures.md 4.1) and whether it is modal
    (``rayleigh``: ``C = a M + b K``, diagonal in the modes of every phase by
    construction, whatever the rounding of ``Phi^T C Phi``)."""
    Cm = phi.T @ C @ phi
    Cs = phi_s.T @ (T.T @ C @ T) @ phi_s if T.shape[1] else np.zeros((0, 0))
    proportional = rayleigh or (modal_diagonal(Cm) and modal_diagonal(Cs))
    return {
        "damp_slip": np.diag(Cm).copy(),
        "damp_stick": np.diag(Cs).copy(),
        "g_c": C.T @ g_load,
        "g_c_s": (g_load @ C @ T) @ phi_s if T.shape[1] else np.zeros(0),
        "proportional": proportional,
    }
