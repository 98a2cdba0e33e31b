"""A 200-run Monte Carlo sweep of the Bojilov scenario on Dask vs the same runs serially.

Run as ``python benchmarks/sweep.py [--runs 200] [--workers 2] [--scans N] [--out FILE]``.

One cell (the Bojilov scenario, ``run_scenario``'s defaults: JPDA, exact
association, tracks started from the truth), seeds 0…runs−1, through the one
cell function :func:`jointtrack.sweep.run_cell`:

* **serial**: every run in this process, one after another, after one untimed
  warm-up run (numba kernels loaded); wall time of the loop.
* **sweep**: :func:`jointtrack.sweep.run_sweep` on a new LocalCluster of
  ``--workers`` processes, rows written to a temporary Parquet store; wall
  time of the whole call (cluster start, worker imports and kernel loading
  included), and also from the first submission to the last result (from the
  rows' timestamps).

Printed: both wall times, the ratio ``sweep wall / (serial wall / workers)``
(target ≤ 1.3) and the overhead per run, ``sweep wall × workers / runs −
mean run time`` with the mean run time taken from the rows (measured inside
the workers), target ≤ 50 ms; also the rows' mean queue and result-return
times. The metrics of every run are checked against the serial ones (timings
excluded): equal to a relative 1e-9, and the number of bit-equal rows is printed
(the tracker's results can differ in the last bits with the process's history of
earlier runs; see benchmarks/RESULTS.md).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import tempfile
import time

from jointtrack.sweep import ResultStore, parse_spec, run_cell, run_sweep
from jointtrack.sweep.cell import TIMING_METRICS


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--scans", type=int, default=None, help="n_scans of Bojilov (default 81)")
    ap.add_argument("--out", default=None, help="also write the numbers as JSON")
    args = ap.parse_args(argv)
    if args.runs < 1 or args.workers < 1:
        raise SystemExit("--runs and --workers must be >= 1")
    scenario = {"name": "bojilov"}
    if args.scans is not None:
        scenario["n_scans"] = args.scans
    spec = parse_spec({"sweep": {"seeds": args.runs}, "scenario": scenario})
    runs = spec.runs()
    print(f"{len(runs)} runs of {scenario}, {args.workers} workers, load {os.getloadavg()}")

    run_cell(runs[0].params, runs[0].seed)  # warm-up: kernels loaded, not timed
    t0 = time.perf_counter()
    serial = {r.run_id: run_cell(r.params, r.seed) for r in runs}
    serial_wall = time.perf_counter() - t0
    serial_mean = statistics.fmean(v["run_seconds"] for v in serial.values())
    print(f"serial: {serial_wall:.2f} s, mean run {1000 * serial_mean:.1f} ms")

    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        outcome = run_sweep(spec, tmp, workers=args.workers)
        wall = time.perf_counter() - t0
        rows = ResultStore(outcome.results).read_rows()
    assert outcome.complete and len(rows) == len(runs), outcome
    exact, worst = 0, 0.0
    for row in rows:
        want = {
            f"metric.{k}": v
            for k, v in serial[row["run_id"]]["metrics"].items()
            if k not in TIMING_METRICS
        }
        got = {k: row[k] for k in want}
        exact += got == want
        for k, v in want.items():
            if v is None or got[k] is None:
                assert v is None and got[k] is None, (row["run_id"], k, got[k], v)
            else:
                assert math.isclose(got[k], v, rel_tol=1e-9, abs_tol=1e-12), (row["run_id"], k)
                worst = max(worst, abs(got[k] - v) / max(abs(v), 1e-300))
    busy = max(r["finished_at"] for r in rows) - min(r["submitted_at"] for r in rows)
    mean_run = statistics.fmean(r["run_seconds"] for r in rows)
    ideal = serial_wall / args.workers
    overhead = wall * args.workers / len(runs) - mean_run
    overhead_busy = busy * args.workers / len(runs) - mean_run
    result = {
        "runs": len(runs),
        "workers": outcome.workers,
        "scenario": scenario,
        "serial_seconds": serial_wall,
        "serial_mean_run_ms": 1000 * serial_mean,
        "sweep_seconds": wall,
        "sweep_submit_to_last_seconds": busy,
        "ratio": wall / ideal,
        "ratio_submit_to_last": busy / ideal,
        "worker_mean_run_ms": 1000 * mean_run,
        "overhead_per_run_ms": 1000 * overhead,
        "overhead_per_run_submit_to_last_ms": 1000 * overhead_busy,
        "mean_result_return_ms": 1000
        * statistics.fmean(
            r["overhead_seconds"] for r in rows if r["overhead_seconds"] is not None
        ),
        "rows_bit_equal_serial": exact,
        "max_relative_difference": worst,
        "load_after": os.getloadavg(),
    }
    print(
        f"sweep: {wall:.2f} s (submit to last result {busy:.2f} s); serial / {args.workers} = "
        f"{ideal:.2f} s"
    )
    print(
        f"ratio sweep / (serial / {args.workers}) = {result['ratio']:.3f} "
        f"(submit to last: {result['ratio_submit_to_last']:.3f}); target <= 1.3: "
        f"{'PASS' if result['ratio'] <= 1.3 else 'FAIL'}"
    )
    print(
        f"overhead per run = wall x workers / runs - mean run time in the workers "
        f"({result['worker_mean_run_ms']:.1f} ms) = {result['overhead_per_run_ms']:.1f} ms "
        f"(submit to last: {result['overhead_per_run_submit_to_last_ms']:.1f} ms); target "
        f"<= 50 ms: {'PASS' if result['overhead_per_run_ms'] <= 50 else 'FAIL'}; result "
        f"return per run {result['mean_result_return_ms']:.1f} ms"
    )
    print(
        f"metrics vs the serial runs (timings excluded): {exact} of {len(rows)} rows bit-equal, "
        f"max relative difference {worst:.1e} (checked <= 1e-9)"
    )
    if args.out:
        with open(args.out, "w", encoding="utf-8") as fh:
            json.dump(result, fh, indent=2)
    return result


if __name__ == "__main__":
    main()
