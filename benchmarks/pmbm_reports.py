"""PMB and PMBM against JIPDA on the Solent AIS file (issue 32, item 4).

The real-data scenes of :mod:`jointtrack.bench.realdata` — ``solent-labels`` (MMSI
given as labels) and ``solent`` (no labels) — stepped one scan per report time with
the asynchronous reporting model, each tracker with the settings ``jointtrack run``
gives it on an AIS file: JIPDA by
:func:`jointtrack.bench.jointtrack_realdata.run_jointtrack`; PMB and PMBM by the same runner:
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
            res = run_jointtrack(scene, tracker=kind, wall_cap=3600.0)
            s = score_run(scene, res, truth).score
            print(
                f"{scene.name:14} {kind:9} {s['coverage']:8.3f} {s['purity']:7.3f} "
                f"{s['tracks_per_identity']:10.2f} {s['n_id_switches']:8d} "
                f"{s['false_tracks_per_hour']:8.1f} {s['gospa_mean']:6.0f} {res.cpu:7.1f}",
                flush=True,
            )


if __name__ == "__main__":
    main()
