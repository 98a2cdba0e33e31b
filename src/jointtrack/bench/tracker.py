"""The JPDA tracker end to end: scan rate on a many-target scene, and the cost of
Bojilov's 5-target clusters beside his Table 3.

Run as ``jointtrack bench tracker [--quick] [--out FILE]`` or
``python benchmarks/tracker.py``.

* **many-target scene** (``scenarios.many_targets``): 100 targets with births and
  deaths, 50 clutter points per scan, 100 scans (quick: 40), no tracks at the
  start (two-point initiation, JIPDA existence). Timed: ``JPDATracker.step`` over
  all scans (gating, clustering, exact association, PDA update, track logic and
  initiation — everything but generating the scenario), median of three runs
  after one untimed warm-up run that compiles the numba kernels. Target:
  ≥ 20 scans/s.
* **Bojilov clusters** (``scenarios.bojilov``): five targets on parallel lanes
  drifting into one cluster, clutter β = 1 and 2, ten seeds each (quick: two),
  tracker started from the truth as in the paper. Every association call on a
  cluster of confirmed tracks is timed by the tracker (``"exact"`` method);
  mean and max seconds per cluster size are printed beside Bojilov's Table 3
  (his optimised enumeration). Target: 5-target clusters ≤ 1 ms on average.

Stone Soup is not run here: wiring its full tracker (initiator, deleter,
updater) on these scenes would time Stone Soup's object model more than its
association; its association step is compared in ``jointtrack bench association``.
"""

from __future__ import annotations

import json
import logging
import statistics
import time

import numpy as np
from rich.table import Table

from jointtrack._console import make_console
from jointtrack.metrics import gospa_series, track_statistics
from jointtrack.scenarios import bojilov, many_targets
from jointtrack.trackers import JPDATracker, TrackerConfig

# Bojilov, Alexiev & Konstantinova, Table 3: seconds per cluster (optimised enumeration)
PAPER_TABLE3_OPT = {3: (0.0213, 0.0377), 4: (0.1, 0.19), 5: (0.438, 5.71)}


def scenario_config(sc, **overrides) -> TrackerConfig:
    """Tracker settings matching a simulated scenario's parameters."""
    speeds = [np.hypot(*s[:, 2:4].T).max() for s in sc.truth_states if len(s)]
    settings = dict(
        process_noise=max(sc.process_noise, 0.05),
        measurement_noise=float(sc.R[0, 0]),
        p_d=sc.p_d,
        clutter_density=sc.clutter_density,
        max_speed=1.5 * max(speeds) if speeds else 50.0,
    )
    settings.update(overrides)
    return TrackerConfig(**settings)


def _run_scene(sc, cfg, start_from_truth=False):
    trk = JPDATracker(cfg)
    if start_from_truth:
        P0 = np.diag([sc.R[0, 0], sc.R[1, 1], 4.0, 4.0])
        trk.start_tracks(sc.truth_states[0], P0)
    rows, clusters = [], []
    t0 = time.perf_counter()
    for t, z in zip(sc.times, sc.detections, strict=True):
        r = trk.step(t, z)
        rows += [(t, i, x[0], x[1]) for i, x in zip(r.ids, r.x, strict=True)]
        clusters += [
            (n, sec)
            for (n, _), sec, conf in zip(
                r.cluster_sizes, r.cluster_seconds, r.cluster_confirmed, strict=True
            )
            if conf
        ]
    return time.perf_counter() - t0, np.array(rows).reshape(-1, 4), clusters


def _many(console, quick, results):
    n_scans = 40 if quick else 100
    sc = many_targets(100, 50.0, seed=0, n_scans=n_scans)
    cfg = scenario_config(sc)
    logging.disable(logging.WARNING)
    try:
        _run_scene(sc, cfg)  # warm-up: numba compilation, caches
        runs = [_run_scene(sc, cfg) for _ in range(3)]  # identical runs: take the median time
        seconds = statistics.median(r[0] for r in runs)
        _, rows, clusters = runs[0]
    finally:
        logging.disable(logging.NOTSET)
    truth = sc.truth_table()
    stats = track_statistics(*truth, rows[:, 0], rows[:, 1].astype(int), rows[:, 2:4], gate=50)
    g = gospa_series(*truth, rows[:, 0], rows[:, 1].astype(int), rows[:, 2:4], c=50)
    rate = n_scans / seconds
    res = dict(
        scans=n_scans,
        seconds=seconds,
        scans_per_second=rate,
        mean_detections=float(np.mean([len(d) for d in sc.detections])),
        largest_cluster=max((n for n, _ in clusters), default=1),
        gospa_mean=g.mean,
        true_tracks=stats.n_true_tracks,
        false_tracks=stats.n_false_tracks,
        truths=stats.n_truths,
        target_met=rate >= 20.0,
    )
    results["many_targets"] = res
    t = Table(title="Many-target scene: 100 targets, 50 clutter/scan (end to end)")
    for col in (
        "scans",
        "detections/scan",
        "seconds",
        "scans/s",
        "target",
        "GOSPA mean (c=50)",
        "true / false tracks (truths)",
    ):
        t.add_column(col)
    t.add_row(
        str(n_scans),
        f"{res['mean_detections']:.0f}",
        f"{seconds:.3f}",
        f"{rate:.0f}",
        ("PASS" if res["target_met"] else "FAIL") + " (≥ 20)",
        f"{g.mean:.1f}",
        f"{stats.n_true_tracks} / {stats.n_false_tracks} ({stats.n_truths})",
    )
    console.print(t)


def _bojilov(console, quick, results):
    seeds = range(2 if quick else 10)
    per_size = {1.0: {}, 2.0: {}}
    logging.disable(logging.WARNING)
    try:
        for beta in per_size:
            for seed in seeds:
                sc = bojilov(beta, seed=seed)
                _, _, clusters = _run_scene(sc, scenario_config(sc), start_from_truth=True)
                for n, sec in clusters:
                    per_size[beta].setdefault(n, []).append(sec)
    finally:
        logging.disable(logging.NOTSET)
    t = Table(title="Bojilov clusters of confirmed tracks: exact association time per cluster")
    for col in (
        "targets",
        "β=1 clusters",
        "β=1 mean",
        "β=1 max",
        "paper opt. β=1",
        "β=2 clusters",
        "β=2 mean",
        "β=2 max",
        "paper opt. β=2",
    ):
        t.add_column(col)
    rows = []
    for n in range(2, 6):
        a, b = per_size[1.0].get(n, []), per_size[2.0].get(n, [])
        paper = PAPER_TABLE3_OPT.get(n, (None, None))
        row = dict(
            targets=n,
            beta1_count=len(a),
            beta1_mean=statistics.fmean(a) if a else None,
            beta1_max=max(a) if a else None,
            beta2_count=len(b),
            beta2_mean=statistics.fmean(b) if b else None,
            beta2_max=max(b) if b else None,
            paper_beta1=paper[0],
            paper_beta2=paper[1],
        )
        rows.append(row)

        def f(x):
            return "—" if x is None else f"{x * 1e3:.3f} ms"

        t.add_row(
            str(n),
            str(len(a)),
            f(row["beta1_mean"]),
            f(row["beta1_max"]),
            "—" if paper[0] is None else f"{paper[0]} s",
            str(len(b)),
            f(row["beta2_mean"]),
            f(row["beta2_max"]),
            "—" if paper[1] is None else f"{paper[1]} s",
        )
    console.print(t)
    five = per_size[1.0].get(5, []) + per_size[2.0].get(5, [])
    mean5 = statistics.fmean(five) if five else None
    ok = mean5 is not None and mean5 <= 1e-3
    results["bojilov"] = dict(rows=rows, five_target_mean=mean5, target_met=ok)
    console.print(
        f"5-target clusters: {len(five)} met, mean exact association "
        + ("n/a" if mean5 is None else f"{mean5 * 1e3:.3f} ms")
        + f" — {'PASS' if ok else 'FAIL'} (≤ 1 ms; Bojilov's optimised enumeration: 0.438 s)"
    )


def run(quick: bool = False, out: str | None = None) -> dict:
    console = make_console()
    results: dict = {"quick": quick}
    _many(console, quick, results)
    _bojilov(console, quick, results)
    if out:
        with open(out, "w") as fh:
            json.dump(results, fh, indent=2, default=float)
    return results
