"""Per-point constants: both phases' modal data at (r, beta), and the initial state.

:func:`_context` turns a scene's modal data (:meth:`tasks.model.SceneModes.kernel_args`)
and the solver settings (:func:`tasks.classifier.settings_args`) into the
context tuple every cycle uses (entries ``CTX_*`` of :mod:`tasks.kernel.layout`)
and the start of the simulation (:mod:`tasks.kernel.starts`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.kernel.cycle import _max_abs
from tasks.kernel.events import DIP_STACK
from tasks.kernel.layout import (
    ALPHA,
    COMPLIANCE,
    CTX_K,
    CTX_P,
    CTX_PHI,
    CTX_SC,
    CTX_SEG_SLIP,
    DAMP,
    DAMPED,
    DELTA,
    FLOOR,
    LOAD_COS,
    N_ROWS,
    N_SCALARS,
    OMEGA,
    WORK_CAP,
)
from tasks.kernel.linsolve import _solve
from tasks.kernel.phases import _contact_force, _dot
from tasks.kernel.starts import _held_response, _random_start, start_phase
from tasks.regimes import IC_HELD, IC_RANDOM, IC_REST


@njit(cache=True)
def _event_cap(events):
    """The per-cycle event limit implied by the fastest mode, as an int (capped at 1e9)."""
    if not events < 1e9:
        return 1_000_000_000
    return int(events)


@njit(cache=True)
def _scaled_pairs_map(A, r):
    """The map of :mod:`tasks.damped_pairs` at ratio r. ``A`` acts on the scaled state
    ``(x, r x')`` -> ``(eta, r xi)`` or back; the result acts on ``(x, x')`` ->
    ``(eta, xi)`` or back (the same scaling both ways)."""
    h = A.shape[0] // 2
    out = A.copy()
    for i in range(2 * h):
        for j in range(2 * h):
            out[i, j] = A[i, j] * (r if j >= h else 1.0) / (r if i >= h else 1.0)
    return out


@njit(cache=True)
def _undamped_scales(K, b, p, lam, phi, r):
    """The contact's compliance at the excitation frequency and the largest entry of
    the motion floor's response, from the undamped modes ``(lam, phi)`` of ``(K, Gamma)``
    (``phi^T Gamma phi = I``), for a scene whose damping is not proportional (its
    phases run on damped pairs, which have no real modes: docs/structures.md 4.5).

    The same formulas, in the same arithmetic, as :func:`tasks.kernel.creep.creep_threshold`
    and :func:`motion_floor` take from the real modes of an undamped or proportionally
    damped scene: ``c = min(sum_k (b . phi_k)^2 / max(lambda_k, r^2), b^T K^-1 b)``, and
    ``sum_k phi_k a_k / max(Omega_k^2, 1)`` (``a_k = phi_k . p / r^2``, ``Omega_k^2 =
    lambda_k / r^2``), the static response ``K^-1 p`` where no mode lies below the
    excitation. Both are scales of the structure at the excitation frequency, not of its
    damping. Returns ``(c, floor)``.
    """
    n = b.shape[0]
    r2 = r * r
    c = 0.0
    soft = False
    resp = np.zeros(n)
    for k in range(n):
        om = math.sqrt(lam[k]) / r
        bk = 0.0
        pk = 0.0
        for i in range(n):
            bk += b[i] * phi[i, k]
            pk += phi[i, k] * p[i]
        c += bk * bk / max(om * om * r2, r2)
        soft = soft or om < 1.0
        a = pk / r2 / max(om**2, 1.0)
        for i in range(n):
            resp[i] += phi[i, k] * a
    static = abs(_dot(b, _solve(K, b)))
    if not soft:
        resp = _solve(K, p)
    return min(c, static), _max_abs(resp)


#: A held mode is resonant (its frequency the excitation's) to this relative
#: tolerance of ``Omega^2 - 1``: the rounding of the held system's eigenvalues and of
#: a grid's r (a grid through r = 1 exactly computes 1 - 2e-16).
RESONANT_RTOL = 1e-12
#: ... and unloaded when its modal load is below this fraction of ``|phi_k| |p|``
#: (the bound of the modal load): the rounding of the eigenvectors (a mode of a held
#: subsystem that the load does not reach carries about 1e-17 of it); the closed
#: forms' exact zeros use the same fraction (analysis.modal.NOISE).
UNLOADED_RTOL = 1e-13


@njit(cache=True)
def _lock_unloaded_resonances(seg_stick, load_reach):
    """Set every undamped held mode that is resonant (:data:`RESONANT_RTOL`) and
    unloaded (:data:`UNLOADED_RTOL` of ``load_reach``, its modal load's bound) to
    ``Omega = 1``, load 0 exactly: a free vibration of the held system at the
    excitation's frequency, which :func:`tasks.kernel.starts._held_response` uses to
    cancel the held contact force (the absorber's held state, docs/theory.md 3) and
    :func:`tasks.kernel.events.stick_force_bound` adds to the harmonic of ``g``.
    Elsewhere nothing changes (a loaded resonance stays resonant)."""
    for k in range(seg_stick.shape[1]):
        w = seg_stick[OMEGA, k]
        if seg_stick[DAMP, k] != 0.0 or abs(w * w - 1.0) > RESONANT_RTOL * max(w * w, 1.0):
            continue
        if abs(seg_stick[LOAD_COS, k]) <= UNLOADED_RTOL * load_reach[k]:
            seg_stick[OMEGA, k] = 1.0
            seg_stick[LOAD_COS, k] = 0.0


@njit(cache=True)
def _context(r, beta, scene, settings):
    """Per-point constants of both phases, the held initial condition and its phase.

    ``scene`` is :meth:`tasks.model.SceneModes.kernel_args`, ``settings`` is
    :func:`tasks.classifier.settings_args`. Returns ``(ctx, work, X0, mode0,
    ic_used)``: ``ctx`` is the tuple :func:`run_cycle` takes, ``X0 = (x, x')``
    the initial section state.
    """
    (
        gamma,
        K,
        b,
        p0,
        load_scales_r2,
        lam,
        phi,
        phi_t_gamma,
        w_slip,
        f_slip,
        T,
        w,
        lam_s,
        phi_s,
        phi_s_t_gamma_s,
        load_s,
        d_static,
        proj,
        g_load,
        g_modes_s,
        g_d0,
        damp_slip,
        damp_stick,
        g_c,
        g_c_s,
        _,
        load_slip,
        lam_u,
        phi_u,
    ) = scene
    event_tol = settings[0]
    step_fraction = settings[1]
    max_events = settings[7]
    initial_condition = settings[9]
    max_work = settings[10]
    n = gamma.shape[0]
    m = lam_s.shape[0]
    r2 = r * r
    p = p0 * r2 if load_scales_r2 else p0.copy()
    general = phi.shape[0] != n  # non-proportional damping: pairs (docs/structures.md 4.5)
    if general:
        phi = _scaled_pairs_map(phi, r)
        phi_t_gamma = _scaled_pairs_map(phi_t_gamma, r)
        phi_s = _scaled_pairs_map(phi_s, r)
        phi_s_t_gamma_s = _scaled_pairs_map(phi_s_t_gamma_s, r)
    seg_slip = np.zeros((N_ROWS, n))
    om_max = 1.0
    for k in range(n):
        om = math.sqrt(lam[k]) / r
        seg_slip[OMEGA, k] = om
        acc = 0.0
        for i in range(n):
            acc += (load_slip[k, i] if general else phi[i, k]) * p[i]
        seg_slip[LOAD_COS, k] = acc / r2
        seg_slip[DELTA, k] = w_slip[k]
        if general:  # contact velocity: alpha = b . V_v,eta / r
            seg_slip[ALPHA, k] = f_slip[2 * n + k] / r
        seg_slip[DAMP, k] = 0.5 * damp_slip[k] / r  # sigma = c_k / (2 r), Eq. 4.1
        om_max = max(om_max, om)
    h_slip = step_fraction * math.pi / om_max
    om_slip = om_max
    seg_stick = np.zeros((N_ROWS, m))
    load_reach = np.zeros(m)
    p_norm2 = 0.0
    for i in range(n):
        p_norm2 += p[i] * p[i]
    om_max = 1.0
    for k in range(m):
        om = math.sqrt(lam_s[k]) / r
        seg_stick[OMEGA, k] = om
        acc = 0.0
        reach = 0.0  # |load_s[k]| |p|: the bound of |acc| (Cauchy-Schwarz)
        for i in range(n):
            acc += load_s[k, i] * p[i]
            reach += load_s[k, i] * load_s[k, i]
        seg_stick[LOAD_COS, k] = acc / r2
        load_reach[k] = math.sqrt(reach * p_norm2) / r2
        seg_stick[ALPHA, k] = -g_modes_s[k]
        # viscous part of g while stuck: -r g_load^T C T phi_s eta' (docs/structures.md 4)
        if g_c_s[k] != 0.0:  # (undamped: row DELTA stays exactly 0)
            seg_stick[DELTA, k] = -r * g_c_s[k]
        seg_stick[DAMP, k] = 0.5 * damp_stick[k] / r
        om_max = max(om_max, om)
    if not general:
        _lock_unloaded_resonances(seg_stick, load_reach)
    h_stick = step_fraction * math.pi / om_max
    sc = np.zeros(N_SCALARS)
    sc[WORK_CAP] = max_work
    damped = False
    for k in range(n):
        damped = damped or damp_slip[k] != 0.0
    sc[DAMPED] = 1.0 if damped else 0.0
    if general:  # the pairs have no real modes: the undamped ones give both scales
        sc[COMPLIANCE], sc[FLOOR] = _undamped_scales(K, b, p, lam_u, phi_u, r)
    if general:  # (constant load / r^2, offset of eta' / r) per unit force or d0
        f_r2 = np.concatenate((f_slip[:n] / r2, f_slip[n : 2 * n] / r))
        dstat_r2 = np.concatenate((d_static[:m] / r2, d_static[m:] / r))
    else:
        f_r2 = f_slip / r2
        dstat_r2 = d_static / r2
    ctx = (
        seg_slip,
        seg_stick,
        sc,
        beta,
        p,
        K,
        b,
        w,
        T,
        phi,
        phi_t_gamma,
        phi_s,
        phi_s_t_gamma_s,
        proj,
        f_r2,
        dstat_r2,
        g_load,
        _dot(g_load, p),
        g_d0,
        h_slip,
        h_stick,
        event_tol,
        1e3 * event_tol,
        max(max_events, _event_cap(8.0 * max(om_slip, om_max))),
        max_work,
        g_c * r,
    )
    work = (
        np.zeros(n),
        np.zeros(n),
        np.zeros(m),
        np.zeros(m),
        np.zeros(2 * m),
        np.empty((DIP_STACK, 6)),
    )
    # Held start: contact at d0 = 0, the rest on the forced response of the
    # held system at tau = 0 (from rest if the held system is resonant).
    X_held, held_exists = _held_response(seg_stick, phi_s, T, n, p, K, g_load)
    ic_used = initial_condition
    X = np.zeros(2 * n)
    if initial_condition == IC_HELD or initial_condition >= IC_RANDOM:
        if held_exists:
            X = X_held
        else:
            ic_used = IC_REST
    if initial_condition >= IC_RANDOM:
        X = _random_start(X, gamma, K, p, r, beta, initial_condition - IC_RANDOM, settings[11])
        ic_used = initial_condition
        return ctx, work, X, start_phase(X, beta, ctx, 0.0), ic_used
    g0 = _contact_force(p, 1.0, K, X[:n], g_load)
    if damped:
        g0 -= r * _dot(g_c, X[n:])
    mode = 0 if abs(g0) <= beta else (1 if g0 > 0.0 else -1)
    return ctx, work, X, mode, ic_used


@njit(cache=True)
def motion_floor(ctx, X_held):
    """Scale a section residual is measured against when the motion itself is small.

    The larger of the held start ``X_held`` and the response of the sliding
    system's modes to the load amplitude with each mode's stiffness at least
    the excitation's inertia: ``sum_k phi_k a_k / max(Omega_k^2, 1)`` (modal
    equation ``eta_k'' + Omega_k^2 eta_k = a_k cos tau``, docs/simulator.md 2).
    Where every mode lies at or above the excitation (``Omega_k >= 1``) this is
    the static response ``K^-1 p``, solved directly. A mode far below the
    excitation (a soft spring under a heavy mass) moves about ``a_k`` at the
    excitation frequency, not its static ``a_k / Omega_k^2``: the static
    response would be a scale many orders of magnitude above the motion, and a
    tolerance relative to it would accept a transient of that mode still
    creeping as a steady state (docs/simulator.md 5). A scene whose damping is not
    proportional (damped pairs, docs/structures.md 4.5, no real modes) takes the same
    response in the undamped modes of ``(K, Gamma)``, computed once per point
    (:func:`_undamped_scales`, entry ``FLOOR`` of the context's scalars): it kept the
    static response, and every preset accepted such a transient of a chain with a
    dashpot (its period still moving by 0.43 / 0.11 / 8.8e-3 of the motion at
    ``fast`` / ``balanced`` / ``exact``).

    Parameters
    ----------
    ctx : tuple
        The point's context (:func:`_context`).
    X_held : ndarray
        The held start ``(x, x')`` (:func:`tasks.kernel.starts._held_response`).

    Returns
    -------
    float
        The floor, positive.
    """
    seg = ctx[CTX_SEG_SLIP]
    phi = ctx[CTX_PHI]
    n = seg.shape[1]
    if phi.shape[0] != n:  # damped pairs: from the undamped modes (_undamped_scales)
        return max(_max_abs(X_held), ctx[CTX_SC][FLOOR], 1e-300)
    soft = False
    for k in range(n):  # real modes (undamped or proportionally damped)
        soft = soft or seg[OMEGA, k] < 1.0
    if soft:
        resp = np.zeros(n)
        for k in range(n):
            c = seg[LOAD_COS, k] / max(seg[OMEGA, k] ** 2, 1.0)
            for i in range(n):
                resp[i] += phi[i, k] * c
    else:
        resp = _solve(ctx[CTX_K], ctx[CTX_P])
    return max(_max_abs(X_held), _max_abs(resp), 1e-300)
