"""Studies: definition, validation, expansion into tasks, Dask orchestration, netCDF I/O.

Public API::

    from study import Study, run_study
    s = Study.from_toml("examples/quickstart.toml")
    run_study(s, "quickstart.nc")          # LocalCluster, one worker per core

Command line: ``study run | plan | report`` (:mod:`study.cli`).
Heavy modules (Dask, xarray) are imported only when used, so workers that run
:func:`study.compute.compute_chunk` import little.
"""

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
    # imported on first use: ``python -m study`` starts in milliseconds, so a Ctrl-C
    # right after the start reaches the command's handler (one line, no traceback)
    if name == "run_study":
        from study.run import run_study

        return run_study
    if name in ("Axis", "Points", "SceneSpec", "Study"):
        import study.definition

        return getattr(study.definition, name)
    raise AttributeError(name)
