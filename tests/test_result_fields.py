"""The attributes of the result fields and the promises of the trajectory API."""

from __future__ import annotations

import numpy as np
import pytest

from tasks import Scene, regimes, trajectory
from tasks.classifier import reached_bit
from tasks.result import FIELDS, LONG_NAMES, REACHED_BITS, field_attrs


@pytest.mark.parametrize("name", list(FIELDS))
def test_long_name_is_the_meaning_without_its_trailing_parenthesis(name):
    """A long_name is never a meaning cut in the middle (``two starts reached different``)."""
    attrs = field_attrs(name)
    meaning = FIELDS[name][1]
    long_name = attrs["long_name"]
    if name in LONG_NAMES:
        assert long_name == LONG_NAMES[name]
    else:
        rest = meaning[len(long_name) :]
        assert meaning.startswith(long_name)
        assert rest == "" or (rest.startswith(" (") and rest.endswith(")")), (long_name, rest)
    if long_name != meaning:
        assert attrs["comment"] == meaning


def test_regimes_reached_has_cf_flag_masks_matching_the_bits_the_classifier_sets():
    attrs = field_attrs("regimes_reached")
    masks = [int(m) for m in attrs["flag_masks"]]
    meanings = str(attrs["flag_meanings"]).split()
    assert len(masks) == len(meanings) == 4
    by_name = dict(zip(meanings, masks, strict=True))
    for code in (regimes.NO_MOTION, regimes.STICK_SLIP, regimes.CONTINUOUS):
        assert int(reached_bit(np.array([code]))[0]) == by_name[regimes.name(code)]
    for code in (regimes.NOT_CONVERGED, regimes.UNBOUNDED, regimes.WORK_LIMIT):
        assert int(reached_bit(np.array([code]))[0]) == by_name["undetermined"]
    assert REACHED_BITS == {m: n for n, m in by_name.items()}


def test_sample_at_any_time_of_a_steady_state():
    """README: ``.sample(tau)`` gives the exact state at any time; the steady state is
    periodic, so tau = 0 and tau = 2 pi k give the same state, equal to the recorded
    event states at their times (also shifted by whole periods)."""
    tr = trajectory(Scene("ground", 2, 1, gamma=1.0, kappa=1.0), 1.3, 0.4)
    assert tr.periodic
    period = 2 * np.pi * int(tr.result.period)
    x0, v0 = tr.sample(0.0)
    assert x0.shape == (2,) and np.all(np.isfinite(x0))
    x1, v1 = tr.sample(np.array([period, -3 * period, 7 * period]))
    np.testing.assert_allclose(x1, np.broadcast_to(x0, x1.shape), atol=1e-9)
    np.testing.assert_allclose(v1, np.broadcast_to(v0, v1.shape), atol=1e-9)
    inside = tr.tau[1:-1]  # event times (exact states recorded there)
    xs, _ = tr.sample(inside + 5 * period)
    np.testing.assert_allclose(xs, tr.x[1:-1], atol=1e-9)


def test_sample_outside_a_transient_stretch_is_refused_with_its_range():
    tr = trajectory(Scene("ground", 1), 0.8, 0.3, start="held", cycles=1)
    assert not tr.periodic
    tr.sample(np.pi)
    with pytest.raises(ValueError, match=r"tau: outside the simulated stretch \[0, 6.28"):
        tr.sample(3 * np.pi)
