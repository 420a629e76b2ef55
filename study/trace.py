"""Hook for ``mode = "trace"``: boundaries traced along r instead of a full grid.

The numerics belong to ``tasks`` (``tasks.trace_boundaries``, to be written by
the lead). The study layer already validates trace scenes, cuts them into
chunks of r values and stores ``beta_continuous_numerical`` and
``beta_motion_numerical`` along r. Expected signature::

    tasks.trace_boundaries(scene, r, beta_range=(beta_min, beta_max), **settings)
        -> (beta_continuous, beta_motion)      # arrays shaped like r
"""

from __future__ import annotations

import numpy as np

from tasks.scene import Scene

#: Variables a traced chunk returns (one value per r).
TRACE_FIELDS = ("beta_continuous_numerical", "beta_motion_numerical")


def available() -> bool:
    """Whether ``tasks.trace_boundaries`` exists yet."""
    import tasks

    try:
        tasks.trace_boundaries  # noqa: B018
    except AttributeError:
        return False
    return True


def trace_chunk(task: dict) -> dict[str, np.ndarray]:
    """Trace both boundaries at the r values of one chunk."""
    import tasks

    beta = np.asarray(task["beta"], dtype=float)
    cont, motion = tasks.trace_boundaries(
        Scene(**task["scene"]),
        np.asarray(task["r"], dtype=float),
        beta_range=(float(beta.min()), float(beta.max())),
        **task["settings"],
    )
    return {TRACE_FIELDS[0]: np.asarray(cont, float), TRACE_FIELDS[1]: np.asarray(motion, float)}
