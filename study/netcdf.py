"""Assembly of the result file: one labelled xarray Dataset per scene, one netCDF4 file.

Schema (docs/results.md): dims ``(gamma, kappa, beta, r)`` with the
unswept ratios as scalar coordinates (a point list: one dim ``point``), so
``ds.regime.plot()`` draws r along x; one variable per field of
``tasks.result.FIELDS`` (per-mass fields with a dim ``mass`` before beta);
coded fields are integers with CF ``flag_values`` / ``flag_meanings`` and no
fill value (a written result is complete); the closed-form boundaries of
``analysis.boundaries`` for the methods "paper" and "exact" along r; CF
attributes and provenance (study text, resolved settings, versions, history).
A single scene is written at the root (``xr.open_dataset``), several scenes as
groups named by scene (``xr.open_datatree``).

Every scene kind is written the same way, through its plan (:mod:`study.chunks`:
layout, coordinates, and the stored units as blocks of its variables). Memory
stays flat in the number of points and of scenes: each scene's group is first
defined with xarray's CF encoding from placeholders without values (a read-only
view of one fill value), one scene at a time, then every unit is read from the
work folder and written into its block with netCDF4, one unit at a time.
Everything goes to a temporary file that replaces the output only when
complete.
"""

from __future__ import annotations

import functools
import json
import math
import os
import platform
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path

import netCDF4
import numpy as np
import xarray as xr

from study import contacts
from study.definition import Study
from study.errors import StudyFailed
from study.plans import ScenePlan
from study.preflight import older_result_note
from study.store import TMP_SUFFIX, WorkDir, fsync_dir, os_cause
from study.structures import structure_variables
from study.trace import TRACE_FIELDS
from tasks import regimes
from tasks.adaptive import ADAPTIVE_FIELDS
from tasks.result import COORD_ATTRS, FIELDS, MASS_FIELDS, field_attrs

#: Closed-form methods stored for every scene (``analysis.boundaries``).
BOUNDARY_METHODS = ("paper", "exact")
#: Elements per netCDF (HDF5) chunk of a per-point variable: small enough that
#: the bounded chunk cache below holds every chunk being filled, whatever the
#: size of the grid (512 KiB of float64).
NC_CHUNK_ELEMENTS = 1 << 16
#: HDF5 chunk cache per variable while the result is written (bytes, slots).
#: The library default (64 MiB per variable) would keep every chunk of a large
#: map in memory until the file is closed: client memory would grow with it.
NC_CACHE_BYTES = 2 << 20
NC_CACHE_SLOTS = 1009
#: Compression of every variable: deflate (zlib) at level 1, which any netCDF-4 reader
#: decodes, with HDF5's byte shuffle except where a plan says its values repeat in
#: runs (``nc_shuffle = False``: an adaptive map, whose inferred points copy their
#: cell's corner). Measured (benchmarks/bench_write.py --encoding, CPU of writing
#: every per-point variable): a 1000 x 500 adaptive map of Fig. 4, zlib level 4 with
#: shuffle (before) 1.73 MB in 0.141 s, level 1 without shuffle 1.53 MB in 0.068 s;
#: a dense 500 x 250 grid 3.51 MB in 0.079 s, level 1 with shuffle 3.54 MB in 0.064 s
#: (without: 4.22 MB, 0.092 s). No compression: 0.024 s, 46 MB and 11 MB.
COMPRESSION: dict[str, object] = {"zlib": True, "complevel": 1, "shuffle": True}

BOUNDARY_ATTRS = {
    "beta_continuous": "largest beta of continuous motion (continuous / stick-slip boundary)",
    "beta_motion": "smallest beta of no motion (stick-slip / no-motion boundary)",
}
METHOD_NOTES = {
    "paper": (
        "closed form of Marino & Cicirello (2021), Eqs. 13, 53 with S = 1 (docs/theory.md 4.1-4.2)"
    ),
    "exact": "exact antisymmetric continuous-motion limit (docs/theory.md 4.3)",
}
PACKAGES = (
    "frictionregimes",
    "numpy",
    "scipy",
    "numba",
    "dask",
    "distributed",
    "xarray",
    "netCDF4",
)


def _fill(dtype: str) -> object:
    if dtype == "int8":
        return regimes.NOT_COMPUTED
    return np.nan if dtype.startswith("float") else 0


def versions() -> dict[str, str]:
    """Versions of Python and of the packages that made the result."""
    return dict(_versions())


@functools.cache
def _versions() -> dict[str, str]:
    """:func:`versions`, looked up once per process (reading the installed packages'
    metadata costs about 25 ms of CPU at every result written)."""
    from frictionregimes import __version__

    out = {"python": platform.python_version()}
    for pkg in PACKAGES:
        if pkg == "frictionregimes":  # the release and, where known, the git commit
            out[pkg] = __version__
            continue
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = "not installed"
    return out


def global_attrs(study: Study, command: str | None = None) -> dict[str, str]:
    """Global attributes: title, Conventions, study text, history, versions."""
    stamp = datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    command = command or "study.run_study(" + repr(study.name) + ")"
    attrs = {
        "title": f"Motion regimes of chains with one Coulomb contact: study {study.name}",
        "Conventions": "CF-1.10",
        "institution": "",
        "source": "frictionregimes: exact event-driven simulation (tasks.classify)",
        "references": "Marino & Cicirello (2021), Nonlinear Dynamics 104:35-63",
        "history": f"{stamp}: {command}",
        "study": study.text or study.to_toml(),
        "study_name": study.name,
        "versions": json.dumps(versions(), sort_keys=True),
    }
    if study.description:
        attrs["comment"] = study.description
    return {k: v for k, v in attrs.items() if v}


# --------------------------------------------------------------------------- boundaries
def _boundaries(scene, r: np.ndarray, method: str) -> tuple[np.ndarray, np.ndarray]:
    """``analysis.boundaries`` (the one home of the closed forms), in blocks of r values
    (bounded memory), remembered: an adaptive plane's hint computed them already."""
    from analysis.closed_form import boundaries_along

    return boundaries_along(scene, r, method)


def _boundary_vars(plan: ScenePlan, axes: dict[str, np.ndarray]) -> dict[str, xr.Variable]:
    out: dict[str, xr.Variable] = {}
    if contacts.is_multi(plan.spec.structure):  # no closed form bounds several contacts
        return out
    for method in BOUNDARY_METHODS:
        groups = plan.boundary_groups(axes)
        dims, shape = next(groups)
        cont = np.empty(shape)
        motion = np.empty(shape)
        for index, scene, r in groups:
            cont[index], motion[index] = _boundaries(scene, r, method)
        for base, values in (("beta_continuous", cont), ("beta_motion", motion)):
            out[f"{base}_{method}"] = xr.Variable(
                dims,
                values,
                {
                    "long_name": f"{BOUNDARY_ATTRS[base]}: {METHOD_NOTES[method]}",
                    "units": "1",
                },
            )
    return out


# --------------------------------------------------------------------------- skeleton
def _var_layout(
    name: str, dims: tuple[str, ...], shape: tuple[int, ...], plan: ScenePlan
) -> tuple[tuple[str, ...], tuple[int, ...]]:
    """Dims and shape of one variable: per-mass fields have ``mass`` before the plane,
    per-contact fields of several contacts ``contact`` (:mod:`study.contacts`)."""
    n = plan.trailing(name)
    if not n:
        return dims, shape
    extra = "contact" if contacts.is_multi(plan.spec.structure) else "mass"
    k = len(dims) - (2 if plan.planar else 1)
    return (*dims[:k], extra, *dims[k:]), (*shape[:k], n, *shape[k:])


def _nc_chunksizes(shape: tuple[int, ...], grid: bool = False) -> tuple[int, ...]:
    """netCDF chunks of at most NC_CHUNK_ELEMENTS: whole columns of beta (runs of r).

    The work chunks are written row band after row band (r, then beta), so a
    netCDF chunk is complete soon after it is first touched and then leaves
    the cache for good.
    """
    if len(shape) == 1:
        return (max(1, min(shape[0], NC_CHUNK_ELEMENTS)),)
    if grid:  # (..., beta, r)
        nb = max(1, min(shape[-2], NC_CHUNK_ELEMENTS))
        nr = max(1, min(shape[-1], NC_CHUNK_ELEMENTS // nb))
        return (*([1] * (len(shape) - 2)), nb, nr)
    cols = max(1, min(shape[-1], NC_CHUNK_ELEMENTS))
    rows = max(1, min(shape[-2], NC_CHUNK_ELEMENTS // cols))
    return (*([1] * (len(shape) - 2)), rows, cols)


#: CF flags of the coded trace variables.
TRACE_FLAGS = {
    "trace_monotone": {
        "flag_values": np.array([0, 1], dtype=np.int8),
        "flag_meanings": "dense_scan bisection",
    }
}


def _attrs(name: str) -> dict[str, object]:
    if name in FIELDS:
        return field_attrs(name)
    if name == "simulated":
        return {
            "long_name": "point simulated",
            "comment": ADAPTIVE_FIELDS[name][1],
            "flag_values": np.array([0, 1], dtype=np.int8),
            "flag_meanings": "inferred simulated",
        }
    if name == "verification":
        return {
            "long_name": "verification sample",
            "comment": ADAPTIVE_FIELDS[name][1],
            "flag_values": np.array([0, 1, 2], dtype=np.int8),
            "flag_meanings": "not_sampled confirmed contradicted",
        }
    attrs: dict[str, object] = {"long_name": TRACE_FIELDS[name][1]}
    attrs.update(TRACE_FLAGS.get(name, {"units": "1"}))
    return attrs


def scalar_ratios(spec) -> dict[str, float]:
    """gamma and kappa of a scene where they are one number and not swept (dof >= 2)."""
    out = {}
    if spec.dof < 2 or spec.structure is not None:
        return out
    for name in ("gamma", "kappa"):
        if name in spec.sweeps:
            continue
        values = set(np.atleast_1d(np.asarray(getattr(spec, name), dtype=float)).tolist())
        if len(values) == 1:
            out[name] = values.pop()
    return out


def scene_dataset(
    plan: ScenePlan, study: Study, placeholders: bool = False
) -> tuple[xr.Dataset, dict[str, dict]]:
    """The Dataset of one scene with lazy fill values, and its netCDF encoding
    (``placeholders``: the per-point variables as :func:`_placeholder`, for the file)."""
    spec = plan.spec
    axes = plan.axes()
    dims, shape, variables = plan.layout()
    grid = plan.planar
    coords = {
        name: xr.Variable(dim, values, COORD_ATTRS[name])
        for name, (dim, values) in plan.coordinates(axes).items()
    }
    for name, value in scalar_ratios(spec).items():
        if name not in coords:
            coords[name] = xr.Variable((), value, COORD_ATTRS[name])
    multi = contacts.is_multi(spec.structure)
    if multi:
        for name, (values, vattrs) in contacts.contact_coordinate(spec.structure).items():
            coords[name] = xr.Variable("contact", values, vattrs)
    if any(name in MASS_FIELDS for name in variables) and not multi:
        coords["mass"] = xr.Variable(
            "mass", np.arange(1, spec.dof + 1, dtype=np.int32), COORD_ATTRS["mass"]
        )
    data_vars: dict[str, xr.Variable] = {}
    encoding: dict[str, dict] = {name: {"_FillValue": None} for name in coords}
    compression = COMPRESSION | {"shuffle": getattr(plan, "nc_shuffle", True)}
    for name, dt in variables.items():
        vdims, vshape = _var_layout(name, dims, shape, plan)
        enc: dict[str, object] = compression | {"chunksizes": _nc_chunksizes(vshape, grid)}
        if not dt.startswith("float"):  # codes and counts: complete, no fill value
            enc["_FillValue"] = None
        if name in ("regime", "regime_rest"):
            enc["dtype"] = "int8"
        fill = np.broadcast_to(np.array(_fill(dt), dtype=dt), vshape)  # no memory
        of_contacts = multi and name in contacts.MULTI_DTYPES
        vattrs = contacts.attrs(name, spec.structure.n_contacts) if of_contacts else _attrs(name)
        data_vars[name] = xr.Variable(vdims, fill, vattrs)
        if placeholders:  # built so at once: assigning them later costs an alignment
            data_vars[name] = _placeholder(data_vars[name])
        encoding[name] = enc
    bounds = _boundary_vars(plan, axes)
    data_vars.update(bounds)
    for name in bounds:
        encoding[name] = dict(COMPRESSION)
    if spec.structure is not None and not spec.sweeps:  # what recomputes it (docs/results.md)
        arrays = (contacts.structure_variables if multi else structure_variables)(spec.structure)
        for name, (vdims, values, vattrs) in arrays.items():
            data_vars[name] = xr.Variable(vdims, values, vattrs)
            encoding[name] = dict(COMPRESSION)
    attrs = {
        "scene": json.dumps(spec.scene_attr()),
        "scene_name": spec.name,
        "scene_label": spec.base_scene.label,
        "contact": spec.base_scene.contact,
        "dof": spec.dof,
        "contact_mass": spec.contact_mass,
        "mode": spec.mode,
        "fidelity": study.fidelity,
        "settings": json.dumps(study.settings.to_dict(), sort_keys=True),
    }
    if multi:  # several contacts: contact_mass is not one mass (the contact coordinates say)
        del attrs["contact_mass"]
        attrs["n_contacts"] = spec.structure.n_contacts
    if (design := plan.design_quantities()) is not None:  # "off": design variables absent
        attrs["design_quantities"] = design
    attrs.update(plan.extra_attrs(axes))
    return xr.Dataset(data_vars, coords, attrs), encoding


def root_attrs(gattrs: dict[str, str], names: list[str]) -> dict[str, str]:
    """Global attributes of a multi-scene file: what its groups hold and how to open them."""
    listing = " ".join(names)
    return {
        **gattrs,
        "groups": listing,
        "how_to_open": (
            f"one group per scene ({listing}): xarray.open_datatree(path), or "
            f"xarray.open_dataset(path, group=NAME); the root holds no variables"
        ),
    }


# --------------------------------------------------------------------------- writing
def write_result(
    study: Study,
    plans: list[ScenePlan],
    work: WorkDir,
    output: str | os.PathLike,
    command: str | None = None,
) -> Path:
    """Assemble every unit in ``work`` into ``output`` (atomically), one scene at a time.

    Every unit of every plan must be in the work folder.
    """
    output = Path(output)
    tmp = output.with_name(f".{output.name}.{os.getpid()}{TMP_SUFFIX}")
    cache = netCDF4.get_chunk_cache()
    netCDF4.set_chunk_cache(NC_CACHE_BYTES, NC_CACHE_SLOTS)  # for every variable opened below
    gattrs = global_attrs(study, command)
    grouped = len(plans) > 1
    try:
        with netCDF4.Dataset(tmp, "w", format="NETCDF4") as nc:  # one handle for every scene
            if grouped:  # the root: attributes only; one group per scene
                nc.setncatts(root_attrs(gattrs, [p.spec.name for p in plans]))
            groups = [nc.createGroup(p.spec.name) if grouped else nc for p in plans]
            values = _Deferred()  # every definition first, then every value (see _Deferred)
            for group, plan in zip(groups, plans, strict=True):
                _define_scene(group, plan, study, {} if grouped else gattrs, values)
            values.write()
            for group, plan in zip(groups, plans, strict=True):
                _fill_units(group, plan, work)
            for group, plan in zip(groups, plans, strict=True):
                group.setncatts(plan.result_attrs(work))
        with open(tmp, "rb+") as f:  # on disk before it takes the output's name
            os.fsync(f.fileno())
        os.replace(tmp, output)
        fsync_dir(output.parent)
    except (OSError, RuntimeError) as exc:  # no space, permission, I/O (NetCDF: HDF error)
        if isinstance(exc, StudyFailed):
            raise
        raise StudyFailed(
            f"cannot write {tmp}: {os_cause(exc)}; every chunk is kept in {work.path}; "
            f"{older_result_note(output)}; rerun the same command to write it"
        ) from None
    finally:
        netCDF4.set_chunk_cache(*cache)
        tmp.unlink(missing_ok=True)
    return output


class _Deferred:
    """The ``writer`` of xarray's store that keeps every value for later.

    netCDF-4 files leave define mode at each write after a definition, and each
    time the library walks the metadata of every group in the file: writing
    each scene's values right after its definitions makes the assembly
    quadratic in the number of scenes. Here every scene is defined first (with
    xarray's CF encoding), then the coordinates and closed-form boundaries are
    written; the per-point variables' placeholders (lazy fill values) are not
    written at all: the units tile every variable (:meth:`ScenePlan.writes`).
    """

    def __init__(self) -> None:
        self.pending: list[tuple[object, object]] = []

    def add(self, source, target, region=None) -> None:
        if not _is_placeholder(source):
            self.pending.append((source, target))

    def write(self) -> None:
        for source, target in self.pending:
            target[...] = source
        self.pending.clear()


def _define_scene(group, plan: ScenePlan, study: Study, gattrs: dict, values: _Deferred) -> None:
    """One scene's variables, dims and attributes in an open netCDF group (no values)."""
    from xarray.backends import NetCDF4DataStore

    try:
        from xarray.backends.writers import dump_to_store
    except ImportError:  # xarray < 2025.9
        from xarray.backends.api import dump_to_store

    ds, enc = scene_dataset(plan, study, placeholders=True)
    if gattrs:
        ds = ds.assign_attrs({**gattrs, **ds.attrs})
    dump_to_store(ds, NetCDF4DataStore(group), values, encoding=enc)
    for var in group.variables.values():
        _size_cache(var)


def _size_cache(var) -> None:
    """A variable's HDF5 chunk cache: at most NC_CACHE_BYTES, at most the variable itself.

    Every variable of the file keeps its cache until the file is closed: caches
    of the full size for thousands of small scenes would make the client's
    memory grow with the number of scenes.
    """
    chunking = var.chunking()
    if not isinstance(chunking, list | tuple) or not chunking:  # contiguous or scalar
        return
    item = var.dtype.itemsize if hasattr(var.dtype, "itemsize") else 8
    chunk_bytes = math.prod(chunking) * item
    n_chunks = math.prod(-(-n // c) for n, c in zip(var.shape, chunking, strict=True))
    size = min(NC_CACHE_BYTES, max(chunk_bytes, n_chunks * chunk_bytes))
    slots = min(NC_CACHE_SLOTS, 2 * n_chunks + 1)
    var.set_var_chunk_cache(size=size, nelems=slots)


def _placeholder(var: xr.Variable) -> xr.Variable:
    """A per-point variable without values (a read-only view of one fill value: no
    memory, whatever the grid), encoded as xarray would encode it: a boolean as
    ``int8`` with the attribute ``dtype = "bool"`` (xarray's ``BooleanCoder``; done
    here so that the encoding keeps the view instead of converting the whole array)."""
    if var.dtype != bool:
        return var
    data = np.broadcast_to(np.zeros((), dtype=np.int8), var.shape)
    return xr.Variable(var.dims, data, {**var.attrs, "dtype": "bool"})


def _is_placeholder(source) -> bool:
    """A placeholder's values (:func:`_placeholder`): never written, the units tile them."""
    return isinstance(source, np.ndarray) and source.size > 1 and not any(source.strides)


def _fill_units(group, plan: ScenePlan, work) -> None:
    """Every unit of a scene into its block of the group (one unit in memory at a time)."""
    group.set_auto_maskandscale(False)
    for name, index, values in plan.writes(work):
        var = group.variables[name]
        var[index] = values.astype(var.dtype, copy=False)


def result_tree(study: Study, plans: list[ScenePlan], work) -> xr.DataTree:
    """The result in memory, laid out as the file :func:`write_result` writes.

    ``work`` holds every unit (``load(scene, key)``); a single scene is the
    root of the tree, several scenes are its children.
    """
    built = {}
    for plan in plans:
        ds, _ = scene_dataset(plan, study)
        variables = plan.layout()[2]
        filled = {name: np.array(ds[name].values) for name in variables}  # own memory
        for name, index, values in plan.writes(work):
            filled[name][index] = values
        ds = ds.assign({name: ds[name].copy(data=filled[name]) for name in variables})
        built[plan.spec.name] = ds.assign_attrs(plan.result_attrs(work))
    gattrs = global_attrs(study)
    if len(built) == 1:
        ((ds,),) = [tuple(built.values())]
        return xr.DataTree(ds.assign_attrs({**gattrs, **ds.attrs}))
    return xr.DataTree.from_dict(
        {"/": xr.Dataset(attrs=root_attrs(gattrs, list(built)))}
        | {f"/{n}": ds for n, ds in built.items()}
    )


def open_result(path: str | os.PathLike) -> xr.Dataset | xr.DataTree:
    """Open a result: a Dataset for a single scene, a DataTree for several."""
    with netCDF4.Dataset(path) as nc:
        grouped = bool(nc.groups)
    return (
        xr.open_datatree(path, engine="netcdf4")
        if grouped
        else xr.open_dataset(path, engine="netcdf4")
    )
