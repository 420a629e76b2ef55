"""When a fixed point of the Poincare map is accepted (docs/simulator.md 5).

A residual ``P(X) - X`` within tolerance is not enough: the fixed point itself
must be near (Newton's step, :func:`_near_fixed_point`), the contact's own motion
must have settled (:func:`contact_within`, measured against :func:`contact_scale`),
and the fixed point must not be unstable (:func:`radius_within`). Used by the
shooting of :mod:`tasks.kernel.shooting` and the plain iteration of
:mod:`tasks.kernel.point`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.kernel.cycle import _max_abs
from tasks.kernel.layout import CTX_B, CTX_BETA, CTX_F_R2, CTX_PHI, CTX_SEG_SLIP, DELTA, LEAF, OMEGA
from tasks.kernel.linsolve import _solve
from tasks.regimes import SLIP_RTOL

# Stability test of a fixed point: spectral radius of dP/dy at most STABLE_RADIUS.
STABLE_RADIUS = 1.0 + 1e-6
# Squarings of dP/dy the stability test tries before it computes the eigenvalues
# (:func:`radius_within`), and the smallest trace of a power, relative to its
# norm, that it reads as a lower bound of the spectral radius.
RADIUS_SQUARINGS = 40
TRACE_RTOL = 1e-2
# Smallest tolerance of the distance to an accepted fixed point (:func:`_near_fixed_point`),
# relative to the motion, and of its contact test (:func:`contact_within`), relative to
# the contact's motion: the polish's 1e-12 is a residual at the rounding of the map,
# and Newton's step from it is that over one minus the slowest Floquet multiplier.
CONTACT_RTOL = 1e-10


@njit(**LEAF)
def _norm_inf(A):
    """The induced infinity norm of ``A`` (largest absolute row sum)."""
    acc = 0.0
    for i in range(A.shape[0]):
        row = 0.0
        for k in range(A.shape[1]):
            row += abs(A[i, k])
        acc = max(acc, row)
    return acc


@njit(cache=True)
def radius_within(A, bound):
    """Whether the spectral radius of the square matrix ``A`` is at most ``bound``.

    ``rho(A) <= ||A^k||^(1 / k)`` for every k and every induced norm, so a power
    ``A^k`` (k = 1, 2, 4, ..., ``2^RADIUS_SQUARINGS``, by repeated squaring, rescaled
    so that nothing overflows) whose infinity norm is at most ``bound^k`` proves it
    in small matrix products. Conversely ``|trace A^k| <= dim rho^k``, so a power
    whose trace exceeds ``dim bound^k`` proves the radius above ``bound`` (read
    only where the trace is at least ``TRACE_RTOL`` of the norm, far above the
    rounding of the squarings). With ``k`` up to ``2^40`` the two bounds close in
    on ``rho`` to far below the margin ``bound - 1``; only where neither proves
    anything (e.g. a dominant complex pair whose powers' traces stay small) do
    the eigenvalues decide (LAPACK, whose call wakes the BLAS threads). The answer
    is the eigenvalues' except within rounding of ``bound``.
    """
    dim = A.shape[0]
    B = A.copy()
    C = np.empty_like(B)
    log_bound = math.log(bound)
    log_scale = 0.0  # B = A^k / exp(log_scale)
    k = 1.0
    for _ in range(RADIUS_SQUARINGS + 1):
        nrm = _norm_inf(B)
        if nrm == 0.0:
            return True
        if not nrm < np.inf:
            break
        tr = 0.0
        for i in range(dim):
            tr += B[i, i]
        # |trace A^k| <= dim rho^k: a trace this large proves rho > bound (counted
        # only where it stands well above the rounding of the repeated squarings)
        if abs(tr) >= TRACE_RTOL * nrm:
            if math.log(abs(tr)) + log_scale - math.log(dim) > k * log_bound:
                return False
        log_scale += math.log(nrm)
        if log_scale <= k * log_bound:
            return True
        for i in range(dim):
            for j in range(dim):
                B[i, j] /= nrm
        for i in range(dim):
            for j in range(dim):
                acc = 0.0
                for m in range(dim):
                    acc += B[i, m] * B[m, j]
                C[i, j] = acc
        B, C = C, B
        log_scale *= 2.0
        k *= 2.0
    radius = np.max(np.abs(np.linalg.eigvals(A.astype(np.complex128))))
    return radius <= bound


@njit(cache=True)
def contact_scale(ctx, amp):
    """Scale of the contact's own motion: the larger of its slip amplitude ``amp`` and
    the deflection the friction force produces at the contact, ``beta c``.

    ``c = sum_k (b . phi_k)^2 / (r^2 max(Omega_k^2, 1))`` is the compliance the
    contact sees at the excitation frequency (:func:`tasks.kernel.creep.creep_threshold`;
    ``(b . phi_k) / r^2`` is the modal load of a unit friction force). 0 where the
    damping is not proportional (no real modes): the contact test is then off.
    """
    b = ctx[CTX_B]
    n = b.shape[0]
    if ctx[CTX_PHI].shape[0] != n:
        return 0.0
    seg = ctx[CTX_SEG_SLIP]
    f_r2 = ctx[CTX_F_R2]
    c = 0.0
    for k in range(n):
        om = seg[OMEGA, k]
        c += abs(seg[DELTA, k] * f_r2[k]) / max(om * om, 1.0)
    return max(amp, ctx[CTX_BETA] * c)


@njit(cache=True)
def contact_within(ctx, D, mode, amp, rtol):
    """Whether a change ``D`` of the section state moves the contact by at most
    ``max(rtol, CONTACT_RTOL) * contact_scale`` (displacement ``b . x`` and velocity
    ``b . x'``; ``D`` in the chart of ``mode``, :func:`_reduce`), or by less than
    the creep threshold ``SLIP_RTOL * beta c`` (:func:`tasks.kernel.creep.creep_threshold`).

    The regime is decided at the contact (a stop, a stick while ``|g| <= beta``),
    whose motion can be far smaller than the section state: a tiny mass between
    two large ones that move together (a contact slip of 3e-4 in a motion of
    0.67), where a transient that still sticks for a moment each period has a
    residual of 5e-10 of the motion and reaches the continuous orbit in 10 more
    periods. Measured against the motion alone it was a stick-slip orbit below the
    exact continuous bound.
    """
    scale = contact_scale(ctx, amp)
    if scale == 0.0 or amp < SLIP_RTOL * contact_scale(ctx, 0.0):
        return True  # (no contact test; or slips below the creep threshold: no motion)
    b = ctx[CTX_B]
    n = b.shape[0]
    if mode == 0:
        moved = abs(D[0])  # (d0, q, q'): the contact is frozen at d0
    else:
        dx = 0.0
        dv = 0.0
        for i in range(n):
            dx += b[i] * D[i]
            dv += b[i] * D[n + i]
        moved = max(abs(dx), abs(dv))
    # (and never below the creep threshold, SLIP_RTOL beta c: a contact moving less
    # is not moving, docs/theory.md 3; a creep settling onto no motion is decided so)
    floor = SLIP_RTOL * contact_scale(ctx, 0.0)
    return moved <= max(max(rtol, CONTACT_RTOL) * scale, floor)


@njit(cache=True)
def _near_fixed_point(J, R, tol, ctx, mode, amp, rtol):
    """Whether the fixed point lies within ``tol`` of an iterate whose residual is ``R``,
    and within ``rtol`` of the contact's motion at the contact (:func:`contact_within`).

    A small residual ``R = P(y) - y`` is not a small distance to the fixed point:
    with a Floquet multiplier mu near 1 the distance is about ``|R| / (1 - mu)``,
    Newton's step ``-(dP/dy - I)^-1 R`` (``J = dP/dy - I``, docs/simulator.md 5).
    Next to the continuous / stick-slip boundary a slow transient sticks for a
    moment each period while it creeps onto the continuous orbit (its stick
    shrinking over 2,500 periods), with a residual of 4e-9 of the motion and the
    fixed point 5e2 times farther: accepted on its residual, it was a stick-slip
    orbit below the exact continuous bound. The step must be within ``tol``, as
    the plain iteration's ``diff / (1 - rho)`` (within ``CONTACT_RTOL`` of the
    motion where ``rtol`` is smaller: the polish and the warm starts, whose
    residual of 1e-12 is at the map's rounding). A singular ``J`` (a multiplier of
    exactly 1, no isolated fixed point) leaves the decision to the residual and
    the stability test.
    """
    if amp < SLIP_RTOL * contact_scale(ctx, 0.0):
        return True  # slips below the creep threshold: no motion, the creep rule decides
    step = _solve(J, -R)
    if not np.all(np.isfinite(step)):
        return True
    # (a polish's 1e-12 residual is at the rounding of the map: its step need only
    # be within CONTACT_RTOL, far below any label's resolution)
    reach = max(tol, CONTACT_RTOL / rtol * tol) if rtol > 0.0 else tol
    return _max_abs(step) <= reach and contact_within(ctx, step, mode, amp, rtol)
