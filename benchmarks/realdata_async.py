"""Issue 34, item 3: reports one at a time on the Solent AIS file — CPU per report, old vs new.

The whole Solent AIS file (Stone Soup 1.9.1's demo CSV, 18,623 reports of 91
vessels), one scan per report time, no labels given to the tracker, the JIPDA
tracker with the settings ``jointtrack run --detections FILE --labels score``
gives it (``reporting = "async"``, reported velocities measured:
:data:`jointtrack.experiments.realdata.REALDATA_TRACKER`). Each tree runs in its
own interpreter (``PYTHONPATH`` = the tree's ``src``), the trees alternated
(old, new, old, new, …); ``uptime`` is printed before and after. A run reports
the CPU seconds (``time.process_time``) and wall seconds of its tracking loop,
reports per CPU second, the peak RSS, and a SHA-256 of every scan's output (the
reported tracks' ids, states, covariances, existences; the tentative count) —
the two trees' digests must be equal (identical association results).

    PYTHONPATH=src python benchmarks/realdata_async.py --against /tmp/orig-reports/src \\
        [--rounds 3] [--scans N] [--ais PATH]

``--one`` (internal): run this interpreter's tree once and print one JSON line.
``--profile N``: cProfile of the first N scans of this tree (no comparison).
``--tracks 10,100,1000``: instead of the file, CPU per report against the number of
live tracks — that many confirmed tracks 1 km apart, one report per scan (1 s apart)
on one of them in turn (every reported track then has an interval of its own; past 200
tracks the unreported ones share t = 0); 200 scans.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

DEFAULT_AIS = Path.home() / ".cache/jointtrack/realdata/extracted/SolentAIS_20160112_130211.csv"


def _workload(path, n_scans):
    """``(tracker, detections, scan count)``: what ``run_reports(path, labels="score")`` steps."""
    from jointtrack.experiments.config import make_tracker_config
    from jointtrack.experiments.realdata import realdata_settings
    from jointtrack.io.reports import read_reports
    from jointtrack.trackers import JPDATracker

    rep = read_reports(path, format="ais")
    centre = rep.centre()
    rep = rep.subset(~centre.outliers)
    dets = rep.detections(centre.frame, scan="report", labels=True, propagate=True, excluded=centre)
    cfg = make_tracker_config({"dim": 2}, realdata_settings("ais", labelled=False))
    trk = JPDATracker(cfg, keep_history=False)
    n = len(dets.times) if n_scans is None else min(n_scans, len(dets.times))
    return trk, dets, n


def _loop(trk, dets, n):
    """Step the first ``n`` scans (reported velocities given, labels not); returns
    ``(digest, reports)``."""
    h = hashlib.sha256()
    reports = 0
    for k in range(n):
        z = dets.scans[k]
        reports += len(z)
        res = trk.step(float(dets.times[k]), z, velocities=dets.velocities[k])
        for a in (res.ids, res.x, res.P, np.asarray(res.existence, float)):
            h.update(np.ascontiguousarray(a).tobytes())
        h.update(str(res.n_tentative).encode())
    return h.hexdigest(), reports


def run_tracks(n_tracks, n_scans=200) -> dict:
    """CPU per report with ``n_tracks`` live tracks (``--tracks``, module docstring)."""
    from jointtrack.experiments.config import make_tracker_config
    from jointtrack.experiments.realdata import realdata_settings
    from jointtrack.trackers import JPDATracker

    settings = {**realdata_settings("ais", labelled=False), "measure_velocity": False}
    trk = JPDATracker(make_tracker_config({"dim": 2}, settings), keep_history=False)
    side = int(np.ceil(np.sqrt(n_tracks)))
    k = np.arange(n_tracks)
    pos = 1000.0 * np.stack([k % side, k // side], 1).astype(float)
    x0 = np.hstack([pos, np.zeros((n_tracks, 2))])
    P0 = np.broadcast_to(np.diag([225.0, 225.0, 1.0, 1.0]), (n_tracks, 4, 4))
    trk.start_tracks(x0, P0, existence=0.99, time=0.0)
    rng = np.random.default_rng(0)
    h = hashlib.sha256()
    c0, w0 = time.process_time(), time.perf_counter()
    for s in range(1, n_scans + 1):
        z = pos[(s * 7919) % n_tracks][None] + rng.normal(scale=15.0, size=(1, 2))
        res = trk.step(float(s), z)
        for a in (res.ids, res.x, res.P):
            h.update(np.ascontiguousarray(a).tobytes())
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    return {
        "tracks": n_tracks,
        "reports": n_scans,
        "cpu_s": cpu,
        "wall_s": wall,
        "reports_per_cpu_s": n_scans / cpu,
        "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "live_tracks_end": len(trk.ids),
        "digest": h.hexdigest(),
    }


def run_once(path, n_scans) -> dict:
    trk, dets, n = _workload(path, n_scans)
    # the numba kernels compiled (cached) outside the timing: a short warm-up tracker
    warm, wdets, wn = _workload(path, 30)
    _loop(warm, wdets, wn)
    c0, w0 = time.process_time(), time.perf_counter()
    digest, reports = _loop(trk, dets, n)
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    return {
        "scans": n,
        "reports": reports,
        "cpu_s": cpu,
        "wall_s": wall,
        "reports_per_cpu_s": reports / cpu,
        "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "live_tracks_end": len(trk.ids),
        "digest": digest,
    }


def _uptime() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ais", default=str(DEFAULT_AIS))
    ap.add_argument("--against", help="the old tree's src directory")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--scans", type=int, default=None)
    ap.add_argument("--one", action="store_true")
    ap.add_argument("--profile", type=int, default=None)
    ap.add_argument("--tracks", help="comma-separated numbers of live tracks")
    args = ap.parse_args()
    if args.one:
        if args.tracks:
            run_tracks(10, 5)  # compiled kernels outside the timing
            print(json.dumps(run_tracks(int(args.tracks))), flush=True)
        else:
            print(json.dumps(run_once(args.ais, args.scans)), flush=True)
        return
    if args.profile is not None:
        import cProfile
        import pstats

        trk, dets, n = _workload(args.ais, args.profile)
        warm, wdets, wn = _workload(args.ais, 30)
        _loop(warm, wdets, wn)
        pr = cProfile.Profile()
        pr.enable()
        _loop(trk, dets, n)
        pr.disable()
        pstats.Stats(pr).sort_stats("cumulative").print_stats(40)
        pstats.Stats(pr).sort_stats("tottime").print_stats(25)
        return
    here = str(Path(__file__).resolve().parents[1] / "src")
    trees = [("old", args.against), ("new", here)]
    if args.tracks:
        scaling(trees, [int(n) for n in args.tracks.split(",")], args.rounds)
        return
    print("before:", _uptime(), flush=True)
    rows = {"old": [], "new": []}
    for r in range(args.rounds):
        for name, src in trees:
            cmd = [sys.executable, __file__, "--one", "--ais", args.ais]
            if args.scans is not None:
                cmd += ["--scans", str(args.scans)]
            env = {**os.environ, "PYTHONPATH": src}
            out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
            res = json.loads(out.stdout.strip().splitlines()[-1])
            rows[name].append(res)
            print(
                f"round {r} {name}: {res['reports']} reports, CPU {res['cpu_s']:.2f} s, "
                f"wall {res['wall_s']:.2f} s, {res['reports_per_cpu_s']:.0f} reports/CPU-s, "
                f"peak RSS {res['peak_rss_mib']:.0f} MiB, {res['live_tracks_end']} live "
                f"tracks at the end, digest {res['digest'][:16]}",
                flush=True,
            )
    print("after:", _uptime(), flush=True)
    same = {r["digest"] for r in rows["old"] + rows["new"]}
    print("identical outputs (every scan, every round):", len(same) == 1)
    old = np.median([r["reports_per_cpu_s"] for r in rows["old"]])
    new = np.median([r["reports_per_cpu_s"] for r in rows["new"]])
    ratios = [
        n["reports_per_cpu_s"] / o["reports_per_cpu_s"]
        for o, n in zip(rows["old"], rows["new"], strict=True)
    ]
    print(
        f"median reports/CPU-s: old {old:.0f}, new {new:.0f}, new/old {new / old:.2f} "
        f"(per round {', '.join(f'{x:.2f}' for x in ratios)})"
    )


def scaling(trees, counts, rounds) -> None:
    """``--tracks``: old and new alternated per count, ``rounds`` times."""
    print("before:", _uptime(), flush=True)
    for n in counts:
        got = {"old": [], "new": []}
        for _ in range(rounds):
            for name, src in trees:
                cmd = [sys.executable, __file__, "--one", "--tracks", str(n)]
                env = {**os.environ, "PYTHONPATH": src}
                out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
                got[name].append(json.loads(out.stdout.strip().splitlines()[-1]))
        same = len({r["digest"] for r in got["old"] + got["new"]}) == 1
        rate = {k: [r["reports_per_cpu_s"] for r in v] for k, v in got.items()}
        med = {k: np.median(v) for k, v in rate.items()}
        each = {k: ", ".join(f"{x:.0f}" for x in v) for k, v in rate.items()}
        print(
            f"{n:6d} tracks: reports/CPU-s old {med['old']:.0f} ({each['old']}), new "
            f"{med['new']:.0f} ({each['new']}), new/old {med['new'] / med['old']:.2f}; "
            f"identical outputs: {same}",
            flush=True,
        )
    print("after:", _uptime(), flush=True)


if __name__ == "__main__":
    main()
