"""Close pairs of aircraft orbiting together: do they keep their track ids? (issue 32, item 3)

The workload: :func:`jointtrack.scenarios.close_pairs` — ``--pairs`` pairs of
aircraft ``separation`` apart (150–250 m/s), 30 scans straight, 36 scans of
orbit at 3–5 °/s, 30 scans straight; a 10 s scanning sensor, P_D 0.9, 20
clutter returns per scan over the region, σ = 50 m. For each separation and
``--seeds`` seeds every tracker runs the same scans:

* ``jipda-cv``      JIPDA, CV with q = ``--q`` (the issue's ADS-B q = 20), exact JPDA β
* ``jipda-cv*``     the same with ``coalescence_avoidance = true`` (JPDA*)
* ``jipda-imm``     JIPDA, ``motion = "imm"`` (CV + coordinated turn, main's defaults)
* ``jipda-imm*``    the same with JPDA*
* ``pmbm``          PMBM (CV, the same q), :func:`jointtrack.bench.tracking_runs.poisson_config`
* ``jipda-fit``     JIPDA with the model fitted to the scene's detections
  (:func:`jointtrack.experiments.fit.fit_tracker_settings`, as a bare ``jointtrack run
  --detections`` gets it): σ, q, P_D, clutter, gate, and JPDA* and the motion model
  chosen from the data
* ``jipda-fit-cv``  the same fit with ``coalescence_avoidance = false`` and
  ``motion = "cv"`` set (the fit before it chose them)
* ``ss-gnn``, ``ss-jpda``  Stone Soup's ADS-B trackers of ``bench realdata`` (CV,
  q = 20) with GNN (``GNNWith2DAssignment``) or its JPDA (``JPDAwithEHM2``)
  (``--stonesoup``)

Scored per run by :func:`jointtrack.metrics.track_statistics` (GOSPA
assignment per scan, gate ``--gate`` = 500 m, the c of the issue's scorer):
**swaps per pair** — a target whose partner track changes to a track that was
its pair-mate's partner before (the ids swapped); **id switches per pair**
(CLEAR-MOT IDSW of both targets: swaps and new ids alike); **ids per target**
(distinct tracks associated with it); **coverage** (target-scans with an
associated track); and CPU seconds per run. Each cell is the mean over seeds
with the spread (min–max) in brackets.

``--oracle`` prints instead, per separation, how often the two returns of a pair
(both detected) are closer to each other's *true* positions than to their own:
the scans where even a tracker that knew both positions exactly would rank the
swapped assignment first (Φ(−d/(√2σ)) in theory; 7.9 % at d = 100 m, σ = 50 m).
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import math
import statistics
import time

import numpy as np

from jointtrack.bench.tracking_runs import (
    TrackRun,
    physical_config,
    poisson_config,
    rows_to_run,
    run_jointtrack,
    run_poisson,
)
from jointtrack.metrics import track_statistics
from jointtrack.scenarios import close_pairs

#: tracker settings shared by the jointtrack kinds (the issue's tuned ADS-B values)
COMMON = {"p_g": 0.9999, "p_survive": 0.99, "max_coast": 60.0, "r_report": 0.3}


def pair_scores(sc, run, gate: float) -> dict:
    """Swaps and id switches per pair, ids per target and coverage of one run."""
    truth = sc.truth_table()
    st = track_statistics(*truth, run.times, run.ids, run.positions, gate)
    mate = {}
    for a, b in sc.info["pairs"]:
        mate[a], mate[b] = b, a
    order = np.argsort(st.assoc_times, kind="stable")
    seen = {tid: set() for tid in mate}  # tracks each target has had so far
    last: dict = {}
    swaps = switches = 0
    truths, tracks = st.assoc_truth_ids[order].tolist(), st.assoc_track_ids[order].tolist()
    for x, y in zip(truths, tracks, strict=True):
        prev = last.get(x)
        if prev is not None and prev != y:
            switches += 1
            swaps += y in seen[mate[x]]
        last[x] = y
        seen[x].add(y)
    n_pairs = len(sc.info["pairs"])
    held = [len(s) for s in seen.values()]
    return {
        "swaps": swaps / n_pairs,
        "switches": switches / n_pairs,
        "ids": float(np.mean(held)),
        "coverage": st.coverage,
    }


def oracle_swaps(sc) -> tuple[int, int]:
    """``(scans, swapped)``: (pair, scan)s where both aircraft were detected, and those
    where their returns are closer to the *swapped* true positions (Σ‖z − p‖² smaller)
    — the permutation a tracker that knew both positions exactly would rank first."""
    n = swapped = 0
    for X, z, o in zip(sc.truth_states, sc.detections, sc.origins, strict=True):
        for a, b in sc.info["pairs"]:
            if (o == a).sum() == 1 and (o == b).sum() == 1:
                za, zb = z[o == a][0], z[o == b][0]
                pa, pb = X[a, :2], X[b, :2]
                straight = np.sum((za - pa) ** 2) + np.sum((zb - pb) ** 2)
                crossed = np.sum((za - pb) ** 2) + np.sum((zb - pa) ** 2)
                n += 1
                swapped += bool(crossed < straight)
    return n, swapped


def run_stonesoup(sc, config: str) -> TrackRun:
    """Stone Soup's ADS-B trackers of ``bench realdata``
    (:func:`jointtrack.bench.stonesoup_realdata.build_tracker`: CV q = 20, GNN or
    JPDA) on the scene's scans."""
    from stonesoup.types.detection import Detection

    from jointtrack.bench.stonesoup_realdata import build_tracker

    tracker, mm = build_tracker(
        config,
        measurement_noise=float(sc.R[0, 0]),
        p_d=sc.p_d,
        clutter_density=sc.clutter_density,
    )
    epoch = datetime.datetime(2000, 1, 1)
    labels: dict = {}
    rows = []
    for t, Z in zip(sc.times, sc.detections, strict=True):
        ts = epoch + datetime.timedelta(seconds=float(t))
        dets = {Detection(z.reshape(-1, 1), timestamp=ts, measurement_model=mm) for z in Z}
        _, tracks = tracker.update_tracker(ts, dets)
        rows += [
            (float(t), labels.setdefault(trk.id, len(labels)), *trk.state_vector[[0, 2], 0])
            for trk in tracks
        ]
    return rows_to_run(rows, 0.0, sc.n_scans)


def runners(q: float, stonesoup: bool):
    """``{kind: run(scene) -> TrackRun}``."""

    def jipda(**kw):
        return lambda sc: run_jointtrack(sc, physical_config(sc, **COMMON, **kw))

    imm = {"motion": "imm", "max_speed": 350.0}

    def fitted(**table):
        def run(sc):
            from jointtrack.experiments.config import make_tracker_config
            from jointtrack.experiments.fit import fit_tracker_settings
            from jointtrack.io import Detections

            d = Detections(times=sc.times, scans=tuple(sc.detections), dim=sc.dim)
            f = fit_tracker_settings(d, table)
            return run_jointtrack(sc, make_tracker_config({"dim": sc.dim}, f.table))

        return run

    kinds = {
        "jipda-fit": fitted(),
        "jipda-fit-cv": fitted(coalescence_avoidance=False, motion="cv"),
        "jipda-cv": jipda(max_speed=350.0),
        "jipda-cv*": jipda(max_speed=350.0, coalescence_avoidance=True),
        "jipda-imm": jipda(**imm),
        "jipda-imm*": jipda(**imm, coalescence_avoidance=True),
        "pmbm": lambda sc: run_poisson(sc, "pmbm", poisson_config(sc, p_g=0.9999)),
    }
    if stonesoup:
        kinds["ss-gnn"] = lambda sc: run_stonesoup(sc, "gnn")
        kinds["ss-jpda"] = lambda sc: run_stonesoup(sc, "jpda")
    return kinds


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--separations", type=float, nargs="+", default=[100, 300, 1000, 2000])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--pairs", type=int, default=4)
    ap.add_argument("--q", type=float, default=20.0)
    ap.add_argument("--clutter", type=float, default=20.0, help="clutter returns per scan")
    ap.add_argument("--gate", type=float, default=500.0)
    ap.add_argument("--kinds", nargs="*", default=None)
    ap.add_argument("--stonesoup", action="store_true")
    ap.add_argument("--oracle", action="store_true", help="only the oracle's ranking errors")
    args = ap.parse_args()
    if args.oracle:
        print("separation  scans with both aircraft detected  swapped permutation ranked first")
        for sep in args.separations:
            n = k = 0
            for seed in range(args.seeds):
                sc = close_pairs(seed, separation=sep, n_pairs=args.pairs)
                dn, dk = oracle_swaps(sc)
                n, k = n + dn, k + dk
            sigma = float(np.sqrt(sc.R[0, 0]))
            # the swap wins when the noise difference along the pair's axis exceeds d:
            # N(0, 2σ²) < −d, probability Φ(−d / (√2 σ)) = erfc(d / 2σ) / 2
            expected = 0.5 * math.erfc(sep / (2.0 * sigma))
            print(f"{sep:8.0f} m {n:8d} {k / n:10.4f} (Φ(−d/√2σ) = {expected:.4f})")
        return
    kinds = runners(args.q, args.stonesoup)
    if args.kinds:
        kinds = {k: kinds[k] for k in args.kinds}
    print(
        f"{args.pairs} pairs per scene, {args.seeds} seeds per separation, q = {args.q:g}, "
        f"gate {args.gate:g} m; mean [min–max] over seeds"
    )
    head = f"{'sep m':>6} {'tracker':11} {'swaps/pair':>17} {'IDSW/pair':>17} "
    print(head + f"{'ids/target':>17} {'coverage':>19} {'CPU s':>6}")
    for sep in args.separations:
        scores = {k: [] for k in kinds}
        cpu = {k: [] for k in kinds}
        for seed in range(args.seeds):
            sc = close_pairs(
                seed, separation=sep, n_pairs=args.pairs, clutter_per_scan=args.clutter
            )
            sc = dataclasses.replace(sc, process_noise=args.q)  # the trackers' q
            for k, run in kinds.items():
                t0 = time.process_time()
                r = run(sc)
                cpu[k].append(time.process_time() - t0)
                scores[k].append(pair_scores(sc, r, args.gate))
        for k in kinds:
            cells = []
            columns = (("swaps", ".2f"), ("switches", ".2f"), ("ids", ".2f"), ("coverage", ".3f"))
            for key, fmt in columns:
                v = [s[key] for s in scores[k]]
                cells.append(f"{np.mean(v):{fmt}} [{min(v):{fmt}}–{max(v):{fmt}}]")
            print(
                f"{sep:6.0f} {k:11} {cells[0]:>17} {cells[1]:>17} {cells[2]:>17} {cells[3]:>19} "
                f"{statistics.mean(cpu[k]):6.1f}"
            )


if __name__ == "__main__":
    main()
