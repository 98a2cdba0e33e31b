"""Run outputs written as the run goes: the tracks file and checkpoint bookkeeping.

:class:`_TrackWriter` writes ``tracks.csv`` (rows appended and flushed every
scan) or ``tracks.parquet`` (one row group per :data:`PARQUET_ROW_GROUP_SCANS`
scans) and keeps the rows in memory for the metrics and plots; on resume it
keeps an existing file's rows up to the checkpoint. :func:`_save_checkpoint`
saves the tracker state and the run's bookkeeping (``FILE.run.json``: what is
being tracked, cluster timings, elapsed seconds); :func:`_load_bookkeeping`
reads it back when resuming.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from jointtrack.experiments.config import RunConfigError, _describe, _one_line
from jointtrack.trackers import JPDATracker

__all__ = ["FORMATS", "PARQUET_ROW_GROUP_SCANS"]

FORMATS = ("csv", "parquet")
PARQUET_ROW_GROUP_SCANS = 50


def _track_columns(dim: int) -> list[str]:
    c = ["x", "y", "z"][:dim]
    cov = [f"P_{c[i]}_{c[j]}" for i in range(dim) for j in range(i, dim)]
    return ["time", "track_id", *c, *(f"v{a}" for a in c), "existence", *cov]


class _TrackWriter:
    """Incremental tracks file (CSV flushed per scan, Parquet row groups per 50 scans).

    Keeps every row written in memory as well (for the metrics and plots).
    With ``resume_time`` an existing file's rows up to that time are kept.
    """

    def __init__(self, path: Path, dim: int, fmt: str, *, resume_time=None, warn=None):
        self.path = path
        self.dim = dim
        self.fmt = fmt
        self.columns = _track_columns(dim)
        self._warn = warn or (lambda msg: None)
        self._chunks: list[np.ndarray] = []  # (rows, ncols) float arrays
        self._pending: list[np.ndarray] = []
        self._pending_scans = 0
        self.n_kept_scans = 0
        kept_lines: list[str] = []
        kept = None
        if resume_time is not None and path.exists():
            kept, kept_lines = self._read_existing(resume_time)
            if kept is not None and len(kept):
                self._chunks.append(kept)
                self.n_kept_scans = int(np.unique(kept[:, 0]).size)
        if fmt == "csv":
            self._fh = open(path, "w", encoding="utf-8", newline="")
            self._fh.write(",".join(self.columns) + "\n")
            self._fh.writelines(kept_lines)
            self._fh.flush()
            self._csv = csv.writer(self._fh, lineterminator="\n")
        else:
            import pyarrow as pa
            import pyarrow.parquet as pq

            self._pa = pa
            self._schema = pa.schema(
                [(n, pa.int64() if n == "track_id" else pa.float64()) for n in self.columns]
            )
            self._writer = pq.ParquetWriter(path, self._schema)
            if kept is not None and len(kept):
                self._write_group(kept)

    def _read_existing(self, resume_time):
        """Rows of the existing file with time ≤ resume_time (array, raw CSV lines)."""
        width = len(self.columns)
        if self.fmt == "csv":
            try:
                text = self.path.read_text(encoding="utf-8")
            except (OSError, UnicodeDecodeError) as exc:
                self._warn(f"could not read {self.path} ({exc}); earlier scans are not in it")
                return None, []
            lines = text.splitlines(keepends=True)
            if not lines or lines[0].strip() != ",".join(self.columns):
                self._warn(f"{self.path} has other columns; earlier scans are not in it")
                return None, []
            keep_lines, rows = [], []
            for line in lines[1:]:
                if not line.endswith("\n"):  # a row cut short by a killed run
                    break
                fields = line.rstrip("\n").split(",")
                try:
                    vals = [float(v) for v in fields]
                except ValueError:
                    break
                if len(vals) != width:
                    break
                if vals[0] <= resume_time:
                    keep_lines.append(line)
                    rows.append(vals)
            arr = np.array(rows, dtype=float).reshape(-1, width)
            return arr, keep_lines
        try:
            import pyarrow.parquet as pq

            table = pq.read_table(self.path)
            arr = np.column_stack(
                [np.asarray(table.column(n).to_numpy(), dtype=float) for n in self.columns]
            )
        except Exception as exc:  # noqa: BLE001 - any unreadable parquet (e.g. killed run)
            self._warn(
                f"could not read {self.path} ({_one_line(exc)[:120]}); earlier scans are not in it"
            )
            return None, []
        return arr[arr[:, 0] <= resume_time], []

    def write_scan(self, t: float, res) -> None:
        k = len(res.ids)
        d = self.dim
        rows = np.empty((k, len(self.columns)))
        rows[:, 0] = t
        rows[:, 1] = res.ids
        rows[:, 2 : 2 + d] = res.x[:, :d]
        rows[:, 2 + d : 2 + 2 * d] = res.x[:, d : 2 * d]
        rows[:, 2 + 2 * d] = res.existence
        col = 3 + 2 * d
        for i in range(d):
            for j in range(i, d):
                rows[:, col] = res.P[:, i, j]
                col += 1
        self._chunks.append(rows)
        if self.fmt == "csv":
            self._csv.writerows(
                [repr(float(r[0])), str(int(r[1])), *(repr(float(v)) for v in r[2:])] for r in rows
            )
            self._fh.flush()
        else:
            self._pending.append(rows)
            self._pending_scans += 1
            if self._pending_scans >= PARQUET_ROW_GROUP_SCANS:
                self._flush_parquet()

    def _write_group(self, rows: np.ndarray) -> None:
        pa = self._pa
        arrays = [
            pa.array(rows[:, j].astype(np.int64) if n == "track_id" else rows[:, j])
            for j, n in enumerate(self.columns)
        ]
        self._writer.write_table(pa.Table.from_arrays(arrays, schema=self._schema))

    def _flush_parquet(self) -> None:
        if self._pending:
            self._write_group(np.concatenate(self._pending))
        self._pending = []
        self._pending_scans = 0

    def close(self) -> None:
        if self.fmt == "csv":
            self._fh.close()
        else:
            self._flush_parquet()
            self._writer.close()

    def table(self):
        """All rows so far as ``(times, ids, positions (R, dim))``."""
        if self._chunks:
            a = np.concatenate(self._chunks)
        else:
            a = np.zeros((0, len(self.columns)))
        return a[:, 0], a[:, 1].astype(np.int64), a[:, 2 : 2 + self.dim]


# ----------------------------------------------------------------------------- checkpoints


def _sidecar(checkpoint: Path) -> Path:
    return checkpoint.with_name(checkpoint.name + ".run.json")


def _save_checkpoint(
    trk: JPDATracker, checkpoint: Path, identity: dict, clusters: list, elapsed: float
) -> None:
    trk.save(checkpoint)
    side = _sidecar(checkpoint)
    tmp = side.with_name(side.name + ".tmp")
    tmp.write_text(
        json.dumps(
            {
                "source": identity,
                "n_scans": int(trk.n_scans),
                "time": trk.time,
                "elapsed_seconds": elapsed,
                "clusters": clusters,
            }
        ),
        encoding="utf-8",
    )
    tmp.replace(side)


def _load_bookkeeping(resume: Path, trk: JPDATracker, identity: dict, warn) -> tuple[list, float]:
    """Cluster timings and elapsed seconds saved beside the checkpoint ``resume``.

    Raises :class:`RunConfigError` when the bookkeeping is unreadable or belongs
    to another run; when it is missing or does not match the checkpoint, ``warn``
    is called and the timings start afresh (``[]``, 0.0).
    """
    clusters: list = []
    elapsed_before = 0.0
    side = _sidecar(resume)
    if side.exists():
        try:
            info = json.loads(side.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise RunConfigError(f"{side}: unreadable run bookkeeping ({exc})") from None
        if info.get("source") != identity:
            raise RunConfigError(
                f"{resume}: the checkpoint was made for {_describe(info.get('source'))}, "
                f"not {_describe(identity)}; repeat that run's --scenario/--seed/--config "
                "or --detections"
            )
        if info.get("n_scans") == trk.n_scans:
            clusters = list(info.get("clusters", []))
            elapsed_before = float(info.get("elapsed_seconds", 0.0))
        else:
            warn(f"{side} does not match the checkpoint; timings start afresh")
    else:
        warn(f"{side} not found: cannot check that the checkpoint belongs to this run")
    return clusters, elapsed_before
