r"""Nannuru & Coates, Gaussian approximation for superpositional sensors: ``reproduce nannuru``.

S. Nannuru and M. Coates, "Gaussian approximation for superpositional sensors",
technical report, McGill University, 2015. Equation, table, figure and section
numbers below are that report's.

What the report runs
--------------------
The likelihood I of a reading y0 (2)–(3) against its Gaussian approximation I₁
(9) built from the Campbell moments (4)–(7), for g(x) = Hx with H of (11),
Σ0 = 0.25 I₃, Gaussian components N(μ_i, I₂), means uniform over 20 m × 20 m,
y0 = Σ Hμ_i (the report prints "H Σ g(μ_i)", a typo for Σ g(μ_i)), n0 = 3…8,
25 trials; the percentage error (13) 100|Î − Î₁|/Î averaged over trials:
Table I for an IIDC set (Poisson(n0) cardinality truncated at 15 and
renormalised, mixture of the n0 Gaussians with equal weights), Table II for a
multi-Bernoulli set (r_i ∈ [0.2, 1]), Table III for the union of that
multi-Bernoulli set and an IIDC set uniform over the region with a uniform
discrete cardinality. Î is a Monte Carlo average (N_s = 500,000, 25 repeats),
Î₁ uses particle moments (N_v = 10,000). §E: the correlation between the
update ratio R(x) of (16) and its approximation R₁(x) (20) for four Bernoulli
components, 100 mean sets × 100 states x from N(one of the means, diag(2, 2)):
Example 1 (r_i ∈ [0.2, 1]: 0.22; r_i ∈ [0.5, 1]: 0.44) and Table IV (r_i = r).

What is run here (:func:`reproduce`)
------------------------------------
* **Ground truth.** Tables I and II: ``likelihood(..., method="exact")``, the
  Gaussian-mixture enumeration (no Monte Carlo error; this replaces the
  report's N_s = 500,000 samples × 25 repeats). Table III: the uniform IIDC
  part has no Gaussian-mixture form, so I is a Rao–Blackwellised Monte Carlo
  estimate: for each cardinality n of the uniform part, sums of n uniform
  points are sampled and the multi-Bernoulli part is integrated exactly,
  I = Σ_n π(n) E[I_MB(y0 − Σ Hu_k)], ``UNION_SAMPLES`` samples per n; its
  standard error goes into the interval. §E: R(x) by
  ``log_likelihood_ratio(..., method="exact")``.
* **Our Gaussian column.** (9) and (20) with the closed-form Campbell moments
  (no particle noise).
* **The report's own estimator.** The same Gaussian with moments from N_v =
  10,000 sampled particles per density, I₁ averaged over ``NV_REPEATS`` draws
  as the report averages its 25 evaluations — to show how much of the report's
  numbers is moment noise.
* **Other methods.** Every other method of the dispatcher ("saddlepoint",
  "hybrid") through :func:`jointtrack.superpositional.likelihood`; a method
  that is missing (NotImplementedError) or fails is reported as such.
* **Choices the report leaves open**, stated in the output: the uniform IIDC
  part of Table III has cardinality uniform on {0, 1, …, n0}; y0 of Table III
  and §E is Σ Hμ_i over the Bernoulli means; in §E each x picks one of the four
  means uniformly at random, and r_i ∼ U[r_lo, 1] independently per component
  and mean set (Example 1), r_i = r (Table IV). Correlation: Pearson's, of R
  and R₁ themselves (not logs), over all mean sets × states; its 95 % interval
  is a bootstrap over mean sets.
* **Intervals.** A table cell is the mean over trials with a 95 % Student-t
  interval over the trials.
* **Figures.** Figures 1–3: histograms (1000 bins, as the report) of each
  component of y for n0 = 4, 6, 8 (first trial's means) with the Campbell
  Gaussian overlaid; Figures 4–5: bin plots of R against R₁ (10 equal-count
  groups by R₁; mean, median, 10–90 percentiles) for r_i ∈ [0.5, 1] and r = 0.95.
"""

from __future__ import annotations

import datetime
import math
import time
from pathlib import Path

import numpy as np
from scipy.special import logsumexp

from jointtrack._provenance import machine_info
from jointtrack.experiments._report import fmt as _f
from jointtrack.experiments._report import table as _table

__all__ = [
    "PAPER",
    "draw_model",
    "print_report",
    "ratio_row",
    "report_tables",
    "reproduce",
    "table_row",
    "union_truth",
]

#: the report's numbers (copied: the package reads no external file)
PAPER = {
    "source": "S. Nannuru and M. Coates, Gaussian approximation for superpositional sensors, "
    "technical report, McGill University, 2015; Tables I-IV, Example 1",
    "H": [[0.1, 0.7], [0.5, 0.5], [0.8, 0.2]],
    "n0": [3, 4, 5, 6, 7, 8],
    "table1_iidc_percent_error": [66.83, 47.63, 27.52, 10.72, 4.90, 5.29],
    "table2_multibernoulli_percent_error": [76.04, 77.24, 76.84, 74.73, 71.55, 66.84],
    "table3_union_percent_error": [80.61, 65.22, 47.47, 30.92, 16.38, 10.23],
    "example1": {"r_in_0.2_1": 0.22, "r_in_0.5_1": 0.44},
    "table4": {
        "r": [0.75, 0.80, 0.85, 0.90, 0.95, 0.99],
        "corr": [0.50, 0.53, 0.58, 0.63, 0.72, 0.91],
    },
    "protocol": "25 trials x 25 evaluations, N_s = 500,000, N_v = 10,000",
}
H = np.array(PAPER["H"])
SIGMA0 = 0.25 * np.eye(3)
REGION = 20.0
N0S = tuple(PAPER["n0"])
CARD_MAX = 15
SEED = 0
TRIALS, QUICK_TRIALS = 25, 5
#: trials behind each of the report's table entries (its §B protocol)
PAPER_TRIALS = 25
NV = 10_000
NV_REPEATS, QUICK_NV_REPEATS = 5, 3
UNION_SAMPLES, QUICK_UNION_SAMPLES = 4_000, 2_000
HIST_SAMPLES, QUICK_HIST_SAMPLES = 500_000, 50_000
HIST_N0 = (4, 6, 8)
RATIO_SETS, QUICK_RATIO_SETS = 100, 10
RATIO_X, QUICK_RATIO_X = 100, 50
BOOTSTRAP = 500
EXTRA_METHODS = ("saddlepoint", "hybrid")
TABLES = {
    "table1": ("Table I: IIDC", "table1_iidc_percent_error"),
    "table2": ("Table II: multi-Bernoulli", "table2_multibernoulli_percent_error"),
    "table3": ("Table III: multi-Bernoulli ∪ uniform IIDC", "table3_union_percent_error"),
}
#: §E rows: (name, r specification, paper's correlation)
RATIO_ROWS = (
    ("example1 r∈[0.2,1]", ("uniform", 0.2), PAPER["example1"]["r_in_0.2_1"]),
    ("example1 r∈[0.5,1]", ("uniform", 0.5), PAPER["example1"]["r_in_0.5_1"]),
    *(
        (f"table4 r={r:.2f}", ("equal", r), c)
        for r, c in zip(PAPER["table4"]["r"], PAPER["table4"]["corr"], strict=True)
    ),
)
FIGURE4_ROW, FIGURE5_ROW = "example1 r∈[0.5,1]", "table4 r=0.95"
_TABLE_ID = {"table1": 1, "table2": 2, "table3": 3}


# ----------------------------------------------------------------------------- models


def truncated_poisson(n0: float, n_max: int = CARD_MAX) -> np.ndarray:
    """Poisson(n0) on 0..n_max, renormalised (§B)."""
    from scipy.stats import poisson

    pmf = poisson.pmf(np.arange(n_max + 1), n0)
    return pmf / pmf.sum()


def union_pmf(n0: int) -> np.ndarray:
    """Cardinality of Table III's uniform IIDC part: uniform on {0, 1, …, n0} (our choice)."""
    return np.full(n0 + 1, 1.0 / (n0 + 1))


def draw_model(table: str, n0: int, trial: int, seed: int = SEED):
    """``(model, y0, mb or None)`` of one trial (seed ``[seed, table, n0, trial]``)."""
    from jointtrack.superpositional import IIDC, MultiBernoulli, Union

    rng = np.random.default_rng([seed, _TABLE_ID[table], n0, trial])
    means = rng.uniform(0.0, REGION, (n0, 2))
    covs = np.broadcast_to(np.eye(2), (n0, 2, 2))
    y0 = H @ means.sum(axis=0)
    if table == "table1":
        return IIDC(truncated_poisson(n0), np.ones(n0), means, covs), y0, None
    mb = MultiBernoulli(rng.uniform(0.2, 1.0, n0), means, covs)
    if table == "table2":
        return mb, y0, mb
    iidc = IIDC.uniform(union_pmf(n0), [0.0, 0.0], [REGION, REGION])
    return Union(mb, iidc), y0, mb


def union_truth(mb, pmf, y0, n_per_card: int, rng) -> tuple[float, float]:
    """Rao–Blackwellised Monte Carlo ``(log I, std error of log I)`` for MB ∪ uniform IIDC.

    I = Σ_n π(n) E[I_MB(y0 − Σ_{k ≤ n} H u_k)], u_k uniform over the region; the
    multi-Bernoulli part is integrated exactly (mixture enumeration), only the
    uniform points are sampled (``n_per_card`` sums per cardinality n ≥ 1).
    """
    from jointtrack.superpositional._exact import _evaluate
    from jointtrack.superpositional.measurement import as_measurement

    m = as_measurement(H)
    logs, var = [], 0.0
    for n, p in enumerate(pmf):
        if p <= 0.0:
            continue
        if n == 0:
            logs.append(math.log(p) + _evaluate(mb, m, SIGMA0, y0[None])[0][0])
            continue
        shift = rng.uniform(0.0, REGION, (n_per_card, n, 2)).sum(axis=1) @ H.T
        lv = _evaluate(mb, m, SIGMA0, y0[None] - shift)[0]
        top = lv.max()
        w = np.exp(lv - top)
        logs.append(math.log(p) + top + math.log(w.mean()))
        var += (p * math.exp(top)) ** 2 * w.var(ddof=1) / n_per_card if top > -700 else 0.0
    log_i = float(logsumexp(logs))
    return log_i, math.sqrt(var) / math.exp(log_i) if log_i > -700 else float("nan")


# ----------------------------------------------------------------------------- statistics


def _interval(values) -> dict:
    """Mean and 95 % Student-t interval over trials (a percentage error is ≥ 0: lo clipped at 0).

    Also ``paper_lo``/``paper_hi``: where another mean of :data:`PAPER_TRIALS` trials
    from the same distribution falls with 95 % probability (half-width t·s·√(1/n +
    1/25)). The report's entries are such means (25 random trials each, drawn
    from the same protocol), so this two-sample interval, not the interval of
    our mean alone, is the one its values should fall in if the protocols agree.
    """
    from scipy.stats import t as student

    v = np.asarray([x for x in values if x is not None and math.isfinite(x)], dtype=float)
    if v.size == 0:
        return {"mean": None, "lo": None, "hi": None, "n": 0}
    mean = float(v.mean())
    if v.size < 2:
        return {"mean": mean, "lo": None, "hi": None, "n": int(v.size)}
    t975 = float(student.ppf(0.975, v.size - 1))
    sd = float(v.std(ddof=1))
    half = t975 * sd / math.sqrt(v.size)
    half2 = t975 * sd * math.sqrt(1.0 / v.size + 1.0 / PAPER_TRIALS)
    return {
        "mean": mean,
        "lo": max(0.0, mean - half),
        "hi": mean + half,
        "paper_lo": max(0.0, mean - half2),
        "paper_hi": mean + half2,
        "n": int(v.size),
    }


def percent_error(log_true: float, log_approx: float) -> float:
    """(13): 100 |I − I₁| / I from logs (no underflow)."""
    return 100.0 * abs(math.expm1(log_approx - log_true))


def _unknown(method: str) -> str | None:
    from jointtrack.superpositional.likelihood import METHODS

    return None if method in METHODS else f"not available: {method!r} is not a dispatcher method"


def _call(fn):
    """``(value, None)`` or ``(None, message)`` for a method that is missing or fails.

    Only the columns of other modules' methods ("saddlepoint", "hybrid") go
    through here: whatever they raise is printed with its type in the report,
    and the reproduction of the Gaussian columns carries on.
    """
    try:
        return fn(), None
    except NotImplementedError as exc:
        return None, f"not available: {exc}"
    except Exception as exc:  # noqa: BLE001 — another module's bug is reported in the table, not fatal
        return None, f"failed: {type(exc).__name__}: {exc}"


# ----------------------------------------------------------------------------- Tables I–III


def table_row(
    table: str,
    n0: int,
    trials: int = TRIALS,
    seed: int = SEED,
    *,
    nv_repeats: int = NV_REPEATS,
    union_samples: int = UNION_SAMPLES,
    methods=EXTRA_METHODS,
    on_trial=None,
) -> dict:
    """One row (n0) of Table I, II or III: percentage errors (13) per method and trial."""
    from jointtrack.superpositional import likelihood

    columns = ["gaussian", "gaussian N_v", *methods]
    errors = {c: [] for c in columns}
    status = {c: _unknown(c) if c in methods else None for c in columns}
    seconds = dict.fromkeys(["truth", *columns], 0.0)
    truth_se = []
    for trial in range(trials):
        model, y0, mb = draw_model(table, n0, trial, seed)
        t0 = time.perf_counter()
        if table == "table3":
            rng = np.random.default_rng([seed, 10 + _TABLE_ID[table], n0, trial])
            log_true, se = union_truth(mb, model.parts[1].cardinality_pmf, y0, union_samples, rng)
            truth_se.append(se)
        else:
            log_true = likelihood(y0, model, H, SIGMA0, method="exact").log_value
        seconds["truth"] += time.perf_counter() - t0
        for c in columns:
            t0 = time.perf_counter()
            if c == "gaussian":
                val, msg = likelihood(y0, model, H, SIGMA0).log_value, None
            elif c == "gaussian N_v":
                rng = np.random.default_rng([seed, 20 + _TABLE_ID[table], n0, trial])
                logs = [
                    likelihood(y0, model, H, SIGMA0, moment_particles=NV, rng=rng).log_value
                    for _ in range(nv_repeats)
                ]
                val, msg = float(logsumexp(logs) - math.log(nv_repeats)), None
            elif status[c] is not None and status[c].startswith("not available"):
                val, msg = None, status[c]
            else:
                val, msg = _call(
                    lambda c=c, y0=y0, model=model: (
                        likelihood(y0, model, H, SIGMA0, method=c).log_value
                    )
                )
            seconds[c] += time.perf_counter() - t0
            if msg is not None:
                status[c] = msg
                errors[c].append(None)
            else:
                errors[c].append(percent_error(log_true, val))
        if on_trial is not None:
            on_trial()
    paper = PAPER[TABLES[table][1]][N0S.index(n0)] if n0 in N0S else None
    return {
        "table": table,
        "n0": n0,
        "trials": trials,
        "paper": paper,
        "truth": "Rao-Blackwellised Monte Carlo" if table == "table3" else "exact",
        "truth_std_error_mean": float(np.mean(truth_se)) if truth_se else 0.0,
        "methods": {
            c: {"status": status[c] or "ok", **_interval(errors[c]), "errors": errors[c]}
            for c in columns
        },
        "seconds": seconds,
    }


# ----------------------------------------------------------------------------- §E ratio


def _draw_ratio_set(spec, rng, n_x: int):
    from jointtrack.superpositional import MultiBernoulli

    means = rng.uniform(0.0, REGION, (4, 2))
    kind, val = spec
    r = rng.uniform(val, 1.0, 4) if kind == "uniform" else np.full(4, val)
    pick = rng.integers(0, 4, n_x)
    x = means[pick] + math.sqrt(2.0) * rng.standard_normal((n_x, 2))
    return MultiBernoulli(r, means, np.broadcast_to(np.eye(2), (4, 2, 2))), H @ means.sum(0), x


def _corr(a: np.ndarray, b: np.ndarray) -> float | None:
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 3 or a[ok].std() == 0 or b[ok].std() == 0:
        return None
    return float(np.corrcoef(a[ok], b[ok])[0, 1])


def _bootstrap_corr(R: np.ndarray, A: np.ndarray, rng, n_boot: int = BOOTSTRAP):
    """95 % percentile interval of corr(R, A) resampling whole mean sets (rows)."""
    S = R.shape[0]
    vals = []
    for _ in range(n_boot):
        idx = rng.integers(0, S, S)
        c = _corr(R[idx].ravel(), A[idx].ravel())
        if c is not None:
            vals.append(c)
    if len(vals) < 10:
        return None, None
    return float(np.percentile(vals, 2.5)), float(np.percentile(vals, 97.5))


def ratio_row(
    name: str,
    spec,
    paper,
    n_sets: int = RATIO_SETS,
    n_x: int = RATIO_X,
    seed: int = SEED,
    *,
    methods=EXTRA_METHODS,
    on_set=None,
) -> dict:
    """One row of Example 1 / Table IV: corr(R, R_method) over n_sets × n_x states."""
    from jointtrack.superpositional import log_likelihood_ratio

    columns = ["gaussian", "gaussian N_v", *methods]
    rng = np.random.default_rng([seed, 4, int(round(1000 * spec[1])), spec[0] == "equal"])
    R = np.empty((n_sets, n_x))
    A = {c: np.full((n_sets, n_x), np.nan) for c in columns}
    status = {c: _unknown(c) if c in methods else None for c in columns}
    seconds = dict.fromkeys(["exact", *columns], 0.0)
    for s in range(n_sets):
        mb, y0, x = _draw_ratio_set(spec, rng, n_x)
        t0 = time.perf_counter()
        R[s] = np.exp(log_likelihood_ratio(y0, x, mb, H, SIGMA0, method="exact"))
        seconds["exact"] += time.perf_counter() - t0
        for c in columns:
            if status[c] is not None:
                continue
            t0 = time.perf_counter()
            if c == "gaussian":
                val, msg = log_likelihood_ratio(y0, x, mb, H, SIGMA0), None
            elif c == "gaussian N_v":
                val, msg = (
                    log_likelihood_ratio(y0, x, mb, H, SIGMA0, moment_particles=NV, rng=rng),
                    None,
                )
            else:
                val, msg = _call(
                    lambda c=c, y0=y0, x=x, mb=mb: log_likelihood_ratio(
                        y0, x, mb, H, SIGMA0, method=c
                    )
                )
            seconds[c] += time.perf_counter() - t0
            if msg is not None:
                status[c] = msg
            else:
                A[c][s] = np.exp(val)
        if on_set is not None:
            on_set()
    brng = np.random.default_rng([seed, 5])
    out = {}
    for c in columns:
        if status[c] is not None:
            out[c] = {"status": status[c], "corr": None, "lo": None, "hi": None}
            continue
        lo, hi = _bootstrap_corr(R, A[c], brng)
        out[c] = {"status": "ok", "corr": _corr(R.ravel(), A[c].ravel()), "lo": lo, "hi": hi}
    return {
        "name": name,
        "r": {"kind": spec[0], "value": spec[1]},
        "paper": paper,
        "mean_sets": n_sets,
        "states_per_set": n_x,
        "methods": out,
        "seconds": seconds,
        "R": R,
        "R1": A["gaussian"],
    }


def bin_plot_data(R: np.ndarray, R1: np.ndarray, groups: int = 10) -> dict:
    """Figures 4–5: equal-count groups by R₁: mean R₁ (x) and mean, median, 10/90 % of R."""
    r, a = R.ravel(), R1.ravel()
    ok = np.isfinite(r) & np.isfinite(a)
    r, a = r[ok], a[ok]
    order = np.argsort(a)
    out = {k: [] for k in ("x", "mean", "median", "p10", "p90")}
    for idx in np.array_split(order, groups):
        if idx.size == 0:
            continue
        out["x"].append(float(a[idx].mean()))
        out["mean"].append(float(r[idx].mean()))
        out["median"].append(float(np.median(r[idx])))
        out["p10"].append(float(np.percentile(r[idx], 10)))
        out["p90"].append(float(np.percentile(r[idx], 90)))
    return out


# ----------------------------------------------------------------------------- figures 1–3 data


def histogram_data(table: str, n0: int, n_samples: int, seed: int = SEED) -> dict:
    """Samples of y for the first trial of a table and the Campbell mean/variance per component."""
    from jointtrack.superpositional import campbell_moments, sample_superposition

    model, _, _ = draw_model(table, n0, 0, seed)
    y = sample_superposition(model, H, n_samples, rng=np.random.default_rng([seed, 6, n0]))
    mean, cov = campbell_moments(model, H)
    return {"n0": n0, "y": y, "mean": mean, "var": np.diag(cov).copy()}


# ----------------------------------------------------------------------------- driver


def reproduce(
    quick: bool = False,
    *,
    out_dir="jointtrack-out",
    trials: int | None = None,
    seed: int = SEED,
    n0s=N0S,
    ratio_sets: int | None = None,
    ratio_states: int | None = None,
    hist_samples: int | None = None,
    methods=EXTRA_METHODS,
    progress: bool = False,
    console=None,
    write: bool = True,
) -> dict:
    """Tables I–IV, Example 1, Figures 1–5; write ``nannuru.json`` and the PNGs.

    Parameters
    ----------
    quick : bool
        :data:`QUICK_TRIALS` trials, :data:`QUICK_RATIO_SETS` × :data:`QUICK_RATIO_X`
        ratio states, fewer samples; explicit arguments win.
    out_dir : path
        Where ``nannuru.json`` and ``nannuru-figure{1..5}.png`` go (with ``write``).
    trials : int, optional
        Trials per row of Tables I–III, ≥ 2.
    seed : int
        Base seed ≥ 0.
    n0s : sequence of int
        Rows of Tables I–III (default 3…8).
    ratio_sets, ratio_states : int, optional
        Mean sets and states per set for Example 1 / Table IV.
    hist_samples : int, optional
        Samples of y per histogram (Figures 1–3).
    methods : sequence of str
        Dispatcher methods compared beside the Gaussian (default
        :data:`EXTRA_METHODS`); an unknown name is reported as not available.
    progress : bool
        Show a progress bar on ``console``.
    console : rich.console.Console, optional
    write : bool

    Returns
    -------
    dict
        Everything printed (JSON-ready once arrays are listed); ``files`` when written.
    """
    from rich.console import Console

    from jointtrack import __version__
    from jointtrack._console import progress_bar
    from jointtrack.assignment._checks import as_int
    from jointtrack.io import write_metrics

    trials = as_int(
        trials if trials is not None else (QUICK_TRIALS if quick else TRIALS), "trials", 2
    )
    seed = as_int(seed, "seed", 0)
    n0s = tuple(as_int(n, "n0s entry", 1, 12) for n in n0s)
    n_sets = as_int(ratio_sets or (QUICK_RATIO_SETS if quick else RATIO_SETS), "ratio_sets", 2)
    n_x = as_int(ratio_states or (QUICK_RATIO_X if quick else RATIO_X), "ratio_states", 2)
    n_hist = as_int(
        hist_samples or (QUICK_HIST_SAMPLES if quick else HIST_SAMPLES), "hist_samples", 10
    )
    methods = tuple(str(m) for m in methods)
    nv_repeats = QUICK_NV_REPEATS if quick else NV_REPEATS
    union_samples = QUICK_UNION_SAMPLES if quick else UNION_SAMPLES
    console = console or Console(quiet=True)
    wall0 = time.perf_counter()

    rows = {t: [] for t in TABLES}
    ratio_rows = []
    with progress_bar(console, enabled=progress) as bar:
        t1 = bar.add_task("Tables I-III (trials)", total=len(TABLES) * len(n0s) * trials)
        t2 = bar.add_task("Example 1, Table IV (mean sets)", total=len(RATIO_ROWS) * n_sets)
        for table in TABLES:
            for n0 in n0s:
                bar.update(t1, description=f"{TABLES[table][0]}, n0 = {n0}")
                rows[table].append(
                    table_row(
                        table,
                        n0,
                        trials,
                        seed,
                        nv_repeats=nv_repeats,
                        union_samples=union_samples,
                        methods=methods,
                        on_trial=lambda: bar.advance(t1),
                    )
                )
        for name, spec, paper in RATIO_ROWS:
            bar.update(t2, description=f"§E {name}")
            ratio_rows.append(
                ratio_row(
                    name,
                    spec,
                    paper,
                    n_sets,
                    n_x,
                    seed,
                    methods=methods,
                    on_set=lambda: bar.advance(t2),
                )
            )
    hists = {t: [histogram_data(t, n0, n_hist, seed) for n0 in HIST_N0] for t in TABLES}
    bins = {
        r["name"]: bin_plot_data(r["R"], r["R1"])
        for r in ratio_rows
        if r["name"] in (FIGURE4_ROW, FIGURE5_ROW)
    }
    result = {
        "experiment": "Nannuru & Coates, Gaussian approximation for superpositional sensors: "
        "Tables I-IV, Example 1, Figures 1-5",
        "jointtrack_version": __version__,
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": machine_info(),
        "settings": {
            "quick": quick,
            "trials": trials,
            "seed": seed,
            "n0": list(n0s),
            "H": PAPER["H"],
            "Sigma0": "0.25 I3",
            "Sigma_i": "I2",
            "region": f"{REGION:g} m x {REGION:g} m, means uniform",
            "y0": "sum of H mu_i over the Gaussian / Bernoulli means",
            "table1_cardinality": f"Poisson(n0) truncated at {CARD_MAX}, renormalised",
            "table2_r": "r_i ~ U[0.2, 1] per component and trial",
            "table3_iidc_part": "uniform over the region; cardinality uniform on {0, 1, ..., n0} "
            "(our choice: the report says only 'uniform discrete')",
            "truth": "Tables I, II: exact mixture enumeration (no Monte Carlo error; replaces "
            "N_s = 500,000 x 25 repeats); Table III: Rao-Blackwellised Monte Carlo, "
            f"{union_samples} samples per cardinality of the uniform part, multi-Bernoulli "
            "part exact; Example 1 / Table IV: exact ratio",
            "gaussian": "closed-form Campbell moments (no particle noise)",
            "gaussian_N_v": f"Campbell moments from N_v = {NV} particles per density, I1 averaged "
            f"over {nv_repeats} draws (the report's estimator)",
            "interval": "95 % Student-t interval of the mean over trials (lower end clipped at 0); "
            "two-sample: where another 25-trial mean (the report's) falls with 95 % probability",
            "ratio_sets": n_sets,
            "ratio_states_per_set": n_x,
            "ratio_x": "x ~ N(mu_j, diag(2, 2)), j uniform among the 4 means per state",
            "ratio_r": "Example 1: r_i ~ U[r_lo, 1] per component and mean set; Table IV: r_i = r",
            "correlation": "Pearson of R and R1 (not logs) over all states; 95 % interval: "
            f"bootstrap over mean sets ({BOOTSTRAP} resamples)",
            "histogram_samples": n_hist,
            "seed_scheme": "trial draws numpy.random.default_rng([seed, table, n0, trial])",
        },
        "paper": PAPER,
        "tables": {t: [{k: v for k, v in r.items()} for r in rows[t]] for t in TABLES},
        "ratio": [{k: v for k, v in r.items() if k not in ("R", "R1")} for r in ratio_rows],
        "figure_bins": bins,
        "histograms": {
            t: [{"n0": h["n0"], "mean": h["mean"], "var": h["var"]} for h in hs]
            for t, hs in hists.items()
        },
    }
    result["notes"] = _notes(result)
    result["seconds"] = time.perf_counter() - wall0
    if write:
        from jointtrack.experiments import nannuru_plots

        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        files = {"json": str(out_dir / "nannuru.json")}
        for k, t in enumerate(TABLES, start=1):
            files[f"figure{k}"] = str(
                nannuru_plots.plot_histograms(
                    out_dir / f"nannuru-figure{k}.png",
                    hists[t],
                    f"Nannuru & Coates Figure {k} ({TABLES[t][0]})",
                )
            )
        files["figure4"] = (
            str(
                nannuru_plots.plot_bins(
                    out_dir / "nannuru-figure4.png",
                    bins[FIGURE4_ROW],
                    "Nannuru & Coates Figure 4: R vs R₁, Example 1, $r_i \\sim U[0.5, 1]$",
                )
            )
            if FIGURE4_ROW in bins
            else None
        )
        files["figure5"] = (
            str(
                nannuru_plots.plot_bins(
                    out_dir / "nannuru-figure5.png",
                    bins[FIGURE5_ROW],
                    "Nannuru & Coates Figure 5: R vs R₁, Table IV, $r_i = 0.95$",
                )
            )
            if FIGURE5_ROW in bins
            else None
        )
        result["files"] = {k: v for k, v in files.items() if v is not None}
        write_metrics(result, out_dir / "nannuru.json")
    return result


def _inside(iv: dict, value, lo: str = "lo", hi: str = "hi") -> bool | None:
    if value is None or iv.get(lo) is None:
        return None
    return iv[lo] <= value <= iv[hi]


def _notes(result: dict) -> list[str]:
    """What the numbers say against the report, worded from the numbers."""
    notes = []
    for t, rows in result["tables"].items():
        g = [r for r in rows if r["paper"] is not None]
        inside = [_inside(r["methods"]["gaussian"], r["paper"]) for r in g]
        k = sum(bool(v) for v in inside)
        k2 = sum(
            bool(_inside(r["methods"]["gaussian"], r["paper"], "paper_lo", "paper_hi")) for r in g
        )
        worst = max(
            g, key=lambda r: abs((r["methods"]["gaussian"]["mean"] or 0) - r["paper"]), default=None
        )
        if worst is not None:
            notes.append(
                f"{TABLES[t][0]}: the report's value lies inside our Gaussian column's 95 % "
                f"interval in {k} of {len(g)} rows, inside the two-sample interval (where "
                f"another {PAPER_TRIALS}-trial mean falls) in {k2} of {len(g)}; largest gap at "
                f"n0 = {worst['n0']} "
                f"(ours {worst['methods']['gaussian']['mean']:.1f} vs {worst['paper']:.2f})"
            )
    for r in result["ratio"]:
        c = r["methods"]["gaussian"]
        if c["corr"] is not None and r["paper"] is not None:
            notes.append(
                f"§E {r['name']}: corr(R, R1) = {c['corr']:.2f} "
                f"[{_f(c['lo'], '.2f')}, {_f(c['hi'], '.2f')}] vs the report's {r['paper']:.2f}"
            )
    return notes


# ----------------------------------------------------------------------------- printing


def _cell(m: dict) -> str:
    if m["status"] != "ok":
        return "n/a"
    if m["mean"] is None:
        return "–"
    if m["lo"] is None:
        return f"{m['mean']:.1f}"
    return f"{m['mean']:.1f} [{m['lo']:.1f}, {m['hi']:.1f}]"


def report_tables(result: dict) -> list:
    """The rich tables: Tables I–III (percentage error) and §E (correlations)."""
    out = []
    for t, rows in result["tables"].items():
        if not rows:
            continue
        cols = list(rows[0]["methods"])
        tab = _table(
            f"{TABLES[t][0]} — percentage error (13), mean [95 % interval] over "
            f"{rows[0]['trials']} trials; truth: {rows[0]['truth']}",
            ["n0", "paper", "gaussian two-sample 95 %", *cols, "truth s.e."],
        )
        for r in rows:
            g = r["methods"].get("gaussian", {})
            two = (
                f"[{g['paper_lo']:.1f}, {g['paper_hi']:.1f}] "
                + ("∋" if _inside(g, r["paper"], "paper_lo", "paper_hi") else "∌")
                if g.get("paper_lo") is not None and r["paper"] is not None
                else "–"
            )
            tab.add_row(
                str(r["n0"]),
                _f(r["paper"], ".2f"),
                two,
                *[_cell(r["methods"][c]) for c in cols],
                _f(r["truth_std_error_mean"], ".4f") if r["truth"] != "exact" else "exact",
            )
        out.append(tab)
    rr = result["ratio"]
    if rr:
        cols = list(rr[0]["methods"])
        tab = _table(
            f"Example 1 / Table IV — corr(R, R_method), {rr[0]['mean_sets']} mean sets × "
            f"{rr[0]['states_per_set']} states, [95 % bootstrap interval]; R exact",
            ["row", "paper", *cols],
        )
        for r in rr:
            cells = []
            for c in cols:
                m = r["methods"][c]
                cells.append(
                    "n/a"
                    if m["status"] != "ok"
                    else f"{_f(m['corr'], '.3f')} [{_f(m['lo'], '.2f')}, {_f(m['hi'], '.2f')}]"
                )
            tab.add_row(r["name"], _f(r["paper"], ".2f"), *cells)
        out.append(tab)
    return out


def print_report(result: dict, console) -> None:
    """Print the settings line, the tables, the unavailable methods, notes and files."""
    s = result["settings"]
    console.print(
        f"Nannuru & Coates (2015): {s['trials']} trials per row, seed {s['seed']}"
        f"{' (quick)' if s['quick'] else ''}; §E {s['ratio_sets']} mean sets × "
        f"{s['ratio_states_per_set']} states; {result['seconds']:.1f} s.",
        markup=False,
        highlight=False,
    )
    for key in (
        "truth",
        "gaussian",
        "gaussian_N_v",
        "table3_iidc_part",
        "y0",
        "ratio_x",
        "ratio_r",
        "correlation",
    ):
        console.print(f"  {key}: {s[key]}", markup=False, highlight=False, style="dim")
    for t in report_tables(result):
        console.print(t)
    seen = set()
    for rows in [*result["tables"].values(), [{"methods": r["methods"]} for r in result["ratio"]]]:
        for r in rows:
            for c, m in r["methods"].items():
                if m["status"] != "ok" and (c, m["status"]) not in seen:
                    seen.add((c, m["status"]))
                    console.print(
                        f"{c}: {m['status']}", style="yellow", markup=False, highlight=False
                    )
    for n in result["notes"]:
        console.print(f"Note: {n}", style="dim", markup=False, highlight=False)
    if "files" in result:
        console.print("wrote " + ", ".join(result["files"].values()), markup=False, highlight=False)
