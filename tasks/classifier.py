"""``classify``: steady-state motion regime of many (r, beta) points of one scene."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from tasks import kernel, regimes
from tasks.fidelity import Settings, resolve
from tasks.model import SceneModes, scene_modes
from tasks.result import FIELDS, ClassifyResult
from tasks.scene import Scene

_IC_CODES = {name: code for code, name in regimes.INITIAL_CONDITIONS.items()}


@lru_cache(maxsize=64)
def scene_modes_cached(scene: Scene) -> SceneModes:
    """:func:`tasks.model.scene_modes`, computed once per scene."""
    return scene_modes(scene)


def settings_args(settings: Settings, start: int | None = None) -> tuple:
    """The solver settings as the tuple the kernels take (:func:`tasks.kernel._context`).

    ``start`` overrides the initial condition code (``tasks.regimes.IC_*``;
    ``IC_RANDOM + k`` is the k-th seeded random start)."""
    ic = _IC_CODES[settings.initial_condition] if start is None else int(start)
    return (
        float(settings.event_tol),
        float(settings.step_fraction),
        float(settings.section_rtol),
        int(settings.max_cycles),
        int(settings.min_cycles),
        bool(settings.shooting),
        int(settings.shooting_after),
        int(settings.max_events),
        float(settings.growth_factor),
        ic,
        float(settings.max_work),
        int(settings.seed),
    )


def classify(
    scene: Scene,
    r: float | np.ndarray,
    beta: float | np.ndarray,
    fidelity: str = "balanced",
    **settings: object,
) -> ClassifyResult:
    """Steady-state motion regime of ``scene`` at every (r, beta).

    Each point is simulated exactly, event by event (:mod:`tasks.kernel`),
    from the *held* initial condition (contact stuck at zero relative
    displacement, the other masses on the forced response of the held system)
    until the Poincare section at ``tau = 2 pi n`` repeats (period 1 or 2), or a
    stick phase provably never ends (no motion).

    Parameters
    ----------
    scene : Scene
        The chain and its contact.
    r, beta : float or array_like
        Frequency ratio (> 0, Eq. 7) and friction ratio (>= 0, Eq. 8); they
        broadcast together.
    fidelity : {"fast", "balanced", "exact"}
        Preset of solver settings (:mod:`tasks.fidelity`).
    **settings
        Overrides of single settings, e.g. ``max_cycles=5000``; several starts
        per point with ``starts=("held", "rest")`` and ``n_random=4`` (seeded
        random starts, ``seed=0``; :mod:`tasks.fidelity`). Each start costs one
        more simulation of every point.

    Returns
    -------
    ClassifyResult
        Arrays of the broadcast shape: ``regime`` (codes of
        :mod:`tasks.regimes`; negative = undetermined, with the reason),
        ``converged``, ``cycles``, ``stops_per_cycle``, ``slip_amplitude``,
        ``stick_fraction``, ``period``, ``initial_condition`` (of the first
        start), ``asymptotic`` (no motion reached by a creep: slips shrinking
        below the threshold of ``tasks.regimes.SLIP_RTOL``), and over all starts
        ``regime_rest``, ``regimes_reached`` (bit mask) and ``start_dependent``.

    Raises
    ------
    ValueError
        For r <= 0, beta < 0, non-finite values or bad settings.
    """
    resolved = resolve(fidelity, **settings)
    r_arr, beta_arr = np.broadcast_arrays(
        np.asarray(r, dtype=np.float64), np.asarray(beta, dtype=np.float64)
    )
    if not np.all(np.isfinite(r_arr)) or np.any(r_arr <= 0.0):
        raise ValueError("r: every frequency ratio must be positive and finite")
    if not np.all(np.isfinite(beta_arr)) or np.any(beta_arr < 0.0):
        raise ValueError("beta: every friction ratio must be >= 0 and finite")
    shape = r_arr.shape
    flat_r = np.ascontiguousarray(r_arr.ravel())
    flat_beta = np.ascontiguousarray(beta_arr.ravel())
    scene_args = scene_modes_cached(scene).kernel_args()
    codes = start_codes(resolved)
    runs = [
        kernel.run_points(flat_r, flat_beta, scene_args, settings_args(resolved, c))[0]
        for c in codes
    ]
    return result_from_kernel(runs[0], shape, runs[1:], codes)


def start_codes(settings: Settings) -> list[int]:
    """Initial condition codes of the starts to run, the first giving ``regime``:
    ``settings.starts`` (or ``initial_condition`` alone) and ``n_random`` seeded
    random starts."""
    named = settings.starts or (settings.initial_condition,)
    codes = [_IC_CODES[s] for s in named]
    return codes + [regimes.IC_RANDOM + k for k in range(settings.n_random)]


def reached_bit(regime: np.ndarray) -> np.ndarray:
    """Bit of ``regimes_reached`` for each regime code: ``1 << code`` for a regime
    (0, 1, 2), ``1 << 3`` for any undetermined code."""
    regime = np.asarray(regime, dtype=np.int64)
    return np.where(regime >= 0, np.left_shift(1, np.clip(regime, 0, 2)), 8).astype(np.int8)


#: Column of :func:`tasks.kernel.run_points`'s output holding each result field.
KERNEL_COLUMNS = {
    "regime": kernel.OUT_REGIME,
    "converged": kernel.OUT_CONVERGED,
    "cycles": kernel.OUT_CYCLES,
    "stops_per_cycle": kernel.OUT_STOPS,
    "slip_amplitude": kernel.OUT_AMP,
    "stick_fraction": kernel.OUT_STICK,
    "period": kernel.OUT_PERIOD,
    "initial_condition": kernel.OUT_IC,
    "asymptotic": kernel.OUT_ASYMPTOTIC,
}


def result_from_kernel(
    out: np.ndarray,
    shape: tuple[int, ...],
    others: list[np.ndarray] = (),
    codes: list[int] = (regimes.IC_HELD,),
) -> ClassifyResult:
    """A :class:`ClassifyResult` of ``shape`` from the kernel's ``(n_points, N_OUT)``
    output of the first start and ``others``, the outputs of the other starts
    (initial condition ``codes``, the first one that of ``out``)."""
    fields = {
        name: out[:, col].astype(FIELDS[name][0]).reshape(shape)
        for name, col in KERNEL_COLUMNS.items()
    }
    all_regimes = [out[:, kernel.OUT_REGIME]] + [o[:, kernel.OUT_REGIME] for o in others]
    reached = np.zeros(out.shape[0], dtype=np.int8)
    for reg in all_regimes:
        reached |= reached_bit(reg)
    rest = np.full(out.shape[0], regimes.NOT_COMPUTED, dtype=np.int8)
    for code, reg in zip(codes, all_regimes, strict=False):
        if code == regimes.IC_REST:
            rest = reg.astype(np.int8)
    determined = (reached & 7).astype(np.int64)
    n_regimes = (determined & 1) + ((determined >> 1) & 1) + ((determined >> 2) & 1)
    fields["regime_rest"] = rest.reshape(shape)
    fields["regimes_reached"] = reached.reshape(shape)
    fields["start_dependent"] = (n_regimes >= 2).reshape(shape)
    return ClassifyResult(**fields)
