"""The results store of a sweep: one Parquet dataset directory, one small file per run.

Each finished run is one row in its own file ``<run_id>.parquet``, written to a
temporary name in the same directory, flushed to disk and renamed into place
(``os.replace``, atomic). So a kill at any instant leaves either the whole file
or none, never a partial one; and since a run's file name is its id, a run can
never have two rows — writing it again (a failed run retried on resume)
replaces the old row. Only the sweep's driver writes here, never a worker.

The directory reads as one dataset (``pyarrow.dataset.dataset(path)`` or
:func:`read_rows`); leftover temporary files (``.*.tmp``) from a kill are
ignored and removed on the next open.
"""

from __future__ import annotations

import os
from pathlib import Path

from jointtrack._atomic import atomic_file

__all__ = ["ResultStore"]

_SUFFIX = ".parquet"
_STRING_COLUMNS = {
    "run_id",
    "cell_id",
    "method",
    "params",
    "status",
    "error",
    "kind",
    "version",
    "host",
    "worker",
}
_INT_COLUMNS = {"seed", "pid"}
_FLOAT_COLUMNS = {
    "run_seconds",
    "queue_seconds",
    "overhead_seconds",
    "submitted_at",
    "started_at",
    "finished_at",
}


class ResultStore:
    """A sweep's Parquet dataset directory.

    Parameters
    ----------
    path : the directory (created).
    """

    def __init__(self, path):
        self.path = Path(path)
        if self.path.exists() and not self.path.is_dir():
            raise ValueError(f"out: {self.path} exists and is not a directory")
        self.path.mkdir(parents=True, exist_ok=True)
        for stale in self.path.glob(".*.tmp"):
            stale.unlink(missing_ok=True)  # a write interrupted before its rename

    def _file(self, run_id: str) -> Path:
        return self.path / f"{run_id}{_SUFFIX}"

    def write(self, row: dict) -> Path:
        """Write one run's row atomically (replacing an earlier row of the same run).

        ``row`` is a flat dict of column → scalar (str, int, float, bool or
        None); ``row["run_id"]`` names the file.
        """
        import pyarrow as pa
        import pyarrow.parquet as pq

        run_id = row.get("run_id")
        if not isinstance(run_id, str) or not run_id.isalnum():
            raise ValueError(f"row: run_id must be an alphanumeric string, got {run_id!r}")
        # fixed types for the bookkeeping and metric columns, so that a failed run's
        # row (no metrics, an error text) and an ok row read as one dataset
        fields = []
        for key, value in row.items():
            if key in _STRING_COLUMNS:
                typ = pa.string()
            elif key in _INT_COLUMNS:
                typ = pa.int64()
            elif key in _FLOAT_COLUMNS or key.startswith("metric."):
                typ = pa.float64()
            elif isinstance(value, int | float) and not isinstance(value, bool):
                # a parameter column: an axis like [0.5, 1, 2] mixes int and float
                # values, and files of one column must agree on its type; the exact
                # values (1, not 1.0) stay in the row's "params" JSON
                typ = pa.float64()
            else:
                typ = pa.array([value]).type
            fields.append(pa.field(key, typ))
        table = pa.Table.from_pylist([row], schema=pa.schema(fields))
        final = self._file(run_id)
        tmp = self.path / f".{run_id}.{os.getpid()}.tmp"
        with atomic_file(final, tmp) as part, open(part, "wb") as fh:
            pq.write_table(table, fh)
        return final

    def run_ids(self, status: str | None = None) -> set[str]:
        """Ids of the runs with a row (only those with ``status`` when given)."""
        if status is None:
            return {p.name[: -len(_SUFFIX)] for p in self.path.glob(f"*{_SUFFIX}")}
        return {r["run_id"] for r in self.read_rows() if r.get("status") == status}

    def read_rows(self) -> list[dict]:
        """Every row, as dicts (columns absent from a row's file are missing from it)."""
        import pyarrow.parquet as pq

        rows = []
        for p in sorted(self.path.glob(f"*{_SUFFIX}")):
            rows.extend(pq.read_table(p).to_pylist())
        return rows
