"""A several-contact creep whose slip straddles the section (docs/contacts.md 4).

The damped 3 DOF structure of tests/test_multicontact_creep.py (reference.random_structure,
seed 103, Rayleigh C = 0.02 M + 0.01 K): a contact at DOF 2 at its motion bound (5e-10
above it) and a frictionless partner at DOF 0, from rest, at r = 0.6 and 0.8. The contact slips
at every force peak, one way, shrinking, and its slip straddles the section tau = 2 pi n:
it is never stuck there, so the stuck structure's rule measured at the section did not
see the creep (not_converged at the cycle budget). Against independent truths: the
one-contact kernel on the scene without the partner, and the scipy reference from the
held start.
"""

from __future__ import annotations

import numpy as np

from tasks import Scene, classify, regimes
from tasks.multicontact import MultiScene
from tasks.multicontact import reference as ref

_M, _K, _P = ref.random_structure(np.random.default_rng(103), 3)
_RAYLEIGH = ("rayleigh", 0.02, 0.01)
_R = np.array([0.6, 0.8])


def _scenes():
    from analysis import damped

    one = Scene.from_matrices(_M, _K, _P, ("ground", 2), damping=_RAYLEIGH)
    two = MultiScene.from_matrices(
        _M, _K, _P, [("ground", 0), ("ground", 2)], beta_ratio=[0.0, 1.0], damping=_RAYLEIGH
    )
    return one, two, damped.motion_bound(one, _R)


def test_a_creep_straddling_the_section_settles_as_the_one_contact_kernel():
    """No motion, ``asymptotic``, converged within the budget, as the one-contact kernel
    labels the scene without the partner (its section moves into the stick); the
    frictionless partner continuous; the scipy reference from the held start is no
    motion at the contact."""
    one, two, bound = _scenes()
    beta = bound * (1.0 + 5e-10)
    res = classify(two, _R, beta, initial_condition="rest")
    kern = classify(one, _R, beta, initial_condition="rest")
    assert np.all(kern.converged) and np.all(kern.regime == regimes.NO_MOTION)
    assert np.all(res.converged) and np.all(res.asymptotic)
    np.testing.assert_array_equal(res.regime[:, 1], kern.regime)
    assert np.all(res.regime[:, 0] == regimes.CONTINUOUS)
    for r, b in zip(_R, beta, strict=True):
        regime, _, ok = ref.reference_point(two, float(r), float(b), max_cycles=20)
        assert ok and regime[1] == regimes.NO_MOTION


def test_a_stick_slip_below_the_bound_stays_stick_slip():
    """1e-3 below the motion bound the contact moves (stick-slip, as the one-contact
    kernel says): the shifted section's rule must not take it for a creep."""
    one, two, bound = _scenes()
    beta = bound[1:] * (1.0 - 1e-3)
    res = classify(two, _R[1:], beta, initial_condition="rest")
    kern = classify(one, _R[1:], beta, initial_condition="rest")
    assert np.all(kern.regime == regimes.STICK_SLIP)
    np.testing.assert_array_equal(res.regime[:, 1], kern.regime)
    assert np.all(res.converged) and not np.any(res.asymptotic)
