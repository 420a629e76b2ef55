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


def settings_args(settings: Settings) -> tuple:
    """The solver settings as the tuple the kernels take (:func:`tasks.kernel._context`)."""
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
        _IC_CODES[settings.initial_condition],
        float(settings.max_work),
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
        Overrides of single settings, e.g. ``max_cycles=5000``.

    Returns
    -------
    ClassifyResult
        Arrays of the broadcast shape: ``regime`` (codes of
        :mod:`tasks.regimes`; negative = undetermined, with the reason),
        ``converged``, ``cycles``, ``stops_per_cycle``, ``slip_amplitude``,
        ``stick_fraction``, ``period``, ``initial_condition``.

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
    args = settings_args(resolved)
    out, final = kernel.run_points(flat_r, flat_beta, scene_args, args)
    design, _ = kernel.orbit_designs(
        flat_r, flat_beta, scene_args, args, out, final, kernel.DESIGN_SAMPLES
    )
    return result_from_kernel(out, shape, design, scene.contact == "base")


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
}


def result_from_kernel(
    out: np.ndarray,
    shape: tuple[int, ...],
    design: np.ndarray | None = None,
    base: bool = False,
) -> ClassifyResult:
    """A :class:`ClassifyResult` of ``shape`` from the kernel's output.

    ``out`` is :func:`tasks.kernel.run_points`' ``(n_points, N_OUT)`` array,
    ``design`` :func:`tasks.kernel.orbit_designs`' ``(n_points, 2 N + 2)``
    (NaN design quantities if omitted); ``base`` says the kernel's coordinates
    are relative to the base (base-fixed wall, docs/theory.md 2).
    """
    fields = {
        name: out[:, col].astype(FIELDS[name][0]).reshape(shape)
        for name, col in KERNEL_COLUMNS.items()
    }
    fields.update(design_fields(design, out.shape[0], shape, base))
    return ClassifyResult(**fields)


def design_fields(
    design: np.ndarray | None, n_points: int, shape: tuple[int, ...], base: bool
) -> dict[str, np.ndarray]:
    """The design quantities of :data:`tasks.result.FIELDS` from the kernel's columns."""
    if design is None:
        design = np.full((n_points, 4), np.nan)  # dof unknown: one mass of NaN
    n = (design.shape[1] - 2) // 2
    own, other = design[:, :n], design[:, n : 2 * n]
    absolute, relative = (other, own) if base else (own, other)
    return {
        "amplitude": absolute.reshape((*shape, n)),
        "amplitude_relative": relative.reshape((*shape, n)),
        "contact_force_amplitude": design[:, 2 * n + kernel.DESIGN_FORCE].reshape(shape),
        "dissipation": design[:, 2 * n + kernel.DESIGN_DISSIPATION].reshape(shape),
    }
