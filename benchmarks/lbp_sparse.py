"""The sparse LBP tier (``lbp_pair_marginals``) and the dense LBP: time and error, before/after.

Issue 31, item 12: the sparse tier's floor (factors raised to 2^-400 of their
track's largest) moved β once likelihood/miss ratios passed ~1e120; its messages
are now split floats (mantissa and power-of-two exponent), which cost more per
message. Workloads, each on the tree being timed:

* ``sparse scene``: DESIGN.md's sparse scene (``jointtrack.bench.association.
  sparse_scene()``: 200 targets on a line, 2 detections each, Poisson clutter,
  overlapping gates), all of its gated pairs in one ``lbp_pair_marginals`` call;
* ``sparse scene, ratios ×1e130``: the same with every likelihood ratio ×1e130
  (a clutter density 1e130 times smaller: ratios ≥ 1e120 against miss = 0.109,
  the issue's regime);
* ``sparse scene, 2000 targets``: ``sparse_scene(n=2000)``, its pairs in one call;
* ``chain 2001×2000``: track i gates measurements i−1 and i (L = 2, miss = 0.1),
  the cluster of ``tests/test_issue22_scale`` that the dense LBP refuses;
* ``random pairs, 20 sweeps``: 20,000 tracks and measurements, ~71,000 pairs
  (each track gates measurements within ±3 of its index, L ~ Exp(2), miss = 0.1),
  exactly 20 sweeps: the cost of one message update (pair × sweep), which the
  budget's ``MAX_LBP_WORK`` caps;
* ``dense 20/40``: ``lbp_marginals`` on DESIGN.md's 20×40 cluster
  (L = 5·U[0,1], miss = 0.1);
* ``tracker-like, ratios ≥ 1e120``: the 400 clusters of
  ``tests/test_lbp_sparse.py`` (2–6 tracks on a line, P_D = 0.9, clutter density
  10^-U(120, 300)), one ``lbp_pair_marginals`` call each (time: all 400); the
  error is over the cycle-free ones, where BP is exact, and the count of
  clusters whose β is ≥ 0.1 from the dense ``lbp_marginals`` β is printed.

Each workload: best CPU time (``time.process_time``; the machine may be shared)
of ``--calls`` calls after one untimed warm-up call, sweeps, and the largest
|β − β_exact| (exact: ``exact_jpda`` of the same tree, the assignment engine).
``--against DIR [DIR ...]`` runs other source trees (``PYTHONPATH=DIR``) in fresh
interpreters, interleaved with this one over ``--repeats`` rounds; the median of
each tree's best times is printed with the ratio to this tree::

    git worktree add /tmp/before ef50439
    PYTHONPATH=src python benchmarks/lbp_sparse.py --against /tmp/before/src
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


def _best(fn, calls: int) -> float:
    fn()
    best = np.inf
    for _ in range(calls):
        t = time.process_time()
        fn()
        best = min(best, time.process_time() - t)
    return best


def _pairs(L):
    rows, cols = np.nonzero(L)
    return rows, cols, L[rows, cols]


def _pair_workload(L, miss, calls, exact=True, **kw):
    from jointtrack.association import exact_jpda
    from jointtrack.association.lbp import lbp_pair_marginals

    rows, cols, vals = _pairs(L)

    def call():
        return lbp_pair_marginals(rows, cols, vals, miss, L.shape[1], **kw)

    t = _best(call, calls)
    beta0, pair_beta, info = call()
    out = {"s": t, "sweeps": info.iterations, "pairs": int(rows.size)}
    if exact:
        ref = exact_jpda(L, miss).beta
        err = max(np.abs(beta0 - ref[:, 0]).max(), np.abs(pair_beta - ref[rows, cols + 1]).max())
        out["err"] = float(err)
    return out


def run_once(calls: int) -> dict:
    """Every workload on the tree jointtrack is imported from."""
    from jointtrack.association import exact_jpda
    from jointtrack.association.lbp import lbp_marginals
    from jointtrack.bench.association import dense_cluster, sparse_scene

    res = {}
    L, miss, _ = sparse_scene()
    res["sparse scene"] = _pair_workload(L, miss, calls)
    res["sparse scene, ratios ×1e130"] = _pair_workload(L * 1e130, miss, calls)
    L2, miss2, _ = sparse_scene(n=2000)
    res["sparse scene, 2000 targets"] = _pair_workload(L2, miss2, max(1, calls // 3))
    n, m = 2001, 2000
    i, j = np.arange(n)[:, None], np.arange(m)[None, :]
    chain = np.where((j == i) | (j == i - 1), 2.0, 0.0)
    res["chain 2001×2000"] = _pair_workload(chain, np.full(n, 0.1), max(1, calls // 3))
    rng = np.random.default_rng(0)
    N, P = 20_000, 100_000
    r = rng.integers(0, N, P)
    c = np.clip(r + rng.integers(-3, 4, P), 0, N - 1)
    key = np.unique(r * N + c)
    from jointtrack.association.lbp import lbp_pair_marginals

    r, c = key // N, key % N
    vals = rng.exponential(2.0, r.size)

    def random_pairs():
        return lbp_pair_marginals(r, c, vals, np.full(N, 0.1), N, max_iter=20, tol=1e-300)

    t = _best(random_pairs, max(1, calls // 3))
    res["random pairs, 20 sweeps"] = {
        "s": t,
        "sweeps": random_pairs()[2].iterations,
        "pairs": int(r.size),
        "ns_per_update": t / (20 * r.size) * 1e9,
    }
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from test_lbp_sparse import is_forest, sparse_beta, tracker_cluster

    rng = np.random.default_rng(0)
    cl = [tracker_cluster(rng, 10.0 ** -rng.uniform(120, 300)) for _ in range(400)]
    cl = [(Lc, mc) for Lc, mc in cl if (Lc > 0).any()]
    t = _best(lambda: [sparse_beta(Lc, mc) for Lc, mc in cl], max(1, calls // 3))
    err, moved, sweeps = 0.0, 0, 0
    for Lc, mc in cl:
        beta, info = sparse_beta(Lc, mc)
        sweeps = max(sweeps, info.iterations)
        moved += int(np.abs(beta - lbp_marginals(Lc, mc)[0]).max() >= 0.1)
        if is_forest(Lc):
            err = max(err, float(np.abs(beta - exact_jpda(Lc, mc).beta).max()))
    res["tracker-like, ratios ≥ 1e120"] = {
        "s": t,
        "sweeps": sweeps,
        "pairs": int(sum((Lc > 0).sum() for Lc, _ in cl)),
        "err": err,
        "moved": moved,
    }
    Ld, missd = dense_cluster(20, 40)
    t = _best(lambda: lbp_marginals(Ld, missd), calls)
    beta, info = lbp_marginals(Ld, missd)
    res["dense 20/40 (lbp_marginals)"] = {
        "s": t,
        "sweeps": info.iterations,
        "pairs": 800,
        "err": float(np.abs(beta - exact_jpda(Ld, missd).beta).max()),
    }
    return res


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=9, help="timed calls per workload")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", action="store_true", help="one JSON line (used by --against)")
    parser.add_argument("--against", nargs="+", default=[], metavar="DIR")
    args = parser.parse_args()
    if args.json:
        print(json.dumps(run_once(args.calls)))
        return
    here = str(Path(__import__("jointtrack").__file__).parents[1])
    trees = [here, *args.against]
    cmd = [sys.executable, __file__, "--json", "--calls", str(args.calls)]
    runs: dict[str, list[dict]] = {tree: [] for tree in trees}
    for _ in range(args.repeats):
        for tree in trees:  # interleaved: load drift on a shared machine hits all alike
            env = {**os.environ, "PYTHONPATH": tree}
            out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
            runs[tree].append(json.loads(out.stdout.strip().splitlines()[-1]))
    print(f"best CPU time of {args.calls} calls, median of {args.repeats} interleaved runs")
    head = "| workload | pairs | " + " | ".join(
        f"{tree}: ms (sweeps, max abs(β − β_exact))" for tree in trees
    )
    if len(trees) > 1:
        head += " | " + " | ".join(f"{tree} / {here}" for tree in trees[1:])
    print(head + " |")
    print("|---" * (2 + len(trees) + len(trees) - 1) + "|")
    for name in runs[here][0]:
        med = {tree: statistics.median(r[name]["s"] for r in runs[tree]) for tree in trees}
        cells = [name, str(runs[here][0][name]["pairs"])]
        for tree in trees:
            last = runs[tree][-1][name]
            err = f", {last['err']:.1e}" if "err" in last else ""
            cells.append(f"{med[tree] * 1e3:.2f} ({last['sweeps']}{err})")
        cells += [f"{med[tree] / med[here]:.2f}" for tree in trees[1:]]
        print("| " + " | ".join(cells) + " |")
    for tree in trees:
        moved = runs[tree][-1]["tracker-like, ratios ≥ 1e120"]["moved"]
        print(f"{tree}: tracker-like clusters with β ≥ 0.1 from the dense LBP's: {moved}")
    for tree in trees:
        ns = statistics.median(r["random pairs, 20 sweeps"]["ns_per_update"] for r in runs[tree])
        print(f"{tree}: {ns:.0f} ns per message update (pair × sweep)")


if __name__ == "__main__":
    main()
