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
    """Import :mod:`study.cli` with SIGINT deferred, then run the command line."""
    caught: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        from study.cli import main as command
    finally:
        signal.signal(signal.SIGINT, previous)
    try:
        if caught:
            raise KeyboardInterrupt
        return command()
    except KeyboardInterrupt:
        print(INTERRUPTED, file=sys.stderr)
        return 130
