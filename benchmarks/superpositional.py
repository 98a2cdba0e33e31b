"""Superpositional likelihoods: cost of "exact", "gaussian", "montecarlo" (and any others).

S. Nannuru and M. Coates, "Gaussian approximation for superpositional sensors",
technical report, McGill University, 2015 (§C's multi-Bernoulli setup).

Run as ``python benchmarks/superpositional.py [--repeats R] [--out FILE]``.

* **Exact 8-component multi-Bernoulli (256 mixture terms).** The report's
  setup (H of (11), Σ0 = 0.25 I, Σ_i = I, means uniform over 20 × 20 m, r_i
  uniform on [0.2, 1], y0 = Σ Hμ_i), 20 random sets; the time of one
  ``likelihood(..., method="exact")`` call (validation included), median of
  ``repeats`` calls per set, after a warm-up (no JIT time). Target (issue 14):
  ≤ 1 ms per evaluation.
* **Monte Carlo to a given error.** ``method="montecarlo"`` with 100,000
  samples on the same sets: its time and standard error of log I; the time it
  would need for a standard error of 1e-3 and of the exact method's rounding
  level (1e-12) (samples ∝ error⁻²), and the ratio of those to the exact time.
* **Others.** "gaussian" per evaluation, the exact IIDC of Table I at n0 = 8
  (Poisson(8) truncated at 15, 8 mixture components: 490,314 terms), and
  "saddlepoint"/"hybrid" when the package provides them.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np
from scipy.stats import poisson

from jointtrack.superpositional import IIDC, MultiBernoulli, likelihood

H = np.array([[0.1, 0.7], [0.5, 0.5], [0.8, 0.2]])
S0 = 0.25 * np.eye(3)


def mb_sets(n_sets=20, n=8, seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n_sets):
        means = rng.uniform(0, 20, (n, 2))
        mb = MultiBernoulli(rng.uniform(0.2, 1.0, n), means, [np.eye(2)] * n)
        out.append((H @ means.sum(axis=0), mb))
    return out


def per_call(fn, repeats):
    fn()  # warm-up: numba compile / cache load, imports
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=200)
    ap.add_argument("--out", default=None)
    args = ap.parse_args(argv)
    sets = mb_sets()
    res = {}

    exact_t = [
        per_call(lambda y0=y0, mb=mb: likelihood(y0, mb, H, S0, method="exact"), args.repeats)
        for y0, mb in sets
    ]
    res["exact_mb8_ms"] = 1e3 * statistics.median(exact_t)
    res["exact_mb8_ms_max"] = 1e3 * max(exact_t)
    gauss_t = [
        per_call(lambda y0=y0, mb=mb: likelihood(y0, mb, H, S0), args.repeats) for y0, mb in sets
    ]
    res["gaussian_ms"] = 1e3 * statistics.median(gauss_t)

    n_mc = 100_000
    mc_t, mc_se, mc_err = [], [], []
    for k, (y0, mb) in enumerate(sets[:5]):
        t = time.perf_counter()
        r = likelihood(y0, mb, H, S0, method="montecarlo", n_samples=n_mc, rng=k)
        mc_t.append(time.perf_counter() - t)
        mc_se.append(r.std_error)
        mc_err.append(abs(r.log_value - likelihood(y0, mb, H, S0, method="exact").log_value))
    t_mc, se_mc = statistics.median(mc_t), statistics.median(mc_se)
    res["montecarlo_100k_s"] = t_mc
    res["montecarlo_100k_std_error"] = se_mc
    res["montecarlo_abs_error_vs_exact_median"] = statistics.median(mc_err)
    for target in (1e-3, 1e-12):
        need = t_mc * (se_mc / target) ** 2
        res[f"montecarlo_s_for_se_{target:g}"] = need
        res[f"ratio_montecarlo_over_exact_se_{target:g}"] = need / (res["exact_mb8_ms"] * 1e-3)

    pmf = poisson.pmf(np.arange(16), 8.0)
    pmf /= pmf.sum()
    rng = np.random.default_rng(1)
    means = rng.uniform(0, 20, (8, 2))
    iidc = IIDC(pmf, np.ones(8), means, [np.eye(2)] * 8)
    y0 = H @ means.sum(axis=0)
    t = time.perf_counter()
    r = likelihood(y0, iidc, H, S0, method="exact")
    res["exact_iidc8_s"] = time.perf_counter() - t
    res["exact_iidc8_terms"] = r.info["terms"]

    for method in ("saddlepoint", "hybrid"):
        try:
            y0, mb = sets[0]
            res[f"{method}_ms"] = 1e3 * statistics.median(
                per_call(lambda y0=y0, mb=mb, m=method: likelihood(y0, mb, H, S0, method=m), 20)
                for y0, mb in sets
            )
        except (NotImplementedError, ValueError) as exc:
            res[f"{method}_ms"] = f"not available: {exc}"

    print(
        f"exact, 8-component MB (256 terms): {res['exact_mb8_ms']:.3f} ms per evaluation "
        f"(median over 20 sets; worst set {res['exact_mb8_ms_max']:.3f} ms); target <= 1 ms: "
        f"{'PASS' if res['exact_mb8_ms'] <= 1.0 else 'FAIL'}"
    )
    print(f"gaussian: {res['gaussian_ms']:.3f} ms per evaluation")
    print(
        f"montecarlo, 100,000 samples: {t_mc:.3f} s, std error of log I {se_mc:.4f} "
        f"(|MC - exact| median {res['montecarlo_abs_error_vs_exact_median']:.4f})"
    )
    for target in (1e-3, 1e-12):
        print(
            f"  for std error {target:g}: {res[f'montecarlo_s_for_se_{target:g}']:.3g} s = "
            f"{res[f'ratio_montecarlo_over_exact_se_{target:g}']:.3g} x the exact time"
        )
    print(
        f"exact IIDC of Table I at n0 = 8 ({res['exact_iidc8_terms']} terms): "
        f"{res['exact_iidc8_s']:.3f} s"
    )
    for method in ("saddlepoint", "hybrid"):
        v = res[f"{method}_ms"]
        print(f"{method}: " + (f"{v:.3f} ms per evaluation" if isinstance(v, float) else v))
    if args.out:
        with open(args.out, "w") as fh:
            json.dump(res, fh, indent=2)
    return res


if __name__ == "__main__":
    main()
