"""The main job, ``jointtrack run``: detections in, tracks out, scored and plotted.

:func:`run_scenario` runs the JPDA tracker on a built-in scenario (which has a
truth, so the tracks are scored); :func:`run_detections` runs it on detections
read from a file (no truth: tracks and timing only). Both write into ``out_dir``:

* ``tracks.csv`` (or ``tracks.parquet``): one row per confirmed track per scan,
  columns ``time, track_id, x, y[, z], vx, vy[, vz], existence`` and the
  position covariance ``P_x_x, P_x_y, P_y_y`` (3-D: also ``P_x_z, P_y_z,
  P_z_z``) — the format of :func:`jointtrack.io.read_tracks`. Written as the
  run goes: CSV rows are appended and flushed every scan (a killed run keeps
  every scan written so far); Parquet is written one row group per 50 scans
  (:class:`pyarrow.parquet.ParquetWriter`; the file is readable once the run
  finishes).
* ``metrics.json``: GOSPA (α = 2, p = 2, mean per scan and its localisation /
  missed / false parts, identity switches), OSPA mean, the track statistics of
  :func:`jointtrack.metrics.track_statistics`, and timing: per cluster size
  (number of tracks in a multi-track cluster) the count, mean and maximum
  association seconds, plus the run's wall time and scans per second. Without a
  truth (``--detections``) there is no GOSPA/OSPA and the track counts are the
  numbers of confirmed tracks.
* ``scene.png``: truth trajectories, detections (grey; clutter lighter),
  confirmed tracks as coloured lines labelled with their ids.
* ``gospa.png``: GOSPA per scan and its decomposition (only with a truth).

Tracker settings for a built-in scenario are derived from the scenario
(:func:`scenario_tracker_settings`): P_D, R = σ² I, the known clutter density
λ, the truth's process noise q, P_G of the scenario (0.99) and ``max_speed`` =
1.5 × the fastest true speed. For ``bojilov`` the five tracks are started from
the true states at the first scan with the steady-state covariance of the NCV
Kalman filter (:func:`steady_state_covariance`), as in Bojilov et al.'s
experiment, which studies track maintenance and association, not initiation;
the other scenarios start with no tracks.

Config file (``--config FILE``, TOML)
-------------------------------------
::

    [tracker]              # any TrackerConfig field; overrides the derived value
    p_d = 0.9
    association = "exact"  # or enumerate, pda, lbp, mcmc, kbest
    clutter_density = "estimate"   # a number (per unit area), or "estimate" =
                                   # Bojilov's heuristic (8)
    exact_max_tracks = 12

    [scenario]             # built-in scenario (ignored with --detections)
    name = "crossing"      # bojilov | crossing | many
    seed = 3
    start_from_truth = false
    n_scans = 20           # any keyword of the scenario function, e.g.
    clutter_per_scan = 5   # bojilov: clutter_density (β), n_scans, speeds, …

    [metrics]
    c = 50.0               # GOSPA/OSPA cut-off (default 5σ)
    switch_penalty = 0.0   # GOSPA identity-switch penalty

Unknown tables or keys, wrong types and bad values raise :class:`RunConfigError`
with a one-line message naming the file and the key. ``--scenario`` and
``--seed`` on the command line override ``name`` and ``seed``.

Checkpoints: with ``checkpoint=FILE`` the tracker state is saved every
``checkpoint_every`` scans and at the end (:meth:`JPDATracker.save`; the run's
bookkeeping — what is being tracked, cluster timings — goes to ``FILE.run.json``
beside it). ``resume=FILE`` loads the state and continues with the next scan;
rows of an existing tracks file up to the checkpoint are kept and later rows
dropped, so an interrupted-and-resumed run writes the same tracks file as an
uninterrupted one.
"""

from __future__ import annotations

import csv
import dataclasses
import inspect
import json
import math
import time
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from jointtrack.io import Detections, write_metrics
from jointtrack.trackers import JPDATracker, TrackerConfig

__all__ = [
    "SCENARIOS",
    "RunConfig",
    "RunConfigError",
    "load_config",
    "make_scenario",
    "make_tracker_config",
    "print_summary",
    "run_detections",
    "run_scenario",
    "scenario_tracker_settings",
    "start_truth_tracks",
    "steady_state_covariance",
]

SCENARIOS = ("bojilov", "crossing", "many")
_GENERATOR_NAMES = {"bojilov": "bojilov", "crossing": "crossing", "many": "many_targets"}
FORMATS = ("csv", "parquet")
PARQUET_ROW_GROUP_SCANS = 50
TRUTH_START_NOTE = (
    "tracks started from the truth at the first scan: Bojilov's experiment studies "
    "track maintenance and association, not initiation"
)


class RunConfigError(ValueError):
    """A bad run configuration (config file, scenario or option); one-line message."""


# ----------------------------------------------------------------------------- config


@dataclass(frozen=True)
class RunConfig:
    """A parsed ``--config`` file: the three optional tables, as plain dicts."""

    tracker: dict = field(default_factory=dict)
    scenario: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)
    source: str | None = None


_TABLES = ("tracker", "scenario", "metrics")
_METRIC_KEYS = {"c": "number > 0", "p": "number ≥ 1", "switch_penalty": "number ≥ 0"}


def load_config(path) -> RunConfig:
    """Read a TOML run configuration (format in the module docstring).

    Checks the table names, the ``[tracker]`` keys and value types and the
    ``[metrics]`` values here; ``[scenario]`` keywords are checked against the
    scenario function when the scenario is made (:func:`make_scenario`).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise RunConfigError(f"{path}: no such config file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise RunConfigError(f"{path}: cannot read config file ({exc})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise RunConfigError(f"{path}: not valid TOML: {_one_line(exc)}") from None
    for key, value in data.items():
        if key not in _TABLES:
            raise RunConfigError(
                f"{path}: unknown key '{key}' (known tables: {', '.join(_TABLES)})"
            )
        if not isinstance(value, dict):
            raise RunConfigError(f"{path}: '{key}' must be a table ([{key}])")
    tracker = dict(data.get("tracker", {}))
    _check_tracker_keys(tracker, str(path))
    metrics = dict(data.get("metrics", {}))
    for key, value in metrics.items():
        if key not in _METRIC_KEYS:
            raise RunConfigError(
                f"{path}: unknown key '{key}' in [metrics] (known: {', '.join(_METRIC_KEYS)})"
            )
        ok = isinstance(value, int | float) and not isinstance(value, bool)
        ok = ok and math.isfinite(value)
        ok = ok and {"c": value > 0, "p": value >= 1, "switch_penalty": value >= 0}[key]
        if not ok:
            raise RunConfigError(
                f"{path}: [metrics] key '{key}' must be a {_METRIC_KEYS[key]}, got {value!r}"
            )
    scenario = dict(data.get("scenario", {}))
    if "name" in scenario and scenario["name"] not in SCENARIOS:
        raise RunConfigError(
            f"{path}: [scenario] key 'name' must be one of {', '.join(SCENARIOS)}, "
            f"got {scenario['name']!r}"
        )
    if "seed" in scenario and not _is_int(scenario["seed"]):
        raise RunConfigError(f"{path}: [scenario] key 'seed' must be an integer")
    if "start_from_truth" in scenario and not isinstance(scenario["start_from_truth"], bool):
        raise RunConfigError(f"{path}: [scenario] key 'start_from_truth' must be true or false")
    return RunConfig(tracker=tracker, scenario=scenario, metrics=metrics, source=str(path))


def _one_line(exc) -> str:
    return " ".join(str(exc).split())


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _check_tracker_keys(d: Mapping, where: str) -> None:
    """Known keys and TOML-level value types of a ``[tracker]`` table."""
    ann = {f.name: str(f.type) for f in dataclasses.fields(TrackerConfig)}
    for key, value in d.items():
        if key not in ann:
            raise RunConfigError(
                f"{where}: unknown key '{key}' in [tracker] (known: {', '.join(sorted(ann))})"
            )
        a = ann[key]
        if key == "clutter_density" and value == "estimate":
            continue
        if "bool" in a:
            ok = isinstance(value, bool)
            want = "true or false"
        elif "int" in a:
            ok = _is_int(value)
            want = "an integer"
        elif "float" in a:
            ok = isinstance(value, int | float) and not isinstance(value, bool)
            want = "a number" + (' or "estimate"' if key == "clutter_density" else "")
        else:
            ok = isinstance(value, str)
            want = "a string"
        if not ok:
            raise RunConfigError(f"{where}: [tracker] key '{key}' must be {want}, got {value!r}")


def make_tracker_config(
    base: Mapping | None = None, overrides: Mapping | None = None, *, source: str | None = None
) -> TrackerConfig:
    """``TrackerConfig`` from derived settings ``base`` updated by ``overrides``.

    ``clutter_density = "estimate"`` in the overrides means ``None`` (Bojilov's
    heuristic (8)). Errors name ``source`` (the config file) when given.
    """
    where = source or "tracker settings"
    overrides = dict(overrides or {})
    _check_tracker_keys(overrides, where)
    if overrides.get("clutter_density") == "estimate":
        overrides["clutter_density"] = None
    d = {**TrackerConfig().to_dict(), **dict(base or {}), **overrides}
    try:
        return TrackerConfig.from_dict(d)
    except (ValueError, TypeError) as exc:
        raise RunConfigError(f"{where}: [tracker] {_one_line(exc)}") from None


def make_scenario(
    name: str = "bojilov",
    seed: int = 0,
    kwargs: Mapping | None = None,
    *,
    source: str | None = None,
):
    """Build a built-in scenario by name (``bojilov | crossing | many``).

    ``kwargs`` are passed to the scenario function (:mod:`jointtrack.scenarios`);
    unknown keywords and bad values raise :class:`RunConfigError` naming them.
    """
    from jointtrack import scenarios

    where = f"{source}: [scenario]" if source else "scenario"
    if name not in SCENARIOS:
        raise RunConfigError(
            f"{where}: unknown scenario {name!r}; choose one of {', '.join(SCENARIOS)}"
        )
    fn = getattr(scenarios, _GENERATOR_NAMES[name])
    params = [p for p in inspect.signature(fn).parameters if p != "seed"]
    kwargs = dict(kwargs or {})
    for key in kwargs:
        if key not in params:
            raise RunConfigError(
                f"{where} unknown key '{key}' for scenario {name} (known: name, seed, "
                f"start_from_truth, {', '.join(params)})"
            )
    try:
        return fn(seed=seed, **kwargs)
    except (ValueError, TypeError) as exc:
        raise RunConfigError(f"{where} scenario {name}: {_one_line(exc)}") from None


def scenario_tracker_settings(scenario) -> dict:
    """Tracker settings derived from a scenario's parameters (see the module docstring)."""
    speeds = [np.linalg.norm(s[:, scenario.dim :], axis=1) for s in scenario.truth_states if len(s)]
    vmax = float(max((v.max() for v in speeds), default=0.0))
    d = {
        "dim": scenario.dim,
        "motion": "cv",
        "process_noise": max(float(scenario.process_noise), 1e-9),
        "measurement_noise": float(np.mean(np.diag(scenario.R))),
        "p_d": float(scenario.p_d),
        "p_g": float(scenario.info.get("p_g", 0.99)),
        "clutter_density": float(scenario.clutter_density)
        if scenario.clutter_density > 0
        else None,
        "max_speed": 1.5 * vmax if vmax > 0 else 1.0,
    }
    return d


def steady_state_covariance(dt: float, q: float, r: float, dim: int = 2) -> np.ndarray:
    """Steady-state updated covariance of the NCV Kalman filter, layout [pos…, vel…].

    Per axis: the discrete Riccati equation for F = [[1, T], [0, 1]],
    Q = q [[T³/3, T²/2], [T²/2, T]], H = [1 0], R = r gives the predicted P⁻;
    the updated P = P⁻ − P⁻Hᵀ S⁻¹ H P⁻ with S = P⁻ₓₓ + r.
    """
    from scipy import linalg

    from jointtrack.scenarios import ncv_matrices

    F, Q = ncv_matrices(dt, max(q, 1e-12), 1)
    H = np.array([[1.0, 0.0]])
    Pp = linalg.solve_discrete_are(F.T, H.T, Q, np.array([[r]]))
    S = Pp[0, 0] + r
    Pu = Pp - np.outer(Pp[:, 0], Pp[0, :]) / S
    Pu = 0.5 * (Pu + Pu.T)
    P = np.zeros((2 * dim, 2 * dim))
    for a in range(dim):
        idx = [a, dim + a]
        P[np.ix_(idx, idx)] = Pu
    return P


def start_truth_tracks(trk: JPDATracker, states, dt: float) -> np.ndarray:
    """Start confirmed tracks at the true NCV ``states`` (K, 2·dim) of the first scan.

    Covariance: :func:`steady_state_covariance` of the tracker's own q and σ²
    (what a track that has been followed for long has), so the first gates are
    the nominal steady-state gates; a constant-acceleration tracker gets zero
    acceleration with unit variance. Returns the track ids.
    """
    c = trk.config
    n = trk._motion.state_dim
    d = c.dim
    states = np.atleast_2d(np.asarray(states, dtype=float))
    x0 = np.zeros((len(states), n))
    x0[:, : 2 * d] = states[:, : 2 * d]
    P0 = np.eye(n)
    P0[: 2 * d, : 2 * d] = steady_state_covariance(dt, c.process_noise, c.measurement_noise, d)
    return trk.start_tracks(x0, P0)


# ----------------------------------------------------------------------------- tracks file


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


# ----------------------------------------------------------------------------- the run


@dataclass
class _Source:
    """What is being tracked: scans, plus the truth when simulated."""

    identity: dict
    times: np.ndarray
    scans: tuple
    dim: int
    truth: tuple | None = None  # (times, ids, positions)
    truth_states: tuple | None = None  # per scan, for plots
    truth_ids: tuple | None = None
    origins: tuple | None = None
    region: np.ndarray | None = None
    x0: np.ndarray | None = None  # start tracks from these states at the first scan
    sigma: float = 10.0
    notes: list = field(default_factory=list)


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


def _jsonify(obj):
    return json.loads(
        json.dumps(obj, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o))
    )


def _cluster_timing(clusters: list) -> list[dict]:
    """Per number of tracks in a multi-track cluster: count, mean/max seconds, mean size."""
    by: dict[int, list] = {}
    for n_tr, n_me, sec in clusters:
        by.setdefault(int(n_tr), []).append((n_me, sec))
    out = []
    for n in sorted(by):
        a = np.array(by[n], dtype=float)
        out.append(
            {
                "n_tracks": n,
                "count": int(len(a)),
                "mean_measurements": float(a[:, 0].mean()),
                "mean_seconds": float(a[:, 1].mean()),
                "max_seconds": float(a[:, 1].max()),
                "total_seconds": float(a[:, 1].sum()),
            }
        )
    return out


def _warm_up(cfg: TrackerConfig) -> None:
    """Load / compile the association kernels before anything is timed.

    numba loads each compiled kernel on its first call (≈ 0.1 s), which would
    otherwise be charged to the first cluster of that kind.
    """
    from jointtrack.association import marginals

    rng = np.random.default_rng(12345)
    methods = {cfg.association, cfg.approximation}
    for n, m in ((2, 2), (3, 5), (5, 9), (8, 14)):
        L = rng.random((n, m)) * (rng.random((n, m)) < 0.6) + np.eye(n, m)
        miss = np.full(n, 0.1)
        for method in methods:
            opts = {"rng": np.random.default_rng(0)} if method == "mcmc" else {}
            try:
                marginals(L, miss, method=method, **opts)
            except ValueError:
                pass


def _ospa_mean(truth, tracks, scan_times, c, p) -> float:
    from jointtrack.metrics import ospa

    tt, _ti, tp = truth
    et, _ei, ep = tracks
    vals = []
    for t in scan_times:
        X = tp[tt == t]
        Y = ep[et == t]
        vals.append(ospa(X, Y, c, p))
    return float(np.mean(vals)) if vals else float("nan")


def _run(
    src: _Source,
    cfg: TrackerConfig,
    out_dir,
    *,
    fmt: str = "csv",
    progress: bool = False,
    checkpoint=None,
    checkpoint_every: int = 10,
    resume=None,
    max_scans: int | None = None,
    metrics_opts: Mapping | None = None,
    console=None,
    plots: bool = True,
) -> dict:
    from rich.console import Console

    wall0 = time.perf_counter()
    console = console or Console(quiet=True)
    notes = list(src.notes)

    def warn(msg: str) -> None:
        notes.append(msg)
        console.print(
            f"warning: {msg}", style="yellow", markup=False, highlight=False, soft_wrap=True
        )

    if fmt not in FORMATS:
        raise RunConfigError(f"unknown format {fmt!r}; choose csv or parquet")
    if checkpoint_every < 1:
        raise RunConfigError(f"--checkpoint-every must be ≥ 1, got {checkpoint_every}")
    if max_scans is not None and max_scans < 1:
        raise RunConfigError(f"--max-scans must be ≥ 1, got {max_scans}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    checkpoint = Path(checkpoint) if checkpoint is not None else None
    identity = _jsonify(src.identity)

    clusters: list = []  # [n_tracks, n_measurements, seconds] of multi-track confirmed clusters
    elapsed_before = 0.0
    start = 0
    if resume is not None:
        resume = Path(resume)
        trk = JPDATracker.load(resume)
        if trk.config.dim != src.dim:
            raise RunConfigError(
                f"{resume}: the checkpoint tracks {trk.config.dim}-D data, these scans are "
                f"{src.dim}-D"
            )
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
        if trk.config != cfg:
            diff = sorted(k for k, v in cfg.to_dict().items() if trk.config.to_dict()[k] != v)
            warn(
                f"{resume}: continuing with the checkpoint's tracker settings "
                f"(differ in: {', '.join(diff)})"
            )
        cfg = trk.config
        if trk.time is not None:
            start = int(np.searchsorted(src.times, trk.time, side="right"))
    else:
        trk = JPDATracker(cfg)
        if src.x0 is not None and len(src.x0):
            dt = float(np.median(np.diff(src.times))) if len(src.times) > 1 else 1.0
            start_truth_tracks(trk, src.x0, dt)

    K = len(src.times)
    stop = K if max_scans is None else min(K, int(max_scans))
    ext = "csv" if fmt == "csv" else "parquet"
    writer = _TrackWriter(
        out_dir / f"tracks.{ext}",
        src.dim,
        fmt,
        resume_time=trk.time if resume is not None else None,
        warn=warn,
    )
    if resume is not None and start > 0 and writer.n_kept_scans == 0:
        warn(f"no earlier rows in {writer.path}: it holds only the scans from this run")

    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    _warm_up(cfg)
    loop0 = time.perf_counter()
    n_done = 0
    try:
        with Progress(
            TextColumn("[progress.description]{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("scans"),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
            console=console,
            disable=not progress,
            transient=False,
        ) as bar:
            task = bar.add_task("tracking", total=stop, completed=start)
            for k in range(start, stop):
                t = float(src.times[k])
                res = trk.step(t, src.scans[k])
                for (n_tr, n_me), sec, conf in zip(
                    res.cluster_sizes, res.cluster_seconds, res.cluster_confirmed, strict=True
                ):
                    if conf:
                        clusters.append([int(n_tr), int(n_me), float(sec)])
                writer.write_scan(t, res)
                n_done += 1
                if checkpoint is not None and trk.n_scans % checkpoint_every == 0:
                    _save_checkpoint(
                        trk,
                        checkpoint,
                        identity,
                        clusters,
                        elapsed_before + time.perf_counter() - loop0,
                    )
                bar.update(task, advance=1)
    finally:
        writer.close()
    loop_seconds = time.perf_counter() - loop0
    if checkpoint is not None and n_done:
        _save_checkpoint(trk, checkpoint, identity, clusters, elapsed_before + loop_seconds)

    # ------------------------------------------------------------ metrics
    tracks = writer.table()
    t_last = float(src.times[stop - 1]) if stop else -math.inf
    scan_times = src.times[:stop]
    metrics: dict = {
        "jointtrack_version": _version(),
        "source": identity,
        "n_scans": int(stop),
        "n_scans_this_run": int(n_done),
        "n_detections": int(sum(len(z) for z in src.scans[:stop])),
        "tracker": cfg.to_dict(),
        "start_from_truth": src.x0 is not None,
        "tracks_file": str(writer.path),
    }
    sigma = src.sigma
    mo = dict(metrics_opts or {})
    c = float(mo.get("c", 5.0 * sigma))
    p = float(mo.get("p", 2.0))
    gamma = float(mo.get("switch_penalty", 0.0))
    series = None
    if src.truth is not None:
        from jointtrack.metrics import gospa_series, track_statistics

        tt, ti, tp = src.truth
        keep = tt <= t_last
        truth = (tt[keep], ti[keep], tp[keep])
        series = gospa_series(*truth, *tracks, c=c, p=p, switch_penalty=gamma)
        stats = track_statistics(*truth, *tracks, gate=c)
        metrics["gospa"] = {
            "c": c,
            "p": p,
            "alpha": 2.0,
            "switch_penalty": gamma,
            "mean": series.mean,
            "mean_localisation": float(np.mean(series.localisation)),
            "mean_missed": float(np.mean(series.missed)),
            "mean_false": float(np.mean(series.false)),
            "parts_unit": f"p-th power (m^{p:g}); gospa**p = localisation + missed + false",
            "mean_n_missed": float(np.mean(series.n_missed)),
            "mean_n_false": float(np.mean(series.n_false)),
            "n_switches": int(series.switches.sum()),
            "total": series.total,
        }
        metrics["ospa"] = {"c": c, "p": p, "mean": _ospa_mean(truth, tracks, scan_times, c, p)}
        metrics["tracks"] = stats.as_dict()
    else:
        ids = tracks[1]
        per_scan = [int(np.sum(tracks[0] == t)) for t in scan_times]
        metrics["tracks"] = {
            "n_tracks": int(np.unique(ids).size),
            "mean_confirmed_per_scan": float(np.mean(per_scan)) if per_scan else 0.0,
            "max_confirmed_per_scan": int(max(per_scan, default=0)),
        }
    total_loop = elapsed_before + loop_seconds
    metrics["timing"] = {
        "clusters": _cluster_timing(clusters),
        "association_seconds": float(sum(c_[2] for c_ in clusters)),
        "loop_seconds": total_loop,
        "scans_per_second": (stop / total_loop) if total_loop > 0 and stop else None,
        "note": "clusters = multi-track clusters of confirmed tracks (single-track gates use "
        "PDA directly; tentative tracks are associated in a separate pass); "
        "loop = predict/gate/cluster/associate/update/track logic + writing tracks",
    }
    if src.x0 is not None:
        notes.insert(0, TRUTH_START_NOTE)
    metrics["notes"] = notes

    files = {"tracks": str(writer.path), "metrics": str(out_dir / "metrics.json")}
    if plots:
        from jointtrack.experiments import plots as _plots

        files["scene"] = str(
            _plots.plot_scene(
                out_dir / "scene.png",
                times=scan_times,
                scans=src.scans[:stop],
                origins=src.origins[:stop] if src.origins is not None else None,
                truth=truth if src.truth is not None else None,
                tracks=tracks,
                region=src.region,
                title=_describe(identity),
            )
        )
        if series is not None:
            files["gospa"] = str(
                _plots.plot_gospa(out_dir / "gospa.png", series, title=_describe(identity))
            )
    metrics["files"] = files
    metrics["timing"]["total_seconds"] = time.perf_counter() - wall0
    write_metrics(metrics, out_dir / "metrics.json")
    return metrics


def _version() -> str:
    from jointtrack import __version__

    return __version__


def _describe(identity) -> str:
    if not isinstance(identity, Mapping):
        return "an unknown run"
    if "detections" in identity:
        return f"detections {identity['detections']}"
    kw = identity.get("kwargs") or {}
    extra = "".join(f", {k}={v}" for k, v in kw.items())
    return f"scenario {identity.get('scenario')} (seed {identity.get('seed')}{extra})"


def run_scenario(
    scenario="bojilov",
    config: TrackerConfig | Mapping | None = None,
    out_dir="jointtrack-out",
    fmt: str = "csv",
    progress: bool = False,
    *,
    seed: int = 0,
    scenario_kwargs: Mapping | None = None,
    start_from_truth: bool | None = None,
    checkpoint=None,
    checkpoint_every: int = 10,
    resume=None,
    max_scans: int | None = None,
    metrics_opts: Mapping | None = None,
    console=None,
    plots: bool = True,
) -> dict:
    """Run the tracker on a built-in scenario, write the outputs, return the metrics dict.

    Parameters
    ----------
    scenario : a :class:`~jointtrack.scenarios.Scenario`, or a name
        (``bojilov | crossing | many``) built with ``seed`` and ``scenario_kwargs``.
    config : a :class:`TrackerConfig` (used as is) or a mapping of overrides on
        the settings derived from the scenario (:func:`scenario_tracker_settings`);
        ``None`` = the derived settings.
    out_dir : output directory (created).
    fmt : ``"csv"`` or ``"parquet"`` (tracks file).
    progress : show a rich progress bar over scans.
    start_from_truth : start the tracks from the true states at the first scan
        (default: True for ``bojilov``, False otherwise).
    checkpoint, checkpoint_every, resume : see the module docstring.
    max_scans : process only the first ``max_scans`` scans (counted from the
        first scan of the scenario, also when resuming).
    metrics_opts : ``c`` (GOSPA/OSPA cut-off, default 5σ), ``p`` (2),
        ``switch_penalty`` (0).
    console : rich console for the progress bar and warnings.
    plots : write ``scene.png`` and ``gospa.png``.
    """
    kwargs = dict(scenario_kwargs or {})
    if isinstance(scenario, str):
        name = scenario
        scenario = make_scenario(name, seed, kwargs)
        identity = {"scenario": name, "seed": seed, "kwargs": kwargs}
    else:
        identity = {"scenario": scenario.name, "seed": scenario.seed, "kwargs": kwargs}
    if start_from_truth is None:
        start_from_truth = scenario.name == "bojilov"
    if isinstance(config, TrackerConfig):
        cfg = config
    else:
        cfg = make_tracker_config(scenario_tracker_settings(scenario), config)
    if cfg.dim != scenario.dim:
        raise RunConfigError(
            f"[tracker] dim = {cfg.dim} but scenario {scenario.name} is {scenario.dim}-D"
        )
    identity["start_from_truth"] = bool(start_from_truth)
    sigma = float(math.sqrt(np.mean(np.diag(scenario.R))))
    src = _Source(
        identity=identity,
        times=scenario.times,
        scans=scenario.detections,
        dim=scenario.dim,
        truth=scenario.truth_table(),
        truth_states=scenario.truth_states,
        truth_ids=scenario.truth_ids,
        origins=scenario.origins,
        region=scenario.region,
        x0=scenario.truth_states[0] if start_from_truth else None,
        sigma=sigma,
    )
    return _run(
        src,
        cfg,
        out_dir,
        fmt=fmt,
        progress=progress,
        checkpoint=checkpoint,
        checkpoint_every=checkpoint_every,
        resume=resume,
        max_scans=max_scans,
        metrics_opts=metrics_opts,
        console=console,
        plots=plots,
    )


def run_detections(
    detections: Detections,
    config: TrackerConfig | Mapping | None = None,
    out_dir="jointtrack-out",
    fmt: str = "csv",
    progress: bool = False,
    **options,
) -> dict:
    """Run the tracker on detections (e.g. from :func:`jointtrack.io.read_detections`).

    ``config``: a :class:`TrackerConfig` or a mapping of overrides on the
    defaults (``dim`` is taken from the detections). No truth: the metrics hold
    track counts and timing only. Other options as :func:`run_scenario`
    (``checkpoint``, ``checkpoint_every``, ``resume``, ``max_scans``,
    ``console``, ``plots``).
    """
    if detections.dim not in (2, 3):
        raise RunConfigError(f"the tracker handles 2-D or 3-D detections, got {detections.dim}-D")
    if isinstance(config, TrackerConfig):
        cfg = config
    else:
        over = dict(config or {})
        if "dim" in over and over["dim"] != detections.dim:
            raise RunConfigError(
                f"[tracker] dim = {over['dim']} but the detections are {detections.dim}-D"
            )
        cfg = make_tracker_config({"dim": detections.dim}, over)
    if cfg.dim != detections.dim:
        raise RunConfigError(f"tracker dim = {cfg.dim} but the detections are {detections.dim}-D")
    pts = [z for z in detections.scans if len(z)]
    region = None
    if pts:
        allz = np.concatenate(pts)
        region = np.stack([allz.min(axis=0), allz.max(axis=0)], axis=1)
    src = _Source(
        identity={
            "detections": str(Path(detections.source).resolve())
            if detections.source
            else "<memory>"
        },
        times=detections.times,
        scans=detections.scans,
        dim=detections.dim,
        region=region,
        sigma=math.sqrt(cfg.measurement_noise),
    )
    return _run(src, cfg, out_dir, fmt=fmt, progress=progress, **options)


# ----------------------------------------------------------------------------- summary


def _fmt(v, spec=".3g") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    if isinstance(v, int):
        return str(v)
    return format(v, spec)


def summary_tables(metrics: Mapping) -> list:
    """Rich tables summarising a run's metrics dict."""
    from rich.table import Table

    main = Table(title="jointtrack run", show_header=False, title_justify="left")
    main.add_column("what", style="bold")
    main.add_column("value")
    main.add_row("source", _describe(metrics.get("source")))
    main.add_row("scans", f"{metrics['n_scans']} ({metrics['n_detections']} detections)")
    tr = metrics["tracks"]
    if "gospa" in metrics:
        g, o = metrics["gospa"], metrics["ospa"]
        main.add_row(
            "tracks",
            f"{tr['n_tracks']} confirmed: {tr['n_true_tracks']} true, {tr['n_false_tracks']} "
            f"false; {tr['n_truths_tracked']}/{tr['n_truths']} targets tracked",
        )
        main.add_row(
            "breaks / id switches",
            f"{tr['n_breaks']} / {tr['n_id_switches']} (fragmentations {tr['n_fragmentations']})",
        )
        main.add_row("position RMSE", f"{_fmt(tr['rmse'])} (coverage {_fmt(tr['coverage'])})")
        main.add_row(
            f"GOSPA mean (c={g['c']:g}, p={g['p']:g})",
            f"{_fmt(g['mean'])}  [parts² mean: localisation {_fmt(g['mean_localisation'])}, "
            f"missed {_fmt(g['mean_missed'])}, false {_fmt(g['mean_false'])}]",
        )
        main.add_row(f"OSPA mean (c={o['c']:g}, p={o['p']:g})", _fmt(o["mean"]))
    else:
        main.add_row(
            "tracks",
            f"{tr['n_tracks']} confirmed ids; {_fmt(tr['mean_confirmed_per_scan'])} per scan "
            f"(max {tr['max_confirmed_per_scan']}); no truth, so no GOSPA",
        )
    tm = metrics["timing"]
    main.add_row(
        "time",
        f"{_fmt(tm['loop_seconds'])} s tracking, {_fmt(tm['scans_per_second'])} scans/s "
        f"({_fmt(tm['association_seconds'])} s in multi-track association)",
    )
    main.add_row("outputs", ", ".join(Path(f).name for f in metrics.get("files", {}).values()))
    for note in metrics.get("notes", []):
        main.add_row("note", note)

    cl = Table(
        title="association time per multi-track cluster of confirmed tracks",
        title_justify="left",
    )
    for name in ("tracks in cluster", "clusters", "mean meas.", "mean ms", "max ms"):
        cl.add_column(name, justify="right")
    for row in tm["clusters"]:
        cl.add_row(
            str(row["n_tracks"]),
            str(row["count"]),
            f"{row['mean_measurements']:.1f}",
            f"{1e3 * row['mean_seconds']:.3f}",
            f"{1e3 * row['max_seconds']:.3f}",
        )
    if not tm["clusters"]:
        cl.add_row("–", "0", "–", "–", "–")
    return [main, cl]


def print_summary(metrics: Mapping, console) -> None:
    """Print :func:`summary_tables` to a rich console."""
    for table in summary_tables(metrics):
        console.print(table)
