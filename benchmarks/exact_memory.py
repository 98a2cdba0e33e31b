"""Dense JPDA 24×48 (DESIGN canonical: L = 5·U[0,1), miss 0.1): old vs new code, same run.

Each measurement is a fresh Python process whose ``PYTHONPATH`` selects the source
tree (``--tree NAME=PATH[@MAX_MEMORY][+serial]``, given twice or more: a
configuration may set its own ``max_memory`` in bytes and ``parallel=False``). The
configurations are alternated (old, new, old, new, …) for ``--rounds`` rounds, with
``uptime`` printed before and after. Every process first solves a 16×32 cluster with
the same call (numba code loaded or compiled, not timed), then times the 24×48
solve: wall time, process CPU time (``time.process_time``), peak RSS
(``resource.getrusage(RUSAGE_SELF).ru_maxrss``, whole process) and the DP's own
``state_bytes``. ``--threads 1`` sets ``NUMBA_NUM_THREADS=1`` (one core). The β of
every run is compared with the first configuration's first β in the same run (max
absolute difference).

    python benchmarks/exact_memory.py --tree old=/tmp/orig-exact/src@3221225472 \
        --tree new=src@2147483648 --rounds 3
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

_CHILD = r"""
import json, resource, sys, time
import numpy as np
from jointtrack.assignment import assignment_sum
mem = {mem}
def cluster(n, m, seed=0):
    rng = np.random.default_rng(seed)
    return 5 * rng.random((n, m)), np.full(n, 0.1)
L, miss = cluster(16, 32)
assignment_sum(L, miss, parallel={parallel}, max_memory=mem)
L, miss = cluster({n}, {m})
rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
c0 = time.process_time(); t0 = time.perf_counter()
r = assignment_sum(L, miss, parallel={parallel}, max_memory=mem)
t1 = time.perf_counter(); c1 = time.process_time()
np.save({out!r}, r.beta)
print(json.dumps(dict(wall=t1 - t0, cpu=c1 - c0, rss0_kib=rss0,
    peak_kib=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
    state_bytes=int(r.info.get("state_bytes", -1)), logZ=r.log_normalizer)))
"""


def _uptime():
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def run_one(src, n, m, mem, parallel, threads, out):
    env = dict(os.environ, PYTHONPATH=os.path.abspath(src))
    if threads:
        env["NUMBA_NUM_THREADS"] = str(threads)
    code = _CHILD.format(n=n, m=m, mem=mem, parallel=parallel, out=out)
    proc = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=3600
    )
    if proc.returncode:
        return {"error": (proc.stderr.strip().splitlines() or ["?"])[-1]}
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tree", action="append", required=True, help="NAME=PATH of a src tree")
    ap.add_argument("--memory", type=int, default=3 * 2**30, help="max_memory in bytes")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--threads", type=int, default=0, help="NUMBA_NUM_THREADS (0: default)")
    ap.add_argument("--serial", action="store_true", help="parallel=False")
    ap.add_argument("--size", default="24x48")
    args = ap.parse_args(argv)
    n, m = (int(v) for v in args.size.split("x"))
    trees = []
    for spec in args.tree:
        name, rest = spec.split("=", 1)
        serial = rest.endswith("+serial")
        rest = rest.removesuffix("+serial")
        path, _, mem = rest.partition("@")
        trees.append((name, (path, int(mem) if mem else args.memory, serial or args.serial)))
    print(
        "uptime before:", subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    )
    ref = None
    rows = {name: [] for name, _ in trees}
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.rounds):
            for name, (src, mem, serial) in trees:
                out = os.path.join(tmp, "beta.npy")
                r = run_one(src, n, m, mem, not serial, args.threads, out)
                if "error" not in r:
                    beta = np.load(out)
                    if ref is None:
                        ref = beta
                    r["max_dbeta"] = float(np.abs(beta - ref).max())
                rows[name].append(r)
                print(f"round {k} {name}: {json.dumps(r)}", flush=True)
    print(
        "uptime after:", subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    )
    base = trees[0][0]
    for name, _ in trees:
        ok = [r for r in rows[name] if "error" not in r]
        if not ok:
            print(f"{name}: every run failed")
            continue
        wall = [r["wall"] for r in ok]
        cpu = [r["cpu"] for r in ok]
        peak = [r["peak_kib"] / 2**20 for r in ok]
        line = (
            f"{name}: wall {', '.join(f'{w:.2f}' for w in wall)} s; cpu "
            f"{', '.join(f'{c:.1f}' for c in cpu)} s; peak RSS "
            f"{', '.join(f'{p:.2f}' for p in peak)} GiB; "
            f"max |Δβ| {max(r['max_dbeta'] for r in ok):.1e}"
        )
        bok = [r for r in rows[base] if "error" not in r]
        if name != base and bok:
            ratio = [b["wall"] / r["wall"] for b, r in zip(bok, ok, strict=False)]
            line += f"; {base}/{name} wall per round {', '.join(f'{x:.2f}' for x in ratio)}"
        print(line)


if __name__ == "__main__":
    main()
