"""Scenes with several Coulomb contacts in a study: their fields and layout (docs/results.md).

A scene with several contacts (:class:`tasks.multicontact.MultiScene`,
docs/contacts.md) writes per-contact fields with a dimension ``contact``
(before the plane, as per-mass fields have ``mass``) and a per-point
``regime_combined`` (:func:`tasks.multicontact.combined_label`). One-contact
scenes never go through this module: their files are unchanged.
"""

from __future__ import annotations

import numpy as np

from study import fields
from study.axes import Axis
from study.errors import StudyError, field_error
from tasks import regimes
from tasks.multicontact import MAX_CONTACTS, MultiScene
from tasks.result import FIELDS, field_attrs

#: Per-contact fields (a trailing axis ``contact`` in memory, the dim ``contact``
#: in a written result) and their meanings where they differ from one contact's.
CONTACT_FIELDS: dict[str, str] = {
    "regime": "steady-state motion regime of each contact (codes: docs/regimes.md)",
    "stops_per_cycle": "stick phases of each contact in one steady-state period",
    "slip_amplitude": "half peak-to-peak relative displacement b_c . x of each contact",
    "stick_fraction": "fraction of the period each contact is stuck in steady state",
    "dissipation": (
        "energy dissipated by each contact per excitation cycle (/ (k_1 Y^2): beta_c times "
        "the slip distance per cycle)"
    ),
    "contact_force_amplitude": (
        "largest friction force of each contact over the steady-state period (/ (k_1 Y); "
        "beta_c whenever the contact slides)"
    ),
    "regime_rest": "regime of each contact reached from rest (-127 if rest was not a start)",
}
#: Per-point fields of a several-contact scene (meanings as for one contact).
POINT_FIELDS: tuple[str, ...] = (
    "converged",
    "cycles",
    "period",
    "initial_condition",
    "asymptotic",
    "start_dependent",
    "dissipation_viscous",
)
#: The combined label: one code per point (:func:`combined_attrs`).
COMBINED = "regime_combined"
#: Fields that must agree within a uniform cell of an adaptive map of several contacts
#: (:class:`tasks.adaptive.Refinement`): the combined label and its flags.
KEY_FIELDS: tuple[str, ...] = (COMBINED, "converged", "start_dependent")

#: dtypes of every field of a several-contact scene, in the order they are written.
MULTI_DTYPES: dict[str, str] = {
    **{name: FIELDS[name][0] for name in CONTACT_FIELDS},
    COMBINED: "int16",
    **{name: FIELDS[name][0] for name in POINT_FIELDS},
}


def is_multi(scene: object) -> bool:
    """A scene with several contacts."""
    return isinstance(scene, MultiScene)


def check_scene(scene: MultiScene, field: str) -> MultiScene:
    """Refuse what a study cannot simulate with several contacts (one line naming ``field``)."""
    if scene.n_contacts > MAX_CONTACTS:
        raise StudyError(field, f"at most {MAX_CONTACTS} contacts, got {scene.n_contacts}")
    return scene


def no_ratio(beta_ratio: object) -> None:
    """A scene with one contact takes no ``beta_ratio`` (one line naming it)."""
    if beta_ratio is not None:
        raise StudyError("beta_ratio", "applies to scenes with several contacts (a list contact)")


def checked_ratio(beta_ratio: object) -> object:
    """``beta_ratio`` as given (None), one number >= 0 or a non-empty list of them (the
    count is checked against the contacts by the scene), or a StudyError naming it."""
    if beta_ratio is None:
        return None
    if fields.is_number(beta_ratio):
        return fields.number(beta_ratio, "beta_ratio", 0.0)
    return list(fields.numbers(beta_ratio, "beta_ratio", 0.0))


def chain_scene(
    contact: object, dof: int, contact_mass: object, ratios: dict, beta_ratio: object
) -> tuple[str | list[str], list[int], MultiScene]:
    """The chain of ``dof`` masses with a contact on each of ``contact_mass`` (a list),
    ``contact`` one kind or one per contact, fixed ``ratios`` (gamma, kappa): the
    checked kinds, masses and :meth:`MultiScene.chain`, or a StudyError naming the field."""
    masses = list(contact_mass) if fields.is_list(contact_mass) else [contact_mass]
    if not masses:
        raise StudyError("contact_mass", "must list at least one mass, got []")
    if len(masses) > MAX_CONTACTS:
        raise StudyError("contact_mass", f"at most {MAX_CONTACTS} contacts, got {len(masses)}")
    masses = [fields.integer(j, f"contact_mass[{i}]", minimum=1) for i, j in enumerate(masses)]
    if fields.is_list(contact):
        kinds: str | list[str] = [fields.string(k, f"contact[{i}]") for i, k in enumerate(contact)]
        if len(kinds) != len(masses):
            raise StudyError(
                "contact", f"one kind per contact_mass ({len(masses)}), got {len(kinds)}"
            )
    else:
        kinds = fields.string(contact, "contact")
    first = {k: v.first if isinstance(v, Axis) else v for k, v in ratios.items()}
    try:  # a sweep (gamma, kappa) is checked at its first value (chain_at gives the others)
        scene = MultiScene.chain(kinds, dof, masses, beta_ratio=beta_ratio, **first)
    except ValueError as exc:
        raise field_error("", exc) from None
    return kinds, masses, scene


def chain_at(spec, ratios: dict[str, float]) -> MultiScene:
    """The several-contact chain of ``spec`` (a :class:`study.definition.SceneSpec`) with
    the swept ratios set to ``ratios`` (the fixed ones as given)."""
    fixed = {k: getattr(spec, k) for k in ("gamma", "kappa") if k not in spec.sweeps}
    return MultiScene.chain(
        spec.contact, spec.dof, spec.contact_mass, beta_ratio=spec.beta_ratio, **fixed, **ratios
    )


def check_mode(scene: object, mode: str) -> None:
    """Refuse ``mode = "trace"`` for several contacts (one line naming ``mode``): a traced
    boundary is the one beta at which the regime changes at each r, and with several
    contacts each contact has its own boundaries, which cross (docs/contacts.md 8)."""
    if is_multi(scene) and mode == "trace":
        raise StudyError(
            "mode",
            "'trace' is not available for several contacts (each contact has its own "
            "boundaries, which cross: use grid or adaptive, docs/contacts.md)",
        )


def variables(starts: list[str]) -> dict[str, str]:
    """{variable: dtype} of a several-contact scene (``regime_rest`` where rest is a start)."""
    skip = () if "rest" in starts else ("regime_rest",)
    return {k: dt for k, dt in MULTI_DTYPES.items() if k not in skip}


def from_result(res) -> dict[str, np.ndarray]:
    """The arrays of a :class:`tasks.multicontact.MultiResult` under the study's names."""
    out = {}
    for name, dt in MULTI_DTYPES.items():
        value = res.combined if name == COMBINED else getattr(res, name)
        out[name] = np.asarray(value, dtype=dt)
    return out


def combined_meanings(k: int) -> tuple[np.ndarray, str]:
    """CF ``flag_values`` and ``flag_meanings`` of ``regime_combined`` for k contacts:
    the negative codes of :mod:`tasks.regimes`, then ``sum_c regime_c 3^c``
    (``c0_stick_slip_c1_no_motion``: contact 0 first)."""
    negatives = sorted(regimes.UNDETERMINED)
    values = list(negatives)
    meanings = [regimes.UNDETERMINED[c] for c in negatives]
    for code in range(3**k):
        digits = [(code // 3**c) % 3 for c in range(k)]
        values.append(code)
        meanings.append("_".join(f"c{c}_{regimes.REGIMES[d]}" for c, d in enumerate(digits)))
    return np.array(values, dtype=np.int16), " ".join(meanings)


def attrs(name: str, k: int) -> dict[str, object]:
    """CF attributes of a field of a several-contact scene."""
    if name == COMBINED:
        values, meanings = combined_meanings(k)
        return {
            "long_name": "combined regime of the contacts",
            "comment": (
                "sum over contacts c of regime_c * 3^c (contact 0 the least significant "
                "ternary digit) when every contact's regime is determined; otherwise the "
                "most severe (smallest) negative code of the contacts (docs/results.md)"
            ),
            "flag_values": values,
            "flag_meanings": meanings,
        }
    out = field_attrs(name)
    if name in CONTACT_FIELDS:
        out["comment"] = CONTACT_FIELDS[name]
    return out


def contact_coordinate(scene: MultiScene) -> dict[str, tuple]:
    """Coordinates along ``contact``: its index, what it is (``ground 0``,
    ``between 1 2``, DOF indices from 0) and its ``beta_ratio``."""
    k = scene.n_contacts
    where = np.array([" ".join(str(x) for x in c) for c in scene.contacts], dtype=object)
    return {
        "contact": (
            np.arange(k, dtype=np.int32),
            {"long_name": "index c of the contact (0 = the first listed)", "units": "1"},
        ),
        "contact_where": (
            where,
            {"long_name": "the contact: 'ground j' (b = e_j) or 'between i j' (b = e_j - e_i)"},
        ),
        "beta_ratio": (
            np.array(scene.beta_ratio, dtype=float),
            {
                "long_name": "friction ratio of the contact over beta",
                "comment": "beta_c = beta_ratio_c * beta (docs/contacts.md 1)",
                "units": "1",
            },
        ),
    }


def _plain(v: object) -> object:
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, tuple | list):
        return [_plain(x) for x in v]
    return v


def describe(scene: MultiScene, beam: dict | None = None) -> str:
    """What the scene is, for titles: ``2-DOF structure, 2 contacts (ground 0, ground 1)``
    (a beam: ``cantilever beam, contacts at nodes 5, 10``)."""
    from study.structures import damping_label

    damping = damping_label(scene)
    damping = f", {damping}" if damping else ""
    if beam is not None:
        nodes = ", ".join(str(n) for n in beam["contact_node"])
        return f"{beam.get('supports', 'cantilever')} beam, contacts at nodes {nodes}{damping}"
    where = ", ".join(" ".join(str(x) for x in c) for c in scene.contacts)
    return f"{scene.dof}-DOF structure, {scene.n_contacts} contacts ({where}){damping}"


def scene_attr(spec) -> dict[str, object]:
    """The ``scene`` attribute of a result of ``spec`` (a
    :class:`study.definition.SceneSpec`): what the scene is (its arrays are variables,
    :func:`structure_variables`); a chain also by its chain fields (a swept ratio as
    its list of values), a beam by its table."""
    scene = spec.structure
    d: dict[str, object] = {
        "contact": "multi",
        "dof": scene.dof,
        "contacts": _plain(scene.contacts),
        "beta_ratio": list(scene.beta_ratio),
        "load": "base" if scene.load_scales_r2 else "force",
        "damping": scene.structures[0].damping_kind,
        "description": describe(scene, spec.beam),
    }
    if spec.beam is not None:
        d["beam"] = dict(spec.beam)
    elif fields.is_list(spec.contact_mass):  # a chain
        d["chain"] = {"contact": _plain(spec.contact), "contact_mass": list(spec.contact_mass)}
        for k in ("gamma", "kappa"):
            v = getattr(spec, k)
            d["chain"][k] = (
                [float(x) for x in v.values_array()] if isinstance(v, Axis) else _plain(v)
            )
    return d


def toml_fields(spec) -> dict[str, object]:
    """The keys of a ``[[scene]]`` table of matrices or of a beam that give the scene of
    ``spec`` (a :class:`study.definition.SceneSpec`) again."""
    from study.structures import damping_toml

    scene = spec.structure
    s = scene.structures[0]
    if spec.beam is not None:
        damping = damping_toml(s, spec.beam)
        return {"beam": dict(spec.beam), "beta_ratio": list(scene.beta_ratio), **damping}
    load = {"base": _plain(s.load_spec[1])} if s.load_scales_r2 else _plain(s.load_spec)
    contact = [{kind: idx[0] if kind == "ground" else list(idx)} for kind, *idx in scene.contacts]
    return {
        "matrices": {"mass": _plain(s.mass), "stiffness": _plain(s.stiffness), "load": load},
        "contact": contact,
        "beta_ratio": list(scene.beta_ratio),
        **damping_toml(s, None),
    }


def structure_variables(scene: MultiScene) -> dict[str, tuple[tuple[str, ...], np.ndarray, dict]]:
    """The arrays that recompute the scene: name -> (dims, values, attrs), as
    :func:`study.structures.structure_variables` with one contact direction per contact."""
    s = scene.structures[0]
    load = s.load_spec[1] if s.load_scales_r2 else s.load_spec
    values = {
        "mass_matrix": (("dof", "dof2"), s.mass, "mass matrix M of Eq. 1.1 of docs/contacts.md"),
        "stiffness_matrix": (("dof", "dof2"), s.stiffness, "stiffness matrix K of Eq. 1.1"),
        "load_vector": (
            ("dof",),
            np.asarray(load, dtype=float),
            "load p of Eq. 1.1, or the influence vector u of a base load",
        ),
        "contact_vector": (
            ("contact", "dof"),
            scene.contact_vectors().T,
            "contact direction b_c of Eq. 1.1 of each contact (slip velocity b_c . x')",
        ),
    }
    if s.damping is not None:  # as one contact's (study.structures.structure_variables)
        from study.structures import structure_variables as single_variables

        single = single_variables(scene.single(0))["damping_matrix"]
        values["damping_matrix"] = (single[0], single[1], single[2]["comment"])
    out = {}
    for name, (dims, value, meaning) in values.items():
        attrs: dict[str, object] = {"long_name": meaning.split(" of Eq.")[0], "units": "1"}
        attrs["comment"] = meaning
        if name == "load_vector":
            attrs["load_kind"] = "base" if s.load_scales_r2 else "force"
        if name == "damping_matrix":
            attrs = single[2]
        out[name] = (dims, np.array(value, dtype=np.float64), attrs)
    return out
