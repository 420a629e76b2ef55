"""Viscous damping of a scene with several contacts (docs/contacts.md 7), compiled.

The per-point damping data travel after the k compliances in the context's
``ctx[CX_COMPLIANCE]`` (:mod:`tasks.multicontact.layout`), so that an undamped
scene's context is unchanged; they are read only on the damped code path. The
array ``D`` (``n`` DOFs, ``k`` contacts, ``2^k`` sets):

* ``D[:k]`` the compliances ``b_c^T K^-1 b_c``; ``D[k] = r``;
* ``r C`` (n x n);
* ``sigma[S, a] = cdiag[S, a] / (2 r)``, the modal decay rates (2^k x n);
* ``r (H_S C X_S)[c, a]``, the viscous part of the stuck forces (2^k x k x n);
* ``cdiag[S, a]``, the diagonal of ``X_S^T C X_S`` (2^k x n);
* ``K^-1 r C`` (n x n), for :func:`effective`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.kernel.design import _GL_NODES, _GL_WEIGHTS
from tasks.kernel.layout import DAMP, DAMPED, DELTA, OBS0, OMEGA
from tasks.kernel.propagation import evaluate

#: The most Gauss-Legendre sub-intervals per phase of :func:`viscous_work` (the nodes
#: and weights are the design pass's, :mod:`tasks.kernel.design`).
VISCOUS_MAX_INTERVALS = 100000


@njit(cache=True)
def pack(compliance, r, C, cdiag, HCX, KinvC):
    """``D`` of one point (see the module notes)."""
    n = C.shape[0]
    n_sets, k = HCX.shape[0], HCX.shape[1]
    out = np.empty(k + 1 + 2 * n * n + 2 * n_sets * n + n_sets * k * n)
    for c in range(k):
        out[c] = compliance[c]
    out[k] = r
    i = k + 1
    for a in range(n):
        for b in range(n):
            out[i] = r * C[a, b]
            i += 1
    for S in range(n_sets):
        for a in range(n):
            out[i] = cdiag[S, a] / (2.0 * r)
            i += 1
    for S in range(n_sets):
        for c in range(k):
            for a in range(n):
                out[i] = r * HCX[S, c, a]
                i += 1
    for S in range(n_sets):
        for a in range(n):
            out[i] = cdiag[S, a]
            i += 1
    for a in range(n):
        for b in range(n):
            out[i] = r * KinvC[a, b]
            i += 1
    return out


@njit(cache=True)
def effective(D, k, x, xd):
    """``x + K^-1 r C x'``: the displacement whose elastic force ``K x_e`` is the elastic
    plus the viscous force, ``K x + r C x'``. The event decision
    (:func:`tasks.multicontact.decide.decide`) of a damped scene takes it for ``x``."""
    n = x.shape[0]
    start = k + 1 + n * n + (1 << k) * n * (2 + k)
    out = x.copy()
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += D[start + i * n + j] * xd[j]
        out[i] += acc
    return out


@njit(cache=True)
def force(D, k, xd, out):
    """``out = r C x'`` (n = ``xd.shape[0]``)."""
    n = xd.shape[0]
    base = k + 1
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += D[base + i * n + j] * xd[j]
        out[i] = acc


@njit(cache=True)
def sigma(D, n, k, S, a):
    """The decay rate of mode a of stuck set S."""
    return D[k + 1 + n * n + S * n + a]


@njit(cache=True)
def cdiag_row(D, n, k, S):
    """``diag(X_S^T C X_S)`` of stuck set S (length n; its first ``m`` entries count)."""
    start = k + 1 + n * n + (1 << k) * n * (1 + k) + S * n
    return D[start : start + n]


@njit(cache=True)
def damp_phase(D, n, k, stuck, active, m, etad0, segs, scs):
    """Make the phase just filled by :func:`tasks.multicontact.cycle.start_phase` damped:
    the modal decay rates (row DAMP, docs/structures.md 4.1) of every active contact's
    segment, and the viscous part ``-r (H_S C X_S)_c eta'`` of each stuck contact's
    force (row DELTA, and its value at the start in OBS0)."""
    rates = k + 1 + n * n
    base = rates + (1 << k) * n
    for c in range(k):
        if not (active >> c) & 1:
            continue
        seg = segs[c]
        sc = scs[c]
        sc[DAMPED] = 1.0
        for a in range(m):
            seg[DAMP, a] = D[rates + stuck * n + a]
        if (stuck >> c) & 1:
            g = 0.0
            for a in range(m):
                seg[DELTA, a] = -D[base + (stuck * k + c) * n + a]
                g += seg[DELTA, a] * etad0[a]
            sc[OBS0] += g


@njit(cache=True)
def viscous_work(seg, sc, t, cdiag, r):
    """``int_0^t r x'^T C x' dtau = r sum_a cdiag_a int eta_a'^2`` over a damped phase of
    length ``t`` (``X_S^T C X_S`` diagonal, docs/contacts.md 7): 4-point Gauss-Legendre
    on sub-intervals short against the fastest rate of the phase (``Omega_a + 2 sigma_a``
    and the excitation), where the rule's error is below 1e-12 of the integral."""
    m = seg.shape[1]
    rate = 1.0
    for a in range(m):
        rate = max(rate, seg[OMEGA, a] + 2.0 * seg[DAMP, a])
    n_sub = min(max(1, int(math.ceil(2.0 * rate * t))), VISCOUS_MAX_INTERVALS)
    h = t / n_sub
    eta = np.empty(m)
    etad = np.empty(m)
    total = 0.0
    for j in range(n_sub):
        for q in range(4):
            evaluate(seg, sc, (j + _GL_NODES[q]) * h, eta, etad)
            acc = 0.0
            for a in range(m):
                acc += cdiag[a] * etad[a] * etad[a]
            total += _GL_WEIGHTS[q] * acc
    return r * h * total
