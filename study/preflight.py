"""Checks of a run's command-line inputs before any cluster starts or any point is computed.

* the output (``-o``): a regular file path (or a new name) in an existing,
  writable directory; never a directory, FIFO, device or socket; its name short
  enough for the temporary and work-folder names derived from it;
* ``--scheduler-file``: a readable JSON file naming a scheduler address;
* ``--workers``: at most :data:`MAX_WORKERS_PER_CORE` local worker processes
  per core (the numerics hold one core each), at most :data:`MAX_REMOTE_WORKERS`
  awaited on a running scheduler;
* ``--retries`` in 0..:data:`MAX_RETRIES`; ``--worker-timeout`` in
  (0, :data:`MAX_WORKER_TIMEOUT`] seconds.

Each failure raises :class:`~study.errors.StudyError` naming the option (exit 2).
"""

from __future__ import annotations

import json
import os
import stat
import tempfile
import time
from pathlib import Path

from study.errors import StudyError

#: Local worker processes per core at most (``--workers``).
MAX_WORKERS_PER_CORE = 4
#: Workers a run may wait for on a running scheduler (``--workers`` with ``--scheduler``).
MAX_REMOTE_WORKERS = 100_000
#: Retries of a failing task at most (``--retries``).
MAX_RETRIES = 100
#: Longest wait without any worker, in seconds (``--worker-timeout``): one day.
MAX_WORKER_TIMEOUT = 86_400.0
#: Characters added to the output's name by the temporary and work-folder names
#: (``.NAME.PID.tmp``, ``NAME.work``).
_NAME_OVERHEAD = 20


def default_workers() -> int:
    """Cores available to this process."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _kind(mode: int) -> str | None:
    """What a non-regular file is, or None for a regular file."""
    for test, what in (
        (stat.S_ISDIR, "a directory"),
        (stat.S_ISFIFO, "a FIFO (named pipe)"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return what
    return None if stat.S_ISREG(mode) else "not a regular file"


def check_output(output: str | os.PathLike) -> Path:
    """The output path, checked: a regular file (or a new name) in a writable directory."""
    output = Path(output)
    parent = output.parent
    if not parent.is_dir():
        raise StudyError("-o", f"output directory does not exist: {parent}")
    try:
        st = os.stat(output)  # follows a symbolic link: what would be replaced
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise StudyError("-o", f"cannot use {output}: {exc.strerror}") from None
    if st is not None and (what := _kind(st.st_mode)):
        raise StudyError("-o", f"output must be a regular file, but {output} is {what}")
    try:
        name_max = os.pathconf(parent, "PC_NAME_MAX")
    except (OSError, ValueError):
        name_max = 255
    if len(os.fsencode(output.name)) + _NAME_OVERHEAD > name_max:
        raise StudyError(
            "-o",
            f"output file name too long ({len(output.name)} characters; at most "
            f"{name_max - _NAME_OVERHEAD} here)",
        )
    work = output.with_name(output.name + ".work")
    if work.exists() and not work.is_dir():
        raise StudyError("-o", f"{work} (the work folder of the output) is not a directory")
    try:  # the only sure test (root ignores permission bits, a file system may be read-only)
        fd, probe = tempfile.mkstemp(prefix=f".{output.name[:50]}.", suffix=".probe", dir=parent)
    except OSError as exc:
        raise StudyError(
            "-o", f"cannot write in the output directory {parent}: {exc.strerror}"
        ) from None
    os.close(fd)
    os.unlink(probe)
    return output


def check_scheduler_file(path: str) -> str:
    """The scheduler address a scheduler file names (raises for anything else)."""
    flag = "--scheduler-file"
    p = Path(path)
    if not p.is_file():
        raise StudyError(flag, f"no such scheduler file: {path}")
    try:
        info = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise StudyError(
            flag, f"not a scheduler file (JSON with an address): {path}: {msg}"
        ) from None
    address = info.get("address") if isinstance(info, dict) else None
    if not isinstance(address, str) or "://" not in address:
        raise StudyError(flag, f"not a scheduler file (no scheduler address in it): {path}")
    return address


def check_options(
    *,
    workers: int | None,
    local: bool,
    retries: int,
    worker_timeout: float,
    cores: int,
) -> None:
    """``--workers``, ``--retries`` and ``--worker-timeout`` in their ranges."""
    if workers is not None:
        top = MAX_WORKERS_PER_CORE * cores if local else MAX_REMOTE_WORKERS
        why = f"{MAX_WORKERS_PER_CORE} per core, {cores} cores" if local else "on a scheduler"
        if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= top:
            raise StudyError("--workers", f"must be an integer in 1..{top} ({why}), got {workers}")
    if isinstance(retries, bool) or not isinstance(retries, int) or not 0 <= retries <= MAX_RETRIES:
        raise StudyError("--retries", f"must be an integer in 0..{MAX_RETRIES}, got {retries}")
    ok = isinstance(worker_timeout, int | float) and not isinstance(worker_timeout, bool)
    if not ok or not 0 < worker_timeout <= MAX_WORKER_TIMEOUT:
        raise StudyError(
            "--worker-timeout",
            f"must be a number of seconds in (0, {MAX_WORKER_TIMEOUT:g}], got {worker_timeout}",
        )


def older_result_note(output: str | os.PathLike) -> str:
    """What an unfinished run left at ``output``: the older result, or nothing."""
    output = Path(output)
    try:
        st = output.stat()
    except OSError:
        return "no result file was written"
    when = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(st.st_mtime))
    return f"no new result was written; the older {output} (of {when}) is still in place"


def check_run(
    output: str | os.PathLike | None,
    client,
    scheduler: str | None,
    scheduler_file: str | None,
    workers: int | None,
    retries: int,
    worker_timeout: float,
) -> None:
    """Every check of :func:`study.run.run_study`'s inputs that needs no cluster."""
    local = client is None and not (scheduler or scheduler_file)
    check_options(
        workers=workers,
        local=local,
        retries=retries,
        worker_timeout=worker_timeout,
        cores=default_workers(),
    )
    if output is not None:  # None: an in-memory run writes nothing
        check_output(output)
    if scheduler_file and client is None:
        check_scheduler_file(scheduler_file)
