"""The paper's method in plain scipy (tasks.baseline): reference labels and Den Hartog."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from tasks import Scene, regimes
from tasks.baseline import classify_paper_method, paper_method

#: Cheap public cases (0.1-0.3 s each) over all three regimes and contact types; the
#: last two are transients the paper's 100 cycles from rest do not settle
#: (baseline stick-slip, reference no motion): the baseline must reproduce them too.
CASES = (
    "case0002",  # sdof_ground, no motion
    "case0013",  # sdof_base, continuous
    "case0026",  # 2dof_ground_m1, continuous
    "case0032",  # 2dof_ground_m1, stick-slip
    "case0124",  # 2dof_mass, continuous
    "case0135",  # 2dof_mass, stick-slip
    "case0155",  # 5dof_ground_m4, no motion
    "case0094",  # 2dof_base_m1, baseline stick-slip != reference no motion
    "case0133",  # 2dof_mass, baseline stick-slip != reference no motion
)


def scene_of(case: dict) -> Scene:
    n = case["N"]
    ratios = {"gamma": tuple(case["g"][1:]), "kappa": tuple(case["k"][1:])} if n > 1 else {}
    return Scene(case["contact"], n, case["j"], **ratios)


@pytest.fixture(scope="module")
def public_cases(reference_cases_path):
    path = reference_cases_path
    return {c["id"]: c for c in json.loads(path.read_text())["cases"]}


@pytest.mark.parametrize("case_id", CASES)
def test_reproduces_the_published_baseline(public_cases, case_id):
    case = public_cases[case_id]
    code, info = paper_method(scene_of(case), case["r"], case["b"])
    assert regimes.name(code) == case["baseline_regime"]
    if code == regimes.NO_MOTION:
        assert info["stick_time"] == pytest.approx(2.0 * math.pi)
        assert info["amplitude"] == 0.0
    elif code == regimes.CONTINUOUS:
        assert info["stick_time"] == 0.0 and info["stops"] == 0 and info["reversals"] == 2


@pytest.mark.parametrize(("contact", "r", "beta"), [("ground", 2.5, 0.2), ("base", 2.0, 0.5)])
def test_den_hartog_amplitude(contact, r, beta):
    """SDOF continuous steady state: X = sqrt(V^2 - beta^2 U^2) (docs/theory.md 4.3)."""
    p = r * r if contact == "base" else 1.0
    V = p / (1.0 - r * r)
    U = math.tan(math.pi / (2.0 * r)) / r
    amplitude = math.sqrt(V * V - (beta * U) ** 2)
    code, info = paper_method(Scene(contact, 1), r, beta)
    assert code == regimes.CONTINUOUS
    assert abs(info["amplitude"] - amplitude) <= 1e-5 * amplitude


def test_vectorised_result_and_bad_input():
    scene = Scene("ground", 1)
    res = classify_paper_method(scene, np.array([[1.6], [2.5]]), np.array([1.5, 0.2]), cycles=20)
    assert res.shape == (2, 2)
    assert res.regime[0, 0] == regimes.NO_MOTION and res.stick_fraction[0, 0] == 1.0
    assert res.regime[1, 1] == regimes.CONTINUOUS and res.stops_per_cycle[1, 1] == 0
    assert np.all(res.cycles == 20) and not res.converged.any()
    assert np.all(res.initial_condition == regimes.IC_REST)
    with pytest.raises(ValueError, match="r > 0"):
        paper_method(scene, 0.0, 0.5)
