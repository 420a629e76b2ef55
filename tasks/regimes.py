"""Regime codes: the one place where the integer labels of a regime map are defined.

Every part of the project (simulation, closed forms, netCDF flags, figures,
reports) uses these constants; nothing else hard-codes the numbers.

Non-negative codes are steady-state regimes (docs/theory.md section 3, the paper's
Tables 1-3). Negative codes mean *undetermined*, one code per reason, so that
a point that did not settle is never silently given a regime.
"""

from __future__ import annotations

import numpy as np

NO_MOTION = 0
"""The contact stays stuck for the whole excitation period."""
STICK_SLIP = 1
"""The contact sticks for intervals of positive length and also slides."""
CONTINUOUS = 2
"""The contact never sticks: its relative velocity only crosses zero."""

NOT_CONVERGED = -1
"""No periodic steady state found within the cycle budget (``max_cycles``)."""
UNBOUNDED = -2
"""The response grows without bound (e.g. SDOF at r = 1 with beta < pi/4)."""
EVENT_LIMIT = -3
"""Too many events in one cycle (chattering or a degenerate event sequence)."""
NUMERICAL_FAILURE = -4
"""A non-finite state, an event that could not be located, or a converged orbit
that fails the orbit invariant (``tasks.kernel.orbit_holds``: a stick phase with
``|g| > beta`` or a slip phase whose contact velocity changes sign)."""
WORK_LIMIT = -5
"""The point exceeded its budget of function evaluations (``max_work``): modal
frequencies far above the excitation (extreme mass or stiffness ratios at
small r) or persistent chattering."""
NOT_COMPUTED = -127
"""Fill value of stored maps: the point has not been simulated (yet)."""

REGIMES: dict[int, str] = {
    NO_MOTION: "no_motion",
    STICK_SLIP: "stick_slip",
    CONTINUOUS: "continuous",
}
UNDETERMINED: dict[int, str] = {
    NOT_CONVERGED: "not_converged",
    UNBOUNDED: "unbounded_growth",
    EVENT_LIMIT: "event_limit",
    NUMERICAL_FAILURE: "numerical_failure",
    WORK_LIMIT: "work_limit",
}
ALL_CODES: dict[int, str] = {**REGIMES, **UNDETERMINED}
"""Every code a simulation can return, with its name (CF ``flag_meanings``)."""

INITIAL_CONDITIONS: dict[int, str] = {0: "held", 1: "rest"}
"""Initial condition codes: ``held`` = contact stuck at zero relative
displacement with the other masses on the forced response of the held system;
``rest`` = everything at zero (used where the held system is resonant)."""
IC_HELD = 0
IC_REST = 1
IC_RANDOM = 2
"""Codes ``IC_RANDOM + k`` (k = 0, 1, ...): the k-th seeded random start, a state on
the energy scale of the forced response (:func:`tasks.kernel._random_start`)."""

SLIP_RTOL = 1e-7
"""Creep threshold: a slip whose amplitude (half peak-to-peak of the contact's
relative displacement) is below ``SLIP_RTOL * beta * c`` is not motion, ``c`` being
the compliance the contact sees at the excitation frequency, ``sum_i (b . psi_i)^2 /
max(lambda_i, r^2)`` over the modes of the sliding system (the static ``b^T K^-1 b``
below the natural frequencies, the inertial ``b^T Gamma^-1 b / r^2`` above them;
:func:`tasks.kernel.creep.creep_threshold`), so ``beta c`` is the deflection the
friction force produces. Such a slip changes the force at the contact by less than
``SLIP_RTOL`` of the friction force: the same as holding with beta changed by one
part in 10^7. It is the same for every preset (docs/theory.md 3, creep). Genuine
stick-slip has slips this small only within about 5e-4 of beta below the motion
bound (the slip amplitude there is 0.4-10 times the square of the relative distance
to the bound, in units of ``beta c``), inside the tolerance of the traced boundaries."""
CREEP_SLIP_RTOL = 1e-5
"""A creep in progress: cycles whose slips stay below ``CREEP_SLIP_RTOL * beta * c``."""
CREEP_FORCE_RTOL = 1e-3
"""A stuck section state whose contact force can exceed beta by at most this
fraction of beta, after ``CREEP_WINDOW`` cycles of slips below the creep slip
bound of which most had no event at all (no orbit of period 1 or 2 does that),
is no motion reached asymptotically."""
CREEP_WINDOW = 20
"""Consecutive cycles with slips below the creep threshold before the force
excess is tested."""


def name(code: int) -> str:
    """Name of a regime code, e.g. ``name(1) == "stick_slip"``."""
    return ALL_CODES.get(int(code), "not_computed" if code == NOT_COMPUTED else "unknown")


def code(regime_name: str) -> int:
    """Code of a regime name, inverse of :func:`name`."""
    for c, n in ALL_CODES.items():
        if n == regime_name:
            return c
    raise ValueError(f"unknown regime name {regime_name!r}; known: {sorted(ALL_CODES.values())}")


def is_determined(regime: np.ndarray) -> np.ndarray:
    """Boolean mask of points with a steady-state regime (code >= 0)."""
    return np.asarray(regime) >= 0


def cf_flag_attributes() -> dict[str, object]:
    """CF-convention flag attributes for a stored ``regime`` variable."""
    codes = sorted(ALL_CODES)
    return {
        "flag_values": np.array(codes, dtype=np.int8),
        "flag_meanings": " ".join(ALL_CODES[c] for c in codes),
    }
