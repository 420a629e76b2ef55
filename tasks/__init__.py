"""Pure numerics: scenes, exact event-driven simulation and regime classification.

No Dask, no files. Public API::

    from tasks import Scene, classify, regimes, trajectory, trace_boundaries
    scene = Scene("ground", 2, contact_mass=1, gamma=1.0, kappa=1.0)
    res = classify(scene, r, beta)            # regime codes and diagnostics per point
    tr = trajectory(scene, 1.5, 0.3)          # the converged period, event by event
    tb = trace_boundaries(scene, r, (0, 2))   # numerical boundaries along r

Modules: :mod:`tasks.scene` (the chain), :mod:`tasks.model` (modal data),
:mod:`tasks.kernel` (the compiled simulator), :mod:`tasks.classifier`,
:mod:`tasks.trajectory`, :mod:`tasks.trace`, :mod:`tasks.fidelity` (presets),
:mod:`tasks.regimes` (the codes), :mod:`tasks.result`, :mod:`tasks.baseline`
(the paper's method, for benchmarks), :mod:`tasks.numba_cache` (where the
compiled simulator is cached; ``NUMBA_CACHE_DIR``).
"""

# numba_cache first: it picks numba's cache folder before anything is compiled
from tasks import numba_cache, regimes
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
    "numba_cache",
    "regimes",
    "resolve",
    "trace_boundaries",
    "trajectory",
]
