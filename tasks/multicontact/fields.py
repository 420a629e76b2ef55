"""The result fields of a point with several contacts (docs/contacts.md 4): the
converged period run once more with the orbit check, the regimes per contact, the
creep rule's result, and an undetermined point."""

from __future__ import annotations

import numpy as np
from numba import njit

from tasks.kernel.layout import TWO_PI
from tasks.multicontact import creep
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
    CX_BETAS,
    CX_STICK_MIN,
    GS_STATUS,
    GS_VISCOUS,
    N_CST,
    N_GST,
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
from tasks.multicontact.section import run_period
from tasks.regimes import (
    CONTINUOUS,
    NO_MOTION,
    NOT_CONVERGED,
    NUMERICAL_FAILURE,
    SLIP_RTOL,
    STICK_SLIP,
)

#: Velocity against the slip sign tolerated by the orbit check, relative to the
#: contact's slip range (rounding of the samples next to a stop).
ORBIT_VEL_RTOL = 1e-7


@njit(cache=True)
def undetermined(out_g, out_c, code, cycles, ic):
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
def finish(X, stuck, signs, ctx, period, cycles, ic, out_g, out_c, max_work):
    """Run the converged period once more with the orbit check; write the fields."""
    k = signs.shape[0]
    cst = np.zeros((k, N_CST))
    gst = np.zeros(N_GST)
    for c in range(k):
        cst[c, CS_STICK_START] = -1e300 if (stuck >> c) & 1 else 0.0
    s = signs.copy()
    _, _, tot = run_period(X, stuck, s, cst, gst, ctx, period, max_work, True)
    if gst[GS_STATUS] != 0.0:
        undetermined(out_g, out_c, gst[GS_STATUS], cycles, ic)
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
def settle(X, stuck, signs, ctx, held, betas, period, cycles, ic, out_g, out_c, amps, max_work):
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
        undetermined(out_g, out_c, NOT_CONVERGED, cycles, ic)
        return
    for c in range(out_c.shape[0]):
        if (held >> c) & 1:
            out_c[c, OC_REGIME] = NO_MOTION
            out_c[c, OC_STOPS] = 0.0
            out_c[c, OC_AMP] = amps[c]
            out_c[c, OC_DISSIPATION] = 0.0
    out_g[OG_ASYMPTOTIC] = 1.0
