"""Studies: definition, validation, expansion into tasks, Dask orchestration, netCDF I/O.

Public API::

    from study import Study, run_study
    s = Study.from_toml("examples/quickstart.toml")
    run_study(s, "quickstart.nc")          # LocalCluster, one worker per core

Command line: ``study run | plan | report`` (:mod:`study.cli`).
Heavy modules (Dask, xarray) are imported only when used, so workers that run
:func:`study.compute.compute_chunk` import little.
"""

from study.definition import Axis, Points, SceneSpec, Study
from study.errors import StudyError, StudyFailed, StudyInterrupted

__all__ = [
    "Axis",
    "Points",
    "SceneSpec",
    "Study",
    "StudyError",
    "StudyFailed",
    "StudyInterrupted",
    "run_study",
]


def __getattr__(name: str):
    if name == "run_study":
        from study.run import run_study

        return run_study
    raise AttributeError(name)
