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
max_events         400     2000      8000     events per cycle before EVENT_LIMIT (raised
                                               to 8 Omega_max: a free mode of frequency
                                               Omega reverses the contact 2 Omega times)
max_work           2e6     2e7       2e8      mode evaluations (one per mode per evaluation
                                               of the event function) per point before
                                               WORK_LIMIT: bounds the time of any point
                                               (about 50 ns each: 1 s for "balanced")
growth_factor      1e3     1e4       1e5      section growth (vs. start) flagged UNBOUNDED
=================  ======  ========  =======  ============================================

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
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace


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

    def __post_init__(self) -> None:
        checks = (
            ("event_tol", 0.0 < self.event_tol < 1e-2, "in (0, 1e-2)"),
            ("step_fraction", 0.0 < self.step_fraction <= 1.0, "in (0, 1]"),
            ("section_rtol", 0.0 < self.section_rtol < 1.0, "in (0, 1)"),
            ("max_cycles", self.max_cycles >= 1, ">= 1"),
            ("min_cycles", 1 <= self.min_cycles <= self.max_cycles, "in 1..max_cycles"),
            ("shooting_after", self.shooting_after >= 1, ">= 1"),
            ("max_events", self.max_events >= 4, ">= 4"),
            ("max_work", self.max_work >= 1000, ">= 1000"),
            ("growth_factor", self.growth_factor > 1.0, "> 1"),
            ("initial_condition", self.initial_condition in ("held", "rest"), "'held' or 'rest'"),
            (
                "starts",
                all(s in ("held", "rest") for s in self.starts)
                and len(set(self.starts)) == len(self.starts),
                "a list of distinct starts, each 'held' or 'rest'",
            ),
            ("n_random", 0 <= self.n_random <= 100, "in 0..100"),
            ("seed", 0 <= self.seed < 2**31, "in 0..2**31 - 1"),
        )
        for name, ok, rule in checks:
            if not ok:
                raise ValueError(f"{name}: must be {rule}, got {getattr(self, name)!r}")

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


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
        if kind is bool and not isinstance(value, bool):
            raise ValueError(f"{name}: must be true or false, got {value!r}")
        if kind is int and (isinstance(value, bool) or not float(value).is_integer()):
            raise ValueError(f"{name}: must be an integer, got {value!r}")
        if kind is tuple:
            if not isinstance(value, list | tuple) or not all(isinstance(v, str) for v in value):
                raise ValueError(f"{name}: must be a list of names, got {value!r}")
            typed[name] = tuple(value)
            continue
        typed[name] = kind(value) if kind is not str else value
    return replace(base, **typed)
