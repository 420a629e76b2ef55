"""Which contacts stick and which slide after an event (docs/contacts.md 3).

At an event the *candidates* are the contacts with zero relative velocity: the
stuck ones and those whose slip just stopped (two at once when stops coincide).
Contacts sliding with a nonzero velocity keep their sign. Each candidate either
sticks or slides with sign +1 or -1 (3^|C| assignments, |C| <= 4). An
assignment is *admissible* when

* every stuck candidate's force is within its limit, ``|g_c| <= beta_c``, with
  ``g_S = H_S f`` (:mod:`tasks.multicontact.sets`), and
* every sliding candidate accelerates in its slip direction, ``s_c b_c . x'' > 0``,
  with ``r^2 G x'' = f - B_S g_S``,

``f = p cos tau - K x - sum_(c sliding) beta_c s_c b_c``. A damped scene
(docs/contacts.md 7) has ``- r C x'`` in f too: its callers pass
``x + K^-1 r C x'`` for x (:func:`tasks.multicontact.viscous.effective`), so this
module is the undamped one, unchanged. The contact
accelerations ``a = A (f_free + F)`` with ``A = B^T G^-1 B / r^2`` positive
definite and ``F`` in the Coulomb graph make a strictly monotone inclusion, so
the admissible assignment is unique except on its boundary (``|g_c| = beta_c``
and ``b_c . x'' = 0`` at once), where the admissible ones give the same
accelerations; the first in the order "fewest sliding candidates first" is
taken (``|g| = beta`` sticks, as for one contact). For one contact the rule is
the single-contact kernel's: stick if ``|g| <= beta``, else slide with
``s = sgn g``. If rounding leaves no assignment admissible, the one of least
violation (in force units) is taken.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tasks.multicontact.layout import CX_B, CX_BETAS, CX_GINV, CX_H, CX_K, CX_P


@njit(cache=True)
def _violation(x, tau, stuck, slide_sign, ctx, fbuf, abuf):
    """Largest violation (force units) of the assignment ``stuck`` (bit mask) with
    slip signs ``slide_sign`` (0 for stuck contacts): <= 0 when admissible."""
    p = ctx[CX_P]
    K = ctx[CX_K]
    B = ctx[CX_B]
    betas = ctx[CX_BETAS]
    H = ctx[CX_H][stuck]
    n = x.shape[0]
    k = B.shape[1]
    ctau = math.cos(tau)
    for i in range(n):
        acc = p[i] * ctau
        for j in range(n):
            acc -= K[i, j] * x[j]
        for c in range(k):
            if slide_sign[c] != 0.0:
                acc -= betas[c] * slide_sign[c] * B[i, c]
        fbuf[i] = acc
    worst = -np.inf
    # stuck forces, then f - B g into fbuf's copy abuf
    for i in range(n):
        abuf[i] = fbuf[i]
    for c in range(k):
        if not (stuck >> c) & 1:
            continue
        g = 0.0
        for i in range(n):
            g += H[c, i] * fbuf[i]
        worst = max(worst, abs(g) - betas[c])
        for i in range(n):
            abuf[i] -= g * B[i, c]
    return worst


@njit(cache=True)
def _slide_violation(c, sign, ctx, abuf):
    """``-s_c b_c . G^-1 (f - B g) / (b_c^T G^-1 b_c)``: the slip acceleration of
    candidate c against its sign, in force units."""
    B = ctx[CX_B]
    Ginv = ctx[CX_GINV]
    n = abuf.shape[0]
    acc = 0.0
    norm = 0.0
    for i in range(n):
        gi = 0.0
        gb = 0.0
        for j in range(n):
            gi += Ginv[i, j] * abuf[j]
            gb += Ginv[i, j] * B[j, c]
        acc += B[i, c] * gi
        norm += B[i, c] * gb
    return -sign * acc / norm


@njit(cache=True)
def decide(x, tau, candidates, signs, ctx, new_signs):
    """The stuck set after an event (bit mask); writes the slip signs into ``new_signs``.

    ``candidates`` is the bit mask of contacts with zero velocity, ``signs`` the
    slip signs of the others (0 for candidates and inactive contacts). Returns
    ``(stuck, violation)``; ``violation <= 0`` when the choice is admissible.
    """
    k = signs.shape[0]
    n = x.shape[0]
    fbuf = np.empty(n)
    abuf = np.empty(n)
    cand = np.empty(k, dtype=np.int64)
    nc = 0
    for c in range(k):
        if (candidates >> c) & 1:
            cand[nc] = c
            nc += 1
    trial = np.empty(k)
    best_stuck = 0
    best_viol = np.inf
    best_sliding = k + 1
    total = 1
    for _ in range(nc):
        total *= 3
    for code in range(total):
        # digit 0: stuck, 1: +1, 2: -1
        for c in range(k):
            trial[c] = signs[c]
        stuck = 0
        rest = code
        n_sliding = 0
        for i in range(nc):
            digit = rest % 3
            rest //= 3
            c = cand[i]
            if digit == 0:
                stuck |= 1 << c
                trial[c] = 0.0
            else:
                trial[c] = 1.0 if digit == 1 else -1.0
                n_sliding += 1
        worst = _violation(x, tau, stuck, trial, ctx, fbuf, abuf)
        for i in range(nc):
            c = cand[i]
            if trial[c] != 0.0:
                v = _slide_violation(c, trial[c], ctx, abuf)
                # strict: a slip must start (a = 0 with |g| = beta sticks)
                if v >= 0.0:
                    v = max(v, 0.0) + 1e-300
                worst = max(worst, v)
        admissible = worst <= 0.0
        better = False
        if admissible:
            better = best_viol > 0.0 or n_sliding < best_sliding
        else:
            better = best_viol > 0.0 and worst < best_viol
        if better:
            best_viol = worst
            best_stuck = stuck
            best_sliding = n_sliding
            for c in range(k):
                new_signs[c] = trial[c]
    return best_stuck, best_viol
