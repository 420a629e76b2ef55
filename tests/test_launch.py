"""study.launch: a Ctrl-C that a compiled extension's initialisation turns into an
ImportError (numpy's "PyCapsule_Import could not import module datetime", seen on
CI 0.05 s after the start) ends the command as interrupted, in one line; a real
ImportError keeps its traceback."""

from __future__ import annotations

import os
import signal

import pytest

import study.cli
from study import launch


def _extension_init_interrupted() -> int:
    """What a C extension does with a KeyboardInterrupt raised inside its init."""
    try:
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(10**6):  # the handler runs between bytecodes
            pass
    except KeyboardInterrupt:
        raise ImportError("initialization failed") from None
    return 0


@pytest.fixture
def default_sigint(monkeypatch):
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


def test_an_import_broken_by_ctrl_c_is_an_interruption(monkeypatch, capsys, default_sigint):
    monkeypatch.setattr(study.cli, "main", _extension_init_interrupted)
    assert launch.main() == 130
    assert capsys.readouterr().err.splitlines() == [launch.INTERRUPTED]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # restored


def test_a_real_import_error_is_not_hidden(monkeypatch, default_sigint):
    def missing() -> int:
        raise ImportError("No module named 'netCDF4'")

    monkeypatch.setattr(study.cli, "main", missing)
    with pytest.raises(ImportError, match="netCDF4"):
        launch.main()
