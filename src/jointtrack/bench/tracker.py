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
* **scaling at constant density**: ``many_targets(n, 0.5·n, seed=0, region=side²)``
  with side = 10 km·√(n/100) (the target and clutter density of the 100-target
  scene), n = 100, 300, 1000, 3000, 10000, tracker set up as in the many-target
  row. The first ``SKIP_SCANS`` scans (two-point initiation of every target) run
  untimed; each later ``step`` is timed. Printed: steady-state scans/s (median
  over repeated runs), median and mean ms per scan, µs per target per scan and
  its ratio to n = 100, and the least-squares slope of log(ms/scan) against
  log n. Targets: ≥ 10 scans/s at n = 3000 (1500 clutter/scan); slope ≤ 1.2
  (cost per scan roughly linear in n).
* **scaling of PMB and PMBM** (issue 34): the same scenes, n = 100 to 3,000,
  ``PMBTracker`` and ``PMBMTracker`` built as ``jointtrack run --tracker pmb|pmbm``
  builds them on a scenario (:func:`~jointtrack.experiments.config.make_pmbm_config`;
  from nothing), fewer timed scans (PMBM's step is the slowest). Printed beside
  JIPDA's: scans/s, ms per scan, and per tracker the log-log slope of ms/scan
  against n past 300 targets. Target: ≤ 1.1 (cost per step linear in n).
* **memory against scans**: each of JIPDA, PMB and PMBM on the 100-target scene
  for ``MEMORY_SCANS`` scans (quick: fewer), without a kept history (as
  ``jointtrack run`` runs them: the tracks go to the writer); the memory allocated
  and still held since the tracker was built (``tracemalloc``, after a garbage
  collection) every ``MEMORY_EVERY`` scans and its growth over the second half of
  the run. Target: flat (growth over the second half ≤ 2 %).

With ``--out FILE`` the log-log plot of the scaling (scans/s and ms per scan
against n, one line per tracker) and the memory against scans are written next to
it (``<stem>_scaling.png``). ``--part`` runs only the named parts (many, bojilov,
scaling, memory, large).
* **large single scans**: ``TrackerConfig(clutter_density=1e-6)`` fed
  ``LARGE_SCANS`` consecutive scans of M = 5,000, 10,000 (full run only) and
  20,000 uniform detections over 1e5 × 1e5 m (so two-point initiation pairs
  some of them and the third scan gates tentative tracks), each M in a fresh
  subprocess under ``RLIMIT_AS`` = 2 GiB: completes or not, seconds per scan
  (after a small untimed warm-up scene that loads the numba kernels) and peak
  RSS (``getrusage(RUSAGE_SELF).ru_maxrss``), beside the numbers of the
  issue before the linear-scaling rewrite.

Stone Soup is not run here: wiring its full tracker (initiator, deleter,
updater) on these scenes would time Stone Soup's object model more than its
association; its association step is compared in ``jointtrack bench association``.
"""

from __future__ import annotations

import json
import logging
import math
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from rich.table import Table

from jointtrack._console import make_console
from jointtrack.experiments.config import make_pmbm_config
from jointtrack.io import to_jsonable
from jointtrack.metrics import gospa_series, track_statistics
from jointtrack.scenarios import bojilov, many_targets
from jointtrack.trackers import JPDATracker, TrackerConfig
from jointtrack.trackers.pmbm import PMBMTracker, PMBTracker

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


# ---------------------------------------------------------------- scaling curve
SKIP_SCANS = 5  # initiation transient: untimed
# n targets -> (timed scans per run, runs); full aims at ≥ 2 s of timed steps per point
SCALING_FULL = {100: (150, 3), 300: (100, 3), 1000: (60, 3), 3000: (30, 3), 10000: (20, 1)}
SCALING_QUICK = {100: (30, 1), 300: (20, 1), 1000: (10, 1), 3000: (8, 1), 10000: (5, 1)}
#: PMB and PMBM, n = 100 to 3,000 (the issue's range): fewer timed scans per point
SCALING_POISSON_FULL = {
    "pmb": {100: (60, 2), 300: (40, 2), 1000: (20, 2), 3000: (10, 1)},
    "pmbm": {100: (20, 1), 300: (15, 1), 1000: (10, 1), 3000: (6, 1)},
}
SCALING_POISSON_QUICK = {
    "pmb": {100: (10, 1), 300: (8, 1), 1000: (5, 1), 3000: (3, 1)},
    "pmbm": {100: (5, 1), 300: (4, 1), 1000: (3, 1), 3000: (2, 1)},
}
#: the slope target of PMB/PMBM holds past this many targets (issue 34)
POISSON_SLOPE_FROM = 300
POISSON_SLOPE_MAX = 1.1
KINDS = ("jipda", "pmb", "pmbm")


def scaling_scene(n: int, n_scans: int, seed: int = 0):
    """``many_targets`` with n targets, n/2 clutter/scan, at the 100-target scene's density."""
    side = 10_000.0 * math.sqrt(n / 100.0)
    return many_targets(n, 0.5 * n, seed=seed, n_scans=n_scans, region=((0, side), (0, side)))


def scaling_tracker(kind: str, sc):
    """JIPDA (:func:`scenario_config`), or PMB / PMBM as ``jointtrack run`` builds them on
    ``sc`` (:func:`~jointtrack.experiments.config.make_pmbm_config` of those settings);
    no kept history (the tracks of a long run go to its writer)."""
    cfg = scenario_config(sc)
    if kind == "jipda":
        return JPDATracker(cfg, keep_history=False)
    if kind not in ("pmb", "pmbm"):
        raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")
    pcfg, _ = make_pmbm_config(cfg, {}, None, scenario=sc, region=sc.region, scans=sc.detections)
    return (PMBMTracker if kind == "pmbm" else PMBTracker)(pcfg, keep_history=False)


def _timed_steps(sc, cfg, kind: str = "jipda"):
    """Per-scan wall and CPU seconds of the tracker's ``step`` and the final result."""
    trk = JPDATracker(cfg) if kind == "jipda" else scaling_tracker(kind, sc)
    times, cpu = [], []
    r = None
    for t, z in zip(sc.times, sc.detections, strict=True):
        t0, c0 = time.perf_counter(), time.process_time()
        r = trk.step(t, z)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return np.array(times), np.array(cpu), r


def loglog_slope(n, y) -> float:
    """Least-squares slope of log y against log n."""
    return float(np.polyfit(np.log(np.asarray(n, float)), np.log(np.asarray(y, float)), 1)[0])


def scaling_points(kind: str, plan: dict, warm_targets: int = 100) -> list[dict]:
    """Steady-state cost per scan of one tracker kind at each n of ``plan``
    (``{n: (timed scans, runs)}``) on :func:`scaling_scene`, after an untimed run on
    ``warm_targets`` targets; one dict per n."""
    points = []
    logging.disable(logging.WARNING)
    try:
        warm = scaling_scene(warm_targets, 10)
        _timed_steps(warm, scenario_config(warm), kind)  # numba kernels, caches
        for n, (timed, runs) in plan.items():
            sc = scaling_scene(n, SKIP_SCANS + timed)
            cfg = scenario_config(sc)
            per_run, all_steps, per_run_cpu, last = [], [], [], None
            for _ in range(runs):
                steps, cpu, last = _timed_steps(sc, cfg, kind)
                steady = steps[SKIP_SCANS:]
                per_run.append(float(steady.sum()))
                per_run_cpu.append(float(cpu[SKIP_SCANS:].sum()))
                all_steps.append(steady)
            steps = np.concatenate(all_steps)
            seconds = statistics.median(per_run)
            rate = timed / seconds
            ms_mean = 1e3 / rate
            alive = len(sc.truth_ids[-1])
            points.append(
                dict(
                    tracker=kind,
                    n_targets=n,
                    clutter_per_scan=0.5 * n,
                    side_m=10_000.0 * math.sqrt(n / 100.0),
                    clutter_density=cfg.clutter_density,
                    mean_detections=float(np.mean([len(d) for d in sc.detections[SKIP_SCANS:]])),
                    timed_scans=timed,
                    runs=runs,
                    run_seconds=per_run,
                    scans_per_second=rate,
                    ms_per_scan_mean=ms_mean,
                    ms_per_scan_median=float(np.median(steps) * 1e3),
                    ms_per_scan_max=float(steps.max() * 1e3),
                    cpu_ms_per_scan_mean=statistics.median(per_run_cpu) / timed * 1e3,
                    us_per_target_scan=ms_mean * 1e3 / n,
                    confirmed_tracks_last_scan=len(last.ids),
                    tentative_tracks_last_scan=last.n_tentative,
                    truths_last_scan=alive,
                )
            )
    finally:
        logging.disable(logging.NOTSET)
    return points


def _scaling(console, quick, results):
    points = scaling_points("jipda", SCALING_QUICK if quick else SCALING_FULL)
    ns = [p["n_targets"] for p in points]
    ms = [p["ms_per_scan_mean"] for p in points]
    slope = loglog_slope(ns, ms)
    big = [i for i, n in enumerate(ns) if n >= 1000]
    slope_big = loglog_slope([ns[i] for i in big], [ms[i] for i in big]) if len(big) > 1 else None
    base = points[0]["us_per_target_scan"]
    t = Table(
        title="Scaling at constant density: n targets + n/2 clutter/scan, "
        f"side = 10 km·√(n/100) (steady state, first {SKIP_SCANS} scans untimed)"
    )
    for col in (
        "targets",
        "clutter/scan",
        "detections/scan",
        "timed scans × runs",
        "scans/s",
        "ms/scan median",
        "ms/scan mean",
        "µs/target/scan",
        "vs n=100",
        "confirmed (truths) last scan",
    ):
        t.add_column(col)
    for p in points:
        t.add_row(
            f"{p['n_targets']:,}",
            f"{p['clutter_per_scan']:,.0f}",
            f"{p['mean_detections']:,.0f}",
            f"{p['timed_scans']} × {p['runs']}",
            f"{p['scans_per_second']:.1f}",
            f"{p['ms_per_scan_median']:.1f}",
            f"{p['ms_per_scan_mean']:.1f}",
            f"{p['us_per_target_scan']:.1f}",
            f"{p['us_per_target_scan'] / base:.2f}×",
            f"{p['confirmed_tracks_last_scan']:,} ({p['truths_last_scan']:,})",
        )
    console.print(t)
    at3000 = next((p for p in points if p["n_targets"] == 3000), None)
    rate_ok = at3000 is not None and at3000["scans_per_second"] >= 10.0
    slope_ok = slope <= 1.2
    console.print(
        f"log-log slope of ms/scan vs n: {slope:.2f} (all n)"
        + (f", {slope_big:.2f} (n ≥ 1000)" if slope_big is not None else "")
        + f" — {'PASS' if slope_ok else 'FAIL'} (≤ 1.2, roughly linear)"
    )
    if at3000 is not None:
        console.print(
            f"3000 targets + 1500 clutter: {at3000['scans_per_second']:.1f} scans/s — "
            f"{'PASS' if rate_ok else 'FAIL'} (≥ 10)"
        )
    results["scaling"] = dict(
        skip_scans=SKIP_SCANS,
        points=points,
        slope=slope,
        slope_n_ge_1000=slope_big,
        scans_per_second_3000=None if at3000 is None else at3000["scans_per_second"],
        target_rate_met=rate_ok,
        target_slope_met=slope_ok,
        target_met=rate_ok and slope_ok,
    )


def _scaling_poisson(console, quick, results):
    plans = SCALING_POISSON_QUICK if quick else SCALING_POISSON_FULL
    by_kind = {"jipda": results.get("scaling", {}).get("points", [])}
    for kind, plan in plans.items():
        by_kind[kind] = scaling_points(kind, plan)
    t = Table(
        title="JIPDA, PMB and PMBM at constant density (n targets + n/2 clutter/scan, "
        f"first {SKIP_SCANS} scans untimed)"
    )
    for col in (
        "targets",
        *(f"{k} scans/s" for k in KINDS),
        *(f"{k} ms/scan" for k in KINDS),
        *(f"{k} CPU ms/scan" for k in KINDS),
    ):
        t.add_column(col)
    ns = sorted({p["n_targets"] for pts in by_kind.values() for p in pts if p["n_targets"] <= 3000})
    at = {k: {p["n_targets"]: p for p in pts} for k, pts in by_kind.items()}

    def cell(k, n, key, fmt):
        p = at.get(k, {}).get(n)
        return "—" if p is None else format(p[key], fmt)

    for n in ns:
        t.add_row(
            f"{n:,}",
            *(cell(k, n, "scans_per_second", ".1f") for k in KINDS),
            *(cell(k, n, "ms_per_scan_mean", ".1f") for k in KINDS),
            *(cell(k, n, "cpu_ms_per_scan_mean", ".1f") for k in KINDS),
        )
    console.print(t)
    out = {}
    for kind, pts in by_kind.items():
        far = [p for p in pts if POISSON_SLOPE_FROM <= p["n_targets"] <= 3000]
        # CPU time: on a shared machine the wall time is mostly the other processes'
        slope = (
            loglog_slope([p["n_targets"] for p in far], [p["cpu_ms_per_scan_mean"] for p in far])
            if len(far) > 1
            else None
        )
        ok = slope is not None and slope <= POISSON_SLOPE_MAX
        out[kind] = dict(points=pts, slope_past_300=slope, target_met=ok)
        if slope is not None:
            console.print(
                f"{kind}: log-log slope of CPU ms/scan vs n for {POISSON_SLOPE_FROM} ≤ n ≤ 3000: "
                f"{slope:.2f} — {'PASS' if ok else 'FAIL'} (≤ {POISSON_SLOPE_MAX})"
            )
    results["scaling_by_tracker"] = out


# ------------------------------------------------------------- memory against scans
MEMORY_SCANS = 200
MEMORY_SCANS_QUICK = 60
MEMORY_EVERY = 10
#: flat: the memory held grows by at most this fraction over the run's second half
MEMORY_GROWTH_MAX = 0.02


def memory_series(kind: str, n_scans: int, every: int = MEMORY_EVERY, n_targets: int = 100):
    """``(scans, bytes)`` of one tracker on ``scaling_scene(n_targets, n_scans)``: the
    memory allocated since it was built and still held (``tracemalloc``, which numpy
    reports its arrays to), sampled after every ``every`` scans. Not the resident set:
    the allocator keeps what an earlier, larger run freed (the 10,000-target scaling
    point left the process at 213 MiB, and every tracker after it read 213.0 MiB flat)."""
    import gc
    import tracemalloc

    sc = scaling_scene(n_targets, n_scans)
    started = not tracemalloc.is_tracing()
    if started:
        tracemalloc.start()
    scans, held = [], []
    logging.disable(logging.WARNING)
    try:
        gc.collect()
        base = tracemalloc.get_traced_memory()[0]
        trk = scaling_tracker(kind, sc)
        for k, (t, z) in enumerate(zip(sc.times, sc.detections, strict=True), start=1):
            trk.step(t, z)
            if k % every == 0 or k == n_scans:
                gc.collect()
                scans.append(k)
                held.append(tracemalloc.get_traced_memory()[0] - base)
    finally:
        logging.disable(logging.NOTSET)
        if started:
            tracemalloc.stop()
    return np.array(scans), np.array(held)


def memory_growth(scans, held) -> float:
    """Growth of the memory held over the second half of the run, as a fraction of it."""
    half = scans >= scans[-1] / 2
    return float((held[half][-1] - held[half][0]) / held[half][0]) if half.sum() > 1 else 0.0


def _memory(console, quick, results):
    n_scans = MEMORY_SCANS_QUICK if quick else MEMORY_SCANS
    out = {}
    t = Table(
        title=f"Memory against scans: 100 targets + 50 clutter/scan, {n_scans} scans, "
        "no kept history (bytes allocated and held since the tracker was built, tracemalloc)"
    )
    for col in ("tracker", "first sample", "half-way", "at the end", "growth"):
        t.add_column(col)
    for kind in KINDS:
        scans, held = memory_series(kind, n_scans)
        growth = memory_growth(scans, held)
        ok = growth <= MEMORY_GROWTH_MAX
        mid = int(np.searchsorted(scans, scans[-1] / 2))
        out[kind] = dict(
            scans=scans.tolist(), held_bytes=held.tolist(), growth_second_half=growth, target_met=ok
        )
        t.add_row(
            kind,
            f"{held[0] / 2**20:.2f} MiB",
            f"{held[mid] / 2**20:.2f} MiB",
            f"{held[-1] / 2**20:.2f} MiB",
            f"{growth:+.1%} ({'PASS' if ok else 'FAIL'}, ≤ {MEMORY_GROWTH_MAX:.0%})",
        )
    console.print(t)
    console.print(
        "memory held by Python objects and numpy arrays (tracemalloc; numba's compiled "
        "code and the interpreter not included); tracemalloc slows the steps, so no timing here"
    )
    results["memory"] = dict(n_scans=n_scans, every=MEMORY_EVERY, trackers=out)


def plot_tracker_scaling(by_kind: dict, memory: dict | None, path) -> Path:
    """Steps/s and ms per scan against n (log-log) per tracker, and memory against scans."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    # fixed margins: a constrained layout measured every log tick label (seconds)
    fig, (a, b, c) = plt.subplots(1, 3, figsize=(16, 4.5))
    fig.subplots_adjust(left=0.05, right=0.99, bottom=0.12, top=0.92, wspace=0.22)
    for color, (kind, pts) in zip(("C0", "C1", "C2"), by_kind.items(), strict=False):
        if not pts:
            continue
        n = np.array([p["n_targets"] for p in pts], float)
        rate = np.array([p["scans_per_second"] for p in pts])
        # CPU time where measured: on a shared machine the wall time is others' too
        ms = np.array([p.get("cpu_ms_per_scan_mean", p["ms_per_scan_mean"]) for p in pts])
        a.loglog(n, rate, "o-", color=color, label=kind.upper())
        label = kind.upper()
        if len(n) > 1:
            label += f" (slope {loglog_slope(n, ms):.2f})"
        b.loglog(n, ms, "o-", color=color, label=label)
        b.loglog(n, ms[0] * n / n[0], color=color, ls=":", lw=1)
    a.set_title("scans per second (steady state)")
    b.set_title("CPU ms per scan (dotted: ∝ n from the first point)")
    for ax in (a, b):
        ax.set_xlabel("targets n (clutter n/2 per scan, constant density)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    if memory:
        for color, (kind, m) in zip(("C0", "C1", "C2"), memory["trackers"].items(), strict=False):
            label = f"{kind.upper()} ({m['growth_second_half']:+.1%} in the second half)"
            c.plot(
                m["scans"], np.array(m["held_bytes"]) / 2**20, "o-", ms=3, color=color, label=label
            )
        c.set_xlabel("scans (100 targets, 50 clutter/scan)")
        c.set_ylabel("memory held since the start (MiB, tracemalloc)")
        c.set_ylim(bottom=0)
        c.set_title("memory against scans")
        c.grid(True, alpha=0.3)
        c.legend(fontsize=8)
    else:
        c.set_visible(False)
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


# ------------------------------------------------------------ large single scans
LARGE_SIZES_FULL = (5_000, 10_000, 20_000)
LARGE_SIZES_QUICK = (5_000, 20_000)
LARGE_SCANS = 3
LARGE_REGION = 1e5
ADDRESS_LIMIT = 2 * 2**30
# the issue, before the linear-scaling rewrite: (peak memory, seconds) or the failure
LARGE_BEFORE = {
    5_000: "2.1 GB, 10 s",
    10_000: "7.8 GB, 47 s",
    20_000: "tried to allocate 11.9 GiB: fails",
}

_CHILD = (
    "import sys; from jointtrack.bench.tracker import large_scan_child; "
    "large_scan_child(int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]))"
)


def large_scan_child(m: int, n_scans: int = LARGE_SCANS, limit: int = ADDRESS_LIMIT) -> None:
    """Run in a fresh process: the address-space limit, then ``n_scans`` scans of m
    uniform detections; prints one JSON line (seconds per scan, peak RSS)."""
    import resource

    if limit > 0:
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    rng = np.random.default_rng(0)
    # untimed warm-up on a small, denser scene of the same kind, so that the numba
    # kernels (assignment of initiation components, cluster association) are loaded
    warm = JPDATracker(TrackerConfig(clutter_density=1e-6))
    for k in range(4):
        warm.step(float(k), rng.uniform(0, 3e3, (300, 2)))
    base_rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    trk = JPDATracker(TrackerConfig(clutter_density=1e-6))
    seconds, tracks, confirmed, clusters = [], [], [], []
    for k in range(n_scans):
        z = rng.uniform(0.0, LARGE_REGION, (m, 2))
        t0 = time.perf_counter()
        r = trk.step(float(k), z)
        seconds.append(time.perf_counter() - t0)
        tracks.append(len(trk.ids))
        confirmed.append(len(r.ids))
        clusters.append(len(r.cluster_sizes))
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # KiB on Linux
    print(
        json.dumps(
            dict(
                detections=m,
                seconds=seconds,
                tracks=tracks,
                confirmed=confirmed,
                clusters=clusters,
                peak_rss_bytes=rss,
                warm_rss_bytes=base_rss,
            )
        ),
        flush=True,
    )


def run_large_scan(
    m: int, n_scans: int = LARGE_SCANS, limit: int = ADDRESS_LIMIT, timeout: float = 600.0
) -> dict:
    """``large_scan_child`` in a fresh interpreter; its JSON plus completion status."""
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(
            [sys.executable, "-c", _CHILD, str(m), str(n_scans), str(limit)],
            capture_output=True,
            text=True,
            timeout=timeout,
        )
    except subprocess.TimeoutExpired:
        return dict(detections=m, completed=False, returncode=None, error=f"timeout {timeout} s")
    wall = time.perf_counter() - t0
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
    if proc.returncode != 0 or not lines:
        tail = (proc.stderr.strip().splitlines() or ["(no stderr)"])[-1]
        return dict(
            detections=m,
            completed=False,
            returncode=proc.returncode,
            error=tail,
            process_seconds=wall,
        )
    res = json.loads(lines[-1])
    res.update(completed=True, returncode=0, process_seconds=wall)
    return res


def _large(console, quick, results):
    sizes = LARGE_SIZES_QUICK if quick else LARGE_SIZES_FULL
    rows = [run_large_scan(m) for m in sizes]
    t = Table(
        title=f"Large single scans: M uniform detections over 1e5 × 1e5 m, {LARGE_SCANS} "
        "consecutive scans, TrackerConfig(clutter_density=1e-6), fresh process, "
        "RLIMIT_AS = 2 GiB"
    )
    for col in (
        "detections/scan",
        "before (issue)",
        "completes ≤ 2 GiB",
        "s/scan median",
        "s/scan max",
        "s all scans",
        "peak RSS (process)",
        "tracks after each scan",
        "before/after",
    ):
        t.add_column(col)
    for r in rows:
        m = r["detections"]
        before = LARGE_BEFORE.get(m, "—")
        if not r["completed"]:
            t.add_row(f"{m:,}", before, f"FAIL ({r['error']})", *["—"] * 6)
            continue
        s = r["seconds"]
        r["seconds_median"] = statistics.median(s)
        r["seconds_max"] = max(s)
        r["seconds_total"] = sum(s)
        rss = r["peak_rss_bytes"]
        ratio = {5_000: (2.1e9, 10.0), 10_000: (7.8e9, 47.0)}.get(m)
        if ratio is not None:
            r["memory_ratio"] = ratio[0] / rss
            r["time_ratio_vs_total"] = ratio[1] / r["seconds_total"]
            cmp = f"{ratio[0] / rss:.0f}× less memory, {ratio[1] / r['seconds_total']:.0f}× faster"
        elif m == 20_000:
            cmp = "failed before, completes now"
        else:
            cmp = "—"
        t.add_row(
            f"{m:,}",
            before,
            "PASS",
            f"{r['seconds_median']:.3f}",
            f"{r['seconds_max']:.3f}",
            f"{r['seconds_total']:.3f}",
            f"{rss / 2**20:.0f} MiB ({r['warm_rss_bytes'] / 2**20:.0f} after warm-up)",
            " → ".join(f"{k:,}" for k in r["tracks"]),
            cmp,
        )
    console.print(t)
    console.print(
        "before/after: the issue's memory (GB, 1e9 bytes) over the peak RSS (whole process: "
        "interpreter, numpy, numba, jointtrack; in brackets the peak before the big scans) "
        "and its seconds over all timed scans here. The issue's numbers are quoted, "
        "not re-run."
    )
    ok = all(r["completed"] for r in rows)
    results["large_scans"] = dict(
        scans=LARGE_SCANS,
        region=LARGE_REGION,
        address_limit_bytes=ADDRESS_LIMIT,
        before=LARGE_BEFORE,
        rows=rows,
        target_met=ok,
    )
    console.print(f"all large scans complete under RLIMIT_AS = 2 GiB — {'PASS' if ok else 'FAIL'}")


PARTS = ("many", "bojilov", "scaling", "memory", "large")


def run(quick: bool = False, out: str | None = None, parts=None) -> dict:
    """Every part (or those named in ``parts``, see :data:`PARTS`); the JSON to ``out``."""
    parts = PARTS if not parts else tuple(parts)
    unknown = sorted(set(parts) - set(PARTS))
    if unknown:
        raise ValueError(f"unknown part(s) {', '.join(unknown)}; the parts: {', '.join(PARTS)}")
    console = make_console()
    results: dict = {"quick": quick, "parts": list(parts)}
    if "many" in parts:
        _many(console, quick, results)
    if "bojilov" in parts:
        _bojilov(console, quick, results)
    if "scaling" in parts:
        _scaling(console, quick, results)
        _scaling_poisson(console, quick, results)
    if "memory" in parts:
        _memory(console, quick, results)
    if "large" in parts:
        _large(console, quick, results)
    if out and ("scaling" in parts or "memory" in parts):
        png = Path(out).with_name(Path(out).stem + "_scaling.png")
        by_kind = {k: v["points"] for k, v in results.get("scaling_by_tracker", {}).items()}
        try:
            results["plot"] = str(plot_tracker_scaling(by_kind, results.get("memory"), png))
            console.print(f"scaling plot: {png}")
        except ImportError as exc:  # matplotlib is a dependency, but say so rather than fail
            console.print(f"scaling plot not written: {exc}")
    if out:
        with open(out, "w") as fh:
            json.dump(to_jsonable(results, fallback=float), fh, indent=2)
    return results
