"""The exact Jacobian of the Poincare map of one period (the monodromy matrix).

Along a recorded period (:func:`tasks.kernel.shooting._period_recorded`) every
phase is linear with closed-form modal solutions (docs/theory.md 2, Eq. (1) of
:mod:`tasks.kernel.propagation`), so the derivative of the period's end state
with respect to its start is a product over the phases:

* inside a phase, the modal transition matrix: per mode the response to a unit
  start displacement, a unit start velocity and (stuck: the constant load
  ``-dstat d0`` moves with the frozen contact ``d0``) a unit constant load,
  each one :func:`tasks.kernel.propagation.evaluate` of a scratch phase with
  the harmonic load removed; entering a stick phase projects the state on the
  held system (``d0 = b . x``, ``q = proj (x - d0 w)``, ``q' = proj x'``,
  Eqs. 131-135), which is linear and part of the phase's start;
* at each event ending a phase at ``tau_e`` (``y = 0`` while sliding, ``|g| =
  beta`` while stuck, ``y`` the phase's observable), the event-time sensitivity
  ``d tau_e = -(grad y . dX) / y'``, and the start-time term of the next phase
  ``-Phi f(X_e, tau_e) d tau_e`` with the state's time derivative ``f`` of
  that phase: together the saltation matrix
  ``S = I + (f+ - f-) grad y^T / y'`` of the event.

The last phase ends at the fixed section ``theta + 2 pi``. The result is
``dP/dy - I`` in the chart of the section (:func:`tasks.kernel.shooting._reduce`),
the matrix :func:`tasks.kernel.shooting._fd_jacobian` approximates by forward
differences of followed periods, at the cost of a few evaluations per phase
instead of one followed period per column. Scenes with non-proportional
damping (pairs, docs/structures.md 4.5) and records with a graze or a phase of
zero length are left to the differences (the function returns False).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.kernel.layout import (
    ALPHA,
    CTX_B,
    CTX_BETA,
    CTX_DSTAT_R2,
    CTX_F_R2,
    CTX_G_D0,
    CTX_PHI,
    CTX_PHI_S,
    CTX_PHI_S_T_GAMMA_S,
    CTX_PHI_T_GAMMA,
    CTX_PROJ,
    CTX_SC,
    CTX_SEG_SLIP,
    CTX_SEG_STICK,
    CTX_T,
    CTX_W,
    DAMP,
    DELTA,
    ETA0,
    ETAD0,
    EV_END,
    EV_GRAZE,
    LEAF,
    LOAD_CONST,
    LOAD_COS,
    OMEGA,
    REC_KIND,
    REC_MODE,
    REC_TAU,
    REC_X,
)
from tasks.kernel.phases import _start_slip, start_stick_in
from tasks.kernel.propagation import evaluate

# A phase shorter than this (in tau) makes the record unusable: an event at the
# section or two events together, where the map is not smooth enough to chain.
MIN_PHASE = 1e-9


@njit(**LEAF)
def _modal_basis(seg, sc, t, s, basis, eta, etad):
    """Per mode, the displacement and velocity at ``t`` of the phase ``seg, sc``
    started from a unit displacement (rows 0, 1 of ``basis``), a unit velocity
    (rows 2, 3) and under a unit constant load (rows 4, 5), without the harmonic
    load: the columns of the modal transition matrix. ``s``: scratch of
    ``seg``'s shape."""
    m = seg.shape[1]
    for i in range(seg.shape[0]):
        for k in range(m):
            s[i, k] = seg[i, k]
    for k in range(m):
        s[LOAD_COS, k] = 0.0
        s[LOAD_CONST, k] = 0.0
        s[ETA0, k] = 1.0
        s[ETAD0, k] = 0.0
    for j in range(3):
        evaluate(s, sc, t, eta, etad)
        for k in range(m):
            basis[2 * j, k] = eta[k]
            basis[2 * j + 1, k] = etad[k]
            if j == 0:
                s[ETA0, k] = 0.0
                s[ETAD0, k] = 1.0
            else:
                s[ETAD0, k] = 0.0
                s[LOAD_CONST, k] = 1.0


@njit(**LEAF)
def _modal_rate(seg, k, tau, e, v):
    """Acceleration of mode ``k`` of a phase at ``tau`` with displacement ``e`` and
    velocity ``v``: ``a cos(tau) + c - 2 sigma v - Omega^2 e`` (Eq. (1))."""
    w = seg[OMEGA, k]
    return (
        seg[LOAD_COS, k] * math.cos(tau) + seg[LOAD_CONST, k] - 2.0 * seg[DAMP, k] * v - w * w * e
    )


@njit(cache=True)
def exact_jacobian(y0, mode, rec, nr, ctx, work, J, probe):
    """``J = dP/dy - I`` of the recorded period from ``y0`` (chart of ``mode``), exactly.

    ``rec`` holds the ``nr`` rows of the period from the expanded ``y0``
    (:func:`tasks.kernel.shooting._period_recorded`, which
    :func:`tasks.kernel.shooting._records_usable` accepts). Chains, phase by
    phase, the modal transition matrices, the stick projection and the event-time
    sensitivities (module docstring). Returns False (``J`` undefined) where the
    record cannot carry it: non-proportional damping, a graze, a phase shorter
    than ``MIN_PHASE``, an event whose observable does not cross (``y' = 0``),
    a period ending in the other chart, or an event so close to tangency
    that a difference column could not follow it: where a change of ``y`` by
    ``probe[k]`` (the step of column k of
    :func:`tasks.kernel.shooting._fd_jacobian`) moves a phase's end by more than
    ``probe[-1]`` times its length (``FD_REACH``; the events a difference column
    follows, :func:`tasks.kernel.shooting._follow_records`), so the map is used
    exactly where its differences were. ``J`` is then left as it was.
    """
    phi = ctx[CTX_PHI]
    n = ctx[CTX_B].shape[0]
    if phi.shape[0] != n or phi.shape[1] != n:
        return False
    if nr < 2 or rec[nr - 1, REC_KIND] != EV_END:
        return False
    if (int(rec[nr - 1, REC_MODE]) == 0) != (mode == 0):
        return False
    b = ctx[CTX_B]
    w = ctx[CTX_W]
    T = ctx[CTX_T]
    proj = ctx[CTX_PROJ]
    ptg = ctx[CTX_PHI_T_GAMMA]
    phi_s = ctx[CTX_PHI_S]
    pstgs = ctx[CTX_PHI_S_T_GAMMA_S]
    dstat = ctx[CTX_DSTAT_R2]
    g_d0 = ctx[CTX_G_D0]
    sc = ctx[CTX_SC]
    beta = ctx[CTX_BETA]
    m_s = phi_s.shape[0]
    if pstgs.shape[0] != m_s or dstat.shape[0] != m_s:
        return False
    dim = y0.shape[0]
    eta, etad, _, _, q, _ = work
    # D: d(state at the current phase start) / dy; dtau: d(its start time) / dy
    D = np.zeros((2 * n, dim))
    if mode == 0:
        for j in range(n):
            D[j, 0] = w[j]
            for i in range(m_s):
                D[j, 1 + i] = T[j, i]
                D[n + j, 1 + m_s + i] = T[j, i]
    else:
        for j in range(2 * n):
            D[j, j] = 1.0
    dtau = np.zeros(dim)
    # modal start (then end) displacements, velocities and loads, and a scratch
    mats = np.zeros((4, n, dim))
    de = mats[0]
    dv = mats[1]
    dc = mats[2]
    tmp = mats[3]
    dd0 = np.zeros(dim)
    vecs = np.empty((10, n))
    basis = vecs[:6]
    r11, r21, r12, r22, c1, c2 = basis[0], basis[1], basis[2], basis[3], basis[4], basis[5]
    ee = vecs[6]
    ve = vecs[7]
    x = vecs[8]
    xd = vecs[9]
    s_slip = np.empty_like(ctx[CTX_SEG_SLIP])
    s_stick = np.empty_like(ctx[CTX_SEG_STICK])
    for j in range(nr - 1):
        if rec[j + 1, REC_KIND] == EV_GRAZE:
            return False
        tau0 = rec[j, REC_TAU]
        t = rec[j + 1, REC_TAU] - tau0
        if not t > MIN_PHASE:
            return False
        for i in range(n):
            x[i] = rec[j, REC_X + i]
            xd[i] = rec[j, REC_X + n + i]
        stuck = int(rec[j, REC_MODE]) == 0
        if stuck:
            seg = ctx[CTX_SEG_STICK]
            start_stick_in(ctx, x, xd, tau0, beta, q)
            m = m_s
            # d0 = b . x, q = proj (x - d0 w), q' = proj x'; modal via pstgs
            for c in range(dim):
                acc = 0.0
                for i in range(n):
                    acc += b[i] * D[i, c]
                dd0[c] = acc
            for i in range(m):
                for c in range(dim):
                    acc = 0.0
                    accd = 0.0
                    for k in range(n):
                        acc += proj[i, k] * (D[k, c] - w[k] * dd0[c])
                        accd += proj[i, k] * D[n + k, c]
                    tmp[i, c] = acc
                    dc[i, c] = accd  # (q' for now)
            for k in range(m):
                for c in range(dim):
                    acc = 0.0
                    accd = 0.0
                    for i in range(m):
                        acc += pstgs[k, i] * tmp[i, c]
                        accd += pstgs[k, i] * dc[i, c]
                    de[k, c] = acc
                    dv[k, c] = accd
            for k in range(m):
                for c in range(dim):
                    dc[k, c] = -dstat[k] * dd0[c]
        else:
            seg = ctx[CTX_SEG_SLIP]
            _start_slip(
                seg,
                sc,
                x,
                xd,
                tau0,
                float(rec[j, REC_MODE]),
                0.0,
                beta,
                ctx[CTX_F_R2],
                ptg,
            )
            m = n
            for k in range(m):
                for c in range(dim):
                    acc = 0.0
                    accd = 0.0
                    for i in range(n):
                        acc += ptg[k, i] * D[i, c]
                        accd += ptg[k, i] * D[n + i, c]
                    de[k, c] = acc
                    dv[k, c] = accd
                    dc[k, c] = 0.0
        _modal_basis(seg, sc, t, s_stick if stuck else s_slip, basis, eta, etad)
        _, dy = evaluate(seg, sc, t, eta, etad)
        for k in range(m):
            ee[k] = eta[k]
            ve[k] = etad[k]
        last = j + 1 == nr - 1
        # through the phase: modal transition, constant load, start-time shift
        for k in range(m):
            e0 = seg[ETA0, k]
            v0 = seg[ETAD0, k]
            a0 = _modal_rate(seg, k, tau0, e0, v0)
            se = r11[k] * v0 + r12[k] * a0  # Phi f at the start
            sv = r21[k] * v0 + r22[k] * a0
            for c in range(dim):
                e = r11[k] * de[k, c] + r12[k] * dv[k, c] + c1[k] * dc[k, c] - se * dtau[c]
                v = r21[k] * de[k, c] + r22[k] * dv[k, c] + c2[k] * dc[k, c] - sv * dtau[c]
                de[k, c] = e
                dv[k, c] = v
        # the event time: y(X_e, tau_e) = target, y the phase's observable
        tau_e = tau0 + t
        if last:
            for c in range(dim):
                dtau[c] = 0.0
        else:
            if not (dy != 0.0 and math.isfinite(dy)):
                return False
            for c in range(dim):
                acc = 0.0
                for k in range(m):
                    acc += seg[ALPHA, k] * de[k, c] + seg[DELTA, k] * dv[k, c]
                if stuck:
                    acc -= g_d0 * dd0[c]
                shift = -acc / dy
                # the phase's end moves by (shift - dtau) per unit of y_c
                if abs(shift - dtau[c]) * probe[c] > probe[dim] * max(t, 1e-3):
                    return False
                dtau[c] = shift
            for k in range(m):
                ve_k = ve[k]
                ae_k = _modal_rate(seg, k, tau_e, ee[k], ve_k)
                for c in range(dim):
                    de[k, c] += ve_k * dtau[c]
                    dv[k, c] += ae_k * dtau[c]
        # back to (x, x')
        if stuck:
            for i in range(m):
                for c in range(dim):
                    acc = 0.0
                    accd = 0.0
                    for k in range(m):
                        acc += phi_s[i, k] * de[k, c]
                        accd += phi_s[i, k] * dv[k, c]
                    tmp[i, c] = acc
                    dc[i, c] = accd
            for r in range(n):
                for c in range(dim):
                    acc = w[r] * dd0[c]
                    accd = 0.0
                    for i in range(m):
                        acc += T[r, i] * tmp[i, c]
                        accd += T[r, i] * dc[i, c]
                    D[r, c] = acc
                    D[n + r, c] = accd
        else:
            for r in range(n):
                for c in range(dim):
                    acc = 0.0
                    accd = 0.0
                    for k in range(m):
                        acc += phi[r, k] * de[k, c]
                        accd += phi[r, k] * dv[k, c]
                    D[r, c] = acc
                    D[n + r, c] = accd
    for r in range(2 * n):
        for c in range(dim):
            if not math.isfinite(D[r, c]):
                return False
    # the end state in the chart of the section, minus the identity (J written
    # only here: where False is returned, J is left as it was)
    if mode == 0:
        for c in range(dim):
            acc = 0.0
            for i in range(n):
                acc += b[i] * D[i, c]
            J[0, c] = acc
            for i in range(m_s):
                acc1 = 0.0
                accd = 0.0
                for k in range(n):
                    acc1 += proj[i, k] * (D[k, c] - w[k] * acc)
                    accd += proj[i, k] * D[n + k, c]
                J[1 + i, c] = acc1
                J[1 + m_s + i, c] = accd
    else:
        for i in range(2 * n):
            for c in range(dim):
                J[i, c] = D[i, c]
    for i in range(dim):
        J[i, i] -= 1.0
    return True
