"""Closed-form boundaries of the motion regimes (Marino & Cicirello 2021; docs/theory.md 4).

Every configuration of :class:`tasks.scene.Scene` is one linear chain with one
Coulomb contact (docs/theory.md 2, :mod:`analysis.modal`):

    M x'' + K x = p cos(tau) + F_c b,     M = r^2 diag(gamma),

contact direction ``b`` (``e_j`` for a ground or base wall, ``e_(j+1) - e_j`` for
a contact between masses j and j + 1), load ``p`` (``e_1``, or ``M 1`` for the
base wall in the relative coordinates z = x - y 1, Eq. 98). With the
mass-normalised modes ``psi_i`` (Eq. 26) and ``R_i = 1 / Omega_i`` (Eq. 40):

* response function ``V_b = b . (K - M)^-1 p = sum_i (b.psi_i)(psi_i.p) R_i^2/(1 - R_i^2)``
  (Eqs. 41, 46-47, 84-85, 121);
* damping function ``U_b = sum_i (b.psi_i)^2 R_i^2 u_i``,
  ``u_i = tan(pi / (2 R_i)) / R_i = sin(pi/R_i) / (R_i (1 + cos(pi/R_i)))`` (Eqs. 48-55, 58, 122);
* effective contact mass ``m_b = 1 / (b^T M^-1 b)``: ``gamma_j r^2`` for a wall
  (Eq. 53), ``G r^2`` with ``G = gamma/(1+gamma)`` for the 2DOF mass contact (Eq. 110).

**Continuous / stick-slip** (Eqs. 13, 53, 56, 59, 123; Tables 1-3)::

    beta_continuous = sqrt(V_b^2 / (U_b^2 + (S / m_b)^2)),

with ``S = 1`` (``method="paper"``) or the generalised Den Hartog ``S``
(``method="exact"``, docs/theory.md 4.3; Eq. 16 for one DOF), see :func:`generalised_S`.
For the 2DOF mass contact this is Eq. 123: the paper's equivalent system has
``U_d = G U_b`` and friction ``beta / G``, so ``G sqrt(V_d^2 / (U_d^2 + r^-4))``
is the same number.

**Motion / no motion** (Eqs. 60-63, 86-95, 124-128; Sects. 2.6.3, 3.4): hold the
contact (``x = T Q``, ``b^T T = 0``), take the forced response of the held system
``(T^T (K - M) T) Q = T^T p`` and the amplitude of the force the contact must carry,

    beta_motion = |m_b b^T M^-1 (p - K T Q)|,

which for a wall on mass j is ``|p_j + kappa_j X_(j-1) + kappa_(j+1) X_(j+1)|``
with X from the lower and upper subsystems (signed amplitudes), and for the 2DOF
mass contact is Eq. 128.

**Mass contact with N > 2** (contact between masses j and j + 1 of a longer
chain) is not in the paper. It is handled by the same formulas with
``b = e_(j+1) - e_j`` and ``p = e_1``: modal superposition over the N modes for
``V_b`` and ``U_b``, effective mass ``m_b = r^2 gamma_j gamma_(j+1) /
(gamma_j + gamma_(j+1))``, and for the motion bound the held chain in which the
two masses move as one mass ``gamma_j + gamma_(j+1)``. For N = 2 this reduces to
Eqs. 116-130.

**Singular frequency ratios.** All functions are vectorised over r and return
finite values or ``inf``, never NaN:

* held-system resonance (``r^2`` within 4 ulp of an eigenvalue of the held
  system whose peak has a non-zero residue): ``beta_motion = inf``;
* sliding-system resonance (``Omega_i = 1``): ``V_b`` and ``U_b`` are both
  infinite; ``beta_continuous`` takes its limit ``pi |psi_i.p| / (4 |b.psi_i|)``
  (Den Hartog's ``pi/4`` for one DOF), the same from both sides for both methods;
* ``Omega_i`` an odd integer > 1 (``cos(Omega_i pi) = -1``) for a mode the contact
  sees: ``U_b`` is infinite, no antisymmetric continuous motion exists, and
  ``beta_continuous = 0`` (the limit from both sides).

The quantities are computed scaled by the distance of the nearest ``Omega_i`` to
an odd integer (``beta`` is homogeneous of degree 0 in ``V, U, S``), which
removes the poles exactly.

Scenes of any structure (:meth:`tasks.scene.Scene.from_matrices`) use the same
formulas with full matrices; damped scenes take the damped closed forms of
:mod:`analysis.damped` (docs/structures.md 3), which equal these at zero damping.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from analysis import damped
from analysis.modal import ContactModes, contact_modes
from tasks.kernel.context import RESONANT_RTOL
from tasks.regimes import CONTINUOUS, NO_MOTION, STICK_SLIP
from tasks.scene import Scene

__all__ = [
    "METHODS",
    "boundaries",
    "boundaries_along",
    "continuous_bound",
    "generalised_S",
    "held_resonances",
    "motion_bound",
    "predict",
    "response_functions",
    "slip_velocity",
    "sliding_resonances",
]

METHODS = ("paper", "exact")
"""``"paper"``: S = 1 (Eqs. 13, 53, 123).
``"exact"``: generalised Den Hartog S (docs/theory.md 4.3)."""

POINTS_PER_PERIOD = 16
"""Grid points per period of the fastest mode in the search for S."""
MIN_GRID = 128
"""Smallest uniform grid on (0, pi/2) in the search for S."""
MAX_GRID = 1 << 13
"""Largest uniform grid on (0, pi/2): with Omega_max > 4 MAX_GRID / POINTS_PER_PERIOD
= 2048 (r below about sqrt(lambda_max) / 2048: very small r or very stiff or
light elements) the fastest oscillations are under-resolved (fewer than 16
points per period, refined by golden-section search) and S may be slightly
underestimated there; the time per r value stays bounded."""
END_POINTS = 24
"""Logarithmically spaced points added near tau = 0."""
CANDIDATES = 6
"""Grid maxima refined by golden-section search."""
GOLDEN_ITERATIONS = 32
"""Golden-section steps (bracket shrinks by 0.618^32 ~ 2e-7; the error of the
maximum goes with its square)."""
SNAP_ULPS = 4.0
"""r^2 within this many ulp of a held-system eigenvalue counts as its resonance."""
ABSORBER_RTOL = RESONANT_RTOL
"""r^2 within this relative distance (1e-12, the simulator's) of the eigenvalue of an
unloaded held mode that loads the contact is the absorber's point: the motion bound
is 0 there (docs/theory.md 3)."""
_TAU_COS = 0.1  # from here on cos(tau) - cos(Om tau) is evaluated directly
_CHUNK = 1 << 20  # elements of the (r, tau, mode) work arrays per block

_EPS = np.finfo(float).eps


# ----------------------------------------------------------------------------- inputs
#: Frequency ratios the closed forms are evaluated for: within it every term
#: (r^2, r^4, Omega_i = omega_i / r) is finite and normal in double precision, so
#: the bounds are accurate without overflow; beyond it they would overflow.
R_RANGE = (1e-100, 1e100)


def _as_r(r: ArrayLike) -> np.ndarray:
    """r as a float array of numbers in :data:`R_RANGE` (strings and booleans refused)."""
    arr = np.asarray(r)
    if arr.dtype.kind not in "iuf":
        raise ValueError(f"r: must be a number or an array of numbers, got {r!r}"[:200])
    r_arr = arr.astype(float)
    lo, hi = R_RANGE
    ok = np.isfinite(r_arr) & (r_arr >= lo) & (r_arr <= hi)
    if not np.all(ok):
        bad = r_arr[~ok].flat[0]
        raise ValueError(
            f"r: every frequency ratio must be finite and in [{lo:g}, {hi:g}], got {float(bad)!r}"
        )
    return r_arr


def _undamped(scene: Scene, what: str) -> None:
    """The modal functions of the undamped scene; damped: analysis.damped."""
    if scene.damped:
        raise ValueError(
            f"scene: {what} is for undamped scenes; a damped one has "
            "analysis.damped.half_period_terms (docs/structures.md 3)"
        )


def _check_scene(scene: object) -> None:
    if not isinstance(scene, Scene):
        got = type(scene).__name__
        raise TypeError(f"scene: must be a tasks.Scene, e.g. Scene('ground', 2), got a {got}")


def _check_method(method: str) -> None:
    if method not in METHODS:
        raise ValueError(f"method: must be one of {METHODS}, got {method!r}")


# ---------------------------------------------------------------- per-r modal terms
@dataclass(frozen=True)
class _Terms:
    """Per-(r, mode) quantities, optionally scaled by ``scale`` (shape (n_r,)).

    ``V, U`` are ``scale`` times ``V_b, U_b``; ``A, C`` are the coefficients of
    ``scale * m_b h(tau)`` (see :func:`_ratio`).
    """

    Om: np.ndarray
    active: np.ndarray
    scale: np.ndarray
    V: np.ndarray
    U: np.ndarray
    A: np.ndarray
    C: np.ndarray
    odd_pole: np.ndarray  # (n_r,) an active Omega_i exactly an odd integer > 1 (unscaled only)


def _odd_split(Om: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest odd integer n, ``delta = Omega - n`` in [-1, 1) and ``g = delta tan(Omega pi/2)``.

    ``tan(Omega pi/2) = -cot(delta pi/2) = g / delta`` with
    ``g = -(2/pi) cos(delta pi/2) / sinc(delta/2)``, finite (in [-1, 0]) for all
    Omega: the pole of ``u_i`` at odd ``Omega_i`` is carried by ``1/delta`` alone.
    """
    n = 2.0 * np.floor(0.5 * Om) + 1.0
    delta = Om - n
    g = -(2.0 / np.pi) * np.cos(0.5 * np.pi * delta) / np.sinc(0.5 * delta)
    return n, delta, g


def _terms(modes: ContactModes, r: np.ndarray, scaled: bool) -> _Terms:
    """Modal terms at the frequency ratios ``r`` (1-D).

    With ``scaled`` the scale is ``min_i |delta_i|`` over the modes the contact sees
    (0 exactly at a pole), and every pole ``1/delta_i`` becomes
    ``q_i = scale/delta_i`` (1 where ``delta_i = 0``: the limit from above, which
    gives the same beta as from below). Without it the scale is 1 and a pole
    gives ``inf`` (``V``, ``U``) or sets ``odd_pole``.
    """
    lam = modes.lam
    active = modes.cb != 0.0
    Om = np.sqrt(lam)[None, :] / r[:, None]
    n, delta, g = _odd_split(Om)
    first = n == 1.0  # poles of V_b (Omega_i = 1) live only here
    at_pole = (delta == 0.0) & active[None, :]
    if scaled:
        scale = np.min(np.where(active[None, :], np.abs(delta), np.inf), axis=1)
        q = np.divide(
            np.broadcast_to(scale[:, None], delta.shape),
            delta,
            out=np.ones_like(delta),
            where=delta != 0.0,
        )
    else:
        scale = np.ones(r.shape)
        q = np.divide(1.0, delta, out=np.zeros_like(delta), where=delta != 0.0)
    q = np.where(active[None, :], q, 0.0)
    r2 = (r * r)[:, None]
    # V_b = r^alpha sum cb p0 / (lambda_i - r^2); lambda_i - r^2 = r^2 delta (Omega + 1) if n = 1.
    cp = (modes.cb * modes.p0)[None, :]
    v_far = scale[:, None] / np.where(first, 1.0, Om * Om - 1.0)
    v_terms = np.where(first, q / (Om + 1.0), v_far) / r2
    V = r**modes.alpha * np.sum(cp * v_terms, axis=1)
    # U_b = sum (cb/r)^2 R_i t_i, t_i = g_i / delta_i.
    cb2 = (modes.cb**2)[None, :]
    U = np.sum(cb2 * g * q / Om, axis=1) / (r * r)
    odd_pole = np.zeros(r.shape, dtype=bool)
    if not scaled:
        V = np.where(np.any(at_pole & first & (cp != 0.0), axis=1), np.inf, V)
        U = np.where(np.any(at_pole, axis=1), np.inf, U)
        odd_pole = np.any(at_pole & ~first, axis=1)
    # m_b h(tau) = sum w_i R_i [sin(Om tau) + t_i (Om - 1) (cos tau - cos(Om tau)) / (Om - 1)],
    # with t_i (Om - 1) = g_i for n = 1 (finite at the resonance) and g_i (Om - 1) / delta_i else.
    wR = modes.weights[None, :] / Om
    A = wR * scale[:, None]
    t_om1 = np.where(first, g * scale[:, None], g * q * (Om - 1.0))
    C = wR * t_om1
    C = np.where(odd_pole[:, None], 0.0, C)
    return _Terms(Om, active, scale, V, U, A, C, odd_pole)


# ------------------------------------------------------------------- the sup for S
def _ratio(tau: np.ndarray, Om: np.ndarray, A: np.ndarray, C: np.ndarray) -> np.ndarray:
    """``m_b h(tau) / sin(tau)`` (times the scale) for tau of shape (n_r, n_tau).

    With ``h`` of docs/theory.md 4.3 written as
    ``U cos tau + sum c_i^2 R_i [sin(Om tau) - t_i cos(Om tau)]
    = sum c_i^2 R_i [sin(Om tau) + t_i (cos tau - cos(Om tau))]``,
    ``A`` is the coefficient of ``sin(Om tau)`` and ``C`` that of
    ``(cos tau - cos(Om tau)) / (Om - 1)``. The difference is evaluated without
    cancellation as ``2 sin((Om+1) tau/2) sin((Om-1) tau/2)`` for small tau, and
    for ``|Om - 1| < 1/4`` (all tau) the quotient as
    ``tau sin((Om+1) tau/2) sinc((Om-1) tau/(2 pi))``, so that the resonance
    ``Om -> 1`` has its finite limit.
    """
    ot = tau[:, :, None] * Om[:, None, :]
    near = np.abs(Om - 1.0) < 0.25
    om1 = np.where(near, 1.0, Om - 1.0)
    far = np.all(tau >= _TAU_COS, axis=0)
    diff = np.empty_like(ot)
    if far.any():
        diff[:, far] = np.cos(tau[:, far])[:, :, None] - np.cos(ot[:, far])
    if not far.all():
        half = 0.5 * tau[:, ~far, None]
        diff[:, ~far] = 2.0 * np.sin(half * (Om + 1.0)[:, None, :])
        diff[:, ~far] *= np.sin(half * (Om - 1.0)[:, None, :])
    diff /= om1[:, None, :]
    cols = np.flatnonzero(np.any(near, axis=0))
    if cols.size:
        half = 0.5 * tau[:, :, None]
        om = Om[:, None, cols]
        prod = 2.0 * np.sin(half * (om + 1.0)) * half * np.sinc(half * (om - 1.0) / np.pi)
        diff[:, :, cols] = np.where(near[:, None, cols], prod, diff[:, :, cols])
    num = np.matmul(np.sin(ot), A[:, :, None]) + np.matmul(diff, C[:, :, None])
    return num[:, :, 0] / np.sin(tau)


def _sup_ratio(Om: np.ndarray, A: np.ndarray, C: np.ndarray, active: np.ndarray) -> np.ndarray:
    """``sup over 0 < tau < pi`` of :func:`_ratio`, for each row (r value).

    Every mode term of ``h`` is odd about the middle of the half period,
    ``h(pi - tau) = -h(tau)`` (use ``sin(Om pi) - t cos(Om pi) = t`` and
    ``cos(Om pi) + t sin(Om pi) = 1`` with ``t = tan(Om pi/2)``), so the sup over
    (0, pi) is the sup of ``|ratio|`` over (0, pi/2]. It is searched on a uniform
    grid resolving the fastest mode the contact sees (:data:`POINTS_PER_PERIOD`,
    between :data:`MIN_GRID` and :data:`MAX_GRID` points) plus a logarithmic grid
    towards tau = 0; the best grid maxima are refined by golden-section search on
    their two neighbouring cells.
    """
    n_r = Om.shape[0]
    out = np.full(n_r, -np.inf)
    if n_r == 0:
        return out
    used = active & (np.any(A != 0.0, axis=0) | np.any(C != 0.0, axis=0))
    Om, A, C = Om[:, used], A[:, used], C[:, used]
    if Om.shape[1] == 0:
        return np.zeros(n_r)
    om_max = np.max(Om, axis=1)
    want = np.ceil(0.25 * POINTS_PER_PERIOD * om_max)  # om_max/4 periods in (0, pi/2)
    n_grid = np.clip(2 ** np.ceil(np.log2(np.maximum(want, 1.0))), MIN_GRID, MAX_GRID).astype(int)
    k = min(CANDIDATES, MIN_GRID)
    lo = np.zeros((n_r, k))
    hi = np.zeros((n_r, k))
    valid = np.zeros((n_r, k), dtype=bool)
    for n in np.unique(n_grid):
        rows = np.flatnonzero(n_grid == n)
        per_row = (n + END_POINTS) * Om.shape[1]
        step = max(1, _CHUNK // per_row)
        for start in range(0, rows.size, step):
            idx = rows[start : start + step]
            out[idx], lo[idx], hi[idx], valid[idx] = _grid_block(
                int(n), k, Om[idx], A[idx], C[idx], om_max[idx]
            )
    refined = np.where(valid, _golden_max(lo, hi, Om, A, C), -np.inf)
    return np.maximum(out, np.max(refined, axis=1))


def _grid_block(n: int, k: int, Om: np.ndarray, A: np.ndarray, C: np.ndarray, om_max: np.ndarray):
    """Grid maximum of ``|ratio|`` and brackets of its ``k`` best local maxima (one grid size)."""
    n_r = Om.shape[0]
    uni = 0.5 * np.pi * (np.arange(n) + 0.5) / n
    first = uni[0]
    lo = np.minimum(0.5 * first, 1e-3 / np.maximum(om_max, 1.0))
    frac = np.linspace(0.0, 1.0, END_POINTS, endpoint=False)
    left = np.exp(np.log(lo)[:, None] + frac[None, :] * np.log(first / lo)[:, None])
    tau = np.concatenate([left, np.broadcast_to(uni, (n_r, n))], axis=1)
    f = np.abs(_ratio(tau, Om, A, C))
    best = np.max(f, axis=1)
    # local maxima of the grid; brackets end at tau = 0 and at the mirror image
    # pi - tau_last of the last point (|ratio| is symmetric about pi/2)
    pad = np.concatenate([np.full((n_r, 1), -np.inf), f, f[:, -1:]], axis=1)
    is_max = (f >= pad[:, :-2]) & (f >= pad[:, 2:])
    score = np.where(is_max, f, -np.inf)
    cand = np.argpartition(-score, k - 1, axis=1)[:, :k]
    tpad = np.concatenate([np.zeros((n_r, 1)), tau, np.pi - tau[:, -1:]], axis=1)
    rows = np.arange(n_r)[:, None]
    valid = np.isfinite(score[rows, cand])
    return best, tpad[rows, cand], tpad[rows, cand + 2], valid


def _golden_max(a: np.ndarray, b: np.ndarray, Om: np.ndarray, A: np.ndarray, C: np.ndarray):
    """Vectorised golden-section maximisation of ``|_ratio|`` on brackets [a, b]."""
    phi = 0.5 * (np.sqrt(5.0) - 1.0)
    c = b - phi * (b - a)
    d = a + phi * (b - a)
    fc = np.abs(_ratio(c, Om, A, C))
    fd = np.abs(_ratio(d, Om, A, C))
    best = np.maximum(fc, fd)
    for _ in range(GOLDEN_ITERATIONS):
        left = fc >= fd  # the maximum is in [a, d]
        a = np.where(left, a, c)
        b = np.where(left, d, b)
        new = np.where(left, b - phi * (b - a), a + phi * (b - a))
        f_new = np.abs(_ratio(new, Om, A, C))
        best = np.maximum(best, f_new)
        c, d = np.where(left, new, d), np.where(left, c, new)
        fc, fd = np.where(left, f_new, fd), np.where(left, fc, f_new)
    return best


# ------------------------------------------------------------------------ public API
def response_functions(scene: Scene, r: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Response function V_b, damping function U_b and effective contact mass m_b.

    Parameters
    ----------
    scene : tasks.scene.Scene
    r : array_like
        Frequency ratios r = r_1 > 0 (Eq. 7), any shape.

    Returns
    -------
    V_b : ndarray
        ``b . (K - M)^-1 p`` (Eqs. 41, 46-47, 84-85, 121): the undamped response of
        the contact coordinate (relative displacement for a mass contact).
    U_b : ndarray
        ``sum_i (b . psi_i)^2 R_i^2 u_i`` (Eqs. 49-55, 58, 122).
    m_b : ndarray
        ``1 / (b^T M^-1 b)``: ``gamma_j r^2`` (Eq. 53) or ``G r^2`` (mass contact).

    Notes
    -----
    At a pole the value is ``+inf`` (its sign is undefined there): ``V_b`` at a
    resonance of the sliding system seen by the contact and the load, ``U_b`` where
    some ``Omega_i`` the contact sees is an odd integer. For the 2DOF mass contact
    the paper's ``V_d`` (Eq. 121) equals ``V_b`` and its ``U_d`` (Eq. 122) equals
    ``G U_b``.
    """
    r_arr = _as_r(r)
    _undamped(scene, "response_functions")
    modes = contact_modes(scene)
    rf = r_arr.ravel()
    t = _terms(modes, rf, scaled=False)
    m_b = rf * rf / modes.b_gamma_b
    shape = r_arr.shape
    return t.V.reshape(shape), t.U.reshape(shape), m_b.reshape(shape)


def generalised_S(scene: Scene, r: ArrayLike) -> np.ndarray:
    """Generalised Den Hartog S of docs/theory.md 4.3 (Eq. 16 for one DOF).

    ``S = max(1, sup_{0 < tau < pi} m_b h(tau) / sin(tau))`` with

        h(tau) = U_b cos(tau)
                 + sum_i (b.psi_i)^2 R_i [sin(Omega_i tau) - tan(Omega_i pi/2) cos(Omega_i tau)],

    the friction-driven part of the contact velocity during a half period of the
    antisymmetric continuous motion (reversal at tau = 0):
    ``b.x'(tau) = -|V_b| sqrt(1 - beta^2 U_b^2 / V_b^2) sin(tau) + beta h(tau)``
    (:func:`slip_velocity`). Condition (c), ``b.x' < 0`` on (0, pi), is monotone
    in beta at every tau, so the admissible betas form an interval [0, beta*) with
    ``beta* = sqrt(V_b^2 / (U_b^2 + (S/m_b)^2))``; condition (a) ``|beta U_b| <=
    |V_b|`` then holds automatically. S does not depend on beta.

    ``m_b h / sin`` tends to 1 as tau -> 0 (condition (b), the paper's S = 1) and
    to -1 as tau -> pi; in fact ``h(pi - tau) = -h(tau)``, so the sup is that of
    ``|m_b h / sin|`` over (0, pi/2]. For one DOF (``b.psi = 1/r``, ``R = r``,
    ``m_b = r^2``) this is exactly Eq. 16.

    Parameters
    ----------
    scene : tasks.scene.Scene
    r : array_like
        Frequency ratios (> 0), any shape.

    Returns
    -------
    S : ndarray
        ``>= 1``; finite at the resonances ``Omega_i = 1``; ``inf`` where an
        ``Omega_i`` the contact sees is an odd integer > 1.

    Notes
    -----
    The sup is found on a grid resolving the fastest mode plus golden-section
    refinement (see :data:`MAX_GRID` for its limit at very high Omega).
    """
    r_arr = _as_r(r)
    _undamped(scene, "generalised_S")
    rf = r_arr.ravel()
    modes = contact_modes(scene)
    t = _terms(modes, rf, scaled=False)
    S = np.maximum(1.0, _sup_ratio(t.Om, t.A, t.C, t.active))
    S = np.where(t.odd_pole, np.inf, S)
    return S.reshape(r_arr.shape)


def continuous_bound(scene: Scene, r: ArrayLike, method: str = "paper") -> np.ndarray:
    """Boundary between continuous and stick-slip motion, ``beta_continuous(r)``.

    ``sqrt(V_b^2 / (U_b^2 + (S / m_b)^2))`` with ``S = 1`` (``"paper"``: Eqs. 13
    with S = 1, 53, 56, 59, 123; Tables 1-3 with the Table 2 misprint fixed,
    docs/theory.md 6) or S of :func:`generalised_S` (``"exact"``: the largest beta
    admitting the antisymmetric continuous motion, conditions (a)-(c) of
    docs/theory.md 4.3). ``"exact" <= "paper"``, with equality where S = 1.

    Parameters
    ----------
    scene : tasks.scene.Scene
    r : array_like
        Frequency ratios (> 0), any shape.
    method : {"paper", "exact"}

    Returns
    -------
    ndarray
        Same shape as ``r``; finite and >= 0 (limits at the poles, see the module
        notes).
    """
    _check_scene(scene)
    _check_method(method)
    r_arr = _as_r(r)
    if scene.damped:  # docs/structures.md 3.2
        return damped.continuous_bound(scene, r_arr, method)
    rf = r_arr.ravel()
    modes = contact_modes(scene)
    t = _terms(modes, rf, scaled=True)
    if method == "exact":
        S_scaled = np.maximum(t.scale, _sup_ratio(t.Om, t.A, t.C, t.active))
    else:
        S_scaled = t.scale
    den = np.hypot(t.U, S_scaled * modes.b_gamma_b / (rf * rf))
    num = np.abs(t.V)
    beta = np.divide(num, den, out=np.zeros_like(num), where=den > 0.0)
    return beta.reshape(r_arr.shape)


def motion_bound(scene: Scene, r: ArrayLike) -> np.ndarray:
    """Boundary between motion and no motion, ``beta_motion(r)`` (Sects. 2.5, 2.6.3, 3.3, 3.4, 4.3).

    Amplitude of the total dynamic load on the held contact,
    ``|m_b b^T M^-1 (p - K T Q)|`` with Q the forced response of the held
    system. Reproduces 1 and r^2 (SDOF), Eqs. 63, 89, 94, 128 and the
    lower/upper-subsystem procedure of Sect. 2.6.3 (signed amplitudes).

    Parameters
    ----------
    scene : tasks.scene.Scene
    r : array_like
        Frequency ratios (> 0), any shape.

    Returns
    -------
    ndarray
        Same shape as ``r``; ``inf`` at a resonance of the held system (``r^2``
        within :data:`SNAP_ULPS` ulp of one of its eigenvalues with non-zero
        residue); 0 where an unloaded held mode that loads the contact is resonant
        (:data:`ABSORBER_RTOL`): its free vibration, a tuned absorber, cancels the
        held contact force (docs/theory.md 3).
    """
    _check_scene(scene)
    r_arr = _as_r(r)
    if scene.damped:  # docs/structures.md 3.1
        return damped.motion_bound(scene, r_arr)
    rf = r_arr.ravel()
    modes = contact_modes(scene)
    r2 = (rf * rf)[:, None]
    lam_s = modes.lam_s[None, :]
    z = modes.z_s[None, :]
    d = lam_s - r2
    seen = z != 0.0
    snap = (np.abs(d) <= SNAP_ULPS * _EPS * np.maximum(lam_s, r2)) & seen
    terms = np.divide(
        np.broadcast_to(z, d.shape), d, out=np.zeros_like(d), where=seen & ~snap & (d != 0.0)
    )
    F = rf**modes.alpha * np.abs(modes.F0 - np.sum(terms, axis=1))
    F = np.where(np.any(snap, axis=1), np.inf, F)
    absorb = modes.lam_absorb[None, :]
    tuned = np.abs(absorb - r2) <= ABSORBER_RTOL * np.maximum(absorb, r2)
    F = np.where(np.any(tuned, axis=1) & np.isfinite(F), 0.0, F)
    return F.reshape(r_arr.shape)


def boundaries(scene: Scene, r: ArrayLike, method: str = "paper") -> tuple[np.ndarray, np.ndarray]:
    """Both regime boundaries at the frequency ratios ``r``.

    Parameters
    ----------
    scene : tasks.scene.Scene
        Ground or base wall on any mass of any chain; mass contact between
        masses j and j + 1 (the paper's Sect. 4 for N = 2; for N > 2 the
        generalisation described in the module docstring).
    r : array_like
        Frequency ratios r > 0 (scalar or any shape).
    method : {"paper", "exact"}
        ``"paper"``: the paper's formulas (S = 1; Tables 1-3, Eqs. 13, 53, 63,
        89, 94, 123, 128; Table 2 misprint fixed, docs/theory.md 6). ``"exact"``: the
        continuous bound of docs/theory.md 4.3 (generalised S); the motion bound is the
        same for both (it is exact for the held contact).

    Returns
    -------
    beta_continuous, beta_motion : ndarray
        Arrays of shape ``np.shape(r)``: continuous motion for
        ``beta < beta_continuous``, no motion for ``beta >= beta_motion``.
        The two can cross (docs/theory.md 7); :func:`predict` gives no motion there.
    """
    _check_method(method)
    return continuous_bound(scene, r, method), motion_bound(scene, r)


#: r values per call of :func:`boundaries` in :func:`boundaries_along` (bounded memory:
#: the exact method's work arrays grow with the number of r values).
BOUNDARY_BLOCK = 256
#: Results of :func:`boundaries_along` remembered (the last ones asked for): an
#: adaptive plane's hint and its result file ask for the same curves of one scene.
REMEMBERED = 8
_remembered: OrderedDict = OrderedDict()
_remembered_lock = threading.Lock()


def boundaries_along(
    scene: Scene, r: ArrayLike, method: str = "paper"
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`boundaries` along the axis ``r``, in blocks of :data:`BOUNDARY_BLOCK` r
    values, the last :data:`REMEMBERED` answers remembered.

    Every r value is computed on its own (the blocks change no number), so the
    curves equal those of :func:`boundaries`; a second call with the same scene,
    method and r values (an adaptive map's closed-form hint, then its result file)
    returns them without computing them again.

    Returns
    -------
    beta_continuous, beta_motion : ndarray
        New arrays of shape ``np.shape(r)`` (the caller may change them).
    """
    _check_method(method)
    r = np.asarray(r, dtype=float)
    key = (scene, method, r.shape, r.tobytes())
    try:
        hash(key)
    except TypeError:  # a scene that cannot be a key: computed every time
        key = None
    found = None
    with _remembered_lock:
        if key is not None and (found := _remembered.get(key)) is not None:
            _remembered.move_to_end(key)
    if found is None:
        flat = r.ravel()
        cont = np.empty(flat.shape)
        motion = np.empty(flat.shape)
        for i in range(0, flat.size, BOUNDARY_BLOCK):
            sl = slice(i, i + BOUNDARY_BLOCK)
            c, m = boundaries(scene, flat[sl], method=method)
            cont[sl] = np.broadcast_to(np.asarray(c, dtype=float), flat[sl].shape)
            motion[sl] = np.broadcast_to(np.asarray(m, dtype=float), flat[sl].shape)
        found = (cont.reshape(r.shape), motion.reshape(r.shape))
        with _remembered_lock:
            if key is not None:
                _remembered[key] = found
            while len(_remembered) > REMEMBERED:
                _remembered.popitem(last=False)
    return found[0].copy(), found[1].copy()


def predict(scene: Scene, r: ArrayLike, beta: ArrayLike, method: str = "paper") -> np.ndarray:
    """Regime codes from the closed-form boundaries (Tables 1-3).

    Parameters
    ----------
    scene : tasks.scene.Scene
    r, beta : array_like
        Frequency ratios (> 0) and friction ratios (>= 0); broadcast against
        each other.
    method : {"paper", "exact"}
        See :func:`boundaries`.

    Returns
    -------
    ndarray of int8
        :data:`tasks.regimes.NO_MOTION` where ``beta >= beta_motion`` (also where
        the bounds cross), else :data:`tasks.regimes.CONTINUOUS` where
        ``beta < beta_continuous``, else :data:`tasks.regimes.STICK_SLIP`;
        ``beta = 0`` (the linear system, as the simulator labels it) is always
        :data:`tasks.regimes.CONTINUOUS`, also where ``beta_motion`` is 0 (a tuned
        absorber, :func:`motion_bound`).
    """
    r_arr = _as_r(r)
    beta_arr = np.asarray(beta)
    if beta_arr.dtype.kind not in "iuf":
        raise ValueError(f"beta: must be a number or an array of numbers, got {beta!r}"[:200])
    beta_arr = beta_arr.astype(float)
    if np.any(np.isnan(beta_arr)) or np.any(beta_arr < 0.0):
        raise ValueError("beta: every friction ratio must be >= 0 (and not NaN)")
    shape = np.broadcast_shapes(r_arr.shape, beta_arr.shape)
    # each distinct r once: a meshgrid repeats every r along beta (a damped scene's
    # continuous bound costs ~20 ms per r)
    r_once, where = np.unique(r_arr.ravel(), return_inverse=True)
    b_cont, b_motion = (
        b[where.ravel()].reshape(r_arr.shape) for b in boundaries(scene, r_once, method)
    )
    b_cont = np.broadcast_to(b_cont, shape)
    b_motion = np.broadcast_to(b_motion, shape)
    beta_b = np.broadcast_to(beta_arr, shape)
    codes = np.where(
        beta_b >= b_motion, NO_MOTION, np.where(beta_b < b_cont, CONTINUOUS, STICK_SLIP)
    )
    return np.where(beta_b == 0.0, CONTINUOUS, codes).astype(np.int8)


def held_resonances(scene: Scene) -> np.ndarray:
    """Frequency ratios where ``beta_motion`` is infinite (resonances of the held system).

    Only eigenvalues whose peak has a non-zero residue (the held system is
    excited there and pushes on the contact), ascending. E.g. 5DOF, ground wall
    on m_4: 0.7654, 1.4142, 1.8478 (Sect. 2.6.4).
    """
    modes = contact_modes(scene)
    return np.sqrt(modes.lam_s[modes.z_s != 0.0])


def sliding_resonances(scene: Scene) -> np.ndarray:
    """Frequency ratios ``r = sqrt(lambda_i)`` where ``V_b`` has a pole (Omega_i = 1)."""
    modes = contact_modes(scene)
    return np.sqrt(modes.lam[modes.cb * modes.p0 != 0.0])


def slip_velocity(scene: Scene, r: float, beta: float, tau: ArrayLike) -> np.ndarray:
    """Contact velocity ``b . x'(tau)`` of the antisymmetric continuous motion (docs/theory.md 4.3).

    Reversal at tau = 0 with ``b . x(0) = V_b cos(phi) > 0``; for ``0 < tau < pi``

        b.x'(tau) = -V_b sin(tau + phi) + beta sum_i (b.psi_i)^2 R_i^2 Omega_i
                    [sin(Omega_i tau) - tan(Omega_i pi/2) cos(Omega_i tau)],

    ``sin(phi) = -beta U_b / V_b``, ``V_b cos(phi) > 0``. The motion is continuous
    iff this stays negative on (0, pi); :func:`continuous_bound` with
    ``method="exact"`` is the largest such beta.

    Parameters
    ----------
    scene : tasks.scene.Scene
    r, beta : float
        One frequency ratio (not a pole) and one friction ratio with
        ``|beta U_b| <= |V_b|`` (condition (a)).
    tau : array_like
        Times in [0, pi].

    Returns
    -------
    ndarray
        Same shape as ``tau``.

    Raises
    ------
    ValueError
        At a pole (V_b, U_b or S infinite) or where condition (a) fails.
    """
    rf = _as_r(np.atleast_1d(r)).ravel()
    _undamped(scene, "slip_velocity")
    if rf.size != 1:
        raise ValueError("r: slip_velocity takes one frequency ratio")
    modes = contact_modes(scene)
    t = _terms(modes, rf, scaled=False)
    V, U = float(t.V[0]), float(t.U[0])
    if not (np.isfinite(V) and np.isfinite(U)) or t.odd_pole[0]:
        raise ValueError(f"r = {rf[0]!r} is a pole of V_b, U_b or S")
    if abs(beta * U) > abs(V):
        raise ValueError("condition (a) fails: |beta U_b| > |V_b|, no continuous motion")
    tau_arr = np.asarray(tau, dtype=float)
    tt = tau_arr.ravel()[None, :]
    # m_b h(tau) = sin(tau) * ratio; at the ends use h(0) = h(pi) = 0.
    s = np.sin(tt)
    interior = (tt > 0.0) & (tt < np.pi)
    safe = np.where(interior, tt, 0.5 * np.pi)
    mh = np.where(interior, _ratio(safe, t.Om, t.A, t.C) * np.sin(safe), 0.0)
    h = mh[0] * modes.b_gamma_b / (rf[0] ** 2)
    amp = np.sqrt(max(V * V - (beta * U) ** 2, 0.0))
    out = -amp * s[0] + beta * h
    return out.reshape(tau_arr.shape)
