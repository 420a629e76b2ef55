"""Non-proportional damping with a repeated or defective damped eigenvalue is refused in
one ``damping`` line (tasks.damped_pairs, docs/structures.md 4.5): by the simulator's
scenes (the Python API), by a study before any run (a StudyError naming the field),
and by ``study run`` with exit code 2, one line and nothing written.

The cases are exact: M = K = I with C = [[1.25, 0.75], [0.75, 1.25]] (eigenvalues 2
and 0.5: not diagonal in the modes of (K, M), and the mode of C's eigenvalue 2
critically damped, a defective double eigenvalue -1 of the quadratic problem), alone
or as the held system of a stuck set; two identical decoupled non-proportional
subsystems (every damped eigenvalue double); one contact whose held system is M = K = I,
C = 0.1 I against a non-proportional sliding system. Nothing here is simulated.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from study import Study
from study.errors import StudyError
from tasks import Scene
from tasks.damped_pairs import damped_pairs
from tasks.multicontact import MultiScene
from tasks.multicontact.sets import stuck_sets

REPO = Path(__file__).resolve().parents[1]
CRITICAL = [[1.25, 0.75], [0.75, 1.25]]  # eigenvalues 2 (critical with M = K = I) and 0.5
REFUSED = "damping: two damped eigenvalues coincide"

# one contact: the held system (DOFs 0, 1) is M = K = I, C = 0.1 I (tests/test_damped.py)
ONE = {
    "matrices": {
        "mass": np.eye(3).tolist(),
        "stiffness": [[1.0, 0.0, 0.3], [0.0, 1.0, 0.2], [0.3, 0.2, 2.0]],
        "load": [1.0, 0.0, 0.0],
    },
    "contact": {"ground": 2},
    "damping": {"matrix": np.diag([0.1, 0.1, 0.5]).tolist()},
}
# two contacts, the set with DOF 2 held defective (CRITICAL on DOFs 0, 1)
HELD = {
    "matrices": {
        "mass": np.eye(3).tolist(),
        "stiffness": [[1.0, 0.0, 0.3], [0.0, 1.0, 0.2], [0.3, 0.2, 3.0]],
        "load": [0.0, 0.0, 1.0],
    },
    "contact": [{"ground": 0}, {"ground": 2}],
    "beta_ratio": [1.0, 0.5],
    "damping": {"matrix": [[1.25, 0.75, 0.0], [0.75, 1.25, 0.0], [0.0, 0.0, 0.5]]},
}
# two contacts on two identical decoupled non-proportional subsystems: every eigenvalue double
TWIN = {
    "matrices": {
        "mass": np.eye(4).tolist(),
        "stiffness": np.kron(np.eye(2), [[2.0, -1.0], [-1.0, 2.0]]).tolist(),
        "load": [1.0, 0.0, 0.0, 0.0],
    },
    "contact": [{"ground": 0}, {"ground": 2}],
    "beta_ratio": [1.0, 0.5],
    "damping": {"matrix": np.diag([0.3, 0.1, 0.3, 0.1]).tolist()},
}
WHERE = {
    "one": (ONE, ""),
    "held": (HELD, " (the structure with [('ground', 2)] held)"),
    "twin": (TWIN, " (the structure without contacts held)"),
}


def _scene_table(case: dict) -> dict:
    return {
        "name": "refused",
        **case,
        "r": {"start": 0.5, "stop": 1.5, "num": 2},
        "beta": {"start": 0.1, "stop": 0.5, "num": 2},
    }


def _toml(case: dict) -> str:
    def value(v):
        if isinstance(v, dict):
            return "{" + ", ".join(f"{k} = {value(x)}" for k, x in v.items()) + "}"
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return repr(v) if isinstance(v, str) else str(v)

    lines = ['[study]\nname = "refused"\nfidelity = "fast"\n\n[[scene]]']
    lines += [f"{k} = {value(v)}" for k, v in _scene_table(case).items()]
    return "\n".join(lines).replace("'", '"') + "\n"


def test_a_defective_eigenvalue_is_refused_not_let_through_by_rounding():
    """The critically damped mode of CRITICAL: rounding splits -1 into -1 +- 1.5e-8 with
    an eigenvector matrix of condition 1.5e8 (both under the former limits)."""
    with pytest.raises(ValueError, match=f"^{REFUSED}"):
        damped_pairs(np.eye(2), np.array(CRITICAL), np.eye(2), np.array([1.0, 0.0]))
    # the control: distinct damped eigenvalues (C diagonal in the modes), accepted
    pairs = damped_pairs(np.eye(2), np.diag([0.1, 0.2]), np.diag([1.0, 4.0]), np.ones(2))
    np.testing.assert_allclose(np.sort(pairs.lam), [1.0, 4.0])


@pytest.mark.parametrize("name", ["held", "twin"])
def test_a_several_contact_scene_is_refused_naming_its_stuck_set(name):
    case, where = WHERE[name]
    m = case["matrices"]
    contacts = [(k, v) for c in case["contact"] for k, v in c.items()]
    with pytest.raises(ValueError) as info:
        MultiScene.from_matrices(
            m["mass"],
            m["stiffness"],
            m["load"],
            contacts,
            beta_ratio=case["beta_ratio"],
            damping=np.array(case["damping"]["matrix"]),
        )
    assert str(info.value).startswith(REFUSED) and str(info.value).endswith(where)
    assert "\n" not in str(info.value)


def test_the_same_structure_without_the_coupling_is_accepted():
    """The control: HELD with C diagonal in DOFs 0, 1 (no defective set) is simulable."""
    m = HELD["matrices"]
    scene = MultiScene.from_matrices(
        m["mass"],
        m["stiffness"],
        m["load"],
        [("ground", 0), ("ground", 2)],
        beta_ratio=[1.0, 0.5],
        damping=np.diag([1.25, 1.25, 0.5]),
    )
    assert stuck_sets(scene).general.any()  # non-proportional, through the pairs


@pytest.mark.parametrize("name", sorted(WHERE))
def test_a_study_refuses_it_in_one_line_naming_damping(name):
    case, where = WHERE[name]
    with pytest.raises(StudyError) as info:
        Study.from_dict({"study": {"name": "refused"}, "scene": [_scene_table(case)]})
    assert info.value.field == "scene[0].damping"
    assert info.value.message.startswith(REFUSED[len("damping: ") :])
    assert info.value.message.endswith(where) and "\n" not in str(info.value)


def test_the_scene_api_of_one_contact_refuses_it_when_simulated():
    from tasks import classify

    m = ONE["matrices"]
    scene = Scene.from_matrices(
        m["mass"], m["stiffness"], m["load"], ("ground", 2), damping=np.diag([0.1, 0.1, 0.5])
    )
    with pytest.raises(ValueError, match=f"^{REFUSED}"):
        classify(scene, 1.0, 0.1)  # refused while building the pairs: nothing compiled


@pytest.mark.parametrize("name", ["one", "held"])
def test_study_run_refuses_it_with_exit_code_2_and_writes_nothing(tmp_path, name, cli_env):
    case, where = WHERE[name]
    (tmp_path / "refused.toml").write_text(_toml(case), encoding="utf-8")
    proc = subprocess.run(
        [sys.executable, "-m", "study", "run", "refused.toml", "-o", "out.nc"],
        cwd=tmp_path,
        env=cli_env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith(f"study: error: refused.toml: scene[0].{REFUSED}")
    assert lines[0].endswith(where)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["refused.toml"]
