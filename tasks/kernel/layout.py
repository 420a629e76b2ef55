"""Layouts of the arrays and tuples the kernel's functions pass around.

numba compiles module-level integers as constants, so these names cost nothing
at run time: they only name the rows, entries and columns below.
"""

from __future__ import annotations

import math

#: numba options of the kernel's leaf functions (they allocate and return no array):
#: compiled without numba's reference counting (``_nrt=False``), so a call that
#: passes arrays costs no atomic reference-count operations (two per array and
#: call otherwise, which cost as much as evaluating a phase). The same operations,
#: so the same values to the last bit; a leaf that allocated would not compile.
LEAF = {"cache": True, "_nrt": False}

#: One excitation period (the excitation is ``cos(tau)``).
TWO_PI = 2.0 * math.pi

# Rows of the per-mode segment array ``seg`` (shape (N_ROWS, m)), the data of one
# phase in its modal coordinates (tasks.kernel.propagation, Eq. (1)).
# DAMP is the modal decay rate sigma (eta'' + 2 sigma eta' + ..., tasks.kernel.damping);
# zero for every mode of an undamped scene.
# ETAD_OFF: the constant part o of eta' = xi + o of a pair of general (non-proportional)
# damping (tasks.damped_pairs, docs/structures.md 4.5); unused otherwise.
OMEGA, ETA0, ETAD0, LOAD_COS, LOAD_CONST, ALPHA, DELTA, DAMP, ETAD_OFF = range(9)
N_ROWS = 9
# Entries of the scalar segment array ``sc``. DAMPED: 1.0 when the scene is damped
# (both phases then take tasks.kernel.damping), 0.0 for the undamped code path.
# LAST_T, LAST_Y: the time after the phase start of the state last written by the event
# search (tasks.kernel.events) into the phase's modal arrays, and the observable there
# (NaN: none), so that the state at a located event is not computed twice.
(TAU0, COS_TAU0, SIN_TAU0, OBS_COS, OBS0, KIND, SIGN, BETA, EVALS, WORK_CAP, DAMPED) = range(11)
LAST_T, LAST_Y = 11, 12
# COMPLIANCE, FLOOR: per-point constants of a scene whose damping is not proportional
# (damped pairs, docs/structures.md 4.5; 0.0 otherwise), from the undamped modes of
# (K, Gamma) (tasks.kernel.context._context): the contact's compliance at the
# excitation frequency, sum_k (b . phi_k)^2 / max(lambda_k, r^2), of the creep
# threshold (tasks.kernel.creep.creep_threshold), and the largest entry of the
# motion floor's response (tasks.kernel.context.motion_floor). Real modes compute
# both from the modes themselves.
COMPLIANCE, FLOOR = 13, 14
N_SCALARS = 15
KIND_SLIP = 0.0
KIND_STICK = 1.0

# Entries of the per-point context tuple ``ctx`` (built by tasks.kernel.context._context).
CTX_SEG_SLIP = 0
CTX_SEG_STICK = 1
CTX_SC = 2
CTX_BETA = 3
CTX_P = 4
CTX_K = 5
CTX_B = 6
CTX_W = 7
CTX_T = 8
CTX_PHI = 9
CTX_PHI_T_GAMMA = 10
CTX_PHI_S = 11
CTX_PHI_S_T_GAMMA_S = 12
CTX_PROJ = 13
CTX_F_R2 = 14
CTX_DSTAT_R2 = 15
CTX_G_LOAD = 16
CTX_G_COS = 17
CTX_G_D0 = 18
CTX_H_SLIP = 19
CTX_H_STICK = 20
CTX_TOL = 21
CTX_STICK_MIN = 22
CTX_MAX_EVENTS = 23
CTX_MAX_WORK = 24
CTX_G_C = 25  # r C^T g_load: the viscous part of the contact force is -CTX_G_C . x'

# Entries of the per-cycle statistics array.
(
    ST_STOPS,
    ST_REVERSALS,
    ST_STUCK_TIME,
    ST_DMIN,
    ST_DMAX,
    ST_FOREVER,
    ST_EVENTS,
    ST_STATUS,
    ST_MID,
    ST_LONGEST,
) = range(10)
N_STATS = 10
STATUS_OK = 0.0

# Event records (tasks.trajectory): kinds and columns of the record buffer.
EV_SECTION, EV_STOP, EV_REVERSAL, EV_UNSTICK, EV_GRAZE, EV_END = 0.0, 1.0, 2.0, 3.0, 4.0, 5.0
REC_TAU, REC_KIND, REC_MODE, REC_G, REC_X = range(5)

# Fields of the per-point output array (see tasks.result.FIELDS).
OUT_REGIME, OUT_CONVERGED, OUT_CYCLES, OUT_STOPS, OUT_AMP, OUT_STICK, OUT_PERIOD, OUT_IC = range(8)
OUT_ASYMPTOTIC = 8
N_OUT = 9
