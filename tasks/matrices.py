"""The validated matrices of a scene given as a linear structure (docs/structures.md 1).

A structure with one Coulomb contact obeys, in dimensionless time ``tau = omega t``,

    r^2 M x'' + r C x' + K x + beta s b = p cos(tau),                        (1.1)

``M``, ``C`` and ``K`` in units of a reference mass ``m_ref``, damping
``sqrt(k_ref m_ref)`` and stiffness ``k_ref`` (so ``r = omega sqrt(m_ref/k_ref)``,
``beta = F / (k_ref Y)``, Eqs. 7-8 of the paper for a chain with ``m_ref = m_1``,
``k_ref = k_1``), ``b`` the contact direction and ``p`` the load amplitude.
This module checks user matrices once and stores them, hashable, for
:class:`tasks.scene.Scene` (:meth:`tasks.scene.Scene.from_matrices`).

Load: a vector ``p``, or ``("base", u)``: the supports move as ``u Y cos(tau)``
(``u`` the influence vector, all ones for a chain), the coordinates are relative
to them and the load is inertial, ``p = r^2 M u`` (docs/theory.md 2, Eq. 98).
The damping then acts on the relative velocities (dampers to the moving supports).

Contact: ``("ground", j)`` (``b = e_j``) or ``("between", i, j)``
(``b = e_j - e_i``, the slip velocity ``x_j' - x_i'``), DOF indices from 0.

Damping: ``None``, a matrix ``C`` (symmetric positive semidefinite),
``("rayleigh", a, b)`` (``C = a M + b K``) or ``("modal", zeta)`` (damping
ratios of the modes of ``(K, M)``: ``C = M Phi diag(2 zeta_i sqrt(lambda_i)) Phi^T M``
with ``Phi^T M Phi = I``, docs/structures.md 1). Zero damping of any kind is no
damping (the undamped simulator, bit for bit).
"""

from __future__ import annotations

from dataclasses import dataclass
from numbers import Integral, Real

import numpy as np
from scipy.linalg import eigh

#: Largest number of DOFs of a structure (a beam of 100 elements, or its modes).
MAX_MATRIX_DOF = 200
#: Largest ratio of the largest to the smallest eigenvalue of (K, M): the natural
#: frequencies then stay within 1e6 of each other, the range of the chain ratios
#: (tasks.scene.RATIO_RANGE) where the simulator's brackets stay affordable.
MAX_EIGEN_SPREAD = 1e12
#: Relative asymmetry tolerated (rounding of a user's assembly), then symmetrised.
SYMMETRY_RTOL = 1e-10
DAMPING_KINDS = ("none", "matrix", "rayleigh", "modal")


def _is_int(v: object) -> bool:
    return isinstance(v, Integral) and not isinstance(v, bool | np.bool_)


def _is_real(v: object) -> bool:
    return isinstance(v, Real) and not isinstance(v, bool | np.bool_)


def _numbers(name: str, value: object, ndim: int) -> np.ndarray:
    """``value`` as a finite float array of ``ndim`` dimensions, or a ValueError."""
    if isinstance(value, str | bytes):
        raise ValueError(f"{name}: expected an array of numbers, got the string {value!r}")
    try:
        arr = np.array(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected an array of numbers, got {value!r}"[:200]) from None
    if arr.dtype.kind not in "iuf":
        raise ValueError(f"{name}: expected an array of numbers, got {arr.dtype} {value!r}"[:200])
    if arr.ndim != ndim:
        what = "a square matrix" if ndim == 2 else "a vector"
        raise ValueError(f"{name}: expected {what}, got an array of shape {arr.shape}")
    arr = arr.astype(np.float64)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: every entry must be finite")
    return arr


def _square(name: str, value: object, n: int | None) -> np.ndarray:
    arr = _numbers(name, value, 2)
    if arr.shape[0] != arr.shape[1] or arr.shape[0] == 0:
        raise ValueError(f"{name}: expected a square matrix, got shape {arr.shape}")
    if n is not None and arr.shape[0] != n:
        raise ValueError(f"{name}: expected shape ({n}, {n}) like mass, got {arr.shape}")
    scale = np.max(np.abs(arr))
    asym = np.max(np.abs(arr - arr.T))
    if asym > SYMMETRY_RTOL * scale:
        raise ValueError(f"{name}: must be symmetric, largest |A - A^T| is {asym:.3g}")
    return 0.5 * (arr + arr.T)  # exact no-op for a symmetric matrix


def _positive_definite(name: str, arr: np.ndarray) -> None:
    try:
        np.linalg.cholesky(arr)
    except np.linalg.LinAlgError:
        raise ValueError(f"{name}: must be positive definite") from None


def _vector(name: str, value: object, n: int) -> np.ndarray:
    arr = _numbers(name, value, 1)
    if arr.shape != (n,):
        raise ValueError(f"{name}: expected {n} numbers (one per DOF), got shape {arr.shape}")
    return arr


def _contact(value: object, n: int) -> tuple[tuple, np.ndarray]:
    """Contact spec and its direction ``b``."""
    rule = "expected ('ground', j) or ('between', i, j) with DOF indices from 0"
    if not isinstance(value, tuple | list) or not value or value[0] not in ("ground", "between"):
        raise ValueError(f"contact: {rule}, got {value!r}")
    kind, idx = value[0], tuple(value[1:])
    if len(idx) != (1 if kind == "ground" else 2) or not all(_is_int(i) for i in idx):
        raise ValueError(f"contact: {rule}, got {value!r}")
    idx = tuple(int(i) for i in idx)
    for i in idx:
        if not 0 <= i < n:
            raise ValueError(f"contact: DOF index {i} is outside the DOFs 0..{n - 1}")
    b = np.zeros(n)
    if kind == "between":
        if idx[0] == idx[1]:
            raise ValueError(f"contact: 'between' needs two different DOFs, got {value!r}")
        b[idx[0]] = -1.0
    b[idx[-1]] = 1.0
    return (kind, *idx), b


def _load(value: object, mass: np.ndarray) -> tuple[object, np.ndarray, bool]:
    """Load spec (as given back by ``Scene.matrices``), ``p_hat`` and whether it scales as r^2."""
    n = mass.shape[0]
    base = isinstance(value, tuple | list) and len(value) == 2 and value[0] == "base"
    if base:
        u = _vector("load", value[1], n)
        if not np.any(u):
            raise ValueError("load: the influence vector u of ('base', u) must not be zero")
        return ("base", u), mass @ u, True
    p = _vector("load", value, n)
    if not np.any(p):
        raise ValueError("load: must not be zero (nothing would move)")
    return p, p, False


def _modal_damping(zeta: object, mass: np.ndarray, stiffness: np.ndarray) -> np.ndarray:
    n = mass.shape[0]
    z = np.full(n, float(zeta)) if _is_real(zeta) else _vector("damping", zeta, n)
    if np.any(z < 0.0) or not np.all(np.isfinite(z)):
        raise ValueError("damping: modal damping ratios must be finite and >= 0")
    lam, phi = eigh(stiffness, mass)
    mp = mass @ phi
    with np.errstate(over="ignore", invalid="ignore"):
        return _finite((mp * (2.0 * z * np.sqrt(lam))) @ mp.T), z


def _finite(C: np.ndarray) -> np.ndarray:
    """``C`` when every entry is finite, else a ValueError naming damping (coefficients
    so large that C overflows)."""
    if not np.all(np.isfinite(C)):
        raise ValueError("damping: too large: the damping matrix C overflows")
    return C


def _damping(value: object, mass: np.ndarray, stiffness: np.ndarray):
    """``(kind, spec, C)``: kind in :data:`DAMPING_KINDS`, ``C`` None when undamped."""
    if value is None:
        return "none", None, None
    if isinstance(value, tuple | list) and value and isinstance(value[0], str):
        kind = value[0]
        if kind == "rayleigh":
            if len(value) != 3 or not all(_is_real(v) for v in value[1:]):
                raise ValueError(f"damping: expected ('rayleigh', a, b), got {value!r}")
            a, b = float(value[1]), float(value[2])
            if not (np.isfinite(a) and np.isfinite(b) and a >= 0.0 and b >= 0.0):
                raise ValueError(
                    f"damping: Rayleigh coefficients must be finite and >= 0: {value!r}"
                )
            if a == 0.0 and b == 0.0:
                return "none", None, None
            with np.errstate(over="ignore", invalid="ignore"):
                C = _finite(a * mass + b * stiffness)
            return "rayleigh", ("rayleigh", a, b), C
        if kind == "modal":
            if len(value) != 2:
                raise ValueError(f"damping: expected ('modal', zeta), got {value!r}")
            C, z = _modal_damping(value[1], mass, stiffness)
            if not np.any(z):
                return "none", None, None
            return "modal", ("modal", z), 0.5 * (C + C.T)
        raise ValueError(
            f"damping: expected a matrix, ('rayleigh', a, b) or ('modal', zeta), got {value!r}"[
                :200
            ]
        )
    C = _square("damping", value, mass.shape[0])
    if not np.any(C):
        return "none", None, None
    ev = np.linalg.eigvalsh(C)
    if ev[0] < -1e-12 * max(abs(ev[-1]), 1e-300):
        raise ValueError("damping: must be positive semidefinite (it would feed energy)")
    return "matrix", C, C


@dataclass(frozen=True, eq=False)
class StructureMatrices:
    """The matrices of Eq. (1.1) of one structure, validated (see the module notes).

    Attributes
    ----------
    mass, stiffness : ndarray (n, n)
        ``M`` and ``K``, symmetric positive definite.
    load : ndarray (n,)
        ``p_hat``: the load is ``p = p_hat`` or, for a base load, ``r^2 p_hat``.
    load_scales_r2 : bool
        Base load (``p_hat = M u``).
    b : ndarray (n,)
        Contact direction.
    damping : ndarray (n, n) or None
        ``C`` (None: undamped).
    damping_kind : str
        One of :data:`DAMPING_KINDS`.
    contact : tuple
        ``("ground", j)`` or ``("between", i, j)``.
    load_spec, damping_spec : object
        As accepted by :meth:`tasks.scene.Scene.from_matrices` (round trip).
    """

    mass: np.ndarray
    stiffness: np.ndarray
    load: np.ndarray
    load_scales_r2: bool
    b: np.ndarray
    damping: np.ndarray | None
    damping_kind: str
    contact: tuple
    load_spec: object
    damping_spec: object

    @property
    def dof(self) -> int:
        return self.mass.shape[0]

    def _key(self) -> tuple:
        arrays = [self.mass, self.stiffness, self.load, self.b]
        if self.damping is not None:
            arrays.append(self.damping)
        return (
            self.dof,
            self.contact,
            self.load_scales_r2,
            self.damping_kind,
            tuple(a.tobytes() for a in arrays),
        )

    def __eq__(self, other: object) -> bool:
        return isinstance(other, StructureMatrices) and self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def kwargs(self) -> dict[str, object]:
        """The keyword arguments of :meth:`tasks.scene.Scene.from_matrices` (copies)."""

        def copy(v):
            if isinstance(v, np.ndarray):
                return v.copy()
            if isinstance(v, tuple):
                return tuple(copy(x) for x in v)
            return v

        return {
            "mass": self.mass.copy(),
            "stiffness": self.stiffness.copy(),
            "load": copy(self.load_spec),
            "contact": self.contact,
            "damping": copy(self.damping_spec),
        }


def structure_matrices(mass, stiffness, load, contact, damping=None) -> StructureMatrices:
    """Validate the matrices of Eq. (1.1); one ``ValueError`` naming the argument."""
    M = _square("mass", mass, None)
    n = M.shape[0]
    if n > MAX_MATRIX_DOF:
        raise ValueError(f"mass: at most {MAX_MATRIX_DOF} DOFs (reduce to modes), got {n}")
    _positive_definite("mass", M)
    K = _square("stiffness", stiffness, n)
    _positive_definite("stiffness", K)
    lam = eigh(K, M, eigvals_only=True)
    if lam[-1] > MAX_EIGEN_SPREAD * lam[0]:
        raise ValueError(
            f"stiffness: the eigenvalues of (K, M) spread over {lam[-1] / lam[0]:.3g}, more than "
            f"{MAX_EIGEN_SPREAD:g} (natural frequencies over 1e6): reduce to fewer modes"
        )
    load_spec, p_hat, scales = _load(load, M)
    contact_spec, b = _contact(contact, n)
    kind, damping_spec, C = _damping(damping, M, K)
    for arr in (M, K, p_hat, b, C):
        if arr is not None:
            arr.setflags(write=False)
    return StructureMatrices(
        mass=M,
        stiffness=K,
        load=p_hat,
        load_scales_r2=scales,
        b=b,
        damping=C,
        damping_kind=kind,
        contact=contact_spec,
        load_spec=load_spec,
        damping_spec=damping_spec,
    )
