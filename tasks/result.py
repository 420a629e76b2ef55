"""The result of classifying many points of one scene."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

#: Output fields of :func:`tasks.classify`, their dtypes and meanings (one home,
#: reused by the study layer for netCDF variables).
FIELDS: dict[str, tuple[str, str]] = {
    "regime": ("int8", "steady-state motion regime code (tasks.regimes)"),
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
    "asymptotic": (
        "bool",
        "no motion reached asymptotically: slips shrank below the creep threshold "
        "(tasks.regimes.SLIP_RTOL of the static friction deflection)",
    ),
    "regime_rest": ("int8", "regime reached from rest (-127 if rest was not a start)"),
    "regimes_reached": (
        "int8",
        "regimes reached over all starts, bit mask: 1 no_motion, 2 stick_slip, "
        "4 continuous, 8 undetermined",
    ),
    "start_dependent": ("bool", "two starts reached different (determined) regimes"),
}


@dataclass
class ClassifyResult:
    """Arrays of one shape (the broadcast shape of ``r`` and ``beta``)."""

    regime: np.ndarray
    converged: np.ndarray
    cycles: np.ndarray
    stops_per_cycle: np.ndarray
    slip_amplitude: np.ndarray
    stick_fraction: np.ndarray
    period: np.ndarray
    initial_condition: np.ndarray
    asymptotic: np.ndarray
    regime_rest: np.ndarray
    regimes_reached: np.ndarray
    start_dependent: np.ndarray

    @classmethod
    def empty(cls, shape: tuple[int, ...]) -> ClassifyResult:
        return cls(**{name: np.zeros(shape, dtype=dt) for name, (dt, _) in FIELDS.items()})

    @property
    def shape(self) -> tuple[int, ...]:
        return self.regime.shape

    def as_dict(self) -> dict[str, np.ndarray]:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def reshape(self, shape: tuple[int, ...]) -> ClassifyResult:
        return ClassifyResult(**{k: v.reshape(shape) for k, v in self.as_dict().items()})
