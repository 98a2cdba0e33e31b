"""Per-call time of Murty's k-best ranking: the compiled kernel against the pre-change baseline.

``jointtrack.association.kbest.kbest_hypotheses`` now runs Murty's partition loop in
one numba kernel on the package's LSAP kernel. The PRE-CHANGE BASELINE below (a Python
heap loop calling the public ``linear_assignment`` per Murty subproblem) is a verbatim
copy of the implementation it replaced, kept here only to measure the speed-up in the
same run; nothing else uses it. Clusters are random N × M likelihood-ratio matrices
(L = 5·U[0,1] with ~20 % ungated zeros, miss ~ U[0.05, 0.5]); each reported time is the
median over clusters of the best of ``--repeat`` timings, and both implementations must
return identical events, log weights and ``exhausted`` flags on every cluster.

    python benchmarks/kbest_speed.py [--clusters 5] [--repeat 5] [--seed 0]
"""

from __future__ import annotations

import argparse
import heapq
import time

import numpy as np

from jointtrack.assignment import linear_assignment
from jointtrack.assignment._checks import as_int
from jointtrack.association._validate import NO_FEASIBLE_EVENT, check_cluster
from jointtrack.association.kbest import KBestHypotheses, kbest_hypotheses
from jointtrack.errors import InfeasibleAssignmentError

# --------------------------------------------------------------------------- pre-change baseline
# Verbatim copy of jointtrack.association.kbest before the compiled kernel (commit e52caa0).


def _baseline_augmented_cost(L, miss) -> np.ndarray:
    n, m = L.shape
    C = np.full((n, m + n), np.inf)
    with np.errstate(divide="ignore"):
        C[:, :m] = np.where(L > 0, -np.log(np.where(L > 0, L, 1.0)), np.inf)
        C[np.arange(n), m + np.arange(n)] = np.where(
            miss > 0, -np.log(np.where(miss > 0, miss, 1.0)), np.inf
        )
    return C


def _baseline_solve(C, forced, forbidden):
    C = C.copy()
    for r, c in forbidden:
        C[r, c] = np.inf
    for r, c in forced:
        keep = C[r, c]
        C[r, :] = np.inf
        C[:, c] = np.inf
        C[r, c] = keep
    if not np.isfinite(C).any(axis=1).all():
        return None
    try:
        res = linear_assignment(C)
    except InfeasibleAssignmentError:
        return None
    rows, cols = res.rows, res.cols
    cost = C[rows, cols]
    if not np.all(np.isfinite(cost)):
        return None
    return float(cost.sum()), cols


def baseline_kbest_hypotheses(L, miss, *, k: int = 100) -> KBestHypotheses:
    """PRE-CHANGE BASELINE of ``kbest_hypotheses`` (Python heap loop over the public LSAP)."""
    L, miss = check_cluster(L, miss)
    k = as_int(k, "k", minimum=1)
    n, m = L.shape
    if n == 0:
        return KBestHypotheses(np.zeros((1, 0), dtype=np.int64), np.zeros(1), k > 1)
    C = _baseline_augmented_cost(L, miss)
    root = _baseline_solve(C, (), ())
    if root is None:
        raise InfeasibleAssignmentError(NO_FEASIBLE_EVENT)
    counter = 0
    heap = [(root[0], counter, root[1], (), ())]
    out_cols = []
    while heap and len(out_cols) < k:
        cost, _, cols, forced, forbidden = heapq.heappop(heap)
        out_cols.append(cols)
        if len(out_cols) == k:
            break
        forced_rows = {r for r, _ in forced}
        free = [r for r in range(n) if r not in forced_rows]
        new_forced = list(forced)
        for r in free:
            child = _baseline_solve(C, new_forced, (*forbidden, (r, int(cols[r]))))
            if child is not None:
                counter += 1
                heapq.heappush(
                    heap,
                    (
                        child[0],
                        counter,
                        child[1],
                        tuple(new_forced),
                        (*forbidden, (r, int(cols[r]))),
                    ),
                )
            new_forced.append((r, int(cols[r])))
    cols = np.array(out_cols, dtype=np.int64)
    beta_cols = np.where(cols < m, cols + 1, 0)
    logL = np.log(np.where(L > 0, L, 1.0))
    with np.errstate(divide="ignore"):
        logm = np.log(miss)
    rows = np.arange(n)
    lw = np.where(cols < m, logL[rows, np.minimum(cols, m - 1)] if m else 0.0, logm[rows]).sum(
        axis=1
    )
    order = np.argsort(-lw, kind="stable")
    return KBestHypotheses(
        assignments=beta_cols[order], log_weights=lw[order], exhausted=len(out_cols) < k
    )


# --------------------------------------------------------------------------- timing


def _cluster(rng, n, m):
    L = 5.0 * rng.uniform(size=(n, m))
    L[rng.uniform(size=(n, m)) < 0.2] = 0.0  # a few ungated pairs
    return L, rng.uniform(0.05, 0.5, n)


def _best_time(fn, repeat, min_seconds=0.02):
    """Best over ``repeat`` rounds of the mean per-call time (each round ≥ ``min_seconds``)."""
    calls = 1
    while True:
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        dt = time.perf_counter() - t0
        if dt >= min_seconds:
            break
        calls *= 2
    best = dt / calls
    for _ in range(repeat - 1):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        best = min(best, (time.perf_counter() - t0) / calls)
    return best


def _same(a, b):
    return (
        np.array_equal(a.assignments, b.assignments)
        and np.array_equal(a.log_weights, b.log_weights)
        and a.exhausted == b.exhausted
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clusters", type=int, default=5, help="random clusters per size")
    parser.add_argument("--repeat", type=int, default=5, help="timing rounds (best is kept)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    t0 = time.perf_counter()
    kbest_hypotheses(np.ones((2, 2)), np.full(2, 0.5), k=3)  # compile or load the kernel
    print(f"first call (numba compile or cache load): {time.perf_counter() - t0:.2f} s")
    print(f"{'N×M':>6} {'k':>4} {'events':>7} {'baseline ms':>12} {'new ms':>9} {'speed-up':>9}")
    for n, m in ((4, 10), (6, 15)):
        clusters = [_cluster(rng, n, m) for _ in range(args.clusters)]
        for k in (1, 5, 50, 200):
            old_t, new_t, ratios, sizes = [], [], [], []
            for L, miss in clusters:
                old = baseline_kbest_hypotheses(L, miss, k=k)
                new = kbest_hypotheses(L, miss, k=k)
                if not _same(old, new):
                    raise SystemExit(f"results differ on a {n}×{m} cluster at k = {k}")
                sizes.append(len(new.log_weights))
                to = _best_time(
                    lambda L=L, miss=miss, k=k: baseline_kbest_hypotheses(L, miss, k=k), args.repeat
                )
                tn = _best_time(
                    lambda L=L, miss=miss, k=k: kbest_hypotheses(L, miss, k=k), args.repeat
                )
                old_t.append(to)
                new_t.append(tn)
                ratios.append(to / tn)
            print(
                f"{n}×{m:<4} {k:>4} {int(np.median(sizes)):>7} {1e3 * np.median(old_t):>12.3f} "
                f"{1e3 * np.median(new_t):>9.4f} {np.median(ratios):>8.1f}×"
            )
    print("identical assignments, log weights and exhausted flags on every cluster")


if __name__ == "__main__":
    main()
