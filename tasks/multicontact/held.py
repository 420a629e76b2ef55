"""The held forced response of a point with several contacts, and its margins
(docs/contacts.md 4): the start held, and the bound above which every start
reaches no motion."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.kernel.damping import particular
from tasks.multicontact import viscous
from tasks.multicontact.layout import (
    CX_ACTIVE,
    CX_B,
    CX_BETAS,
    CX_COMPLIANCE,
    CX_H,
    CX_HP,
    CX_K,
    CX_LOAD_COS,
    CX_OMEGA,
    CX_P,
    CX_SIZE,
    CX_X,
)

#: Relative margin above which every start reaches no motion (docs/contacts.md 4).
HELD_MARGIN_RTOL = 1e-9


@njit(cache=True)
def held_response(ctx, stuck):
    """The forced response of the structure with the contacts ``stuck`` held at zero
    relative displacement, at tau = 0 (``x_h(tau) = x_h(0) cos tau``; damped:
    ``x_c cos tau + x_s sin tau``, returned as ``(x_c, x_s)`` = ``(x, x')`` at tau = 0,
    Eq. 4.2 of docs/structures.md). Returns ``(X, exists)``: it does not exist at a
    resonance of a loaded undamped mode."""
    n = ctx[CX_P].shape[0]
    m = ctx[CX_SIZE][stuck]
    Xs = ctx[CX_X][stuck]
    k = ctx[CX_B].shape[1]
    D = ctx[CX_COMPLIANCE]
    damped = D.shape[0] > k
    out = np.zeros(2 * n)
    if damped and viscous.is_general(D, n, k, stuck):  # damped pairs
        return out, viscous.general_held(ctx, stuck, out)
    for a in range(m):
        load = ctx[CX_LOAD_COS][stuck, a]
        if load == 0.0:
            continue
        om2 = ctx[CX_OMEGA][stuck, a] ** 2
        den = om2 - 1.0
        sigma = viscous.sigma(D, n, k, stuck, a) if damped else 0.0
        if sigma == 0.0 and abs(den) < 1e-9 * max(om2, 1.0):
            return out, False
        if damped:
            P, Q = particular(math.sqrt(om2), sigma, load)
            for i in range(n):
                out[i] += Xs[i, a] * P
                out[n + i] += Xs[i, a] * Q
        else:
            for i in range(n):
                out[i] += Xs[i, a] * load / den
    return out, True


@njit(cache=True)
def held_margins(ctx, margins):
    """``beta_c - max |g_c|`` of the held steady state (every active contact held);
    all ``-inf`` where it does not exist. Returns whether every margin exceeds
    ``HELD_MARGIN_RTOL beta_c`` (then every start reaches no motion: the
    energy argument of docs/theory.md 3 with the sum over contacts)."""
    active = ctx[CX_ACTIVE]
    X, exists = held_response(ctx, active)
    n = X.shape[0] // 2
    k = margins.shape[0]
    K = ctx[CX_K]
    H = ctx[CX_H][active]
    ok = exists and active != 0
    for c in range(k):
        if not exists:
            margins[c] = -np.inf
            continue
        g = ctx[CX_HP][active, c]
        for i in range(n):
            kx = 0.0
            for j in range(n):
                kx += K[i, j] * X[j]
            g -= H[c, i] * kx
        amp = abs(g)
        if ctx[CX_COMPLIANCE].shape[0] > k:  # damped: g = gc cos tau + gs sin tau
            gs = 0.0
            cx_s = np.empty(n)
            cx_c = np.empty(n)
            viscous.force(ctx[CX_COMPLIANCE], k, X[n:], cx_s)  # gc -= H r C x_s
            viscous.force(ctx[CX_COMPLIANCE], k, X[:n], cx_c)  # gs = H (r C x_c - K x_s)
            for i in range(n):
                kxs = 0.0
                for j in range(n):
                    kxs += K[i, j] * X[n + j]
                g -= H[c, i] * cx_s[i]
                gs += H[c, i] * (cx_c[i] - kxs)
            amp = math.hypot(g, gs)
        margins[c] = ctx[CX_BETAS][c] - amp
        if (active >> c) & 1 and margins[c] <= HELD_MARGIN_RTOL * ctx[CX_BETAS][c]:
            ok = False
    return ok
