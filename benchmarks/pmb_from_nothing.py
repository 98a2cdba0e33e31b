"""PMB/PMBM from nothing on a built-in scene: GOSPA, id switches and where they happen (issue 33).

Usage: ``python benchmarks/pmb_from_nothing.py SCENE pmb|pmbm SEEDS ['{"pmbm": "settings"}'] [-v]``
e.g. ``python benchmarks/pmb_from_nothing.py bojilov pmb 0,1,2,3,4``. The tracker's
settings are a run's (:func:`jointtrack.experiments.config.make_pmbm_config` of the
scene's derived settings; the JSON, a ``[pmbm]`` table, on top), the scoring a run's
(GOSPA with the scene's c — 5σ when it has none — p = 2, α = 2; id switches and
coverage from :func:`jointtrack.metrics.track_statistics` with gate c), as
``jointtrack run --scenario SCENE --start-from nothing --tracker KIND`` reports them,
without the run's files. ``-v`` prints, per target, the scans at which its
associated id changed (old id → new id).
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np

from jointtrack.experiments.config import (
    make_pmbm_config,
    make_scenario,
    make_tracker_config,
    scenario_metric_settings,
    scenario_tracker_settings,
)
from jointtrack.experiments.run import jpda_kind_overrides
from jointtrack.metrics import gospa_series, track_statistics
from jointtrack.trackers.pmbm import PMBMTracker, PMBTracker


def run(scene: str, kind: str, seed: int, pmbm: dict) -> tuple:
    """``(GOSPA mean, id switches, false tracks, coverage, switches)`` of one run."""
    sc = make_scenario(scene, seed, {})
    base = make_tracker_config(scenario_tracker_settings(sc), jpda_kind_overrides(kind, {}))
    cfg, _ = make_pmbm_config(base, {}, pmbm, scenario=sc, region=sc.region, scans=sc.detections)
    trk = (PMBTracker if kind == "pmb" else PMBMTracker)(cfg, keep_history=False)
    t_, i_, x_ = [], [], []
    for t, z in zip(sc.times, sc.detections, strict=True):
        res = trk.step(float(t), np.asarray(z, float))
        t_ += [t] * len(res.ids)
        i_ += res.ids.tolist()
        x_ += list(res.x[:, : sc.dim])
    truth = sc.truth_table()
    est = (np.array(t_, float), np.array(i_, np.int64), np.array(x_, float).reshape(-1, sc.dim))
    sigma = float(np.sqrt(np.mean(np.diag(sc.R))))
    c = scenario_metric_settings(sc).get("c", 5 * sigma)
    stats = track_statistics(*truth, *est, gate=c)
    series = gospa_series(*truth, *est, c=c, p=2)
    switches = {}
    for tid in np.unique(stats.assoc_truth_ids):
        m = stats.assoc_truth_ids == tid
        order = np.argsort(stats.assoc_times[m])
        ts, ks = stats.assoc_times[m][order], stats.assoc_track_ids[m][order]
        changed = np.flatnonzero(ks[1:] != ks[:-1])
        switches[int(tid)] = [(float(ts[i + 1]), int(ks[i]), int(ks[i + 1])) for i in changed]
    return series.mean, stats.n_id_switches, stats.n_false_tracks, stats.coverage, switches


def main(argv) -> None:
    scene, kind, seeds = argv[0], argv[1], [int(s) for s in argv[2].split(",")]
    pmbm = json.loads(argv[3]) if len(argv) > 3 and not argv[3].startswith("-") else {}
    rows = []
    for seed in seeds:
        t0 = time.perf_counter()
        g, sw, false, cov, where = run(scene, kind, seed, pmbm)
        rows.append((g, sw, false, cov))
        print(f"seed {seed}: GOSPA {g:.2f}, {sw} id switches, {false} false tracks, "
              f"coverage {cov:.3f} ({time.perf_counter() - t0:.0f} s)", flush=True)  # fmt: skip
        if "-v" in argv:
            for tid, s in where.items():
                print(f"  target {tid}: (scan, id → id) {s}")
    a = np.array(rows)
    print(f"{scene} {kind} {pmbm}: GOSPA {a[:, 0].mean():.2f} ± {a[:, 0].std():.2f} (sd), "
          f"{a[:, 1].mean():.1f} switches/run, {a[:, 2].mean():.1f} false tracks/run, "
          f"coverage {a[:, 3].mean():.3f}")  # fmt: skip


if __name__ == "__main__":
    main(sys.argv[1:])
