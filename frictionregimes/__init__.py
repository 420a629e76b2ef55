"""frictionregimes: the version and the packaged example studies.

The code lives in three packages (dependencies point one way):
:mod:`study` (study files, Dask, netCDF, the ``study`` command) ->
:mod:`analysis` (closed forms, scores, figures, reports) -> :mod:`tasks` (the
numerics). This package holds what belongs to the distribution as a whole:

* ``__version__``: the release, with the git commit where it is known, e.g.
  ``0.1.0+g0f7b1cb2a1d4`` (``.dirty`` when a clone has uncommitted changes);
  recorded in every result file (global attribute ``versions``);
* :func:`examples`: the paper's example studies and the HPC recipe, shipped
  inside the installed package (``study examples``).
"""

from __future__ import annotations

import subprocess
from pathlib import Path

#: The release (the one home of the version number; pyproject.toml reads it).
RELEASE = "0.1.0"

_HERE = Path(__file__).resolve().parent
#: Written at build time (``setup.py``): the commit a wheel or sdist was built from.
_COMMIT_FILE = _HERE / "_commit.txt"


def _git_commit(root: Path) -> str | None:
    """``g<sha>`` (``.dirty`` with uncommitted changes) of a clone, or None."""
    if not ((root / "pyproject.toml").is_file() and (root / ".git").exists()):
        return None
    try:
        sha = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "--short=12", "HEAD"],
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    if not sha:
        return None
    return f"g{sha}" + (".dirty" if dirty else "")


def _version() -> str:
    """``RELEASE+<commit>``: from git in a clone, else as recorded at build time."""
    commit = _git_commit(_HERE.parent)
    if commit is None and _COMMIT_FILE.is_file():
        commit = _COMMIT_FILE.read_text().strip() or None
    return f"{RELEASE}+{commit}" if commit else RELEASE


__version__ = _version()


def examples_dir() -> Path:
    """The folder of the example studies: installed with the package, or a clone's ``examples/``."""
    packaged = _HERE / "examples"
    if packaged.is_dir():
        return packaged
    return _HERE.parent / "examples"


def examples() -> dict[str, Path]:
    """The example files by name (``quickstart``, ``fig04``, ..., ``hpc_slurm``)."""
    folder = examples_dir()
    files = sorted(p for p in folder.iterdir() if p.suffix in (".toml", ".md"))
    return {p.stem: p for p in files}
