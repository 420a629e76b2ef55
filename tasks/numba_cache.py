"""Where numba keeps the compiled simulator, and compiling it once.

:mod:`tasks.kernel` is compiled with ``cache=True``: the first process that
runs it compiles it (40 s to 2 min on 2 cores, depending on the load) and
stores the machine code on disk; every later process, Dask workers included,
loads it in seconds. The *base* folder is chosen before anything is compiled,
so ``import tasks`` never fails with "cannot cache function ...: no locator
available" (a read-only site-packages, a shared installation):

1. ``NUMBA_CACHE_DIR``, when set by the user, always wins (numba's own rule);
2. otherwise ``tasks/__pycache__`` when writable (a clone, an editable
   install, a user-writable virtual environment);
3. otherwise ``$XDG_CACHE_HOME/frictionregimes/numba`` (default
   ``~/.cache/frictionregimes/numba``) when writable;
4. otherwise ``<temporary folder>/frictionregimes-numba-<user id>``.

Choices 3 and 4 are exported as ``NUMBA_CACHE_DIR`` in the environment, so
worker processes started later (a ``LocalCluster``) use the same folder.
Imported first by :mod:`tasks` (side effect on import, before :mod:`tasks.kernel`).

The kernel is a package of modules that call each other, and numba checks only
the source file a compiled function is defined in: a caller's cached machine
code, which contains its callees, would survive an edit of a callee's module.
So the kernel is cached in a subfolder ``kernel-<key>`` of the base folder,
``key`` a hash of every kernel module's source, of :mod:`tasks.regimes` (whose
constants are compiled in) and of the Python, numba and numpy versions
(:func:`kernel_key`). :func:`kernel_cache` points numba there only while the
kernel's functions are decorated (numba fixes a function's cache folder at
decoration), so other numba code in the process keeps its own cache. Every
process computes the same key from the same sources, so workers share the folder.
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TextIO

_PACKAGE = Path(__file__).resolve().parent
#: Sources compiled into the kernel, relative to the ``tasks`` package.
KERNEL_SOURCES = ("kernel/*.py", "regimes.py")
#: Sources compiled into the several-contact simulator (:mod:`tasks.multicontact`),
#: which calls the kernel's functions: its key covers both.
MULTICONTACT_SOURCES = (*KERNEL_SOURCES, "multicontact/*.py")
#: How long the first compile takes, as the announcements say it (measured on
#: 2 cores: 38 s at a load average of 2, 80 s at 3.6, up to 100 s busier).
COMPILE_TIME = "40 s to 2 min on 2 cores, depending on the load"
_announced = False


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


def kernel_key(package: Path = _PACKAGE, sources: tuple[str, ...] = KERNEL_SOURCES) -> str:
    """Hash of the kernel's sources (:data:`KERNEL_SOURCES` under ``package``, or
    ``sources``) and of the Python, numba and numpy versions: the name of the
    kernel's cache folder."""
    import numba
    import numpy

    digest = hashlib.sha256()
    for pattern in sources:
        for path in sorted(package.glob(pattern)):
            digest.update(path.relative_to(package).as_posix().encode() + b"\0")
            digest.update(path.read_bytes() + b"\0")
    versions = f"python {sys.version_info[:2]} numba {numba.__version__} numpy {numpy.__version__}"
    digest.update(versions.encode())
    return digest.hexdigest()[:16]


def kernel_cache_folder(
    package: Path = _PACKAGE, sources: tuple[str, ...] = KERNEL_SOURCES, name: str = "kernel"
) -> Path:
    """The folder numba caches the kernel in: ``kernel-<key>`` in the base folder
    (``<name>-<key>`` of ``sources`` for another compiled package)."""
    base = os.environ.get("NUMBA_CACHE_DIR") or str(package / "__pycache__")
    return Path(base) / f"{name}-{kernel_key(package, sources)}"


@contextmanager
def kernel_cache(
    package: Path = _PACKAGE, sources: tuple[str, ...] = KERNEL_SOURCES, name: str = "kernel"
) -> Iterator[Path]:
    """Within the block, functions decorated with ``cache=True`` are cached in
    :func:`kernel_cache_folder` (numba's ``config.CACHE_DIR``, restored after)."""
    import numba.core.config

    folder = kernel_cache_folder(package, sources, name)
    previous = numba.core.config.CACHE_DIR
    numba.core.config.CACHE_DIR = str(folder)
    try:
        yield folder
    finally:
        numba.core.config.CACHE_DIR = previous


def cache_dir() -> str:
    """The folder holding the compiled simulator."""
    from tasks import kernel

    try:
        return str(kernel.run_points._cache._cache_path)
    except AttributeError:  # another numba layout, or NUMBA_DISABLE_JIT
        return str(kernel_cache_folder())


def is_compiled() -> bool:
    """Whether the simulator's entry point (``run_points_given``, the one
    :func:`tasks.classify`, :func:`tasks.classifier.classify_given` and
    :func:`compile_simulator` call) is in the on-disk cache, for this source.

    Reads numba's cache index (a stale index, of an edited source, counts as
    absent). When the index cannot be read, answers False (compiling is then
    announced and takes only the time to load it).
    """
    from tasks import kernel

    try:
        return bool(kernel.run_points_given._cache._cache_file._load_index())
    except Exception:  # numba internals differ: announce rather than stay silent
        return False


def announce_compile(stream: TextIO | None = None, prefix: str = "tasks") -> bool:
    """Say so, in one line (default: on stderr), when the simulator is about to be
    compiled: once per process, before its first use; nothing when it is cached.

    Returns whether the line was printed.
    """
    global _announced
    if _announced:
        return False
    _announced = True
    import numba.core.config

    if numba.core.config.DISABLE_JIT or is_compiled():
        return False
    print(compile_message(prefix), file=stream or sys.stderr, flush=True)
    return True


def compile_message(prefix: str) -> str:
    """The line announcing the first compile."""
    return (
        f"{prefix}: compiling the simulator once ({COMPILE_TIME}); "
        f"cached in {cache_dir()} for later runs ..."
    )


def compile_simulator() -> float:
    """Compile (or load) the simulator by classifying two points; returns the seconds."""
    import numpy as np

    from tasks.classifier import classify
    from tasks.scene import Scene

    global _announced
    _announced = True  # the caller announces it (study.firstrun)
    t0 = time.perf_counter()
    classify(Scene("ground", 2), np.array([0.8, 1.6]), np.array([0.2, 0.6]))
    return time.perf_counter() - t0


configure()
