"""Layouts of the arrays the several-contact simulator passes around (numba constants)."""

from __future__ import annotations

# Entries of the per-point context tuple (tasks.multicontact.cycle.point_context).
(
    CX_G,
    CX_GINV,
    CX_K,
    CX_P,
    CX_B,
    CX_BETAS,
    CX_ACTIVE,
    CX_SIZE,
    CX_X,
    CX_XTG,
    CX_W,
    CX_H,
    CX_HKX,
    CX_BX,
    CX_OMEGA,
    CX_LOAD_COS,
    CX_HP,
    CX_R2,
    CX_STEP,
    CX_TOL,
    CX_STICK_MIN,
    CX_MAX_EVENTS,
    CX_COMPLIANCE,
) = range(23)
# CX_COMPLIANCE holds b_c^T K^-1 b_c of each contact (k entries) and, in a damped
# scene only, the flat damping data after them (tasks.multicontact.viscous, docs/contacts.md
# 7): longer than k means damped. So an undamped scene's context is what it was, entry
# for entry (every array of the context costs reference counting on each call).

# Columns of the per-contact statistics of a run (shape (k, N_CST)).
(
    CS_STOPS,
    CS_REVERSALS,
    CS_STUCK_TIME,
    CS_DMIN,
    CS_DMAX,
    CS_SLIP,
    CS_FORCE_MAX,
    CS_STICK_START,
    CS_ORBIT_ERROR,
    CS_VEL_ERROR,
) = range(10)
N_CST = 10

# Entries of the global statistics of a run.
# GS_VISCOUS: the viscous dissipation, integral of r x'^T C x' (checked runs of a damped scene).
GS_EVENTS, GS_STATUS, GS_FOREVER, GS_WORK, GS_VISCOUS = range(5)
N_GST = 5

# Columns of the per-point global output.
OG_CONVERGED, OG_CYCLES, OG_PERIOD, OG_IC, OG_STATUS, OG_ASYMPTOTIC, OG_VISCOUS = range(7)
N_OG = 7
# Columns of the per-point, per-contact output.
OC_REGIME, OC_STOPS, OC_AMP, OC_STICK, OC_DISSIPATION, OC_FORCE = range(6)
N_OC = 6
