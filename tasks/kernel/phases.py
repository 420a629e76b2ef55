"""Starting a phase from a state, the state at its end, and the contact force.

The motion alternates between two linear systems (:mod:`tasks.model`):

* sliding with sign ``s`` (all N coordinates), until the contact velocity
  ``v = b . x'`` reaches 0. There the contact force ``g`` decides: ``|g| <= beta``
  sticks (Eqs. 11, 12, 79, 103), otherwise the slip reverses (``s = sgn g``);
* stuck (N - 1 coordinates, the contact frozen at ``d0 = b . x``, so
  ``x = T q + d0 w``; Eqs. 131-135), until ``|g|`` reaches ``beta``; the contact
  then slides with ``s = sgn g``.

:func:`_start_slip` and :func:`_start_stick` project a state ``(x, x')`` onto the
modal coordinates of the phase (the ``seg, sc`` arrays of
:mod:`tasks.kernel.layout`); :func:`_slip_state` and :func:`_stick_state` map the
modal state back.

They run once or more per phase and allocate nothing, so they are compiled as
leaves (``tasks.kernel.layout.LEAF``: no reference counting of the arrays they
are passed).
"""

from __future__ import annotations

import math

from numba import njit

from tasks.kernel.layout import (
    ALPHA,
    BETA,
    COS_TAU0,
    CTX_B,
    CTX_DSTAT_R2,
    CTX_G_COS,
    CTX_G_D0,
    CTX_PHI_S_T_GAMMA_S,
    CTX_PROJ,
    CTX_SC,
    CTX_SEG_STICK,
    CTX_W,
    DAMPED,
    DELTA,
    ETA0,
    ETAD0,
    ETAD_OFF,
    KIND,
    KIND_SLIP,
    KIND_STICK,
    LEAF,
    LOAD_CONST,
    OBS0,
    OBS_COS,
    SIGN,
    SIN_TAU0,
    TAU0,
)

# A stick phase ends when |g| exceeds beta by more than this (relative): the
# rounding of g's terms, as in :func:`tasks.kernel.events.never_unsticks` (else a
# tangential touch of |g| = beta at a no-motion boundary unsticks on rounding noise).
STICK_RTOL = 1e-12


@njit(**LEAF)
def _matvec(a, x, out):
    for i in range(a.shape[0]):
        acc = 0.0
        for j in range(a.shape[1]):
            acc += a[i, j] * x[j]
        out[i] = acc


@njit(**LEAF)
def _dot(a, b):
    acc = 0.0
    for i in range(a.shape[0]):
        acc += a[i] * b[i]
    return acc


@njit(**LEAF)
def _contact_force(p, ctau, K, x, g_load):
    """g = g_load . (p cos tau - K x): the force the contact must transmit."""
    acc = 0.0
    n = x.shape[0]
    for i in range(n):
        kx = 0.0
        for j in range(n):
            kx += K[i, j] * x[j]
        acc += g_load[i] * (p[i] * ctau - kx)
    return acc


@njit(**LEAF)
def _to_pairs(L, x, xd, seg, offset_unit, load_unit, scale):
    """General damping: ``(eta, xi) = L (x, x')``, ``eta' = xi + o`` with
    ``o = scale offset_unit`` and the constant load ``scale load_unit``
    (tasks.damped_pairs, docs/structures.md 4.5)."""
    n = x.shape[0]
    m = seg.shape[1]
    for k in range(m):
        e = 0.0
        v = 0.0
        for j in range(n):
            e += L[k, j] * x[j] + L[k, n + j] * xd[j]
            v += L[m + k, j] * x[j] + L[m + k, n + j] * xd[j]
        off = scale * offset_unit[k]
        seg[ETAD_OFF, k] = off
        seg[ETA0, k] = e
        seg[ETAD0, k] = v + off
        seg[LOAD_CONST, k] = scale * load_unit[k]


@njit(**LEAF)
def _from_pairs(V, eta, etad, off, x, xd):
    """General damping: ``(x, x') = V (eta, eta' - o)``."""
    n = x.shape[0]
    m = eta.shape[0]
    for i in range(n):
        acc = 0.0
        accd = 0.0
        for k in range(m):
            acc += V[i, k] * eta[k] + V[i, m + k] * (etad[k] - off[k])
            accd += V[n + i, k] * eta[k] + V[n + i, m + k] * (etad[k] - off[k])
        x[i] = acc
        xd[i] = accd


@njit(**LEAF)
def _start_slip(seg, sc, x, xd, tau, s, v0, beta, f_r2, phi_t_gamma):
    n = x.shape[0]
    if phi_t_gamma.shape[0] == n:
        _matvec(phi_t_gamma, x, seg[ETA0])
        _matvec(phi_t_gamma, xd, seg[ETAD0])
        for k in range(seg.shape[1]):
            seg[LOAD_CONST, k] = -beta * s * f_r2[k]
    else:  # general damping: f_r2 = (constant load, offset) per unit friction force
        _to_pairs(phi_t_gamma, x, xd, seg, f_r2[n:], f_r2[:n], -beta * s)
    sc[TAU0] = tau
    sc[COS_TAU0] = math.cos(tau)
    sc[SIN_TAU0] = math.sin(tau)
    sc[OBS_COS] = 0.0
    sc[OBS0] = v0
    sc[KIND] = KIND_SLIP
    sc[SIGN] = s
    sc[BETA] = beta


@njit(**LEAF)
def _start_stick(seg, sc, x, xd, tau, beta, b, w, proj, phi_s_t_gamma_s, dstat_r2, g_cos, g_d0, q):
    """Freeze the contact at d0 = b . x; returns d0."""
    n = x.shape[0]
    m = seg.shape[1]
    general = phi_s_t_gamma_s.shape[0] != m
    d0 = _dot(b, x)
    # q = proj (x - d0 w), q' = proj x' (momentum-conserving)
    for i in range(m):
        acc = 0.0
        accd = 0.0
        for j in range(n):
            acc += proj[i, j] * (x[j] - d0 * w[j])
            accd += proj[i, j] * xd[j]
        q[i] = acc
        q[m + i] = accd
    if general:  # dstat_r2 = (constant load, offset) per unit d0
        _to_pairs(phi_s_t_gamma_s, q[:m], q[m:], seg, dstat_r2[m:], dstat_r2[:m], -d0)
    else:
        for k in range(m):
            e0 = 0.0
            v0 = 0.0
            for i in range(m):
                e0 += phi_s_t_gamma_s[k, i] * q[i]
                v0 += phi_s_t_gamma_s[k, i] * q[m + i]
            seg[ETA0, k] = e0
            seg[ETAD0, k] = v0
            seg[LOAD_CONST, k] = -dstat_r2[k] * d0
    ctau = math.cos(tau)
    g0 = g_cos * ctau - g_d0 * d0
    for k in range(m):
        g0 += seg[ALPHA, k] * seg[ETA0, k]
    if sc[DAMPED] != 0.0:  # viscous part of g (row DELTA of the stuck phase)
        for k in range(m):
            g0 += seg[DELTA, k] * seg[ETAD0, k]
        if general:  # g holds delta xi = delta (eta' - o)
            for k in range(m):
                g0 -= seg[DELTA, k] * seg[ETAD_OFF, k]
    sc[TAU0] = tau
    sc[COS_TAU0] = ctau
    sc[SIN_TAU0] = math.sin(tau)
    sc[OBS_COS] = g_cos
    sc[OBS0] = g0
    sc[KIND] = KIND_STICK
    sc[SIGN] = 0.0
    sc[BETA] = beta * (1.0 + STICK_RTOL)
    return d0


@njit(**LEAF)
def start_stick_in(ctx, x, xd, tau, beta, q):
    """:func:`_start_stick` with the scene's stick-phase arrays taken from the
    point's context ``ctx`` (:mod:`tasks.kernel.context`); returns d0."""
    return _start_stick(
        ctx[CTX_SEG_STICK],
        ctx[CTX_SC],
        x,
        xd,
        tau,
        beta,
        ctx[CTX_B],
        ctx[CTX_W],
        ctx[CTX_PROJ],
        ctx[CTX_PHI_S_T_GAMMA_S],
        ctx[CTX_DSTAT_R2],
        ctx[CTX_G_COS],
        ctx[CTX_G_D0],
        q,
    )


@njit(**LEAF)
def _slip_state(phi, eta, etad, x, xd, off):
    """``(x, x')`` of the slip phase's modal state (``off``: row ETAD_OFF, general
    damping only)."""
    if phi.shape[0] != x.shape[0]:
        _from_pairs(phi, eta, etad, off, x, xd)
        return
    _matvec(phi, eta, x)
    _matvec(phi, etad, xd)


@njit(**LEAF)
def _stick_state(phi_s, T, w, d0, eta, etad, q, x, xd, off):
    """``(x, x')`` of the stick phase's modal state (``off``: row ETAD_OFF, general
    damping only)."""
    m = eta.shape[0]
    n = x.shape[0]
    if phi_s.shape[0] != m:
        _from_pairs(phi_s, eta, etad, off, q[:m], q[m:])
    else:
        for i in range(m):
            acc = 0.0
            accd = 0.0
            for k in range(m):
                acc += phi_s[i, k] * eta[k]
                accd += phi_s[i, k] * etad[k]
            q[i] = acc
            q[m + i] = accd
    for j in range(n):
        acc = d0 * w[j]
        accd = 0.0
        for i in range(m):
            acc += T[j, i] * q[i]
            accd += T[j, i] * q[m + i]
        x[j] = acc
        xd[j] = accd
