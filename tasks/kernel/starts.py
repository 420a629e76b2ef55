"""Initial conditions: the held start, seeded random starts, and the held margin.

The held start (the reference of ``initial_condition``) holds the contact at
zero relative displacement and puts the other coordinates on the forced
response of the held system. :func:`held_margin` says how far inside the
friction limit that held steady state stays: when positive, every start
reaches no motion (docs/theory.md 3).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.kernel.damping import held_force_amplitude, held_modal_state, is_damped
from tasks.kernel.layout import (
    ALPHA,
    CTX_B,
    CTX_BETA,
    CTX_G_C,
    CTX_G_COS,
    CTX_G_LOAD,
    CTX_K,
    CTX_P,
    CTX_PHI_S,
    CTX_SC,
    CTX_SEG_STICK,
    CTX_T,
    DAMPED,
    LOAD_COS,
    OMEGA,
)
from tasks.kernel.linsolve import _solve
from tasks.kernel.phases import _contact_force, _dot, _stick_state


@njit(cache=True)
def _held_response(seg_stick, phi_s, T, n, p, K, g_load):
    """The held steady state at ``tau = 0``: contact held at zero relative
    displacement, the other coordinates on the forced response of the held
    system (``x_h(tau) = x_h(0) cos tau``). Returns ``(X, exists)``; it does not
    exist when a loaded mode of the held system is resonant.

    Where an unloaded undamped held mode is resonant (``Omega = 1``, load 0, set by
    :func:`tasks.kernel.context._lock_unloaded_resonances`) the held steady states
    are a family: the forced response plus any free vibration ``A cos tau`` of that
    mode. The one returned is the absorber's: ``A`` cancels the contact force
    ``g_h`` (the mode of those that feel the contact most), so the contact needs no
    friction at all and every start reaches it (docs/theory.md 3)."""
    m = seg_stick.shape[1]
    X = np.zeros(2 * n)
    if is_damped(seg_stick):  # damped: cos and sin parts (tasks.kernel.damping)
        eta, etad = held_modal_state(seg_stick)
        x = np.zeros(n)
        xd = np.zeros(n)
        _stick_state(phi_s, T, np.zeros(n), 0.0, eta, etad, np.zeros(2 * m), x, xd, np.zeros(m))
        X[:n] = x
        X[n:] = xd
        return X, True
    zeta = np.zeros(m)
    for k in range(m):
        den = seg_stick[OMEGA, k] ** 2 - 1.0
        if seg_stick[LOAD_COS, k] == 0.0:
            continue  # mode not loaded: no forced response
        if abs(den) < 1e-9 * max(seg_stick[OMEGA, k] ** 2, 1.0):
            return X, False
        zeta[k] = seg_stick[LOAD_COS, k] / den
    # (pairs of a general C with an undamped held system: eta' = xi = 0 at tau = 0
    # and d0 = 0, so the block phi_s[:m, :m] of V maps eta to q, docs/structures.md 4.5)
    for i in range(m):
        qi = 0.0
        for k in range(m):
            qi += phi_s[i, k] * zeta[k]
        for j in range(n):
            X[j] += T[j, i] * qi
    _absorb_contact_force(X, seg_stick, phi_s, T, n, p, K, g_load)
    return X, True


@njit(cache=True)
def _absorb_contact_force(X, seg_stick, phi_s, T, n, p, K, g_load):
    """Add to the held steady state ``X`` the free vibration of a resonant unloaded
    held mode (``Omega = 1``, load 0) that cancels its contact force (the absorber's
    held state, :func:`_held_response`): of such modes the one with the largest
    coupling ``alpha_k`` to ``g`` (row ALPHA); nothing where there is none, or it
    does not reach the contact (``alpha_k`` below 1e-12 of the largest)."""
    m = seg_stick.shape[1]
    biggest = 0.0
    for k in range(m):
        biggest = max(biggest, abs(seg_stick[ALPHA, k]))
    best = -1
    coupling = 1e-12 * biggest
    for k in range(m):
        if seg_stick[OMEGA, k] != 1.0 or seg_stick[LOAD_COS, k] != 0.0:
            continue
        if abs(seg_stick[ALPHA, k]) > abs(coupling):
            best = k
            coupling = seg_stick[ALPHA, k]
    if best < 0:
        return
    amplitude = -_contact_force(p, 1.0, K, X[:n], g_load) / coupling
    for i in range(m):
        for j in range(n):
            X[j] += T[j, i] * phi_s[i, best] * amplitude


@njit(cache=True)
def held_margin(ctx):
    """``beta - max_tau |g_h|``: how far inside the friction limit the held steady
    state stays, or ``-inf`` where the held system is resonant.

    The held steady state (:func:`_held_response`) needs the contact force
    ``g_h(tau) = g_h(0) cos tau``. When the margin ``delta`` is positive, every
    start reaches no motion (docs/theory.md 3, "every start reaches no motion
    above the motion bound"): Coulomb friction is monotone, so the energy of the
    difference between any motion and the held one decreases by at least
    ``delta |v|`` per unit time while the contact slides, and the total future
    sliding is at most that energy over ``delta``.
    """
    seg_stick = ctx[CTX_SEG_STICK]
    if ctx[CTX_SC][DAMPED] != 0.0:  # g_h = Hc cos tau + Hs sin tau (docs/structures.md 3.1)
        return ctx[CTX_BETA] - held_force_amplitude(seg_stick, ctx[CTX_G_COS])
    n = ctx[CTX_P].shape[0]
    X, exists = _held_response(
        seg_stick, ctx[CTX_PHI_S], ctx[CTX_T], n, ctx[CTX_P], ctx[CTX_K], ctx[CTX_G_LOAD]
    )
    if not exists:
        return -np.inf
    g0 = _contact_force(ctx[CTX_P], 1.0, ctx[CTX_K], X[:n], ctx[CTX_G_LOAD])
    return ctx[CTX_BETA] - abs(g0)


@njit(cache=True)
def _energy(X, gamma, K, r):
    """``1/2 x^T K x + 1/2 x'^T M x'`` with ``M = r^2 diag(gamma)`` (Eq. 68)."""
    n = K.shape[0]
    e = 0.0
    for i in range(n):
        e += 0.5 * r * r * gamma[i] * X[n + i] * X[n + i]
        for j in range(n):
            e += 0.5 * X[i] * K[i, j] * X[j]
    return e


@njit(cache=True)
def _random_start(X_held, gamma, K, p, r, beta, k, seed):
    """Seeded random start number ``k`` on the energy scale of the forced response.

    A random direction in the state space ``(x, x')`` scaled to an energy
    ``E = 1/2 x^T K x + 1/2 x'^T M x'`` drawn uniformly in ``(0, 2 E_ref]``,
    ``E_ref`` the larger of the energies of the held start (the forced response
    of the held system) and of the static response ``K^-1 p``. The stream
    depends only on ``(seed, k, r, beta)``: the same point gets the same starts
    in any chunk and on any worker.
    """
    n = K.shape[0]
    h = (seed * 1000003 + k * 7919) & 0x7FFFFFFF
    h = (h * 31 + int(r * 1e9)) & 0x7FFFFFFF
    h = (h * 31 + int(beta * 1e9)) & 0x7FFFFFFF
    np.random.seed(h)  # noqa: NPY002 (numba: the legacy API only)
    x_stat = _solve(K, p)
    e_ref = max(_energy(X_held, gamma, K, r), 0.5 * _dot(x_stat, p), 1e-300)
    X = np.empty(2 * n)
    for i in range(2 * n):
        X[i] = np.random.standard_normal()  # noqa: NPY002
    e = _energy(X, gamma, K, r)
    u = 1.0 - np.random.random()  # noqa: NPY002
    scale = math.sqrt(2.0 * e_ref * u / max(e, 1e-300))
    for i in range(2 * n):
        X[i] *= scale
    return X


@njit(cache=True)
def start_phase(X, beta, ctx, theta):
    """Phase a section state starts in: sliding with the sign of ``b . x'``, or
    (at rest relative to the contact) stuck if ``|g| <= beta``."""
    p = ctx[CTX_P]
    K = ctx[CTX_K]
    b = ctx[CTX_B]
    g_load = ctx[CTX_G_LOAD]
    n = X.shape[0] // 2
    v = _dot(b, X[n:])
    if v > 0.0:
        return 1
    if v < 0.0:
        return -1
    g0 = _contact_force(p, math.cos(theta), K, X[:n], g_load)
    if ctx[CTX_SC][DAMPED] != 0.0:
        g0 -= _dot(ctx[CTX_G_C], X[n:])
    return 0 if abs(g0) <= beta else (1 if g0 > 0.0 else -1)
