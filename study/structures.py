"""Scenes of any linear structure in a study: matrices or a beam (docs/studies.md).

A ``[[scene]]`` table (or :class:`study.definition.SceneSpec`) gives a structure
instead of a chain by one of

* ``matrices``: a table ``{mass = [[...]], stiffness = [[...]], load = [...]}``
  (``load = {base = [...]}`` for a support motion with influence vector u), or
  the path of a ``.npz`` file, relative to the study file, with the arrays
  ``mass``, ``stiffness``, ``load`` (or ``base``) and optionally ``damping``;
  with ``contact = {ground = j}`` or ``{between = [i, j]}`` (DOF indices from 0);
* ``beam``: the parameters of :func:`tasks.structures.beam` (``supports``,
  ``n_elements``, ``contact_node``, ``load``, ``modes``, ``support_stiffness``);

and optionally ``damping = {rayleigh = [a, b]}``, ``{modal = zeta}`` (one ratio
or one per mode) or ``{matrix = [[...]]}``. The matrices are those of Eq. 1.1 of
docs/structures.md and are checked by :meth:`tasks.Scene.from_matrices`; every
rule broken is one :class:`~study.errors.StudyError` naming the field.
"""

from __future__ import annotations

import io
import os
import stat
import zipfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from scipy.linalg import eigh

from study import fields
from study.contacts import no_ratio
from study.errors import StudyError, field_error
from study.fields import show
from study.limits import entry_kind
from tasks.model import scene_modes
from tasks.multicontact import MultiScene
from tasks.scene import Scene
from tasks.structures import beam

#: Largest ``.npz`` file read (and largest total of its uncompressed arrays), bytes:
#: four 200 x 200 float64 matrices (``tasks.matrices.MAX_MATRIX_DOF``) take 1.3 MB.
MAX_NPZ_BYTES = 8 * 1024 * 1024
#: Arrays a ``.npz`` of a scene may hold.
NPZ_KEYS = ("mass", "stiffness", "load", "base", "damping")
#: Keys of ``matrices = {...}`` given inline.
MATRIX_KEYS = ("mass", "stiffness", "load")
#: Keys of ``beam = {...}`` (the parameters of :func:`tasks.structures.beam`).
BEAM_KEYS = ("supports", "n_elements", "contact_node", "load", "modes", "support_stiffness")
DAMPING_KINDS = ("rayleigh", "modal", "matrix")
CONTACT_KINDS = ("ground", "between")


def _one_key(raw: object, key: str, kinds: tuple[str, ...], example: str) -> tuple[str, object]:
    """The single ``{kind = value}`` of a table (or a Python tuple ``(kind, *values)``)."""
    if isinstance(raw, tuple | list) and raw and raw[0] in kinds:
        return raw[0], (raw[1] if len(raw) == 2 else list(raw[1:]))
    if not isinstance(raw, Mapping) or len(raw) != 1 or next(iter(raw)) not in kinds:
        raise StudyError(key, f"must be {example}, got {show(raw)}")
    kind = next(iter(raw))
    return str(kind), raw[kind]


def contact_spec(raw: object) -> tuple:
    """``{ground = j}`` -> ``("ground", j)``, ``{between = [i, j]}`` -> ``("between", i, j)``."""
    kind, value = _one_key(raw, "contact", CONTACT_KINDS, "{ground = j} or {between = [i, j]}")
    if kind == "ground":
        return ("ground", fields.integer(value, "contact.ground", minimum=0))
    if not fields.is_list(value) or len(value) != 2:
        raise StudyError("contact.between", f"must be two DOF indices [i, j], got {show(value)}")
    return ("between", *(fields.integer(v, "contact.between", minimum=0) for v in value))


def contact_specs(raw: object) -> tuple | list[tuple]:
    """:func:`contact_spec`, or a list of them for several contacts
    (``[{ground = 0}, {between = [1, 2]}]``, docs/contacts.md)."""
    if isinstance(raw, list) and raw and all(isinstance(c, Mapping | tuple) for c in raw):
        out = []
        for i, c in enumerate(raw):
            try:
                out.append(contact_spec(c))
            except StudyError as exc:  # contact.ground -> contact[1].ground
                field = f"contact[{i}]" + exc.field.removeprefix("contact")
                raise StudyError(field, exc.message) from None
        return out
    return contact_spec(raw)


def damping_spec(raw: object) -> object:
    """A damping table as the ``damping`` argument of ``Scene.from_matrices``."""
    if raw is None:
        return None
    example = "{rayleigh = [a, b]}, {modal = zeta} or {matrix = [[...]]}"
    kind, value = _one_key(raw, "damping", DAMPING_KINDS, example)
    if kind == "rayleigh":
        if not fields.is_list(value) or len(value) != 2:
            raise StudyError("damping.rayleigh", f"must be [a, b], got {show(value)}")
        a, b = (fields.number(v, "damping.rayleigh", 0.0) for v in value)
        return ("rayleigh", a, b)
    if kind == "modal":
        if fields.is_number(value):
            return ("modal", fields.number(value, "damping.modal", 0.0))
        return ("modal", fields.numbers(value, "damping.modal", 0.0))
    return value  # a matrix: checked by from_matrices


def read_npz(path: Path) -> dict[str, np.ndarray]:
    """The arrays of a scene's ``.npz``: a regular file of at most :data:`MAX_NPZ_BYTES`.

    Looked at before and after opening (never blocks on a FIFO or a device), read
    up to the limit, its members' uncompressed sizes checked before any is
    inflated, no pickles, no other keys than :data:`NPZ_KEYS`.
    """
    where = "matrices"
    try:
        st = os.stat(path)
        if not stat.S_ISREG(st.st_mode):
            raise StudyError(
                where, f"{path} must be a regular .npz file, this is {entry_kind(st.st_mode)}"
            )
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0))
    except FileNotFoundError:
        raise StudyError(
            where, f"no such file {path} (paths are relative to the study file)"
        ) from None
    except OSError as exc:
        raise StudyError(where, f"cannot read {path}: {exc.strerror}") from None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise StudyError(where, f"{path} must be a regular .npz file")
        with os.fdopen(os.dup(fd), "rb") as f:
            data = f.read(MAX_NPZ_BYTES + 1)
    finally:
        os.close(fd)
    if len(data) > MAX_NPZ_BYTES:
        raise StudyError(where, f"{path}: a .npz of a scene holds at most {MAX_NPZ_BYTES:,} bytes")
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as z:
            members = z.infolist()
        if sum(m.file_size for m in members) > MAX_NPZ_BYTES:
            raise StudyError(where, f"{path}: arrays larger than {MAX_NPZ_BYTES:,} bytes")
        with np.load(io.BytesIO(data), allow_pickle=False) as npz:
            arrays = {k: np.asarray(npz[k]) for k in npz.files}
    except StudyError:
        raise
    except Exception as exc:  # not a zip, a pickle, a bad header: one line
        raise StudyError(
            where, f"{path} is not a readable .npz file ({type(exc).__name__})"
        ) from None
    for k in arrays:
        if k not in NPZ_KEYS:
            raise StudyError(
                f"{where}.{k}", f"unknown array in {path} (known: {', '.join(NPZ_KEYS)})"
            )
    return arrays


def _load(raw: object) -> object:
    """``load = [...]`` or ``load = {base = [...]}`` as ``from_matrices`` takes it."""
    if isinstance(raw, Mapping):
        if set(raw) != {"base"}:
            raise StudyError(
                "matrices.load", f"must be a vector or {{base = [...]}}, got {show(raw)}"
            )
        return ("base", raw["base"])
    return raw


def matrices_scene(
    matrices: object, contact: object, damping: object, directory: Path, beta_ratio: object = None
) -> Scene:
    """The scene of ``matrices`` (a table or a ``.npz`` path), ``contact`` and ``damping``
    (a list of contacts, with ``beta_ratio``: a :class:`tasks.multicontact.MultiScene`)."""
    if contact is None:
        raise StudyError(
            "contact", "a scene of matrices needs contact = {ground = j} or {between = [i, j]}"
        )
    spec_contact = contact_specs(contact)
    if not isinstance(spec_contact, list):
        no_ratio(beta_ratio)
    spec_damping = damping_spec(damping)
    if isinstance(matrices, str | os.PathLike):
        path = Path(matrices)
        arrays = read_npz(path if path.is_absolute() else directory / path)
        if "load" in arrays and "base" in arrays:
            raise StudyError("matrices.base", "give either the array load or base, not both")
        if "damping" in arrays:
            if spec_damping is not None:
                raise StudyError("damping", "the .npz already holds a damping matrix")
            spec_damping = arrays.pop("damping")
        if "base" in arrays:
            arrays["load"] = ("base", arrays.pop("base"))
    elif isinstance(matrices, Mapping):
        for k in matrices:
            if k not in MATRIX_KEYS:
                raise StudyError(
                    f"matrices.{k}", f"unknown key (known keys here: {', '.join(MATRIX_KEYS)})"
                )
        arrays = dict(matrices)
        if "load" in arrays:
            arrays["load"] = _load(arrays["load"])
    else:
        raise StudyError(
            "matrices",
            "must be a table {mass, stiffness, load} or the path of a .npz file, "
            f"got {show(matrices)}",
        )
    for k in MATRIX_KEYS:
        if k not in arrays:
            raise StudyError(f"matrices.{k}", "is required")
    try:
        if isinstance(spec_contact, list):
            return MultiScene.from_matrices(
                arrays["mass"],
                arrays["stiffness"],
                arrays["load"],
                spec_contact,
                beta_ratio=beta_ratio,
                damping=spec_damping,
            )
        return Scene.from_matrices(
            arrays["mass"], arrays["stiffness"], arrays["load"], spec_contact, damping=spec_damping
        )
    except ValueError as exc:
        err = field_error("", exc)
        if err.field.split(".")[0] in MATRIX_KEYS:
            err = StudyError(f"matrices.{err.field}", err.message)
        raise err from None


def beam_scene(raw: object, damping: object, beta_ratio: object = None) -> Scene:
    """The scene of ``beam = {...}`` (:func:`tasks.structures.beam`) with ``damping``
    (a list ``contact_node``, with ``beta_ratio``: a :class:`tasks.multicontact.MultiScene`)."""
    if not isinstance(raw, Mapping):
        raise StudyError("beam", f"must be a table of {', '.join(BEAM_KEYS)}, got {show(raw)}")
    for k in raw:
        if k not in BEAM_KEYS:
            raise StudyError(f"beam.{k}", f"unknown key (known keys here: {', '.join(BEAM_KEYS)})")
    kw = dict(raw)
    for k in ("n_elements", "contact_node", "modes"):
        if k == "contact_node" and fields.is_list(kw.get(k)):
            kw[k] = [fields.integer(v, f"beam.{k}[{i}]") for i, v in enumerate(kw[k])]
        elif k in kw:
            kw[k] = fields.integer(kw[k], f"beam.{k}")
    if not fields.is_list(kw.get("contact_node")):
        no_ratio(beta_ratio)
    elif beta_ratio is not None:
        kw["beta_ratio"] = beta_ratio
    for k in ("supports", "load"):
        if k in kw:
            kw[k] = fields.string(kw[k], f"beam.{k}")
    if "support_stiffness" in kw:
        kw["support_stiffness"] = fields.number(kw["support_stiffness"], "beam.support_stiffness")
    spec_damping = damping_spec(damping)
    try:
        return beam(**kw, damping=spec_damping)
    except ValueError as exc:
        err = field_error("", exc)
        if err.field.split(".")[0] not in ("damping", "beta_ratio"):
            err = StudyError(f"beam.{err.field}" if err.field else "beam", err.message)
        raise err from None


def check_simulable(scene: Scene) -> Scene:
    """``scene`` if the simulator takes it (proportional damping, docs/structures.md 4.1),
    else the one-line error of ``tasks.model`` naming ``damping``, before any run."""
    if isinstance(scene, MultiScene):  # its constructor checked the damping (docs/contacts.md 7)
        return scene
    try:
        scene_modes(scene).kernel_args()
    except ValueError as exc:
        raise field_error("", exc) from None
    return scene


def describe(scene: Scene, beam_raw: Mapping | None) -> str:
    """What a structure scene is, for titles: ``cantilever, contact at node 18,
    $\\zeta_1$ = 0.01`` (matplotlib mathtext)."""
    s = scene.structure
    if beam_raw is not None:
        supports = beam_raw.get("supports", "cantilever")
        n = int(beam_raw.get("n_elements", 20))
        node = beam_raw.get("contact_node", n // 2 if supports == "pinned" else n)
        parts = [f"{supports}", f"contact at node {node}"]
    else:
        kind, *idx = s.contact
        where = f"DOF {idx[0]}" if kind == "ground" else f"DOFs {idx[0]}-{idx[1]}"
        parts = [f"{scene.dof}-DOF structure", f"contact at {where}"]
    parts.append(damping_label(scene))
    return ", ".join(p for p in parts if p)


def damping_label(scene: Scene) -> str:
    """``zeta = 0.01`` (modal), ``zeta_1 = 0.01`` (Rayleigh: the first mode's ratio),
    ``damping matrix`` or ``""`` (undamped); several contacts: their common structure."""
    s = scene.structures[0] if isinstance(scene, MultiScene) else scene.structure
    if s.damping_kind == "modal":
        z = np.atleast_1d(s.damping_spec[1])
        zs = f"{z[0]:.3g}" if np.all(z == z[0]) else f"{z.min():.3g}..{z.max():.3g}"
        return f"$\\zeta$ = {zs}"
    if s.damping_kind == "rayleigh":  # zeta_i = (a + b lambda_i) / (2 sqrt(lambda_i)), Eq. 1.2
        lam1 = eigh(s.stiffness, s.mass, eigvals_only=True, subset_by_index=[0, 0])[0]
        zeta1 = (s.damping_spec[1] + s.damping_spec[2] * lam1) / (2.0 * np.sqrt(lam1))
        return f"$\\zeta_1$ = {zeta1:.3g}"
    return "" if s.damping_kind == "none" else "damping matrix"


def scene_attr(scene: Scene, beam_raw: Mapping | None) -> dict[str, object]:
    """The ``scene`` attribute of a structure: what it is; its arrays are variables
    (:func:`structure_variables`)."""
    s = scene.structure
    d: dict[str, object] = {
        "contact": scene.contact,
        "dof": scene.dof,
        "contact_mass": scene.contact_mass,
        "contact_dofs": list(s.contact),
        "load": "base" if s.load_scales_r2 else "force",
        "damping": s.damping_kind,
        "description": describe(scene, beam_raw),
    }
    if beam_raw is not None:
        d["beam"] = dict(beam_raw)
    return d


def _plain(v: object) -> object:
    return v.tolist() if isinstance(v, np.ndarray) else v


def toml_fields(scene: Scene, beam_raw: Mapping | None) -> dict[str, object]:
    """The structure keys of a ``[[scene]]`` table that give ``scene`` again."""
    s = scene.structure
    d: dict[str, object] = {}
    if beam_raw is not None:
        d["beam"] = dict(beam_raw)
    else:
        load = {"base": _plain(s.load_spec[1])} if s.load_scales_r2 else _plain(s.load_spec)
        d["matrices"] = {"mass": _plain(s.mass), "stiffness": _plain(s.stiffness), "load": load}
        kind, *idx = s.contact
        d["contact"] = {kind: idx[0] if kind == "ground" else idx}
    d.update(damping_toml(s, beam_raw))
    return d


def damping_toml(s, beam_raw: Mapping | None) -> dict[str, object]:
    """``{"damping": table}`` of the structure ``s`` (:class:`tasks.matrices.StructureMatrices`)
    as a study file writes it, ``{}`` when undamped (a beam's matrix: from its table)."""
    spec = s.damping_spec
    if s.damping_kind == "rayleigh":
        return {"damping": {"rayleigh": [spec[1], spec[2]]}}
    if s.damping_kind == "modal":
        return {"damping": {"modal": _plain(np.asarray(spec[1]))}}
    if s.damping_kind == "matrix" and beam_raw is None:
        return {"damping": {"matrix": _plain(s.damping)}}
    return {}


#: Variables of a structure's group: name -> (dims, meaning). ``dof`` indexes the
#: DOFs from 0 (the contact's indices), ``dof2`` the columns of a matrix.
STRUCTURE_VARIABLES = {
    "mass_matrix": (("dof", "dof2"), "mass matrix M of Eq. 1.1 of docs/structures.md"),
    "stiffness_matrix": (("dof", "dof2"), "stiffness matrix K of Eq. 1.1"),
    "damping_matrix": (("dof", "dof2"), "damping matrix C of Eq. 1.1 (damped scenes only)"),
    "load_vector": (("dof",), "load p of Eq. 1.1, or the influence vector u of a base load"),
    "contact_vector": (("dof",), "contact direction b of Eq. 1.1 (slip velocity b . x')"),
}


def structure_variables(scene: Scene) -> dict[str, tuple[tuple[str, ...], np.ndarray, dict]]:
    """The arrays that recompute a structure scene: name -> (dims, values, attrs).

    ``load_vector`` holds p (``load_kind = "force"``) or u (``"base"``); the
    damping attribute of ``damping_matrix`` gives the damping as it was declared
    (``rayleigh a b``, ``modal zeta...`` or ``matrix``).
    """
    s = scene.structure
    load = s.load_spec[1] if s.load_scales_r2 else s.load_spec
    values = {
        "mass_matrix": s.mass,
        "stiffness_matrix": s.stiffness,
        "damping_matrix": s.damping,
        "load_vector": np.asarray(load, dtype=float),
        "contact_vector": s.b,
    }
    out = {}
    for name, (dims, meaning) in STRUCTURE_VARIABLES.items():
        if values[name] is None:
            continue
        attrs: dict[str, object] = {"long_name": meaning.split(" of Eq.")[0], "units": "1"}
        attrs["comment"] = meaning
        if name == "load_vector":
            attrs["load_kind"] = "base" if s.load_scales_r2 else "force"
        if name == "contact_vector":
            attrs["contact"] = " ".join(str(c) for c in s.contact)
        if name == "damping_matrix":
            spec = s.damping_spec
            numbers = [] if s.damping_kind == "matrix" else np.atleast_1d(spec[1:]).ravel()
            if s.damping_kind == "modal":
                numbers = np.atleast_1d(spec[1])
            attrs["damping"] = " ".join([s.damping_kind, *(repr(float(v)) for v in numbers)])
        out[name] = (dims, np.array(values[name], dtype=np.float64), attrs)
    return out
