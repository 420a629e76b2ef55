"""A scene with several Coulomb contacts (docs/contacts.md 1).

The dimensionless equation of any linear structure with k contacts is

    r^2 M x'' + K x + sum_k F_k b_k = p cos(tau),                          (1.1)

with ``F_k = beta_k sgn(b_k . x')`` while contact k slides and ``|F_k| <= beta_k``
while it is stuck; ``beta_k = beta_ratio[k] * beta``, so that a map over
``(r, beta)`` stays a map. ``M``, ``K``, ``p`` are those of
:meth:`tasks.scene.Scene.from_matrices` (docs/structures.md 1): a chain is the
special case (:meth:`MultiScene.chain`). Every contact is ``("ground", j)``
(``b = e_j``) or ``("between", i, j)`` (``b = e_j - e_i``), DOF indices from 0.
The contact directions must be linearly independent (a set of stuck contacts
then fixes its forces uniquely, docs/contacts.md 2). Damping ``r C x'`` as for one
contact (docs/structures.md 1): modal in every stuck set where C is proportional
there (Rayleigh ``C = a M + b K`` always), the set's damped pairs elsewhere
(docs/contacts.md 7).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from numbers import Real

import numpy as np

from tasks.matrices import StructureMatrices, structure_matrices

#: Largest number of contacts: the stuck sets (2^k) and the event decision (3^k
#: assignments, docs/contacts.md 3) stay small.
MAX_CONTACTS = 4


def _contact_list(contact: object) -> list:
    """The contacts as a list of specs, or a ValueError naming ``contact``."""
    if not isinstance(contact, list | tuple) or not contact:
        raise ValueError(f"contact: expected a list of contacts, got {contact!r}")
    if isinstance(contact[0], str):  # a single contact spec
        return [contact]
    return list(contact)


def _ratios(beta_ratio: object, k: int) -> tuple[float, ...]:
    if beta_ratio is None:
        return (1.0,) * k
    if isinstance(beta_ratio, bool | np.bool_ | str | bytes):
        raise ValueError(f"beta_ratio: expected {k} numbers >= 0, got {beta_ratio!r}")
    if isinstance(beta_ratio, Real):
        beta_ratio = [beta_ratio] * k
    try:
        values = list(beta_ratio)
    except TypeError:
        raise ValueError(f"beta_ratio: expected {k} numbers >= 0, got {beta_ratio!r}") from None
    if len(values) != k:
        raise ValueError(f"beta_ratio: expected one number per contact ({k}), got {len(values)}")
    out = []
    for v in values:
        if not isinstance(v, Real) or isinstance(v, bool | np.bool_):
            raise ValueError(f"beta_ratio: every entry must be a number, got {v!r}")
        if not np.isfinite(v) or v < 0.0:
            raise ValueError(f"beta_ratio: every entry must be finite and >= 0, got {v!r}")
        out.append(float(v))
    return tuple(out)


@dataclass(frozen=True, eq=False)
class MultiScene:
    """A linear structure with several Coulomb contacts (Eq. 1.1 above).

    Made by :meth:`from_matrices` or :meth:`chain` (or by
    ``tasks.Scene.from_matrices(..., contact=[...], beta_ratio=[...])`` and
    ``tasks.Scene(contact, dof, contact_mass=[...], ...)``, which return one).

    Attributes
    ----------
    structures : tuple of StructureMatrices
        One validated structure per contact (same M, K and load).
    beta_ratio : tuple of float
        ``beta_k / beta`` per contact.
    label_hint : str
        Short name of the scene (``2dof_ground_m1_m2``, ``3dof_matrices_...``).
    """

    structures: tuple[StructureMatrices, ...]
    beta_ratio: tuple[float, ...]
    label_hint: str = ""

    # ------------------------------------------------------------ constructors
    @classmethod
    def from_matrices(
        cls, mass, stiffness, load, contact, *, beta_ratio=None, damping=None, label=""
    ) -> MultiScene:
        """Several contacts on any linear structure.

        Parameters
        ----------
        mass, stiffness, load :
            As :meth:`tasks.scene.Scene.from_matrices`.
        contact : list of ("ground", j) or ("between", i, j)
            The contacts, DOF indices from 0; at most :data:`MAX_CONTACTS`,
            linearly independent directions.
        beta_ratio : sequence of float, optional
            ``beta_k = beta_ratio[k] * beta`` (default all 1); 0 is a contact
            without friction.
        damping : optional
            As :meth:`tasks.scene.Scene.from_matrices`: a matrix C, ``("rayleigh", a, b)``
            or ``("modal", zeta)`` (docs/contacts.md 7). Zero damping is none.

        Raises
        ------
        ValueError
            One line naming the argument and the rule it breaks.
        """
        contacts = _contact_list(contact)
        if len(contacts) > MAX_CONTACTS:
            raise ValueError(f"contact: at most {MAX_CONTACTS} contacts, got {len(contacts)}")
        structures = tuple(structure_matrices(mass, stiffness, load, c, damping) for c in contacts)
        B = np.array([s.b for s in structures]).T
        if np.linalg.matrix_rank(B) < len(contacts):
            raise ValueError(
                "contact: the contact directions must be linearly independent "
                f"(got {[s.contact for s in structures]})"
            )
        if len({s.contact for s in structures}) < len(structures):
            raise ValueError("contact: a contact is listed twice")
        ratios = _ratios(beta_ratio, len(contacts))
        scene = cls(structures, ratios, label)
        if scene.damped:  # proportional in every stuck set, or one line naming damping
            from tasks.multicontact.sets import stuck_sets

            stuck_sets(scene)
        return scene

    @classmethod
    def chain(
        cls,
        contact: str | Sequence[str],
        dof: int,
        contact_mass: Sequence[int],
        gamma: float | Sequence[float] = 1.0,
        kappa: float | Sequence[float] = 1.0,
        beta_ratio: Sequence[float] | None = None,
    ) -> MultiScene:
        """A chain of masses (docs/theory.md 1) with a contact on each listed mass.

        ``contact`` is one kind for all contacts or one per contact: ``"ground"``
        or ``"base"`` (a wall on mass j) or ``"mass"`` (between masses j and
        j + 1); walls of a scene are all ground-fixed or all base-fixed (the
        load must be one). ``contact_mass`` lists the 1-based masses j.
        """
        from tasks.scene import Scene

        if isinstance(contact_mass, int | np.integer) and not isinstance(contact_mass, bool):
            contact_mass = [int(contact_mass)]
        masses = list(contact_mass)
        kinds = [contact] * len(masses) if isinstance(contact, str) else list(contact)
        if len(kinds) != len(masses):
            raise ValueError(
                f"contact: one kind per contact mass expected ({len(masses)}), got {len(kinds)}"
            )
        if "base" in kinds and "ground" in kinds:
            raise ValueError("contact: walls of one chain are all 'ground' or all 'base'")
        singles = [
            Scene(kind, dof, j, gamma=gamma, kappa=kappa)
            for kind, j in zip(kinds, masses, strict=True)
        ]
        base = "base" in kinds
        mats = singles[0].matrices()
        if base:
            load: object = ("base", np.ones(dof))
        else:
            load = np.eye(dof)[0]
        contacts = [s.matrices()["contact"] for s in singles]
        label = f"{dof}dof_" + "_".join(f"{k}_m{j}" for k, j in zip(kinds, masses, strict=True))
        return cls.from_matrices(
            mats["mass"], mats["stiffness"], load, contacts, beta_ratio=beta_ratio, label=label
        )

    # ------------------------------------------------------------------ access
    @property
    def n_contacts(self) -> int:
        return len(self.structures)

    @property
    def dof(self) -> int:
        return self.structures[0].dof

    @property
    def contacts(self) -> tuple[tuple, ...]:
        return tuple(s.contact for s in self.structures)

    @property
    def contact(self) -> str:
        """``"multi"``: what :class:`tasks.scene.Scene` calls its contact kind."""
        return "multi"

    @property
    def damped(self) -> bool:
        return self.structures[0].damping is not None

    def damping_matrix(self, r: float = 1.0) -> np.ndarray:
        """``r C`` of Eq. 1.1 of docs/structures.md (zeros when undamped)."""
        C = self.structures[0].damping
        return np.zeros((self.dof, self.dof)) if C is None else r * C

    @property
    def label(self) -> str:
        if self.label_hint:
            return self.label_hint
        where = "_".join(kind + "".join(f"x{i}" for i in idx) for kind, *idx in self.contacts)
        return f"{self.dof}dof_matrices_{where}"

    def mass_matrix(self, r: float = 1.0) -> np.ndarray:
        return r * r * self.structures[0].mass

    def stiffness_matrix(self) -> np.ndarray:
        return self.structures[0].stiffness.copy()

    @property
    def load_scales_r2(self) -> bool:
        return self.structures[0].load_scales_r2

    def load_vector(self, r: float = 1.0) -> np.ndarray:
        s = self.structures[0]
        return r * r * s.load if s.load_scales_r2 else s.load.copy()

    def contact_vectors(self) -> np.ndarray:
        """``B``: column k is the direction ``b_k`` of contact k."""
        return np.array([s.b for s in self.structures]).T

    def single(self, k: int):
        """The one-contact :class:`tasks.scene.Scene` of contact ``k`` alone."""
        from tasks.scene import Scene

        return Scene.from_matrices(**self.structures[k].kwargs())

    def to_dict(self) -> dict[str, object]:
        """Plain data (JSON lists) that :meth:`from_dict` turns back into this scene."""

        def plain(v):
            if isinstance(v, np.ndarray):
                return v.tolist()
            if isinstance(v, tuple):
                return [plain(x) for x in v]
            return v

        kw = self.structures[0].kwargs()
        return {
            "contact": "multi",
            "dof": self.dof,
            "mass": plain(kw["mass"]),
            "stiffness": plain(kw["stiffness"]),
            "load": plain(kw["load"]),
            "contacts": [plain(c) for c in self.contacts],
            "beta_ratio": list(self.beta_ratio),
            "label": self.label_hint,
            "damping": plain(kw["damping"]),
        }

    @classmethod
    def from_dict(cls, data: dict[str, object]) -> MultiScene:
        """The scene of :meth:`to_dict`."""
        load = data["load"]
        if isinstance(load, list) and load and load[0] == "base":
            load = ("base", np.asarray(load[1], dtype=float))
        return cls.from_matrices(
            data["mass"],
            data["stiffness"],
            load,
            [tuple(c) for c in data["contacts"]],
            beta_ratio=data["beta_ratio"],
            damping=data.get("damping"),
            label=data.get("label", ""),
        )

    def _key(self) -> tuple:
        return (tuple(s._key() for s in self.structures), self.beta_ratio)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, MultiScene) and self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())
