"""Issue 31: what a clutter burst costs the PMBM tracker per scan, and what its budget is made of.

1. **The burst** (issue 31, defect 2): K returns in a 3 m blob, three scans of
   ``rng.normal(0, 3, (K, 2))`` (seed 0), ``PMBMConfig(clutter_density=1e-5,
   measurement_noise=1.0, process_noise=1.0, birth_density=1e-6)``. Per K: the
   worst scan's CPU time (``time.process_time``: the machine may be shared) of
   PMBM with its default ranking budget (``max_ranking_work``), the tier that
   solved the blob (``ScanResult.cluster_methods``), and in the same run PMB on
   the same scans and — up to ``--unbudgeted-max`` returns — PMBM without the
   budget (``max_ranking_work=None``: the ranking of every earlier jointtrack),
   with the ratios; and JIPDA (``TrackerConfig(existence=True)``, the same
   clutter, noise and process noise) on the same scans, whose tentative tracks
   make the second scan one cluster of 2,000 tracks.
2. **Murty's cost per cell**: :func:`~jointtrack.association.kbest_hypotheses`
   on dense random clusters of n tracks × n returns (80 % gated), k events,
   against the budget's estimate (1 + (k − 1) n) · n · (n + m) cost-matrix cells
   (``PMBMTracker._ranking_cap``): nanoseconds per cell.
3. **The set-up per tuple**: one scan of a state whose one cluster (18 tracks
   10 m apart) holds ``--tuples`` distinct single-target-hypothesis tuples (one
   global hypothesis each, equal weights), without the budget: milliseconds per
   tuple (``_TUPLE_WORK``).

    PYTHONPATH=src python benchmarks/pmbm_burst.py [--sizes 100 200 400 1000 2000]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from jointtrack.association.kbest import kbest_hypotheses
from jointtrack.trackers import JPDATracker, TrackerConfig
from jointtrack.trackers.pmbm import PMBMConfig, PMBMTracker, PMBTracker

BURST = dict(clutter_density=1e-5, measurement_noise=1.0, process_noise=1.0, birth_density=1e-6)


def burst(kind, K: int, **config) -> tuple[float, str, int]:
    """``(worst scan CPU seconds, blob tier, hypotheses)`` of three burst scans of K returns."""
    if kind is JPDATracker:
        jipda = {k: v for k, v in BURST.items() if k != "birth_density"}
        trk = JPDATracker(TrackerConfig(existence=True, **jipda, **config))
    else:
        trk = kind(PMBMConfig(**BURST, **config))
    rng = np.random.default_rng(0)
    worst, tier = 0.0, ""
    for t in range(3):
        z = rng.normal(0, 3, (K, 2))
        t0 = time.process_time()
        res = trk.step(float(t), z)
        dt = time.process_time() - t0
        if dt >= worst:
            worst = dt
            tier = ", ".join(sorted(set(res.cluster_methods))) or "-"
    return worst, tier, getattr(trk, "n_hypotheses", 1)


def murty_ns_per_cell(rng) -> list:
    rows = []
    for n in (10, 20, 40, 80, 160):
        for k in (10, 50, 200):
            L = np.exp(rng.normal(0, 2, (n, n))) * (rng.random((n, n)) < 0.8)
            miss = np.full(n, 0.1)
            t0 = time.process_time()
            kbest_hypotheses(L, miss, k=k)
            dt = time.process_time() - t0
            cells = (1 + (k - 1) * n) * n * (2 * n)
            rows.append((n, k, dt, dt / cells * 1e9))
    return rows


def tuple_setup_ms(n_tuples: int) -> float:
    T = 18
    trk = PMBMTracker(
        PMBMConfig(clutter_density=1e-4, birth_density=1e-6, measurement_noise=1.0,
                   max_ranking_work=None)
    )  # fmt: skip
    trk.sth_r = np.full(T, 0.9)
    trk.sth_x = np.array([[10.0 * i, 0.0, 1.0, 0.0] for i in range(T)])
    trk.sth_P = np.tile(np.diag([4.0, 4.0, 1.0, 1.0]), (T, 1, 1))
    trk.sth_track = np.arange(T)
    trk.track_ids = np.arange(1, T + 1)
    trk.track_reported = np.zeros(T, bool)
    trk.next_id = T + 1
    bits = (np.arange(n_tuples)[:, None] >> np.arange(T)[None, :]) & 1
    trk.hyp = np.where(bits == 1, np.arange(T)[None, :], -1).astype(np.int64)
    trk.hyp_logw = np.zeros(n_tuples)
    trk.time = 0.0
    z = np.array([[10.0 * i + 1.0, 0.5] for i in range(0, T, 2)])
    t0 = time.process_time()
    trk.step(1.0, z)
    return (time.process_time() - t0) / n_tuples * 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 200, 400, 1000, 2000])
    ap.add_argument("--unbudgeted-max", type=int, default=200)
    ap.add_argument("--tuples", type=int, default=20_000)
    args = ap.parse_args()
    burst(PMBMTracker, 30)  # numba kernels compiled or loaded before any timing
    burst(PMBTracker, 30)
    burst(JPDATracker, 30)
    budget = PMBMConfig().max_ranking_work
    print(f"1. burst: worst of 3 scans, CPU s (PMBM max_ranking_work = {budget})")
    print("| returns | PMBM | PMBM tier | hypotheses | PMB | PMB tier | PMBM/PMB | JIPDA "
          "| JIPDA tier | unbudgeted PMBM | unbudgeted/PMBM |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for K in args.sizes:
        s, tier, H = burst(PMBMTracker, K)
        s_pmb, tier_pmb, _ = burst(PMBTracker, K)
        s_jipda, tier_jipda, _ = burst(JPDATracker, K)
        line = (
            f"| {K} | {s:.2f} | {tier} | {H} | {s_pmb:.2f} | {tier_pmb} | {s / s_pmb:.2f} "
            f"| {s_jipda:.2f} | {tier_jipda} |"
        )
        if K <= args.unbudgeted_max:
            s_old, tier_old, _ = burst(PMBMTracker, K, max_ranking_work=None)
            line += f" {s_old:.2f} ({tier_old}) | {s_old / s:.1f} |"
        else:
            line += " – | – |"
        print(line, flush=True)
    print("\n2. Murty: CPU s and ns per estimated cost-matrix cell")
    print("| n = m | k | s | ns/cell |")
    print("|---|---|---|---|")
    for n, k, dt, ns in murty_ns_per_cell(np.random.default_rng(1)):
        print(f"| {n} | {k} | {dt:.4f} | {ns:.1f} |", flush=True)
    ms = tuple_setup_ms(args.tuples)
    print(f"\n3. set-up per tuple ({args.tuples} tuples in one cluster, no budget): {ms:.3f} ms")


if __name__ == "__main__":
    main()
