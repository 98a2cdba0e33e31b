"""jointtrack's runners of the real-data benchmark (:mod:`jointtrack.bench.realdata`).

``jointtrack-handset`` (:func:`run_jointtrack`): settings a person chose for the data.
The scene's reports are stepped as the tracker's own run would: on the AIS
scenes (``solent``, ``solent-labels``) one scan per report time with the
asynchronous-reporting model and the settings of ``jointtrack run`` on a report
file (:data:`jointtrack.experiments.realdata.REALDATA_TRACKER`, ``"ais"``), the
MMSI as labels where the scene gives them; on the ADS-B scene, whose reports a
synthetic *scanning* sensor made (P_D, clutter and noise per 10 s scan), a
scanning JIPDA with that sensor's numbers. Measured in this process (wall, CPU,
RSS samples every 0.5 s); the track table holds every confirmed track's
position after each scan.

``jointtrack-bare`` (:func:`run_bare`): the bare command a user types on the same
data. The scene's rows are written as a plain ``time, lat, lon`` CSV
(:func:`write_plain_detections`: ISO-8601 times, the rows' positions back in lat/lon;
identities stripped, or a ``label`` column where the scene gives labels) and run
through :func:`jointtrack.experiments.run.run_detections` on
:func:`jointtrack.io.read_detections` of that file with **no config** (only
``tracker=`` when one is named) in a temporary folder — whatever the run path does by
default (report-like detection, fitted or default model) is what is measured. The
tracks are read back from its ``tracks.csv`` (its ``lat, lon`` columns projected to the
scene's frame, its times moved to the scene's clock). A run the path refuses (e.g. a
tracker kind it does not accept on these data) is the runner's result: no tracks, the
refusal as its ``error``.
"""

from __future__ import annotations

import time

import numpy as np

__all__ = ["ADSB_TRACKER", "BARE_TRACKERS", "run_bare", "run_jointtrack", "write_plain_detections"]

#: the tracker kinds ``jointtrack-bare-<kind>`` passes as ``tracker=`` (``jointtrack-bare``
#: passes none: the run path's default)
BARE_TRACKERS = ("jipda", "pmb", "pmbm")

#: JIPDA settings of the ADS-B scene's scanning sensor (its P_D, clutter and noise
#: come from the scene); aircraft manoeuvre: CV with q = 1 m²/s³.
ADSB_TRACKER = {
    "process_noise": 1.0,
    "max_speed": 350.0,
    "p_survive": 0.99,
    "max_coast": 60.0,
    "r_report": 0.3,
}


def run_jointtrack(scene, *, tracker: str = "jipda", wall_cap: float, workdir=None, progress=None):
    """jointtrack on ``scene``, hand-set settings → :class:`~jointtrack.bench.realdata.RunResult`.

    ``tracker``: ``"jipda"``, or ``"pmb"`` / ``"pmbm"`` with the same shared settings
    (positions only) as ``jointtrack run --tracker pmb|pmbm`` gives them.
    """
    from jointtrack.bench.realdata import RssSampler, RunResult
    from jointtrack.experiments.realdata import realdata_settings
    from jointtrack.trackers.config import TrackerConfig
    from jointtrack.trackers.jpda import JPDATracker

    if tracker not in BARE_TRACKERS:
        raise ValueError(f"tracker must be one of {', '.join(BARE_TRACKERS)}, got {tracker!r}")
    scanning = scene.p_d < 1.0 or scene.clutter_density > 0
    if scanning:
        cfg = TrackerConfig(
            **ADSB_TRACKER,
            p_d=scene.p_d,
            clutter_density=scene.clutter_density,
            measurement_noise=scene.measurement_noise,
        )
        order = np.argsort(scene.scan_index, kind="stable")
        step_index, step_times = scene.scan_index[order], scene.scan_times
    else:
        # PMB/PMBM do not measure reported velocities: the positions-only settings
        labelled = scene.labels is not None or tracker != "jipda"
        cfg = TrackerConfig(**realdata_settings("ais", labelled=labelled))
        order = np.argsort(scene.times, kind="stable")
        step_times, step_index = np.unique(scene.times[order], return_inverse=True)
    positions = scene.positions[order]
    labels = scene.labels[order] if scene.labels is not None else None
    velocities = scene.velocities[order] if scene.velocities is not None else None
    bounds = np.searchsorted(step_index, np.arange(len(step_times) + 1))
    notes = []
    if tracker == "jipda":
        trk = JPDATracker(cfg, keep_history=False)
    else:
        # as `jointtrack run --tracker pmb|pmbm` on the scene's file: the same shared
        # settings, births uniform over the rows' bounding box (make_pmbm_config)
        from jointtrack.experiments.config import make_pmbm_config
        from jointtrack.trackers.pmbm import PMBMTracker, PMBTracker

        region = np.stack([scene.positions.min(axis=0), scene.positions.max(axis=0)], axis=1)
        cfg, notes = make_pmbm_config(cfg, {}, None, region=region)
        trk = (PMBMTracker if tracker == "pmbm" else PMBTracker)(cfg, keep_history=False)
    rows_t, rows_id, rows_xy = [], [], []
    w0, c0 = time.perf_counter(), time.process_time()
    stopped = None
    done = 0
    with RssSampler() as sampler:
        for k, t in enumerate(step_times.tolist()):
            if time.perf_counter() - w0 > wall_cap:
                stopped = "wall cap"
                break
            a, b = bounds[k], bounds[k + 1]
            kw = {} if labels is None else {"labels": labels[a:b]}
            if velocities is not None:
                kw["velocities"] = velocities[a:b]
            res = trk.step(t, positions[a:b], **kw)
            rows_t.append(np.full(len(res.ids), t))
            rows_id.append(res.ids)
            rows_xy.append(res.x[:, :2])
            done += 1
            if progress is not None and k % 200 == 0:  # progress(scans_done, scans_total)
                progress(int(np.count_nonzero(scene.scan_times <= t)), len(scene.scan_times))
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    # scans of the scene (not of the tracker, which may step each report time)
    last = step_times[done - 1] if done else -np.inf
    n_scans = len(scene.scan_times)
    scans_done = (
        n_scans if done == len(step_times) else int(np.count_nonzero(scene.scan_times <= last))
    )
    return RunResult(
        runner="jointtrack-handset" if tracker == "jipda" else f"jointtrack-handset-{tracker}",
        scene=scene.name,
        wall=wall,
        cpu=cpu,
        peak_rss=_own_peak(sampler),
        scans_done=scans_done,
        scans_total=n_scans,
        rss_times=np.asarray(sampler.times),
        rss=np.asarray(sampler.rss),
        track_times=np.concatenate(rows_t) if rows_t else np.zeros(0),
        track_ids=np.concatenate(rows_id) if rows_id else np.zeros(0, np.int64),
        track_positions=np.concatenate(rows_xy) if rows_xy else np.zeros((0, 2)),
        stopped_by=stopped,
        details={
            "scans": "one per scan" if scanning else "one per report time (async reporting)",
            "tracker_steps": done,
            "config": {k: v for k, v in cfg.to_dict().items() if k in _SHOWN},
            "notes": list(notes),
            "measured": "in process: wall, CPU of the loop; peak = max of RSS samples every 0.5 s",
        },
    )


_SHOWN = (
    "reporting",
    "report_interval",
    "p_d",
    "clutter_density",
    "measurement_noise",
    "process_noise",
    "p_survive",
    "p_survive_per",
    "max_coast",
)


def write_plain_detections(scene, path) -> int:
    """The scene's rows as a plain detections CSV: ``time, lat, lon`` (``label`` too when
    the scene gives labels). Times are ISO-8601 (``scene.time_origin`` + the rows' times,
    to the nanosecond), positions the rows' local east/north converted back to WGS-84
    by the scene's frame (17 significant digits). Rows in time order. Returns the number
    of rows written."""
    from jointtrack.io.times import format_timestamp, parse_origin

    _, ns0, aware = parse_origin(scene.time_origin)
    order = np.argsort(scene.times, kind="stable")
    lat, lon = scene.frame.to_geodetic(scene.positions[order])[:2]
    ns = ns0 + np.rint(scene.times[order] * 1e9).astype(np.int64)
    labels = None if scene.labels is None else np.asarray(scene.labels)[order]
    with open(path, "w", newline="") as fh:
        fh.write("time,lat,lon" + (",label" if labels is not None else "") + "\n")
        for k in range(order.size):
            row = f"{format_timestamp(int(ns[k]), aware)},{float(lat[k])!r},{float(lon[k])!r}"
            if labels is not None:
                row += f",{labels[k]}"
            fh.write(row + "\n")
    return int(order.size)


def run_bare(scene, *, tracker: str | None = None, wall_cap: float, workdir=None, progress=None):
    """The bare ``jointtrack run --detections FILE`` on ``scene`` (module docstring) →
    :class:`~jointtrack.bench.realdata.RunResult`. ``tracker``: None (the run path's
    default) or one of :data:`BARE_TRACKERS`. Measured in process over
    ``run_detections`` (reading the file and writing it are not counted; plots are
    off: they are output, not tracking). ``wall_cap`` is not enforced (the run path has
    no wall cap); ``workdir`` keeps the run's folder there instead of a temporary one."""
    import tempfile
    from pathlib import Path

    from jointtrack.bench.realdata import RssSampler, RunResult
    from jointtrack.experiments.run import run_detections
    from jointtrack.io import read_detections
    from jointtrack.io.times import parse_origin

    if tracker is not None and tracker not in BARE_TRACKERS:
        raise ValueError(f"tracker must be None or one of {BARE_TRACKERS}, got {tracker!r}")
    name = "jointtrack-bare" + ("" if tracker is None else f"-{tracker}")
    n_scans = len(scene.scan_times)
    with tempfile.TemporaryDirectory(prefix="jt-bare-") as tmp:
        folder = Path(workdir) if workdir is not None else Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        plain = folder / "plain.csv"
        n_rows = write_plain_detections(scene, plain)
        detections = read_detections(plain)
        out = folder / "run"
        kw = {} if tracker is None else {"tracker": tracker}
        error = None
        w0, c0 = time.perf_counter(), time.process_time()
        with RssSampler() as sampler:
            try:
                metrics = run_detections(detections, out_dir=out, plots=False, **kw)
            except (ValueError, TypeError, NotImplementedError) as exc:
                # the run path refused these data with this tracker: that is the result
                error = f"{type(exc).__name__}: {exc}"
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        details = {
            "command": "run_detections(read_detections(plain.csv)"
            + ("" if tracker is None else f", tracker={tracker!r}")
            + ") with no config, plots off",
            "plain_rows": n_rows,
            "labels": scene.labels is not None,
            "measured": "in process: wall, CPU of run_detections; peak = max of RSS "
            "samples every 0.5 s",
        }
        if error is None:
            from jointtrack.io.tracks import read_tracks

            cols = read_tracks(out / "tracks.csv")
            _, ns_scene, _ = parse_origin(scene.time_origin)
            _, ns_run, _ = parse_origin(metrics.get("time_origin") or detections.time_origin)
            shift = (ns_run - ns_scene) / 1e9
            track_times = cols["time"] + shift
            if len(cols["time"]):
                xy = np.asarray(scene.frame.to_local(cols["lat"], cols["lon"]), dtype=np.float64)
            else:
                xy = np.zeros((0, 2))
            used = metrics.get("tracker", {})
            details["config"] = {k: used[k] for k in _SHOWN if k in used}
            details["notes"] = list(metrics.get("notes", []))
            scans_done = n_scans
        else:
            track_times, xy = np.zeros(0), np.zeros((0, 2))
            cols = {"track_id": np.zeros(0, np.int64)}
            scans_done = 0
    return RunResult(
        runner=name,
        scene=scene.name,
        wall=wall,
        cpu=cpu,
        peak_rss=_own_peak(sampler),
        scans_done=scans_done,
        scans_total=n_scans,
        rss_times=np.asarray(sampler.times),
        rss=np.asarray(sampler.rss),
        track_times=track_times,
        track_ids=np.asarray(cols["track_id"], dtype=np.int64),
        track_positions=xy[:, :2],
        error=error,
        details=details,
    )


def _own_peak(sampler) -> int:
    """The run's own peak RSS: the largest of its 0.5 s samples. Not the process's
    ``ru_maxrss`` (:attr:`RssSampler.peak`), which holds every earlier run of this process
    (the bench runs several in process) and would give each the largest so far."""
    return int(max(sampler.rss)) if sampler.rss else 0
