"""Fidelity presets: what each costs and buys, and how to override a setting.

=================  ======  ========  =======  ============================================
setting            fast    balanced  exact    meaning
=================  ======  ========  =======  ============================================
event_tol          1e-9    1e-12     1e-13    event location tolerance in tau
step_fraction      0.5     0.25      0.125    bracket length / shortest modal half-period
section_rtol       1e-5    1e-8      1e-10    Poincare section repeat tolerance (relative)
max_cycles         600     2000      5000     cycle budget before NOT_CONVERGED
min_cycles         2       3         4        cycles simulated before testing convergence
shooting           True    True      True     Newton on the Poincare map for slow points
shooting_after     4       6         8        cycles of plain iteration before shooting
                                               (one early shot after 3 once the event
                                               pattern repeats, tasks.kernel.point)
max_events         400     2000      8000     events per cycle before EVENT_LIMIT (raised
                                               to 8 Omega_max: a free mode of frequency
                                               Omega reverses the contact 2 Omega times)
max_work           2e6     2e7       2e8      work units per point before WORK_LIMIT: one
                                               per mode per evaluation of a phase (scan,
                                               certificate, bisection, root solve, orbit
                                               check) and 4 N^2 per event; the event
                                               search stops when it is spent, so it
                                               bounds the time of any point whatever
                                               the other settings (about 50 ns each)
growth_factor      1e3     1e4       1e5      section growth (vs. start) flagged UNBOUNDED
=================  ======  ========  =======  ============================================

What is computed (the same in every preset): ``warm`` (True) seeds each point's
steady-state search with the converged orbit of a close point solved before it
in the same call (``tasks.seeds``, ``tasks.kernel.batch.run_points_seeded``;
dense grid blocks, point lists of adaptive maps, traced columns), and polishes
every moving period-1 orbit, seeded or not, to the fixed point of its Poincare
map (residual 1e-12 of the motion). The labels (regime, stops, period, creep
flag) are those of the held start whatever the seeds (docs/theory.md 3, "One
regime per point"), the other fields agree across any grouping of the points
to about 1e-9 (``cycles`` excepted: it counts the periods the search took), and
the same points in the same order give the same result to the bit (a chunk
recomputed on resume). ``warm=False`` runs every point from the held start
without polish: the fields then hold to ``section_rtol`` and do not depend on
the call at all. ``design`` (False by default) says whether the design
quantities (amplitudes, contact force amplitude, dissipation,
:data:`tasks.result.DESIGN_FIELDS`) of every orbit are computed: with
``design=True`` each converged orbit is replayed and sampled once more (the
design pass, docs/simulator.md 8; it adds 25-33 % to a warm point), without
it the result's design fields are None. A map wants the labels; a designer
asks for the amplitudes.

Starts (the same in every preset): ``initial_condition`` ("held") is the start of
a single run; ``starts`` (e.g. ``("held", "rest")``) lists the starts to compare,
the first giving ``regime``; ``n_random`` seeded random starts (``seed``) on the
energy scale of the forced response are added to them (``tasks.classify``:
``regime_rest``, ``regimes_reached``, ``start_dependent``).

``fast`` is for exploratory maps (coarser events and a looser steady-state
test: a few points near a boundary may flip or stay undetermined);
``balanced`` is the default for production maps; ``exact`` is for reference
data and for checking the other two. The cycle budgets matter only for the
slow points next to a boundary: a typical point settles in 10-30 periods.
The measured cost and disagreement of each preset is in the README
(``study bench``).

Every setting must lie in its range of :data:`LIMITS` (e.g. ``step_fraction``
0.01..1, ``event_tol`` 1e-15..1e-3, ``max_cycles`` 1..1e6, ``max_work``
1e3..1e11) and have its type (an integer setting refuses ``"5"`` and ``True``);
anything else raises ``ValueError`` naming the setting.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace
from numbers import Integral, Real

import numpy as np

#: Ranges each setting must lie in (closed unless listed in ``OPEN_BELOW``): the
#: ranges where the kernel's numerics are sound and every point ends in bounded
#: time. Below ``event_tol`` 1e-15 a root cannot be located in double precision;
#: ``step_fraction`` below 0.01 (12.5 times finer than ``exact``) only multiplies
#: the brackets (1e-17 would never finish a period); ``section_rtol`` below 1e-14
#: is below the rounding of the section state; the integer budgets are capped so
#: that a point stays within minutes and the values fit the kernel's int64.
LIMITS: dict[str, tuple[float, float]] = {
    "event_tol": (1e-15, 1e-3),
    "step_fraction": (0.01, 1.0),
    "section_rtol": (1e-14, 1e-2),
    "max_cycles": (1, 1_000_000),
    "min_cycles": (1, 1_000_000),
    "shooting_after": (1, 1_000_000),
    "max_events": (4, 10_000_000),
    "max_work": (1_000, 100_000_000_000),
    "growth_factor": (1.0, 1e15),
    "n_random": (0, 100),
    "seed": (0, 2**31 - 1),
}
#: Settings whose lower limit is excluded.
OPEN_BELOW = frozenset({"growth_factor"})


def _check_type(name: str, value: object, kind: type) -> None:
    """Reject a value of the wrong type (a string for a number, a bool for an integer)."""
    if kind is bool:
        ok = isinstance(value, bool | np.bool_)
        rule = "true or false"
    elif kind is int:
        ok = isinstance(value, Integral) or (
            isinstance(value, Real) and math.isfinite(value) and float(value).is_integer()
        )
        ok = ok and not isinstance(value, bool | np.bool_)
        rule = "an integer"
    elif kind is tuple:
        ok = isinstance(value, tuple) and all(isinstance(v, str) for v in value)
        rule = "a list of names"
    elif kind is float:
        ok = isinstance(value, Real) and not isinstance(value, bool | np.bool_)
        ok = ok and math.isfinite(value)
        rule = "a finite number"
    else:
        ok = isinstance(value, str)
        rule = "a string"
    if not ok:
        shown = " ".join(repr(value).split())[:60]  # one line, whatever the value
        raise ValueError(f"{name}: must be {rule}, got {type(value).__name__} {shown}")


@dataclass(frozen=True)
class Settings:
    """Resolved solver settings (see the module table)."""

    event_tol: float = 1e-12
    step_fraction: float = 0.25
    section_rtol: float = 1e-8
    max_cycles: int = 2000
    min_cycles: int = 3
    shooting: bool = True
    shooting_after: int = 6
    max_events: int = 2000
    max_work: int = 20_000_000
    growth_factor: float = 1e4
    initial_condition: str = "held"
    starts: tuple[str, ...] = ()
    n_random: int = 0
    seed: int = 0
    warm: bool = True
    design: bool = False

    def __post_init__(self) -> None:
        for f in fields(self):
            _check_type(f.name, getattr(self, f.name), type(f.default))
        for name, (lo, hi) in LIMITS.items():
            v = getattr(self, name)
            if not lo <= v <= hi or (name in OPEN_BELOW and v == lo):
                rule = f"in ({lo:g}, {hi:g}]" if name in OPEN_BELOW else f"in [{lo:g}, {hi:g}]"
                raise ValueError(f"{name}: must be {rule}, got {v!r}")
        if self.min_cycles > self.max_cycles:
            raise ValueError(
                f"min_cycles: must be in 1..max_cycles ({self.max_cycles}), got {self.min_cycles}"
            )
        if self.initial_condition not in ("held", "rest"):
            raise ValueError(
                f"initial_condition: must be 'held' or 'rest', got {self.initial_condition!r}"
            )
        if not all(s in ("held", "rest") for s in self.starts) or len(set(self.starts)) != len(
            self.starts
        ):
            raise ValueError(
                f"starts: must be a list of distinct starts, each 'held' or 'rest', "
                f"got {list(self.starts)!r}"
            )

    def to_dict(self) -> dict[str, object]:
        """The settings as JSON-ready values (``starts`` as a list)."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}


PRESETS: dict[str, Settings] = {
    "fast": Settings(
        event_tol=1e-9,
        step_fraction=0.5,
        section_rtol=1e-5,
        max_cycles=600,
        min_cycles=2,
        shooting_after=4,
        max_events=400,
        max_work=2_000_000,
        growth_factor=1e3,
    ),
    "balanced": Settings(),
    "exact": Settings(
        event_tol=1e-13,
        step_fraction=0.125,
        section_rtol=1e-10,
        max_cycles=5000,
        min_cycles=4,
        shooting_after=8,
        max_events=8000,
        max_work=200_000_000,
        growth_factor=1e5,
    ),
}

SETTING_NAMES = tuple(f.name for f in fields(Settings))


def resolve(fidelity: str = "balanced", **overrides: object) -> Settings:
    """Settings of a preset with any field overridden.

    Raises
    ------
    ValueError
        For an unknown preset or setting name, or a value out of range.
    """
    if fidelity not in PRESETS:
        raise ValueError(f"fidelity: must be one of {tuple(PRESETS)}, got {fidelity!r}")
    unknown = sorted(set(overrides) - set(SETTING_NAMES))
    if unknown:
        raise ValueError(
            f"{unknown[0]}: unknown setting; known settings: {', '.join(SETTING_NAMES)}"
        )
    base = PRESETS[fidelity]
    typed = {}
    for name, value in overrides.items():
        kind = type(getattr(base, name))
        if kind is tuple:
            if not isinstance(value, list | tuple) or not all(isinstance(v, str) for v in value):
                raise ValueError(f"{name}: must be a list of names, got {value!r}")
            typed[name] = tuple(value)
            continue
        _check_type(name, value, kind)
        typed[name] = kind(value) if kind is not str else value
    return replace(base, **typed)
