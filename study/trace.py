"""``mode = "trace"``: numerical boundaries traced along r instead of a full grid.

The numerics are :func:`tasks.trace.trace_boundaries` (bisection in beta per r,
starting from the exact closed forms of :func:`analysis.boundaries`). A traced
scene gives r and beta axes like a grid scene: the beta axis sets the search
range and the tolerance, half its step, so tracing returns the boundaries a
dense grid with that beta axis would resolve, with far fewer simulations
(``benchmarks/bench_trace.py``).
"""

from __future__ import annotations

import numpy as np

from tasks.scene import Scene

#: Variables a traced chunk returns (one value per r): dtype and long name.
TRACE_FIELDS: dict[str, tuple[str, str]] = {
    "beta_continuous_numerical": (
        "float64",
        "largest beta of continuous motion (continuous / stick-slip boundary): "
        "traced by simulation (tasks.trace_boundaries)",
    ),
    "beta_motion_numerical": (
        "float64",
        "smallest beta of no motion (stick-slip / no-motion boundary): "
        "traced by simulation (tasks.trace_boundaries)",
    ),
    "trace_points": ("int32", "simulations spent to trace both boundaries at this r"),
    "trace_monotone": (
        "int8",
        "1 if the regime did not increase with beta along the column (bisection), "
        "0 if it did (dense column scan instead)",
    ),
}


def trace_chunk(task: dict) -> dict[str, np.ndarray]:
    """Trace both boundaries at the r values of one chunk."""
    from analysis import boundaries
    from tasks.trace import trace_boundaries

    scene = Scene.from_dict(task["scene"])
    r = np.asarray(task["r"], dtype=float)
    beta = np.asarray(task["beta"], dtype=float)
    step = float(np.min(np.diff(beta))) if beta.size > 1 else 1e-3 * float(beta.max())
    guess_c, guess_m = boundaries(scene, r, method="exact")
    res = trace_boundaries(
        scene,
        r,
        beta_range=(float(beta.min()), float(beta.max())),
        guess_continuous=guess_c,
        guess_motion=guess_m,
        rtol=1e-12,
        atol=0.5 * step,
        **(task["settings"] | {"design": False}),  # only the labels are used
    )
    return {
        "beta_continuous_numerical": res.beta_continuous,
        "beta_motion_numerical": res.beta_motion,
        "trace_points": res.points.astype(np.int32),
        "trace_monotone": res.monotone.astype(np.int8),
    }
