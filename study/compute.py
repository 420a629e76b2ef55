"""The Dask task: classify one chunk of points. Pure: same input, same output.

Workers run only this module (and ``tasks``); they return numpy arrays and
never touch files. The client persists each result (:mod:`study.store`).
"""

from __future__ import annotations

import time

import numpy as np

from tasks.result import DESIGN_FIELDS, FIELDS, field_shape
from tasks.scene import Scene


def compute_chunk(task: dict) -> dict[str, np.ndarray]:
    """Run ``tasks.classify`` on the points of one chunk.

    The points of a chunk are classified in one call, in order (a grid block: r
    outer, beta inner; a point list: its order), so with the setting ``warm`` (on
    by default, :mod:`tasks.fidelity`) each point's search starts from the orbit
    of a close point already solved in the chunk (:mod:`tasks.seeds`). The labels
    do not depend on it, the other fields only to about 1e-9 (``cycles``
    excepted), and the same chunk gives the same arrays to the bit on every run
    (a resumed study recomputes a missing chunk exactly).

    Parameters
    ----------
    task : dict
        From :meth:`study.chunks.ScenePlan.task`: ``kind`` ("grid", "points",
        "trace", or "adaptive": a point list of an adaptive plane), ``scene``
        (``Scene.to_dict()``), ``settings`` (resolved
        ``Settings.to_dict()``), and the coordinates ``r``, ``beta`` (and
        per-point ``gamma``, ``kappa`` for a point list).

    Returns
    -------
    dict of numpy.ndarray
        One array per field of :func:`point_fields` (grid: shape
        ``(len(r), len(beta))``; points: ``(len(r),)``; per-mass fields with
        a trailing axis of length dof), plus ``seconds``,
        the compute time of the chunk (a 0-d float array).
    """
    t0 = time.perf_counter()
    run = KINDS.get(task["kind"])
    if run is None:
        raise ValueError(f"kind: unknown chunk kind {task['kind']!r}")
    out = run(task)
    out["seconds"] = np.float64(time.perf_counter() - t0)
    return out


def design_on(settings: dict) -> bool:
    """Whether the design quantities are computed: the setting ``design``, off unless
    the study asks (``design = true``; :class:`tasks.fidelity.Settings`)."""
    return bool(settings.get("design", False))


def point_fields(settings: dict) -> dict[str, str]:
    """{field: dtype} a one-contact unit returns under ``settings``: every field of
    :data:`tasks.result.FIELDS`, without :data:`tasks.result.DESIGN_FIELDS` when
    ``design`` is off (then not computed, and absent: never NaN-filled)."""
    skip = () if design_on(settings) else DESIGN_FIELDS
    return {k: dt for k, (dt, _) in FIELDS.items() if k not in skip}


def _grid(task: dict) -> dict:
    """A block of a grid: every (r, beta) pair of its axes."""
    r, beta = np.meshgrid(task["r"], task["beta"], indexing="ij")
    return _classify(task["scene"], task["settings"], r, beta)


def _point_list(task: dict) -> dict:
    """A point list of an adaptive plane (study.adaptive): one scene.

    With ``given`` (``(r, beta, final)`` of solved points near the list's points,
    one contact) the points are also seeded from those orbits
    (:func:`tasks.classifier.classify_given`), and the result holds ``final``,
    the points' own orbits to seed later lists (not saved: :data:`TRANSIENT`)."""
    return _classify(task["scene"], task["settings"], task["r"], task["beta"], task.get("given"))


def _trace(task: dict) -> dict:
    from study.trace import trace_chunk

    return trace_chunk(task)


def _tile(task: dict) -> dict:
    from study.tiles import tile_chunk  # a tile of an adaptive plane, refined here

    return tile_chunk(task)


def _classify(
    scene: dict | Scene,
    settings: dict,
    r: np.ndarray,
    beta: np.ndarray,
    given: tuple | None = None,
) -> dict:
    """Classify the points ``(r, beta)`` of ``scene`` (its dict; with ``given``, also a
    built one-contact :class:`~tasks.scene.Scene`: a tile classifies a round of points
    per refinement level and builds it once) into the unit's fields."""
    from tasks import classify

    if given is not None:  # one contact, seeded by solved points too: their orbits back
        from tasks.classifier import classify_given

        built = scene if isinstance(scene, Scene) else Scene.from_dict(scene)
        res, final = classify_given(built, r, beta, given, **settings)
        fields = point_fields(settings)
        out = {name: np.asarray(getattr(res, name), dtype=dt) for name, dt in fields.items()}
        return out | {"final": final}
    res = classify(Scene.from_dict(scene), r, beta, **settings)
    if scene.get("contact") == "multi":  # several contacts (study.contacts)
        from study.contacts import from_result

        return from_result(res)
    fields = point_fields(settings)
    return {name: np.asarray(getattr(res, name), dtype=dt) for name, dt in fields.items()}


def _classify_points(task: dict) -> dict:
    """A point list: group the points by their (gamma, kappa) and classify each group."""
    r, beta = task["r"], task["beta"]
    if "gamma" not in task and "kappa" not in task:  # one scene (NaN != NaN in np.unique)
        return _classify(task["scene"], task["settings"], r, beta)
    n = r.size
    gamma = task.get("gamma", np.full(n, np.nan))
    kappa = task.get("kappa", np.full(n, np.nan))
    dof = int(task["scene"]["dof"])
    fields = point_fields(task["settings"])
    out = {name: np.zeros(field_shape(name, (n,), dof), dtype=dt) for name, dt in fields.items()}
    pairs = np.stack([gamma, kappa], axis=1)
    for g, k in np.unique(pairs, axis=0):
        sel = (np.isnan(gamma) if np.isnan(g) else gamma == g) & (
            np.isnan(kappa) if np.isnan(k) else kappa == k
        )
        scene = dict(task["scene"])
        if not np.isnan(g):
            scene["gamma"] = float(g)
        if not np.isnan(k):
            scene["kappa"] = float(k)
        part = _classify(scene, task["settings"], r[sel], beta[sel])
        for name in out:
            out[name][sel] = part[name]
    return out


#: Arrays a unit's result may hold for its plan that are not saved with it (the orbits
#: that seed later point lists of an adaptive plane: :func:`_point_list`).
TRANSIENT = ("final",)

#: The computation of each kind of unit (:mod:`study.plans`).
KINDS = {
    "grid": _grid,
    "points": _classify_points,
    "adaptive": _point_list,
    "adaptive-tile": _tile,
    "trace": _trace,
}
