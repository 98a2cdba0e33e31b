"""Stone Soup's own real-data trackers, fed plain arrays, each run in a capped subprocess.

The real-data benchmark (:mod:`jointtrack.bench.realdata`) gives Stone Soup and
jointtrack the identical reports: per-report times (seconds since an origin),
positions in a local east/north plane (metres), optional labels (``""`` = none)
and the scan each report belongs to. :func:`run_stonesoup` runs one of the
configurations below on them in a child process and measures it.

Configurations (:data:`CONFIGURATIONS`)
---------------------------------------
``demo``
    Exactly the components of Stone Soup's ``docs/demos/AIS_Solent_Tracker.py``
    (stonesoup 1.9.1 sdist): ``CombinedLinearGaussianTransitionModel`` of two
    ``OrnsteinUhlenbeck(0.5, 1e-4)``, ``LinearGaussian(4, [0, 2], diag(15, 15))``,
    ``KalmanPredictor`` / ``KalmanUpdater``, ``FilteredDetectionsGater(
    DistanceHypothesiser(predictor, updater, Mahalanobis(), missed_distance=3),
    metadata_filter="MMSI")`` on the label, ``NearestNeighbour``,
    ``SimpleMeasurementInitiator(GaussianState(0, diag(0, 10, 0, 10)))``,
    ``UpdateTimeDeleter(10 min)``, ``MultiTargetTracker``. One difference: the
    demo converts longitude/latitude to UTM (``LongLatToUTMConverter``); here the
    positions are the benchmark's local east/north metres about the data's centre
    (the same plane jointtrack tracks in). Over the Solent (≈ 50 km) the two
    planes differ by a rotation and a scale within 0.1 %, far below the 15 m²
    noise the demo assumes.
``nn``
    The same without the label gater: nearest neighbour on positions alone.
``gnn``
    The tracker of Stone Soup's ``docs/demos/OpenSky_Demo.py`` in the horizontal
    plane: ``ConstantVelocity(20)`` per axis (initiation ``ConstantVelocity(5)``),
    ``DistanceHypothesiser(Mahalanobis(), missed_distance=5)``,
    ``GNNWith2DAssignment`` (the demo's global-nearest-neighbour associator),
    ``UpdateTimeDeleter(20 s, delete_last_pred=True)``,
    ``MultiMeasurementInitiator(GaussianState(0, diag(15², 100², 15², 100²)),
    GNNWith2DAssignment(DistanceHypothesiser(missed_distance=3)), min_points=2)``,
    ``MultiTargetTracker``. The demo's radars measure elevation, bearing and range
    (extended Kalman filters); the benchmark's sensor measures positions with
    ``LinearGaussian`` noise ``measurement_noise`` · I, so the linear
    ``KalmanPredictor`` / ``KalmanUpdater`` (identical to the extended ones for
    a linear model) stand in.
``jpda``
    ``gnn`` with the demo's association replaced by Stone Soup's JPDA:
    ``PDAHypothesiser(predictor, updater, clutter_spatial_density, prob_detect)``
    with ``JPDAwithEHM2`` (Stone Soup's exact JPDA with efficient hypothesis
    management — plain ``JPDA`` enumerates the joint events and cannot run
    scenes of this size) in a ``MultiTargetMixtureTracker``; the initiator and
    deleter of ``gnn``.

Stone Soup is imported lazily (the ``bench`` / ``test`` extras).

Measurement
-----------
Each run is a child process (``python -m jointtrack.bench.stonesoup_realdata
DIR``) reading ``DIR/input.npz`` (``allow_pickle=False``) and
``DIR/params.json``, writing ``DIR/tracks.csv`` and ``DIR/status.json``. The
parent samples the child's resident set size with ``psutil`` every ``poll``
seconds (the RSS-over-time series), and at ``wall_cap`` seconds of the child's
life (or above ``rss_cap`` bytes) sends ``SIGUSR1``: the child stops between
two scans, writes the tracks of the scans it completed and exits; a child that
does not exit within ``grace`` seconds more is killed (then no tracks). The
total CPU time and peak RSS of the child come from ``wait4``'s resource usage;
the tracking loop's own wall and CPU time from the child.
"""

from __future__ import annotations

import csv
import datetime
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = [
    "CONFIGURATIONS",
    "StoneSoupRun",
    "build_tracker",
    "run_stonesoup",
    "track_stonesoup",
]

CONFIGURATIONS = ("demo", "nn", "gnn", "jpda")
#: configurations that take the scene's sensor figures (the AIS demo fixes its own noise)
NEEDS_SENSOR = ("gnn", "jpda")
#: origin of the datetimes handed to Stone Soup (only differences matter)
EPOCH = datetime.datetime(2000, 1, 1)
#: the metadata key the demo's label gater filters on
LABEL_KEY = "MMSI"
TRACK_COLUMNS = ("time", "track_id", "x", "y", "vx", "vy", "updated")


def build_tracker(
    config: str,
    *,
    measurement_noise: float | None = None,
    p_d: float | None = None,
    clutter_density: float | None = None,
):
    """One of :data:`CONFIGURATIONS` as Stone Soup components (module docstring).

    ``measurement_noise`` (m², per axis) is required by ``gnn`` and ``jpda``;
    ``p_d`` and ``clutter_density`` (false returns per m² per scan) by ``jpda``.
    Returns ``(tracker, measurement_model)``; the tracker has ``detector=None``
    and is driven with ``update_tracker``.
    """
    from stonesoup.dataassociator.neighbour import GNNWith2DAssignment, NearestNeighbour
    from stonesoup.dataassociator.probability import JPDAwithEHM2
    from stonesoup.deleter.time import UpdateTimeDeleter
    from stonesoup.gater.filtered import FilteredDetectionsGater
    from stonesoup.hypothesiser.distance import DistanceHypothesiser
    from stonesoup.hypothesiser.probability import PDAHypothesiser
    from stonesoup.initiator.simple import MultiMeasurementInitiator, SimpleMeasurementInitiator
    from stonesoup.measures import Mahalanobis
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.transition.linear import (
        CombinedLinearGaussianTransitionModel,
        ConstantVelocity,
        OrnsteinUhlenbeck,
    )
    from stonesoup.predictor.kalman import KalmanPredictor
    from stonesoup.tracker.simple import MultiTargetMixtureTracker, MultiTargetTracker
    from stonesoup.types.state import GaussianState
    from stonesoup.updater.kalman import KalmanUpdater

    if config not in CONFIGURATIONS:
        raise ValueError(f"config must be one of {CONFIGURATIONS}, got {config!r}")
    if config in ("demo", "nn"):
        transition = CombinedLinearGaussianTransitionModel(
            (OrnsteinUhlenbeck(0.5, 1e-4), OrnsteinUhlenbeck(0.5, 1e-4))
        )
        measurement = LinearGaussian(ndim_state=4, mapping=[0, 2], noise_covar=np.diag([15, 15]))
        predictor = KalmanPredictor(transition)
        updater = KalmanUpdater(measurement)
        hypothesiser = DistanceHypothesiser(predictor, updater, Mahalanobis(), missed_distance=3)
        if config == "demo":
            hypothesiser = FilteredDetectionsGater(hypothesiser, metadata_filter=LABEL_KEY)
        tracker = MultiTargetTracker(
            initiator=SimpleMeasurementInitiator(
                GaussianState([[0], [0], [0], [0]], np.diag([0, 10, 0, 10])), measurement
            ),
            deleter=UpdateTimeDeleter(time_since_update=datetime.timedelta(minutes=10)),
            detector=None,
            data_associator=NearestNeighbour(hypothesiser),
            updater=updater,
        )
        return tracker, measurement

    _positive("measurement_noise", measurement_noise)
    if config == "jpda":
        _positive("clutter_density", clutter_density)
        _positive("p_d", p_d)
        if p_d > 1:
            raise ValueError(f"p_d must be in (0, 1], got {p_d!r}")
    transition = CombinedLinearGaussianTransitionModel((ConstantVelocity(20), ConstantVelocity(20)))
    init_transition = CombinedLinearGaussianTransitionModel(
        (ConstantVelocity(5), ConstantVelocity(5))
    )
    measurement = LinearGaussian(
        ndim_state=4, mapping=[0, 2], noise_covar=np.diag([measurement_noise] * 2)
    )
    predictor = KalmanPredictor(transition)
    updater = KalmanUpdater(measurement)
    deleter = UpdateTimeDeleter(datetime.timedelta(seconds=20), delete_last_pred=True)
    initiator = MultiMeasurementInitiator(
        GaussianState(np.zeros((4, 1)), np.diag([15.0**2, 100.0**2, 15.0**2, 100.0**2])),
        measurement_model=measurement,
        deleter=deleter,
        data_associator=GNNWith2DAssignment(
            DistanceHypothesiser(
                KalmanPredictor(init_transition), updater, Mahalanobis(), missed_distance=3
            )
        ),
        updater=updater,
        min_points=2,
    )
    if config == "gnn":
        tracker = MultiTargetTracker(
            initiator=initiator,
            deleter=deleter,
            detector=None,
            data_associator=GNNWith2DAssignment(
                DistanceHypothesiser(predictor, updater, Mahalanobis(), missed_distance=5)
            ),
            updater=updater,
        )
    else:
        tracker = MultiTargetMixtureTracker(
            initiator=initiator,
            deleter=deleter,
            detector=None,
            data_associator=JPDAwithEHM2(
                PDAHypothesiser(
                    predictor=predictor,
                    updater=updater,
                    clutter_spatial_density=float(clutter_density),
                    prob_detect=float(p_d),
                )
            ),
            updater=updater,
        )
    return tracker, measurement


def _positive(name: str, value) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")


def check_inputs(times, positions, labels, scan_index, scan_times) -> tuple:
    """The inputs as arrays, or a ValueError/TypeError naming the bad argument.

    ``times`` (R,) seconds; ``positions`` (R, 2) metres; ``labels`` (R,) str or
    ``None``; ``scan_index`` (R,) int, non-decreasing, in ``[0, K)``;
    ``scan_times`` (K,) strictly increasing. A report of scan k lies in
    ``(scan_times[k-1], scan_times[k]]`` — the windows of Stone Soup's
    ``TimeSyncFeeder`` — so a scan's reports never postdate its update.
    """

    def real(name, value, ndim):
        a = np.asarray(value)
        if a.dtype == bool or a.dtype.kind not in "iuf":
            raise TypeError(f"{name} must be real numbers, got dtype {a.dtype}")
        a = a.astype(np.float64)
        if a.ndim != ndim:
            raise ValueError(f"{name} must be {ndim}-D, got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name} must be finite (no NaN/inf)")
        return a

    t = real("times", times, 1)
    z = real("positions", positions, 2)
    st = real("scan_times", scan_times, 1)
    r = len(t)
    if z.shape != (r, 2):
        raise ValueError(f"positions must have shape ({r}, 2) like times, got {z.shape}")
    k = np.asarray(scan_index)
    if k.dtype == bool or k.dtype.kind not in "iu":
        raise TypeError(f"scan_index must be integers, got dtype {k.dtype}")
    k = k.astype(np.int64)
    if k.shape != (r,):
        raise ValueError(f"scan_index must have shape ({r},) like times, got {k.shape}")
    if len(st) == 0:
        raise ValueError("scan_times must hold at least one scan")
    if np.any(np.diff(st) <= 0):
        raise ValueError("scan_times must be strictly increasing")
    if r:
        if k.min() < 0 or k.max() >= len(st):
            raise ValueError(f"scan_index must lie in [0, {len(st)}) (len(scan_times))")
        if np.any(np.diff(k) < 0):
            raise ValueError("scan_index must be non-decreasing (reports in scan order)")
        if np.any(t > st[k]):
            raise ValueError("times must not exceed their scan's time (scan_times[scan_index])")
        previous = np.where(k > 0, st[np.maximum(k - 1, 0)], -np.inf)
        if np.any(t <= previous):
            raise ValueError("times must be later than the previous scan's time")
    if labels is None:
        lab = None
    else:
        lab = np.asarray(labels)
        if lab.dtype.kind != "U":
            raise TypeError(f"labels must be strings ('' = none), got dtype {lab.dtype}")
        if lab.shape != (r,):
            raise ValueError(f"labels must have shape ({r},) like times, got {lab.shape}")
    return t, z, lab, k, st


def demo_pipeline_reports(csv_path, window: float = 60.0) -> dict:
    """The AIS reports as Stone Soup's Solent demo pipeline feeds them to its tracker.

    Runs the demo's own reader and feeders on ``csv_path`` (a CSV in the layout of
    ``SolentAIS_20160112_130211.csv``): ``CSVDetectionReader(state_vector_fields=
    ("Longitude_degrees", "Latitude_degrees"), time_field="Time")`` →
    ``TimeSyncFeeder(time_window=window s)`` → ``MetadataReducer("MMSI")`` (the
    latest report of each vessel per window). The demo's last stage, the UTM
    conversion, is left to the caller (the benchmark projects into its own local
    plane).

    Returns a dict of arrays, one row per kept report, in scan order (by time,
    then MMSI, within a scan): ``times`` (seconds since ``time_origin``, the
    first report's time as ISO-8601 UTC), ``lat``, ``lon`` (degrees), ``labels``
    (the MMSI strings), ``scan_index``; per scan ``scan_times`` (the feeder's
    window ends, empty windows included); and ``n_raw``, the reports read.
    """
    from stonesoup.feeder.filter import MetadataReducer
    from stonesoup.feeder.time import TimeSyncFeeder
    from stonesoup.reader.generic import CSVDetectionReader

    path = Path(csv_path)
    if not path.is_file():
        raise FileNotFoundError(f"csv_path {path} is not a file")
    _positive("window", window)
    reader = CSVDetectionReader(
        str(path),
        state_vector_fields=("Longitude_degrees", "Latitude_degrees"),
        time_field="Time",
    )
    feeder = MetadataReducer(
        TimeSyncFeeder(reader, time_window=datetime.timedelta(seconds=float(window))),
        LABEL_KEY,
    )
    rows = []
    scan_stamps = []
    for k, (stamp, detections) in enumerate(feeder):
        scan_stamps.append(stamp)
        rows.extend(
            (
                k,
                d.timestamp,
                str(d.metadata.get(LABEL_KEY, "")),
                *np.ravel(d.state_vector),
                _number(d.metadata.get("SOG_knots")),
                _number(d.metadata.get("COG_degrees")),
            )
            for d in detections
        )
    if not scan_stamps:
        raise ValueError(f"csv_path {path} holds no reports")
    rows.sort(key=lambda r: (r[0], r[1], r[2]))
    origin = min([r[1] for r in rows], default=scan_stamps[0])

    def seconds(stamp):
        return (stamp - origin).total_seconds()

    with open(path, newline="") as f:
        n_raw = sum(1 for _ in csv.DictReader(f))
    return {
        "time_origin": origin.isoformat(timespec="milliseconds") + "Z",
        "times": np.array([seconds(r[1]) for r in rows], dtype=np.float64),
        "lon": np.array([float(r[3]) for r in rows], dtype=np.float64),
        "lat": np.array([float(r[4]) for r in rows], dtype=np.float64),
        "labels": np.array([r[2] for r in rows], dtype=str),
        # the reports' own speed (knots) and course (degrees), NaN where not given;
        # Stone Soup's demo ignores them
        "speed_knots": np.array([r[5] for r in rows], dtype=np.float64),
        "course_deg": np.array([r[6] for r in rows], dtype=np.float64),
        "scan_index": np.array([r[0] for r in rows], dtype=np.int64),
        "scan_times": np.array([seconds(s) for s in scan_stamps], dtype=np.float64),
        "n_raw": n_raw,
    }


def _number(text) -> float:
    """A metadata cell as a float, NaN when missing or not a number."""
    try:
        return float(text)
    except (TypeError, ValueError):
        return float("nan")


class StopTracking(BaseException):
    """Raised by the child's SIGUSR1 handler; a BaseException so no ``except Exception``
    inside Stone Soup swallows it."""


def track_stonesoup(
    config: str,
    times,
    positions,
    labels,
    scan_index,
    scan_times,
    *,
    measurement_noise: float | None = None,
    p_d: float | None = None,
    clutter_density: float | None = None,
    on_scan: Callable[[int], None] | None = None,
) -> dict:
    """Run a configuration in this process over the scans; the track table and the counts.

    Each report becomes a ``Detection`` at its own time (as the demo's
    ``TimeSyncFeeder`` keeps them) with the label as ``metadata["MMSI"]`` when the
    label is not ``""`` (the ``demo`` gater uses it; the other configurations get
    no metadata); ``update_tracker`` is called at every scan time, empty scans
    included. A :class:`StopTracking` raised during a scan (the parent's stop
    signal) ends the run after the last completed scan.

    Returns a dict: ``table`` (columns :data:`TRACK_COLUMNS`: every state of
    every track the tracker ever held — updates and predictions, ``updated`` 1
    for an update — time in seconds on the scene's time base, integer ids by
    first appearance), ``scans_done``, ``scans_total``, ``loop_wall``,
    ``loop_cpu`` (seconds of the loop: building each scan's ``Detection`` objects
    and ``update_tracker``) and ``stopped``.
    """
    from stonesoup.types.detection import Detection

    t, z, lab, k, st = check_inputs(times, positions, labels, scan_index, scan_times)
    tracker, measurement = build_tracker(
        config, measurement_noise=measurement_noise, p_d=p_d, clutter_density=clutter_density
    )
    use_labels = config == "demo" and lab is not None

    def stamp(seconds):
        return EPOCH + datetime.timedelta(seconds=float(seconds))

    starts = np.searchsorted(k, np.arange(len(st) + 1))

    def scan(j):
        # built scan by scan: a long record's Detection objects are never all alive twice
        return {
            Detection(
                z[i].reshape(2, 1),
                timestamp=stamp(t[i]),
                measurement_model=measurement,
                metadata={LABEL_KEY: str(lab[i])} if use_labels and lab[i] else {},
            )
            for i in range(starts[j], starts[j + 1])
        }

    every_track: dict = {}  # Stone Soup track → (integer id); insertion order = first appearance
    done = 0
    stopped = False
    wall0, cpu0 = time.perf_counter(), time.process_time()
    try:
        for j in range(len(st)):
            _, current = tracker.update_tracker(stamp(st[j]), scan(j))
            for track in current:
                every_track.setdefault(track, len(every_track))
            done = j + 1
            if on_scan is not None:
                on_scan(done)
    except StopTracking:
        stopped = True
    loop_wall, loop_cpu = time.perf_counter() - wall0, time.process_time() - cpu0

    # states of a scan the stop interrupted lie after the last completed scan's time
    last = stamp(st[done - 1]) if done else None
    rows = []
    for track, tid in every_track.items():
        for state in track.states:
            if last is None or state.timestamp > last:
                continue
            sv = np.asarray(state.state_vector, dtype=np.float64).ravel()
            seconds = (state.timestamp - EPOCH).total_seconds()
            is_update = float(bool(getattr(state, "hypothesis", None)))
            rows.append((seconds, tid, sv[0], sv[2], sv[1], sv[3], is_update))
    table = np.array(rows, dtype=np.float64).reshape(-1, len(TRACK_COLUMNS))
    if len(table):
        table = table[np.lexsort((table[:, 1], table[:, 0]))]
    return {
        "table": table,
        "scans_done": done,
        "scans_total": len(st),
        "loop_wall": loop_wall,
        "loop_cpu": loop_cpu,
        "stopped": stopped,
    }


@dataclass
class StoneSoupRun:
    """One measured Stone Soup run (:func:`run_stonesoup`).

    Times in seconds, memory in bytes. ``track_times`` … ``track_updated`` are
    the columns of the track table (:func:`track_stonesoup`); empty when the
    child died without writing it (``error`` says why).
    """

    config: str
    scans_done: int
    scans_total: int
    completed: bool
    stopped_by: str | None  # None, "wall_cap", "rss_cap" or "killed"
    wall: float  # the child's life
    cpu: float  # user + system CPU of the child
    loop_wall: float | None
    loop_cpu: float | None
    peak_rss: int
    rss_times: np.ndarray  # seconds since the child started
    rss: np.ndarray  # bytes
    track_times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    track_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    track_positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    track_velocities: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    track_updated: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    error: str | None = None

    def summary(self) -> dict:
        """The figures as JSON-ready numbers (no arrays but the RSS series)."""
        return {
            "config": self.config,
            "scans_done": self.scans_done,
            "scans_total": self.scans_total,
            "completed": self.completed,
            "stopped_by": self.stopped_by,
            "wall_s": round(self.wall, 3),
            "cpu_s": round(self.cpu, 3),
            "loop_wall_s": None if self.loop_wall is None else round(self.loop_wall, 3),
            "loop_cpu_s": None if self.loop_cpu is None else round(self.loop_cpu, 3),
            "peak_rss_bytes": int(self.peak_rss),
            "rss_series": {
                "t_s": [round(float(v), 2) for v in self.rss_times],
                "rss_bytes": [int(v) for v in self.rss],
            },
            "n_tracks": int(len(np.unique(self.track_ids))),
            "n_track_states": int(len(self.track_ids)),
            "error": self.error,
        }


def run_stonesoup(
    config: str,
    times,
    positions,
    labels,
    scan_index,
    scan_times,
    *,
    measurement_noise: float | None = None,
    p_d: float | None = None,
    clutter_density: float | None = None,
    wall_cap: float = 600.0,
    rss_cap: int | None = None,
    poll: float = 0.5,
    grace: float = 30.0,
    workdir=None,
    progress: Callable[[int, int], None] | None = None,
) -> StoneSoupRun:
    """Run a configuration in a child process under a wall-time cap; measure it.

    Parameters
    ----------
    config : one of :data:`CONFIGURATIONS`.
    times, positions, labels, scan_index, scan_times : the reports
        (:func:`check_inputs`); ``labels`` may be ``None``.
    measurement_noise, p_d, clutter_density : the sensor figures
        (:func:`build_tracker`).
    wall_cap : seconds of the child's life before it is told to stop.
    rss_cap : bytes of resident memory above which it is told to stop (``None``:
        no cap).
    poll : seconds between RSS samples.
    grace : seconds a told child has to write its tracks before it is killed.
    workdir : folder for the child's files (default a temporary folder, removed
        afterwards).
    progress : called as ``progress(scans_done, scans_total)`` at each poll.
    """
    if config not in CONFIGURATIONS:
        raise ValueError(f"config must be one of {CONFIGURATIONS}, got {config!r}")
    for name, value in (("wall_cap", wall_cap), ("poll", poll), ("grace", grace)):
        _positive(name, value)
    if rss_cap is not None:
        _positive("rss_cap", rss_cap)
    # the child's sensor checks, here, so bad figures fail before a process starts
    build_tracker(
        config, measurement_noise=measurement_noise, p_d=p_d, clutter_density=clutter_density
    )
    t, z, lab, k, st = check_inputs(times, positions, labels, scan_index, scan_times)

    with tempfile.TemporaryDirectory(prefix="jt-stonesoup-") as tmp:
        folder = Path(workdir) if workdir is not None else Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        arrays = dict(times=t, positions=z, scan_index=k, scan_times=st)
        if lab is not None:
            arrays["labels"] = lab
        np.savez(folder / "input.npz", **arrays)
        params = dict(
            config=config,
            measurement_noise=measurement_noise,
            p_d=p_d,
            clutter_density=clutter_density,
        )
        (folder / "params.json").write_text(json.dumps(params))
        for stale in ("tracks.csv", "status.json", "progress"):
            (folder / stale).unlink(missing_ok=True)
        return _supervise(folder, config, len(st), wall_cap, rss_cap, poll, grace, progress)


def _supervise(folder, config, total, wall_cap, rss_cap, poll, grace, progress) -> StoneSoupRun:
    """Start the child, sample its RSS, stop it at the caps, collect its results."""
    import psutil

    env = dict(os.environ)
    # the child imports this very package, wherever it is loaded from
    package_root = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = os.pathsep.join(p for p in (package_root, env.get("PYTHONPATH")) if p)
    log = open(folder / "child.log", "w")
    start = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, "-m", "jointtrack.bench.stonesoup_realdata", str(folder)],
        stdout=log,
        stderr=subprocess.STDOUT,
        env=env,
    )
    ps = psutil.Process(proc.pid)
    rss_t: list = []
    rss_v: list = []
    stopped_by = None
    told_at = None
    status = rusage = None
    try:
        while True:
            pid, status, rusage = os.wait4(proc.pid, os.WNOHANG)
            now = time.perf_counter() - start
            if pid:
                break
            try:
                rss = ps.memory_info().rss
                rss_t.append(now)
                rss_v.append(rss)
            except psutil.Error:  # exited between wait4 and the sample
                rss = 0
            if progress is not None:
                progress(_read_progress(folder), total)
            if told_at is None:
                if now >= wall_cap:
                    stopped_by = "wall_cap"
                elif rss_cap is not None and rss > rss_cap:
                    stopped_by = "rss_cap"
                if stopped_by and not (folder / "progress").exists():
                    # the child has not yet installed its handler: SIGUSR1 would kill it
                    # anyway, with no tracks to write
                    proc.kill()
                    told_at = now
                elif stopped_by:
                    told_at = now
                    proc.send_signal(signal.SIGUSR1)
            elif now - told_at > grace:
                proc.kill()
                stopped_by = "killed"
            time.sleep(poll)
    finally:
        if proc.returncode is None and status is None:  # interrupted ourselves: no orphan
            proc.kill()
            os.wait4(proc.pid, 0)
        log.close()
    wall = time.perf_counter() - start
    proc.returncode = os.waitstatus_to_exitcode(status)
    cpu = rusage.ru_utime + rusage.ru_stime
    # not rusage.ru_maxrss: Linux keeps the parent's size at the fork in it (_own_peak_rss)
    peak = max(rss_v, default=0)
    run = StoneSoupRun(
        config=config,
        scans_done=0,
        scans_total=total,
        completed=False,
        stopped_by=stopped_by,
        wall=wall,
        cpu=cpu,
        loop_wall=None,
        loop_cpu=None,
        peak_rss=int(peak),
        rss_times=np.asarray(rss_t, dtype=np.float64),
        rss=np.asarray(rss_v, dtype=np.int64),
    )
    status_file = folder / "status.json"
    if proc.returncode != 0 or not status_file.is_file():
        tail = (folder / "child.log").read_text(errors="replace")[-2000:]
        run.error = f"child exited with {proc.returncode}: {tail.strip() or 'no output'}"
        run.scans_done = _read_progress(folder)
        return run
    info = json.loads(status_file.read_text())
    run.scans_done = int(info["scans_done"])
    run.completed = run.scans_done == total
    run.loop_wall, run.loop_cpu = float(info["loop_wall"]), float(info["loop_cpu"])
    run.peak_rss = max(run.peak_rss, int(info.get("vm_hwm_bytes") or 0))
    lines = (folder / "tracks.csv").read_text().splitlines()[1:]  # below the header
    table = np.loadtxt(lines, delimiter=",", ndmin=2) if lines else np.zeros((0, 0))
    table = table.reshape(-1, len(TRACK_COLUMNS))
    run.track_times = table[:, 0]
    run.track_ids = table[:, 1].astype(np.int64)
    run.track_positions = table[:, 2:4]
    run.track_velocities = table[:, 4:6]
    run.track_updated = table[:, 6] > 0
    return run


def _own_peak_rss() -> int | None:
    """This process's peak RSS since its ``exec`` (Linux ``VmHWM``), else ``None``.

    Not ``getrusage``: Linux carries ``ru_maxrss`` over ``fork`` + ``exec``, so a
    child would report the parent's size at the fork if that was larger.
    """
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _read_progress(folder: Path) -> int:
    try:
        return int((folder / "progress").read_text() or 0)
    except (OSError, ValueError):
        return 0


def _child(folder: Path) -> None:
    """The child process: track the input in ``folder``, write the tracks and the status."""

    def stop(signum, frame):
        raise StopTracking

    signal.signal(signal.SIGUSR1, stop)
    # tells the parent the stop signal is handled from now on (before, it kills instead)
    (folder / "progress").write_text("0")
    params = json.loads((folder / "params.json").read_text())
    with np.load(folder / "input.npz", allow_pickle=False) as data:
        arrays = {key: data[key] for key in data.files}
    last_write = [0.0]

    def on_scan(done: int) -> None:
        # at most once a second: the parent only reads it at each poll
        now = time.perf_counter()
        if now - last_write[0] >= 1.0:
            (folder / "progress").write_text(str(done))
            last_write[0] = now

    try:
        result = track_stonesoup(
            params["config"],
            arrays["times"],
            arrays["positions"],
            arrays.get("labels"),
            arrays["scan_index"],
            arrays["scan_times"],
            measurement_noise=params["measurement_noise"],
            p_d=params["p_d"],
            clutter_density=params["clutter_density"],
            on_scan=on_scan,
        )
    except StopTracking:  # stopped before the first scan (importing, building the tracker)
        result = {
            "table": np.zeros((0, len(TRACK_COLUMNS))),
            "scans_done": 0,
            "scans_total": len(arrays["scan_times"]),
            "loop_wall": 0.0,
            "loop_cpu": 0.0,
            "stopped": True,
        }
    # no stop may interrupt the writing
    signal.signal(signal.SIGUSR1, signal.SIG_IGN)
    (folder / "progress").write_text(str(result["scans_done"]))
    np.savetxt(
        folder / "tracks.csv",
        result["table"],
        delimiter=",",
        header=",".join(TRACK_COLUMNS),
        comments="",
        fmt=["%.6f", "%d", "%.6f", "%.6f", "%.6f", "%.6f", "%d"],
    )
    status = {key: result[key] for key in ("scans_done", "scans_total", "loop_wall", "loop_cpu")}
    status["stopped"] = result["stopped"]
    status["vm_hwm_bytes"] = _own_peak_rss()
    (folder / "status.json").write_text(json.dumps(status))


if __name__ == "__main__":
    _child(Path(sys.argv[1]))
