"""``classify_multi``: the regime of every contact at many (r, beta) points (docs/contacts.md 5)."""

from __future__ import annotations

from dataclasses import dataclass, fields
from functools import lru_cache

import numpy as np

from tasks import numba_cache, regimes
from tasks.fidelity import resolve
from tasks.multicontact import layout, steady
from tasks.multicontact.scene import MultiScene
from tasks.multicontact.sets import StuckSets, stuck_sets

#: Per-contact fields (trailing axis ``contact`` of length k) and their columns.
CONTACT_COLUMNS = {
    "regime": layout.OC_REGIME,
    "stops_per_cycle": layout.OC_STOPS,
    "slip_amplitude": layout.OC_AMP,
    "stick_fraction": layout.OC_STICK,
    "dissipation": layout.OC_DISSIPATION,
    "contact_force_amplitude": layout.OC_FORCE,
}
#: Per-point fields and their columns.
POINT_COLUMNS = {
    "converged": layout.OG_CONVERGED,
    "cycles": layout.OG_CYCLES,
    "period": layout.OG_PERIOD,
    "initial_condition": layout.OG_IC,
    "asymptotic": layout.OG_ASYMPTOTIC,
    "dissipation_viscous": layout.OG_VISCOUS,
}
DTYPES = {
    "regime": np.int8,
    "stops_per_cycle": np.int16,
    "converged": np.bool_,
    "cycles": np.int32,
    "period": np.int8,
    "initial_condition": np.int8,
    "asymptotic": np.bool_,
}


def combined_label(regime: np.ndarray) -> np.ndarray:
    """One code per point from the per-contact regimes (trailing axis k).

    ``sum_c regime_c 3^c`` (contact 0 the least significant ternary digit: 0 ..
    3^k - 1) when every contact's regime is determined; otherwise the smallest
    (most severe) negative code of :mod:`tasks.regimes`. Two contacts: 0 = both
    no motion, 1 = contact 0 stick-slip and contact 1 no motion, ... 8 = both continuous.
    """
    regime = np.asarray(regime, dtype=np.int64)
    k = regime.shape[-1]
    weights = 3 ** np.arange(k)
    code = (np.clip(regime, 0, 2) * weights).sum(axis=-1)
    worst = regime.min(axis=-1)
    return np.where(worst < 0, worst, code).astype(np.int16)


@dataclass
class MultiResult:
    """Per-point arrays of shape ``s`` and per-contact arrays of shape ``s + (k,)``.

    ``regime`` (per contact, codes of :mod:`tasks.regimes`), ``combined``
    (:func:`combined_label`), ``converged``, ``cycles``, ``period``,
    ``initial_condition``, ``asymptotic`` (no motion reached by a creep or by
    the held margin), per contact ``stops_per_cycle``, ``slip_amplitude`` (half
    the range of ``b_c . x``), ``stick_fraction``, ``dissipation`` (``beta_c``
    times the slip distance per excitation cycle) and
    ``contact_force_amplitude`` (largest ``|F_c|`` over the period; sampled in
    stick phases), per point ``dissipation_viscous`` (the integral of
    ``r x'^T C x'`` per excitation cycle, 0 when undamped; docs/contacts.md 7),
    ``regime_rest`` (per contact, ``NOT_COMPUTED`` when rest was
    no start) and ``start_dependent`` (two starts gave different regimes).
    """

    regime: np.ndarray
    combined: np.ndarray
    converged: np.ndarray
    cycles: np.ndarray
    period: np.ndarray
    initial_condition: np.ndarray
    asymptotic: np.ndarray
    stops_per_cycle: np.ndarray
    slip_amplitude: np.ndarray
    stick_fraction: np.ndarray
    dissipation: np.ndarray
    contact_force_amplitude: np.ndarray
    dissipation_viscous: np.ndarray
    regime_rest: np.ndarray
    start_dependent: np.ndarray

    @property
    def shape(self) -> tuple[int, ...]:
        return self.converged.shape

    @property
    def n_contacts(self) -> int:
        return self.regime.shape[-1]

    def as_dict(self) -> dict[str, np.ndarray]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


@lru_cache(maxsize=32)
def stuck_sets_cached(scene: MultiScene) -> StuckSets:
    """:func:`tasks.multicontact.sets.stuck_sets`, once per scene."""
    return stuck_sets(scene)


def run_raw(scene: MultiScene, r: np.ndarray, beta: np.ndarray, settings: tuple):
    """The compiled simulator's raw output for flat arrays ``r``, ``beta``."""
    args = stuck_sets_cached(scene).kernel_args()
    numba_cache.announce_compile(kernel=numba_cache.SEVERAL_CONTACTS)
    return steady.run_points(
        np.ascontiguousarray(r, dtype=float),
        np.ascontiguousarray(beta, dtype=float),
        args,
        settings,
    )


def classify_multi(
    scene: MultiScene, r, beta, fidelity: str = "balanced", **settings: object
) -> MultiResult:
    """Steady-state regime of every contact of ``scene`` at every (r, beta).

    Parameters as :func:`tasks.classify`; contact c has friction
    ``beta_ratio[c] * beta``. Starts: ``initial_condition`` / ``starts`` of
    "held" and "rest", and ``n_random`` seeded random starts
    (:func:`tasks.multicontact.starts.random_start`); ``start_dependent`` flags a
    point where two starts reached different regimes.

    Raises
    ------
    ValueError
        Naming the field (as :func:`tasks.classify`).
    """
    from tasks.classifier import BETA_MAX, R_RANGE, check_points, settings_args, start_codes

    if not isinstance(scene, MultiScene):
        raise ValueError(f"scene: must be a MultiScene, got {type(scene).__name__}")
    if not isinstance(fidelity, str):
        raise ValueError(f"fidelity: must be a string, got {fidelity!r}")
    resolved = resolve(fidelity, **settings)
    r_arr, beta_arr = np.broadcast_arrays(
        check_points("r", r, *R_RANGE, open_lower=False),
        check_points("beta", beta, 0.0, BETA_MAX, open_lower=False),
    )
    shape = r_arr.shape
    k = scene.n_contacts
    codes = start_codes(resolved)
    outs = [
        run_raw(scene, r_arr.ravel(), beta_arr.ravel(), settings_args(resolved, c)) for c in codes
    ]
    out_g, out_c = outs[0]
    data: dict[str, np.ndarray] = {}
    for name, col in POINT_COLUMNS.items():
        data[name] = out_g[:, col].astype(DTYPES.get(name, np.float64)).reshape(shape)
    for name, col in CONTACT_COLUMNS.items():
        value = out_c[:, :, col]
        if name in DTYPES:
            value = np.nan_to_num(value, nan=0.0)
        data[name] = value.astype(DTYPES.get(name, np.float64)).reshape((*shape, k))
    data["combined"] = combined_label(data["regime"])
    rest = np.full((*shape, k), regimes.NOT_COMPUTED, dtype=np.int8)
    dependent = np.zeros(shape, dtype=bool)
    for code, (_, oc) in zip(codes, outs, strict=True):
        reg = oc[:, :, layout.OC_REGIME].astype(np.int8).reshape((*shape, k))
        if code == regimes.IC_REST:
            rest = reg
        both = (reg >= 0) & (data["regime"] >= 0)
        dependent |= np.any(both & (reg != data["regime"]), axis=-1)
    data["regime_rest"] = rest
    data["start_dependent"] = dependent
    return MultiResult(**data)
