"""study.cost: the factor of a scene's fastest mode and of its contact count.

Exact truths: the eigenvalues of (K, M) of a 1- and 2-DOF chain (1 and the golden
ratio squared), their scaling with K, and the monotone growth the model states.
Timings are measured in benchmarks/bench_plan.py, not here.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from study import cost
from study.definition import Study
from tasks import Scene
from tasks.multicontact.scene import MultiScene


def _matrix_scene(stiffness_scale: float) -> Scene:
    mass = np.eye(3)
    stiffness = stiffness_scale * np.array([[2.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]])
    return Scene.from_matrices(mass, stiffness, [0.0, 0.0, 1.0], ("ground", 2))


def test_mode_rate_of_chains_is_exact():
    r = np.array([0.5, 1.0, 2.0])
    assert cost.mode_rate(Scene("ground", 1), r) == pytest.approx((2.0 + 1.0 + 0.5) / 3)
    golden = (1.0 + math.sqrt(5.0)) / 2.0  # sqrt of the largest eigenvalue, gamma = kappa = 1
    assert cost.mode_rate(Scene("ground", 2), np.array([1.0])) == pytest.approx(golden)


def test_estimate_grows_with_sqrt_lambda_max():
    r = np.linspace(0.1, 3.0, 20)
    rates = [cost.mode_rate(_matrix_scene(s), r) for s in (1.0, 100.0, 10000.0)]
    assert rates[1] == pytest.approx(10.0 * rates[0])
    assert rates[2] == pytest.approx(100.0 * rates[0])
    factors = [cost.scene_factor(_matrix_scene(s), r) for s in (1.0, 100.0, 10000.0)]
    assert factors[0] == 1.0  # as fast as a chain: no extra cost
    assert factors[0] < factors[1] < factors[2]
    assert factors[2] - 1.0 == pytest.approx(cost.MODE_SLOPE * (rates[2] - cost.CHAIN_MODE_RATE))


def test_estimate_grows_with_the_contact_count():
    r = np.linspace(0.1, 2.5, 16)
    one = cost.scene_factor(Scene("ground", 4), r)
    factors = [
        cost.scene_factor(MultiScene.chain("ground", 4, masses), r)
        for masses in ([1, 2], [1, 2, 4], [1, 2, 3, 4])
    ]
    assert one == 1.0
    assert one < factors[0] < factors[1] < factors[2]
    assert factors[0] == pytest.approx(1.0 + cost.CONTACT_SLOPE)


def _study(**scene) -> Study:
    base = {"name": "s", "r": {"start": 0.1, "stop": 2.5, "num": 20}}
    base["beta"] = {"start": 0.0, "stop": 1.2, "num": 12}
    return Study.from_dict({"study": {"name": "t", "fidelity": "fast"}, "scene": [base | scene]})


def test_several_contacts_get_smaller_tasks_and_a_larger_estimate():
    from study.chunks import plan

    (one,) = plan(_study(contact="ground", dof=2, contact_mass=1))
    (two,) = plan(_study(contact="ground", dof=2, contact_mass=[1, 2], beta_ratio=[1.0, 0.5]))
    assert two.est_seconds == pytest.approx((1.0 + cost.CONTACT_SLOPE) * one.est_seconds)
    assert two.block[0] * two.block[1] < one.block[0] * one.block[1]
    # a pure function of the study: the same plan twice
    assert plan(_study(contact="ground", dof=2, contact_mass=[1, 2]))[0].block == two.block
