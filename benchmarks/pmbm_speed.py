"""PMBM on the coalescence scene: steps/s and CPU per step, old code against new (issue 34).

Each side runs in its own subprocess with ``PYTHONPATH`` at a source tree (``--old``:
e.g. a worktree of the commit before the change; ``--new``: this tree's ``src``),
builds :class:`~jointtrack.trackers.pmbm.PMBMTracker` as ``benchmarks/coalescence.py``
does (the paper's model, 200 global hypotheses, the scenario's gate P_G = 0.99),
compiles its kernels on a 5-step scene outside the timing, then steps through the
detections of coalescence seeds 0..N−1 and reports per seed: wall and CPU seconds
(``time.perf_counter``, ``time.process_time``) of the ``step`` calls, the GOSPA of
every step (c = 10, p = 2, α = 2) and a digest of the reported ids and states.

The sides alternate (old, new, old, new, …) for ``--rounds`` rounds, with ``uptime``
printed before and after, since the machine is shared; the ratios are of the sums
over the rounds. The GOSPA per step and the estimates of both sides are compared
seed by seed in the same run. ``--gospa-runs N`` then runs the new side alone on
seeds 0..N−1 for the mean GOSPA over N runs.

``--gospa-runs N --gospa-old --rounds 0`` runs both sides once on seeds 0..N−1 and
compares them seed by seed (equality, not speed). ``--phases`` prints the CPU per step
of each part of the new side's step (what remains to be made faster).

Usage: ``python benchmarks/pmbm_speed.py --old /tmp/orig/src [--new src] [--seeds 5]
[--rounds 3] [--gospa-runs 100 [--gospa-old]] [--phases]``
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def worker(seeds: list[int]) -> dict:
    """Run PMBM on the given seeds in this process (``PYTHONPATH`` picks the code)."""
    import numpy as np

    sys.path.insert(0, str(HERE))
    from coalescence import ALPHA, C, P, pmbm_config
    from jointtrack.metrics import gospa
    from jointtrack.scenarios import coalescence
    from jointtrack.trackers.pmbm import PMBMTracker

    def run(sc):
        trk = PMBMTracker(pmbm_config(sc), keep_history=False)
        wall = cpu = 0.0
        per_step, digest = [], hashlib.sha256()
        for t, z, truth in zip(sc.times, sc.detections, sc.truth_states, strict=True):
            w0, c0 = time.perf_counter(), time.process_time()
            res = trk.step(t, z)
            wall += time.perf_counter() - w0
            cpu += time.process_time() - c0
            per_step.append(gospa(truth[:, :2], res.x[:, :2], c=C, p=P, alpha=ALPHA).total)
            digest.update(np.ascontiguousarray(res.ids, np.int64).tobytes())
            digest.update(np.ascontiguousarray(res.x, float).tobytes())
        return wall, cpu, per_step, digest.hexdigest()

    run(coalescence(10_000, n_steps=5))  # compile (or load) the kernels
    out = {}
    for s in seeds:
        wall, cpu, per_step, digest = run(coalescence(s))
        out[s] = {"wall": wall, "cpu": cpu, "steps": len(per_step), "gospa": per_step,
                  "digest": digest}  # fmt: skip
    return out


#: what ``--phases`` times: PMBMTracker methods (its step and the parts of it) and the
#: module-level functions it calls (the compiled kernels' wrappers among them); the
#: times of nested parts are inside their callers'
PHASES = ("_step", "_hypotheses_after", "_children", "_recycle", "_estimate",
          "_gate_set", "_pair_weights", "_poisson_detection", "_thin_and_prune_poisson",
          "_predict_set", "_predict_poisson", "_labelled_scan", "_check_scan")  # fmt: skip
KERNELS = ("check_pair_weights", "track_clusters", "rank_tuples", "combine_events",
           "merge_identical", "distinct_rows", "connected_components", "_tuple_costs")  # fmt: skip


def phases(seeds: list[int]) -> None:
    """CPU ms per step in each part of the PMBM step (this process' code), to show
    where the time goes: each part wrapped with ``time.process_time``."""
    import collections

    sys.path.insert(0, str(HERE))
    import jointtrack.trackers.pmbm as pmbm
    from coalescence import pmbm_config
    from jointtrack.scenarios import coalescence

    spent = collections.Counter()

    def timed(owner, name):
        real = getattr(owner, name)

        def wrapper(*args, **kwargs):
            t0 = time.process_time()
            try:
                return real(*args, **kwargs)
            finally:
                spent[name] += time.process_time() - t0

        setattr(owner, name, wrapper)

    for name in PHASES:
        timed(pmbm.PMBMTracker, name)
    for name in KERNELS:
        if hasattr(pmbm, name):
            timed(pmbm, name)

    def run(sc):
        trk = pmbm.PMBMTracker(pmbm_config(sc), keep_history=False)
        for t, z in zip(sc.times, sc.detections, strict=True):
            trk.step(t, z)
        return len(sc.times)

    run(coalescence(10_000, n_steps=5))
    spent.clear()
    t0 = time.process_time()
    steps = sum(run(coalescence(s)) for s in seeds)
    total = time.process_time() - t0
    print(f"CPU per step, seeds {seeds[0]}..{seeds[-1]}: {1e3 * total / steps:.2f} ms in all")
    for name, sec in spent.most_common():
        kind = "module function" if name in KERNELS else "PMBMTracker method"
        print(f"  {name:28s} {1e3 * sec / steps:6.2f} ms ({kind})")


def side(src: str, seeds: list[int]) -> dict:
    env = dict(os.environ, PYTHONPATH=str(Path(src).resolve()))
    cmd = [sys.executable, __file__, "--worker", ",".join(map(str, seeds))]
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"worker on {src} failed:\n{done.stderr}")
    return {int(k): v for k, v in json.loads(done.stdout.splitlines()[-1]).items()}


def uptime() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True, check=False).stdout.strip()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worker", default="", help=argparse.SUPPRESS)
    ap.add_argument("--old", help="source tree of the old code (its src directory)")
    ap.add_argument("--new", default=str(HERE.parent / "src"), help="source tree of the new code")
    ap.add_argument("--seeds", type=int, default=5, help="coalescence seeds 0..N-1 per round")
    ap.add_argument("--rounds", type=int, default=3, help="alternated old/new rounds (≥ 3)")
    ap.add_argument("--gospa-runs", type=int, default=0, help="new side alone: mean GOSPA")
    ap.add_argument("--gospa-old", action="store_true",
                    help="with --gospa-runs: the old side too, compared seed by seed")  # fmt: skip
    ap.add_argument("--phases", action="store_true", help="CPU per part of the step (--new)")
    args = ap.parse_args(argv)
    if args.worker:
        print(json.dumps(worker([int(s) for s in args.worker.split(",")])))
        return 0
    if args.phases:
        env = dict(os.environ, PYTHONPATH=str(Path(args.new).resolve()))
        code = f"import sys; sys.path.insert(0, {str(HERE)!r}); import pmbm_speed; "
        code += f"pmbm_speed.phases(list(range({args.seeds})))"
        return subprocess.run([sys.executable, "-c", code], env=env, check=False).returncode
    if not args.old:
        ap.error("--old is required")
    if args.rounds < 1:
        return gospa_runs(args)
    seeds = list(range(args.seeds))
    print("before:", uptime())
    totals = {"old": [0.0, 0.0, 0], "new": [0.0, 0.0, 0]}
    results = {}
    mismatch = []
    for r in range(args.rounds):
        for name, src in (("old", args.old), ("new", args.new)):
            res = side(src, seeds)
            wall = sum(v["wall"] for v in res.values())
            cpu = sum(v["cpu"] for v in res.values())
            steps = sum(v["steps"] for v in res.values())
            for i, v in enumerate((wall, cpu, steps)):
                totals[name][i] += v
            print(f"round {r + 1} {name}: {steps / wall:7.1f} steps/s wall, "
                  f"{1e3 * cpu / steps:6.2f} ms CPU/step ({steps} steps)", flush=True)  # fmt: skip
            if name in results and any(
                results[name][s]["digest"] != res[s]["digest"] for s in seeds
            ):
                mismatch.append(f"{name} differs between rounds")
            results[name] = res
    print("after: ", uptime())
    old, new = totals["old"], totals["new"]
    rate_old, rate_new = old[2] / old[0], new[2] / new[0]
    cpu_old, cpu_new = old[1] / old[2], new[1] / new[2]
    print(f"old: {rate_old:.1f} steps/s wall, {1e3 * cpu_old:.2f} ms CPU/step, "
          f"{1 / cpu_old:.1f} steps per CPU-second")  # fmt: skip
    print(f"new: {rate_new:.1f} steps/s wall, {1e3 * cpu_new:.2f} ms CPU/step, "
          f"{1 / cpu_new:.1f} steps per CPU-second")  # fmt: skip
    print(f"new / old: {rate_new / rate_old:.2f}× steps/s wall, {cpu_old / cpu_new:.2f}× less CPU")
    same_gospa = same_tracks = 0
    worst = 0.0
    for s in seeds:
        a, b = results["old"][s], results["new"][s]
        same_gospa += a["gospa"] == b["gospa"]
        same_tracks += a["digest"] == b["digest"]
        worst = max(worst, abs(sum(a["gospa"]) - sum(b["gospa"])) / len(a["gospa"]))
    print(f"seeds 0..{len(seeds) - 1}: GOSPA per step identical on {same_gospa}/{len(seeds)}, "
          f"ids and states identical on {same_tracks}/{len(seeds)}; largest |Δ mean GOSPA| "
          f"{worst:.3g}")  # fmt: skip
    for s in seeds:
        a, b = results["old"][s], results["new"][s]
        n = len(a["gospa"])
        print(f"  seed {s}: mean GOSPA old {sum(a['gospa']) / n:.6f} new {sum(b['gospa']) / n:.6f}")
    for m in mismatch:
        print("warning:", m)
    status = gospa_runs(args) if args.gospa_runs else 0
    return 1 if same_gospa < len(seeds) else status


def gospa_runs(args) -> int:
    """Mean GOSPA of the new side over seeds 0..N−1 (and the old side's, seed by seed)."""
    seeds = list(range(args.gospa_runs))
    sides = [("new", args.new)] + ([("old", args.old)] if args.gospa_old else [])
    out = {}
    for name, src in sides:
        t0 = time.perf_counter()
        res = out[name] = side(src, seeds)
        means = [sum(v["gospa"]) / len(v["gospa"]) for v in res.values()]
        n = len(means)
        mean = sum(means) / n
        se = (sum((m - mean) ** 2 for m in means) / (n - 1) / n) ** 0.5 if n > 1 else 0.0
        steps = sum(v["steps"] for v in res.values())
        print(f"{name}, {n} runs (seeds 0..{n - 1}): mean GOSPA {mean:.4f} ± {se:.4f}, "
              f"{steps / sum(v['wall'] for v in res.values()):.1f} steps/s wall, "
              f"{steps / sum(v['cpu'] for v in res.values()):.1f} steps per CPU-second "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)  # fmt: skip
    print("after GOSPA runs:", uptime())
    if "old" in out:
        same = sum(out["old"][s]["gospa"] == out["new"][s]["gospa"] for s in seeds)
        tracks = sum(out["old"][s]["digest"] == out["new"][s]["digest"] for s in seeds)
        n = len(seeds)
        print(f"old vs new, seeds 0..{n - 1}: GOSPA per step identical on {same}/{n}, "
              f"ids and states identical on {tracks}/{n}")  # fmt: skip
        return 0 if same == n else 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
