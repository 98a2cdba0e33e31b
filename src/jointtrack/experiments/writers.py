"""Run outputs that survive a kill at any instant: committed track parts, checkpoints
and a finishing phase that resumes.

Rows of the tracks table are written as *parts*: ``OUT/.tracks-parts/part-NNNNNN.csv``
(or ``.parquet``), each holding the scans since the previous commit. A part is
written to a temporary file, flushed to disk and renamed into place (atomic,
:func:`atomic_output`), and only then is the checkpoint saved — the tracker state
and, in the same checksummed file, the run's bookkeeping (:func:`_save_checkpoint`:
the inputs, the output directory and format, the number of committed parts,
cluster timings, the phase). Between commits, CSV rows are also appended to
``part-NNNNNN.csv.partial`` and flushed every scan, so progress is visible.

A killed run therefore leaves: committed parts (all of them ≤ the checkpoint's
count are complete), possibly one part newer than the checkpoint, and possibly a
partial or temporary file. Resuming (:meth:`_TrackWriter.resume`) deletes
everything newer than the checkpoint and continues.

The finishing phase. Once the run's last scan is committed, the checkpoint says
``phase = "finishing"``; then every output — the tracks file (``tracks.csv`` or
``tracks.parquet``, the parts concatenated, with a report run's ``lat, lon``
columns), the figures, ``metrics.json`` last — is written once, in its final form,
each to a temporary file that is flushed and renamed into place, and after each the
checkpoint records it in ``outputs_done``. Then the checkpoint says ``phase =
"done"`` and only after that are the parts removed (a run stopped early by
``--max-scans`` keeps them: a resume can extend it). A resume in the finishing
phase writes exactly the outputs not yet recorded (or no longer there); a resume of
a done run whose outputs are all there has nothing to do
(:class:`RunAlreadyComplete`). The parts directory is removed also when a run
without a checkpoint ends in any way, error or Ctrl-C included. The final files
equal an uninterrupted run's byte for byte, whatever was killed when. An
interrupted run (Ctrl-C) while tracking also writes the rows so far to the tracks
file.

Fault injection for the kill tests: the environment variable
``JOINTTRACK_FAULT=STAGE:N[:SIGNAL]`` sends SIGNAL (default KILL) to the process at
STAGE of scan or output number N. Tracking stages (N = the scan): ``scan`` (after
that scan's rows were written), ``part`` (after a part was committed, before its
checkpoint), ``checkpoint`` (after the checkpoint). Finishing stages:
``finishing:0`` (after the checkpoint that starts the finishing phase), and for
output N of the phase (in the order of ``outputs`` in the checkpoint: the tracks
file first, metrics.json last) ``write`` (its temporary file complete, not yet
renamed), ``output`` (renamed into place, not yet recorded) and ``recorded``
(recorded in the checkpoint); ``done:0`` (after the checkpoint that says the run is
done, before the parts are removed) and ``cleanup:N`` (after the N-th part was
removed).
"""

from __future__ import annotations

import csv
import io
import os
import shutil
import signal
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from jointtrack._atomic import atomic_file
from jointtrack.experiments.config import RunConfigError

if TYPE_CHECKING:
    from jointtrack.trackers import JPDATracker

__all__ = [
    "FORMATS",
    "PARQUET_ROW_GROUP_SCANS",
    "PARTS_DIR",
    "PHASES",
    "ExtraOutputs",
    "RunAlreadyComplete",
    "atomic_output",
    "check_run_phase",
    "run_is_complete",
]

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
#: A run's phases, as its checkpoint records them (``phase``; see the module docstring).
#: Checkpoints written before the finishing phase was recorded have no ``phase``.
PHASES = ("tracking", "finishing", "done")


class RunAlreadyComplete(RunConfigError):
    """``resume`` of a run that has written every output: there is nothing to do.

    Not a failure: ``jointtrack run --resume`` reports it and exits 0. ``metrics``:
    the run's ``metrics.json`` as it was written.
    """

    def __init__(self, message: str, metrics: dict):
        super().__init__(message)
        self.metrics = metrics


@dataclass(frozen=True)
class ExtraOutputs:
    """What a caller adds to a run's outputs (report runs:
    :func:`jointtrack.experiments.realdata.run_reports`).

    Everything here is computed from the run's tracks alone, so a run resumed in
    its finishing phase writes the same files.

    ``frame``: a :class:`~jointtrack.io.geodetic.LocalFrame` that ``x, y`` are
    metres in, or None; the tracks file then has ``lat, lon`` columns after ``y``
    (:func:`jointtrack.io.tracks.with_geodetic_columns`), written once, in that form.
    ``metrics(metrics, tracks)``: adds entries to the metrics dict in place (writes
    no file). ``figures``: ``(file name, key of metrics.json "files", draw)`` drawn
    when the run draws its plots, ``draw(path, tracks)`` writing the figure to the
    (temporary) path given, whose suffix is the file name's.
    """

    frame: object | None = None
    metrics: Callable[[dict, tuple], None] | None = None
    figures: tuple[tuple[str, str, Callable[[Path, tuple], object]], ...] = field(default=())


def _track_columns(dim: int, mode_names=()) -> list[str]:
    c = ["x", "y", "z"][:dim]
    cov = [f"P_{c[i]}_{c[j]}" for i in range(dim) for j in range(i, dim)]
    modes = [f"mode_{m}" for m in mode_names]  # an IMM's mode probabilities
    return ["time", "track_id", *c, *(f"v{a}" for a in c), "existence", *cov, *modes]


def mode_names_of(config) -> tuple:
    """The IMM mode names of a tracker configuration (``motion = "imm"``), else ()."""
    if getattr(config, "motion", None) != "imm":
        return ()
    return tuple(getattr(config, "imm_modes", ()))  # a PMB/PMBM config refuses imm later


def _temporary_name(path: Path) -> Path:
    """The temporary file beside ``path`` that :func:`atomic_output` renames into place:
    hidden, and with ``path``'s suffix (matplotlib picks the image format by it)."""
    return path.with_name(f".{path.stem}.tmp{path.suffix}")


@contextmanager
def atomic_output(path, stage: tuple[str, int] | None = None) -> Iterator[Path]:
    """Write the file ``path`` atomically: the body writes the path yielded (a temporary
    file beside ``path``), which is then flushed to disk and renamed over ``path``, and
    the rename made durable. If the body fails, the temporary file is removed and
    ``path`` is as it was. ``stage``: a fault-injection point (:func:`fault`) between
    the complete temporary file and the rename."""
    path = Path(path)
    hook = None if stage is None else (lambda: fault(*stage))
    with atomic_file(path, _temporary_name(path), before_rename=hook) as tmp:
        yield tmp


def fault(stage: str, scan: int) -> None:
    """Fault-injection point (see the module docstring); a no-op unless requested."""
    spec = os.environ.get("JOINTTRACK_FAULT")
    if not spec:
        return
    parts = spec.split(":")
    if parts[0] == stage and int(parts[1]) == scan:
        sig = getattr(signal, "SIG" + (parts[2] if len(parts) > 2 else "KILL"))
        os.kill(os.getpid(), sig)


def check_run_phase(path, info: dict) -> None:
    """The finishing-phase bookkeeping of a checkpoint (``phase``, ``outputs``,
    ``outputs_done``, ``stop``, ``n_scans_total``) is well formed, else a
    :class:`RunConfigError` naming the file and the field (the checkpoint is
    checksummed, so this guards against a writer's bug, not damage)."""

    def bad(what: str) -> RunConfigError:
        return RunConfigError(f"{path}: the checkpoint's run bookkeeping {what}")

    phase = info.get("phase")
    if phase is None:
        return  # written before the phase was recorded: a tracking checkpoint
    if phase not in PHASES:
        raise bad(f"has phase {phase!r}, not one of {', '.join(PHASES)}")
    for key in ("outputs", "outputs_done"):
        names = info.get(key)
        if not isinstance(names, list) or not all(n in OUTPUT_NAMES for n in names):
            raise bad(f"{key} = {names!r} is not a list of output file names")
    for key in ("stop", "n_scans_total"):
        value = info.get(key)
        if type(value) is not int or value < 0:
            raise bad(f"{key} = {value!r} is not a number of scans")


def run_is_complete(info: dict, parts_dir: Path) -> bool:
    """Whether a checkpoint's run has processed every scan and written every output
    (nothing can continue it). A checkpoint written before the phase was recorded:
    complete when the parts are gone (its run removed them at the end)."""
    if info.get("phase") is None:
        return not parts_dir.is_dir()
    return info["phase"] == "done" and info.get("stop") == info.get("n_scans_total")


class _TrackWriter:
    """Tracks table written as committed parts (see the module docstring).

    Keeps every row in memory as well (for the metrics and plots). ``frame``: a
    :class:`~jointtrack.io.geodetic.LocalFrame` whose ``lat, lon`` the tracks file
    holds next to ``x, y`` (report runs), or None. ``mode_names``: an IMM tracker's
    modes (``motion = "imm"``), whose probabilities follow the covariance columns
    as ``mode_<name>``.
    """

    def __init__(
        self, out_dir: Path, dim: int, fmt: str, scan_times=None, frame=None, mode_names=()
    ):
        self.out_dir = Path(out_dir)
        # the run's scan times: Parquet row groups hold PARQUET_ROW_GROUP_SCANS scans each
        self.scan_times = None if scan_times is None else np.asarray(scan_times, float)
        self.dim = dim
        self.fmt = fmt
        self.frame = frame
        self.mode_names = tuple(mode_names)
        self.columns = _track_columns(dim, self.mode_names)
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
        self._remove_outputs(keep=())
        self.parts_dir.mkdir(parents=True)

    def _remove_outputs(self, keep) -> None:
        """Remove the outputs (and temporary files of outputs) of an earlier or
        interrupted run, except the names in ``keep``."""
        for name in OUTPUT_NAMES:
            path = self.out_dir / name
            if name not in keep:
                path.unlink(missing_ok=True)
            _temporary_name(path).unlink(missing_ok=True)
            path.with_name(name + ".tmp").unlink(missing_ok=True)  # older runs' name

    def parts_complete(self, n_parts: int) -> bool:
        """Whether the ``n_parts`` committed parts are all there (a resume can use them)."""
        return self.parts_dir.is_dir() and all(self._part_path(k).is_file() for k in range(n_parts))

    def resume(self, n_parts: int, keep=()) -> None:
        """Continue after ``n_parts`` committed parts: drop everything newer, reload the rows.

        ``keep``: outputs already written in their final form (a resume in the
        finishing phase); every other output of the interrupted run is removed.
        """
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
        self._remove_outputs(keep)  # stale outputs of the interrupted run

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
        if self.mode_names:  # motion = "imm": mode_<name> columns, in the config's order
            rows[:, col:] = res.mode_probabilities
        self._pending.append(rows)
        if self.fmt == "csv":
            if self._partial is None:
                partial = self._part_path(self.n_parts).with_name(
                    self._part_path(self.n_parts).name + ".partial"
                )
                self._partial = open(partial, "w", encoding="utf-8", newline="")
            self._partial.write(self._csv_text(rows, header=False))
            self._partial.flush()

    def _csv_text(self, rows: np.ndarray, header: bool, columns=None) -> str:
        columns = self.columns if columns is None else columns
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        if header:
            w.writerow(columns)
        # track_id is the second column of every table written here
        w.writerows(
            [repr(float(r[0])), str(int(r[1])), *(repr(float(v)) for v in r[2:])] for r in rows
        )
        return buf.getvalue()

    def _write_atomic(
        self, path: Path, rows: np.ndarray, header: bool = True, columns=None, stage=None
    ) -> None:
        columns = self.columns if columns is None else columns
        with atomic_output(path, stage) as tmp:
            if self.fmt == "csv":
                with open(tmp, "w", encoding="utf-8", newline="") as fh:
                    fh.write(self._csv_text(rows, header, columns))
            else:
                import pyarrow as pa
                import pyarrow.parquet as pq

                schema = pa.schema(
                    [(n, pa.int64() if n == "track_id" else pa.float64()) for n in columns]
                )
                arrays = [
                    pa.array(rows[:, j].astype(np.int64) if n == "track_id" else rows[:, j])
                    for j, n in enumerate(columns)
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

    def commit_pending(self) -> int:
        """Commit the rows since the last commit, if any; returns the parts count."""
        return self.commit() if self._pending else self.n_parts

    def write_tracks_file(self, stage=None) -> Path:
        """Write the tracks file atomically, in its final form: every row so far, with
        ``lat, lon`` columns when the writer has a ``frame``. ``stage``: see
        :func:`atomic_output`."""
        rows, columns = self.rows(), self.columns
        if self.frame is not None:
            from jointtrack.io.tracks import with_geodetic_columns

            table = with_geodetic_columns(
                {n: rows[:, j] for j, n in enumerate(columns)}, self.frame
            )
            columns = list(table)
            rows = np.column_stack([np.asarray(v, dtype=float) for v in table.values()])
            rows = rows.reshape(-1, len(columns))
        self._write_atomic(self.path, rows, columns=columns, stage=stage)
        return self.path

    def remove_parts(self) -> None:
        """Remove the parts directory, part by part (``cleanup`` fault points): the run
        is done, or it had no checkpoint that could need them."""
        self.close()
        if self.parts_dir.is_dir():
            for k, p in enumerate(sorted(self.parts_dir.iterdir())):
                p.unlink(missing_ok=True)
                fault("cleanup", k)
        shutil.rmtree(self.parts_dir, ignore_errors=True)

    def discard_parts(self) -> None:
        """Remove the parts directory (a failed run without a checkpoint: nothing can
        resume from them; the tracks so far are in the tracks file after a Ctrl-C)."""
        self.close()
        shutil.rmtree(self.parts_dir, ignore_errors=True)

    def snapshot(self) -> None:
        """Write every row so far to the tracks file (an interrupted run shows its progress);
        the parts are left as they are, so a resume continues from the checkpoint."""
        self.write_tracks_file()

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
