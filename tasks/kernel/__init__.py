"""Event-driven simulation of one point: cycles, Poincare section, shooting, regime.

The motion alternates between two linear systems (:mod:`tasks.model`):

* sliding with sign ``s`` (all N coordinates), until the contact velocity
  ``v = b . x'`` reaches 0. There the contact force ``g`` decides: ``|g| <= beta``
  sticks (Eqs. 11, 12, 79, 103), otherwise the slip reverses (``s = sgn g``);
* stuck (N - 1 coordinates, the contact frozen at ``d0 = b . x``), until
  ``|g|`` reaches ``beta``; the contact then slides with ``s = sgn g``.

Each phase is propagated in closed form (:mod:`~tasks.kernel.propagation`,
Eq. (1) there), each event located by a bracketed root find that skips no
zero (:mod:`~tasks.kernel.events`). Steady state is detected on the Poincare
section ``tau = 2 pi n`` (the excitation has period 2 pi): the section state
``X = (x, x')`` repeating to a relative tolerance (period 1 or 2). Slow
continuous transients are settled by Newton's method on the Poincare map
(shooting). A stick phase that provably never ends (:func:`never_unsticks`)
is the no-motion steady state.

Modules, one job each (dependencies point down the list):

* :mod:`~tasks.kernel.layout`: rows, entries and columns of the arrays passed around;
* :mod:`~tasks.kernel.propagation`: closed-form phase propagation and derivative bounds;
* :mod:`~tasks.kernel.events`: event location (:func:`next_event`, :func:`never_unsticks`);
* :mod:`~tasks.kernel.phases`: starting a slip or stick phase, its end state, the contact force;
* :mod:`~tasks.kernel.cycle`: one cycle event by event (:func:`run_cycle`), the Poincare map;
* :mod:`~tasks.kernel.starts`: held, rest and random starts, the held margin;
* :mod:`~tasks.kernel.shooting`: Newton's method on the Poincare map;
* :mod:`~tasks.kernel.acceptance`: when a fixed point is accepted (Newton's step, the
  contact's own motion, the stability radius);
* :mod:`~tasks.kernel.context`: the per-point constants and initial state;
* :mod:`~tasks.kernel.creep`: the creep rule;
* :mod:`~tasks.kernel.outcome`: writing a point's fields;
* :mod:`~tasks.kernel.orbit`: the orbit invariant;
* :mod:`~tasks.kernel.records`: recorded stretches of motion (:func:`trace_cycles`);
* :mod:`~tasks.kernel.design`: amplitudes, contact force amplitude, dissipation;
* :mod:`~tasks.kernel.point`: the steady-state search of a point from the held start
  (:func:`simulate_point`) or from a neighbour's orbit (:func:`warm_point`), the polish
  of its orbit (:func:`polish_point`);
* :mod:`~tasks.kernel.batch`: the search of many points in order (:func:`run_points`,
  with the design pass on the orbit check's replay: :func:`run_points_design`, and
  seeded by solved neighbours, best seed first: :func:`run_points_seeded`,
  :func:`run_points_given`).

Everything is compiled with numba (``cache=True``); with ``NUMBA_DISABLE_JIT=1``
the same code runs as plain Python (slowly). numba's on-disk cache checks only
the source of the file a compiled function is defined in, while a caller's
machine code contains its callees from other modules: so the whole package is
decorated inside :func:`tasks.numba_cache.kernel_cache`, which points numba at a
cache folder named by a hash of every module here (and of :mod:`tasks.regimes`,
whose constants are compiled in) and of the numba and numpy versions. An edit
anywhere gets a fresh folder (a full compile); an unchanged package reuses it.
"""

from __future__ import annotations

from tasks import numba_cache

with numba_cache.kernel_cache():
    from tasks.kernel.batch import (
        ALT_TRIES,
        run_points,
        run_points_design,
        run_points_given,
        run_points_seeded,
    )
    from tasks.kernel.context import _context
    from tasks.kernel.creep import creep_settled, creep_threshold
    from tasks.kernel.cycle import run_cycle
    from tasks.kernel.design import (
        DESIGN_DISSIPATION,
        DESIGN_FORCE,
        DESIGN_MAX_SAMPLES,
        DESIGN_SAMPLES,
        DESIGN_SCALARS,
        DESIGN_VISCOUS,
        orbit_design,
        orbit_designs,
    )
    from tasks.kernel.events import never_unsticks, next_event, stick_force_bound
    from tasks.kernel.layout import (
        CTX_B,
        CTX_BETA,
        CTX_K,
        CTX_P,
        CTX_SEG_SLIP,
        CTX_SEG_STICK,
        EV_END,
        EV_GRAZE,
        EV_REVERSAL,
        EV_SECTION,
        EV_STOP,
        EV_UNSTICK,
        N_OUT,
        OUT_AMP,
        OUT_ASYMPTOTIC,
        OUT_CONVERGED,
        OUT_CYCLES,
        OUT_IC,
        OUT_PERIOD,
        OUT_REGIME,
        OUT_STICK,
        OUT_STOPS,
        REC_G,
        REC_KIND,
        REC_MODE,
        REC_TAU,
        REC_X,
        TWO_PI,
    )
    from tasks.kernel.orbit import ORBIT_RTOL, orbit_holds
    from tasks.kernel.point import polish_point, simulate_point, warm_point
    from tasks.kernel.propagation import derivative_bounds, evaluate, event_function
    from tasks.kernel.records import sample_states, trace_cycles
    from tasks.kernel.shooting import SETTLE_CYCLES, SETTLE_PHASES, newton_settle, settle_at_phases
    from tasks.kernel.starts import _energy, held_margin, start_phase

__all__ = [
    "ALT_TRIES",
    "CTX_B",
    "CTX_BETA",
    "CTX_K",
    "CTX_P",
    "CTX_SEG_SLIP",
    "CTX_SEG_STICK",
    "DESIGN_DISSIPATION",
    "DESIGN_FORCE",
    "DESIGN_MAX_SAMPLES",
    "DESIGN_SAMPLES",
    "DESIGN_SCALARS",
    "DESIGN_VISCOUS",
    "EV_END",
    "EV_GRAZE",
    "EV_REVERSAL",
    "EV_SECTION",
    "EV_STOP",
    "EV_UNSTICK",
    "N_OUT",
    "ORBIT_RTOL",
    "OUT_AMP",
    "OUT_ASYMPTOTIC",
    "OUT_CONVERGED",
    "OUT_CYCLES",
    "OUT_IC",
    "OUT_PERIOD",
    "OUT_REGIME",
    "OUT_STICK",
    "OUT_STOPS",
    "REC_G",
    "REC_KIND",
    "REC_MODE",
    "REC_TAU",
    "REC_X",
    "SETTLE_CYCLES",
    "SETTLE_PHASES",
    "TWO_PI",
    "_context",
    "_energy",
    "creep_settled",
    "creep_threshold",
    "derivative_bounds",
    "evaluate",
    "event_function",
    "held_margin",
    "never_unsticks",
    "newton_settle",
    "next_event",
    "orbit_design",
    "orbit_designs",
    "orbit_holds",
    "polish_point",
    "run_cycle",
    "run_points",
    "run_points_design",
    "run_points_given",
    "run_points_seeded",
    "sample_states",
    "settle_at_phases",
    "simulate_point",
    "start_phase",
    "stick_force_bound",
    "trace_cycles",
    "warm_point",
]
