"""SPS-PHD / SPS-CPHD / SPS-MB particle filters on the acoustic scenario: update cost and accuracy.

S. Nannuru, M. Coates and R. Mahler, "Computationally-tractable approximate PHD
and CPHD filters for superpositional sensors", IEEE J. Sel. Topics Signal
Process. 7(3):410-420, 2013.

Run as ``python benchmarks/sps_filters.py [--quick] [--seeds S] [--out FILE]``.

* **(a) One SPS-CPHD update, 10,000 particles, 25 sensors, Gaussian likelihood.**
  The filter (run settings of :mod:`jointtrack.experiments.acoustic_run`, but
  10,000 particles and no birth particles, so the update sees exactly 10,000)
  runs 5 scans of acoustic seed 0; then the update of scan 5 is timed
  ``REPEATS`` times from the same predicted state. Printed: best and median ms,
  and the part of it spent in ``campbell_moments`` and in ``g``. Target
  (issue 14): ≤ 50 ms.
* **(b) Per-scan time and accuracy of each filter.** ``run_acoustic``'s
  settings (4,000 particles for PHD/CPHD, 1,000 per Bernoulli component for
  MB, 2,000 birth particles), 50 scans, seeds 0…S−1: mean ms per scan
  (predict + update + estimate), mean OSPA (c = 10 m, p = 1) after 10 scans,
  and the fraction of scans with the right number of estimates.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time

import numpy as np

REPEATS = 15


def _cphd_update(repeats: int) -> dict:
    import cProfile
    import pstats

    from jointtrack.experiments.acoustic_run import make_filter
    from jointtrack.scenarios.acoustic import acoustic

    sc = acoustic(seed=0)
    f, _ = make_filter(
        "sps-cphd", sc, seed=0, particles=10_000, n_birth_particles=1, birth_rate=0.0
    )
    for k in range(5):
        f.step(sc.measurements[k])
    f.predict()
    state = (f.particles, f.weights, f._log_pmf)
    y = sc.measurements[5]
    times = []
    for _ in range(repeats):
        f.particles, f.weights, f._log_pmf = state
        t0 = time.perf_counter()
        f.update(y)
        times.append(time.perf_counter() - t0)
    f.particles, f.weights, f._log_pmf = state
    prof = cProfile.Profile()
    prof.enable()
    f.update(y)
    prof.disable()
    stats = pstats.Stats(prof).stats
    parts = {"campbell_moments": 0.0, "acoustic_gain": 0.0}
    total = 0.0
    for (_file, _line, name), (_cc, _nc, tt, ct, _callers) in stats.items():
        if name in parts:
            parts[name] += ct
        total += tt
    return {
        "particles": int(state[0].shape[0]),
        "sensors": int(y.size),
        "best_ms": 1e3 * min(times),
        "median_ms": 1e3 * statistics.median(times),
        "profile_share": {k: v / total for k, v in parts.items()},
    }


def _filters(seeds: int, n_scans: int) -> dict:
    from jointtrack.experiments.acoustic_run import FILTER_DEFAULTS, run_acoustic

    out = {}
    tmp = tempfile.TemporaryDirectory(prefix="sps-bench-")
    for name in FILTER_DEFAULTS:
        rows = []
        for seed in range(seeds):
            m = run_acoustic(
                os.path.join(tmp.name, f"{name}-{seed}"),
                filter_name=name,
                seed=seed,
                n_scans=n_scans,
                plots=False,
            )
            card = np.asarray(m["cardinality"]["true"]) == np.asarray(m["cardinality"]["estimated"])
            rows.append(
                {
                    "seed": seed,
                    "ms_per_scan": 1e3 * m["timing"]["mean_seconds_per_scan"],
                    "ospa_after_burn_in": m["ospa_mean_after_burn_in"],
                    "cardinality_right": float(card[m["burn_in"] :].mean()),
                }
            )
        out[name] = rows
    tmp.cleanup()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="1 seed, 20 scans, 5 repeats")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--out", default=None, help="also write the results as JSON here")
    args = ap.parse_args()
    seeds = 1 if args.quick else args.seeds
    n_scans = 20 if args.quick else 50
    load = os.getloadavg()[0]
    print(f"load average {load:.2f}")
    a = _cphd_update(5 if args.quick else REPEATS)
    verdict = "PASS" if a["best_ms"] <= 50 else "FAIL"
    print(
        f"(a) SPS-CPHD update, {a['particles']} particles, {a['sensors']} sensors, Gaussian: "
        f"best {a['best_ms']:.1f} ms, median {a['median_ms']:.1f} ms — target <= 50 ms: {verdict}"
    )
    print(
        "    share of the update: campbell_moments "
        f"{100 * a['profile_share']['campbell_moments']:.0f} %, g (acoustic_gain) "
        f"{100 * a['profile_share']['acoustic_gain']:.0f} %"
    )
    b = _filters(seeds, n_scans)
    print(f"(b) run_acoustic, {n_scans} scans, seeds 0..{seeds - 1}")
    print("| filter | ms per scan | OSPA after 10 scans (m) | right cardinality |")
    print("|---|---|---|---|")
    for name, rows in b.items():
        ms = np.mean([r["ms_per_scan"] for r in rows])
        o = [r["ospa_after_burn_in"] for r in rows]
        c = np.mean([r["cardinality_right"] for r in rows])
        print(
            f"| {name} | {ms:.0f} | {np.mean(o):.2f} ({', '.join(f'{v:.2f}' for v in o)}) "
            f"| {100 * c:.0f} % |"
        )
    if args.out:
        with open(args.out, "w", encoding="utf-8") as fh:
            json.dump({"load": load, "cphd_update": a, "filters": b}, fh, indent=2)


if __name__ == "__main__":
    main()
