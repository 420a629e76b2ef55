"""Linear algebra of the stuck sets: one linear system per set of stuck contacts.

With k contacts the motion is linear for each set ``S`` of stuck contacts (2^k
sets, a bit mask: bit c set when contact c is stuck; docs/contacts.md 2). While
``S`` is stuck, ``B_S^T x = d_S`` is frozen and

    x = T_S q + W_S d_S,    B_S^T T_S = 0,  B_S^T W_S = I,

``T_S`` an orthonormal basis of the null space of ``B_S^T`` and
``W_S = B_S (B_S^T B_S)^-1``. The moving coordinates obey

    r^2 T^T G T q'' + T^T K T q = T^T (p cos tau - K W d + f_slide),

``f_slide = -sum_(c sliding) beta_c s_c b_c``; its modes ``K_S phi = lam G_S phi``
(``phi^T G_S phi = I``) give ``x = X_S eta + W_S d`` with ``X_S = T_S phi`` and
``eta = X_S^T G (x - W_S d)`` (the momentum-conserving projection; ``X_S^T G X_S = I``).
The forces the stuck contacts must carry are

    g_S = H_S (p cos tau - K x + f_slide),   H_S = (B_S^T G^-1 B_S)^-1 B_S^T G^-1,

(the friction forces are ``-g_S``) and the set stays stuck while ``|g_c| <= beta_c``.
Everything here is independent of r and beta (``M = r^2 G``: ``Omega = sqrt(lam) / r``).

**Damping** ``r C x'`` (docs/contacts.md 7): where ``X_S^T C X_S`` is diagonal
(:func:`tasks.model.modal_diagonal`), as Rayleigh ``C = a G + b K`` always is
(``T^T C T = a G_S + b K_S``), each mode gets ``eta'' + 2 sigma eta' + ...`` with
``sigma = cdiag / (2 r)`` (docs/structures.md 4.1), and the stuck forces their
viscous part, ``g_S = H_S (... - r C x')`` with ``x' = X_S eta'``
(``HCX[S, c, :m] = (H_S C X_S)_c``). Elsewhere (``general[S] = 1``) the set runs
on its damped pairs (docs/structures.md 4.5, :func:`tasks.damped_pairs.damped_pairs`
of ``(T^T G T, T^T C T, T^T K T)`` and ``T^T p``): ``lam``, ``cdiag`` hold the
pairs' ``nu_1 nu_2`` and ``-(nu_1 + nu_2)``, ``X = T load_nu^T`` (so the per-point
loads come out as for modes), and ``Tset``, ``Lset``, ``Vset``, ``Wo = T load_w^T``
the maps of :mod:`tasks.multicontact.viscous`.
Arrays are padded to n modes and k contacts so that the compiled simulator
indexes them by the set's bit mask.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import eigh, null_space

from tasks.model import modal_diagonal
from tasks.multicontact.scene import MultiScene


@dataclass(frozen=True)
class StuckSets:
    """Per-set arrays (leading axis: the set's bit mask), see the module notes.

    ``size[S]`` moving coordinates ``m = n - |S|``; ``lam[S, :m]``; ``X[S, :, :m]``
    (``X_S``); ``XtG[S, :m, :]`` (``X_S^T G``); ``W[S, :, c]`` the column of
    ``W_S`` for stuck contact c (0 otherwise); ``H[S, c, :]`` the row of ``H_S``
    for stuck contact c (0 otherwise); ``HKX[S, c, :m] = (H_S K X_S)_c``;
    ``BX[S, c, :m] = b_c^T X_S`` (contact velocity per modal velocity).
    """

    n: int
    k: int
    G: np.ndarray
    Ginv: np.ndarray
    K: np.ndarray
    p0: np.ndarray
    load_scales_r2: bool
    B: np.ndarray
    ratio: np.ndarray
    compliance: np.ndarray
    size: np.ndarray
    lam: np.ndarray
    X: np.ndarray
    XtG: np.ndarray
    W: np.ndarray
    H: np.ndarray
    HKX: np.ndarray
    BX: np.ndarray
    C: np.ndarray
    cdiag: np.ndarray
    HCX: np.ndarray
    general: np.ndarray
    Tset: np.ndarray
    Lset: np.ndarray
    Vset: np.ndarray
    Wo: np.ndarray

    @property
    def damped(self) -> bool:
        return bool(np.any(self.cdiag))

    def kernel_args(self) -> tuple:
        """The arrays in the order :func:`tasks.multicontact.steady.run_points` takes them."""
        c = np.ascontiguousarray
        return (
            c(self.G),
            c(self.Ginv),
            c(self.K),
            c(self.p0),
            bool(self.load_scales_r2),
            c(self.B),
            c(self.ratio),
            c(self.compliance),
            c(self.size),
            c(self.lam),
            c(self.X),
            c(self.XtG),
            c(self.W),
            c(self.H),
            c(self.HKX),
            c(self.BX),
            c(self.C),
            c(self.cdiag),
            c(self.HCX),
            c(np.linalg.solve(self.K, self.C)),
            c(self.general),
            c(self.Tset),
            c(self.Lset),
            c(self.Vset),
            c(self.Wo),
            self.damped,
        )


def stuck_sets(scene: MultiScene) -> StuckSets:
    """The arrays of every stuck set of ``scene`` (see :class:`StuckSets`).

    Raises
    ------
    ValueError
        One ``damping:`` line when a stuck set's damped pairs are refused
        (docs/structures.md 4.5: repeated or defective eigenvalues).
    """
    G = scene.mass_matrix(1.0)
    K = scene.stiffness_matrix()
    B = scene.contact_vectors()
    n, k = B.shape
    Ginv = np.linalg.inv(G)
    Ginv = 0.5 * (Ginv + Ginv.T)
    n_sets = 1 << k
    size = np.zeros(n_sets, dtype=np.int64)
    lam = np.zeros((n_sets, n))
    X = np.zeros((n_sets, n, n))
    XtG = np.zeros((n_sets, n, n))
    W = np.zeros((n_sets, n, k))
    H = np.zeros((n_sets, k, n))
    HKX = np.zeros((n_sets, k, n))
    BX = np.zeros((n_sets, k, n))
    C = scene.damping_matrix(1.0)
    rayleigh = scene.structures[0].damping_kind == "rayleigh"
    cdiag = np.zeros((n_sets, n))
    HCX = np.zeros((n_sets, k, n))
    general = np.zeros(n_sets)
    Tset = np.zeros((n_sets, n, n))
    Lset = np.zeros((n_sets, 2 * n, 2 * n))
    Vset = np.zeros((n_sets, 2 * n, 2 * n))
    Wo = np.zeros((n_sets, n, n))
    p0 = scene.load_vector(1.0)
    for S in range(n_sets):
        stuck = [c for c in range(k) if S >> c & 1]
        Bs = B[:, stuck]
        m = n - len(stuck)
        size[S] = m
        T = null_space(Bs.T) if stuck else np.eye(n)
        if m:
            Gs = T.T @ G @ T
            Ks = T.T @ K @ T
            lam_s, phi = eigh(0.5 * (Ks + Ks.T), 0.5 * (Gs + Gs.T))
            Xs = T @ phi
            lam[S, :m] = lam_s
            X[S, :, :m] = Xs
            XtG[S, :m, :] = Xs.T @ G
            BX[S, :, :m] = B.T @ Xs
            if scene.damped:
                held = [scene.contacts[c] for c in stuck]
                diag = _modal_damping(Xs.T @ C @ Xs, rayleigh)
                if diag is not None:
                    cdiag[S, :m] = diag
                else:  # the damped pairs of the set (docs/structures.md 4.5)
                    pairs = _pairs(Gs, T.T @ C @ T, Ks, T.T @ p0, held)
                    general[S] = 1.0
                    lam[S, :m] = pairs.lam
                    cdiag[S, :m] = pairs.damp
                    X[S, :, :m] = T @ pairs.load_nu.T
                    Tset[S, :, :m] = T
                    Lset[S, : 2 * m, : 2 * m] = pairs.L
                    Vset[S, : 2 * m, : 2 * m] = pairs.V
                    Wo[S, :, :m] = T @ pairs.load_w.T
        if stuck:
            Ws = Bs @ np.linalg.inv(Bs.T @ Bs)
            Hs = np.linalg.solve(Bs.T @ Ginv @ Bs, Bs.T @ Ginv)
            for i, c in enumerate(stuck):
                W[S, :, c] = Ws[:, i]
                H[S, c, :] = Hs[i]
                if m:
                    HKX[S, c, :m] = Hs[i] @ K @ X[S, :, :m]
                    HCX[S, c, :m] = Hs[i] @ C @ X[S, :, :m]
    compliance = np.einsum("ik,ik->k", B, np.linalg.solve(K, B))
    return StuckSets(
        n=n,
        k=k,
        G=G,
        Ginv=Ginv,
        K=K,
        p0=scene.load_vector(1.0),
        load_scales_r2=scene.load_scales_r2,
        B=B,
        ratio=np.array(scene.beta_ratio),
        compliance=compliance,
        size=size,
        lam=lam,
        X=X,
        XtG=XtG,
        W=W,
        H=H,
        HKX=HKX,
        BX=BX,
        C=C,
        cdiag=cdiag,
        HCX=HCX,
        general=general,
        Tset=Tset,
        Lset=Lset,
        Vset=Vset,
        Wo=Wo,
    )


def _modal_damping(Cs: np.ndarray, rayleigh: bool) -> np.ndarray | None:
    """The diagonal of ``Cs = X_S^T C X_S``, or None when it is not diagonal
    (:func:`tasks.model.modal_diagonal`; a Rayleigh ``C`` always is)."""
    if not (rayleigh or modal_diagonal(Cs)):
        return None
    return np.maximum(np.diag(Cs).copy(), 0.0)


def _pairs(Gs, Cs, Ks, ps, held: list):
    """:func:`tasks.damped_pairs.damped_pairs` of one stuck set, or its ValueError with
    the set named (one ``damping:`` line)."""
    from tasks.damped_pairs import damped_pairs

    try:
        return damped_pairs(0.5 * (Gs + Gs.T), 0.5 * (Cs + Cs.T), 0.5 * (Ks + Ks.T), ps)
    except ValueError as exc:
        where = f"with {held} held" if held else "without contacts held"
        raise ValueError(f"{str(exc).rstrip('.')} (the structure {where})") from None
