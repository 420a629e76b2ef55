"""The paper's numerical method in plain scipy: the speed and accuracy baseline.

Marino & Cicirello (2021), Sect. 5: a variable-step Runge-Kutta (4,5) solver
(Matlab's ``ode45``; here ``scipy.integrate.solve_ivp(method="RK45")``) with
events, exact stick phases, 100 excitation cycles from rest, absolute tolerance
1e-6 and relative tolerance 1e-12. Pure Python + scipy, no numba; nothing here
is used by :func:`tasks.classify`, it only measures what the compiled simulator
buys (``benchmarks/bench_classify.py``, ``study bench``).

One formulation covers every contact (:mod:`tasks.scene`, :mod:`tasks.model`) and
every scene of matrices (:meth:`tasks.scene.Scene.from_matrices`: full ``M`` and
``K``, viscous damping ``C``, docs/structures.md 1). With damping this integrator
is the independent reference of the damped simulator: the terms ``C x'`` are added
to both phases and to the contact force ``g`` below (``- g_load . C x'``).

* **sliding** with sign ``s`` of the contact velocity ``v = b . x'``::

      M x'' + K x = p cos(tau) - beta s b,

  integrated until ``v`` reaches 0 (event, direction ``-s``). There the stick
  test of Eqs. 11b, 12b, 79b, 103b: with the force the contact must carry while
  stuck, ``g = b^T Gamma^-1 (p cos tau - K x) / (b^T Gamma^-1 b)``, the contact
  sticks if ``|g| <= beta``, else it reverses and slides with ``s = sgn g``;
* **stuck** (N - 1 coordinates, Eqs. 131-135): ``x = T q + d0 w`` with the
  contact frozen at ``d0 = b . x`` (:meth:`tasks.scene.Scene.stuck_basis`)::

      T^T M T q'' + T^T K T q = T^T (p cos(tau) - d0 K w),

  integrated until ``|g|`` reaches ``beta`` (events ``g = +beta`` upwards and
  ``g = -beta`` downwards); the contact then slides with ``s = sgn g``. For the
  base wall the coordinates are ``z = x - y 1`` (frozen ``z_j`` is Eq. 132); for
  the mass contact the stuck pair moves as one mass (Eqs. 134-135).

Classification from the last cycle, as the paper did: stuck for the whole last
cycle is no motion, any stick phase of positive length in it is stick-slip,
otherwise continuous. There is no steady-state test (``converged`` is False
everywhere): residual transients give the paper's "spikes" (docs/theory.md 3, 7).

Deviations, all minor: scipy accepts ``rtol >= 100 eps`` (~2.2e-14), so the
paper's 1e-12 is used as is; stuck phases use ``max_step = pi/8`` (the stuck
system of an SDOF chain has no coordinates, and an RK45 step over a constant
state would grow past a whole period and step over the ``|g| = beta`` events);
the integration is restarted at the start of the last cycle to get the state
there.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from tasks import regimes
from tasks.result import DESIGN_FIELDS, ClassifyResult
from tasks.scene import Scene

CYCLES = 100
"""Excitation cycles integrated (Sect. 5)."""
RTOL = 1e-12
"""Relative tolerance of the paper (Sect. 5); scipy accepts it (its floor is 100 eps)."""
ATOL = 1e-6
"""Absolute tolerance of the paper (Sect. 5)."""
STICK_MAX_STEP = math.pi / 8
"""Largest step in a stuck phase (see the module notes)."""
MAX_TRANSITIONS = 20_000
"""Phase changes (in the whole run, 200 per cycle on average) before it is stopped as
:data:`tasks.regimes.EVENT_LIMIT`. From rest, an undamped free vibration of the
stuck subsystem can make ``|g|`` cross ``beta`` on every one of its periods,
each time with a tiny slip (e.g. 2DOF base m_2 at r = 0.15 just above the motion
bound: over 2000 phase changes per cycle, about 0.4 ms each); the cap bounds
such a point to about 10 s."""

_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class _System:
    """Matrices of one scene at one r (plain numpy; see the module docstring)."""

    n: int
    m: int
    b: np.ndarray
    minv_p: np.ndarray  # M^-1 p
    minv_k: np.ndarray  # M^-1 K
    minv_c: np.ndarray  # M^-1 C (C = r C_hat, zeros when undamped)
    minv_b: np.ndarray  # M^-1 b
    g_p: float  # g_load . p
    g_k: np.ndarray  # g_load^T K
    g_c: np.ndarray  # g_load^T C
    T: np.ndarray
    w: np.ndarray
    proj: np.ndarray  # (T^T Gamma T)^-1 T^T Gamma: q from x (momentum conserving)
    ms_inv_tp: np.ndarray  # (T^T M T)^-1 T^T p
    ms_inv_kt: np.ndarray  # (T^T M T)^-1 T^T K T
    ms_inv_ct: np.ndarray  # (T^T M T)^-1 T^T C T
    ms_inv_kw: np.ndarray  # (T^T M T)^-1 T^T K w
    g_kt: np.ndarray  # g_load^T K T
    g_ct: np.ndarray  # g_load^T C T
    g_kw: float  # g_load^T K w


def _system(scene: Scene, r: float) -> _System:
    """Plain numpy matrices of ``scene`` at ``r``: ``M = r^2 Gamma``, ``C = r C_hat``
    (docs/structures.md 1, Eq. 1.1), full matrices allowed; nothing shared with the
    simulator's modal data (:mod:`tasks.model`)."""
    n = scene.dof
    M = scene.mass_matrix(r)
    G = scene.mass_matrix(1.0)
    C = scene.damping_matrix(r)
    K = scene.stiffness_matrix()
    p = scene.load_vector(r)
    b = scene.contact_vector()
    minv_b1 = np.linalg.solve(G, b)
    g_load = minv_b1 / float(b @ minv_b1)
    T, w = scene.stuck_basis()
    m = T.shape[1]
    Ms = T.T @ M @ T
    if m:
        ms_inv_tp = np.linalg.solve(Ms, T.T @ p)
        ms_inv_kt = np.linalg.solve(Ms, T.T @ K @ T)
        ms_inv_ct = np.linalg.solve(Ms, T.T @ C @ T)
        ms_inv_kw = np.linalg.solve(Ms, T.T @ K @ w)
        proj = np.linalg.solve(T.T @ G @ T, T.T @ G)
    else:
        ms_inv_tp = ms_inv_kw = np.zeros(0)
        ms_inv_kt = ms_inv_ct = np.zeros((0, 0))
        proj = np.zeros((0, n))
    return _System(
        n=n,
        m=m,
        b=b,
        minv_p=np.linalg.solve(M, p),
        minv_k=np.linalg.solve(M, K),
        minv_c=np.linalg.solve(M, C),
        minv_b=np.linalg.solve(M, b),
        g_p=float(g_load @ p),
        g_k=g_load @ K,
        g_c=g_load @ C,
        T=T,
        w=w,
        proj=proj,
        ms_inv_tp=ms_inv_tp,
        ms_inv_kt=ms_inv_kt,
        ms_inv_ct=ms_inv_ct,
        ms_inv_kw=ms_inv_kw,
        g_kt=g_load @ K @ T,
        g_ct=g_load @ C @ T,
        g_kw=float(g_load @ K @ w),
    )


def _contact_force(sys: _System, tau: float, x: np.ndarray, xd: np.ndarray | None = None) -> float:
    """``g = g_load . (p cos tau - K x - C x')``: the force the contact must carry to
    stay stuck (tasks.model; the viscous term is docs/structures.md 1; ``xd`` None:
    at rest)."""
    viscous = 0.0 if xd is None else float(sys.g_c @ xd)
    return sys.g_p * math.cos(tau) - float(sys.g_k @ x) - viscous


def _slide(sys, beta, s, tau0, tau1, x, xd, rtol, atol):
    """Slide with sign ``s`` from ``tau0`` until ``b . x' = 0`` or ``tau1``."""
    n = sys.n
    # first-order form y' = A y + c cos(t) + f, y = (x, x')
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -sys.minv_k
    A[n:, n:] = -sys.minv_c
    c = np.concatenate((np.zeros(n), sys.minv_p))
    f = np.concatenate((np.zeros(n), -sys.minv_b * (beta * s)))

    def rhs(t, y):
        return A @ y + c * math.cos(t) + f

    def velocity(t, y):
        return float(sys.b @ y[n:])

    velocity.terminal = True
    velocity.direction = -s
    sol = solve_ivp(
        rhs, (tau0, tau1), np.concatenate((x, xd)), "RK45", events=velocity, rtol=rtol, atol=atol
    )
    if sol.status == -1:
        return None
    if sol.status == 1:
        t, y = sol.t_events[0][0], sol.y_events[0][0]
        return t, y[:n], y[n:], True, sol.nfev
    return sol.t[-1], sol.y[:n, -1], sol.y[n:, -1], False, sol.nfev


def _stick(sys, beta, tau0, tau1, d0, q, qd, rtol, atol):
    """Stay stuck at ``b . x = d0`` from ``tau0`` until ``|g| = beta`` or ``tau1``."""
    m = sys.m
    static = sys.ms_inv_kw * d0
    g_static = sys.g_kw * d0

    if m:
        A = np.zeros((2 * m, 2 * m))
        A[:m, m:] = np.eye(m)
        A[m:, :m] = -sys.ms_inv_kt
        A[m:, m:] = -sys.ms_inv_ct
        c = np.concatenate((np.zeros(m), sys.ms_inv_tp))
        f = np.concatenate((np.zeros(m), -static))

        def rhs(t, y):
            return A @ y + c * math.cos(t) + f

        def force(t, y):
            gx = float(sys.g_kt @ y[:m]) + float(sys.g_ct @ y[m:])
            return sys.g_p * math.cos(t) - gx - g_static

        y0 = np.concatenate((q, qd))
    else:  # SDOF: nothing moves; a dummy coordinate keeps the event machinery

        def rhs(t, y):
            return np.zeros(1)

        def force(t, y):
            return sys.g_p * math.cos(t) - g_static

        y0 = np.zeros(1)

    def upper(t, y):
        return force(t, y) - beta

    def lower(t, y):
        return force(t, y) + beta

    upper.terminal = lower.terminal = True
    upper.direction, lower.direction = 1, -1
    sol = solve_ivp(
        rhs,
        (tau0, tau1),
        y0,
        "RK45",
        events=(upper, lower),
        rtol=rtol,
        atol=atol,
        max_step=STICK_MAX_STEP,
    )
    if sol.status == -1:
        return None
    if sol.status == 1:
        k = 0 if sol.t_events[0].size else 1
        t, y = sol.t_events[k][0], sol.y_events[k][0]
        s = 1 if k == 0 else -1
    else:
        t, y, s = sol.t[-1], sol.y[:, -1], 0
    if m:
        x = sys.T @ y[:m] + d0 * sys.w
        xd = sys.T @ y[m:]
    else:
        x = d0 * sys.w
        xd = np.zeros(sys.n)
    return t, x, xd, s, sol.nfev


def paper_method(
    scene: Scene,
    r: float,
    beta: float,
    cycles: int = CYCLES,
    rtol: float = RTOL,
    atol: float = ATOL,
    max_transitions: int = MAX_TRANSITIONS,
) -> tuple[int, dict[str, object]]:
    """Regime of one point by the paper's method (Sect. 5): RK45 + events, from rest.

    Parameters
    ----------
    scene : Scene
    r, beta : float
        Frequency ratio (> 0) and friction ratio (>= 0).
    cycles : int
        Excitation cycles integrated (the paper: 100); the last one is classified.
    rtol, atol : float
        Tolerances of ``solve_ivp`` (the paper: 1e-12 and 1e-6).
    max_transitions : int
        Phase changes before giving up with ``EVENT_LIMIT`` (see :data:`MAX_TRANSITIONS`).

    Returns
    -------
    regime : int
        :data:`tasks.regimes.NO_MOTION`, ``STICK_SLIP`` or ``CONTINUOUS``, or
        ``NUMERICAL_FAILURE`` / ``EVENT_LIMIT`` if the integration failed.
    info : dict
        ``stick_time`` (stuck time in the last cycle), ``stops`` (stick phases
        starting in the last cycle), ``reversals`` (slip reversals in it),
        ``amplitude`` (half peak-to-peak of ``b . x`` in the last cycle),
        ``transitions`` (phase changes in the whole run), ``nfev``, ``wall``
        (seconds) and ``x_end``, ``xd_end`` (final state).
    """
    if not (r > 0.0 and math.isfinite(r)) or not (beta >= 0.0 and math.isfinite(beta)):
        raise ValueError(f"need r > 0 and beta >= 0 (finite), got r={r!r}, beta={beta!r}")
    if cycles < 1:
        raise ValueError(f"cycles: must be >= 1, got {cycles!r}")
    start = time.perf_counter()
    sys = _system(scene, r)
    n = sys.n
    tau_end = _TWO_PI * cycles
    tau_last = tau_end - _TWO_PI
    tau = 0.0
    x = np.zeros(n)
    xd = np.zeros(n)
    # at rest the contact velocity is zero: the stick test decides the first phase
    g = _contact_force(sys, tau, x, xd)
    mode = 0 if abs(g) <= beta else (1 if g > 0.0 else -1)
    nfev = transitions = stops = reversals = 0
    stick_time = 0.0
    extremes: list[float] = []  # b . x where b . x' = 0 in the last cycle (and its ends)
    status = 0
    while tau < tau_end:
        in_last = tau >= tau_last
        stop_at = tau_end if in_last else tau_last
        if in_last:
            extremes.append(float(sys.b @ x))
        if mode == 0:
            d0 = float(sys.b @ x)
            q = sys.proj @ (x - d0 * sys.w)  # exact: x - d0 w is in the range of T
            out = _stick(sys, beta, tau, stop_at, d0, q, sys.proj @ xd, rtol, atol)
            if out is None:
                status = regimes.NUMERICAL_FAILURE
                break
            t1, x, xd, s, nf = out
            if in_last:
                stick_time += t1 - tau
            mode = s
        else:
            out = _slide(sys, beta, mode, tau, stop_at, x, xd, rtol, atol)
            if out is None:
                status = regimes.NUMERICAL_FAILURE
                break
            t1, x, xd, hit, nf = out
            if hit:
                g = _contact_force(sys, t1, x, xd)
                if abs(g) <= beta:
                    mode = 0
                    stops += in_last and t1 < tau_end
                else:
                    mode = 1 if g > 0.0 else -1
                    reversals += in_last and t1 < tau_end
        nfev += nf
        transitions += t1 < stop_at
        tau = t1
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(xd))):
            status = regimes.NUMERICAL_FAILURE
            break
        if transitions > max_transitions:
            status = regimes.EVENT_LIMIT
            break
    extremes.append(float(sys.b @ x))
    if status:
        regime = status
    elif stick_time >= _TWO_PI * (1.0 - 1e-12):
        regime = regimes.NO_MOTION
    elif stick_time > 0.0:
        regime = regimes.STICK_SLIP
    else:
        regime = regimes.CONTINUOUS
    info = {
        "stick_time": stick_time,
        "stops": int(stops),
        "reversals": int(reversals),
        "amplitude": 0.5 * (max(extremes) - min(extremes)),
        "transitions": int(transitions),
        "nfev": int(nfev),
        "wall": time.perf_counter() - start,
        "x_end": x,
        "xd_end": xd,
    }
    return int(regime), info


def classify_paper_method(
    scene: Scene,
    r: float | np.ndarray,
    beta: float | np.ndarray,
    **kwargs: object,
) -> ClassifyResult:
    """:func:`paper_method` at every (r, beta) (broadcast), as a :class:`ClassifyResult`.

    ``converged`` is False and ``period`` 0 everywhere (the method has no
    steady-state test); ``cycles`` is the number integrated; ``initial_condition``
    is ``rest``; ``stops_per_cycle``, ``stick_fraction`` and ``slip_amplitude``
    describe the last cycle; the design quantities are NaN. ``kwargs`` go to
    :func:`paper_method`.
    """
    r_arr, beta_arr = np.broadcast_arrays(
        np.asarray(r, dtype=np.float64), np.asarray(beta, dtype=np.float64)
    )
    res = ClassifyResult.empty(r_arr.shape, scene.dof)
    res.initial_condition[...] = regimes.IC_REST
    for name in DESIGN_FIELDS:
        getattr(res, name)[...] = np.nan  # not measured by the paper's method
    for idx in np.ndindex(r_arr.shape):
        code, info = paper_method(scene, float(r_arr[idx]), float(beta_arr[idx]), **kwargs)
        res.regime[idx] = code
        res.cycles[idx] = kwargs.get("cycles", CYCLES)
        res.stops_per_cycle[idx] = info["stops"]
        res.slip_amplitude[idx] = info["amplitude"]
        res.stick_fraction[idx] = min(1.0, info["stick_time"] / _TWO_PI)
    return res
