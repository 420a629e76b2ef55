"""Steady state of one point with several contacts, and many points (docs/contacts.md 4).

From the held start or rest, excitation cycles (:func:`tasks.multicontact.cycle.run_cycle`)
run until the section ``tau = 2 pi n`` repeats with the same stuck set and slip signs
(period 1 or 2; Newton on the Poincare map for slow transients) or every contact provably
stays stuck; the converged period is run once more with the orbit check and the design
quantities (docs/contacts.md 4).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from tasks.kernel.damping import particular
from tasks.kernel.layout import TWO_PI
from tasks.multicontact import creep, viscous
from tasks.multicontact.cycle import run_cycle
from tasks.multicontact.decide import decide
from tasks.multicontact.layout import (
    CS_DMAX,
    CS_DMIN,
    CS_FORCE_MAX,
    CS_ORBIT_ERROR,
    CS_SLIP,
    CS_STICK_START,
    CS_STOPS,
    CS_STUCK_TIME,
    CS_VEL_ERROR,
    CX_ACTIVE,
    CX_B,
    CX_BETAS,
    CX_COMPLIANCE,
    CX_G,
    CX_H,
    CX_HP,
    CX_K,
    CX_LOAD_COS,
    CX_OMEGA,
    CX_P,
    CX_R2,
    CX_SIZE,
    CX_STICK_MIN,
    CX_X,
    GS_EVENTS,
    GS_FOREVER,
    GS_STATUS,
    GS_VISCOUS,
    GS_WORK,
    N_CST,
    N_GST,
    N_OC,
    N_OG,
    OC_AMP,
    OC_DISSIPATION,
    OC_FORCE,
    OC_REGIME,
    OC_STICK,
    OC_STOPS,
    OG_ASYMPTOTIC,
    OG_CONVERGED,
    OG_CYCLES,
    OG_IC,
    OG_PERIOD,
    OG_STATUS,
    OG_VISCOUS,
)
from tasks.regimes import (
    CONTINUOUS,
    CREEP_SLIP_RTOL,
    CREEP_WINDOW,
    IC_HELD,
    IC_RANDOM,
    IC_REST,
    NO_MOTION,
    NOT_CONVERGED,
    NUMERICAL_FAILURE,
    SLIP_RTOL,
    STICK_SLIP,
    UNBOUNDED,
)

#: Relative margin above which every start reaches no motion (docs/contacts.md 4).
HELD_MARGIN_RTOL = 1e-9
#: Newton iterations per shooting attempt, and cycles between attempts.
NEWTON_ITERATIONS = 8
SHOOT_EVERY = 20
#: Velocity against the slip sign tolerated by the orbit check, relative to the
#: contact's slip range (rounding of the samples next to a stop).
ORBIT_VEL_RTOL = 1e-7
#: The polish of a converged section (:func:`polish`): residual sought (relative to
#: the section state), difference step of its Jacobian, chord steps at most.
POLISH_RTOL = 1e-14
POLISH_STEP = 1e-7
POLISH_STEPS = 4


@njit(cache=True)
def point_context(r, beta, args, settings):
    """The per-point context tuple (entries ``CX_*`` of :mod:`tasks.multicontact.layout`)."""
    (G, Ginv, K, p0, scales, B, ratio, compliance, size, lam, X, XtG, W, H, HKX, BX) = args[:16]
    C, cdiag, HCX, KinvC = args[16], args[17], args[18], args[19]
    general, Tset, Lset, Vset, Wo, damped = args[20:26]
    event_tol = settings[0]
    step_fraction = settings[1]
    max_events = settings[7]
    r2 = r * r
    p = p0 * r2 if scales else p0.copy()
    n = p.shape[0]
    k = B.shape[1]
    n_sets = size.shape[0]
    betas = ratio * beta
    active = 0
    for c in range(k):
        if betas[c] > 0.0:
            active |= 1 << c
    omega = np.zeros((n_sets, n))
    load_cos = np.zeros((n_sets, n))
    hp = np.zeros((n_sets, k))
    om_max = 1.0
    for S in range(n_sets):
        for a in range(size[S]):
            omega[S, a] = math.sqrt(max(lam[S, a], 0.0)) / r
            om_max = max(om_max, omega[S, a])
            acc = 0.0
            for i in range(n):
                acc += X[S, i, a] * p[i]
            load_cos[S, a] = acc / r2
        for c in range(k):
            acc = 0.0
            for i in range(n):
                acc += H[S, c, i] * p[i]
            hp[S, c] = acc
    events = max(float(max_events), min(8.0 * om_max, 1e9))
    if damped:  # the damping data after the compliances (tasks.multicontact.viscous)
        compliance = viscous.pack(
            compliance, r, C, cdiag, HCX, KinvC, general, Tset, Lset, Vset, Wo
        )
    return (
        G,
        Ginv,
        K,
        p,
        B,
        betas,
        active,
        size,
        X,
        XtG,
        W,
        H,
        HKX,
        BX,
        omega,
        load_cos,
        hp,
        r2,
        step_fraction,
        event_tol,
        1e3 * event_tol,
        events,
        compliance,
    )


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


@njit(cache=True)
def _period(X, stuck, signs, cst, gst, ctx, n_cycles, max_work, check):
    """Run ``n_cycles`` cycles from the section; returns the new state, set and
    the per-contact statistics summed (ranges merged) over them."""
    n = X.shape[0] // 2
    k = signs.shape[0]
    x = X[:n].copy()
    xd = X[n:].copy()
    total = np.zeros((k, N_CST))
    rec_n = np.zeros(1, dtype=np.int64)
    buf = np.zeros((0, 2 + k + 2 * n))
    viscous = 0.0
    for cyc in range(n_cycles):
        stuck = run_cycle(
            x, xd, stuck, signs, cst, gst, ctx, 0.0, TWO_PI, max_work, check, buf, rec_n
        )
        viscous += gst[GS_VISCOUS]
        gst[GS_VISCOUS] = viscous
        for c in range(k):
            cst[c, CS_STICK_START] -= TWO_PI
            for j in range(N_CST):
                if cyc == 0:
                    total[c, j] = cst[c, j]
                elif j == CS_DMIN:
                    total[c, j] = min(total[c, j], cst[c, j])
                elif j == CS_DMAX or j == CS_FORCE_MAX or j == CS_ORBIT_ERROR or j == CS_VEL_ERROR:
                    total[c, j] = max(total[c, j], cst[c, j])
                elif j != CS_STICK_START:
                    total[c, j] += cst[c, j]
        if gst[GS_STATUS] != 0.0:
            break
    out = np.empty(2 * n)
    out[:n] = x
    out[n:] = xd
    return out, stuck, total


@njit(cache=True)
def _undetermined(out_g, out_c, code, cycles, ic):
    out_g[OG_CONVERGED] = 0.0
    out_g[OG_CYCLES] = cycles
    out_g[OG_PERIOD] = 0.0
    out_g[OG_IC] = ic
    out_g[OG_STATUS] = code
    out_g[OG_VISCOUS] = np.nan
    for c in range(out_c.shape[0]):
        out_c[c, :] = np.nan
        out_c[c, OC_REGIME] = code


@njit(cache=True)
def _max_abs(v):
    acc = 0.0
    for i in range(v.shape[0]):
        acc = max(acc, abs(v[i]))
    return acc


@njit(cache=True)
def _signs_hold(X, stuck, signs, ctx):
    """Every sliding contact at the section moves in its slip direction (or has
    zero velocity to rounding): a section state the map ``P`` is defined at."""
    B = ctx[CX_B]
    n = X.shape[0] // 2
    vmax = 1e-300
    for i in range(n):
        vmax = max(vmax, abs(X[n + i]))
    for c in range(signs.shape[0]):
        if (ctx[CX_ACTIVE] >> c) & 1 and not (stuck >> c) & 1:
            v = 0.0
            for i in range(n):
                v += B[i, c] * X[n + i]
            if signs[c] * v < -1e-9 * vmax:
                return False
    return True


@njit(cache=True)
def _newton(X, stuck, signs, cst, gst, ctx, max_work, tol):
    """Newton's method on the Poincare map ``P(X) - X = 0`` (finite-difference
    Jacobian, the section's stuck set and signs kept). A fixed point is accepted
    only where the section's slip signs hold and it attracts (spectral radius of
    ``dP/dX`` at most 1 + 1e-6, as for one contact). Returns ``(X, cycles, ok)``."""
    n2 = X.shape[0]
    cycles = 0
    J = np.zeros((n2, n2))
    have_j = False
    for _ in range(NEWTON_ITERATIONS):
        if not _signs_hold(X, stuck, signs, ctx):
            return X, cycles, False
        s0 = signs.copy()
        P0, _, _ = _period(X, stuck, s0, cst, gst, ctx, 1, max_work, False)
        cycles += 1
        if gst[GS_STATUS] != 0.0:
            return X, cycles, False
        F0 = P0 - X
        scale = max(_max_abs(X), 1e-300)
        if _max_abs(F0) <= tol * scale:
            if not have_j:
                return X, cycles, True
            A = J.astype(np.complex128)
            for i in range(n2):
                A[i, i] += 1.0
            rho = np.max(np.abs(np.linalg.eigvals(A)))
            return X, cycles, rho <= 1.0 + 1e-6
        h = 1e-7 * scale
        for i in range(n2):
            Xp = X.copy()
            Xp[i] += h
            s1 = signs.copy()
            Pi, _, _ = _period(Xp, stuck, s1, cst, gst, ctx, 1, max_work, False)
            cycles += 1
            if gst[GS_STATUS] != 0.0:
                return X, cycles, False
            for j in range(n2):
                J[j, i] = (Pi[j] - P0[j]) / h
            J[i, i] -= 1.0
        have_j = True
        # least squares: a stuck coordinate's displacement is carried over
        # unchanged (a zero column of J - I), the step leaves it alone
        dX = np.linalg.lstsq(J, -F0)[0]
        if not np.all(np.isfinite(dX)):
            return X, cycles, False
        X = X + dX
    return X, cycles, False


@njit(cache=True)
def _map(X, stuck, signs, ctx, period, max_work):
    """``(P^period(X), same)``: ``same`` when the period ran without a fault and
    ended in the section's stuck set and slip signs (the branch of the map)."""
    k = signs.shape[0]
    cst = np.zeros((k, N_CST))
    gst = np.zeros(N_GST)
    s = signs.copy()
    PX, st, _ = _period(X, stuck, s, cst, gst, ctx, period, max_work, False)
    same = gst[GS_STATUS] == 0.0 and st == stuck and np.all(s == signs)
    return PX, same


@njit(cache=True)
def polish(X, stuck, signs, ctx, period, max_work):
    """The fixed point of ``P^period`` next to a converged section state ``X``,
    to ``POLISH_RTOL`` (docs/contacts.md 4).

    The plain iteration stops when two sections agree to ``section_rtol``; the
    fixed point is then that close but no closer (slow points: further). A
    chord Newton step (Jacobian of ``P^period - I`` by forward differences,
    once; least squares, so a contact stuck through the period keeps its
    position) is repeated while it shrinks the residual, at most
    ``POLISH_STEPS`` times. The section's stuck set and signs must hold for
    every evaluation; else (or if nothing shrinks) ``X`` is returned as it came.
    """
    n2 = X.shape[0]
    P0, same = _map(X, stuck, signs, ctx, period, max_work)
    if not same:
        return X
    F = P0 - X
    scale = max(_max_abs(X), 1e-300)
    res = _max_abs(F)
    if res <= POLISH_RTOL * scale:
        return X
    J = np.zeros((n2, n2))
    h = POLISH_STEP * scale
    for i in range(n2):
        Xp = X.copy()
        Xp[i] += h
        Pi, same = _map(Xp, stuck, signs, ctx, period, max_work)
        if not same:
            return X
        for j in range(n2):
            J[j, i] = (Pi[j] - P0[j]) / h
        J[i, i] -= 1.0
    best = X
    for _ in range(POLISH_STEPS):
        dX = np.linalg.lstsq(J, -F)[0]
        if not np.all(np.isfinite(dX)):
            break
        Xn = best + dX
        Pn, same = _map(Xn, stuck, signs, ctx, period, max_work)
        if not same:
            break
        Fn = Pn - Xn
        rn = _max_abs(Fn)
        if rn >= res:
            break
        best = Xn
        F = Fn
        res = rn
        if res <= POLISH_RTOL * scale:
            break
    return best


@njit(cache=True)
def _finish(X, stuck, signs, ctx, period, cycles, ic, out_g, out_c, max_work):
    """Run the converged period once more with the orbit check; write the fields."""
    k = signs.shape[0]
    cst = np.zeros((k, N_CST))
    gst = np.zeros(N_GST)
    for c in range(k):
        cst[c, CS_STICK_START] = -1e300 if (stuck >> c) & 1 else 0.0
    s = signs.copy()
    _, _, tot = _period(X, stuck, s, cst, gst, ctx, period, max_work, True)
    if gst[GS_STATUS] != 0.0:
        _undetermined(out_g, out_c, gst[GS_STATUS], cycles, ic)
        return
    out_g[OG_CONVERGED] = 1.0
    out_g[OG_CYCLES] = cycles
    out_g[OG_PERIOD] = period
    out_g[OG_IC] = ic
    out_g[OG_STATUS] = 0.0
    out_g[OG_VISCOUS] = gst[GS_VISCOUS] / period
    betas = ctx[CX_BETAS]
    active = ctx[CX_ACTIVE]
    span = TWO_PI * period
    asymptotic = False
    for c in range(k):
        slip_range = tot[c, CS_DMAX] - tot[c, CS_DMIN]
        out_c[c, OC_AMP] = 0.5 * slip_range
        out_c[c, OC_STICK] = tot[c, CS_STUCK_TIME] / span
        out_c[c, OC_DISSIPATION] = betas[c] * tot[c, CS_SLIP] / period
        out_c[c, OC_FORCE] = tot[c, CS_FORCE_MAX]
        out_c[c, OC_STOPS] = tot[c, CS_STOPS]
        if not (active >> c) & 1:
            out_c[c, OC_REGIME] = CONTINUOUS  # no friction: free sliding (beta_c = 0)
            out_c[c, OC_STICK] = 0.0
            out_c[c, OC_FORCE] = 0.0
            continue
        bad = tot[c, CS_ORBIT_ERROR] > 1e-9 or tot[c, CS_VEL_ERROR] > ORBIT_VEL_RTOL * (
            slip_range + 1e-12
        )
        if bad:
            out_g[OG_CONVERGED] = 0.0
            out_g[OG_STATUS] = NUMERICAL_FAILURE
            out_c[c, OC_REGIME] = NUMERICAL_FAILURE
            continue
        if tot[c, CS_STUCK_TIME] >= span - ctx[CX_STICK_MIN]:
            out_c[c, OC_REGIME] = NO_MOTION
        elif tot[c, CS_STOPS] > 0.0:
            if 0.5 * slip_range < SLIP_RTOL * betas[c] * creep.creep_compliance(ctx, c):
                # a stick-slip below the creep threshold: held (tasks.kernel.creep)
                out_c[c, OC_REGIME] = NO_MOTION
                out_c[c, OC_STOPS] = 0.0
                asymptotic = True
            else:
                out_c[c, OC_REGIME] = STICK_SLIP
        else:
            out_c[c, OC_REGIME] = CONTINUOUS
    out_g[OG_ASYMPTOTIC] = 1.0 if asymptotic else 0.0


@njit(cache=True)
def _settle(X, stuck, signs, ctx, held, betas, period, cycles, ic, out_g, out_c, amps, max_work):
    """The creep rule's result (docs/contacts.md 4): the contacts ``held`` (``-1``: every
    contact, already certified by the stuck structure's bound) reach no motion,
    ``asymptotic``, their last creeping cycle's slip amplitude kept as a diagnostic
    (``ctx`` holds them: the period found is the others' steady state). The others'
    orbit must certify the held ones (:func:`tasks.multicontact.creep.swing_certified`);
    else the point is ``not_converged`` (flagged, never guessed). Nothing held: nothing."""
    if held == 0 or out_g[OG_CONVERGED] == 0.0:
        return
    if held < 0:
        held = ctx[CX_ACTIVE]
    elif not creep.swing_certified(X, stuck, signs, ctx, held, betas, period, max_work):
        _undetermined(out_g, out_c, NOT_CONVERGED, cycles, ic)
        return
    for c in range(out_c.shape[0]):
        if (held >> c) & 1:
            out_c[c, OC_REGIME] = NO_MOTION
            out_c[c, OC_STOPS] = 0.0
            out_c[c, OC_AMP] = amps[c]
            out_c[c, OC_DISSIPATION] = 0.0
    out_g[OG_ASYMPTOTIC] = 1.0


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


@njit(cache=True)
def simulate_point(r, beta, args, settings, out_g, out_c):
    """Steady state of one point: fills ``out_g`` (``OG_*``) and ``out_c`` (``OC_*``,
    one row per contact). Returns the section state ``(X, stuck, signs, held)`` of
    the steady state found (of the last cycle run where none was found), ``held``
    the contacts the creep rule held (:func:`tasks.multicontact.creep.held_context`)
    in the run that found it (0: none): its orbit is that of ``ctx`` holding them."""
    section_rtol = settings[2]
    max_cycles = settings[3]
    min_cycles = settings[4]
    shooting = settings[5]
    shooting_after = settings[6]
    growth_factor = settings[8]
    ic = settings[9]
    max_work = settings[10]
    ctx = point_context(r, beta, args, settings)
    k = ctx[CX_BETAS].shape[0]
    out_g[OG_ASYMPTOTIC] = 0.0
    X, stuck, signs, used = start_state(ctx, ic, r, beta, int(settings[11]))
    margins = np.zeros(k)
    if ctx[CX_ACTIVE] == 0:  # no friction anywhere: linear, continuous unless resonant
        Xf, exists = held_response(ctx, 0)
        if not exists:
            _undetermined(out_g, out_c, UNBOUNDED, 0, used)
            return X, stuck, signs, 0
        _finish(Xf, 0, np.zeros(k), ctx, 1, 0, used, out_g, out_c, max_work)
        return Xf, 0, np.zeros(k), 0
    if used != IC_HELD and held_margins(ctx, margins):
        Xh, _ = held_response(ctx, ctx[CX_ACTIVE])
        _finish(Xh, ctx[CX_ACTIVE], np.zeros(k), ctx, 1, 0, used, out_g, out_c, max_work)
        out_g[OG_ASYMPTOTIC] = 1.0
        return Xh, ctx[CX_ACTIVE], np.zeros(k), 0
    cst = np.zeros((k, N_CST))
    gst = np.zeros(N_GST)
    for c in range(k):
        cst[c, CS_STICK_START] = -1e300 if (stuck >> c) & 1 else 0.0
    ref = max(_max_abs(X), _max_abs(np.linalg.solve(ctx[CX_K], ctx[CX_P])), 1e-300)
    X1 = X.copy()
    X2 = X.copy()
    st1 = stuck
    st2 = stuck
    sg1 = signs.copy()
    sg2 = signs.copy()
    cycles = 0
    work = 0.0
    next_shot = shooting_after
    # the creep rule (tasks.multicontact.creep): per-contact runs, the stuck
    # structure's window (as one contact's), the contacts it holds, their last slips
    runs = np.zeros((k, 3), dtype=np.int64)
    prev_drift = np.zeros(k, dtype=np.int64)
    drift = np.zeros(k)
    small_run = 0
    quiet_run = 0
    held = 0
    refused = 0  # creeps the cycle at hand did not certify
    betas = ctx[CX_BETAS]
    amps = np.zeros(k)
    period = 0  # of the steady state found
    while cycles < max_cycles:
        s_before = signs.copy()
        st_before = stuck
        Xn, stuck, tot = _period(X, stuck, signs, cst, gst, ctx, 1, max_work - work, False)
        cycles += 1
        work += gst[GS_WORK]
        if gst[GS_STATUS] != 0.0:
            _undetermined(out_g, out_c, gst[GS_STATUS], cycles, used)
            return X, stuck, signs, held
        if gst[GS_FOREVER] > 0.0:  # every contact stuck for ever: no motion
            stuck = st_before
            signs = s_before
            period = 1
            break
        if held == 0:
            small = True
            for c in range(k):
                amps[c] = 0.5 * (tot[c, CS_DMAX] - tot[c, CS_DMIN])
                if (ctx[CX_ACTIVE] >> c) & 1:
                    small &= amps[c] < CREEP_SLIP_RTOL * betas[c] * ctx[CX_COMPLIANCE][c]
            small_run = small_run + 1 if small else 0
            quiet_run = (
                quiet_run + 1 if small and gst[GS_EVENTS] == 0.0 else (quiet_run if small else 0)
            )
            prev_drift[:] = runs[:, 2]
            held = creep.update(X, Xn, stuck, tot, ctx, runs, drift, refused)
            # most of the window without an event, or every contact drifting one way
            # through it (a creep in progress at each: no orbit of any period)
            if (
                small_run >= CREEP_WINDOW
                and (2 * quiet_run > small_run or held == ctx[CX_ACTIVE])
                and creep.all_stuck_settled(Xn, stuck, signs, ctx)
            ):  # the stuck structure settles as one contact does: hold it, finish
                hctx = creep.held_context(ctx, ctx[CX_ACTIVE])
                _finish(Xn, stuck, signs, hctx, 1, cycles, used, out_g, out_c, max_work)
                _settle(
                    Xn, stuck, signs, hctx, -1, betas, 1, cycles, used, out_g, out_c, amps, max_work
                )
                return Xn, stuck, signs, ctx[CX_ACTIVE]
            if held == ctx[CX_ACTIVE]:
                held = 0  # every contact creeps: the stuck structure's window decides
            if held != 0 and not creep.swing_certified(
                Xn, stuck, signs, creep.held_context(ctx, held), held, betas, 1, max_work
            ):  # not certified on the cycle at hand: the creep keeps running as it is
                refused |= held
                held = 0
            if held != 0:  # others move: continue with the creeping contacts held
                ctx = creep.held_context(ctx, held)
                runs[:, 2] = 0
                prev_drift[:] = 0
                X1 = Xn + 1e300
                X2 = X1
                next_shot = cycles + shooting_after
                X = Xn
                continue
        X2 = X1
        st2 = st1
        sg2 = sg1
        X1 = X
        st1 = st_before
        sg1 = s_before
        X = Xn
        scale = max(_max_abs(X), 1e-300)
        if scale > growth_factor * ref:
            _undetermined(out_g, out_c, UNBOUNDED, cycles, used)
            return X, stuck, signs, held
        # a contact drifting one way (creep.update) over the period: no steady state,
        # whatever the tolerance
        drifts = np.any(runs[:, 2] != 0)
        drifts2 = np.any((runs[:, 2] != 0) & (runs[:, 2] == prev_drift))
        if cycles >= min_cycles:
            if stuck == st1 and not drifts and np.all(signs == sg1):
                if _max_abs(X - X1) <= section_rtol * scale:
                    period = 1
                    break
            if stuck == st2 and not drifts2 and np.all(signs == sg2):
                if _max_abs(X - X2) <= section_rtol * scale:
                    period = 2
                    break
        # a contact creeping in one direction: no fixed point on this branch (its
        # relative displacement drifts), Newton would only spend the cycles it needs
        if shooting and cycles >= next_shot and not creep.creeping(runs, refused):
            Xs, used_cycles, ok = _newton(
                X.copy(), stuck, signs.copy(), cst.copy(), gst, ctx, max_work, section_rtol
            )
            cycles += used_cycles
            next_shot = cycles + SHOOT_EVERY  # 20 cycles of iteration between attempts
            gst[GS_STATUS] = 0.0
            if ok:
                X = Xs
                X1 = Xs + 1e300  # the plain test must see the fixed point repeat
                X2 = X1
    if period == 0:
        _undetermined(out_g, out_c, NOT_CONVERGED, cycles, used)
        return X, stuck, signs, held
    if gst[GS_FOREVER] == 0.0:
        X = polish(X, stuck, signs, ctx, period, max_work)
    _finish(X, stuck, signs, ctx, period, cycles, used, out_g, out_c, max_work)
    _settle(X, stuck, signs, ctx, held, betas, period, cycles, used, out_g, out_c, amps, max_work)
    return X, stuck, signs, held


@njit(cache=True, parallel=False)
def run_points(r, beta, args, settings):
    """Every point: ``(out_g (n, N_OG), out_c (n, k, N_OC))``."""
    npts = r.shape[0]
    k = args[5].shape[1]
    out_g = np.zeros((npts, N_OG))
    out_c = np.zeros((npts, k, N_OC))
    for i in prange(npts):
        simulate_point(r[i], beta[i], args, settings, out_g[i], out_c[i])
    return out_g, out_c


@njit(cache=True)
def record_orbit(r, beta, args, settings, max_rows):
    """The steady state of one point and its last period, phase by phase:
    ``(out_g, out_c, rec, rows)``, ``rec`` rows ``(tau, stuck, signs, x, x')`` at
    every phase start of the period (and its end), for tests and figures. The period
    is the accepted orbit's: run with the contacts the creep rule held held
    (docs/contacts.md 4), as :func:`simulate_point` found it."""
    k = args[5].shape[1]
    n = args[3].shape[0]
    out_g = np.zeros(N_OG)
    out_c = np.zeros((k, N_OC))
    X, stuck, signs, held = simulate_point(r, beta, args, settings, out_g, out_c)
    ctx = point_context(r, beta, args, settings)
    if held != 0:  # the orbit accepted: with the creeping contacts held
        ctx = creep.held_context(ctx, held)
    rec = np.zeros((max_rows, 2 + k + 2 * n))
    period = max(int(out_g[OG_PERIOD]), 1)
    cst = np.zeros((k, N_CST))
    gst = np.zeros(N_GST)
    rec_n = np.zeros(1, dtype=np.int64)
    x = X[:n].copy()
    xd = X[n:].copy()
    s = signs.copy()
    for _ in range(period):
        stuck = run_cycle(
            x, xd, stuck, s, cst, gst, ctx, 0.0, TWO_PI, settings[10], False, rec, rec_n
        )
    return out_g, out_c, rec, rec_n[0]
