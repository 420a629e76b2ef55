"""The result of classifying many points of one scene."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from tasks.regimes import INITIAL_CONDITIONS, NOT_COMPUTED, cf_flag_attributes

#: Output fields of :func:`tasks.classify`, their dtypes and meanings (one home,
#: reused by the study layer for netCDF variables).
FIELDS: dict[str, tuple[str, str]] = {
    "regime": ("int8", "steady-state motion regime (codes: docs/regimes.md)"),
    "converged": ("bool", "a periodic steady state was found and verified"),
    "cycles": ("int32", "excitation cycles simulated (shooting cycles included)"),
    "stops_per_cycle": (
        "int16",
        "stick phases in one steady-state period (of `period` excitation cycles)",
    ),
    "slip_amplitude": ("float64", "half peak-to-peak relative displacement of the contact"),
    "stick_fraction": ("float64", "fraction of the period the contact is stuck in steady state"),
    "period": ("int8", "period of the steady state in excitation cycles (1 or 2; 0 if none)"),
    "initial_condition": ("int8", "initial condition used (tasks.regimes.INITIAL_CONDITIONS)"),
    "amplitude": (
        "float64",
        "displacement amplitude of each mass (half peak-to-peak of x_i / Y over the "
        "steady-state period; absolute displacement)",
    ),
    "amplitude_relative": (
        "float64",
        "displacement amplitude of each mass relative to the base (half peak-to-peak of "
        "(x_i - y) / Y over the steady-state period)",
    ),
    "contact_force_amplitude": (
        "float64",
        "largest friction force over the steady-state period (/ (k_1 Y); beta whenever "
        "the contact slides)",
    ),
    "dissipation": (
        "float64",
        "energy dissipated by the contact per excitation cycle (/ (k_1 Y^2): beta times "
        "the slip distance per cycle, docs/theory.md 2)",
    ),
    "dissipation_viscous": (
        "float64",
        "energy dissipated by the viscous damping per excitation cycle (/ (k_1 Y^2): the "
        "integral of r x'^T C x' over the period per cycle, docs/structures.md 1; 0 when "
        "undamped)",
    ),
    "asymptotic": (
        "bool",
        "no motion reached asymptotically: from a start off the held steady state above "
        "the motion bound (every start reaches no motion, docs/theory.md 3), or slips "
        "shrank below the creep threshold (tasks.regimes.SLIP_RTOL of the static friction "
        "deflection)",
    ),
    "regime_rest": ("int8", "regime reached from rest (-127 if rest was not a start)"),
    "regimes_reached": (
        "int8",
        "regimes reached over all starts, bit mask: 1 no_motion, 2 stick_slip, "
        "4 continuous, 8 undetermined",
    ),
    "start_dependent": ("bool", "two starts reached different determined regimes"),
}

#: ``long_name`` of the fields whose meaning does not begin with a short name
#: followed by a parenthesis (every other ``long_name`` is its meaning without its
#: trailing parenthesis; the full meaning is the ``comment``).
LONG_NAMES: dict[str, str] = {
    "asymptotic": "no motion reached asymptotically",
    "regimes_reached": "regimes reached over all starts (bit mask)",
}

#: Bits of ``regimes_reached`` (CF ``flag_masks`` / ``flag_meanings``).
REACHED_BITS: dict[int, str] = {1: "no_motion", 2: "stick_slip", 4: "continuous", 8: "undetermined"}

#: CF attributes of the coordinates of a result (stored or in memory).
COORD_ATTRS: dict[str, dict[str, str]] = {
    "r": {
        "long_name": "frequency ratio r_1",
        "comment": "r_1 = omega sqrt(m_1/k_1) (Eq. 7)",
        "units": "1",
    },
    "beta": {
        "long_name": "friction ratio beta",
        "comment": "beta = F/(k_1 Y) (Eq. 8)",
        "units": "1",
    },
    "gamma": {
        "long_name": "mass ratio gamma",
        "comment": "gamma_i = m_i/m_1 of every mass i = 2..N (Eq. 66)",
        "units": "1",
    },
    "kappa": {
        "long_name": "stiffness ratio kappa",
        "comment": "kappa_i = k_i/k_1 of every spring i = 2..N (Eq. 67)",
        "units": "1",
    },
    "mass": {"long_name": "index i of the mass m_i (1 = the mass on spring k_1)", "units": "1"},
    "point": {"long_name": "index of the point in the study's point list", "units": "1"},
}

#: Fields with one value per mass: a trailing dimension ``mass`` (1..N) in
#: :class:`ClassifyResult`, the dimension ``mass`` in stored results.
MASS_FIELDS: tuple[str, ...] = ("amplitude", "amplitude_relative")
#: Design quantities of the converged orbit: None in a :class:`ClassifyResult`
#: computed with ``design=False`` (not computed; absent from ``as_dict`` and
#: ``to_dataset``).
DESIGN_FIELDS: tuple[str, ...] = (
    *MASS_FIELDS,
    "contact_force_amplitude",
    "dissipation",
    "dissipation_viscous",
)

#: CF flag attributes of the coded fields (``flag_values`` / ``flag_meanings``).
FLAGS: dict[str, dict[str, object]] = {
    "initial_condition": {
        "flag_values": np.array(sorted(INITIAL_CONDITIONS), dtype=np.int8),
        "flag_meanings": " ".join(INITIAL_CONDITIONS[c] for c in sorted(INITIAL_CONDITIONS)),
    },
    "period": {
        "flag_values": np.array([0, 1, 2], dtype=np.int8),
        "flag_meanings": "no_steady_state one_cycle two_cycles",
    },
    "converged": {
        "flag_values": np.array([0, 1], dtype=np.int8),
        "flag_meanings": "false true",
    },
}


def field_attrs(name: str) -> dict[str, object]:
    """CF attributes of a result field: ``long_name`` (and the full meaning as
    ``comment``), ``units`` and, for coded fields, ``flag_values`` /
    ``flag_meanings`` (``regime``: :mod:`tasks.regimes`)."""
    meaning = FIELDS[name][1]
    short = LONG_NAMES.get(name, meaning.split(" (")[0])  # the details go to the comment
    attrs: dict[str, object] = {"long_name": short}
    if short != meaning:
        attrs["comment"] = meaning
    if name == "regime":
        attrs.update(cf_flag_attributes())
    elif name == "regime_rest":  # the regime codes, and NOT_COMPUTED where rest was no start
        flags = cf_flag_attributes()
        attrs["flag_values"] = np.concatenate(([NOT_COMPUTED], flags["flag_values"])).astype(
            np.int8
        )
        attrs["flag_meanings"] = "not_computed " + flags["flag_meanings"]
    elif name == "regimes_reached":  # a bit field: each bit tested by mask and value (CF 3.5)
        bits = np.array(sorted(REACHED_BITS), dtype=np.int8)
        attrs["flag_masks"] = bits
        attrs["flag_values"] = bits.copy()
        attrs["flag_meanings"] = " ".join(REACHED_BITS[b] for b in sorted(REACHED_BITS))
    elif name in FLAGS:
        attrs.update(FLAGS[name])
    else:
        attrs["units"] = "1"
    return attrs


def field_shape(name: str, shape: tuple[int, ...], dof: int) -> tuple[int, ...]:
    """Shape of a field for points of ``shape`` in a chain of ``dof`` masses."""
    return (*shape, dof) if name in MASS_FIELDS else shape


@dataclass
class ClassifyResult:
    """Arrays of one shape (the broadcast shape of ``r`` and ``beta``); the
    :data:`DESIGN_FIELDS` are None where they were not asked for (``design=False``)."""

    regime: np.ndarray
    converged: np.ndarray
    cycles: np.ndarray
    stops_per_cycle: np.ndarray
    slip_amplitude: np.ndarray
    stick_fraction: np.ndarray
    period: np.ndarray
    initial_condition: np.ndarray
    amplitude: np.ndarray | None
    amplitude_relative: np.ndarray | None
    contact_force_amplitude: np.ndarray | None
    dissipation: np.ndarray | None
    dissipation_viscous: np.ndarray | None
    asymptotic: np.ndarray
    regime_rest: np.ndarray
    regimes_reached: np.ndarray
    start_dependent: np.ndarray

    @classmethod
    def empty(cls, shape: tuple[int, ...], dof: int = 1) -> ClassifyResult:
        return cls(
            **{
                name: np.zeros(field_shape(name, shape, dof), dtype=dt)
                for name, (dt, _) in FIELDS.items()
            }
        )

    @property
    def shape(self) -> tuple[int, ...]:
        return self.regime.shape

    @property
    def dof(self) -> int:
        """Number of masses (length of the trailing axis of the per-mass fields)."""
        return self.amplitude.shape[-1]

    def as_dict(self) -> dict[str, np.ndarray]:
        """The fields computed (design quantities only if asked for)."""
        return {
            f.name: getattr(self, f.name) for f in fields(self) if getattr(self, f.name) is not None
        }

    def reshape(self, shape: tuple[int, ...]) -> ClassifyResult:
        dof = self.dof if self.amplitude is not None else 0
        values = dict.fromkeys(DESIGN_FIELDS)
        values.update({k: v.reshape(field_shape(k, shape, dof)) for k, v in self.as_dict().items()})
        return ClassifyResult(**values)

    def to_dataset(self, r: np.ndarray, beta: np.ndarray, scene=None):
        """The result as an ``xarray.Dataset`` labelled by ``beta`` and ``r``.

        Parameters
        ----------
        r, beta : array_like
            The axes the result was computed on: 1-D axes with the result of
            shape ``(len(r), len(beta))`` (``np.meshgrid(r, beta, indexing="ij")``),
            or the 2-D arrays of that meshgrid.
        scene : tasks.Scene, optional
            Adds its gamma and kappa (scalar coordinates) and its contact, dof
            and contact mass (attributes).

        Returns
        -------
        xarray.Dataset
            Dims ``(beta, r)`` (``ds.regime.plot()`` draws r along x), per-mass
            fields ``(mass, beta, r)``; the same names and attributes as a
            stored result (docs/results.md).
        """
        import xarray as xr  # lazy: tasks stays importable without xarray

        r = np.asarray(r, dtype=float)
        beta = np.asarray(beta, dtype=float)
        if r.ndim == 2:
            r = r[:, 0]
        if beta.ndim == 2:
            beta = beta[0, :]
        if self.shape != (r.size, beta.size):
            raise ValueError(
                f"r, beta: the result has shape {self.shape}, expected (len(r), len(beta)) = "
                f"({r.size}, {beta.size})"
            )
        data = {}
        for name, value in self.as_dict().items():
            if name in MASS_FIELDS:
                data[name] = (("mass", "beta", "r"), np.moveaxis(value, (0, 1, 2), (2, 1, 0)))
            else:
                data[name] = (("beta", "r"), value.T)
            data[name] = xr.Variable(*data[name], attrs=field_attrs(name))
        coords = {
            "beta": ("beta", beta, COORD_ATTRS["beta"]),
            "r": ("r", r, COORD_ATTRS["r"]),
        }
        if self.amplitude is not None:
            coords["mass"] = (
                "mass",
                np.arange(1, self.dof + 1, dtype=np.int32),
                COORD_ATTRS["mass"],
            )
        attrs = {}
        if scene is not None:
            attrs = {
                "contact": scene.contact,
                "dof": scene.dof,
                "contact_mass": scene.contact_mass,
                "scene_label": scene.label,
            }
            for name in ("gamma", "kappa"):
                value = getattr(scene, name)
                if scene.dof > 1 and len(set(np.atleast_1d(value))) == 1:
                    coords[name] = ((), float(np.atleast_1d(value)[0]), COORD_ATTRS[name])
        return xr.Dataset(data, coords, attrs)
