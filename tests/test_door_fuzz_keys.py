"""Bad values of the newer study keys (several contacts, ``beta_ratio``, ``damping`` of
every kind, beams, matrices) are refused in ONE error line naming the field: wrong
type, negative, NaN, inf, wrong shape, too large, unknown key (study.definition,
study.contacts, study.structures, study.fields; through ``study run``, exit code 2).

Each case is a valid scene with one value replaced; the valid scenes are accepted.
Nothing is simulated.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from study import Study
from study.errors import StudyError

NAN, INF = float("nan"), float("inf")
AXES = {"r": {"start": 0.5, "stop": 1.5, "num": 2}, "beta": {"start": 0.1, "stop": 0.5, "num": 2}}
M3, K3 = np.eye(3).tolist(), [[2.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 2.0]]
VALID = {
    "chain": {"contact": "ground", "dof": 2, "contact_mass": [1, 2], "beta_ratio": [1.0, 0.5]},
    "beam": {
        "beam": {"supports": "cantilever", "n_elements": 4, "contact_node": [2, 4], "modes": 2},
        "damping": {"rayleigh": [0.02, 0.002]},
        "beta_ratio": [1.0, 0.5],
    },
    "beam_modal": {
        "beam": {"supports": "cantilever", "n_elements": 4, "contact_node": 4, "modes": 2},
        "damping": {"modal": 0.01},
    },
    "matrices": {
        "matrices": {"mass": M3, "stiffness": K3, "load": [1.0, 0.0, 0.0]},
        "contact": [{"ground": 0}, {"ground": 2}],
        "beta_ratio": [1.0, 0.5],
        "damping": {"matrix": np.diag([0.1, 0.1, 0.2]).tolist()},
    },
    "base_load": {
        "matrices": {"mass": M3, "stiffness": K3, "load": {"base": [1.0, 1.0, 1.0]}},
        "contact": {"between": [0, 1]},
        "damping": {"rayleigh": [0.1, 0.01]},
    },
}
# (scene, path to the value replaced, value, the field the error line names)
CASES = [
    ("chain", ("contact_mass",), [], "contact_mass"),
    ("chain", ("contact_mass", 1), "x", "contact_mass[1]"),
    ("chain", ("contact_mass", 1), -1, "contact_mass[1]"),
    ("chain", ("contact_mass", 1), 1.5, "contact_mass[1]"),
    ("chain", ("beta_ratio",), [], "beta_ratio"),
    ("chain", ("beta_ratio",), {}, "beta_ratio"),
    ("chain", ("beta_ratio",), "x", "beta_ratio"),
    ("chain", ("beta_ratio",), 10**400, "beta_ratio"),
    ("chain", ("beta_ratio", 0), -1.0, "beta_ratio[0]"),
    ("chain", ("beta_ratio", 0), NAN, "beta_ratio[0]"),
    ("chain", ("beta_ratio", 1), INF, "beta_ratio[1]"),
    ("chain", ("beta_ratio", 1), 10**400, "beta_ratio[1]"),
    ("chain", ("beta_ratio", 0), True, "beta_ratio[0]"),
    ("chain", ("beta_ratio",), [1.0, 0.5, 0.2], "beta_ratio"),
    ("chain", ("damping",), {"rayleigh": [0.1, 0.1]}, "damping"),
    ("chain", ("unknown_key",), 1, "unknown_key"),
    ("beam", ("damping", "rayleigh"), [0.1], "damping.rayleigh"),
    ("beam", ("damping", "rayleigh", 0), -0.1, "damping.rayleigh"),
    ("beam", ("damping", "rayleigh", 1), NAN, "damping.rayleigh"),
    ("beam", ("damping", "rayleigh", 0), "x", "damping.rayleigh"),
    ("beam", ("damping",), {"viscous": 0.1}, "damping"),
    ("beam", ("damping",), {"rayleigh": [0.1, 0.1], "modal": 0.1}, "damping"),
    ("beam", ("damping",), 0.1, "damping"),
    ("beam", ("beam", "n_elements"), -4, "beam.n_elements"),
    ("beam", ("beam", "n_elements"), 2.5, "beam.n_elements"),
    ("beam", ("beam", "contact_node", 1), 99, "beam.contact_node"),
    ("beam", ("beam", "contact_node"), [], "beam.contact_node"),
    ("beam", ("beam", "modes"), NAN, "beam.modes"),
    ("beam", ("beam", "supports"), 3, "beam.supports"),
    ("beam", ("beam", "shape"), "x", "beam.shape"),
    ("beam", ("beam",), "x", "beam"),
    ("beam", ("beta_ratio",), [1.0], "beta_ratio"),
    ("beam_modal", ("damping", "modal"), -0.01, "damping.modal"),
    ("beam_modal", ("damping", "modal"), INF, "damping.modal"),
    ("beam_modal", ("damping", "modal"), [0.01, NAN], "damping.modal[1]"),
    ("beam_modal", ("damping", "modal"), [0.01] * 9, "damping"),
    ("beam_modal", ("damping", "modal"), "x", "damping.modal"),
    ("beam_modal", ("damping", "modal"), 1e300, "damping"),
    ("beam_modal", ("beta_ratio",), [1.0, 0.5], "beta_ratio"),
    ("matrices", ("damping", "matrix"), [[1.0]], "damping"),
    ("matrices", ("damping", "matrix"), [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], "damping"),
    ("matrices", ("damping", "matrix", 0, 0), NAN, "damping"),
    ("matrices", ("damping", "matrix", 1, 1), INF, "damping"),
    ("matrices", ("damping", "matrix", 0, 0), -1.0, "damping"),
    ("matrices", ("damping", "matrix", 0, 1), 0.5, "damping"),
    ("matrices", ("damping", "matrix"), "x", "damping"),
    ("matrices", ("matrices", "mass", 0, 0), -1.0, "matrices.mass"),
    ("matrices", ("matrices", "stiffness", 1, 1), NAN, "matrices.stiffness"),
    ("matrices", ("matrices", "load"), [1.0, 0.0], "matrices.load"),
    ("matrices", ("matrices", "load", 0), INF, "matrices.load"),
    ("matrices", ("matrices", "damping"), 1, "matrices.damping"),
    ("matrices", ("contact", 1), {"ground": 7}, "contact"),
    ("matrices", ("contact", 1), {"wall": 1}, "contact[1]"),
    ("matrices", ("contact", 1, "ground"), -1, "contact[1].ground"),
    ("matrices", ("contact",), [{"ground": 0}, {"ground": 0}], "contact"),
    ("matrices", ("beta_ratio",), [1.0], "beta_ratio"),
    ("matrices", ("beta_ratio", 1), -0.5, "beta_ratio[1]"),
    ("base_load", ("contact", "between"), [0], "contact.between"),
    ("base_load", ("contact", "between", 1), "x", "contact.between"),
    ("base_load", ("matrices", "load", "base"), [1.0], "matrices.load"),
    ("base_load", ("matrices", "load"), {"base": [1.0, 1.0, 1.0], "x": 1}, "matrices.load"),
    ("base_load", ("damping", "rayleigh", 1), 1e308, "damping"),  # C = a M + b K overflows
    ("base_load", ("beta_ratio",), [1.0, 0.5], "beta_ratio"),
]


def _data(scene: dict) -> dict:
    return {"study": {"name": "fuzz"}, "scene": [{"name": "s", **scene, **AXES}]}


def _replaced(name: str, path: tuple, value: object) -> dict:
    scene = copy.deepcopy(VALID[name])
    where = scene
    for key in path[:-1]:
        where = where[key]
    where[path[-1]] = value
    return scene


@pytest.mark.parametrize("name", sorted(VALID))
def test_the_valid_scenes_are_accepted(name):
    assert Study.from_dict(_data(VALID[name])).scenes[0].name == "s"


@pytest.mark.parametrize(
    ("name", "path", "value", "field"),
    CASES,
    ids=[f"{c[0]}-{'.'.join(map(str, c[1]))}-{str(c[2])[:12]}" for c in CASES],
)
def test_a_bad_value_is_one_line_naming_its_field(name, path, value, field):
    with np.errstate(all="raise"):  # no numpy warning on the way to the error line
        with pytest.raises(StudyError) as info:
            Study.from_dict(_data(_replaced(name, path, value)))
    assert info.value.field == f"scene[0].{field}", str(info.value)
    assert "\n" not in str(info.value) and len(str(info.value)) < 400


TOML = """[study]
name = "fuzz"

[[scene]]
name = "s"
contact = "ground"
dof = 2
contact_mass = [1, 2]
beta_ratio = {ratio}
r = {{start = 0.5, stop = 1.5, num = 2}}
beta = {{start = 0.1, stop = 0.5, num = 2}}
"""


@pytest.mark.parametrize(
    ("ratio", "field"),
    [
        ("[1.0, nan]", "beta_ratio[1]"),
        ("[1.0, -inf]", "beta_ratio[1]"),
        ("[]", "beta_ratio"),
        ('"half"', "beta_ratio"),
        ("{c = 1.0}", "beta_ratio"),
    ],
)
def test_study_run_refuses_it_with_exit_code_2_in_one_line(tmp_path, capsys, ratio, field):
    from study.cli import EXIT_BAD_INPUT, main

    path = tmp_path / "fuzz.toml"
    path.write_text(TOML.format(ratio=ratio), encoding="utf-8")
    assert main(["run", str(path), "-o", str(tmp_path / "out.nc")]) == EXIT_BAD_INPUT == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith(f"study: error: fuzz.toml: scene[0].{field}: ")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fuzz.toml"]
