"""Particle JPDA with Streit's weights: §7's costs, one scan's weights, tracking accuracy.

R. L. Streit, "Saddle point method for JPDA and related filters", *Proc. 18th
International Conference on Information Fusion* (FUSION), 2015; section and
equation numbers below are that paper's.

Run as ``python benchmarks/particle.py [--quick] [--seeds S] [--out FILE]``.

* **(a) §7's costs, timed by part.** Random JPDA scans (N targets × L
  particles, M measurements, every particle reaching every measurement: P_D =
  0.9, likelihoods U[0, 1), clutter terms U[0.05, 0.5)). Per scan and summed
  over the N targets: the coefficients (7) (:func:`jpda_coefficients`), the
  saddle-point search (24) (:func:`saddle_point`, batched over L, *without*
  its closing determinant; as called by ``log_mixed_derivative``, ≤ 100
  Newton steps, and capped at ``CAPPED_ITER`` steps, which bounds the cost of
  a stalled batch), the determinants of eq. (30)/(31)
  (``np.linalg.slogdet`` of the (L, M, M) Hessians at the saddle points), and
  for comparison the exact weights (one :func:`jpda_log_weights` core call per
  target). Three sweeps around N = 5, M = 10, L = 1000 (one variable at a
  time); printed: milliseconds, ns per N·M·L (coefficients, search) or per
  L·N·M³ (determinants), and the log-log slope of each part in the swept
  variable beside §7's exponent (from the capped search). Best of ``REPEATS`` runs.
* **(b) One scan, 5 targets × 1000 particles, M = 10.** Five targets within
  ≈ 60 m, σ = 10 m, each detected once plus 5 clutter returns around them
  (one component of 5 targets and 10 measurements; no gate), the particles
  drawn around the true states with the steady-state covariance. The
  weights of the scan (coefficients + derivatives of all five targets, as
  :meth:`ParticleJPDATracker.step` reports them) and the whole ``step``, median
  over ``SCANS`` such scans; also the saddle weights' error after the global
  scale (std of log(w_saddle / w_exact) over the particles, cf. Table 1).
  Target (issue): saddle ≤ 50 ms per scan.
* **(c) Tracking accuracy.** ``jointtrack run``'s particle tracker
  (:func:`jointtrack.experiments.run.run_scenario` with ``particle=…``, 1000
  particles, plots off) on ``crossing`` and ``bojilov`` for seeds 0…S−1 (S ≥ 10;
  quick 3 seeds, 300 particles), exact vs saddle weights with the same tracker
  seed (common random numbers). Printed: mean GOSPA (c = 5σ, p = 2) and OSPA,
  the ratio saddle / exact, the paired difference with its standard error,
  weight ms per scan. Target: saddle's mean GOSPA
  within 5 % of exact.

``saddle-corrected`` is run beside ``saddle`` wherever :mod:`jointtrack.saddle`
provides it.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import tempfile
import time

import numpy as np
from rich.table import Table

from jointtrack._console import make_console
from jointtrack._provenance import machine_info
from jointtrack.experiments.config import steady_state_covariance
from jointtrack.experiments.run import run_scenario
from jointtrack.io import to_jsonable
from jointtrack.saddle import jpda_coefficients, jpda_log_weights, saddle_point
from jointtrack.trackers.particle import (
    ParticleConfig,
    ParticleJPDATracker,
    available_weight_methods,
)

REPEATS = 3
# Newton steps of the capped search in (a): converged problems need 5–9, a stall runs to the cap
CAPPED_ITER = 20
SCANS = 20
SCAN_TARGET_SECONDS = 0.050
ACCURACY_TOLERANCE = 0.05
SADDLES = [m for m in available_weight_methods() if m != "exact"]


def _best(f, repeats=REPEATS):
    """Smallest wall time of ``repeats`` calls (after one untimed call), and the last result."""
    out = f()
    best = math.inf
    for _ in range(repeats):
        t = time.perf_counter()
        out = f()
        best = min(best, time.perf_counter() - t)
    return best, out


def _slope(x, y) -> float:
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


# ----------------------------------------------------------------------------- (a) costs


def _random_scan(N, M, L, seed):
    rng = np.random.default_rng([seed, N, M, L])
    a = rng.uniform(0.05, 0.5, M)
    pd = np.full((N, L), 0.9)
    lik = rng.random((N, L, M))
    return a, pd, lik


def _hessian(u, a, F):
    """∇²φ(u) = diag(λ) + Σ_k (diag(p_k) − p_k p_kᵀ) (eq. 31 in u = log r), batched.

    λ_m = a_m e^{u_m}, p_km = f_km e^{u_m} / (f_k0 + Σ_m f_km e^{u_m}): the matrices
    whose determinants eq. (30) needs, built here so the determinants are timed alone.
    """
    r = np.exp(u)
    num = F[..., 1:] * r[..., None, :]
    p = num / (F[..., 0] + num.sum(-1))[..., None]
    H = -np.matmul(np.swapaxes(p, -1, -2), p)
    idx = np.arange(u.shape[-1])
    H[..., idx, idx] += a * r + p.sum(-2)
    return H


def _parts(N, M, L, seed=0) -> dict:
    a, pd, lik = _random_scan(N, M, L, seed)
    problems = []
    for n in range(N):
        others = [j for j in range(N) if j != n]
        problems.append((pd[n], lik[n], [pd[j] for j in others], [lik[j] for j in others]))

    def coefficients():
        return [jpda_coefficients(a, *p) for p in problems]

    t_coef, coefs = _best(coefficients)

    def search(max_iter):
        return [
            saddle_point(a0, aa, F, max_iter=max_iter, raise_on_failure=False)
            for a0, aa, F in coefs
        ]

    t_sp, sps = _best(lambda: search(100))  # as log_mixed_derivative calls it
    t_cap, caps = _best(lambda: search(CAPPED_ITER))
    hessians = [_hessian(sp.u, aa, F) for sp, (_, aa, F) in zip(sps, coefs, strict=True)]
    t_det, _ = _best(lambda: [np.linalg.slogdet(H) for H in hessians])
    t_exact, _ = _best(lambda: [jpda_log_weights(a0, aa, F[:, 0], F[0, 1:]) for a0, aa, F in coefs])
    stalled = [sp.gradient_norm[~sp.converged] for sp in sps]
    return {
        "N": N,
        "M": M,
        "L": L,
        "coefficients_s": t_coef,
        # saddle_point closes with one slogdet of the same Hessians: time it apart
        "search_s": max(t_sp - t_det, 0.0),
        "search_capped_s": max(t_cap - t_det, 0.0),
        "determinants_s": t_det,
        "exact_s": t_exact,
        "newton_iterations": max(sp.iterations for sp in sps),
        "newton_iterations_capped": max(sp.iterations for sp in caps),
        "not_converged": int(sum(g.size for g in stalled)),
        "not_converged_max_gradient": max((float(g.max()) for g in stalled if g.size), default=0.0),
    }


SWEEPS = {
    "L": [dict(N=5, M=10, L=L) for L in (250, 500, 1000, 2000)],
    "N": [dict(N=N, M=10, L=1000) for N in (2, 3, 5, 8)],
    "M": [dict(N=5, M=M, L=1000) for M in (5, 10, 20, 40)],
}
QUICK_SWEEPS = {
    "L": [dict(N=5, M=10, L=L) for L in (250, 1000)],
    "N": [dict(N=N, M=10, L=1000) for N in (2, 5)],
    "M": [dict(N=5, M=M, L=1000) for M in (5, 20)],
}
# §7: coefficients and search O(NML), determinants O(LNM³)
PAPER_EXPONENT = {
    "coefficients_s": {"L": 1, "N": 1, "M": 1},
    "search_s": {"L": 1, "N": 1, "M": 1},
    "determinants_s": {"L": 1, "N": 1, "M": 3},
}


def _costs(console, quick, results):
    sweeps = QUICK_SWEEPS if quick else SWEEPS
    out = {"points": {}, "slopes": {}}
    t = Table(title="(a) §7's costs per scan, all N targets (best of 3)")
    for name in (
        "N",
        "M",
        "L",
        "coef ms",
        "ns/NML",
        "search ms",
        f"search@{CAPPED_ITER} ms",
        "ns/NML",
        "det ms",
        "ns/LNM³",
        "exact ms",
        "Newton it.",
        "not conv.",
    ):
        t.add_column(name, justify="right")
    for var, points in sweeps.items():
        rows = [_parts(**p) for p in points]
        out["points"][var] = rows
        for r in rows:
            nml = r["N"] * r["M"] * r["L"]
            lnm3 = r["L"] * r["N"] * r["M"] ** 3
            t.add_row(
                str(r["N"]),
                str(r["M"]),
                str(r["L"]),
                f"{1e3 * r['coefficients_s']:.2f}",
                f"{1e9 * r['coefficients_s'] / nml:.1f}",
                f"{1e3 * r['search_s']:.1f}",
                f"{1e3 * r['search_capped_s']:.1f}",
                f"{1e9 * r['search_capped_s'] / nml:.1f}",
                f"{1e3 * r['determinants_s']:.2f}",
                f"{1e9 * r['determinants_s'] / lnm3:.3f}",
                f"{1e3 * r['exact_s']:.2f}",
                str(r["newton_iterations"]),
                str(r["not_converged"])
                + (
                    f" (‖∇φ‖ ≤ {r['not_converged_max_gradient']:.0e})" if r["not_converged"] else ""
                ),
            )
        xs = [r[var] for r in rows]
        out["slopes"][var] = {
            part: _slope(xs, [max(r[part], 1e-9) for r in rows])
            for part in (
                "coefficients_s",
                "search_s",
                "search_capped_s",
                "determinants_s",
                "exact_s",
            )
        }
    console.print(t)
    s = Table(title="(a) log-log slope of each part in the swept variable (§7's exponent)")
    for name in ("swept", "coefficients", f"search@{CAPPED_ITER}", "search", "determinants",
                 "exact"):  # fmt: skip
        s.add_column(name, justify="right")
    for var, sl in out["slopes"].items():
        s.add_row(
            var,
            f"{sl['coefficients_s']:.2f} (1)",
            f"{sl['search_capped_s']:.2f} (1)",
            f"{sl['search_s']:.2f} (1)",
            f"{sl['determinants_s']:.2f} ({PAPER_EXPONENT['determinants_s'][var]})",
            f"{sl['exact_s']:.2f}",
        )
    console.print(s)
    console.print(
        "search = saddle_point as log_mixed_derivative calls it (≤ 100 Newton steps); "
        f"search@{CAPPED_ITER} = at most {CAPPED_ITER} steps, which bounds the cost of a "
        "stalled batch (not conv. = stalls, ‖∇φ‖∞ given); the slopes of §7's parts use "
        f"search@{CAPPED_ITER}. Newton's method costs O(K·M² + M³) per particle and step "
        "(Hessian and solve, K = N factors), not §7's O(M) gradient step; the coefficients "
        "are built per target with every other target's c (F is (L, N, M+1) per target): "
        "O(N²·M·L) per scan.",
        markup=False,
        highlight=False,
    )
    results["costs"] = out


# ----------------------------------------------------------------------------- (b) one scan


def _one_scan(seed: int):
    """Five targets within ≈ 60 m, each detected, plus 5 clutter returns: M = 10."""
    rng = np.random.default_rng([seed, 5])
    x0 = np.zeros((5, 4))
    x0[:, 0] = rng.uniform(-30, 30, 5)
    x0[:, 1] = rng.uniform(-30, 30, 5)
    x0[:, 2:] = rng.normal(0.0, 5.0, (5, 2))
    z_t = x0[:, :2] + rng.normal(0.0, 10.0, (5, 2))
    z_c = rng.uniform(-60, 60, (5, 2))
    z = np.concatenate([z_t, z_c])
    return x0, z[rng.permutation(10)]


def _scan(console, quick, results):
    n_scans = 5 if quick else SCANS
    P0 = steady_state_covariance(1.0, 1.0, 100.0, 2)
    methods = ["exact", *SADDLES]
    rows = {m: {"weights_s": [], "step_s": [], "components": set()} for m in methods}
    err = {m: [] for m in SADDLES}
    for seed in range(n_scans):
        x0, z = _one_scan(seed)
        weights = {}
        for m in methods:
            cfg = ParticleConfig(
                particles=1000, weights=m, process_noise=1.0, measurement_noise=100.0,
                p_d=0.9, p_g=1.0, clutter_density=1.0 / 120.0**2, seed=seed,
            )  # fmt: skip
            best_w = best_step = math.inf
            for rep in range(REPEATS + 1):
                trk = ParticleJPDATracker(cfg)
                trk.start(x0, P0)
                t = time.perf_counter()
                res = trk.step(0.0, z)
                dt = time.perf_counter() - t
                if rep:  # the first call loads the kernels
                    best_w, best_step = min(best_w, res.weight_seconds), min(best_step, dt)
            rows[m]["weights_s"].append(best_w)
            rows[m]["step_s"].append(best_step)
            rows[m]["components"].update(res.components)
            weights[m] = res.weights
        for m in SADDLES:  # same seed: the same particles, so the weights compare one to one
            lr = np.log(weights[m]) - np.log(weights["exact"])
            ok = np.isfinite(lr)
            err[m].append(float(np.std(lr[ok])))
    out = {}
    t = Table(title=f"(b) one scan: 5 targets × 1000 particles, M = 10 (median of {n_scans})")
    for name in ("weights", "weights ms", "step ms", "vs exact", "components",
                 "σ log(w/w_exact)", "≤ 50 ms"):  # fmt: skip
        t.add_column(name, justify="right")
    ex = statistics.median(rows["exact"]["weights_s"])
    for m in methods:
        r = rows[m]
        med = statistics.median(r["weights_s"])
        out[m] = {
            "weights_seconds_median": med,
            "weights_seconds_max": max(r["weights_s"]),
            "step_seconds_median": statistics.median(r["step_s"]),
            "ratio_to_exact": med / ex,
            "components": sorted(r["components"]),
            "weight_log_ratio_std_median": statistics.median(err[m]) if m in err else None,
        }
        t.add_row(
            m,
            f"{1e3 * med:.1f}",
            f"{1e3 * out[m]['step_seconds_median']:.1f}",
            f"{med / ex:.2f}×",
            ", ".join(f"{a}×{b}" for a, b in sorted(r["components"])),
            "–" if m not in err else f"{statistics.median(err[m]):.4f}",
            "–" if m == "exact" else ("PASS" if med <= SCAN_TARGET_SECONDS else "FAIL"),
        )
    console.print(t)
    results["scan"] = out


# ----------------------------------------------------------------------------- (c) accuracy


def _accuracy(console, quick, seeds, results):
    particles = 300 if quick else 1000
    methods = ["exact", *SADDLES]
    out = {"particles": particles, "seeds": list(range(seeds)), "scenarios": {}}
    t = Table(title=f"(c) tracking accuracy: {seeds} seeds, {particles} particles, jointtrack run")
    for name in ("scenario", "weights", "GOSPA", "OSPA", "ratio", "paired Δ ± se",
                 "weights ms/scan", "within 5 %"):  # fmt: skip
        t.add_column(name, justify="right")
    with tempfile.TemporaryDirectory() as tmp:
        for name in ("crossing", "bojilov"):
            per = {m: {"gospa": [], "ospa": [], "weight_ms": []} for m in methods}
            for seed in range(seeds):
                for m in methods:
                    met = run_scenario(
                        name,
                        seed=seed,
                        out_dir=f"{tmp}/{name}-{seed}-{m}",
                        plots=False,
                        particle={"weights": m, "particles": particles},
                    )
                    per[m]["gospa"].append(met["gospa"]["mean"])
                    per[m]["ospa"].append(met["ospa"]["mean"])
                    per[m]["weight_ms"].append(
                        1e3 * met["particle"]["weight_seconds_per_scan"]["mean"]
                    )
                console.print(
                    f"  {name} seed {seed}: "
                    + ", ".join(f"{m} {per[m]['gospa'][-1]:.3f}" for m in methods),
                    markup=False,
                    highlight=False,
                )
            g_ex = np.array(per["exact"]["gospa"])
            rows = {}
            for m in methods:
                g = np.array(per[m]["gospa"])
                d = g - g_ex
                ratio = float(g.mean() / g_ex.mean())
                rows[m] = {
                    "gospa_per_seed": g.tolist(),
                    "gospa_mean": float(g.mean()),
                    "ospa_mean": float(np.mean(per[m]["ospa"])),
                    "ratio_to_exact": ratio,
                    "paired_difference_mean": float(d.mean()),
                    "paired_difference_se": float(d.std(ddof=1) / math.sqrt(len(d)))
                    if len(d) > 1
                    else None,
                    "weight_ms_per_scan_mean": float(np.mean(per[m]["weight_ms"])),
                    "within_tolerance": abs(ratio - 1) <= ACCURACY_TOLERANCE,
                }
                r = rows[m]
                se = r["paired_difference_se"]
                t.add_row(
                    name,
                    m,
                    f"{r['gospa_mean']:.3f}",
                    f"{r['ospa_mean']:.3f}",
                    f"{ratio:.4f}",
                    "–" if m == "exact" else f"{d.mean():+.3f} ± {se or 0:.3f}",
                    f"{r['weight_ms_per_scan_mean']:.1f}",
                    "–" if m == "exact" else ("PASS" if r["within_tolerance"] else "FAIL"),
                )
            out["scenarios"][name] = rows
    console.print(t)
    results["accuracy"] = out


def run(quick: bool = False, seeds: int | None = None, out: str | None = None) -> dict:
    console = make_console()
    seeds = seeds if seeds is not None else (3 if quick else 10)
    results: dict = {"quick": quick, "machine": machine_info(), "methods": ["exact", *SADDLES]}
    t0 = time.perf_counter()
    _costs(console, quick, results)
    _scan(console, quick, results)
    _accuracy(console, quick, seeds, results)
    results["seconds"] = time.perf_counter() - t0
    console.print(f"total {results['seconds']:.0f} s", markup=False, highlight=False)
    if out:
        with open(out, "w", encoding="utf-8") as fh:
            json.dump(to_jsonable(results, fallback=float), fh, indent=2)
        console.print(f"results: {out}", markup=False, highlight=False)
    return results


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer sizes, scans and seeds")
    parser.add_argument("--seeds", type=int, help="seeds 0..S-1 for (c) (default 10; quick 3)")
    parser.add_argument("--out", help="also write the results as JSON to this file")
    args = parser.parse_args()
    if args.seeds is not None and args.seeds < 1:
        parser.error("--seeds must be ≥ 1")
    run(quick=args.quick, seeds=args.seeds, out=args.out)
