"""Where numba keeps the compiled simulator, and compiling it once.

:mod:`tasks.kernel` is compiled with ``cache=True``: the first process that
runs it compiles it (about 30 s, longer on a loaded machine) and stores the
machine code on disk; every later process, Dask workers included, loads it in
a fraction of a second. numba stores it in ``tasks/__pycache__`` beside the
source when that folder is writable (a clone, an editable install, a
user-writable virtual environment). Where it is not (a read-only
site-packages, a shared installation), this module points numba at a
per-user cache folder before anything is compiled, so ``import tasks`` never
fails with "cannot cache function ...: no locator available":

1. ``NUMBA_CACHE_DIR``, when set by the user, always wins (numba's own rule);
2. otherwise ``tasks/__pycache__`` when writable (nothing is changed);
3. otherwise ``$XDG_CACHE_HOME/frictionregimes/numba`` (default
   ``~/.cache/frictionregimes/numba``) when writable;
4. otherwise ``<temporary folder>/frictionregimes-numba-<user id>``.

The choice is exported as ``NUMBA_CACHE_DIR`` in the environment, so worker
processes started later (a ``LocalCluster``) use the same folder. Imported
first by :mod:`tasks` (side effect on import, before :mod:`tasks.kernel`).
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent


def _writable(folder: Path) -> bool:
    """Whether ``folder`` exists or can be made, and takes a file (numba's own test)."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError:
        return False
    return True


def _user_cache() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "frictionregimes" / "numba"


def _temporary_cache() -> Path:
    uid = os.getuid() if hasattr(os, "getuid") else os.getpid()
    return Path(tempfile.gettempdir()) / f"frictionregimes-numba-{uid}"


def configure() -> str | None:
    """Set ``NUMBA_CACHE_DIR`` where the package's own ``__pycache__`` is read-only.

    Returns
    -------
    str or None
        The cache folder chosen here, or None when numba's default (the
        user's ``NUMBA_CACHE_DIR`` or ``tasks/__pycache__``) is used.
    """
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    if _writable(_PACKAGE / "__pycache__"):
        return None
    for folder in (_user_cache(), _temporary_cache()):
        if _writable(folder):
            break
    else:
        folder = Path(tempfile.mkdtemp(prefix="frictionregimes-numba-"))
    os.environ["NUMBA_CACHE_DIR"] = str(folder)
    import numba.core.config

    numba.core.config.CACHE_DIR = str(folder)  # numba read its environment already
    return str(folder)


def cache_dir() -> str:
    """The folder holding the compiled simulator."""
    from tasks import kernel

    try:
        return str(kernel.run_points._cache._cache_path)
    except AttributeError:  # another numba layout, or NUMBA_DISABLE_JIT
        return os.environ.get("NUMBA_CACHE_DIR") or str(_PACKAGE / "__pycache__")


def is_compiled() -> bool:
    """Whether the simulator's entry point is in the on-disk cache, for this source.

    Reads numba's cache index (a stale index, of an edited source, counts as
    absent). When the index cannot be read, answers False (compiling is then
    announced and takes only the time to load it).
    """
    from tasks import kernel

    try:
        return bool(kernel.run_points._cache._cache_file._load_index())
    except Exception:  # numba internals differ: announce rather than stay silent
        return False


def compile_simulator() -> float:
    """Compile (or load) the simulator by classifying two points; returns the seconds."""
    import numpy as np

    from tasks.classifier import classify
    from tasks.scene import Scene

    t0 = time.perf_counter()
    classify(Scene("ground", 2), np.array([0.8, 1.6]), np.array([0.2, 0.6]))
    return time.perf_counter() - t0


configure()
