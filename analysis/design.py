"""What a friction-damper designer reads from a result: the response and the best beta.

Works on a scene's Dataset (stored or in memory) with the design quantities of
:data:`tasks.result.FIELDS` (``amplitude``, ``amplitude_relative``,
``contact_force_amplitude``, ``dissipation``). Den Hartog's classic plot is the
amplitude of one mass against r for several beta; its generalisation here
works for every contact and chain, and :func:`optimal_beta` gives per r the beta
of the grid that leaves the smallest amplitude.
"""

from __future__ import annotations

import json

import numpy as np
import xarray as xr

from tasks.scene import Scene

#: Frames of the amplitude: absolute displacement, or relative to the base.
FRAMES = {"absolute": "amplitude", "relative": "amplitude_relative"}


def response(ds: xr.Dataset, mass: int = 1, frame: str = "absolute") -> xr.DataArray:
    """Displacement amplitude of mass ``mass`` (1..N) over the map, NaN where undetermined.

    Parameters
    ----------
    ds : xarray.Dataset
        One scene (dims ``(..., mass, beta, r)`` for the amplitudes).
    mass : int
        Index of the mass, 1 = the mass on spring k_1.
    frame : {"absolute", "relative"}
        Absolute displacement x_i, or relative to the base x_i - y.
    """
    if frame not in FRAMES:
        raise ValueError(f"frame: must be one of {tuple(FRAMES)}, got {frame!r}")
    name = FRAMES[frame]
    if name not in ds:
        raise ValueError(
            f"{name}: this result has no design quantities (not computed: they are off by"
            " default; ask with design=True, or `design = true` in a study's [settings])"
        )
    amp = ds[name].sel(mass=mass)
    return amp.where(ds["regime"] >= 0)


def optimal_beta(ds: xr.Dataset, mass: int = 1, frame: str = "absolute") -> xr.Dataset:
    """Per r, the beta of the grid that minimises the amplitude of ``mass``, and that amplitude.

    Returns
    -------
    xarray.Dataset
        ``beta_optimal`` and ``amplitude_minimum`` along r (and any sweep dims);
        NaN where no beta of the column is determined.
    """
    amp = response(ds, mass, frame)
    determined = amp.notnull().any("beta")
    best = amp.fillna(np.inf).idxmin("beta").where(determined)
    return xr.Dataset(
        {
            "beta_optimal": best.assign_attrs(
                long_name=f"beta of the smallest {frame} amplitude of mass {mass}", units="1"
            ),
            "amplitude_minimum": amp.min("beta").assign_attrs(
                long_name=f"smallest {frame} amplitude of mass {mass} over beta", units="1"
            ),
        }
    )


def map_dataset(
    scene: Scene, r: np.ndarray, beta: np.ndarray, fidelity: str = "balanced", **settings: object
) -> xr.Dataset:
    """Classify the grid ``r`` x ``beta`` of one scene in this process and label it as a
    stored grid scene: every result field, both closed-form boundaries along r and the
    scene attribute, so the figures and scores of :mod:`analysis` take it as they take
    a scene of a result file.

    Parameters
    ----------
    scene : tasks.Scene
    r, beta : numpy.ndarray
        1-D axes.
    fidelity, **settings
        As in :func:`tasks.classify`: ``design=True`` for the design quantities
        (:func:`response`, :func:`optimal_beta`; off by default).

    Returns
    -------
    xarray.Dataset
        Dims ``(beta, r)``, per-mass fields ``(mass, beta, r)``, boundaries ``(r)``.
    """
    from analysis.closed_form import boundaries
    from tasks.classifier import classify

    r = np.asarray(r, dtype=float)
    beta = np.asarray(beta, dtype=float)
    res = classify(scene, *np.meshgrid(r, beta, indexing="ij"), fidelity=fidelity, **settings)
    ds = res.to_dataset(r, beta, scene)
    for method in ("paper", "exact"):
        bc, bm = boundaries(scene, r, method=method)
        ds[f"beta_continuous_{method}"] = ("r", bc)
        ds[f"beta_motion_{method}"] = ("r", bm)
    return ds.assign_attrs(scene=json.dumps(scene.to_dict()))


def scene_of(ds: xr.Dataset) -> Scene | None:
    """The :class:`tasks.Scene` of one (gamma, kappa) plane of a stored scene, if known."""
    if "scene" not in ds.attrs:
        return None
    d = dict(json.loads(ds.attrs["scene"]))
    if d.get("contact") == "matrices":
        return stored_structure(ds)
    for name in ("gamma", "kappa"):
        if name in ds.coords and ds[name].ndim == 0:
            d[name] = float(ds[name])
    try:
        return Scene(**d)
    except (TypeError, ValueError):  # a sweep not selected: no single scene
        return None


def stored_matrices(ds: xr.Dataset) -> dict[str, object]:
    """The keyword arguments of :meth:`tasks.Scene.from_matrices` stored with a scene of
    matrices (its variables ``mass_matrix``, ``stiffness_matrix``, ``load_vector``,
    ``damping_matrix``; docs/results.md)."""
    d = json.loads(ds.attrs["scene"])
    load = ds["load_vector"].values
    damping: object = None
    if "damping_matrix" in ds:
        kind, *values = ds["damping_matrix"].attrs["damping"].split()
        numbers = [float(v) for v in values]
        damping = {
            "rayleigh": lambda: ("rayleigh", *numbers),
            "modal": lambda: ("modal", np.array(numbers)),
        }.get(kind, lambda: ds["damping_matrix"].values)()
    return {
        "mass": ds["mass_matrix"].values,
        "stiffness": ds["stiffness_matrix"].values,
        "load": ("base", load) if d.get("load") == "base" else load,
        "contact": tuple([d["contact_dofs"][0], *map(int, d["contact_dofs"][1:])]),
        "damping": damping,
    }


def stored_structure(ds: xr.Dataset) -> Scene | None:
    """The scene of matrices stored with a result (:func:`stored_matrices`), if whole."""
    if "mass_matrix" not in ds:
        return None
    return Scene.from_matrices(**stored_matrices(ds))


def _contact_numerator(scene: Scene, r: float) -> float:
    """det(K - M) times the contact response b . (K - M)^-1 p of the frictionless chain
    (a polynomial in r^2: continuous through the resonances)."""
    a = scene.stiffness_matrix() - scene.mass_matrix(r)
    b = scene.contact_vector()
    p = scene.load_vector(r)
    # b . adj(A) p = det([[A, p], [b^T, 0]]) * (-1)
    bordered = np.block([[a, p[:, None]], [b[None, :], np.zeros((1, 1))]])
    return -float(np.linalg.det(bordered))


def characteristic_r(scene: Scene, r_max: float) -> tuple[np.ndarray, np.ndarray]:
    """Resonances and antiresonances of the contact, as frequency ratios r_1 in (0, r_max].

    Resonances: natural frequencies of the sliding (frictionless) chain,
    r = sqrt(lambda_i). Antiresonances: the r where the frictionless response of
    the contact, b . (K - M)^-1 p, vanishes (2DOF ground m_1: r = sqrt(kappa/gamma),
    docs/theory.md 5), located by sign changes and Brent's method.
    """
    from scipy.optimize import brentq

    from analysis.modal import contact_modes

    res = np.sqrt(np.asarray(contact_modes(scene).lam, dtype=float))
    grid = np.linspace(1e-3 * r_max, r_max, 2001)
    vals = np.array([_contact_numerator(scene, x) for x in grid])
    scale = np.max(np.abs(vals)) or 1.0
    anti = []
    for i in np.flatnonzero(np.sign(vals[:-1]) * np.sign(vals[1:]) < 0):
        anti.append(brentq(lambda x: _contact_numerator(scene, x) / scale, grid[i], grid[i + 1]))
    anti += [float(x) for x in grid[1:-1][np.abs(vals[1:-1]) <= 1e-13 * scale]]
    return res[res <= r_max], np.unique(np.round(np.asarray(anti, dtype=float), 12))
