"""The event search's shortcuts and the sampled range of a phase (tasks.kernel.events,
tasks.kernel.propagation).

Truths: the closed form itself (:func:`tasks.kernel.propagation.evaluate`) at the
same times, and the first zero of the event function located independently by
dense sampling and scipy's ``brentq`` on the same closed form.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from tasks import Scene
from tasks.classifier import settings_args
from tasks.fidelity import resolve
from tasks.kernel import _context, evaluate
from tasks.kernel.events import DIP_STACK, next_event
from tasks.kernel.layout import (
    BETA,
    COS_TAU0,
    ETA0,
    ETAD0,
    KIND,
    KIND_SLIP,
    KIND_STICK,
    LAST_T,
    LAST_Y,
    OBS0,
    SIGN,
    SIN_TAU0,
    WORK_CAP,
)
from tasks.kernel.propagation import evaluate_start, observable_range
from tasks.model import scene_modes

SCENES = [Scene("ground", 2, 1, gamma=1.0, kappa=0.5), Scene("ground", 5, 2)]


def _phases(scene: Scene, rng: np.random.Generator, count: int):
    """Random slip and stick phases ``(seg, sc, h)`` of the scene at a few r, one
    mode at resonance among them."""
    args = scene_modes(scene).kernel_args()
    settings = settings_args(resolve("balanced"))
    for r in (0.3, 1.1, float(np.sqrt(args[5][0]))):
        ctx = _context(r, 0.4, args, settings)[0]
        h_slip, h_stick = ctx[19], ctx[20]
        for _ in range(count):
            for seg0, h, kind in ((ctx[0], h_slip, KIND_SLIP), (ctx[1], h_stick, KIND_STICK)):
                seg, sc = seg0.copy(), ctx[2].copy()
                m = seg.shape[1]
                seg[ETA0] = rng.normal(size=m)
                seg[ETAD0] = rng.normal(size=m)
                tau0 = rng.uniform(0.0, 2.0 * np.pi)
                sc[COS_TAU0], sc[SIN_TAU0] = np.cos(tau0), np.sin(tau0)
                sc[KIND] = kind
                sc[SIGN] = 1.0 if kind == KIND_SLIP else 0.0
                sc[BETA] = 0.4
                sc[WORK_CAP] = 1e9
                # the observable at the start: a slip phase's contact velocity, or g
                sc[OBS0] = rng.normal() if kind == KIND_SLIP else rng.uniform(-0.3, 0.3)
                if kind == KIND_SLIP:
                    sc[OBS0] = abs(sc[OBS0])
                yield seg, sc, h


@pytest.mark.parametrize("scene", SCENES)
def test_the_start_value_is_the_closed_form_at_zero_to_the_last_bit(scene):
    rng = np.random.default_rng(3)
    for seg, sc, _ in _phases(scene, rng, 6):
        m = seg.shape[1]
        a, ad, b, bd = (np.zeros(m) for _ in range(4))
        assert evaluate_start(seg, sc, a, ad) == evaluate(seg, sc, 0.0, b, bd)
        assert np.array_equal(a, b) and np.array_equal(ad, bd)


def _first_zero(seg, sc, t_end: float) -> float:
    """The first zero of the event function in (0, t_end], found independently: the
    first sign change on a fine grid, refined by brentq (nan if none)."""
    m = seg.shape[1]
    eta, etad = np.zeros(m), np.zeros(m)

    def f(t: float) -> float:
        y = evaluate(seg, sc, t, eta, etad)[0]
        return sc[SIGN] * y if sc[KIND] == KIND_SLIP else sc[BETA] - abs(y)

    ts = np.linspace(0.0, t_end, 20001)[1:]
    vals = np.array([f(t) for t in ts])
    below = np.flatnonzero(vals <= 0.0)
    if below.size == 0:
        return math.nan
    i = below[0]
    lo = ts[i - 1] if i > 0 else 0.0
    if f(lo) <= 0.0:
        return lo
    return brentq(f, lo, ts[i], xtol=1e-15, rtol=1e-15)


@pytest.mark.parametrize("scene", SCENES)
def test_located_events_and_the_state_left_at_them(scene):
    """next_event finds the first zero to the event tolerance (from its far side),
    and the state it leaves in the modal arrays is the closed form at ``sc[LAST_T]``
    to the last bit."""
    rng = np.random.default_rng(11)
    tol = 1e-12
    stack = np.zeros((DIP_STACK, 6))
    found_any = 0
    for seg, sc, h in _phases(scene, rng, 8):
        m = seg.shape[1]
        eta, etad = np.zeros(m), np.zeros(m)
        t_end = 2.0 * np.pi
        t, found = next_event(seg, sc, t_end, h, tol, eta, etad, stack)
        want = _first_zero(seg, sc, t_end)
        if found:  # on the far side of the first zero, within the tolerance
            found_any += 1
            assert -1e-14 <= t - want <= tol + 1e-14
        else:
            assert not math.isfinite(want)
        e2, ed2 = np.zeros(m), np.zeros(m)
        y, _ = evaluate(seg, sc, sc[LAST_T], e2, ed2)
        assert y == sc[LAST_Y]
        assert np.array_equal(eta, e2) and np.array_equal(etad, ed2)
    assert found_any >= 10


@pytest.mark.parametrize("scene", SCENES)
@pytest.mark.parametrize("n", [2, 17, 4096])
def test_observable_range_by_rotation_matches_the_closed_form(scene, n):
    """The uniformly sampled range of the observable (rotations, re-anchored every
    ANCHOR samples) against the closed form evaluated at every sample."""
    rng = np.random.default_rng(5)
    scratch = np.zeros((DIP_STACK, 6))
    for seg, sc, _ in _phases(scene, rng, 3):
        m = seg.shape[1]
        eta, etad = np.zeros(m), np.zeros(m)
        dt = rng.uniform(0.5, 8.0) / (n + 1)
        ys = np.array([evaluate(seg, sc, i * dt, eta, etad)[0] for i in range(1, n + 1)])
        ymin, ymax, finite = observable_range(seg, sc, dt, n, eta, etad, scratch)
        scale = np.abs(ys).max() + np.abs(seg[ETA0]).sum() + np.abs(seg[ETAD0]).sum()
        assert finite
        assert abs(ymin - ys.min()) <= 1e-13 * scale
        assert abs(ymax - ys.max()) <= 1e-13 * scale
        # too few scratch rows: every sample evaluated, the same values exactly
        assert observable_range(seg, sc, dt, n, eta, etad, scratch[: m - 1]) == (
            ys.min(),
            ys.max(),
            True,
        )
