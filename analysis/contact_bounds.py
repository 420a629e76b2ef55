"""Closed forms of one contact among several: what they bound (docs/contacts.md 8).

The closed forms of one contact (docs/theory.md 4, :func:`analysis.boundaries`)
apply to contact c of a scene with several contacts on the structure with the
**other contacts held** (their relative displacements frozen; a frictionless
contact never sticks and stays free): that one-contact structure
(:func:`held_scene`) is the motion of the whole scene whenever every other
contact with friction is stuck for the whole period. Hence

* where every other contact with friction is in no motion, contact c's regime is
  that of the held structure, and its closed forms (``method = "exact"``: the
  exact motion bound and the continuous bound of docs/theory.md 4.3) predict it
  (:func:`held_agreement` counts how often);
* every contact with friction stays stuck exactly when
  ``beta >= max_c beta_motion_c / beta_ratio_c`` with ``beta_motion_c`` the motion
  bound of contact c with the others held (all of them held, each force within
  its limit: the held margin of docs/contacts.md 4); with every contact frictional
  this is the boundary of the combined label 0 (:func:`all_stuck_bound`).

With the **other contacts free** (removed) the closed forms bound nothing unless
the others are frictionless (then they are the held structure's above): a
sliding contact still carries its friction ``beta_ratio_c' beta``, of the order
of contact c's own limit, and it may raise or lower the load contact c carries.
They are not drawn.
"""

from __future__ import annotations

import json

import numpy as np
import xarray as xr
from scipy.linalg import null_space

from analysis.closed_form import boundaries, predict
from tasks import regimes
from tasks.multicontact import MultiScene
from tasks.scene import Scene

#: Method of the closed forms drawn with several contacts (docs/theory.md 4.3).
METHOD = "exact"
#: A point within this relative distance of a bound agrees with the regime on either
#: side (a grid value such as beta = 1.0 on a bound of exactly 1 is decided by rounding).
EDGE_RTOL = 1e-9


def held_by(scene: MultiScene, c: int) -> list[int]:
    """The contacts held with contact ``c``: the others with friction (a frictionless
    contact never sticks; it stays free)."""
    return [o for o, ratio in enumerate(scene.beta_ratio) if o != c and ratio > 0.0]


def held_scene(scene: MultiScene, c: int) -> Scene | None:
    """The one-contact scene of contact ``c`` with the other contacts held (None when the
    held contacts take the whole load: nothing moves, contact c stays stuck).

    Coordinates ``x = T (s, w)`` with ``s = b_c . x`` (so the contact is
    ``("ground", 0)``) and ``w`` spanning the rest of the null space of the other
    contacts' directions ``B_o^T``; ``M_h = T^T M T``, ``K_h = T^T K T``, the load
    ``T^T p`` (a base load: the influence vector ``u_h`` with ``M_h u_h = T^T M u``).
    """
    B = scene.contact_vectors()
    others = held_by(scene, c)
    N = null_space(B[:, others].T)  # x = N y keeps the others' relative displacements at 0
    a = N.T @ B[:, c]
    T = N @ np.column_stack([a / (a @ a), null_space(a[None, :])])
    s = scene.structures[0]
    M, K = T.T @ s.mass @ T, T.T @ s.stiffness @ T
    M, K = 0.5 * (M + M.T), 0.5 * (K + K.T)
    if s.load_scales_r2:
        u = np.linalg.solve(M, T.T @ s.mass @ s.load_spec[1])
        load: object = ("base", u)
    else:
        u = load = T.T @ np.asarray(s.load_spec, dtype=float)
    if np.abs(T @ u).max() <= 1e-12 * np.abs(s.load).max():
        return None
    return Scene.from_matrices(M, K, load, ("ground", 0))


def held_bounds(scene: MultiScene, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``beta_continuous`` and ``beta_motion`` of each contact with the others held, in
    units of beta (``/ beta_ratio_c``; NaN for a frictionless contact): shape (k, n_r)."""
    r = np.asarray(r, dtype=float)
    cont = np.full((scene.n_contacts, r.size), np.nan)
    motion = np.full_like(cont, np.nan)
    for c, ratio in enumerate(scene.beta_ratio):
        held = held_scene(scene, c) if ratio > 0.0 else None
        if held is not None:
            bc, bm = boundaries(held, r, method=METHOD)
            cont[c], motion[c] = np.asarray(bc) / ratio, np.asarray(bm) / ratio
        elif ratio > 0.0:  # the others take the whole load: stuck at any beta
            cont[c], motion[c] = 0.0, 0.0
    return cont, motion


def all_stuck_bound(motion: np.ndarray) -> np.ndarray:
    """The beta above which every contact with friction stays stuck (combined label 0
    when every contact has friction): the largest held motion bound
    (:func:`held_bounds`) over the contacts with friction (NaN if none has)."""
    top = np.where(np.isnan(motion), -np.inf, motion).max(axis=0)
    return np.where(np.isfinite(top), top, np.nan)


def where_held(ds: xr.Dataset, c: int, r: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """The curve ``beta(r)`` of contact ``c`` where it means something: NaN wherever the
    nearest grid point of the (r, beta) plane ``ds`` has another contact with friction
    not in no motion."""
    scene_ratio = ds["beta_ratio"].values
    others = [o for o in range(scene_ratio.size) if o != c and scene_ratio[o] > 0.0]
    reg = ds["regime"].transpose("contact", "r", "beta").values[others]
    held = np.all(reg == regimes.NO_MOTION, axis=0)
    grid_r, grid_b = ds["r"].values, ds["beta"].values
    ir = np.abs(np.asarray(r)[:, None] - grid_r[None, :]).argmin(axis=1)
    finite = np.where(np.isfinite(beta), beta, 0.0)
    ib = np.abs(finite[:, None] - grid_b[None, :]).argmin(axis=1)
    return np.where(held[ir, ib], beta, np.nan)


def scene_of(ds: xr.Dataset) -> MultiScene | None:
    """The scene of a several-contact result of one plane (its stored arrays, or a
    swept chain's fields at the plane's gamma and kappa); None if it cannot be rebuilt."""
    attr = json.loads(ds.attrs.get("scene", "{}"))
    ratio = [float(v) for v in ds["beta_ratio"].values]
    if "mass_matrix" in ds:
        load = ds["load_vector"].values
        if ds["load_vector"].attrs.get("load_kind") == "base":
            load = ("base", load)
        where = [str(w).split() for w in ds["contact_where"].values]
        contacts = [(w[0], *(int(i) for i in w[1:])) for w in where]
        return MultiScene.from_matrices(
            ds["mass_matrix"].values,
            ds["stiffness_matrix"].values,
            load,
            contacts,
            beta_ratio=ratio,
        )
    chain = attr.get("chain")
    if chain is None:
        return None
    ratios = {
        k: float(ds[k]) if k in ds.coords and ds[k].ndim == 0 else chain[k]
        for k in ("gamma", "kappa")
    }
    return MultiScene.chain(
        chain["contact"], int(attr["dof"]), chain["contact_mass"], beta_ratio=ratio, **ratios
    )


def held_agreement(ds: xr.Dataset, scene: MultiScene) -> list[tuple[int, int]]:
    """Per contact c: (points where every other contact with friction is in no motion and
    contact c's
    regime is determined, of them those whose regime the held closed forms predict, at
    beta or within :data:`EDGE_RTOL` of it)."""
    r = ds["r"].values
    reg = ds["regime"].transpose("contact", "beta", "r").values
    rr, bb = np.meshgrid(r, ds["beta"].values)
    out = []
    for c, ratio in enumerate(scene.beta_ratio):
        others = reg[held_by(scene, c)]
        where = np.all(others == regimes.NO_MOTION, axis=0) & (reg[c] >= 0) & (ratio > 0.0)
        if not where.any():
            out.append((0, 0))
            continue
        held = held_scene(scene, c)
        agree = np.full(int(where.sum()), held is None) & (reg[c][where] == regimes.NO_MOTION)
        for side in (-EDGE_RTOL, EDGE_RTOL) if held is not None else ():
            beta_c = ratio * bb[where] * (1.0 + side)
            agree |= predict(held, rr[where], beta_c, method=METHOD) == reg[c][where]
        out.append((int(where.sum()), int(agree.sum())))
    return out
