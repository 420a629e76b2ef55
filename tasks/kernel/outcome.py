"""Writing a point's result: the fields of a converged period, or an undetermined code.

Columns ``OUT_*`` of :mod:`tasks.kernel.layout` (the fields of
:data:`tasks.result.FIELDS`); regime codes of :mod:`tasks.regimes`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from tasks.kernel.layout import (
    OUT_AMP,
    OUT_ASYMPTOTIC,
    OUT_CONVERGED,
    OUT_CYCLES,
    OUT_IC,
    OUT_PERIOD,
    OUT_REGIME,
    OUT_STICK,
    OUT_STOPS,
    ST_DMAX,
    ST_DMIN,
    ST_EVENTS,
    ST_STOPS,
    ST_STUCK_TIME,
    TWO_PI,
)
from tasks.regimes import CONTINUOUS, NO_MOTION, STICK_SLIP


@njit(cache=True)
def _finish(out, stats, stats_prev, period, cycles, ic_used):
    """Regime, stops, amplitude and stick fraction of a converged period."""
    stops = stats[ST_STOPS]
    stuck = stats[ST_STUCK_TIME]
    dmin = stats[ST_DMIN]
    dmax = stats[ST_DMAX]
    moved = stats[ST_EVENTS] > 0.0 or stuck < TWO_PI * (1.0 - 1e-12)
    if period == 2:
        stops += stats_prev[ST_STOPS]
        stuck += stats_prev[ST_STUCK_TIME]
        dmin = min(dmin, stats_prev[ST_DMIN])
        dmax = max(dmax, stats_prev[ST_DMAX])
        moved = moved or stats_prev[ST_EVENTS] > 0.0
    if not moved:
        regime = NO_MOTION
    elif stops > 0.0:
        regime = STICK_SLIP
    else:
        regime = CONTINUOUS
    out[OUT_REGIME] = regime
    out[OUT_CONVERGED] = 1.0
    out[OUT_CYCLES] = cycles
    out[OUT_STOPS] = stops
    out[OUT_AMP] = 0.5 * (dmax - dmin) if moved else 0.0
    out[OUT_STICK] = stuck / (TWO_PI * period)
    out[OUT_PERIOD] = period
    out[OUT_IC] = ic_used


@njit(cache=True)
def _undetermined(out, code, cycles, ic_used):
    out[OUT_REGIME] = code
    out[OUT_CONVERGED] = 0.0
    out[OUT_CYCLES] = cycles
    out[OUT_STOPS] = 0.0
    out[OUT_AMP] = np.nan
    out[OUT_STICK] = np.nan
    out[OUT_PERIOD] = 0.0
    out[OUT_IC] = ic_used


@njit(cache=True)
def _no_motion_by_margin(out, ic_used):
    """No motion reached from a start off the held steady state, decided by
    :func:`held_margin` without simulating (``cycles = 0``, flagged asymptotic)."""
    out[OUT_REGIME] = NO_MOTION
    out[OUT_CONVERGED] = 1.0
    out[OUT_CYCLES] = 0.0
    out[OUT_STOPS] = 0.0
    out[OUT_AMP] = 0.0
    out[OUT_STICK] = 1.0
    out[OUT_PERIOD] = 1.0
    out[OUT_IC] = ic_used
    out[OUT_ASYMPTOTIC] = 1.0
