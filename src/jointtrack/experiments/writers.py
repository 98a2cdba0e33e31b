"""Run outputs that survive a kill at any instant: committed track parts and checkpoints.

Rows of the tracks table are written as *parts*: ``OUT/.tracks-parts/part-NNNNNN.csv``
(or ``.parquet``), each holding the scans since the previous commit. A part is
written to a temporary file, flushed to disk and renamed into place (atomic),
and only then is the checkpoint saved — the tracker state and, in the same
checksummed file, the run's bookkeeping (:func:`_save_checkpoint`: the inputs,
the output directory and format, the number of committed parts, cluster timings).
Between commits, CSV rows are also appended to ``part-NNNNNN.csv.partial`` and
flushed every scan, so progress is visible.

A killed run therefore leaves: committed parts (all of them ≤ the checkpoint's
count are complete), possibly one part newer than the checkpoint, and possibly a
partial or temporary file. Resuming (:meth:`_TrackWriter.resume`) deletes
everything newer than the checkpoint and continues. When the run ends, the parts
are concatenated into ``OUT/tracks.csv`` (or ``tracks.parquet``) — again a
temporary file renamed into place; the parts directory is kept only while a
checkpoint can continue the run (a checkpointed run stopped early by
``--max-scans``, or killed or failed after a checkpoint) and removed otherwise:
when the run has processed every scan, and when a run without a checkpoint
ends in any way, error or Ctrl-C included. The final
file equals an uninterrupted run's row for row, whatever was killed when. An
interrupted run (Ctrl-C) also writes the rows so far to the tracks file.

Fault injection for the kill tests: the environment variable
``JOINTTRACK_FAULT=STAGE:SCAN[:SIGNAL]`` sends SIGNAL (default KILL) to the
process at STAGE (``scan``: after that scan's rows were written; ``part``: after
a part was committed, before its checkpoint; ``checkpoint``: after the
checkpoint) of scan number SCAN.
"""

from __future__ import annotations

import csv
import io
import os
import shutil
import signal
from pathlib import Path

import numpy as np

from jointtrack.trackers import JPDATracker

__all__ = ["FORMATS", "PARQUET_ROW_GROUP_SCANS", "PARTS_DIR"]

FORMATS = ("csv", "parquet")
#: Scans per row group of the final tracks.parquet (independent of the commits).
PARQUET_ROW_GROUP_SCANS = 50
PARTS_DIR = ".tracks-parts"
#: Files of earlier runs that a fresh run into the same directory replaces.
OUTPUT_NAMES = (
    "tracks.csv",
    "tracks.parquet",
    "metrics.json",
    "scene.png",
    "gospa.png",
    "map.png",  # report runs' (jointtrack.experiments.realdata)
)


def _track_columns(dim: int) -> list[str]:
    c = ["x", "y", "z"][:dim]
    cov = [f"P_{c[i]}_{c[j]}" for i in range(dim) for j in range(i, dim)]
    return ["time", "track_id", *c, *(f"v{a}" for a in c), "existence", *cov]


def _fsync_dir(path: Path) -> None:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def fault(stage: str, scan: int) -> None:
    """Fault-injection point (see the module docstring); a no-op unless requested."""
    spec = os.environ.get("JOINTTRACK_FAULT")
    if not spec:
        return
    parts = spec.split(":")
    if parts[0] == stage and int(parts[1]) == scan:
        sig = getattr(signal, "SIG" + (parts[2] if len(parts) > 2 else "KILL"))
        os.kill(os.getpid(), sig)


class _TrackWriter:
    """Tracks table written as committed parts (see the module docstring).

    Keeps every row in memory as well (for the metrics and plots).
    """

    def __init__(self, out_dir: Path, dim: int, fmt: str, scan_times=None):
        self.out_dir = Path(out_dir)
        # the run's scan times: Parquet row groups hold PARQUET_ROW_GROUP_SCANS scans each
        self.scan_times = None if scan_times is None else np.asarray(scan_times, float)
        self.dim = dim
        self.fmt = fmt
        self.columns = _track_columns(dim)
        self.parts_dir = self.out_dir / PARTS_DIR
        self.path = self.out_dir / f"tracks.{'csv' if fmt == 'csv' else 'parquet'}"
        self._chunks: list[np.ndarray] = []  # committed rows
        self._pending: list[np.ndarray] = []  # rows since the last commit
        self.n_parts = 0
        self._partial = None  # open handle of the visible CSV partial part

    # ----------------------------------------------------------------- lifecycle
    def start_fresh(self) -> None:
        """A new run: remove this tool's outputs and parts of an earlier run."""
        if self.parts_dir.exists():
            shutil.rmtree(self.parts_dir)
        for name in OUTPUT_NAMES:
            (self.out_dir / name).unlink(missing_ok=True)
        self.parts_dir.mkdir(parents=True)

    def resume(self, n_parts: int) -> None:
        """Continue after ``n_parts`` committed parts: drop everything newer, reload the rows."""
        if not self.parts_dir.is_dir():
            raise ValueError(
                f"{self.parts_dir} is missing: the checkpoint's committed tracks are gone, "
                "so the run cannot be resumed exactly; start it again"
            )
        for p in self.parts_dir.iterdir():
            idx = self._part_index(p)
            if idx is None or idx >= n_parts or not p.name.endswith(self._ext):
                p.unlink()
        for k in range(n_parts):
            p = self._part_path(k)
            if not p.exists():
                raise ValueError(f"{p} is missing: the run cannot be resumed exactly")
            self._chunks.append(self._read_part(p))
        self.n_parts = n_parts
        for name in OUTPUT_NAMES:  # stale outputs of the interrupted run
            (self.out_dir / name).unlink(missing_ok=True)

    @property
    def _ext(self) -> str:
        return ".csv" if self.fmt == "csv" else ".parquet"

    def _part_path(self, k: int) -> Path:
        return self.parts_dir / f"part-{k:06d}{self._ext}"

    @staticmethod
    def _part_index(p: Path):
        name = p.name
        if not name.startswith("part-"):
            return None
        try:
            return int(name[5:11])
        except ValueError:
            return None

    # ----------------------------------------------------------------- rows
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
        self._pending.append(rows)
        if self.fmt == "csv":
            if self._partial is None:
                partial = self._part_path(self.n_parts).with_name(
                    self._part_path(self.n_parts).name + ".partial"
                )
                self._partial = open(partial, "w", encoding="utf-8", newline="")
            self._partial.write(self._csv_text(rows, header=False))
            self._partial.flush()

    def _csv_text(self, rows: np.ndarray, header: bool) -> str:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        if header:
            w.writerow(self.columns)
        w.writerows(
            [repr(float(r[0])), str(int(r[1])), *(repr(float(v)) for v in r[2:])] for r in rows
        )
        return buf.getvalue()

    def _write_atomic(self, path: Path, rows: np.ndarray, header: bool = True) -> None:
        tmp = path.with_name(path.name + ".tmp")
        if self.fmt == "csv":
            with open(tmp, "w", encoding="utf-8", newline="") as fh:
                fh.write(self._csv_text(rows, header))
                fh.flush()
                os.fsync(fh.fileno())
        else:
            import pyarrow as pa
            import pyarrow.parquet as pq

            schema = pa.schema(
                [(n, pa.int64() if n == "track_id" else pa.float64()) for n in self.columns]
            )
            arrays = [
                pa.array(rows[:, j].astype(np.int64) if n == "track_id" else rows[:, j])
                for j, n in enumerate(self.columns)
            ]
            table = pa.Table.from_arrays(arrays, schema=schema)
            # row groups of PARQUET_ROW_GROUP_SCANS scans, wherever the commits fell
            step = PARQUET_ROW_GROUP_SCANS
            bounds = (
                self.scan_times[step::step]
                if self.scan_times is not None
                else np.unique(rows[:, 0])[step::step]
            )
            cuts = [*np.searchsorted(rows[:, 0], bounds, side="left"), len(rows)]
            with open(tmp, "wb") as fh:
                with pq.ParquetWriter(fh, schema) as pw:
                    lo = 0
                    for hi in cuts:
                        pw.write_table(table.slice(lo, hi - lo))
                        lo = hi
                fh.flush()
                os.fsync(fh.fileno())
        os.replace(tmp, path)
        _fsync_dir(path.parent)

    def _read_part(self, p: Path) -> np.ndarray:
        width = len(self.columns)
        if self.fmt == "csv":
            lines = p.read_text(encoding="utf-8").splitlines()
            if not lines or lines[0] != ",".join(self.columns):
                raise ValueError(f"{p} is not a part of this run's tracks table")
            rows = [[float(v) for v in line.split(",")] for line in lines[1:]]
            return np.array(rows, dtype=float).reshape(-1, width)
        import pyarrow.parquet as pq

        table = pq.read_table(p)
        if table.column_names != self.columns:
            raise ValueError(f"{p} is not a part of this run's tracks table")
        return np.column_stack(
            [np.asarray(table.column(n).to_numpy(), dtype=float) for n in self.columns]
        ).reshape(-1, width)

    def _pending_rows(self) -> np.ndarray:
        if self._pending:
            return np.concatenate(self._pending)
        return np.zeros((0, len(self.columns)))

    def commit(self) -> int:
        """Make the rows since the last commit a durable part; returns the parts count."""
        rows = self._pending_rows()
        self._write_atomic(self._part_path(self.n_parts), rows)
        if self._partial is not None:
            name = self._partial.name
            self._partial.close()
            self._partial = None
            Path(name).unlink(missing_ok=True)
        self._chunks.append(rows)
        self._pending = []
        self.n_parts += 1
        return self.n_parts

    def finish(self, keep_parts: bool) -> None:
        """Commit what is pending and write the tracks file atomically.

        ``keep_parts``: keep the committed parts (a checkpointed run can then be
        continued, e.g. with a larger ``--max-scans``); otherwise remove them.
        """
        if self._pending or self.n_parts == 0:
            self.commit()
        self._write_atomic(self.path, self.rows())
        if not keep_parts:
            shutil.rmtree(self.parts_dir, ignore_errors=True)

    def discard_parts(self) -> None:
        """Remove the parts directory (a failed run without a checkpoint: nothing can
        resume from them; the tracks so far are in the tracks file after a Ctrl-C)."""
        self.close()
        shutil.rmtree(self.parts_dir, ignore_errors=True)

    def snapshot(self) -> None:
        """Write every row so far to the tracks file (an interrupted run shows its progress);
        the parts are left as they are, so a resume continues from the checkpoint."""
        self._write_atomic(self.path, self.rows())

    def close(self) -> None:
        """Close the visible partial file (on any exit; committed parts stay)."""
        if self._partial is not None:
            self._partial.close()
            self._partial = None

    def rows(self) -> np.ndarray:
        chunks = self._chunks + self._pending
        if chunks:
            return np.concatenate(chunks)
        return np.zeros((0, len(self.columns)))

    def table(self):
        """All rows so far as ``(times, ids, positions (R, dim))``."""
        a = self.rows()
        return a[:, 0], a[:, 1].astype(np.int64), a[:, 2 : 2 + self.dim]


# ----------------------------------------------------------------------------- checkpoints


def _save_checkpoint(trk: JPDATracker, checkpoint: Path, run: dict) -> None:
    """Tracker state and the run's bookkeeping, one atomic checksummed file."""
    trk.save(checkpoint, run=run)
