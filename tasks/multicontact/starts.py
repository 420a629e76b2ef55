"""The start of a point with several contacts: held, rest, or a seeded random start
(docs/contacts.md 3, 4)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.multicontact import viscous
from tasks.multicontact.decide import decide
from tasks.multicontact.held import held_response
from tasks.multicontact.layout import (
    CX_ACTIVE,
    CX_B,
    CX_BETAS,
    CX_COMPLIANCE,
    CX_G,
    CX_K,
    CX_P,
    CX_R2,
)
from tasks.regimes import IC_HELD, IC_RANDOM, IC_REST


@njit(cache=True)
def random_start(ctx, X_held, r, beta, k_start, seed):
    """Seeded random start number ``k_start`` on the energy scale of the forced
    response, as one contact's (:func:`tasks.kernel.starts._random_start`): a random
    direction of ``(x, x')`` scaled to an energy ``1/2 x^T K x + 1/2 r^2 x'^T G x'``
    uniform in ``(0, 2 E_ref]``, ``E_ref`` the larger of the held start's and the
    static response's. The stream depends only on ``(seed, k_start, r, beta)``."""
    K = ctx[CX_K]
    G = ctx[CX_G]
    p = ctx[CX_P]
    n = p.shape[0]
    h = (seed * 1000003 + k_start * 7919) & 0x7FFFFFFF
    h = (h * 31 + int(r * 1e9)) & 0x7FFFFFFF
    h = (h * 31 + int(beta * 1e9)) & 0x7FFFFFFF
    np.random.seed(h)  # noqa: NPY002 (numba: the legacy API only)
    x_stat = np.linalg.solve(K, p)
    e_static = 0.0
    for i in range(n):
        e_static += 0.5 * x_stat[i] * p[i]
    e_ref = max(_energy(X_held, K, G, ctx[CX_R2]), e_static, 1e-300)
    X = np.empty(2 * n)
    for i in range(2 * n):
        X[i] = np.random.standard_normal()  # noqa: NPY002
    u = 1.0 - np.random.random()  # noqa: NPY002
    scale = math.sqrt(2.0 * e_ref * u / max(_energy(X, K, G, ctx[CX_R2]), 1e-300))
    for i in range(2 * n):
        X[i] *= scale
    return X


@njit(cache=True)
def _energy(X, K, G, r2):
    """``1/2 x^T K x + 1/2 r^2 x'^T G x'``."""
    n = K.shape[0]
    e = 0.0
    for i in range(n):
        for j in range(n):
            e += 0.5 * (X[i] * K[i, j] * X[j] + r2 * X[n + i] * G[i, j] * X[n + j])
    return e


@njit(cache=True)
def start_state(ctx, ic, r, beta, seed):
    """``(X, stuck, signs, ic_used)`` of the start: held (every active contact held,
    the rest on the held forced response; rest where that is resonant), rest, or
    the seeded random start ``ic - IC_RANDOM`` (every contact slides with the
    sign of its velocity; one at rest relative to its contact is decided by
    docs/contacts.md 3)."""
    B = ctx[CX_B]
    k = ctx[CX_BETAS].shape[0]
    n = ctx[CX_P].shape[0]
    X = np.zeros(2 * n)
    used = ic
    Xh, exists = held_response(ctx, ctx[CX_ACTIVE])
    if ic == IC_HELD:
        if exists:
            X = Xh
        else:
            used = IC_REST
    signs = np.zeros(k)
    new_signs = np.zeros(k)
    candidates = ctx[CX_ACTIVE]
    if ic >= IC_RANDOM:
        X = random_start(ctx, Xh if exists else np.zeros(2 * n), r, beta, ic - IC_RANDOM, seed)
        for c in range(k):
            v = 0.0
            for i in range(n):
                v += B[i, c] * X[n + i]
            if (candidates >> c) & 1 and v != 0.0:
                signs[c] = 1.0 if v > 0.0 else -1.0
                candidates &= ~(1 << c)
    x = X[:n]
    if ctx[CX_COMPLIANCE].shape[0] > k:  # damped: the viscous force in the decision
        x = viscous.effective(ctx[CX_COMPLIANCE], k, X[:n], X[n:])
    stuck, _ = decide(x, 0.0, candidates, signs, ctx, new_signs)
    return X, stuck, new_signs, used
