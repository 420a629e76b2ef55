"""Pure numerics: scenes, exact event-driven simulation and regime classification.

No Dask, no files. Public API::

    from tasks import Scene, classify, regimes
    res = classify(Scene("ground", 2, contact_mass=1, gamma=1.0, kappa=1.0), r, beta)
"""

from tasks import regimes
from tasks.classifier import classify
from tasks.fidelity import PRESETS, Settings, resolve
from tasks.result import FIELDS, ClassifyResult
from tasks.scene import Scene
from tasks.trace import TraceResult, trace_boundaries
from tasks.trajectory import Trajectory, trajectory

__all__ = [
    "FIELDS",
    "PRESETS",
    "ClassifyResult",
    "Scene",
    "Settings",
    "TraceResult",
    "Trajectory",
    "classify",
    "regimes",
    "resolve",
    "trace_boundaries",
    "trajectory",
]
