"""Real AIS and ADS-B data end to end: jointtrack beside Stone Soup's own demo trackers.

Run as ``jointtrack bench realdata [--quick] [--scene NAME|all] [--seeds N]
[--bare-tracker jipda|pmb|pmbm] [--out DIR]`` or ``python benchmarks/realdata.py``. The
data (public, from the package registry) is fetched on first use by
:func:`jointtrack.bench.realdata_data.fetch_realdata` into ``--cache-dir`` (default
``$JOINTTRACK_DATA`` or ``~/.cache/jointtrack/realdata``).

Scenes (:func:`build_scenes`)
-----------------------------
``solent-labels`` / ``solent``
    Stone Soup's ``SolentAIS_20160112_130211.csv`` (18,623 AIS reports of 91
    vessels, 86 minutes) reduced exactly as Stone Soup's Solent demo feeds its
    tracker — its own ``CSVDetectionReader`` → ``TimeSyncFeeder(60 s)`` →
    ``MetadataReducer("MMSI")``, the latest report of each vessel per minute
    (:func:`jointtrack.bench.stonesoup_realdata.demo_pipeline_reports`; 3,626
    reports in 86 scans) — projected to local east/north metres about the
    reports' centre (:class:`jointtrack.io.geodetic.LocalFrame`). ``solent-labels``
    gives the trackers the MMSI of each report as a label, ``solent`` does not.
    Each report keeps its own time; a scan is the feeder's one-minute window.
    Scored against every report of the file (the vessels' self-reports) at
    one-minute instants, c = 500 m. ``--quick``: the first 30 scans.
``adsb`` / ``adsb-quickstart``
    traffic's ``switzerland.json.gz`` (about 17 h, 842 aircraft: the scene the
    hand-set settings were tuned on) / ``quickstart.json.gz`` (3 h, 213 other
    aircraft, manoeuvring: held out, never tuned on) through
    :class:`jointtrack.io.reports.Reports`, seen by a synthetic sensor scanning
    every 10 s (:func:`scanning_sensor`): at each scan time each aircraft at its
    reported positions interpolated to that time (not the last report before it:
    at 250 m/s up to 10 s of lag would be 2.5 km), then each detection kept with
    probability P_D = 0.9, Poisson clutter of 20 false returns per 10 s scan over
    the reports' lat/lon box, identities stripped (``Reports.degrade``, seeded),
    and position noise of 50 m (σ per axis, seeded) added to every row. Every row
    carries its scan's time. Scored against all the undegraded reports at 10 s instants,
    c = 500 m. ``--seeds N`` builds each ADS-B scene with the degradation seeds
    ``--seed`` … ``--seed + N − 1`` (detection draws, clutter and noise); the table
    shows the mean and the spread (min–max) over them and ``realdata.json`` keeps every
    seed's figures. ``--quick``: the first :data:`QUICK_ADSB_SCANS` scans (30 min).

Detection times. Stone Soup's Solent demo keeps each report's own time (its
``TimeSyncFeeder`` groups reports but does not re-stamp them), and so does the
``solent`` scenes' default (``Scene.stamp = "report"``). That is costly for a
tracker without the label gate: Stone Soup then predicts every track to every
report's own time — on the first 25 Solent scans ``stonesoup-nn`` took 110 s of
CPU with own times against 4 s with every report at its scan's time (67 and 69
track ids). The ``adsb`` scene stamps every report at its scan's time
(``stamp = "scan"``: a scanning sensor's output, and what jointtrack's
``Detections`` hold). ``--stamp report|scan`` overrides both.

Runners (:data:`RUNNERS`)
-------------------------
``stonesoup-demo`` (labels), ``stonesoup-nn``, ``stonesoup-gnn``, ``stonesoup-jpda``:
:mod:`jointtrack.bench.stonesoup_realdata` (the configurations and their sources
are listed there), each in a child process capped at ``--cap`` seconds (600)
whose RSS is sampled every 0.5 s. ``jointtrack-handset`` (formerly
``jointtrack-jipda``, still accepted): JIPDA with the settings a person chose for
these data; ``jointtrack-bare``: the bare ``jointtrack run --detections FILE`` with
no config on the scene's rows written as a plain ``time, lat, lon`` file, and
``jointtrack-bare-<kind>`` the same with ``tracker=<kind>`` (``--bare-tracker``;
a refusal is recorded as that run's result) —
:mod:`jointtrack.bench.jointtrack_realdata`. More runners are registered with
:func:`register_runner`; every runner returns a :class:`RunResult` with the same
figures.

Figures
-------
Wall and CPU time (of the whole run: the child's life for Stone Soup), peak
RSS, scans done / total, and the scores of
:func:`jointtrack.metrics.selfreport.score_self_reports` (coverage, purity,
tracks per identity, identity switches, false tracks per hour, mean GOSPA)
on every track state the runner reported, with its splits: ids per identity
counted two ways (all ids; ids held ≥ 1 min) and coverage and lost truth points
per class of truth point — straight flight, manoeuvre (> 1 °/s), close pair
(another identity within 2 km) — as defined there; × real time = the scene's
duration / the run's CPU. ``--out DIR`` writes ``realdata.json`` (figures per
seed and their spread, RSS series), ``realdata.md`` (the table in Markdown),
``coverage_classes.png`` (coverage per class per runner, min–max over seeds),
each run's track table as CSV, ``rss_<scene>.png`` (RSS over time) and
``map_<scene>_<runner>.png`` (the tracks over the self-reports in lon/lat,
:mod:`jointtrack.experiments.map_plot`; first seed).
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from jointtrack._console import make_console

__all__ = [
    "RUNNERS",
    "RssSampler",
    "RunResult",
    "Scene",
    "build_scenes",
    "register_runner",
    "run",
    "score_run",
]

SOLENT_WINDOW = 60.0  # s: the demo's TimeSyncFeeder window, and the scoring instants
QUICK_SOLENT_SCANS = 30
QUICK_ADSB_SCANS = 180  # the first 30 minutes of 10 s scans
ADSB_SCAN = 10.0  # s
ADSB_NOISE_SD = 50.0  # m, per axis
ADSB_P_D = 0.9
ADSB_CLUTTER_PER_SCAN = 20.0
CUTOFF = 500.0  # m: GOSPA cut-off and association gate of the scores
MAX_GAP = 600.0  # s: a self-report gap longer than this is not interpolated
WALL_CAP = 600.0  # s
SEED = 0
SCENE_NAMES = ("solent-labels", "solent", "adsb", "adsb-quickstart")
#: the ADS-B scenes' data files (keys of fetch_realdata)
ADSB_FILES = {"adsb": "switzerland", "adsb-quickstart": "quickstart"}
#: old runner names still accepted
RUNNER_ALIASES = {"jointtrack-jipda": "jointtrack-handset"}
STAMPS = ("report", "scan")


@dataclass(eq=False)
class Scene:
    """The identical reports every runner gets, and what the scores need.

    ``times`` (R,) s since ``time_origin`` (ISO-8601 UTC); ``positions`` (R, 2)
    east/north metres in ``frame`` (a :class:`jointtrack.io.geodetic.LocalFrame`);
    ``labels`` (R,) str (``""`` none) or ``None``; ``scan_index`` (R,) and
    ``scan_times`` (K,) as :func:`jointtrack.bench.stonesoup_realdata.check_inputs`
    wants them. ``measurement_noise`` m² per axis, ``p_d``, ``clutter_density``
    per m² per scan: the sensor as the scene built it (runners that need a sensor
    model use these). ``truth`` loads ``(times, ids, positions)`` of the
    self-reports in ``frame`` for the scores.
    """

    name: str
    description: str
    time_origin: str
    frame: object
    times: np.ndarray
    positions: np.ndarray
    labels: np.ndarray | None
    scan_index: np.ndarray
    scan_times: np.ndarray
    measurement_noise: float
    p_d: float
    clutter_density: float
    window: float
    truth: Callable[[], tuple]
    cutoff: float = CUTOFF
    default_runners: tuple = ()
    info: dict = field(default_factory=dict)
    #: the time Stone Soup's Detection objects carry: "report" (each its own, as the
    #: Solent demo's TimeSyncFeeder leaves them) or "scan" (the scan's time, what a
    #: scanning sensor reports and what jointtrack's Detections hold)
    stamp: str = "report"
    #: (R, 2) east/north velocities the reports carry (AIS speed and course), NaN
    #: where unknown, or None; runners may use them (Stone Soup's demo does not)
    velocities: np.ndarray | None = None
    #: the degradation seed the scene was built with (None: the scene draws nothing)
    seed: int | None = None

    def stamps(self, stamp: str | None = None) -> np.ndarray:
        """Per-report times for Stone Soup under ``stamp`` (default the scene's)."""
        stamp = self.stamp if stamp is None else stamp
        if stamp not in STAMPS:
            raise ValueError(f"stamp must be one of {STAMPS}, got {stamp!r}")
        return self.times if stamp == "report" else self.scan_times[self.scan_index]

    @property
    def n_scans(self) -> int:
        return len(self.scan_times)

    @property
    def duration(self) -> float:
        """Seconds from the first scan to the last."""
        return float(self.scan_times[-1] - self.scan_times[0]) if self.n_scans else 0.0

    def describe(self) -> dict:
        reference = getattr(self.frame, "reference", None)
        return {
            "description": self.description,
            "time_origin": self.time_origin,
            "reference_lat_lon_alt": None if reference is None else [float(v) for v in reference],
            "reports": int(len(self.times)),
            "scans": self.n_scans,
            "duration_s": self.duration,
            "labels": self.labels is not None,
            "measurement_noise_m2": self.measurement_noise,
            "p_d": self.p_d,
            "clutter_density_per_m2_per_scan": self.clutter_density,
            "score_window_s": self.window,
            "cutoff_m": self.cutoff,
            "stonesoup_detection_times": self.stamp,
            "seed": self.seed,
            **self.info,
        }


@dataclass(eq=False)
class RunResult:
    """One runner on one scene: costs, the track table (every reported track state) and
    the scores. Times in seconds, memory in bytes; ``error`` says why a run has no
    tracks."""

    runner: str
    scene: str
    wall: float
    cpu: float
    peak_rss: int
    scans_done: int
    scans_total: int
    rss_times: np.ndarray
    rss: np.ndarray
    track_times: np.ndarray
    track_ids: np.ndarray
    track_positions: np.ndarray
    stopped_by: str | None = None
    error: str | None = None
    details: dict = field(default_factory=dict)
    score: dict | None = None
    score_error: str | None = None

    @property
    def completed(self) -> bool:
        return self.error is None and self.scans_done == self.scans_total

    def as_dict(self) -> dict:
        return {
            "runner": self.runner,
            "scene": self.scene,
            "wall_s": round(self.wall, 3),
            "cpu_s": round(self.cpu, 3),
            "peak_rss_bytes": int(self.peak_rss),
            "scans_done": self.scans_done,
            "scans_total": self.scans_total,
            "completed": self.completed,
            "stopped_by": self.stopped_by,
            "error": self.error,
            "n_track_ids": int(len(np.unique(self.track_ids))),
            "n_track_states": int(len(self.track_ids)),
            "details": self.details,
            "score": self.score,
            "score_error": self.score_error,
            "rss_series": {
                "t_s": [round(float(v), 2) for v in self.rss_times],
                "rss_bytes": [int(v) for v in self.rss],
            },
        }


class RssSampler:
    """Sample this process's RSS every ``poll`` seconds in a background thread.

    For runners measured in-process: ``with RssSampler() as s: ...`` then
    ``s.times`` (s since entry), ``s.rss`` (bytes) and ``s.peak`` (the largest
    sample, and the process's peak RSS so far from ``getrusage`` — which includes
    whatever ran before in this process, so prefer a fresh process for peaks).
    """

    def __init__(self, poll: float = 0.5):
        self.poll = float(poll)
        self.times: list = []
        self.rss: list = []
        self._stop = threading.Event()

    def _sample(self):
        import psutil

        me = psutil.Process()
        while True:
            self.times.append(time.perf_counter() - self._t0)
            self.rss.append(me.memory_info().rss)
            if self._stop.wait(self.poll):
                return

    def __enter__(self):
        self._t0 = time.perf_counter()
        self._thread = threading.Thread(target=self._sample, daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        return False

    @property
    def peak(self) -> int:
        import resource

        return max([*self.rss, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024])


# --------------------------------------------------------------------------- scenes


def truth_arrays(truth) -> tuple:
    """``(times, ids, positions (R, 2))`` from ``Reports.truth(frame)``, which returns the
    three arrays and the identity → truth id dict (as ``((t, ids, xy), dict)`` or
    ``(t, ids, xy, dict)``)."""
    if len(truth) == 2:
        truth = truth[0]
    t, ids, xy = truth[:3]
    xy = np.asarray(xy, dtype=np.float64)
    return np.asarray(t, dtype=np.float64), np.asarray(ids, dtype=np.int64), xy[:, :2]


def _local_frame_about(lat, lon):
    """The local east/north frame about the data's centre (jointtrack.io.geodetic)."""
    from jointtrack.io.geodetic import LocalFrame

    return LocalFrame.centre(np.asarray(lat), np.asarray(lon))


def solent_scenes(path, *, quick: bool = False) -> list[Scene]:
    """``solent-labels`` and ``solent`` (module docstring) from the Solent AIS CSV."""
    from jointtrack.bench.stonesoup_realdata import demo_pipeline_reports

    d = demo_pipeline_reports(path, window=SOLENT_WINDOW)
    times, scan_index, scan_times = d["times"], d["scan_index"], d["scan_times"]
    lat, lon, labels = d["lat"], d["lon"], d["labels"]
    if quick:
        keep = scan_index < QUICK_SOLENT_SCANS
        times, lat, lon = times[keep], lat[keep], lon[keep]
        labels, scan_index = labels[keep], scan_index[keep]
        scan_times = scan_times[:QUICK_SOLENT_SCANS]
    frame = _local_frame_about(lat, lon)
    positions = np.asarray(frame.to_local(lat, lon), dtype=np.float64)[:, :2]
    from jointtrack.io.geodetic import KNOT, velocity_en

    speed, course = d["speed_knots"], d["course_deg"]
    if quick:
        speed, course = speed[keep], course[keep]
    # AIS "not available": speed 102.3 kn, course 360 (a speed of 0 needs no course)
    speed = np.where(speed >= 102.3, np.nan, speed) * KNOT
    course = np.where(course >= 360.0, np.nan, course)
    velocities = velocity_en(speed, np.where(speed == 0, 0.0, course))
    last = float(scan_times[-1])

    def truth():
        from jointtrack.io.reports import read_ais_csv

        t, ids, xy = truth_arrays(read_ais_csv(path).truth(frame))
        keep = t <= last
        return t[keep], ids[keep], np.asarray(xy)[keep, :2]

    info = {
        "data": Path(path).name,
        "raw_reports": int(d["n_raw"]),
        "vessels": int(len(set(labels.tolist()))),
        "reduction": "Stone Soup TimeSyncFeeder(60 s) + MetadataReducer('MMSI')",
    }
    common = dict(
        time_origin=d["time_origin"],
        frame=frame,
        times=times,
        positions=positions,
        scan_index=scan_index,
        scan_times=scan_times,
        measurement_noise=15.0,  # the demo's LinearGaussian diag(15, 15)
        p_d=1.0,
        clutter_density=0.0,
        window=SOLENT_WINDOW,
        truth=truth,
        info=info,
        velocities=velocities,
    )
    return [
        Scene(
            name="solent-labels",
            description="Solent AIS, demo pipeline (60 s), MMSI labels given",
            labels=labels,
            default_runners=("jointtrack-handset", "jointtrack-bare", "stonesoup-demo"),
            **common,
        ),
        Scene(
            name="solent",
            description="Solent AIS, demo pipeline (60 s), no labels",
            labels=None,
            default_runners=("jointtrack-handset", "jointtrack-bare", "stonesoup-nn"),
            **common,
        ),
    ]


def scanning_sensor(reports, frame, scan: float, max_gap: float):
    """What a sensor scanning every ``scan`` seconds sees of self-reporting targets.

    Scan times are the windows' ends of ``reports.window_index(scan)`` (the first
    report's time, then every ``scan`` seconds). At each scan time every identity
    is seen at its reported position linearly interpolated in the local ``frame``
    between its two reports around that time — the same reference the scores use
    (:mod:`jointtrack.metrics.selfreport`) — if those two reports are at most
    ``max_gap`` seconds apart (or one falls on the scan time); outside its reports'
    span an identity is not seen. Returns ``(Reports at the scan times, in lat/lon
    with identities, scan_times)``.
    """
    from jointtrack.io.reports import Reports

    _, scan_times = reports.window_index(scan)
    scan_times = np.asarray(scan_times, dtype=np.float64)
    xy = np.asarray(frame.to_local(reports.lat, reports.lon), dtype=np.float64)[:, :2]
    ident = reports.identity
    has = np.flatnonzero(ident != "")
    order = has[np.argsort(ident[has], kind="stable")]  # by identity, then time
    names, starts = np.unique(ident[order], return_index=True)
    bounds = np.r_[starts, len(order)]
    out_t, out_xy, out_id = [], [], []
    for n, name in enumerate(names):
        rows = order[bounds[n] : bounds[n + 1]]
        tau, p = reports.times[rows], xy[rows]
        lo = np.searchsorted(scan_times, tau[0], side="left")
        hi = np.searchsorted(scan_times, tau[-1], side="right")
        t = scan_times[lo:hi]
        if not t.size:
            continue
        after = np.minimum(np.searchsorted(tau, t, side="left"), len(tau) - 1)
        before = np.maximum(np.searchsorted(tau, t, side="right") - 1, 0)
        seen = (tau[after] == t) | (tau[after] - tau[before] <= max_gap)
        t = t[seen]
        out_t.append(t)
        out_xy.append(np.column_stack([np.interp(t, tau, p[:, 0]), np.interp(t, tau, p[:, 1])]))
        out_id.append(np.full(t.size, name))
    t = np.concatenate(out_t) if out_t else np.zeros(0)
    ids = np.concatenate(out_id) if out_id else np.zeros(0, dtype=str)
    pos = np.concatenate(out_xy) if out_xy else np.zeros((0, 2))
    by_time = np.lexsort((ids, t))
    lat, lon = frame.to_geodetic(pos[by_time])[:2]
    sensor = Reports(
        times=t[by_time],
        time_origin=reports.time_origin,
        lat=lat,
        lon=lon,
        identity=ids[by_time],
        source=reports.source,
    )
    return sensor, scan_times


def adsb_scene(
    path, *, seed: int = SEED, name: str = "adsb", max_scans: int | None = None
) -> Scene:
    """``adsb`` (module docstring) from a traffic records file, via jointtrack.io.reports,
    called ``name``; ``max_scans``: only the first that many scans (and the reports up to
    the last of them)."""
    from jointtrack.io.reports import read_traffic_records

    reports = read_traffic_records(path)
    frame = reports.frame()
    sensor, scan_times = scanning_sensor(reports, frame, ADSB_SCAN, MAX_GAP)
    if max_scans is not None and max_scans < len(scan_times):
        scan_times = scan_times[:max_scans]
        last = float(scan_times[-1])
        sensor = sensor.subset(sensor.times <= last)
        reports = reports.subset(reports.times <= last + MAX_GAP)
    degraded = sensor.degrade(
        p_d=ADSB_P_D,
        # io.reports counts clutter in false reports per second of data
        clutter_rate=ADSB_CLUTTER_PER_SCAN / ADSB_SCAN,
        seed=seed,
        strip_identities=True,
    )
    # aircraft rows sit on a scan time; a clutter row belongs to the scan whose window
    # (previous scan time, scan time] holds it — counted in whole nanoseconds
    w_ns = round(ADSB_SCAN * 1e9)
    t0_ns = round(float(scan_times[0]) * 1e9)
    rel = np.round(degraded.times * 1e9).astype(np.int64) - t0_ns
    scan_index = np.where(
        degraded.is_clutter,
        -(-rel // w_ns),
        np.round((degraded.times - scan_times[0]) / ADSB_SCAN).astype(np.int64),
    )
    scan_index = np.clip(scan_index, 0, len(scan_times) - 1)
    order = np.argsort(scan_index, kind="stable")
    scan_index = scan_index[order]
    positions = np.asarray(frame.to_local(degraded.lat, degraded.lon), dtype=np.float64)
    positions = positions[order, :2]
    is_clutter = degraded.is_clutter[order]
    # the synthetic sensor's noise, on every row (clutter too), the same for every runner
    rng = np.random.default_rng([seed, 24])
    positions = positions + rng.normal(0.0, ADSB_NOISE_SD, positions.shape)
    n_clutter = int(np.count_nonzero(is_clutter))
    # clutter density from the false rows themselves: over the box they were drawn in
    clutter_xy = positions[is_clutter]
    box = float(np.prod(np.ptp(clutter_xy, axis=0))) if n_clutter > 1 else 0.0
    clutter_density = n_clutter / (len(scan_times) * box) if box > 0 else 1e-12
    times = scan_times[scan_index]

    last_scan = float(scan_times[-1])

    def truth():
        t, ids, xy = truth_arrays(reports.truth(frame))
        keep = t <= last_scan
        return t[keep], ids[keep], xy[keep]

    return Scene(
        name=name,
        description=(
            f"ADS-B {Path(path).name}: identities stripped, P_D {ADSB_P_D}, "
            f"{ADSB_CLUTTER_PER_SCAN:g} false returns per {ADSB_SCAN:g} s scan, "
            f"{ADSB_NOISE_SD:g} m noise (seed {seed})"
        ),
        time_origin=degraded.time_origin,
        frame=frame,
        times=times,
        positions=positions,
        labels=None,
        scan_index=scan_index,
        scan_times=scan_times,
        measurement_noise=ADSB_NOISE_SD**2,
        stamp="scan",
        p_d=ADSB_P_D,
        clutter_density=float(clutter_density),
        window=ADSB_SCAN,
        truth=truth,
        default_runners=(
            "jointtrack-handset",
            "jointtrack-bare",
            "stonesoup-gnn",
            "stonesoup-jpda",
        ),
        seed=seed,
        info={
            "data": Path(path).name,
            "raw_reports": int(len(reports.times)),
            "aircraft": int(len(set(reports.identity.tolist()) - {""})),
            "sensor_detections": int(len(sensor.times)),
            "clutter_rows": n_clutter,
            "seed": seed,
        },
    )


def build_scenes(names, paths: dict, *, quick: bool = False, seed: int = SEED) -> list[Scene]:
    """The scenes called ``names`` (of :data:`SCENE_NAMES`) from the fetched files; the
    ADS-B ones degraded with ``seed``."""
    unknown = [n for n in names if n not in SCENE_NAMES]
    if unknown:
        raise ValueError(f"scene must be among {SCENE_NAMES}, got {unknown}")
    scenes = []
    if {"solent", "solent-labels"} & set(names):
        scenes += [s for s in solent_scenes(paths["solent_ais"], quick=quick) if s.name in names]
    for name, key in ADSB_FILES.items():
        if name in names:
            limit = QUICK_ADSB_SCANS if quick else None
            scenes.append(adsb_scene(paths[key], seed=seed, name=name, max_scans=limit))
    return scenes


# --------------------------------------------------------------------------- runners


def _stonesoup_runner(config: str):
    def runner(
        scene: Scene, *, wall_cap: float, workdir=None, progress=None, stamp=None
    ) -> RunResult:
        from jointtrack.bench.stonesoup_realdata import run_stonesoup

        if config == "demo" and scene.labels is None:
            raise ValueError(f"stonesoup-demo gates on labels; scene {scene.name!r} has none")
        r = run_stonesoup(
            config,
            scene.stamps(stamp),
            scene.positions,
            scene.labels if config == "demo" else None,
            scene.scan_index,
            scene.scan_times,
            measurement_noise=scene.measurement_noise,
            p_d=scene.p_d,
            clutter_density=scene.clutter_density,
            wall_cap=wall_cap,
            workdir=workdir,
            progress=progress,
        )
        return RunResult(
            runner=f"stonesoup-{config}",
            scene=scene.name,
            wall=r.wall,
            cpu=r.cpu,
            peak_rss=r.peak_rss,
            scans_done=r.scans_done,
            scans_total=r.scans_total,
            rss_times=r.rss_times,
            rss=r.rss,
            track_times=r.track_times,
            track_ids=r.track_ids,
            track_positions=r.track_positions,
            stopped_by=r.stopped_by,
            error=r.error,
            details={
                "detection_times": scene.stamp if stamp is None else stamp,
                "loop_wall_s": r.loop_wall,
                "loop_cpu_s": r.loop_cpu,
                "measured": "child process: wall = its life, CPU = wait4 user+system, "
                "peak RSS = max(VmHWM, 0.5 s samples)",
            },
        )

    runner.__name__ = f"run_stonesoup_{config}"
    return runner


#: name → runner(scene, *, wall_cap, workdir=None, progress=None) -> RunResult
RUNNERS: dict[str, Callable] = {
    f"stonesoup-{c}": _stonesoup_runner(c) for c in ("demo", "nn", "gnn", "jpda")
}


def _run_jointtrack(scene: Scene, *, wall_cap: float, workdir=None, progress=None):
    from jointtrack.bench.jointtrack_realdata import run_jointtrack

    return run_jointtrack(scene, wall_cap=wall_cap, workdir=workdir, progress=progress)


def _bare_runner(tracker: str | None):
    def runner(scene: Scene, *, wall_cap: float, workdir=None, progress=None) -> RunResult:
        from jointtrack.bench.jointtrack_realdata import run_bare

        return run_bare(
            scene, tracker=tracker, wall_cap=wall_cap, workdir=workdir, progress=progress
        )

    runner.__name__ = "run_bare" + ("" if tracker is None else f"_{tracker}")
    return runner


#: ``--bare-tracker`` kinds: ``jointtrack-bare-<kind>`` passes ``tracker=<kind>``
BARE_TRACKERS = ("jipda", "pmb", "pmbm")

RUNNERS["jointtrack-handset"] = _run_jointtrack
RUNNERS["jointtrack-bare"] = _bare_runner(None)
for _kind in BARE_TRACKERS:
    RUNNERS[f"jointtrack-bare-{_kind}"] = _bare_runner(_kind)


def register_runner(name: str, runner: Callable) -> None:
    """Add (or replace) a runner ``runner(scene, *, wall_cap, workdir=None, progress=None)``
    returning a :class:`RunResult`."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"name must be a non-empty string, got {name!r}")
    if not callable(runner):
        raise TypeError(f"runner must be callable, got {type(runner).__name__}")
    RUNNERS[name] = runner


# --------------------------------------------------------------------------- scores


def score_run(scene: Scene, result: RunResult, truth=None) -> RunResult:
    """Fill ``result.score`` with :func:`jointtrack.metrics.selfreport.score_self_reports`
    of its track table against the scene's self-reports (``truth``: the scene's, loaded
    once by the caller and passed in to save reloading), over the scans the run
    completed; ``result.score_error`` says why when it cannot be scored."""
    try:
        from jointtrack.metrics.selfreport import score_self_reports
    except ImportError as exc:
        result.score_error = f"jointtrack.metrics.selfreport unavailable ({exc})"
        return result
    if result.error is not None and not len(result.track_ids):
        result.score_error = "no tracks (the run failed)"
        return result
    if not result.scans_done:
        result.score_error = "no scan completed"
        return result
    try:
        t, ids, xy = scene.truth() if truth is None else truth
    except ImportError as exc:
        result.score_error = f"self-reports unavailable ({exc})"
        return result
    end = float(scene.scan_times[result.scans_done - 1])
    keep = t <= end
    score = score_self_reports(
        t[keep],
        ids[keep],
        xy[keep],
        result.track_times,
        result.track_ids,
        result.track_positions,
        window=scene.window,
        c=scene.cutoff,
        max_gap=MAX_GAP,
        duration=max(end - float(scene.scan_times[0]), scene.window),
        t0=float(scene.scan_times[0]),
    )
    result.score = score.as_dict()
    result.score.pop("per_identity", None)  # large; the per-run CSVs allow recomputing it
    return result


# --------------------------------------------------------------------------- output

#: the figures of the table, per run: (key, column title, format); ``lost_*`` in %
FIGURES = (
    ("coverage", "cov", ".3f"),
    ("coverage_straight", "cov straight", ".3f"),
    ("coverage_manoeuvre", "cov manoeuvre", ".3f"),
    ("coverage_close_pair", "cov close pair", ".3f"),
    ("lost_straight", "lost % straight", ".1f"),
    ("lost_manoeuvre", "lost % manoeuvre", ".1f"),
    ("lost_close_pair", "lost % close pair", ".1f"),
    ("purity", "purity", ".3f"),
    ("tracks_per_identity", "ids / target", ".2f"),
    ("tracks_per_identity_held", "ids ≥ 1 min", ".2f"),
    ("false_tracks_per_hour", "false / h", ".1f"),
    ("gospa_mean", "GOSPA", ".0f"),
    ("cpu_s", "CPU s", ".1f"),
    ("x_real_time", "× real time", ".0f"),
    ("peak_rss_mib", "peak RSS MiB", ".0f"),
)

#: the figures of :data:`FIGURES` that are costs (defined without a score)
_COSTS = ("cpu_s", "x_real_time", "peak_rss_mib")


def run_figures(result: RunResult, scan_times) -> dict:
    """The table's figures of one run (keys of :data:`FIGURES`; None where undefined):
    the scores, lost truth points in % per class, CPU, × real time (the span of the
    scans the run completed, of the scene's ``scan_times``, over its CPU) and peak RSS
    in MiB."""
    score = result.score or {}
    out = {}
    for key, _, _ in FIGURES:
        v = score.get(key)
        if key.startswith("lost_") and v is not None:
            v = 100.0 * v
        out[key] = v
    out["cpu_s"] = float(result.cpu)
    done = min(int(result.scans_done), len(scan_times))
    span = float(scan_times[done - 1] - scan_times[0]) if done else 0.0
    out["x_real_time"] = span / result.cpu if result.cpu > 0 and span > 0 else None
    out["peak_rss_mib"] = result.peak_rss / 2**20 if result.peak_rss else None
    if result.score is None:  # not scored: no figure of the tracks means anything
        out = {k: (v if k in _COSTS else None) for k, v in out.items()}
    return out


def spread(values: list) -> dict | None:
    """``{"mean", "min", "max", "n"}`` of the defined values (None for none)."""
    v = [float(x) for x in values if x is not None and math.isfinite(float(x))]
    if not v:
        return None
    return {"mean": sum(v) / len(v), "min": min(v), "max": max(v), "n": len(v)}


def _cell(s: dict | None, fmt: str) -> str:
    if s is None:
        return "—"
    if s["n"] < 2 or s["min"] == s["max"]:
        return format(s["mean"], fmt)
    return f"{format(s['mean'], fmt)} ({format(s['min'], fmt)}–{format(s['max'], fmt)})"


def _rows(report: dict):
    """(scene, runner, seeds text, scans text, {key: cell}, errors) per scene and runner."""
    for scene, entry in report["scenes"].items():
        for runner, run_entry in entry["runs"].items():
            per_seed = run_entry["per_seed"]
            scans = {f"{r['scans_done']}/{r['scans_total']}" for r in per_seed.values()}
            cells = {key: _cell(run_entry["spread"].get(key), fmt) for key, _, fmt in FIGURES}
            errors = sorted({r["error"] for r in per_seed.values() if r["error"]})
            yield scene, runner, len(per_seed), ", ".join(sorted(scans)), cells, errors


def table(report: dict, title: str = "real data"):
    """The rich table of a :func:`run` report: per scene and runner, the mean and the
    spread (min–max) over the seeds of every figure of :data:`FIGURES`."""
    from rich.table import Table

    t = Table(title=title)
    for col in ("scene", "runner", "seeds", "scans"):
        t.add_column(col, justify="left" if col in ("scene", "runner") else "right")
    for _, name, _ in FIGURES:
        t.add_column(name, justify="right")
    for scene, runner, n, scans, cells, _ in _rows(report):
        t.add_row(scene, runner, str(n), scans, *(cells[k] for k, _, _ in FIGURES))
    return t


def markdown_table(report: dict) -> str:
    """The table of :func:`table` in Markdown (for ``RESULTS.md``), with each run's
    error under it."""
    head = ["scene", "runner", "seeds", "scans", *(name for _, name, _ in FIGURES)]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    notes = []
    for scene, runner, n, scans, cells, errors in _rows(report):
        lines.append(
            "| "
            + " | ".join([scene, runner, str(n), scans, *(cells[k] for k, _, _ in FIGURES)])
            + " |"
        )
        notes += [f"- {scene} / {runner}: {e}" for e in errors]
    return "\n".join(lines + ([""] + notes if notes else [])) + "\n"


def plot_coverage_classes(report: dict, path) -> Path | None:
    """Bar chart: per scene (one panel each), per runner, the coverage overall and per
    class (straight, manoeuvre, close pair), the bars at the mean over the seeds with
    min–max whiskers. None when no run was scored."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = (
        ("coverage", "all"),
        ("coverage_straight", "straight"),
        ("coverage_manoeuvre", "manoeuvre"),
        ("coverage_close_pair", "close pair"),
    )
    scenes = [(n, e) for n, e in report["scenes"].items() if e["runs"]]
    if not scenes:
        return None
    fig, axes = plt.subplots(
        len(scenes), 1, figsize=(9, 3.2 * len(scenes)), constrained_layout=True, squeeze=False
    )
    width = 0.8 / len(keys)
    for ax, (name, entry) in zip(axes[:, 0], scenes, strict=True):
        runners = list(entry["runs"])
        x = np.arange(len(runners))
        for j, (key, label) in enumerate(keys):
            stats = [entry["runs"][r]["spread"].get(key) for r in runners]
            mean = np.array([np.nan if s is None else s["mean"] for s in stats])
            lo = np.array([0.0 if s is None else s["mean"] - s["min"] for s in stats])
            hi = np.array([0.0 if s is None else s["max"] - s["mean"] for s in stats])
            ax.bar(x + (j - 1.5) * width, np.nan_to_num(mean), width, label=label)
            ax.errorbar(
                x + (j - 1.5) * width, np.nan_to_num(mean), yerr=[lo, hi], fmt="none", c="k", lw=1
            )
        ax.set_xticks(x, runners, fontsize=8)
        ax.set_ylim(0, 1.05)
        ax.set_ylabel("coverage")
        seeds = entry.get("seeds") or []
        ax.set_title(f"{name}" + (f" (seeds {seeds}: mean, min–max)" if len(seeds) > 1 else ""))
        ax.grid(True, axis="y", alpha=0.3)
    axes[0, 0].legend(fontsize=8, ncol=4)
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_rss(results: list[RunResult], path) -> Path:
    """RSS over time of each run of one scene (matplotlib, Agg)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4), constrained_layout=True)
    for r in results:
        if len(r.rss):
            ax.plot(
                r.rss_times,
                np.asarray(r.rss) / 2**20,
                label=f"{r.runner} ({r.scans_done}/{r.scans_total} scans)",
            )
    ax.set_xlabel("seconds since the run started")
    ax.set_ylabel("RSS (MiB)")
    ax.set_title(f"{results[0].scene}: resident memory")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_map(scene: Scene, result: RunResult, truth, path) -> Path | None:
    """A run's tracks over the self-reports in lon/lat
    (:func:`jointtrack.experiments.map_plot.plot_track_map`); ``None`` (nothing drawn)
    when that module is not available."""
    try:
        from jointtrack.experiments.map_plot import plot_track_map
    except ImportError:
        return None
    _, ids, xy = truth
    report_lat, report_lon = scene.frame.to_geodetic(xy)[:2]
    track_lat, track_lon = scene.frame.to_geodetic(result.track_positions)[:2]
    plot_track_map(
        Path(path),
        report_lat,
        report_lon,
        track_lat,
        track_lon,
        result.track_ids,
        title=f"{scene.name}: {result.runner} ({len(np.unique(result.track_ids))} track ids)",
        report_ids=ids,
        track_times=result.track_times,
    )
    return Path(path)


def _write_tracks(result: RunResult, path: Path) -> None:
    data = np.column_stack([result.track_times, result.track_ids, result.track_positions])
    np.savetxt(
        path,
        data,
        delimiter=",",
        header="time,track_id,x,y",
        comments="",
        fmt=["%.6f", "%d", "%.3f", "%.3f"],
    )


# --------------------------------------------------------------------------- run


def run(
    quick: bool = False,
    out: str | None = None,
    *,
    scenes=("solent-labels", "solent", "adsb", "adsb-quickstart"),
    runners=None,
    cache_dir=None,
    wall_cap: float = WALL_CAP,
    seed: int = SEED,
    seeds: int = 1,
    bare_trackers=(),
    stamp: str | None = None,
    console=None,
) -> dict:
    """Fetch the data, build the scenes, run the runners, score, print and write.

    ``runners`` (names of :data:`RUNNERS`) restricts every scene to those among
    its defaults (``None``: all of them); a named runner that is no built scene's
    default runs on every scene (e.g. ``stonesoup-nn`` on ``adsb``). A runner that is not
    registered is listed as not run. ``bare_trackers`` (of :data:`BARE_TRACKERS`) adds
    ``jointtrack-bare-<kind>`` to every scene. ``seeds``: the scenes built with a
    degradation seed (the ADS-B ones) are built and run with the seeds ``seed`` …
    ``seed + seeds − 1``. ``stamp`` (``"report"`` / ``"scan"``) overrides every scene's
    :attr:`Scene.stamp` for the Stone Soup runners.

    Returns the results as a JSON-ready dict: per scene, ``scene`` (its description,
    first seed), ``seeds``, ``not_run``, and per runner ``per_seed`` (``str(seed)``, or
    ``"unseeded"``: the run's figures, :meth:`RunResult.as_dict`) and ``spread`` (per
    figure of :data:`FIGURES`, mean/min/max/n over the seeds). With ``out`` also writes
    ``out/realdata.json``, ``out/realdata.md``, ``out/coverage_classes.png``,
    ``out/tracks_<scene>_<runner>[_s<seed>].csv`` and ``out/rss_<scene>.png``.
    """
    from jointtrack._console import progress_bar
    from jointtrack.bench.realdata_data import fetch_realdata

    if stamp is not None and stamp not in STAMPS:
        raise ValueError(f"stamp must be one of {STAMPS}, got {stamp!r}")
    if isinstance(seeds, bool) or not isinstance(seeds, int | np.integer) or seeds < 1:
        raise ValueError(f"seeds must be a whole number ≥ 1, got {seeds!r}")
    bad = [k for k in bare_trackers if k not in BARE_TRACKERS]
    if bad:
        raise ValueError(f"bare_trackers must be among {BARE_TRACKERS}, got {bad}")
    if runners is not None:
        runners = [RUNNER_ALIASES.get(r, r) for r in runners]
    extra_runners = [f"jointtrack-bare-{k}" for k in bare_trackers]
    console = console or make_console()
    paths = fetch_realdata(cache_dir, progress=console.print)
    seed_list = [seed + k for k in range(int(seeds))]
    built = build_scenes(list(scenes), paths, quick=quick, seed=seed_list[0])
    folder = Path(out) if out else None
    if folder:
        folder.mkdir(parents=True, exist_ok=True)
    report: dict = {
        "quick": quick,
        "wall_cap_s": wall_cap,
        "seed": seed,
        "seeds": seed_list,
        "stamp": stamp,
        "bare_trackers": list(bare_trackers),
        "scenes": {},
    }
    defaults = {r for scene in built for r in scene.default_runners}
    rss_results: dict = {}

    def scene_runs(scene: Scene):
        """Run every wanted runner on one built scene (one seed) into the report."""
        wanted = [r for r in scene.default_runners if runners is None or r in runners]
        if runners is not None:  # a runner no built scene has by default runs on every scene
            wanted += [r for r in runners if r not in wanted and r not in defaults]
        wanted += [r for r in extra_runners if r not in wanted]
        entry = report["scenes"].setdefault(
            scene.name,
            {"scene": scene.describe(), "seeds": [], "not_run": {}, "runs": {}},
        )
        if scene.seed is not None:
            entry["seeds"].append(scene.seed)
        key = "unseeded" if scene.seed is None else str(scene.seed)
        first = len(entry["seeds"]) <= 1
        not_run = entry["not_run"]
        not_run.update({r: "not registered" for r in wanted if r not in RUNNERS})
        if scene.labels is None and "stonesoup-demo" in wanted:
            not_run["stonesoup-demo"] = "gates on labels; this scene has none"
        todo = [r for r in wanted if r not in not_run]
        ref = entry["scene"]["reference_lat_lon_alt"]
        console.print(
            f"[bold]{scene.name}[/]: {scene.description}; {len(scene.times)} reports "
            f"in {scene.n_scans} scans"
            + (f"; local frame about {ref[0]:.5f}°N {ref[1]:.5f}°E" if ref else "")
        )
        truth = None
        for name in todo:
            with progress_bar(console, transient=True) as bar:
                task = bar.add_task(f"{scene.name}: {name}", total=scene.n_scans)

                def progress(done, total, _task=task, _bar=bar):
                    _bar.update(_task, completed=done)

                extra = (
                    {"stamp": stamp} if stamp is not None and name.startswith("stonesoup-") else {}
                )
                try:
                    result = RUNNERS[name](scene, wall_cap=wall_cap, progress=progress, **extra)
                except NotImplementedError as exc:
                    not_run[name] = f"not implemented: {exc}"
                    continue
            if result.error:
                console.print(f"  {name}: {result.error}", markup=False)
            if truth is None:
                try:
                    truth = scene.truth()
                except ImportError:
                    pass  # score_run says why
            score_run(scene, result, truth)
            run_dict = result.as_dict()
            run_dict["figures"] = run_figures(result, scene.scan_times)
            runs = entry["runs"].setdefault(name, {"per_seed": {}, "spread": {}})
            runs["per_seed"][key] = run_dict
            if first:
                rss_results.setdefault(scene.name, []).append(result)
            if folder:
                suffix = "" if scene.seed is None else f"_s{scene.seed}"
                _write_tracks(result, folder / f"tracks_{scene.name}_{name}{suffix}.csv")
                if first and truth is not None and len(result.track_ids):
                    png = plot_map(scene, result, truth, folder / f"map_{scene.name}_{name}.png")
                    run_dict["map_png"] = None if png is None else png.name
            console.print(
                f"  {name}{'' if scene.seed is None else f' (seed {scene.seed})'}: "
                + (result.score_error or "")
                + (
                    ""
                    if result.score is None
                    else "coverage {}, ids/target {}, CPU {:.1f} s".format(
                        _cell(spread([result.score["coverage"]]), ".3f"),
                        _cell(spread([result.score["tracks_per_identity"]]), ".2f"),
                        result.cpu,
                    )
                ),
                markup=False,
            )

    for scene in built:
        scene_runs(scene)
        if scene.seed is not None:  # the other degradation seeds of the same data
            for s in seed_list[1:]:
                for again in build_scenes([scene.name], paths, quick=quick, seed=s):
                    scene_runs(again)
    for name, entry in report["scenes"].items():
        for runs in entry["runs"].values():
            figs = [r["figures"] for r in runs["per_seed"].values()]
            runs["spread"] = {k: spread([f[k] for f in figs]) for k, _, _ in FIGURES}
        if entry["not_run"]:
            console.print(f"  {name} not run: {entry['not_run']}", markup=False)
    console.print(table(report))
    if folder:
        for name, results in rss_results.items():
            report["scenes"][name]["rss_png"] = plot_rss(results, folder / f"rss_{name}.png").name
        png = plot_coverage_classes(report, folder / "coverage_classes.png")
        report["coverage_png"] = None if png is None else png.name
        (folder / "realdata.md").write_text(markdown_table(report))
        (folder / "realdata.json").write_text(json.dumps(report, indent=1))
        console.print(f"wrote {folder / 'realdata.json'}")
    return report
