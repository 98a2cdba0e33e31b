"""jointtrack's runner of the real-data benchmark (:mod:`jointtrack.bench.realdata`).

The scene's reports are stepped as the tracker's own run would: on the AIS
scenes (``solent``, ``solent-labels``) one scan per report time with the
asynchronous-reporting model and the settings of ``jointtrack run`` on a report
file (:data:`jointtrack.experiments.realdata.REALDATA_TRACKER`, ``"ais"``), the
MMSI as labels where the scene gives them; on the ADS-B scene, whose reports a
synthetic *scanning* sensor made (P_D, clutter and noise per 10 s scan), a
scanning JIPDA with that sensor's numbers. Measured in this process (wall, CPU,
RSS samples every 0.5 s); the track table holds every confirmed track's
position after each scan.
"""

from __future__ import annotations

import time

import numpy as np

__all__ = ["ADSB_TRACKER", "run_jointtrack"]

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
    """jointtrack on ``scene`` → :class:`~jointtrack.bench.realdata.RunResult`."""
    from jointtrack.bench.realdata import RssSampler, RunResult
    from jointtrack.experiments.realdata import realdata_settings
    from jointtrack.trackers.config import TrackerConfig
    from jointtrack.trackers.jpda import JPDATracker

    if tracker != "jipda":
        raise ValueError(f"jointtrack-{tracker} has no real-data runner (only jipda)")
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
        cfg = TrackerConfig(**realdata_settings("ais", labelled=scene.labels is not None))
        order = np.argsort(scene.times, kind="stable")
        step_times, step_index = np.unique(scene.times[order], return_inverse=True)
    positions = scene.positions[order]
    labels = scene.labels[order] if scene.labels is not None else None
    velocities = scene.velocities[order] if scene.velocities is not None else None
    bounds = np.searchsorted(step_index, np.arange(len(step_times) + 1))
    trk = JPDATracker(cfg, keep_history=False)
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
        runner=f"jointtrack-{tracker}",
        scene=scene.name,
        wall=wall,
        cpu=cpu,
        peak_rss=sampler.peak,
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
            "measured": "in process: wall, CPU of the loop; RSS samples every 0.5 s",
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
