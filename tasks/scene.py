"""A scene: one chain of masses with one Coulomb contact (docs/theory.md sections 1-2).

All three contact configurations of the paper are written in one form,

    M x'' + K x = p cos(tau) + F_c b,                                  (*)

with the contact force ``F_c = -beta sgn(b . x')`` while sliding and
``|F_c| <= beta`` while stuck:

========  ===============  ==================  ==================================
contact   coordinates      load vector ``p``   contact direction ``b``
========  ===============  ==================  ==================================
ground    x (Eqs. 4, 65)   e_1                 e_j
base      z = x - y 1      M 1 (Eq. 98)        e_j
mass      x (Eq. 99)       e_1                 e_(j+1) - e_j (relative x_(j+1) - x_j)
========  ===============  ==================  ==================================

with ``M = r^2 diag(gamma)`` (Eq. 68) and ``K`` tridiagonal (Eq. 69). For the
mass contact the spring kappa_(j+1) joining masses j and j+1 is in parallel with
the contact (Fig. 16a), and the chain may have any number of masses.

While stuck, ``b . x`` is frozen: ``x = T q + d0 w`` with ``b^T T = 0`` and
``b^T w = 1``; the stuck mass leaves the state (ground, base) or the pair merges
into one mass (mass contact), so only N - 1 coordinates move (Eqs. 131-135).

**Any linear structure** (docs/structures.md 1): :meth:`Scene.from_matrices`
takes the matrices of the dimensionless equation

    r^2 M x'' + r C x' + K x + beta s b = p cos(tau),

with ``M``, ``C``, ``K`` in units of a reference mass, damping and stiffness
(a chain: ``M = diag(gamma)``, Eq. 68; ``K`` of Eq. 69; no damping), so that a
chain is the special case (:meth:`Scene.matrices`). Its validation and storage
live in :mod:`tasks.matrices`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from numbers import Real

import numpy as np

from tasks.matrices import StructureMatrices, structure_matrices

CONTACTS = ("ground", "base", "mass")
#: The contact of a scene given by its matrices (:meth:`Scene.from_matrices`).
MATRICES = "matrices"


#: Range of the mass and stiffness ratios gamma_i, kappa_i (Eqs. 66-67) where the
#: modal data, the closed forms and the kernel are sound in double precision: the
#: modal frequencies then stay within about 1e6 of each other, so the brackets of
#: the shortest modal half-period still resolve the slowest motion in bounded work.
RATIO_RANGE = (1e-6, 1e6)
#: Largest chain handled (``dof``): the study files and tests go to 20 masses.
MAX_DOF = 100


def _shown(v: object) -> str:
    """``repr(v)`` on one line, at most 60 characters (error messages stay one line)."""
    s = " ".join(repr(v).split())
    return s if len(s) <= 60 else s[:57] + "..."


def _is_real(v: object) -> bool:
    """A real number, not a bool (``True`` is an ``int`` in Python) nor a string."""
    return isinstance(v, Real) and not isinstance(v, bool | np.bool_)


def _ratio_vector(name: str, value: float | Sequence[float], dof: int) -> tuple[float, ...]:
    """Ratios of masses (or springs) 2..dof from a number or a sequence of dof - 1 numbers."""
    if isinstance(value, bool | np.bool_):
        raise ValueError(f"{name}: expected a positive number or {dof - 1} numbers, got a bool")
    if isinstance(value, str | bytes):
        raise ValueError(
            f"{name}: expected a positive number or {dof - 1} numbers, got the string {value!r}"
        )
    if _is_real(value):
        values = (float(value),) * (dof - 1)
    else:
        try:
            items = list(value)
        except TypeError:
            raise ValueError(
                f"{name}: expected a positive number or a sequence of {dof - 1} numbers, "
                f"got {_shown(value)}"
            ) from None
        bad = [v for v in items if not _is_real(v)]
        if bad:
            raise ValueError(f"{name}: every ratio must be a number, got {bad[0]!r}")
        values = tuple(float(v) for v in items)
        if len(values) != dof - 1:
            raise ValueError(
                f"{name}: a sequence must have dof - 1 = {dof - 1} entries "
                f"(ratios of masses/springs 2..{dof}), got {len(values)}"
            )
    lo, hi = RATIO_RANGE
    for v in values:
        if not np.isfinite(v) or v <= 0.0:
            raise ValueError(f"{name}: every ratio must be positive and finite, got {v!r}")
        if not lo <= v <= hi:
            raise ValueError(f"{name}: every ratio must be in [{lo:g}, {hi:g}], got {v!r}")
    return values


@dataclass(frozen=True)
class Scene:
    """A chain of ``dof`` masses with one Coulomb contact.

    Parameters
    ----------
    contact : {"ground", "base", "mass"}
        Ground-fixed wall (Sect. 2), base-fixed wall (Sect. 3) or contact
        between masses ``contact_mass`` and ``contact_mass + 1`` (Sect. 4).
    dof : int
        Number of masses N >= 1 (``"mass"`` needs N >= 2).
    contact_mass : int
        1-based index j of the mass in contact (``"mass"``: the lower mass of
        the pair, 1 <= j <= N - 1).
    gamma, kappa : float or sequence of float
        Mass ratios gamma_i = m_i/m_1 and stiffness ratios kappa_i = k_i/k_1 for
        i = 2..N (Eqs. 66-67): one number for all, or N - 1 numbers.

    Raises
    ------
    ValueError
        Naming the field and the rule it breaks.
    """

    contact: str
    dof: int
    contact_mass: int = 1
    gamma: float | tuple[float, ...] = 1.0
    kappa: float | tuple[float, ...] = 1.0
    gammas: tuple[float, ...] = field(init=False, repr=False, compare=False)
    kappas: tuple[float, ...] = field(init=False, repr=False, compare=False)
    structure: StructureMatrices | None = field(default=None, repr=False)

    def __new__(cls, *args, **kwargs):
        # a list of contact masses: several contacts (tasks.multicontact, docs/contacts.md)
        masses = kwargs.get("contact_mass", args[2] if len(args) > 2 else None)
        if isinstance(masses, list | tuple):
            from tasks.multicontact import MultiScene

            return MultiScene.chain(*args, **kwargs)
        return super().__new__(cls)

    @classmethod
    def from_matrices(
        cls, mass, stiffness, load, contact, *, damping=None, beta_ratio=None
    ) -> Scene:
        """A scene of any linear structure (docs/structures.md 1, Eq. 1.1).

        ``r^2 M x'' + r C x' + K x + beta s b = p cos(tau)``, with M, C, K in units
        of a reference mass, damping and stiffness (a chain: :meth:`matrices`).

        Parameters
        ----------
        mass, stiffness : array_like (n, n)
            ``M`` and ``K``: symmetric positive definite.
        load : array_like (n,) or ("base", u)
            The load amplitude ``p``, or a base excitation with influence vector
            ``u`` (coordinates relative to the supports, ``p = r^2 M u``).
        contact : ("ground", j) or ("between", i, j)
            ``b = e_j`` or ``b = e_j - e_i``; DOF indices from 0.
        damping : None, array_like (n, n), ("rayleigh", a, b) or ("modal", zeta)
            ``C``, symmetric positive semidefinite; ``a M + b K``; or damping
            ratios of the modes of ``(K, M)`` (one number for all, or n numbers).
            The simulator propagates every phase exactly: in the modes when C is
            proportional in both the sliding and the held system (Rayleigh
            always), otherwise in the real pairs of the damped eigenvalues
            (docs/structures.md 4.5).

        Raises
        ------
        ValueError
            One line naming the argument and the rule it breaks. The simulator
            (not this constructor) refuses, with one ``damping:`` line, a
            non-proportional C whose damped eigenvalues coincide or are
            defective (e.g. a critically damped mode), docs/structures.md 4.5.

        A list of contacts (``[("ground", 1), ("between", 2, 3)]``) with
        ``beta_ratio`` gives a :class:`tasks.multicontact.MultiScene` (docs/contacts.md).
        """
        if beta_ratio is not None or (
            isinstance(contact, list | tuple) and contact and not isinstance(contact[0], str)
        ):
            from tasks.multicontact import MultiScene

            return MultiScene.from_matrices(
                mass, stiffness, load, contact, beta_ratio=beta_ratio, damping=damping
            )
        data = structure_matrices(mass, stiffness, load, contact, damping)
        return cls(MATRICES, data.dof, data.contact[-1] + 1, structure=data)

    def __post_init__(self) -> None:
        matrices = isinstance(self.contact, str) and self.contact == MATRICES
        if matrices or self.structure is not None:
            if self.contact != MATRICES or not isinstance(self.structure, StructureMatrices):
                raise ValueError("contact: a scene of matrices is made by Scene.from_matrices(...)")
            object.__setattr__(self, "dof", self.structure.dof)
            object.__setattr__(self, "contact_mass", self.structure.contact[-1] + 1)
            object.__setattr__(self, "gamma", 1.0)
            object.__setattr__(self, "kappa", 1.0)
            object.__setattr__(self, "gammas", ())
            object.__setattr__(self, "kappas", ())
            return
        if not isinstance(self.contact, str) or self.contact not in CONTACTS:
            raise ValueError(f"contact: must be one of {CONTACTS}, got {_shown(self.contact)}")
        if isinstance(self.dof, bool) or not isinstance(self.dof, int | np.integer):
            raise ValueError(f"dof: must be an integer >= 1, got {_shown(self.dof)}")
        if not 1 <= self.dof <= MAX_DOF:
            raise ValueError(f"dof: must be in 1..{MAX_DOF}, got {self.dof}")
        if self.contact == "mass" and self.dof < 2:
            raise ValueError("dof: a 'mass' contact joins two masses, so dof must be >= 2")
        j = self.contact_mass
        if isinstance(j, bool) or not isinstance(j, int | np.integer):
            raise ValueError(f"contact_mass: must be an integer, got {_shown(j)}")
        last = self.dof - 1 if self.contact == "mass" else self.dof
        if not 1 <= j <= last:
            what = "lower mass of the contact pair" if self.contact == "mass" else "mass in contact"
            raise ValueError(
                f"contact_mass: the {what} must be in 1..{last} for dof = {self.dof}, got {j}"
            )
        gam = _ratio_vector("gamma", self.gamma, self.dof)
        kap = _ratio_vector("kappa", self.kappa, self.dof)
        object.__setattr__(self, "dof", int(self.dof))
        object.__setattr__(self, "contact_mass", int(j))
        # Canonical, hashable field values (a number stays a number when all equal).
        for name, vals, given in (("gamma", gam, self.gamma), ("kappa", kap, self.kappa)):
            canon = float(given) if _is_real(given) else tuple(vals)
            object.__setattr__(self, name, canon)
        object.__setattr__(self, "gammas", (1.0, *gam))
        object.__setattr__(self, "kappas", (1.0, *kap))

    # ------------------------------------------------------------------ labels
    @property
    def label(self) -> str:
        """Short name such as ``2dof_ground_m1``, ``2dof_mass_m1`` or, for a
        structure, ``12dof_matrices_ground_x11`` (``_damped`` if damped)."""
        if self.structure is not None:
            kind, *idx = self.structure.contact
            where = "_".join(f"x{i}" for i in idx)
            damped = "" if self.structure.damping is None else "_damped"
            return f"{self.dof}dof_{MATRICES}_{kind}_{where}{damped}"
        return f"{self.dof}dof_{self.contact}_m{self.contact_mass}"

    @property
    def damped(self) -> bool:
        """True when the scene has viscous damping (only scenes of matrices)."""
        return self.structure is not None and self.structure.damping is not None

    def matrices(self) -> dict[str, object]:
        """The keyword arguments of :meth:`from_matrices` that make this scene.

        A chain gives ``M = diag(gamma)`` (Eq. 68), ``K`` of Eq. 69 and no damping;
        its load is ``e_1`` (ground wall, mass contact) or ``("base", 1)`` (base
        wall, Eq. 98: ``p = r^2 M 1`` in coordinates relative to the base), its
        contact ``("ground", j - 1)`` (ground or base wall: in the base's
        coordinates the wall is fixed) or ``("between", j - 1, j)`` (mass contact).
        """
        if self.structure is not None:
            return self.structure.kwargs()
        j = self.contact_mass - 1
        if self.contact == "base":
            load: object = ("base", np.ones(self.dof))
        else:
            load = self.load_vector(1.0)
        contact = ("between", j, j + 1) if self.contact == "mass" else ("ground", j)
        return {
            "mass": np.diag(self.mass_ratios),
            "stiffness": self.stiffness_matrix(),
            "load": load,
            "contact": contact,
            "damping": None,
        }

    def to_dict(self) -> dict[str, object]:
        """Plain-data description (for provenance and study files)."""
        if self.structure is not None:
            s = self.structure

            def plain(v):
                if isinstance(v, np.ndarray):
                    return v.tolist()
                if isinstance(v, tuple):
                    return [plain(x) for x in v]
                return v

            kw = {k: plain(v) for k, v in s.kwargs().items()}
            kw["contact_dofs"] = kw.pop("contact")  # from_matrices(contact=...)
            return {"contact": MATRICES, "dof": self.dof, "contact_mass": self.contact_mass, **kw}
        return {
            "contact": self.contact,
            "dof": self.dof,
            "contact_mass": self.contact_mass,
            "gamma": list(self.gamma) if isinstance(self.gamma, tuple) else self.gamma,
            "kappa": list(self.kappa) if isinstance(self.kappa, tuple) else self.kappa,
        }

    @classmethod
    def from_dict(cls, data: dict[str, object]) -> Scene:
        """The scene of :meth:`to_dict` (a chain, or a scene of matrices, JSON lists)."""
        if data.get("contact") == "multi":
            from tasks.multicontact import MultiScene

            return MultiScene.from_dict(data)
        if data.get("contact") != MATRICES:
            return cls(**data)
        return cls.from_matrices(
            data["mass"],
            data["stiffness"],
            data["load"],
            data["contact_dofs"],
            damping=data.get("damping"),
        )

    # ---------------------------------------------------------------- matrices
    def _chain_only(self, what: str) -> None:
        if self.structure is not None:
            raise ValueError(f"{what}: a scene of matrices has no chain ratios (use mass_matrix)")

    @property
    def mass_ratios(self) -> np.ndarray:
        """gamma_1..gamma_N with gamma_1 = 1 (Eq. 66); chains only."""
        self._chain_only("mass_ratios")
        return np.array(self.gammas)

    @property
    def stiffness_ratios(self) -> np.ndarray:
        """kappa_1..kappa_N with kappa_1 = 1 (Eq. 67); chains only."""
        self._chain_only("stiffness_ratios")
        return np.array(self.kappas)

    def mass_matrix(self, r: float = 1.0) -> np.ndarray:
        """M = r^2 diag(gamma) (Eq. 68); a structure: r^2 M (Eq. 1.1)."""
        if self.structure is not None:
            return r * r * self.structure.mass
        return r * r * np.diag(self.mass_ratios)

    def damping_matrix(self, r: float = 1.0) -> np.ndarray:
        """``r C`` of Eq. 1.1 (zeros when undamped)."""
        if self.structure is None or self.structure.damping is None:
            return np.zeros((self.dof, self.dof))
        return r * self.structure.damping

    def stiffness_matrix(self) -> np.ndarray:
        """Tridiagonal K of Eq. 69: K[i,i] = kappa_i + kappa_(i+1), K[i,i+1] = -kappa_(i+1)."""
        if self.structure is not None:
            return self.structure.stiffness.copy()
        return stiffness_matrix(self.stiffness_ratios)

    @property
    def load_scales_r2(self) -> bool:
        """The load is inertial, ``p = r^2 p_hat`` (base wall, base load of a structure)."""
        if self.structure is not None:
            return self.structure.load_scales_r2
        return self.contact == "base"

    def load_vector(self, r: float = 1.0) -> np.ndarray:
        """Amplitude p of the harmonic load p cos(tau) in the scene's coordinates."""
        if self.structure is not None:
            s = self.structure
            return r * r * s.load if s.load_scales_r2 else s.load.copy()
        n = self.dof
        if self.contact == "base":
            return r * r * self.mass_ratios  # M 1 (Eq. 98, docs/theory.md 2)
        p = np.zeros(n)
        p[0] = 1.0  # the base moves spring 1 (Eq. 65)
        return p

    def contact_vector(self) -> np.ndarray:
        """Direction b of the contact force: the slip velocity is b . x'."""
        if self.structure is not None:
            return self.structure.b.copy()
        b = np.zeros(self.dof)
        j = self.contact_mass - 1
        if self.contact == "mass":
            b[j] = -1.0
            b[j + 1] = 1.0
        else:
            b[j] = 1.0
        return b

    def stuck_basis(self) -> tuple[np.ndarray, np.ndarray]:
        """Coordinates of the stuck system: ``x = T q + d0 w`` with b^T T = 0, b^T w = 1.

        Ground/base: T drops coordinate j (Eq. 131). Mass: T merges masses j and
        j + 1 into one coordinate (Eqs. 134-135).
        """
        j = self.contact_mass - 1
        if self.structure is not None:
            return stuck_basis(self.dof, self.structure.contact[1:])
        return stuck_basis(self.dof, (j, j + 1) if self.contact == "mass" else (j,))


def stuck_basis(n: int, dofs: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """``x = T q + d0 w`` for a contact on ``dofs``: ``(j,)`` (``b = e_j``, T drops
    coordinate j) or ``(i, j)`` (``b = e_j - e_i``, T merges i and j into one
    coordinate at the place of the first of them); ``w = e_j``."""
    j = dofs[-1]
    first, second = (min(dofs), max(dofs)) if len(dofs) == 2 else (j, -1)
    cols = []
    for i in range(n):
        if i == second:
            continue
        col = np.zeros(n)
        col[i] = 1.0
        if i == first and len(dofs) == 2:
            col[second] = 1.0
        elif i == first:
            continue
        cols.append(col)
    T = np.array(cols).T if cols else np.zeros((n, 0))
    w = np.zeros(n)
    w[j] = 1.0
    return T, w


#: The configurations of the paper (Sects. 2-4; the configs of tests/data), ratios 1:
#: one home for the tests and benchmarks that sweep every configuration.
CONFIGURATIONS: dict[str, Scene] = {
    "sdof_ground": Scene("ground", 1),
    "sdof_base": Scene("base", 1),
    "2dof_ground_m1": Scene("ground", 2, 1),
    "2dof_ground_m2": Scene("ground", 2, 2),
    "2dof_base_m1": Scene("base", 2, 1),
    "2dof_base_m2": Scene("base", 2, 2),
    "2dof_mass": Scene("mass", 2, 1),
}


def stiffness_matrix(kappas: np.ndarray) -> np.ndarray:
    """Tridiagonal stiffness matrix of a chain fixed to the base (Eq. 69)."""
    kappas = np.asarray(kappas, dtype=float)
    n = kappas.size
    K = np.zeros((n, n))
    for i in range(n):
        K[i, i] = kappas[i] + (kappas[i + 1] if i + 1 < n else 0.0)
        if i + 1 < n:
            K[i, i + 1] = K[i + 1, i] = -kappas[i + 1]
    return K
