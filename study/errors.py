"""Errors of the study layer: one clear line that names the offending field."""

from __future__ import annotations


class StudyError(ValueError):
    """A bad study definition or command-line input.

    ``str(error)`` is one line, ``"<source>: <field>: <message>"`` (the source is
    omitted when unknown), e.g.
    ``study.toml: scene[1].r.num: must be an integer >= 1, got -3``.
    The CLI prints it and exits with code 2.
    """

    def __init__(self, field: str, message: str, source: str | None = None) -> None:
        self.field = field
        self.message = message
        self.source = source
        super().__init__(self._line())

    def _line(self) -> str:
        parts = [p for p in (self.source, self.field, self.message) if p]
        return ": ".join(parts).replace("\n", " ")

    def with_source(self, source: str | None) -> StudyError:
        """The same error attributed to ``source`` (a file name)."""
        return StudyError(self.field, self.message, source)


class StudyInterrupted(RuntimeError):
    """The run was interrupted (Ctrl-C); completed chunks are kept on disk."""


class StudyFailed(RuntimeError):
    """A chunk failed on every retry; completed chunks are kept on disk."""


def field_error(prefix: str, exc: ValueError) -> StudyError:
    """Re-home a ``ValueError("<field>: <message>")`` from ``tasks`` under ``prefix``.

    ``tasks.Scene`` and ``tasks.fidelity.resolve`` name the field first; the
    study layer prepends where that field lives, e.g. ``scene[0].contact_mass``.
    """
    text = str(exc)
    head, sep, tail = text.partition(": ")
    if sep and head.replace("_", "").isalnum():
        return StudyError(f"{prefix}.{head}" if prefix else head, tail)
    return StudyError(prefix, text)
