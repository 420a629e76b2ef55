"""Assembly of the result file: one labelled xarray Dataset per scene, one netCDF4 file.

Schema (README "Results: the netCDF files"): dims ``(gamma, kappa, r, beta)`` with the
unswept ratios dropped (a point list: one dim ``point``); one variable per
field of ``tasks.result.FIELDS``; the closed-form boundaries of
``analysis.boundaries`` for the methods "paper" and "exact" along r; CF
attributes and provenance (study text, resolved settings, versions, history).
A single scene is written at the root (``xr.open_dataset``), several scenes as
groups named by scene (``xr.open_datatree``).

Memory stays flat in the number of points: the file is first written with
lazily generated fill values (dask, synchronous scheduler, large blocks), then
every chunk is read from the work folder and written into its block with
netCDF4, one chunk at a time. Everything goes to a temporary file that replaces
the output only when complete.
"""

from __future__ import annotations

import json
import os
import platform
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path

import dask
import dask.array as da
import netCDF4
import numpy as np
import xarray as xr

from study.chunks import ScenePlan
from study.definition import Study
from study.store import TMP_SUFFIX, WorkDir, fsync_dir
from study.trace import TRACE_FIELDS
from tasks import regimes
from tasks.result import FIELDS

#: Closed-form methods stored for every scene (``analysis.boundaries``).
BOUNDARY_METHODS = ("paper", "exact")
_BLOCK = 1 << 18  # elements per block of the lazily written fill values
_BOUNDARY_BLOCK = 256  # r values per call of analysis.boundaries (bounded memory)
#: Elements per netCDF (HDF5) chunk of a per-point variable: small enough that
#: the bounded chunk cache below holds every chunk being filled, whatever the
#: size of the grid (512 KiB of float64).
NC_CHUNK_ELEMENTS = 1 << 16
#: HDF5 chunk cache per variable while the result is written (bytes, slots).
#: The library default (64 MiB per variable) would keep every chunk of a large
#: map in memory until the file is closed: client memory would grow with it.
NC_CACHE_BYTES = 2 << 20
NC_CACHE_SLOTS = 1009

COORD_ATTRS = {
    "r": {"long_name": "frequency ratio r = omega sqrt(m_1/k_1) (Eq. 7)", "units": "1"},
    "beta": {"long_name": "friction ratio beta = F/(k_1 Y) (Eq. 8)", "units": "1"},
    "gamma": {"long_name": "mass ratio m_i/m_1 of every mass i = 2..N (Eq. 66)", "units": "1"},
    "kappa": {
        "long_name": "stiffness ratio k_i/k_1 of every spring i = 2..N (Eq. 67)",
        "units": "1",
    },
    "point": {"long_name": "index of the point in the study's point list", "units": "1"},
}
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
    out = {"python": platform.python_version()}
    for pkg in PACKAGES:
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
    """``analysis.boundaries`` (the one home of the closed forms)."""
    from analysis import boundaries

    r = np.asarray(r, dtype=float)
    cont = np.empty(r.shape)
    motion = np.empty(r.shape)
    for i in range(0, r.size, _BOUNDARY_BLOCK):  # blocks: the exact method's work
        sl = slice(i, i + _BOUNDARY_BLOCK)  # arrays grow with the number of r values
        c, m = boundaries(scene, r.ravel()[sl], method=method)
        cont.ravel()[sl] = np.broadcast_to(np.asarray(c, dtype=float), r.ravel()[sl].shape)
        motion.ravel()[sl] = np.broadcast_to(np.asarray(m, dtype=float), r.ravel()[sl].shape)
    return cont, motion


def _boundary_vars(plan: ScenePlan, axes: dict[str, np.ndarray]) -> dict[str, xr.Variable]:
    spec = plan.spec
    out: dict[str, xr.Variable] = {}
    for method in BOUNDARY_METHODS:
        if spec.points is not None:
            dims: tuple[str, ...] = ("point",)
            cont = np.empty(len(spec.points))
            motion = np.empty(len(spec.points))
            gk = np.stack(
                [
                    axes.get("gamma", np.full_like(axes["r"], np.nan)),
                    axes.get("kappa", np.full_like(axes["r"], np.nan)),
                ],
                axis=1,
            )
            for g, k in np.unique(gk, axis=0):
                sel = np.all((gk == (g, k)) | (np.isnan(gk) & np.isnan([g, k])), axis=1)
                ratios = {n: float(v) for n, v in (("gamma", g), ("kappa", k)) if not np.isnan(v)}
                cont[sel], motion[sel] = _boundaries(
                    spec.scene_at(**ratios), axes["r"][sel], method
                )
        else:
            sweeps = list(spec.sweeps)
            dims = (*sweeps, "r")
            shape = (*spec.sweep_shape, len(axes["r"]))
            cont = np.empty(shape)
            motion = np.empty(shape)
            for idx in np.ndindex(*spec.sweep_shape):
                ratios = {n: float(axes[n][i]) for n, i in zip(sweeps, idx, strict=True)}
                cont[idx], motion[idx] = _boundaries(spec.scene_at(**ratios), axes["r"], method)
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
def _data_layout(plan: ScenePlan) -> tuple[tuple[str, ...], tuple[int, ...], dict[str, str]]:
    """Dims, shape and {variable: dtype} of the per-point (or per-r) result variables."""
    spec = plan.spec
    if plan.kind == "points":
        return ("point",), (len(spec.points),), {k: dt for k, (dt, _) in FIELDS.items()}
    sweeps = tuple(spec.sweeps)
    if plan.kind == "trace":
        return (
            (*sweeps, "r"),
            (*spec.sweep_shape, len(spec.r)),
            {name: dt for name, (dt, _) in TRACE_FIELDS.items()},
        )
    dims = (*sweeps, "r", "beta")
    shape = (*spec.sweep_shape, len(spec.r), len(spec.beta))
    return dims, shape, {k: dt for k, (dt, _) in FIELDS.items()}


def _nc_chunksizes(shape: tuple[int, ...]) -> tuple[int, ...]:
    """netCDF chunks of at most NC_CHUNK_ELEMENTS: whole rows of beta (runs of points).

    The work chunks are written row band after row band (r, then beta), so a
    netCDF chunk is complete soon after it is first touched and then leaves
    the cache for good.
    """
    if len(shape) == 1:
        return (max(1, min(shape[0], NC_CHUNK_ELEMENTS)),)
    cols = max(1, min(shape[-1], NC_CHUNK_ELEMENTS))
    rows = max(1, min(shape[-2], NC_CHUNK_ELEMENTS // cols))
    return (*([1] * (len(shape) - 2)), rows, cols)


def _fill_chunks_shape(shape: tuple[int, ...]) -> tuple[int, ...]:
    """Blocks of at most ~_BLOCK elements along the last two dims (the rest one by one),
    made of whole netCDF chunks."""
    nc = _nc_chunksizes(shape)
    if len(shape) == 1:
        return (max(nc[0], _BLOCK // nc[0] * nc[0]),)
    rows = max(1, min(shape[-2], _BLOCK // max(1, shape[-1])))
    rows = max(nc[-2], rows // nc[-2] * nc[-2])
    return (*([1] * (len(shape) - 2)), rows, shape[-1])


def scene_dataset(plan: ScenePlan, study: Study) -> tuple[xr.Dataset, dict[str, dict]]:
    """The Dataset of one scene with lazy fill values, and its netCDF encoding."""
    spec = plan.spec
    axes = plan.axes()
    dims, shape, variables = _data_layout(plan)
    coords: dict[str, xr.Variable] = {}
    if plan.kind == "points":
        coords["point"] = xr.Variable("point", np.arange(len(spec.points)), COORD_ATTRS["point"])
        for name in ("r", "beta", "gamma", "kappa"):
            if name in axes:
                coords[name] = xr.Variable("point", axes[name], COORD_ATTRS[name])
    else:
        for name in (*spec.sweeps, "r", "beta"):
            if name == "beta" and plan.kind == "trace":
                continue
            coords[name] = xr.Variable(name, axes[name], COORD_ATTRS[name])
    chunks = _fill_chunks_shape(shape)
    data_vars: dict[str, xr.Variable] = {}
    encoding: dict[str, dict] = {name: {"_FillValue": None} for name in coords}
    for name, dt in variables.items():
        attrs = {"units": "1"}
        attrs["long_name"] = FIELDS[name][1] if name in FIELDS else TRACE_FIELDS[name][1]
        enc: dict[str, object] = {
            "zlib": True,
            "complevel": 4,
            "chunksizes": _nc_chunksizes(shape),
        }
        if name in ("regime", "regime_rest"):
            attrs.update(regimes.cf_flag_attributes())
            enc.update(_FillValue=regimes.NOT_COMPUTED, dtype="int8")
        elif not dt.startswith("float"):
            enc["_FillValue"] = None
        lazy = da.full(shape, _fill(dt), dtype=dt, chunks=chunks)
        data_vars[name] = xr.Variable(dims, lazy, attrs)
        encoding[name] = enc
    bounds = _boundary_vars(plan, axes)
    data_vars.update(bounds)
    for name in bounds:
        encoding[name] = {"zlib": True, "complevel": 4}
    attrs = {
        "scene": json.dumps(spec.scene_attr()),
        "scene_name": spec.name,
        "scene_label": spec.base_scene.label,
        "contact": spec.contact,
        "dof": spec.dof,
        "contact_mass": spec.contact_mass,
        "mode": spec.mode,
        "fidelity": study.fidelity,
        "settings": json.dumps(study.settings.to_dict(), sort_keys=True),
    }
    if plan.kind == "trace":
        attrs["beta_range"] = json.dumps([float(axes["beta"].min()), float(axes["beta"].max())])
    return xr.Dataset(data_vars, coords, attrs), encoding


# --------------------------------------------------------------------------- writing
def write_result(
    study: Study,
    plans: list[ScenePlan],
    work: WorkDir,
    output: str | os.PathLike,
    command: str | None = None,
) -> Path:
    """Assemble every chunk in ``work`` into ``output`` (atomically).

    Every chunk of every plan must be in the work folder.
    """
    output = Path(output)
    tmp = output.with_name(f".{output.name}.{os.getpid()}{TMP_SUFFIX}")
    cache = netCDF4.get_chunk_cache()
    netCDF4.set_chunk_cache(NC_CACHE_BYTES, NC_CACHE_SLOTS)  # for every variable opened below
    try:
        built = {p.spec.name: scene_dataset(p, study) for p in plans}
        gattrs = global_attrs(study, command)
        with dask.config.set(scheduler="synchronous"):
            if len(built) == 1:
                ((ds, enc),) = built.values()
                ds = ds.assign_attrs({**gattrs, **ds.attrs})
                ds.to_netcdf(tmp, engine="netcdf4", format="NETCDF4", encoding=enc)
            else:
                tree = xr.DataTree.from_dict(
                    {"/": xr.Dataset(attrs=gattrs)} | {f"/{n}": ds for n, (ds, _) in built.items()}
                )
                tree.to_netcdf(
                    tmp,
                    engine="netcdf4",
                    format="NETCDF4",
                    encoding={f"/{n}": enc for n, (_, enc) in built.items()},
                )
        _fill_chunks(tmp, plans, work, grouped=len(built) > 1)
        with open(tmp, "rb+") as f:  # on disk before it takes the output's name
            os.fsync(f.fileno())
        os.replace(tmp, output)
        fsync_dir(output.parent)
    finally:
        netCDF4.set_chunk_cache(*cache)
        tmp.unlink(missing_ok=True)
    return output


def _fill_chunks(path: Path, plans: list[ScenePlan], work: WorkDir, grouped: bool) -> None:
    """Write every chunk's arrays into its block of the file (one chunk in memory)."""
    with netCDF4.Dataset(path, "a") as nc:
        nc.set_auto_maskandscale(False)
        for plan in plans:
            group = nc.groups[plan.spec.name] if grouped else nc
            _, _, variables = _data_layout(plan)
            for chunk in plan.chunks():
                arrays = work.load(plan.spec.name, chunk.key)
                if plan.kind == "grid":
                    index = (*chunk.sweep, slice(*chunk.rows), slice(*chunk.cols))
                else:
                    index = (*chunk.sweep, slice(*chunk.rows))
                for name in variables:
                    var = group.variables[name]
                    var[index] = np.asarray(arrays[name]).astype(var.dtype, copy=False)


def open_result(path: str | os.PathLike) -> xr.Dataset | xr.DataTree:
    """Open a result: a Dataset for a single scene, a DataTree for several."""
    with netCDF4.Dataset(path) as nc:
        grouped = bool(nc.groups)
    return (
        xr.open_datatree(path, engine="netcdf4")
        if grouped
        else xr.open_dataset(path, engine="netcdf4")
    )
