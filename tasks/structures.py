"""Continuous structures as scenes: an Euler-Bernoulli beam by finite elements.

The beam (docs/structures.md 2) has bending stiffness EI, mass per length m and
length L; lengths are in units of L, masses of ``m L`` and stiffnesses of
``EI / L^3``. Hermite cubic elements (two nodes, DOFs ``(w, theta)`` per node) give
the consistent element matrices (Eqs. 2.1-2.2 of docs/structures.md)

    K_e = (1/h^3) [[12, 6h, -12, 6h], [6h, 4h^2, -6h, 2h^2],
                   [-12, -6h, 12, -6h], [6h, 2h^2, -6h, 4h^2]],
    M_e = (h/420) [[156, 22h, 54, -13h], [22h, 4h^2, 13h, -3h^2],
                   [54, 13h, 156, -22h], [-13h, -3h^2, -22h, 4h^2]],

``h = 1 / n_elements``. Supports: ``"cantilever"`` (clamped at x = 0),
``"pinned"`` (pinned-pinned: w = 0 at both ends) or ``"free"`` (free-free on two
translational springs of stiffness ``support_stiffness`` at the ends; without
them K is singular and a rigid body would slide away under friction).

The scene (:func:`beam`) refers r to the first natural frequency of the beam
without contact: ``K`` is divided by its first eigenvalue ``lambda_1``, so that
``r = omega / omega_1`` (Eq. 2.3), and the load has unit amplitude, so that
``beta = F / P`` (friction limit over load amplitude; base excitation:
``beta = F / (k_ref Y)`` with ``k_ref = lambda_1 EI / L^3``). The contact is a
Coulomb contact to ground on the transverse DOF of one node, or of each of several
nodes (a :class:`tasks.multicontact.MultiScene`, docs/contacts.md). Optionally the
model is reduced by Craig-Bampton (:func:`craig_bampton`, docs/structures.md 2.2):
the contact DOFs stay physical (the boundary), the rest is represented by its
first ``modes`` fixed-interface modes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import eigh

from tasks.multicontact.scene import MAX_CONTACTS
from tasks.scene import Scene

SUPPORTS = ("cantilever", "pinned", "free")
LOADS = ("tip", "distributed", "base")


def element_matrices(h: float) -> tuple[np.ndarray, np.ndarray]:
    """Consistent mass and stiffness of one Hermite cubic element of length ``h``
    (EI = m = 1; Eqs. 2.1-2.2 of docs/structures.md)."""
    k = (
        np.array(
            [
                [12.0, 6 * h, -12.0, 6 * h],
                [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                [-12.0, -6 * h, 12.0, -6 * h],
                [6 * h, 2 * h * h, -6 * h, 4 * h * h],
            ]
        )
        / h**3
    )
    m = (
        np.array(
            [
                [156.0, 22 * h, 54.0, -13 * h],
                [22 * h, 4 * h * h, 13 * h, -3 * h * h],
                [54.0, 13 * h, 156.0, -22 * h],
                [-13 * h, -3 * h * h, -22 * h, 4 * h * h],
            ]
        )
        * h
        / 420.0
    )
    return m, k


@dataclass(frozen=True)
class BeamModel:
    """Assembled, supported beam (units of docs/structures.md 2).

    Attributes
    ----------
    mass, stiffness : ndarray
        ``M`` and ``K`` on the free DOFs (not yet scaled by ``lambda_1``).
    dofs : ndarray of int
        Global DOF (``2 node + 0`` for w, ``+ 1`` for theta) of each free DOF.
    n_elements : int
    supports : str
    """

    mass: np.ndarray
    stiffness: np.ndarray
    dofs: np.ndarray
    n_elements: int
    supports: str

    def index(self, node: int, rotation: bool = False) -> int:
        """Position of the DOF (w, or theta) of ``node`` among the free DOFs."""
        g = 2 * node + int(rotation)
        hit = np.flatnonzero(self.dofs == g)
        if hit.size == 0:
            raise ValueError(f"contact_node: node {node} is held by the supports")
        return int(hit[0])

    def natural_frequencies(self) -> np.ndarray:
        """``omega_i`` in units of ``sqrt(EI / (m L^4))``, ascending."""
        return np.sqrt(eigh(self.stiffness, self.mass, eigvals_only=True))

    def load_vector(self, load: str) -> np.ndarray:
        """Unit tip force, uniform load of unit total (consistent nodal loads), or the
        influence vector of a support translation (w = 1, theta = 0)."""
        n_nodes = self.n_elements + 1
        full = np.zeros(2 * n_nodes)
        if load == "tip":
            full[2 * (n_nodes - 1)] = 1.0
        elif load == "distributed":
            h = 1.0 / self.n_elements
            for e in range(self.n_elements):
                full[2 * e : 2 * e + 4] += h * np.array([0.5, h / 12.0, 0.5, -h / 12.0])
        else:  # base: rigid translation of the supports
            full[0::2] = 1.0
        return full[self.dofs]


def beam_model(
    n_elements: int = 20, supports: str = "cantilever", support_stiffness: float | None = None
) -> BeamModel:
    """Assemble the beam on its supports (see the module notes)."""
    if isinstance(n_elements, bool) or not isinstance(n_elements, int | np.integer):
        raise ValueError(f"n_elements: must be an integer >= 1, got {n_elements!r}")
    if not 1 <= n_elements <= 99:
        raise ValueError(f"n_elements: must be in 1..99, got {n_elements}")
    if supports not in SUPPORTS:
        raise ValueError(f"supports: must be one of {SUPPORTS}, got {supports!r}")
    n_nodes = n_elements + 1
    me, ke = element_matrices(1.0 / n_elements)
    M = np.zeros((2 * n_nodes, 2 * n_nodes))
    K = np.zeros_like(M)
    for e in range(n_elements):
        sl = slice(2 * e, 2 * e + 4)
        M[sl, sl] += me
        K[sl, sl] += ke
    held: list[int] = []
    if supports == "cantilever":
        held = [0, 1]
    elif supports == "pinned":
        held = [0, 2 * (n_nodes - 1)]
    else:
        ks = support_stiffness
        if ks is None or not (np.isfinite(ks) and ks > 0.0):
            raise ValueError(
                "support_stiffness: a free-free beam needs end springs > 0 (units EI/L^3)"
            )
        K[0, 0] += ks
        K[-2, -2] += ks
    if supports != "free" and support_stiffness is not None:
        raise ValueError("support_stiffness: only for supports = 'free'")
    dofs = np.array([g for g in range(2 * n_nodes) if g not in held])
    sel = np.ix_(dofs, dofs)
    return BeamModel(M[sel], K[sel], dofs, int(n_elements), supports)


def craig_bampton(
    mass: np.ndarray, stiffness: np.ndarray, boundary: list[int], modes: int
) -> np.ndarray:
    """Craig-Bampton basis ``V`` (docs/structures.md 2.2): ``x = V (x_b, eta)``.

    Columns: the static constraint modes of the ``boundary`` DOFs (unit
    displacement of one boundary DOF, the others held, interior statically
    condensed), then the first ``modes`` normal modes of the interior with the
    boundary held (mass-normalised). The boundary DOFs keep their physical
    meaning: rows ``boundary`` of ``V`` are ``[I, 0]``.
    """
    n = mass.shape[0]
    interior = np.array([i for i in range(n) if i not in boundary])
    bnd = np.array(boundary)
    V = np.zeros((n, len(boundary) + modes))
    V[bnd, : len(boundary)] = np.eye(len(boundary))
    Kii = stiffness[np.ix_(interior, interior)]
    V[np.ix_(interior, np.arange(len(boundary)))] = -np.linalg.solve(
        Kii, stiffness[np.ix_(interior, bnd)]
    )
    if modes:
        _, phi = eigh(Kii, mass[np.ix_(interior, interior)], subset_by_index=[0, modes - 1])
        V[np.ix_(interior, np.arange(len(boundary), len(boundary) + modes))] = phi
    return V


def _contact_nodes(contact_node: object, n_elements: int, supports: str) -> list[int]:
    """The contact nodes as a list (one node, or several for several contacts)."""
    if contact_node is None:
        return [n_elements // 2 if supports == "pinned" else n_elements]
    several = isinstance(contact_node, list | tuple | np.ndarray)
    nodes = list(contact_node) if several else [contact_node]
    if several and not 2 <= len(nodes) <= MAX_CONTACTS:
        raise ValueError(f"contact_node: a list of 2..{MAX_CONTACTS} nodes, got {len(nodes)}")
    for node in nodes:
        if isinstance(node, bool) or not isinstance(node, int | np.integer):
            raise ValueError(f"contact_node: must be an integer node, got {node!r}")
        if not 0 <= node <= n_elements:
            raise ValueError(f"contact_node: must be in 0..{n_elements}, got {node}")
    if len(set(nodes)) < len(nodes):
        raise ValueError(f"contact_node: a node is listed twice, got {nodes}")
    return [int(n) for n in nodes]


def beam(
    n_elements: int = 20,
    supports: str = "cantilever",
    contact_node: int | list[int] | None = None,
    load: str = "tip",
    modes: int | None = None,
    damping: object = None,
    support_stiffness: float | None = None,
    beta_ratio: list[float] | None = None,
) -> Scene:
    """A beam with a Coulomb contact to ground at one node (or at several), as a scene.

    Parameters
    ----------
    n_elements : int
        Hermite cubic elements (1..99).
    supports : {"cantilever", "pinned", "free"}
    contact_node : int or list of int, optional
        Node (0 at x = 0, ``n_elements`` at x = L) whose transverse DOF has the
        contact; default: the tip (cantilever, free) or midspan (pinned). A list
        of 2..4 nodes gives a contact on each (a
        :class:`tasks.multicontact.MultiScene`, docs/contacts.md), contact c on
        ``contact_node[c]``.
    load : {"tip", "distributed", "base"}
        Unit harmonic force at the last node, uniform load of unit total, or a
        translation of the supports (cantilever and pinned; coordinates relative
        to the supports).
    modes : int, optional
        Reduce by Craig-Bampton to the contact DOFs plus this many fixed-interface
        modes (docs/structures.md 2.2); None keeps every DOF.
    damping : optional
        As :meth:`tasks.scene.Scene.from_matrices` (on the scaled, reduced matrices).
    support_stiffness : float, optional
        End springs of a free-free beam (units EI/L^3).
    beta_ratio : list of float, optional
        Several contacts only: ``beta_c = beta_ratio[c] * beta`` (default all 1).

    Returns
    -------
    Scene or MultiScene
        ``r`` referred to the first natural frequency without contact; the
        contact DOFs are DOFs ``0..k-1`` of a reduced scene.
    """
    model = beam_model(n_elements, supports, support_stiffness)
    if load not in LOADS:
        raise ValueError(f"load: must be one of {LOADS}, got {load!r}")
    if load == "base" and supports == "free":
        raise ValueError("load: a free-free beam has no supports to move ('base')")
    nodes = _contact_nodes(contact_node, n_elements, supports)
    several = isinstance(contact_node, list | tuple | np.ndarray)
    if beta_ratio is not None and not several:
        raise ValueError("beta_ratio: applies to several contact nodes (a list contact_node)")
    js = [model.index(node) for node in nodes]
    lam1 = eigh(model.stiffness, model.mass, eigvals_only=True, subset_by_index=[0, 0])[0]
    M, K = model.mass, model.stiffness / lam1
    vec = model.load_vector(load)
    if modes is not None:
        n = M.shape[0]
        if isinstance(modes, bool) or not isinstance(modes, int | np.integer):
            raise ValueError(f"modes: must be an integer, got {modes!r}")
        if not 1 <= modes <= n - len(js):
            raise ValueError(f"modes: must be in 1..{n - len(js)} for this mesh, got {modes}")
        V = craig_bampton(M, K, js, int(modes))
        Mr, Kr = V.T @ M @ V, V.T @ K @ V
        if load == "base":  # p = r^2 V^T M u = r^2 M_r u_r
            vec = np.linalg.solve(Mr, V.T @ (M @ vec))
        else:
            vec = V.T @ vec
        M, K, js = 0.5 * (Mr + Mr.T), 0.5 * (Kr + Kr.T), list(range(len(js)))
    load_arg = ("base", vec) if load == "base" else vec
    if several:
        contacts = [("ground", j) for j in js]
        return Scene.from_matrices(
            M, K, load_arg, contacts, damping=damping, beta_ratio=beta_ratio or [1.0] * len(js)
        )
    return Scene.from_matrices(M, K, load_arg, ("ground", js[0]), damping=damping)
