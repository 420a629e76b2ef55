"""Viscous damping of a scene with several contacts (docs/contacts.md 7), compiled.

The per-point damping data travel after the k compliances in the context's
``ctx[CX_COMPLIANCE]`` (:mod:`tasks.multicontact.layout`), so that an undamped
scene's context is unchanged; they are read only on the damped code path. The
array ``D`` (``n`` DOFs, ``k`` contacts, ``2^k`` sets; blocks at :func:`offsets`):

* ``D[:k]`` the compliances ``b_c^T K^-1 b_c``; ``D[k] = r``;
* ``r C`` (n x n);
* ``sigma[S, a]``, the decay rates of the modes (or pairs) of set S (2^k x n);
* ``r (H_S C X_S)[c, a]``, the viscous part of the stuck forces (2^k x k x n);
* ``cdiag[S, a]``, the diagonal of ``X_S^T C X_S`` (2^k x n);
* ``K^-1 r C`` (n x n), for :func:`effective`;
* per set, 1 where C couples its modes: the set then runs on the damped pairs of
  docs/structures.md 4.5 (:func:`general_phase`), with its basis ``T_S`` (n x n),
  the pairs' maps ``L_S``, ``V_S`` (2n x 2n) and ``Wo_S = T_S load_w^T`` (n x n,
  the offsets ``o = Wo^T f / r`` of Eq. 4.10).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.kernel.damping import particular
from tasks.kernel.design import _GL_NODES, _GL_WEIGHTS
from tasks.kernel.layout import (
    ALPHA,
    COS_TAU0,
    DAMP,
    DAMPED,
    DELTA,
    ETA0,
    ETAD0,
    ETAD_OFF,
    OBS0,
    OMEGA,
)
from tasks.kernel.propagation import evaluate
from tasks.multicontact.layout import (
    CX_ACTIVE,
    CX_B,
    CX_COMPLIANCE,
    CX_H,
    CX_HP,
    CX_K,
    CX_LOAD_COS,
    CX_OMEGA,
    CX_SIZE,
    CX_W,
)

#: The most Gauss-Legendre sub-intervals per phase of :func:`viscous_work` (the nodes
#: and weights are the design pass's, :mod:`tasks.kernel.design`).
VISCOUS_MAX_INTERVALS = 100000


@njit(cache=True)
def offsets(n, k):
    """Starts of the blocks of ``D``: ``(rC, sigma, rHCX, cdiag, KinvRC, general, T, L,
    V, Wo, end)``."""
    ns = 1 << k
    rc = k + 1
    sig = rc + n * n
    rhcx = sig + ns * n
    cd = rhcx + ns * k * n
    kinv = cd + ns * n
    gen = kinv + n * n
    tt = gen + ns
    ll = tt + ns * n * n
    vv = ll + ns * 4 * n * n
    wo = vv + ns * 4 * n * n
    return rc, sig, rhcx, cd, kinv, gen, tt, ll, vv, wo, wo + ns * n * n


@njit(cache=True)
def _copy(out, start, values, scale):
    v = values.ravel()
    for i in range(v.shape[0]):
        out[start + i] = scale * v[i]


@njit(cache=True)
def pack(compliance, r, C, cdiag, HCX, KinvC, general, Tset, Lset, Vset, Wo):
    """``D`` of one point (see the module notes)."""
    n = C.shape[0]
    k = HCX.shape[1]
    rc, sig, rhcx, cd, kinv, gen, tt, ll, vv, wo, end = offsets(n, k)
    out = np.empty(end)
    for c in range(k):
        out[c] = compliance[c]
    out[k] = r
    _copy(out, rc, np.ascontiguousarray(C), r)
    _copy(out, sig, np.ascontiguousarray(cdiag), 0.5 / r)
    _copy(out, rhcx, np.ascontiguousarray(HCX), r)
    _copy(out, cd, np.ascontiguousarray(cdiag), 1.0)
    _copy(out, kinv, np.ascontiguousarray(KinvC), r)
    _copy(out, gen, general, 1.0)
    _copy(out, tt, np.ascontiguousarray(Tset), 1.0)
    _copy(out, ll, np.ascontiguousarray(Lset), 1.0)
    _copy(out, vv, np.ascontiguousarray(Vset), 1.0)
    _copy(out, wo, np.ascontiguousarray(Wo), 1.0)
    return out


@njit(cache=True)
def effective(D, k, x, xd):
    """``x + K^-1 r C x'``: the displacement whose elastic force ``K x_e`` is the elastic
    plus the viscous force, ``K x + r C x'``. The event decision
    (:func:`tasks.multicontact.decide.decide`) of a damped scene takes it for ``x``."""
    n = x.shape[0]
    start = offsets(n, k)[4]
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
    """The decay rate of mode (or pair) a of stuck set S."""
    return D[offsets(n, k)[1] + S * n + a]


@njit(cache=True)
def cdiag_row(D, n, k, S):
    """``diag(X_S^T C X_S)`` of stuck set S (length n; its first ``m`` entries count)."""
    start = offsets(n, k)[3] + S * n
    return D[start : start + n]


@njit(cache=True)
def is_general(D, n, k, S):
    """Set S runs on the damped pairs (C couples its modes)."""
    return D[offsets(n, k)[5] + S] != 0.0


@njit(cache=True)
def damp_phase(D, n, k, stuck, active, m, etad0, segs, scs):
    """Make the phase just filled by :func:`tasks.multicontact.cycle.start_phase` damped:
    the modal decay rates (row DAMP, docs/structures.md 4.1) of every active contact's
    segment, and the viscous part ``-r (H_S C X_S)_c eta'`` of each stuck contact's
    force (row DELTA, and its value at the start in OBS0)."""
    _, rates, base, _, _, _, _, _, _, _, _ = offsets(n, k)
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
def _maps(D, n, k, S):
    """``(T, L, V, Wo)`` of set S: views of ``D`` (n x n, 2n x 2n, 2n x 2n, n x n)."""
    _, _, _, _, _, _, tt, ll, vv, wo, _ = offsets(n, k)
    T = D[tt + S * n * n : tt + (S + 1) * n * n].reshape((n, n))
    L = D[ll + S * 4 * n * n : ll + (S + 1) * 4 * n * n].reshape((2 * n, 2 * n))
    V = D[vv + S * 4 * n * n : vv + (S + 1) * 4 * n * n].reshape((2 * n, 2 * n))
    Wo = D[wo + S * n * n : wo + (S + 1) * n * n].reshape((n, n))
    return T, L, V, Wo


@njit(cache=True)
def general_phase(ctx, stuck, zeroed, x, xd, d, fconst, segs, scs, eta0, etad0):
    """Overwrite the phase of :func:`tasks.multicontact.cycle.start_phase` for a set on
    the damped pairs (docs/structures.md 4.5): the pairs' state ``eta = L (q, r q')``,
    ``eta' = xi + o`` (Eq. 4.10, ``o`` kept in row ETAD_OFF of ``segs[0]``), and every
    observable as a combination of ``(eta, eta')``: a sliding contact's velocity
    ``b_c . T q'`` and a stuck contact's force ``H_c (p cos + f - K x - r C x')``."""
    D = ctx[CX_COMPLIANCE]
    B = ctx[CX_B]
    K = ctx[CX_K]
    n, k = B.shape
    r = D[k]
    m = ctx[CX_SIZE][stuck]
    T, L, V, Wo = _maps(D, n, k, stuck)
    W = ctx[CX_W][stuck]
    H = ctx[CX_H][stuck]
    active = ctx[CX_ACTIVE]
    xr = x.copy()
    for c in range(k):
        if (stuck >> c) & 1:
            for i in range(n):
                xr[i] -= W[i, c] * d[c]
    y = np.zeros(2 * m)
    for a in range(m):
        q = 0.0
        qd = 0.0
        for i in range(n):
            q += T[i, a] * xr[i]
            qd += T[i, a] * xd[i]
        y[a] = q
        y[m + a] = r * qd
    for a in range(m):
        e = 0.0
        xi = 0.0
        o = 0.0
        for b in range(2 * m):
            e += L[a, b] * y[b]
            xi += L[m + a, b] * y[b]
        for i in range(n):
            o += Wo[i, a] * fconst[i]
        o /= r
        eta0[a] = e
        etad0[a] = xi / r + o
        segs[0, ETAD_OFF, a] = o
    rc = np.empty(n)
    force(D, k, xd, rc)
    for c in range(k):
        if not (active >> c) & 1:
            continue
        seg = segs[c]
        sc = scs[c]
        # the contact's row of the observable in the moving coordinates q, q'
        rowq = np.zeros(m)
        rowqd = np.zeros(m)
        if (stuck >> c) & 1:
            hk = np.zeros(n)
            hc = np.zeros(n)
            for j in range(n):
                for i in range(n):
                    hk[j] += H[c, i] * K[i, j]
                    hc[j] += H[c, i] * D[k + 1 + i * n + j]  # H r C
            for a in range(m):
                for j in range(n):
                    rowq[a] -= hk[j] * T[j, a]
                    rowqd[a] -= hc[j] * T[j, a]
            g = ctx[CX_HP][stuck, c] * sc[COS_TAU0]
            for i in range(n):
                g += H[c, i] * (fconst[i] - rc[i]) - hk[i] * xr[i]  # K W d is in fconst
            sc[OBS0] = g
        else:
            for a in range(m):
                for j in range(n):
                    rowqd[a] += B[j, c] * T[j, a]
        # (q, q') = V (eta, r (eta' - o)) with q' = (V (..))[m:] / r
        for kk in range(m):
            al = 0.0
            de = 0.0
            for a in range(m):
                al += rowq[a] * V[a, kk] + rowqd[a] * V[m + a, kk] / r
                de += r * rowq[a] * V[a, m + kk] + rowqd[a] * V[m + a, m + kk]
            seg[ALPHA, kk] = al
            seg[DELTA, kk] = de
            seg[ETA0, kk] = eta0[kk]
            seg[ETAD0, kk] = etad0[kk]
        if not (stuck >> c) & 1:
            v = 0.0
            for i in range(n):
                v += B[i, c] * xd[i]
            sc[OBS0] = 0.0 if zeroed[c] else v


@njit(cache=True)
def general_state(ctx, stuck, d, eta, etad, off, x, xd):
    """``x = T q + W d``, ``x' = T q'`` with ``(q, r q') = V (eta, r (eta' - o))``."""
    D = ctx[CX_COMPLIANCE]
    n, k = ctx[CX_B].shape
    r = D[k]
    m = ctx[CX_SIZE][stuck]
    T, _, V, _ = _maps(D, n, k, stuck)
    W = ctx[CX_W][stuck]
    z = np.empty(2 * m)
    for a in range(m):
        z[a] = eta[a]
        z[m + a] = r * (etad[a] - off[a])
    for i in range(n):
        x[i] = 0.0
        xd[i] = 0.0
    for a in range(m):
        q = 0.0
        qd = 0.0
        for b in range(2 * m):
            q += V[a, b] * z[b]
            qd += V[m + a, b] * z[b]
        for i in range(n):
            x[i] += T[i, a] * q
            xd[i] += T[i, a] * qd / r
    for c in range(k):
        if (stuck >> c) & 1:
            for i in range(n):
                x[i] += W[i, c] * d[c]


@njit(cache=True)
def general_held(ctx, stuck, out):
    """The damped held steady state of a set on pairs at tau = 0 into ``out`` (x, x'):
    each pair at ``P cos + Q sin`` (Eq. 4.2, o = 0: nothing constant). False at an
    undamped resonance of a loaded pair."""
    D = ctx[CX_COMPLIANCE]
    n, k = ctx[CX_B].shape
    m = ctx[CX_SIZE][stuck]
    eta = np.zeros(m)
    etad = np.zeros(m)
    for a in range(m):
        load = ctx[CX_LOAD_COS][stuck, a]
        if load == 0.0:
            continue
        P, Q = particular(ctx[CX_OMEGA][stuck, a], sigma(D, n, k, stuck, a), load)
        if not (math.isfinite(P) and math.isfinite(Q)):
            return False
        eta[a] = P
        etad[a] = Q
    general_state(ctx, stuck, np.zeros(k), eta, etad, np.zeros(m), out[:n], out[n:])
    return True


@njit(cache=True)
def _subintervals(seg, t):
    """Sub-intervals of the 4-point Gauss-Legendre rule over a phase of length ``t``:
    short against its fastest rate (``Omega_a + 2 sigma_a`` and the excitation), at
    most :data:`VISCOUS_MAX_INTERVALS` (:func:`viscous_work`, :func:`general_work`)."""
    rate = 1.0
    for a in range(seg.shape[1]):
        rate = max(rate, seg[OMEGA, a] + 2.0 * seg[DAMP, a])
    return min(max(1, int(math.ceil(2.0 * rate * t))), VISCOUS_MAX_INTERVALS)


@njit(cache=True)
def general_work(ctx, stuck, seg, sc, t, off):
    """``int_0^t x'^T r C x' dtau`` over a phase on pairs (the quadrature of
    :func:`viscous_work`, the full quadratic form of x')."""
    D = ctx[CX_COMPLIANCE]
    n, k = ctx[CX_B].shape
    m = seg.shape[1]
    n_sub = _subintervals(seg, t)
    h = t / n_sub
    eta = np.empty(m)
    etad = np.empty(m)
    x = np.empty(n)
    xd = np.empty(n)
    rc = np.empty(n)
    d = np.zeros(k)
    total = 0.0
    for j in range(n_sub):
        for q in range(4):
            evaluate(seg, sc, (j + _GL_NODES[q]) * h, eta, etad)
            general_state(ctx, stuck, d, eta, etad, off, x, xd)
            force(D, k, xd, rc)
            acc = 0.0
            for i in range(n):
                acc += xd[i] * rc[i]
            total += _GL_WEIGHTS[q] * acc
    return h * total


@njit(cache=True)
def viscous_work(seg, sc, t, cdiag, r):
    """``int_0^t r x'^T C x' dtau = r sum_a cdiag_a int eta_a'^2`` over a damped phase of
    length ``t`` (``X_S^T C X_S`` diagonal, docs/contacts.md 7): 4-point Gauss-Legendre
    on sub-intervals short against the fastest rate of the phase (``Omega_a + 2 sigma_a``
    and the excitation), where the rule's error is below 1e-12 of the integral."""
    m = seg.shape[1]
    n_sub = _subintervals(seg, t)
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
