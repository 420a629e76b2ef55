"""``classify``: steady-state motion regime of many (r, beta) points of one scene."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from tasks import kernel, numba_cache, regimes
from tasks.fidelity import Settings, resolve
from tasks.model import SceneModes, scene_modes
from tasks.result import DESIGN_FIELDS, FIELDS, ClassifyResult
from tasks.scene import Scene
from tasks.seeds import CANDIDATES, GIVEN_CANDIDATES, GIVEN_REACH, can_seed, warm_seeds

_IC_CODES = {name: code for code, name in regimes.INITIAL_CONDITIONS.items()}

#: Frequency ratios r (Eq. 7) the kernel handles soundly: within it the modal
#: frequencies relative to the excitation (1 / r times those of the chain) stay
#: resolvable by the bracket scan within the work budget.
R_RANGE = (1e-4, 1e4)
#: Largest friction ratio beta (Eq. 8): far above every motion bound of a scene
#: in ``R_RANGE`` (no motion), and small enough for the contact-force test.
BETA_MAX = 1e6


def check_points(name: str, value: object, lower: float, upper: float, open_lower: bool):
    """``value`` as a float64 array of numbers in range, or a ``ValueError`` naming ``name``.

    Strings, booleans and objects are refused (``np.asarray("1.0", float)`` would
    silently parse a string, ``True`` would become 1.0).
    """
    arr = np.asarray(value)
    if arr.dtype.kind not in "iuf":
        what = type(value).__name__ if arr.ndim == 0 else f"an array of {arr.dtype}"
        text = f"{name}: must be a number or an array of numbers, got {what} {value!r}"
        raise ValueError(text[:200])
    arr = arr.astype(np.float64)
    low_ok = arr > lower if open_lower else arr >= lower
    if not np.all(np.isfinite(arr)) or not np.all(low_ok & (arr <= upper)):
        bad = arr[~(np.isfinite(arr) & low_ok & (arr <= upper))].flat[0]
        rule = f"in {'(' if open_lower else '['}{lower:g}, {upper:g}]"
        raise ValueError(f"{name}: every value must be finite and {rule}, got {float(bad)!r}")
    return arr


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
        bool(settings.warm) and ic == regimes.IC_HELD,
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
        more simulation of every point. Warm starts (``warm=True``, the
        default) seed a point's search with the converged orbit of a close
        point before it in the call (:mod:`tasks.seeds`: the same labels,
        fewer periods; moving orbits polished to the fixed point, so the other
        fields agree to about 1e-9 whatever the grouping, ``cycles`` excepted);
        only the first start is seeded. ``warm=False`` runs every point from
        its start alone. ``design=True`` also computes the design quantities
        (off by default: the design pass replays every orbit once more, adding
        25-33 % to a warm point, docs/benchmarks.md; :mod:`tasks.fidelity`).

    Returns
    -------
    ClassifyResult
        Arrays of the broadcast shape: ``regime`` (codes of
        :mod:`tasks.regimes`; negative = undetermined, with the reason),
        ``converged``, ``cycles``, ``stops_per_cycle``, ``slip_amplitude``,
        ``stick_fraction``, ``period``, ``initial_condition`` (of the first
        start), ``asymptotic`` (no motion reached by a creep: slips shrinking
        below the threshold of ``tasks.regimes.SLIP_RTOL``), and over all starts
        ``regime_rest``, ``regimes_reached`` (bit mask) and ``start_dependent``;
        the design quantities ``amplitude``, ``amplitude_relative``,
        ``contact_force_amplitude``, ``dissipation`` and ``dissipation_viscous``
        of the first start's orbit (NaN where it has none) with ``design=True``,
        None otherwise (the default).

    Raises
    ------
    ValueError
        Naming the field: r outside ``R_RANGE`` (1e-4..1e4), beta outside
        0..``BETA_MAX`` (1e6), non-finite values, strings or booleans for r or
        beta, bad settings (:data:`tasks.fidelity.LIMITS`).
    """
    if type(scene).__name__ == "MultiScene":  # several contacts (docs/contacts.md)
        from tasks.multicontact import classify_multi

        return classify_multi(scene, r, beta, fidelity, **settings)
    return _classify(scene, r, beta, fidelity, settings, None)[0]


def classify_given(
    scene: Scene,
    r: np.ndarray,
    beta: np.ndarray,
    given: tuple[np.ndarray, np.ndarray, np.ndarray] | None,
    fidelity: str = "balanced",
    **settings: object,
) -> tuple[ClassifyResult, np.ndarray]:
    """:func:`classify` of a one-contact ``scene``, warm-started also from orbits solved
    outside the call, and the points' own orbits for later calls.

    ``given`` is ``(r, beta, final)`` of points solved before (None: none): their
    ``final`` rows as this function returns them. With warm starts on, each point
    is seeded by the earlier points of the call and the given points
    (:func:`tasks.seeds.warm_seeds`, up to ``GIVEN_CANDIDATES`` within
    ``GIVEN_REACH``: an adaptive map's new points lie up to a coarse step from
    the solved ones), first by an interpolation between two of them, then the
    nearest's copied orbit, secant predictions and up to ``kernel.ALT_TRIES``
    other candidates (:func:`tasks.kernel.batch._warm_tries`); the labels are those of
    :func:`classify`, the other fields agree with it to the polish (about 1e-9
    of their scale), ``cycles`` excepted.

    Returns the result and ``final``: ``(n_points, 2 N + 2)``, each point's
    section state, phase and section phase where it converged to a moving
    period-1 orbit that can seed a neighbour (NaN rows elsewhere, and everywhere
    without warm starts).
    """
    return _classify(scene, r, beta, fidelity, settings, given, True)


def _classify(scene, r, beta, fidelity, settings, given, from_given=False):
    """:func:`classify_given` (``settings``: the overrides, a dict; ``from_given``:
    called as :func:`classify_given`, whose points take seeds from farther)."""
    if not isinstance(scene, Scene):
        raise ValueError(f"scene: must be a tasks.Scene, got {type(scene).__name__}")
    if not isinstance(fidelity, str):
        raise ValueError(f"fidelity: must be a string, got {fidelity!r}")
    resolved = _resolve(fidelity, settings)
    r_arr, beta_arr = np.broadcast_arrays(
        check_points("r", r, *R_RANGE, open_lower=False),
        check_points("beta", beta, 0.0, BETA_MAX, open_lower=False),
    )
    shape = r_arr.shape
    flat_r = np.ascontiguousarray(r_arr.ravel())
    flat_beta = np.ascontiguousarray(beta_arr.ravel())
    scene_args = scene_modes_cached(scene).kernel_args()
    codes = start_codes(resolved)
    first = settings_args(resolved, codes[0])
    numba_cache.announce_compile()  # one line on stderr before a first compile
    # the design quantities of the first start's orbit, on the orbit check's replay
    samples = kernel.DESIGN_SAMPLES if resolved.design else 0
    # warm starts: the held start seeded by earlier points of the call (tasks.seeds)
    n = scene_args[0].shape[0]
    g_r, g_beta, g_final = given if given is not None else (None, None, np.zeros((0, 2 * n + 2)))
    if first[-1]:
        # an adaptive map's points lie farther from their seeds (tasks.seeds)
        wide = (GIVEN_REACH, GIVEN_CANDIDATES) if from_given else (1.0, CANDIDATES)
        seeds = warm_seeds(flat_r, flat_beta, float(scene_args[5][-1]), g_r, g_beta, *wide)
    else:
        seeds = np.full((flat_r.size, 0), -1, dtype=np.int64)
    g_final = np.asarray(g_final, dtype=np.float64).reshape(-1, 2 * n + 2)
    if given is not None:  # each given orbit's point after its row (tasks.kernel.secant)
        g_final = np.column_stack([g_final, np.ravel(g_r), np.ravel(g_beta)])
    g_final = np.ascontiguousarray(g_final).reshape(-1, 2 * n + 4)
    alt_tries = kernel.ALT_TRIES if from_given else 0
    out, final, design = kernel.run_points_given(
        flat_r, flat_beta, scene_args, first, samples, seeds, g_final, alt_tries
    )
    final[~(first[-1] & can_seed(out, flat_beta))] = np.nan
    design = design if resolved.design else None
    others = [
        kernel.run_points(flat_r, flat_beta, scene_args, settings_args(resolved, c))[0]
        for c in codes[1:]
    ]
    return result_from_kernel(out, shape, design, base_influence(scene), others, codes), final


#: Settings resolved before, by preset and overrides (:func:`_resolve`).
_RESOLVED: dict[tuple, Settings] = {}


def _resolve(fidelity: str, settings: dict) -> Settings:
    """:func:`tasks.fidelity.resolve` of ``fidelity`` and the overrides ``settings``, each
    combination checked once per process (an adaptive map's tile classifies a round of
    points per refinement level with the same settings; the check cost a tenth of a
    millisecond a call). :class:`~tasks.fidelity.Settings` is frozen, so it is shared."""
    try:
        # with each value's type: 1, 1.0 and True are equal keys, not equal overrides
        key = (fidelity, *((k, type(v), _frozen(v)) for k, v in settings.items()))
        hash(key)
    except TypeError:  # an unhashable override: checked (and refused) as it is
        return resolve(fidelity, **settings)
    got = _RESOLVED.get(key)  # (threads of one process may share it: no check-then-read)
    if got is None:
        got = resolve(fidelity, **settings)
        if len(_RESOLVED) >= 64:
            _RESOLVED.clear()
        _RESOLVED[key] = got
    return got


def _frozen(value: object) -> object:
    """A list override as a tuple of (type, item) pairs (hashable, types kept)."""
    return tuple((type(v), v) for v in value) if isinstance(value, list) else value


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
    design: np.ndarray | None = None,
    base: np.ndarray | None = None,
    others: list[np.ndarray] = (),
    codes: list[int] = (regimes.IC_HELD,),
) -> ClassifyResult:
    """A :class:`ClassifyResult` of ``shape`` from the kernel's output.

    ``out`` is :func:`tasks.kernel.run_points`' ``(n_points, N_OUT)`` array of
    the first start, ``others`` those of the other starts (initial condition
    ``codes``, the first one that of ``out``); ``design``
    :func:`tasks.kernel.orbit_designs`' ``(n_points, 2 N + 3)`` of the first
    start's orbit (NaN design quantities if omitted); ``base`` is the
    influence vector u of a base load (:func:`base_influence`: the kernel's
    coordinates are then relative to the supports, docs/theory.md 2), None for a
    force load.
    """
    fields = {
        name: out[:, col].astype(FIELDS[name][0]).reshape(shape)
        for name, col in KERNEL_COLUMNS.items()
    }
    fields.update(design_fields(design, out.shape[0], shape, base))
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


def base_influence(scene: Scene) -> np.ndarray | None:
    """Influence vector u of the scene's base load, None for a force load.

    Under a base load (a base-fixed wall, Eq. 98, or a structure's ``("base", u)``,
    docs/structures.md 1) the simulator's coordinates z are relative to the
    supports and the absolute displacement is ``z + u cos(tau)``; a chain's u is
    all ones. NaN where the design pass cannot give that absolute displacement: a
    u_i other than 0 and 1 where the kernel runs on the pairs of damping that is not
    proportional (:func:`tasks.kernel.design.other_frame`: no modes of (K, M) there).
    """
    if not scene.load_scales_r2:
        return None
    if scene.structure is None:
        return np.ones(scene.dof)
    u = np.asarray(scene.structure.load_spec[1], dtype=np.float64)
    if scene_modes_cached(scene).kernel_args()[6].shape[0] == scene.dof:  # modes Phi
        return u
    return np.where((u == 0.0) | (u == 1.0), u, np.nan)


def design_fields(
    design: np.ndarray | None, n_points: int, shape: tuple[int, ...], base: np.ndarray | None
) -> dict[str, np.ndarray]:
    """The design quantities of :data:`tasks.result.FIELDS` from the kernel's columns
    (all None when ``design`` is None: not computed).

    The kernel samples each coordinate q_i and, under a base load, the absolute
    displacement ``q_i + u_i cos(tau)`` (``base``: :func:`base_influence`;
    :func:`tasks.kernel.design.other_frame`); where u_i = 0 that is q_i itself. A
    NaN u_i (the kernel could not weigh it) leaves the absolute amplitude NaN, not
    computed, rather than a wrong number.
    """
    if design is None:
        return dict.fromkeys(DESIGN_FIELDS)
    n = (design.shape[1] - kernel.DESIGN_SCALARS) // 2
    own, other = design[:, :n], design[:, n : 2 * n]
    if base is None:
        absolute, relative = own, other
    else:
        relative = own
        absolute = np.where(base == 0.0, own, np.where(np.isnan(base), np.nan, other))
    return {
        "amplitude": absolute.reshape((*shape, n)),
        "amplitude_relative": relative.reshape((*shape, n)),
        "contact_force_amplitude": design[:, 2 * n + kernel.DESIGN_FORCE].reshape(shape),
        "dissipation": design[:, 2 * n + kernel.DESIGN_DISSIPATION].reshape(shape),
        "dissipation_viscous": design[:, 2 * n + kernel.DESIGN_VISCOUS].reshape(shape),
    }
