"""PMB and PMBM against JIPDA on the Solent AIS file (issue 32, item 4).

The real-data scenes of :mod:`jointtrack.bench.realdata` — ``solent-labels`` (MMSI
given as labels) and ``solent`` (no labels) — stepped one scan per report time with
the asynchronous reporting model, each tracker with the settings ``jointtrack run``
gives it on an AIS file: JIPDA by
:func:`jointtrack.bench.jointtrack_realdata.run_jointtrack`; PMB and PMBM by
:func:`~jointtrack.experiments.config.make_pmbm_config` of the same settings (as
``jointtrack run --tracker pmb|pmbm`` on the file: positions only, reported
velocities seeding new Bernoullis, uniform births of 0.01 per report_interval over
the reports' bounding box). Scored by
:func:`jointtrack.metrics.selfreport.score_self_reports` (c = 500 m, 60 s windows);
CPU of the tracking loop, all runs in this process, interleaved by scene.

Run: ``PYTHONPATH=src python benchmarks/pmbm_reports.py [--quick]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def run_poisson(scene, kind: str):
    """PMB / PMBM over ``scene`` (the JIPDA runner's stepping) → RunResult."""
    from jointtrack.bench.realdata import RunResult
    from jointtrack.experiments.config import make_pmbm_config
    from jointtrack.experiments.realdata import realdata_settings
    from jointtrack.trackers.config import TrackerConfig
    from jointtrack.trackers.pmbm import PMBMTracker, PMBTracker

    # positions only (as jointtrack run --tracker pmb|pmbm on a report file)
    base = TrackerConfig(**realdata_settings("ais", labelled=True))
    region = np.stack([scene.positions.min(axis=0), scene.positions.max(axis=0)], axis=1)
    cfg, notes = make_pmbm_config(base, {}, None, region=region)
    order = np.argsort(scene.times, kind="stable")
    step_times, step_index = np.unique(scene.times[order], return_inverse=True)
    positions = scene.positions[order]
    labels = scene.labels[order] if scene.labels is not None else None
    velocities = scene.velocities[order] if scene.velocities is not None else None
    bounds = np.searchsorted(step_index, np.arange(len(step_times) + 1))
    trk = (PMBMTracker if kind == "pmbm" else PMBTracker)(cfg, keep_history=False)
    rows_t, rows_id, rows_xy = [], [], []
    w0, c0 = time.perf_counter(), time.process_time()
    for k, t in enumerate(step_times.tolist()):
        a, b = bounds[k], bounds[k + 1]
        kw = {} if labels is None else {"labels": labels[a:b]}
        if velocities is not None:
            kw["velocities"] = velocities[a:b]
        res = trk.step(t, positions[a:b], **kw)
        rows_t.append(np.full(len(res.ids), t))
        rows_id.append(res.ids)
        rows_xy.append(res.x[:, :2])
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    return RunResult(
        runner=f"jointtrack-{kind}",
        scene=scene.name,
        wall=wall,
        cpu=cpu,
        peak_rss=0,
        scans_done=len(scene.scan_times),
        scans_total=len(scene.scan_times),
        rss_times=np.zeros(0),
        rss=np.zeros(0),
        track_times=np.concatenate(rows_t),
        track_ids=np.concatenate(rows_id),
        track_positions=np.concatenate(rows_xy),
        stopped_by=None,
        details={"notes": notes, "tracker_steps": len(step_times)},
    )


def main() -> None:
    from jointtrack.bench.jointtrack_realdata import run_jointtrack
    from jointtrack.bench.realdata import score_run, solent_scenes
    from jointtrack.bench.realdata_data import fetch_realdata

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the first 30 scans only")
    ap.add_argument("--trackers", default="jipda,pmb,pmbm")
    args = ap.parse_args()
    paths = fetch_realdata()
    scenes = solent_scenes(paths["solent_ais"], quick=args.quick)
    print(f"{'scene':14} {'tracker':9} {'coverage':>8} {'purity':>7} {'ids/vessel':>10} "
          f"{'switches':>8} {'false/h':>8} {'GOSPA':>6} {'CPU s':>7}")  # fmt: skip
    for scene in scenes:
        truth = scene.truth()
        for kind in args.trackers.split(","):
            if kind == "jipda":
                res = run_jointtrack(scene, wall_cap=3600.0)
            else:
                res = run_poisson(scene, kind)
            s = score_run(scene, res, truth).score
            print(
                f"{scene.name:14} {kind:9} {s['coverage']:8.3f} {s['purity']:7.3f} "
                f"{s['tracks_per_identity']:10.2f} {s['n_id_switches']:8d} "
                f"{s['false_tracks_per_hour']:8.1f} {s['gospa_mean']:6.0f} {res.cpu:7.1f}",
                flush=True,
            )


if __name__ == "__main__":
    main()
