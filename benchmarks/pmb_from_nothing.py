"""PMB/PMBM from nothing on a built-in scene: GOSPA, id switches and where they happen (issue 33).

Usage: ``python benchmarks/pmb_from_nothing.py SCENE pmb|pmbm SEEDS ['{"pmbm": "settings"}']
[-v] [--misses]``
e.g. ``python benchmarks/pmb_from_nothing.py bojilov pmb 0,1,2,3,4``. The tracker's
settings are a run's (:func:`jointtrack.experiments.config.make_pmbm_config` of the
scene's derived settings; the JSON, a ``[pmbm]`` table, on top), the scoring a run's
(GOSPA with the scene's c — 5σ when it has none — p = 2, α = 2; id switches and
coverage from :func:`jointtrack.metrics.track_statistics` with gate c), as
``jointtrack run --scenario SCENE --start-from nothing --tracker KIND`` reports them,
without the run's files. ``-v`` prints, per target, the scans at which its
associated id changed (old id → new id). ``--misses`` (PMBM) prints where each
target-scan without a report within c/2.5 (20 m on the Bojilov scenes) stood:
``best_low_r`` — a Bernoulli within that distance in the most probable global
hypothesis, below ``r_estimate``; ``other_hypothesis`` — one only in other
hypotheses; ``intensity`` — no Bernoulli, a Poisson component there; ``none``.
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


def _where_missed(trk, truth_x, est_x, near) -> str:
    """Where a target at ``truth_x`` stood in a PMBM tracker after its step
    (``--misses``): ``"reported"`` if an estimate in ``est_x`` is within ``near``."""

    def within(points):
        return len(points) and np.linalg.norm(points - truth_x, axis=1).min() < near

    if within(est_x):
        return "reported"
    best = trk.hyp[0][trk.hyp[0] >= 0]
    if within(trk.sth_x[best, : len(truth_x)]):
        return "best_low_r"
    if within(trk.sth_x[:, : len(truth_x)]):
        return "other_hypothesis"
    if within(trk.poisson_m[:, : len(truth_x)]):
        return "intensity"
    return "none"


def run(scene: str, kind: str, seed: int, pmbm: dict, misses: dict | None = None) -> tuple:
    """``(GOSPA mean, id switches, false tracks, coverage, switches)`` of one run;
    ``misses`` (PMBM), a dict, counts the target-scans by :func:`_where_missed`."""
    sc = make_scenario(scene, seed, {})
    base = make_tracker_config(scenario_tracker_settings(sc), jpda_kind_overrides(kind, {}))
    cfg, _ = make_pmbm_config(base, {}, pmbm, scenario=sc, region=sc.region, scans=sc.detections)
    trk = (PMBTracker if kind == "pmb" else PMBMTracker)(cfg, keep_history=False)
    t_, i_, x_ = [], [], []
    truth = sc.truth_table()
    sigma = float(np.sqrt(np.mean(np.diag(sc.R))))
    c = scenario_metric_settings(sc).get("c", 5 * sigma)
    for t, z in zip(sc.times, sc.detections, strict=True):
        res = trk.step(float(t), np.asarray(z, float))
        if misses is not None and kind == "pmbm":
            for pos in truth[2][truth[0] == t]:
                where = _where_missed(trk, pos, res.x[:, : sc.dim], c / 2.5)
                misses[where] = misses.get(where, 0) + 1
        t_ += [t] * len(res.ids)
        i_ += res.ids.tolist()
        x_ += list(res.x[:, : sc.dim])
    est = (np.array(t_, float), np.array(i_, np.int64), np.array(x_, float).reshape(-1, sc.dim))
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
    rows, misses = [], ({} if "--misses" in argv else None)
    for seed in seeds:
        t0 = time.perf_counter()
        g, sw, false, cov, where = run(scene, kind, seed, pmbm, misses)
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
    if misses:
        print("target-scans by where the target stood (--misses):", dict(sorted(misses.items())))


if __name__ == "__main__":
    main(sys.argv[1:])
