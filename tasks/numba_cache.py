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
The kernel's functions are compiled once per argument type, not once per
constant argument of the calls between them (:func:`compile_per_type`).

There are two compiled simulators (:data:`KERNELS`): the one-contact kernel
(``"kernel"``) and the several-contact one of :mod:`tasks.multicontact`
(``"multicontact"``, whose key covers its own modules and the kernel's, which it
calls). Each is compiled on its first use, announced (:func:`announce_compile`)
and cached in its own folder; a study compiles those its scenes need, once, in
the client (:mod:`study.firstrun`).
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

_PACKAGE = Path(__file__).resolve().parent
#: Sources compiled into the kernel, relative to the ``tasks`` package.
KERNEL_SOURCES = ("kernel/*.py", "regimes.py")
#: Sources compiled into the several-contact simulator (:mod:`tasks.multicontact`),
#: which calls the kernel's functions: its key covers both.
MULTICONTACT_SOURCES = (*KERNEL_SOURCES, "multicontact/*.py")
#: How long the first compile takes, as the announcements say it (measured on
#: 2 cores: 38 s at a load average of 2, 80 s at 3.6, up to 100 s busier; the
#: several-contact simulator alike, docs/simulator.md).
COMPILE_TIME = "40 s to 2 min on 2 cores, depending on the load"
#: The one-contact kernel: the name of its cache folder and of :data:`KERNELS`.
ONE_CONTACT = "kernel"
#: The several-contact simulator (:mod:`tasks.multicontact`).
SEVERAL_CONTACTS = "multicontact"


@dataclass(frozen=True)
class Kernel:
    """One compiled simulator: what the announcement calls it, its sources (the cache
    key, :func:`kernel_key`), and the module and name of its entry point (the function
    whose cache index :func:`is_compiled` reads)."""

    what: str
    sources: tuple[str, ...]
    module: str
    entry: str


#: The compiled simulators, by the name of their cache folder.
KERNELS: dict[str, Kernel] = {
    ONE_CONTACT: Kernel("the simulator", KERNEL_SOURCES, "tasks.kernel", "run_points_given"),
    SEVERAL_CONTACTS: Kernel(
        "the several-contact simulator",
        MULTICONTACT_SOURCES,
        "tasks.multicontact.steady",
        "run_points",
    ),
}
_announced = False  # the one-contact kernel's announcement was made in this process
_announced_others: set[str] = set()  # the other kernels announced in this process


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
    :func:`kernel_cache_folder` (numba's ``config.CACHE_DIR``, restored after), and
    the compiled functions of the modules first imported in it are compiled once per
    argument type, not once per constant (:func:`compile_per_type`)."""
    import numba.core.config

    folder = kernel_cache_folder(package, sources, name)
    previous = numba.core.config.CACHE_DIR
    before = set(sys.modules)
    numba.core.config.CACHE_DIR = str(folder)
    try:
        yield folder
    finally:
        numba.core.config.CACHE_DIR = previous
    for module in set(sys.modules) - before:
        for value in list(getattr(sys.modules.get(module), "__dict__", {}).values()):
            if getattr(getattr(value, "py_func", None), "__module__", None) == module:
                compile_per_type(value)


def compile_per_type(dispatcher) -> None:
    """Make calls from compiled code to ``dispatcher`` (a numba function) compile it
    for the types of their arguments, not for their constant values.

    numba types a constant argument of a call between compiled functions as a
    literal (``Literal[int](0)``, ``Literal[bool](True)``), and compiles the callee
    once more for every combination of constants it is called with, each time with
    everything it calls (``_shoot``, the several-contact ``run_cycle``: three times
    each); a function called from Python has none of these signatures, so a test
    calling it compiled it again. With the constants as their types (``int64``,
    ``bool``), every function is compiled once per argument type, in the kernel and
    from Python alike. Semantics are unchanged (a literal only lets numba specialise
    the callee on the value). Without numba's internals as expected, nothing changes.
    """
    try:
        from numba.core.types import unliteral

        original = dispatcher.get_call_template
    except (ImportError, AttributeError):  # another numba, or NUMBA_DISABLE_JIT
        return
    if getattr(original, "per_type", False):
        return

    def get_call_template(args, kws):
        args = tuple(unliteral(a) for a in args)
        return original(args, {k: unliteral(v) for k, v in kws.items()})

    get_call_template.per_type = True
    dispatcher.get_call_template = get_call_template


def _kernel(name: str) -> Kernel:
    if name not in KERNELS:
        raise ValueError(f"kernel: one of {', '.join(KERNELS)}, got {name!r}")
    return KERNELS[name]


def _entry(name: str):
    """The entry point of the simulator ``name`` (imports its package: no compiling)."""
    import importlib

    kernel = _kernel(name)
    return getattr(importlib.import_module(kernel.module), kernel.entry)


def cache_dir(kernel: str = ONE_CONTACT) -> str:
    """The folder holding the compiled simulator ``kernel`` (:data:`KERNELS`)."""
    try:
        return str(_entry(kernel)._cache._cache_path)
    except AttributeError:  # another numba layout, or NUMBA_DISABLE_JIT
        return str(kernel_cache_folder(sources=_kernel(kernel).sources, name=kernel))


def is_compiled(kernel: str = ONE_CONTACT) -> bool:
    """Whether the entry point of the simulator ``kernel`` is in the on-disk cache,
    for this source: of the one-contact kernel ``run_points_given`` (the one
    :func:`tasks.classify`, :func:`tasks.classifier.classify_given` and
    :func:`compile_simulator` call), of the several-contact one
    :func:`tasks.multicontact.steady.run_points`.

    Reads numba's cache index (a stale index, of an edited source, counts as
    absent). When the index cannot be read, answers False (compiling is then
    announced and takes only the time to load it).
    """
    entry = _entry(kernel)
    try:
        return bool(entry._cache._cache_file._load_index())
    except Exception:  # numba internals differ: announce rather than stay silent
        return False


def compiled(kernel: str) -> bool:
    """:func:`is_compiled` of ``kernel`` (the one-contact kernel's called as
    ``is_compiled()``, the form its callers replace in tests)."""
    return is_compiled() if kernel == ONE_CONTACT else is_compiled(kernel)


def announce_compile(
    stream: TextIO | None = None, prefix: str = "tasks", kernel: str = ONE_CONTACT
) -> bool:
    """Say so, in one line (default: on stderr), when the simulator ``kernel`` is about
    to be compiled: once per process and kernel, before its first use; nothing when
    it is cached.

    Returns whether the line was printed.
    """
    global _announced
    if kernel == ONE_CONTACT:
        if _announced:
            return False
        _announced = True
    else:
        if kernel in _announced_others:
            return False
        _announced_others.add(kernel)
    import numba.core.config

    if numba.core.config.DISABLE_JIT or compiled(kernel):
        return False
    print(compile_message(prefix, kernel), file=stream or sys.stderr, flush=True)
    return True


def compile_message(prefix: str, kernel: str = ONE_CONTACT) -> str:
    """The line announcing the first compile of the simulator ``kernel``."""
    return (
        f"{prefix}: compiling {_kernel(kernel).what} once ({COMPILE_TIME}); "
        f"cached in {cache_dir(kernel)} for later runs ..."
    )


def compile_simulator(kernel: str = ONE_CONTACT) -> float:
    """Compile (or load) the simulator ``kernel`` by classifying two points (of two
    contacts for the several-contact one); returns the seconds."""
    import numpy as np

    global _announced
    _kernel(kernel)
    if kernel == ONE_CONTACT:
        from tasks.classifier import classify
        from tasks.scene import Scene

        _announced = True  # the caller announces it (study.firstrun)
        t0 = time.perf_counter()
        classify(Scene("ground", 2), np.array([0.8, 1.6]), np.array([0.2, 0.6]))
    else:
        from tasks.multicontact import MultiScene, classify_multi

        _announced_others.add(kernel)
        t0 = time.perf_counter()
        scene = MultiScene.chain("ground", 2, [1, 2])
        classify_multi(scene, np.array([0.8, 1.6]), np.array([0.2, 0.6]))
    return time.perf_counter() - t0


configure()
