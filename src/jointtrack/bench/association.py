"""JPDA association engine vs Stone Soup 1.9.1 and pyehm, all in one run.

Run as ``jointtrack bench association [--quick] [--out FILE]`` or
``python benchmarks/association.py``. Peers are optional (``pip install
stonesoup==1.9.1 pyehm``); a missing peer is reported as "not installed".

Workloads (DESIGN.md)
---------------------
* **dense clusters** (N, M) = (5,10), (8,16), (10,20), (12,24), (16,32), (20,40):
  ``rng = default_rng(0)``, ``L = 5*rng.random((N, M))``, ``miss = full(N, 0.1)``,
  every entry gated. Timed: our ``exact_jpda(L, miss)`` (median of repeats after
  one warm-up call; includes input validation, folding, dual scaling, planning
  and the forward–backward DP); Stone Soup ``JPDAwithEHM2.associate(tracks,
  detections, timestamp)`` with a hypothesiser that returns prebuilt
  ``SingleProbabilityHypothesis`` objects carrying the same L / miss as
  probabilities (so what is timed is Stone Soup's own clustering, EHM2 tree and
  posterior-hypothesis construction, not any Kalman work); pyehm ``EHM2().run(
  validation_matrix, likelihood_matrix)`` with ``likelihood_matrix = [miss | L]``.
  Peers run once per size (they are slow) in the same process, on the same
  matrices; sizes where a peer would take over a minute are "not run" and the
  anchor measured on this machine (DESIGN.md) is printed instead. Memory: the
  DP state bytes our solver allocates, and the peak RSS of a fresh process that
  solves the cluster (``resource.getrusage``; numba arrays are invisible to
  tracemalloc).
* **LBP at 20/40**: ``lbp_marginals`` (Williams & Lau with a certified stopping
  rule, tol 1e-9) vs Stone Soup ``JPDAwithLBP.associate`` (its n_iterations=1,
  delta=0.001 rule), both with max |beta − exact|.
* **sparse scene**: 200 targets on a line, 2 detections per target, Poisson
  clutter (1 per median gate volume), gates (P_G = 0.99) from 2-D
  constant-velocity Kalman covariances (random process noise ×[0.5, 2],
  0–2 coasting scans). Spacing 1.5 gate widths with the gate width read as the
  median gate's half-width along the line (with the full width, gates never
  overlap and every cluster is a single track; that variant is reported too).
  Timed: our exact on every cluster (sum of per-cluster calls) and on the whole
  scene matrix in one call; pyehm EHM2 on every cluster; Stone Soup
  JPDAwithEHM2 on the whole scene (it clusters internally).
* **Bojilov Table 2 trend**: clusters of 2..5 targets on parallel, closely
  spaced tracks with Poisson clutter β = 1 and 2 (ten random clusters each);
  ``enumerate`` naive vs incremental multiplication counts, printed beside the
  paper's Table 2 (floating point operations per cluster).

* **large dense cluster 24/48** (DESIGN.md's canonical workload): a fresh
  process runs ``exact_jpda(L, miss, parallel=True)`` at the engine's default
  ``max_memory`` (the budget the tracker uses; issue 34) (and,
  in the full run, the same with ``parallel=False``) and reports its wall time
  and peak RSS (``resource.getrusage``); the parallel and serial β must agree
  to 1e-13 on 16/32 (checked in every run; the 24/48 difference of the full run
  is printed too: its contractions sum 2^24 terms in a different order).

Targets (issue 3, printed PASS/FAIL): 8/16 ≥ 1000× faster than Stone Soup
EHM2 and ≥ 100× faster than pyehm EHM2; 16/32 ≤ 0.1 s; 20/40 ≤ 1 s and
≤ 2 GiB; 24/48 with both cores at the default budget ≤ 5 s and ≤ 1 GiB peak
RSS (issue 34), parallel β =
serial β to 1e-13 on 16/32; sparse scene all clusters ≤ 50 ms; lbp faster than Stone
Soup LBP.
"""

from __future__ import annotations

import datetime
import json
import math
import platform
import statistics
import subprocess
import sys
import time

import numpy as np

from jointtrack.io import to_jsonable

DENSE_SIZES = [(5, 10), (8, 16), (10, 20), (12, 24), (16, 32), (20, 40)]
# peers are run where they finish in about a minute on this machine (anchors in DESIGN.md)
SS_EHM2_SIZES = {(5, 10), (8, 16)}
PYEHM_SIZES_FULL = {(5, 10), (8, 16), (10, 20)}
PYEHM_SIZES_QUICK = {(5, 10), (8, 16)}
ANCHORS = {
    ("stonesoup", (8, 16)): "8.6 s",
    ("stonesoup", (10, 20)): "> 60 s (EHM tree grows ~2^M)",
    ("pyehm", (8, 16)): "0.93 s",
    ("pyehm", (10, 20)): "27 s",
    ("pyehm", (12, 24)): "> 60 s",
}

# Bojilov, Alexiev & Konstantinova, Table 2: floating point operations per cluster
# (targets, beta=1: nonopt, opt, ratio, beta=2: nonopt, opt, ratio) and Table 3 (seconds).
BOJILOV_TABLE2 = {
    2: (207, 184, 1.12, 229, 202, 1.14),
    3: (747, 629, 1.19, 2739, 2189, 1.25),
    4: (7599, 5705, 1.33, 14772, 10937, 1.35),
    5: (35333, 24290, 1.45, 151360, 103598, 1.47),
}
BOJILOV_TABLE3 = {
    3: (0.0225, 0.0213, 1.06, 0.068, 0.0377, 1.8),
    4: (0.423, 0.1, 4.23, 0.51, 0.19, 2.68),
    5: (4.5, 0.438, 10.27, 38.1, 5.71, 6.67),
}

TARGET_SS_RATIO = 1000.0
TARGET_PYEHM_RATIO = 100.0
TARGET_16_32 = 0.1
TARGET_20_40 = 1.0
TARGET_MEMORY = 2 * 1024**3
TARGET_SPARSE = 0.050
BIG = (24, 48)  # DESIGN.md's canonical large dense cluster
TARGET_BIG_TIME = 5.0  # issue 34
TARGET_BIG_RSS = 2**30
TARGET_PAR_DIFF = 1e-13


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------


def _median_time(fn, min_total=0.3, min_reps=3, max_reps=2000):
    fn()
    times = []
    t_start = time.perf_counter()
    while len(times) < min_reps or (
        time.perf_counter() - t_start < min_total and len(times) < max_reps
    ):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), len(times)


def _time_once(fn):
    t = time.perf_counter()
    out = fn()
    return time.perf_counter() - t, out


def _fmt_t(t):
    if t is None:
        return "-"
    if t < 1e-3:
        return f"{t * 1e6:.0f} µs"
    if t < 1:
        return f"{t * 1e3:.2f} ms"
    return f"{t:.2f} s"


def _fmt_b(b):
    return f"{b / 2**20:.1f} MiB"


def dense_cluster(N, M, seed=0):
    rng = np.random.default_rng(seed)
    return 5 * rng.random((N, M)), np.full(N, 0.1)


# ---------------------------------------------------------------------------
# peers
# ---------------------------------------------------------------------------


def _stonesoup_available():
    try:
        import stonesoup  # noqa: F401
    except ImportError:
        return False
    return True


def _pyehm_available():
    try:
        import pyehm.core  # noqa: F401
    except ImportError:
        return False
    return True


class _StoneSoupCluster:
    """Stone Soup objects carrying a plain (L, miss) cluster.

    A Hypothesiser that returns, per track, a prebuilt MultipleHypothesis with
    one SingleProbabilityHypothesis for "missed" (probability miss[i]) and one
    per gated detection (probability L[i, j]); the JPDA associators then run
    their own association code on exactly these numbers.
    """

    def __init__(self, L, miss):
        from stonesoup.base import Property
        from stonesoup.hypothesiser.base import Hypothesiser
        from stonesoup.types.detection import Detection, MissedDetection
        from stonesoup.types.hypothesis import SingleProbabilityHypothesis
        from stonesoup.types.multihypothesis import MultipleHypothesis
        from stonesoup.types.numeric import Probability
        from stonesoup.types.prediction import (
            GaussianMeasurementPrediction,
            GaussianStatePrediction,
        )
        from stonesoup.types.track import Track

        class FixedHypothesiser(Hypothesiser):
            table: dict = Property(doc="track -> MultipleHypothesis")

            def hypothesise(self, track, detections, timestamp, **kwargs):
                return self.table[track]

        ts = datetime.datetime(2024, 1, 1)
        N, M = L.shape
        self.ts = ts
        self.tracks = [Track() for _ in range(N)]
        self.dets = [Detection(np.array([[float(j)]]), timestamp=ts) for j in range(M)]
        pred = GaussianStatePrediction(np.array([[0.0]]), np.array([[1.0]]), timestamp=ts)
        mpred = GaussianMeasurementPrediction(np.array([[0.0]]), np.array([[1.0]]), timestamp=ts)
        table = {}
        for i, tr in enumerate(self.tracks):
            hyps = [
                SingleProbabilityHypothesis(
                    pred,
                    MissedDetection(timestamp=ts),
                    measurement_prediction=mpred,
                    probability=Probability(float(miss[i])),
                )
            ]
            for j in np.flatnonzero(L[i] > 0):
                hyps.append(
                    SingleProbabilityHypothesis(
                        pred,
                        self.dets[j],
                        measurement_prediction=mpred,
                        probability=Probability(float(L[i, j])),
                    )
                )
            table[tr] = MultipleHypothesis(hyps, normalise=False, total_weight=1)
        self.hypothesiser = FixedHypothesiser(table=table)
        self.shape = (N, M)
        self._index = {id(d): j for j, d in enumerate(self.dets)}

    def run(self, cls):
        assoc = cls(hypothesiser=self.hypothesiser)
        t, out = _time_once(lambda: assoc.associate(set(self.tracks), set(self.dets), self.ts))
        beta = np.zeros((self.shape[0], self.shape[1] + 1))
        for i, tr in enumerate(self.tracks):
            for h in out[tr]:
                j = 0 if not h else self._index[id(h.measurement)] + 1
                beta[i, j] = float(h.probability)
        return t, beta


def _pyehm_run(L, miss):
    from pyehm.core import EHM2

    lik = np.column_stack((miss, L))
    val = (lik > 0).astype(int)
    val[:, 0] = 1
    t, beta = _time_once(lambda: EHM2().run(val, lik))
    return t, np.asarray(beta)


_RSS_CODE = """
import resource, numpy as np
from jointtrack.association import exact_jpda

def status(key):
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key):
                return int(line.split()[1]) * 1024
    return None

rng = np.random.default_rng({seed}); L = 5 * rng.random(({N}, {M})); miss = np.full({N}, 0.1)
exact_jpda(L[:4, :8], miss[:4])          # numba code loaded (or compiled) before measuring
try:
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")                     # reset the peak-RSS counter (Linux >= 4.0)
    reset = True
except OSError:
    reset = False
before = status("VmRSS:")
exact_jpda(L, miss)
peak = status("VmHWM:") if reset else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print(before, peak)
"""


def _peak_rss(N, M, seed=0):
    """(RSS before the solve, peak RSS during it) of a fresh process, in bytes."""
    code = _RSS_CODE.format(seed=seed, N=N, M=M)
    try:
        out = subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, timeout=600, check=True
        ).stdout.split()
        return int(out[0]), int(out[1])
    except (subprocess.SubprocessError, ValueError, IndexError):
        return None, None


# ---------------------------------------------------------------------------
# scenes
# ---------------------------------------------------------------------------


def _kalman_innovations(rng, n, sigma_r=1.0, q=0.5):
    """Innovation covariances S = HPHᵀ + R and HPHᵀ of 2-D constant-velocity tracks."""
    F = np.eye(4)
    F[0, 2] = F[1, 3] = 1.0
    G = np.array([[0.5, 0.0], [0.0, 0.5], [1.0, 0.0], [0.0, 1.0]])
    H = np.zeros((2, 4))
    H[0, 0] = H[1, 1] = 1.0
    R = sigma_r**2 * np.eye(2)
    S = np.empty((n, 2, 2))
    HPH = np.empty((n, 2, 2))
    for i in range(n):
        Q = q * np.exp(rng.uniform(np.log(0.5), np.log(2.0))) * G @ G.T
        P = np.diag([10.0, 10.0, 4.0, 4.0])
        for _ in range(30):
            P = F @ P @ F.T + Q
            K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
            P = (np.eye(4) - K @ H) @ P
        for _ in range(int(rng.integers(0, 3))):
            P = F @ P @ F.T + Q
        P = F @ P @ F.T + Q
        HPH[i] = H @ P @ H.T
        S[i] = HPH[i] + R
    return S, HPH


def sparse_scene(seed=0, n=200, spacing=1.5, width="half", P_D=0.9, P_G=0.99, clutter_per_gate=1.0):
    """DESIGN.md's sparse JPDA scene; returns (L, miss, info)."""
    from scipy import stats

    from jointtrack.association.gating import gate_measurements, likelihood_ratios

    rng = np.random.default_rng(seed)
    S, HPH = _kalman_innovations(rng, n)
    gamma = stats.chi2.ppf(P_G, 2)
    half = math.sqrt(gamma * np.median(S[:, 0, 0]))
    gw = half if width == "half" else 2 * half
    truth = np.column_stack((np.arange(n) * spacing * gw, np.zeros(n)))
    z_pred = truth + np.array([rng.multivariate_normal([0, 0], HPH[i]) for i in range(n)])
    det = [
        truth[i] + rng.multivariate_normal([0, 0], S[i] - HPH[i])
        for i in range(n)
        for _ in range(2)
    ]
    vol_med = math.pi * gamma * math.sqrt(np.linalg.det(np.median(S, axis=0)))
    lam = clutter_per_gate / vol_med
    x0, x1 = truth[0, 0] - 3 * half, truth[-1, 0] + 3 * half
    y0, y1 = -3 * half, 3 * half
    nc = rng.poisson(lam * (x1 - x0) * (y1 - y0))
    clutter = np.column_stack((rng.uniform(x0, x1, nc), rng.uniform(y0, y1, nc)))
    z = np.vstack((np.array(det), clutter))
    g = gate_measurements(z_pred, S, z, P_G=P_G)
    L, miss = likelihood_ratios(g, P_D, lam)
    return (
        L,
        miss,
        {
            "n_measurements": int(z.shape[0]),
            "n_clutter": int(nc),
            "clutter_density": lam,
            "gate_width": gw,
        },
    )


def bojilov_cluster(n_targets, beta, rng, sigma=0.35, spacing=0.5, P_D=0.9, P_G=0.99):
    """A Bojilov-like cluster: n targets side by side on parallel tracks, gates
    overlapping, Poisson clutter of density β per unit area. Redrawn until all
    targets form one cluster. Returns (L, miss)."""
    from scipy import stats

    from jointtrack.association.clustering import clusters
    from jointtrack.association.gating import gate_measurements, likelihood_ratios

    gamma = stats.chi2.ppf(P_G, 2)
    r = math.sqrt(gamma) * sigma
    S = np.repeat((sigma**2 * np.eye(2))[None], n_targets, axis=0)
    centres = np.column_stack((np.zeros(n_targets), np.arange(n_targets) * spacing))
    while True:
        z = [c + rng.normal(0, sigma * 0.7, 2) for c in centres if rng.random() < P_D]
        x0, x1 = -r, r
        y0, y1 = -r, centres[-1, 1] + r
        nc = rng.poisson(beta * (x1 - x0) * (y1 - y0))
        z += list(np.column_stack((rng.uniform(x0, x1, nc), rng.uniform(y0, y1, nc))))
        z = np.array(z).reshape(-1, 2)
        g = gate_measurements(centres, S, z, P_G=P_G)
        cl = clusters(g.mask)
        if len(cl) == 1:
            L, miss = likelihood_ratios(g, P_D, beta)
            keep = g.mask.any(axis=0)
            return L[:, keep], miss


# ---------------------------------------------------------------------------
# sections
# ---------------------------------------------------------------------------


def _dense(quick, results, log):
    from jointtrack.association import exact_jpda

    have_ss = _stonesoup_available()
    have_pe = _pyehm_available()
    if have_ss:
        from stonesoup.dataassociator.probability import JPDAwithEHM2
    pyehm_sizes = PYEHM_SIZES_QUICK if quick else PYEHM_SIZES_FULL
    log("## Dense clusters (L = 5·U[0,1], miss = 0.1, all gated; seed 0)\n")
    log(
        "| N/M | exact | DP state | peak RSS | Stone Soup EHM2 | ratio | max|Δβ| "
        "| pyehm EHM2 | ratio | max|Δβ| |"
    )
    log("|---|---|---|---|---|---|---|---|---|---|")
    rows = []
    for N, M in DENSE_SIZES:
        L, miss = dense_cluster(N, M)
        res = exact_jpda(L, miss)
        t_ours, reps = _median_time(
            lambda L=L, miss=miss: exact_jpda(L, miss), min_total=0.2 if quick else 0.5
        )
        row = {
            "N": N,
            "M": M,
            "exact_s": t_ours,
            "exact_reps": reps,
            "state_bytes": res.state_bytes,
            "max_frontier": res.max_frontier,
        }
        if N >= 16:
            base, peak = _peak_rss(N, M)
            row["peak_rss_bytes"] = peak
            row["rss_before_bytes"] = base
        rss = "-"
        if row.get("peak_rss_bytes"):
            rss = (
                f"{_fmt_b(row['peak_rss_bytes'])} "
                f"(+{_fmt_b(row['peak_rss_bytes'] - row['rss_before_bytes'])})"
            )
        cells = [f"{N}/{M}", _fmt_t(t_ours), _fmt_b(res.state_bytes), rss]
        for peer, avail, sizes in (
            ("stonesoup", have_ss, SS_EHM2_SIZES),
            ("pyehm", have_pe, pyehm_sizes),
        ):
            if not avail:
                cells += ["not installed", "-", "-"]
                continue
            if (N, M) not in sizes:
                anchor = ANCHORS.get((peer, (N, M)), "> 60 s")
                cells += [f"not run (anchor {anchor})", "-", "-"]
                row[f"{peer}_s"] = None
                continue
            if peer == "stonesoup":
                t_p, beta_p = _StoneSoupCluster(L, miss).run(JPDAwithEHM2)
            else:
                _pyehm_run(L[:2, :3], miss[:2])  # load the extension once
                t_p, beta_p = _pyehm_run(L, miss)
            diff = float(np.abs(beta_p - res.beta).max())
            row[f"{peer}_s"] = t_p
            row[f"{peer}_ratio"] = t_p / t_ours
            row[f"{peer}_maxdiff"] = diff
            cells += [_fmt_t(t_p), f"{t_p / t_ours:,.0f}×", f"{diff:.1e}"]
        rows.append(row)
        log("| " + " | ".join(cells) + " |")
    results["dense"] = rows
    log("")
    log(
        "exact: median over repeats of `exact_jpda(L, miss)` (validation + leaf folding + "
        "dual scaling + planning + forward–backward DP), single thread. DP state = bytes "
        "of the DP arrays allocated; peak RSS = peak resident memory of a fresh Python "
        "process (numpy, numba, jointtrack loaded) while it solves the cluster, with the "
        "increase over its resident memory just before in parentheses."
    )
    log(
        "Stone Soup: one `JPDAwithEHM2.associate(tracks, detections, t)` call with a "
        "hypothesiser returning prebuilt SingleProbabilityHypothesis objects (probabilities "
        "= miss, L). pyehm: one `EHM2().run(validation, [miss | L])` call.\n"
    )
    return rows


_BIG_CODE = """
import resource, time, numpy as np
from jointtrack.association import exact_jpda

rng = np.random.default_rng({seed}); L = 5 * rng.random(({N}, {M})); miss = np.full({N}, 0.1)
exact_jpda(L[:4, :8], miss[:4], parallel={parallel})   # numba code loaded before timing
rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
t = time.perf_counter()
res = exact_jpda(L, miss, parallel={parallel}, max_memory={mem})
dt = time.perf_counter() - t
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
np.save({out!r}, res.beta)
print(dt, rss0, peak, res.state_bytes)
"""


def _big_run(N, M, parallel, mem, out, seed=0):
    """(seconds, peak RSS before, peak RSS after, DP state bytes) of one fresh-process solve."""
    code = _BIG_CODE.format(seed=seed, N=N, M=M, parallel=parallel, mem=mem, out=out)
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=1800, check=False
    )
    if proc.returncode:
        tail = proc.stderr.strip().splitlines()[-1:] or ["?"]
        return {"error": f"exit {proc.returncode}: {tail[0]}"}
    dt, rss0, peak, state = proc.stdout.split()
    return {
        "s": float(dt),
        "rss_before": int(rss0),
        "peak_rss": int(peak),
        "state_bytes": int(state),
    }


def _big(quick, results, log):
    """DESIGN.md's 24×48 dense cluster with both cores at the default budget, in a fresh process."""
    import os
    import tempfile

    import numba

    from jointtrack.assignment.core import DEFAULT_MAX_MEMORY as BIG_MEMORY
    from jointtrack.association import exact_jpda

    N, M = BIG
    log(f"## Large dense cluster {N}/{M} (L = 5·U[0,1], miss = 0.1, seed 0), both cores\n")
    # parallel and serial kernels agree to rounding (checked on 16/32, in this process)
    L, miss = dense_cluster(16, 32)
    d = float(np.abs(exact_jpda(L, miss, parallel=True).beta - exact_jpda(L, miss).beta).max())
    out = {"par_vs_serial_16_32_maxdiff": d, "threads": numba.get_num_threads()}
    with tempfile.TemporaryDirectory() as tmp:
        runs = {"parallel": _big_run(N, M, True, BIG_MEMORY, os.path.join(tmp, "p.npy"))}
        if not quick:
            runs["serial"] = _big_run(N, M, False, BIG_MEMORY, os.path.join(tmp, "s.npy"))
            if "error" not in runs["parallel"] and "error" not in runs["serial"]:
                bp = np.load(os.path.join(tmp, "p.npy"))
                bs = np.load(os.path.join(tmp, "s.npy"))
                out["par_vs_serial_24_48_maxdiff"] = float(np.abs(bp - bs).max())
    out.update(runs)
    log("| run | exact_jpda call | wall time | peak RSS (fresh process) | DP state |")
    log("|---|---|---|---|---|")
    for name, r in runs.items():
        call = f"exact_jpda(L, miss, parallel={name == 'parallel'})"
        if "error" in r:
            log(f"| {name} | `{call}` | {r['error']} | - | - |")
            continue
        log(
            f"| {name} ({numba.get_num_threads() if name == 'parallel' else 1} thread"
            f"{'s' if name == 'parallel' and numba.get_num_threads() > 1 else ''}) | `{call}` "
            f"| {_fmt_t(r['s'])} | {r['peak_rss'] / 2**30:.2f} GiB "
            f"| {r['state_bytes'] / 2**30:.2f} GiB |"
        )
    if "serial" in runs and "s" in runs["serial"] and "s" in runs["parallel"]:
        out["parallel_speedup"] = runs["serial"]["s"] / runs["parallel"]["s"]
        log(f"\nparallel speedup: {out['parallel_speedup']:.2f}×")
    log(
        f"\nmax |β_parallel − β_serial|: 16/32 {d:.1e}"
        + (
            f", 24/48 {out['par_vs_serial_24_48_maxdiff']:.1e}"
            if "par_vs_serial_24_48_maxdiff" in out
            else ""
        )
        + ". Each run is a fresh Python process (numba code loaded by a 4×8 call first); "
        "peak RSS = `resource.getrusage(RUSAGE_SELF).ru_maxrss` after the solve (whole "
        "process: interpreter, numpy, numba, jointtrack and the DP arrays). DP state: the "
        "checkpoint plan the engine chose within the default max_memory (every stride-th "
        "forward array kept, the segments between recomputed; keeping all 48 would need "
        "51 arrays of 2^24 states, 6.4 GiB).\n"
    )
    results["big"] = out


def _lbp(quick, results, log):
    from jointtrack.association import exact_jpda

    try:
        from jointtrack.association.lbp import lbp_marginals
    except ImportError:
        log("## LBP at 20/40: jointtrack.association.lbp not available\n")
        return
    N, M = 20, 40
    L, miss = dense_cluster(N, M)
    exact = exact_jpda(L, miss).beta
    t_ours, _ = _median_time(lambda: lbp_marginals(L, miss))
    beta, info = lbp_marginals(L, miss)
    err = float(np.abs(beta - exact).max())
    out = {"lbp_s": t_ours, "lbp_maxerr": err, "lbp_iterations": info.iterations}
    log("## LBP at 20/40 (same matrix as the dense row)\n")
    log("| method | time | iterations | max |β − exact| |")
    log("|---|---|---|---|")
    log(
        f"| jointtrack lbp (tol 1e-9, certified) | {_fmt_t(t_ours)} | {info.iterations} "
        f"| {err:.2e} |"
    )
    if _stonesoup_available():
        from stonesoup.dataassociator.probability import JPDAwithLBP

        sc = _StoneSoupCluster(L, miss)
        sc.run(JPDAwithLBP)
        ts = []
        for _ in range(3 if quick else 7):
            t, b = sc.run(JPDAwithLBP)
            ts.append(t)
        t_ss = statistics.median(ts)
        err_ss = float(np.abs(b - exact).max())
        out.update({"stonesoup_lbp_s": t_ss, "stonesoup_lbp_maxerr": err_ss})
        log(f"| Stone Soup JPDAwithLBP.associate | {_fmt_t(t_ss)} | - | {err_ss:.2e} |")
    else:
        log("| Stone Soup JPDAwithLBP | not installed | - | - |")
    log("")
    results["lbp_20_40"] = out


def _sparse(quick, results, log):
    from jointtrack.association import exact_jpda, exact_marginals
    from jointtrack.association.clustering import clusters

    log("## Sparse scene (200 targets on a line, 2 detections each, Poisson clutter)\n")
    log(
        "| variant | measurements | clusters | tracks per cluster (count) | largest "
        "| exact, all clusters | exact, one call | pyehm EHM2, all clusters "
        "| Stone Soup EHM2, scene | max|Δβ| |"
    )
    log("|---|---|---|---|---|---|---|---|---|---|")
    out = []
    for width in ("half", "full"):
        L, miss, info = sparse_scene(width=width)
        cl = clusters(L > 0)
        subs = [c.select(L, miss) for c in cl]
        sizes = np.array([len(c.tracks) for c in cl])
        hist = np.bincount(sizes)
        hist_s = ", ".join(f"{k}:{v}" for k, v in enumerate(hist) if v)
        largest = max(cl, key=lambda c: (len(c.tracks), len(c.measurements)))
        for Lc, mc in subs:
            exact_marginals(Lc, mc)

        def all_clusters(subs=subs):
            for Lc, mc in subs:
                exact_marginals(Lc, mc)

        t_all, _ = _median_time(all_clusters)
        t_one, _ = _median_time(lambda L=L, miss=miss: exact_jpda(L, miss))
        beta = exact_jpda(L, miss).beta
        row = {
            "variant": width,
            "n_measurements": info["n_measurements"],
            "n_clusters": len(cl),
            "cluster_size_hist": hist.tolist(),
            "largest": [len(largest.tracks), len(largest.measurements)],
            "exact_all_clusters_s": t_all,
            "exact_one_call_s": t_one,
        }
        cells = [
            f"gate width = {width} width",
            str(info["n_measurements"]),
            str(len(cl)),
            hist_s,
            f"{len(largest.tracks)}×{len(largest.measurements)}",
            _fmt_t(t_all),
            _fmt_t(t_one),
        ]
        diffs = []
        if _pyehm_available():
            tp = 0.0
            bp = np.zeros_like(beta)
            for c, (Lc, mc) in zip(cl, subs, strict=True):
                t, b = _pyehm_run(Lc, mc)
                tp += t
                bp[np.ix_(c.tracks, np.concatenate(([0], c.measurements + 1)))] = b
            diffs.append(float(np.abs(bp - beta).max()))
            row["pyehm_all_clusters_s"] = tp
            cells.append(_fmt_t(tp))
        else:
            cells.append("not installed")
        if _stonesoup_available() and not quick:
            from stonesoup.dataassociator.probability import JPDAwithEHM2

            t, b = _StoneSoupCluster(L, miss).run(JPDAwithEHM2)
            diffs.append(float(np.abs(b - beta).max()))
            row["stonesoup_scene_s"] = t
            cells.append(_fmt_t(t))
        else:
            cells.append("not run (quick)" if _stonesoup_available() else "not installed")
        row["max_diff_vs_peers"] = max(diffs) if diffs else None
        cells.append(f"{max(diffs):.1e}" if diffs else "-")
        log("| " + " | ".join(cells) + " |")
        out.append(row)
    log("")
    log(
        "Gate width read as the median gate's half-width along the line ('half', the "
        "headline: overlapping gates, chains of clusters) or its full width ('full': "
        "gates almost never overlap). exact, all clusters: sum over the clusters from "
        "`clusters(L > 0)` of `exact_marginals` on each sub-problem (per-call overhead "
        "included); one call: `exact_jpda` on the whole scene matrix, which splits it "
        "itself.\n"
    )
    results["sparse"] = out


def _table2(quick, results, log):
    from jointtrack.association import exact_marginals
    from jointtrack.association.hypotheses import enumerate_jpda

    log("## Bojilov Table 2 trend: multiplications per cluster, naive vs incremental\n")
    log(
        "Ours: mean over 10 random Bojilov-like clusters (targets side by side on parallel "
        "tracks, σ = 0.35, spacing 0.5, P_D = 0.9, clutter β per unit area); counts are "
        "multiplications for hypothesis products only. Paper: floating point operations "
        "per cluster (all operations), averaged over ten runs of its scenario.\n"
    )
    log(
        "| targets | β | hypotheses | naive mults | incremental mults | ratio "
        "| paper nonopt | paper opt | paper ratio | enumerate vs exact max|Δβ| |"
    )
    log("|---|---|---|---|---|---|---|---|---|---|")
    rng = np.random.default_rng(2024)
    rows = []
    for beta_idx, beta in enumerate((1.0, 2.0)):
        for n in (2, 3, 4, 5):
            hyp = []
            naive = []
            opt = []
            t_naive = []
            t_opt = []
            dmax = 0.0
            for _ in range(10):
                L, miss = bojilov_cluster(n, beta, rng)
                a = enumerate_jpda(L, miss, max_hypotheses=None)
                b = enumerate_jpda(L, miss, naive=True, max_hypotheses=None)
                t_opt.append(
                    _median_time(
                        lambda L=L, miss=miss: enumerate_jpda(L, miss, max_hypotheses=None),
                        min_total=0.0,
                    )[0]
                )
                t_naive.append(
                    _median_time(
                        lambda L=L, miss=miss: enumerate_jpda(
                            L, miss, naive=True, max_hypotheses=None
                        ),
                        min_total=0.0,
                    )[0]
                )
                dmax = max(dmax, float(np.abs(a.beta - exact_marginals(L, miss)).max()))
                hyp.append(a.n_hypotheses)
                naive.append(b.n_multiplications)
                opt.append(a.n_multiplications)
            paper = BOJILOV_TABLE2[n][3 * beta_idx : 3 * beta_idx + 3]
            ratio = float(np.mean(naive) / np.mean(opt)) if np.mean(opt) else float("nan")
            rows.append(
                {
                    "targets": n,
                    "beta": beta,
                    "hypotheses": float(np.mean(hyp)),
                    "naive_mults": float(np.mean(naive)),
                    "incremental_mults": float(np.mean(opt)),
                    "ratio": ratio,
                    "paper": paper,
                    "max_diff_vs_exact": dmax,
                    "naive_s": float(np.mean(t_naive)),
                    "incremental_s": float(np.mean(t_opt)),
                }
            )
            log(
                f"| {n} | {beta:g} | {np.mean(hyp):,.0f} | {np.mean(naive):,.0f} "
                f"| {np.mean(opt):,.0f} | {ratio:.2f} | {paper[0]:,} | {paper[1]:,} "
                f"| {paper[2]:.2f} | {dmax:.1e} |"
            )
    log("")
    log(
        "For 2 targets both schemes need one multiplication per hypothesis (ratio 1); the "
        "ratio grows with the cluster size as in the paper (towards (N−1)(n−1)/n when "
        "conflicts are rare). The paper's ratios are smaller because its counts include "
        "every other floating point operation of the cluster processing.\n"
    )
    results["table2"] = rows
    log("### Table 3 analogue: seconds per cluster (same clusters)\n")
    log(
        "Ours: `enumerate_jpda` per cluster (validation, ordering, scaling, depth-first "
        "generation, normalisation), median of 3 calls, mean over the 10 clusters. Paper: "
        "its whole JPDA cluster processing on 2003 hardware.\n"
    )
    log("| targets | β | naive | incremental | ratio | paper nonopt | paper opt | paper ratio |")
    log("|---|---|---|---|---|---|---|---|")
    for r in rows:
        p3 = BOJILOV_TABLE3.get(r["targets"])
        k = 0 if r["beta"] == 1.0 else 3
        paper = f"{p3[k]} s | {p3[k + 1]} s | {p3[k + 2]:.2f}" if p3 else "- | - | -"
        log(
            f"| {r['targets']} | {r['beta']:g} | {_fmt_t(r['naive_s'])} "
            f"| {_fmt_t(r['incremental_s'])} | {r['naive_s'] / r['incremental_s']:.2f} "
            f"| {paper} |"
        )
    log("")


def _verdicts(results, log):
    rows = {(r["N"], r["M"]): r for r in results["dense"]}
    checks = []
    r8 = rows[(8, 16)]
    if r8.get("stonesoup_ratio"):
        checks.append(
            (
                "8/16 ≥ 1000× faster than Stone Soup JPDAwithEHM2",
                r8["stonesoup_ratio"] >= TARGET_SS_RATIO,
                f"{r8['stonesoup_ratio']:,.0f}×",
            )
        )
    if r8.get("pyehm_ratio"):
        checks.append(
            (
                "8/16 ≥ 100× faster than pyehm EHM2",
                r8["pyehm_ratio"] >= TARGET_PYEHM_RATIO,
                f"{r8['pyehm_ratio']:,.0f}×",
            )
        )
    r16 = rows[(16, 32)]
    checks.append(("16/32 ≤ 0.1 s", r16["exact_s"] <= TARGET_16_32, _fmt_t(r16["exact_s"])))
    r20 = rows[(20, 40)]
    checks.append(("20/40 ≤ 1 s", r20["exact_s"] <= TARGET_20_40, _fmt_t(r20["exact_s"])))
    mem = r20.get("peak_rss_bytes") or r20["state_bytes"]
    checks.append(("20/40 ≤ 2 GiB", mem <= TARGET_MEMORY, _fmt_b(mem)))
    big = results.get("big")
    if big:
        par = big.get("parallel", {})
        if "s" in par:
            checks.append(
                (
                    f"{BIG[0]}/{BIG[1]} (parallel, default budget) ≤ {TARGET_BIG_TIME:g} s",
                    par["s"] <= TARGET_BIG_TIME,
                    _fmt_t(par["s"]),
                )
            )
            checks.append(
                (
                    f"{BIG[0]}/{BIG[1]} peak RSS ≤ {TARGET_BIG_RSS / 2**30:g} GiB",
                    par["peak_rss"] <= TARGET_BIG_RSS,
                    f"{par['peak_rss'] / 2**30:.2f} GiB",
                )
            )
        d16 = big["par_vs_serial_16_32_maxdiff"]
        extra = big.get("par_vs_serial_24_48_maxdiff")
        checks.append(
            (
                "parallel β = serial β to 1e-13 on 16/32",
                d16 <= TARGET_PAR_DIFF,
                f"{d16:.1e}" + (f"; 24/48: {extra:.1e}, not a target" if extra is not None else ""),
            )
        )
    sp = results.get("sparse")
    if sp:
        t = sp[0]["exact_all_clusters_s"]
        checks.append(("sparse scene, all clusters exact ≤ 50 ms", t <= TARGET_SPARSE, _fmt_t(t)))
    lb = results.get("lbp_20_40")
    if lb and "stonesoup_lbp_s" in lb:
        checks.append(
            (
                "lbp 20/40 faster than Stone Soup JPDAwithLBP",
                lb["lbp_s"] < lb["stonesoup_lbp_s"],
                f"{_fmt_t(lb['lbp_s'])} vs {_fmt_t(lb['stonesoup_lbp_s'])}",
            )
        )
    t2 = results.get("table2")
    if t2:
        r1 = [r["ratio"] for r in t2 if r["beta"] == 1.0]
        r2 = [r["ratio"] for r in t2 if r["beta"] == 2.0]
        ok = all(np.diff(r1) > 0) and all(np.diff(r2) > 0)
        checks.append(
            (
                "Table 2 trend: ratio grows with cluster size",
                ok,
                " / ".join(f"{x:.2f}" for x in r1 + r2),
            )
        )
    log("## Targets (issue 3)\n")
    for name, ok, val in checks:
        log(f"- {'PASS' if ok else 'FAIL'}: {name} ({val})")
    log("")
    results["checks"] = [{"check": n, "pass": bool(o), "value": v} for n, o, v in checks]


def run(quick: bool = False, out: str | None = None) -> dict:
    """Run the association benchmark; print a Markdown report; optionally write JSON."""
    import numba

    import jointtrack

    def log(s=""):
        print(s, flush=True)

    results: dict = {"quick": quick}
    versions = {
        "jointtrack": jointtrack.__version__,
        "numpy": np.__version__,
        "numba": numba.__version__,
        "python": platform.python_version(),
    }
    try:
        import stonesoup

        versions["stonesoup"] = stonesoup.__version__
    except ImportError:
        pass
    try:
        from importlib.metadata import version

        versions["pyehm"] = version("pyehm")
    except Exception:  # noqa: BLE001 - optional peer
        pass
    results["versions"] = versions
    log(f"# jointtrack association benchmark{' (quick)' if quick else ''}\n")
    log("versions: " + ", ".join(f"{k} {v}" for k, v in versions.items()) + "\n")
    t0 = time.perf_counter()
    _dense(quick, results, log)
    _big(quick, results, log)
    _lbp(quick, results, log)
    _sparse(quick, results, log)
    _table2(quick, results, log)
    _verdicts(results, log)
    results["wall_s"] = time.perf_counter() - t0
    log(f"total wall time {results['wall_s']:.1f} s")
    if out:
        with open(out, "w") as f:
            json.dump(to_jsonable(results, fallback=float), f, indent=2)
    return results
