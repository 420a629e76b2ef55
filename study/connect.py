"""Connecting to a running Dask scheduler, bounded in time.

A scheduler that does not answer must never keep the run waiting in silence:
an address that accepts the TCP connection but never speaks Dask's protocol, a
scheduler file naming one, a scheduler that is stopped (SIGSTOP), swapped out or
overloaded. ``distributed.Client(address, timeout=...)`` alone can wait for ever
in such cases, so :func:`connect`

1. reads the address (from ``scheduler_file`` if given: a regular JSON file
   written by ``dask scheduler --scheduler-file``),
2. asks the scheduler for its identity on a connection of its own, within
   ``timeout`` seconds (this catches a silent peer cleanly, nothing left
   behind), then
3. builds the ``Client``, again within ``timeout`` seconds.

Any failure raises :class:`~study.errors.StudyError` naming the option
(``--scheduler`` or ``--scheduler-file``) in one line; the CLI exits with code 2
and nothing is written.

Timeouts (seconds, CLI ``study run --scheduler-timeout``):

* :data:`DEFAULT_SCHEDULER_TIMEOUT` (30 s): connecting, and, during the run,
  how long the scheduler may stay silent or unreachable before the run stops
  with :class:`~study.errors.StudyFailed` (exit 1, finished chunks kept;
  :mod:`study.watchdog`);
* at most :data:`MAX_SCHEDULER_TIMEOUT` (one day).

:func:`call_within` runs any blocking call of the client (cancel, close) with a
bound, for the moments the scheduler may already be silent.
"""

from __future__ import annotations

import asyncio
import math
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

from study.errors import StudyError

T = TypeVar("T")

#: Default of ``--scheduler-timeout``: seconds a scheduler may take to answer.
DEFAULT_SCHEDULER_TIMEOUT = 30.0
#: Largest ``--scheduler-timeout``, in seconds (one day).
MAX_SCHEDULER_TIMEOUT = 86_400.0


def check_timeout(value: object, flag: str, maximum: float = MAX_SCHEDULER_TIMEOUT) -> float:
    """A number of seconds in ``(0, maximum]`` (raises :class:`StudyError` naming ``flag``)."""
    ok = isinstance(value, int | float) and not isinstance(value, bool)
    if not ok or not math.isfinite(value) or not 0 < value <= maximum:
        raise StudyError(flag, f"must be a number of seconds in (0, {maximum:g}], got {value!r}")
    return float(value)


def call_within(seconds: float, func: Callable[..., T], /, *args: Any, **kwargs: Any) -> T:
    """``func(*args, **kwargs)``, or :class:`TimeoutError` after ``seconds``.

    The call runs in a daemon thread; when it does not return in time it is left
    there (it may never return: a blocked socket read) and the caller goes on.
    Exceptions of ``func`` are raised here.
    """
    box: dict[str, Any] = {}
    done = threading.Event()

    def run() -> None:
        try:
            box["value"] = func(*args, **kwargs)
        except BaseException as exc:  # noqa: BLE001 - handed to the caller
            box["error"] = exc
        finally:
            done.set()

    threading.Thread(target=run, name="study-bounded-call", daemon=True).start()
    if not done.wait(seconds):
        raise TimeoutError(f"no answer within {seconds:g} s")
    if "error" in box:
        raise box["error"]
    return box["value"]


async def _identity(address: str, timeout: float) -> dict:
    """The scheduler's answer to ``identity`` on a connection of our own."""
    from distributed.comm import connect as comm_connect

    comm = await comm_connect(address, timeout=timeout)
    try:
        await comm.write({"op": "identity", "reply": True})
        return await comm.read()
    finally:
        comm.abort()


def probe(address: str, timeout: float) -> dict:
    """Ask the scheduler at ``address`` who it is; :class:`TimeoutError` after ``timeout`` s.

    Runs on a fresh event loop in a helper thread, so it works whether or not
    the caller runs an event loop; a silent peer is abandoned cleanly.
    """

    async def bounded() -> dict:
        return await asyncio.wait_for(_identity(address, timeout), timeout)

    return call_within(timeout + 5.0, asyncio.run, bounded())


def scheduler_address(scheduler_file: str | Path) -> str:
    """The address written in a scheduler file (a regular JSON file)."""
    from study.preflight import check_scheduler_file

    return check_scheduler_file(str(scheduler_file))


def _reason(exc: BaseException) -> str:
    if isinstance(exc, TimeoutError | asyncio.TimeoutError):
        return "no answer (the address is not a Dask scheduler, or it is stopped or overloaded)"
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text[:160]}" if text else type(exc).__name__


def connect(
    address: str | None = None,
    scheduler_file: str | Path | None = None,
    timeout: float = DEFAULT_SCHEDULER_TIMEOUT,
):
    """A ``distributed.Client`` of the running scheduler at ``address`` or in ``scheduler_file``.

    Parameters
    ----------
    address : str, optional
        Scheduler address, e.g. ``tcp://10.0.0.5:8786`` (CLI ``--scheduler``).
    scheduler_file : path, optional
        JSON file written by ``dask scheduler --scheduler-file`` (CLI
        ``--scheduler-file``). Exactly one of ``address`` and ``scheduler_file``.
    timeout : float
        Seconds, in ``(0, MAX_SCHEDULER_TIMEOUT]``, for the scheduler to answer
        the probe, and again for the client to connect (so at most about twice
        ``timeout`` in all).

    Returns
    -------
    distributed.Client
        Connected; the caller closes it.

    Raises
    ------
    StudyError
        Naming the option: no such or no valid scheduler file, an address that
        refuses the connection, or no answer within ``timeout`` seconds.
    """
    if (address is None) == (scheduler_file is None):
        raise StudyError("--scheduler", "give exactly one of a scheduler address or file")
    flag = "--scheduler" if address is not None else "--scheduler-file"
    timeout = check_timeout(timeout, "--scheduler-timeout")
    if address is None:
        address = scheduler_address(scheduler_file)
    if not isinstance(address, str) or not address:
        raise StudyError(
            flag, f"must be a scheduler address such as tcp://host:8786, got {address!r}"
        )
    where = address if scheduler_file is None else f"{address} (from {scheduler_file})"
    try:
        probe(address, timeout)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        raise StudyError(
            flag, f"cannot connect to {where} within {timeout:g} s: {_reason(exc)}"
        ) from None
    from distributed import Client

    try:
        return call_within(timeout, Client, address, timeout=f"{timeout}s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise StudyError(
            flag, f"cannot connect to {where} within {timeout:g} s: {_reason(exc)}"
        ) from None
