"""Errors of :mod:`jointtrack.io`: one-line messages naming the file, row and column."""

from __future__ import annotations

__all__ = ["DataFileError", "DetectionFileError", "TrackFileError", "TruthFileError"]


class DataFileError(ValueError):
    """A data file that cannot be used; the message is one line naming file and row.

    Attributes: ``path``, ``reason`` and, when known, ``row`` (1-based data
    row), ``line`` (1-based physical line, CSV only) and ``column``.
    """

    def __init__(
        self,
        path,
        reason: str,
        *,
        row: int | None = None,
        line: int | None = None,
        column: str | None = None,
    ):
        self.path = str(path)
        self.reason = reason
        self.row = row
        self.line = line
        self.column = column
        where = []
        if line is not None and row is not None:
            where.append(f"line {line} (data row {row})")
        elif row is not None:
            where.append(f"data row {row}")
        elif line is not None:
            where.append(f"line {line}")
        if column is not None:
            where.append(f"column '{column}'")
        prefix = ", ".join([self.path, *where])
        super().__init__(f"{prefix}: {reason}")


class DetectionFileError(DataFileError):
    """Raised by :func:`jointtrack.io.read_detections` for a bad detections file."""


class TrackFileError(DataFileError):
    """Raised by :func:`jointtrack.io.read_tracks` for a bad tracks file."""


class TruthFileError(DataFileError):
    """Raised by :func:`jointtrack.io.read_truth` for a bad truth file."""
