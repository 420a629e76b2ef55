"""An exact resonance of an unloaded held mode: the absorber's held state.

Where the excitation's frequency equals that of an undamped mode of the held system
that the load does not reach (a vibration absorber tuned to it), the held steady
states are a family, and one of them, the absorber's, needs no contact force at all:
the free vibration of that mode cancels the force on the contact mass. By the energy
argument of docs/theory.md 3 (with that member as x_h and margin beta), every start
then reaches no motion, whatever beta > 0, although the motion bound of the member
without the free vibration (and of the points either side) is finite; the closed
form's motion bound is 0 there. The simulator had no such
member: the 6DOF point r = 1 was ``work_limit`` (a creep of about 1 s per point)
or ``not_converged``.
"""

from __future__ import annotations

import numpy as np
import pytest

from analysis import closed_form
from tasks import Scene, classify, regimes
from tasks.model import scene_modes

#: (scene, the r of an unloaded held mode's resonance), with the modal load exactly 0
SCENES = [
    (Scene("ground", dof=2, contact_mass=1), 1.0),
    (Scene("ground", dof=3, contact_mass=2), 1.0),
    (Scene("ground", dof=6, contact_mass=5), 1.0),
]


def _unloaded_resonance(scene: Scene, r: float) -> bool:
    m = scene_modes(scene)
    k = np.argmin(np.abs(m.lam_s - r * r))
    return abs(m.lam_s[k] - r * r) < 1e-12 and abs(m.load_s[k] @ m.p0) < 1e-12


@pytest.mark.parametrize(("scene", "r"), SCENES, ids=lambda v: str(v)[:40])
def test_every_start_reaches_no_motion_at_an_unloaded_held_resonance(scene, r):
    """Below the motion bound of the member without free vibration (finite there),
    from the held, the rest and random starts: no motion, converged, at r exactly
    and one unit of roundoff either side (a grid's r = 1)."""
    assert _unloaded_resonance(scene, r)
    bound = closed_form.motion_bound(scene, np.array([r * (1 + 1e-9)]))
    assert 0.5 < bound[0] < np.inf  # the bound of the member A = 0: motion below it
    beta = bound[0] * np.array([0.01, 0.1, 0.4, 0.9])
    rs = np.array([np.nextafter(r, 0.0), r, np.nextafter(r, 2.0)])
    rr, bb = (a.ravel() for a in np.meshgrid(rs, beta, indexing="ij"))
    res = classify(scene, rr, bb, starts=("held", "rest"), n_random=2)
    assert np.all(res.regime == regimes.NO_MOTION), res.regime
    assert np.all(res.converged)
    assert not np.any(res.start_dependent)
    assert np.all(res.cycles <= 1)  # the held start is proved stuck in its first cycle


def test_away_from_the_resonance_the_bound_holds():
    """The same scene 1e-3 off the resonance: stick-slip below the motion bound (the
    absorber's member is gone), no motion above it."""
    scene, r = SCENES[0]
    rs = np.array([r - 1e-3, r + 1e-3])
    bc, bm = closed_form.boundaries(scene, rs, "exact")
    below = classify(scene, rs, 0.5 * (bc + bm))
    above = classify(scene, rs, 1.1 * bm)
    assert np.all(below.regime == regimes.STICK_SLIP), below.regime
    assert np.all(above.regime == regimes.NO_MOTION), above.regime


def test_the_absorbers_held_state_in_closed_form():
    """2DOF, ground wall on m1, load p cos tau on m1, m2 on k2 = 1: at r = 1 the held
    state has x2 = -(p / k2) cos tau (the force k2 x2 on m1 cancels the load), the
    contact mass still, no contact force."""
    scene, r = SCENES[0]
    m = scene_modes(scene)
    assert np.array_equal(m.p0, [1.0, 0.0]) and m.stiffness[1, 1] == 1.0
    res = classify(scene, np.full(3, r), np.array([0.05, 0.3, 0.8]), design=True)
    assert np.all(res.regime == regimes.NO_MOTION)
    np.testing.assert_allclose(res.amplitude[:, 1], 1.0, rtol=1e-12)
    np.testing.assert_allclose(res.amplitude[:, 0], 0.0, atol=1e-12)
    np.testing.assert_allclose(res.contact_force_amplitude, 0.0, atol=1e-12)


@pytest.mark.parametrize(("scene", "r"), SCENES, ids=lambda v: str(v)[:40])
def test_the_closed_form_knows_the_absorber(scene, r):
    """The motion bound is 0 at the absorber's r (and one ulp either side), the limit
    of its neighbours 1e-6 away (finite, continuous through it), and the prediction
    is no motion there for every beta > 0, as the simulator finds."""
    rs = np.array([np.nextafter(r, 0.0), r, np.nextafter(r, 2.0)])
    assert np.array_equal(closed_form.motion_bound(scene, rs), np.zeros(3))
    near = closed_form.motion_bound(scene, np.array([r - 1e-6, r + 1e-6]))
    assert np.all((near > 0.5) & (near < np.inf)) and abs(near[0] - near[1]) < 1e-4
    beta = np.array([1e-3, 0.3, 0.9]) * near[0]
    rr, bb = (a.ravel() for a in np.meshgrid(rs, beta, indexing="ij"))
    for method in ("paper", "exact"):
        assert np.all(closed_form.predict(scene, rr, bb, method) == regimes.NO_MOTION)
