"""JPDATracker throughput on many tiny scans (issue 24: AIS/ADS-B, one scan per report time).

Real AIS/ADS-B feeds are processed as one scan per report time: thousands of
scans holding one return each while ~80–150 tracks stay alive, so the cost is
the per-scan overhead of ``JPDATracker.step``, not the association. The
workload: ``--targets`` targets moving at constant velocity; each scan holds
one report (σ = 10 m) of a random target, 0.3 s after the previous scan.
``p_survive = 0.9999`` keeps tracks alive between their sparse reports.

``--reporting async`` runs the same reports through the reporting-targets model
(``reporting = "async"``, survival per second, P_D from each track's own rate),
whose per-scan cost includes each track's continuous-time silence outcome
(:func:`jointtrack.trackers.existence.silence_outcomes`).

Prints scans per second (CPU time) and the number of live tracks at the end.
``--against DIR [DIR ...]`` times other source trees (``PYTHONPATH=DIR``) in
fresh interpreters, interleaved with this one over ``--repeats`` rounds, and
prints the median of each: the before/after numbers of benchmarks/RESULTS.md.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np


def run_once(n_scans: int, n_targets: int, seed: int = 0, reporting: str = "scan") -> dict:
    """Step a fresh tracker through the workload; scans/s (CPU time) and live tracks."""
    from jointtrack.trackers.jpda import JPDATracker, TrackerConfig

    rng = np.random.default_rng(seed)
    pos = rng.uniform(0, 50_000, (n_targets, 2))
    vel = rng.normal(0, 5, (n_targets, 2))
    if reporting == "scan":
        # each scan reports one target out of n_targets: that is each track's P_D per scan
        model = dict(p_survive=0.9999, p_d=1.0 / n_targets)
    else:  # each target reports every 0.3·n_targets s on average: its own learnt rate
        model = dict(
            reporting="async",
            p_survive=0.9999,
            p_survive_per="second",
            p_d=0.99,
            report_interval=0.3 * n_targets,
        )
    config = TrackerConfig(
        clutter_density=1e-12, measurement_noise=100.0, process_noise=0.01, **model
    )
    trk = JPDATracker(config)
    scans = []
    t = 0.0
    for _ in range(n_scans):
        t += 0.3
        i = rng.integers(n_targets)
        scans.append((t, (pos[i] + vel[i] * t + rng.normal(0, 10, 2))[None]))
    # warm-up: the first scans (few tracks) are not the steady state being measured
    warm = n_scans // 4
    for t, z in scans[:warm]:
        trk.step(t, z)
    t0 = time.process_time()
    for t, z in scans[warm:]:
        trk.step(t, z)
    seconds = time.process_time() - t0
    return {
        "scans_per_s": (n_scans - warm) / seconds,
        "tracks": len(trk.ids),
        "confirmed": int(trk.confirmed.sum()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scans", type=int, default=4000)
    parser.add_argument("--targets", type=int, default=120)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", action="store_true", help="one JSON line (used by --against)")
    parser.add_argument("--against", nargs="+", default=[], metavar="DIR")
    parser.add_argument("--reporting", choices=["scan", "async"], default="scan")
    args = parser.parse_args()
    if args.json:
        print(json.dumps(run_once(args.scans, args.targets, reporting=args.reporting)))
        return
    here = str(Path(__import__("jointtrack").__file__).parents[1])
    trees = [here, *args.against]
    cmd = [sys.executable, __file__, "--json", "--scans", str(args.scans)]
    cmd += ["--targets", str(args.targets), "--reporting", args.reporting]
    rates: dict[str, list[float]] = {tree: [] for tree in trees}
    tracks: dict[str, int] = {}
    for _ in range(args.repeats):
        for tree in trees:  # interleaved: load drift on a shared machine hits all alike
            env = {**os.environ, "PYTHONPATH": tree}
            out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
            res = json.loads(out.stdout.strip().splitlines()[-1])
            rates[tree].append(res["scans_per_s"])
            tracks[tree] = res["tracks"]
    ours = statistics.median(rates[here])
    for tree in trees:
        med = statistics.median(rates[tree])
        print(
            f"{tree}: {med:8.0f} scans/s (median of {args.repeats}: "
            f"{', '.join(f'{r:.0f}' for r in rates[tree])}), {tracks[tree]} tracks at the end"
            + ("" if tree == here else f"; {here} is {ours / med:.2f}× as fast")
        )


if __name__ == "__main__":
    main()
