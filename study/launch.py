"""The ``study`` command's entry point, light enough to hold a Ctrl-C at the start.

The command line imports numba, scipy, xarray and Dask before it can handle anything.
A SIGINT that lands while a compiled extension initialises does not arrive as
:class:`KeyboardInterrupt`: the extension's import fails with ``ImportError:
initialization failed`` and a traceback. So the import runs with SIGINT deferred
(recorded, not raised), and a Ctrl-C during it ends the command with the same one
line and exit code 130 as a Ctrl-C later on.
"""

from __future__ import annotations

import signal
import sys

INTERRUPTED = "study: interrupted"


def main() -> int:
    """Import :mod:`study.cli` with SIGINT deferred, then run the command line.

    The command imports its heavy modules (numpy, numba, xarray, Dask) only when it
    needs them, with SIGINT live: there a Ctrl-C raises :class:`KeyboardInterrupt`
    as usual, and is also recorded, so that an :class:`ImportError` it caused inside
    a compiled extension's initialisation ends the command as interrupted too."""
    caught: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        from study.cli import main as command
    finally:
        signal.signal(signal.SIGINT, previous)

    def interrupt(signum, frame) -> None:
        caught.append(signum)
        raise KeyboardInterrupt

    live = signal.getsignal(signal.SIGINT)
    if live is signal.default_int_handler:
        signal.signal(signal.SIGINT, interrupt)
    try:
        if caught:
            raise KeyboardInterrupt
        return command()
    except KeyboardInterrupt:
        print(INTERRUPTED, file=sys.stderr)
        return 130
    except ImportError:
        if not caught:  # a real one: its traceback says what is missing
            raise
        print(INTERRUPTED, file=sys.stderr)
        return 130
    finally:
        signal.signal(signal.SIGINT, live)
