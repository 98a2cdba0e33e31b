r"""Unbiased Monte Carlo estimate of the permanent by sequential importance sampling.

Estimator
---------
Let A be non-negative n×m (n ≤ m). First A is scaled by the exact powers of two
of the assignment dual (every entry ≤ ~1, the best assignment ≈ 1; without this,
wide-range input left the mass on entries that underflowed in the proposal and
estimates off by e^300 came with ``rel_stderr`` 0), then *balanced*: B = diag(x) A diag(y)
with every row of B summing to 1 and the columns as close as possible to the
doubly-stochastic target (log-domain Sinkhorn iterations; for n < m the scaling
is that of the square matrix [A; 1] with m − n padding rows of ones, held as one
row of multiplicity m − n, restricted to the rows of A). Entries of A that lie
in no row-saturating matching are set to 0 first (they contribute nothing).

Each sample then builds an injective map σ row by row (rows with fewer allowed
columns first): with F_t the columns still free when row t is reached,

.. math::

    w_t = \sum_{j \in F_t} b_{tj}, \qquad
    \Pr[\sigma(t) = j] = b_{tj} / w_t \quad (j \in F_t),

and if w_t = 0 the sample stops with weight 0. The importance weight is

.. math::

    W = \frac{\prod_t a_{t\sigma(t)}}{\Pr[\sigma]}
      = \prod_t \frac{w_t}{x_t\, y_{\sigma(t)}} ,

so E[W] = Σ_σ Π_t a_{tσ(t)} = Per(A) exactly (every injective σ with positive
weight has positive probability; dead ends contribute 0): the sample mean of N
independent weights is an unbiased estimate of Per(A), and its relative standard
error is estimated by s_W / (W̄ √N) (sample standard deviation s_W). This is the
sequential importance sampler of Rasmussen (1994) / Beichl & Sullivan (1999)
with Sinkhorn-balanced proposals (Schaub eq. 38 for the scaling). All weights are
handled as logarithms and combined by log-sum-exp, so e.g. 100×100 matrices
with entries ~1e-50 (log Per ≈ −11 150) are fine. The scaling does not need to
converge: any positive x, y give an unbiased estimator; balancing only reduces
the variance.

The loop over samples runs in a numba kernel (``cache=True``) on uniforms drawn
from the given numpy Generator, so results are reproducible for a fixed seed.
Cost: O(N·n·m).

Measured accuracy
-----------------
For iid uniform(0, 1) square matrices the log-weights are nearly normal and
the relative standard error at N samples is about c(n)/√N with c(n) ≈ 0.75–0.9
for n = 12–20. Measured at N = 10⁴ (20 matrices and seeds for each n, exact
values by Ryser's formula, ``thewalrus.perm``):

=====  ===================  =========================  ====================
n      median rel_stderr    median |est/exact − 1|     max |est/exact − 1|
=====  ===================  =========================  ====================
12     0.0075               0.0048                     0.0135
20     0.0088               0.0058                     0.0157
=====  ===================  =========================  ====================

with |est/exact − 1| < 2·rel_stderr in all 40 runs; one estimate takes
≈ 7 ms (n = 12) and ≈ 16 ms (n = 20), ≈ 0.2 s for 100×100. The tests assert
|est/exact − 1| ≤ 5·rel_stderr for n ≤ 7 (brute force) and n = 12 (subset DP),
and rel_stderr < 0.02 for uniform 12×12 at 10⁴ samples
(``tests/test_permanent_approx.py``). For sparse or very unbalanced matrices
the weights are heavier-tailed and rel_stderr (itself an estimate) can be
optimistic; dead-end samples (weight 0) are counted in the mean. The result
carries Kish's effective sample size (Σw)²/Σw² and ``converged = ESS ≥
min(50, N/10)``; below that a RuntimeWarning is issued. No sample-based
diagnostic can see mass the proposal reaches with probability ≪ 1/N. Each
row's proposal is normalised by its largest entry, so only entries below
1e-308 of their row's largest are never proposed (a bias of that order).

References
----------
L. E. Rasmussen, "Approximating the permanent: a simple approach", Random
Structures & Algorithms 5(2):349–361, 1994.
I. Beichl, F. Sullivan, "Approximating the permanent via importance sampling
with application to the dimer covering problem", J. Comput. Phys.
149(1):128–147, 1999.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numba
import numpy as np
from scipy.special import logsumexp, ndtri

from jointtrack.assignment._checks import as_int, as_rng
from jointtrack.permanent.bethe import _allowed_support, _matrix, _scaling_exponents

_LN2 = math.log(2.0)

__all__ = ["SampledPermanent", "sample_permanent"]


@dataclass(frozen=True)
class SampledPermanent:
    """Result of :func:`sample_permanent`.

    Attributes
    ----------
    log_value : float
        log of the estimate (the estimate itself is unbiased for Per(A); its
        log is not). ``-inf`` only if every sample hit a dead end (a
        RuntimeWarning is issued then).
    value : float
        the estimate, exp(log_value); 0.0 on underflow (log_value < −745),
        ``inf`` on overflow (log_value > 709) — prefer `log_value`.
    rel_stderr : float
        estimated relative standard error of the estimate, s_W / (W̄ √N)
        (``inf`` if all samples were dead ends, 0.0 for n = 0).
    n_samples : int
        number of samples N.
    effective_sample_size : float
        Kish's effective sample size (Σw)² / Σw² of the importance weights
        (N when all weights are equal, 1 when one sample dominates).
    converged : bool
        False when the effective sample size is tiny (below min(50, N/10)): the
        weights are then dominated by a few samples, `rel_stderr` is itself
        unreliable and the estimate may be far off (a RuntimeWarning is issued).
    marginals, marginals_stderr : (n, m) ndarray or None
        With ``marginals=True``: the self-normalised importance estimate of
        P[t, j] = A[t, j]·Per(A₍₋ₜ,₋ⱼ₎)/Per(A), Σ_s W_s [σ_s(t) = j] / Σ_s W_s,
        and its delta-method standard error
        √(Σ_s W_s² ([σ_s(t) = j] − P̂)²) / Σ_s W_s (consistent, not unbiased:
        a ratio of unbiased sums).
    """

    log_value: float
    value: float
    rel_stderr: float
    n_samples: int
    effective_sample_size: float = math.nan
    converged: bool = True
    marginals: np.ndarray | None = None
    marginals_stderr: np.ndarray | None = None

    def confidence_interval(self, level: float = 0.95, *, log: bool = False):
        """Normal-approximation (CLT) confidence interval for Per(A).

        Per(A) ∈ value · (1 ± z·rel_stderr) with z the two-sided normal quantile
        of `level`; the lower end is clipped at 0. With ``log=True`` the ends
        are returned as logarithms (log 0 = −inf), computed without forming
        `value`, so they are finite even when `value` over- or underflows.
        The interval inherits the CLT approximation and the estimated standard
        error: for heavy-tailed weights (sparse, unbalanced A, few samples) it
        can be too narrow.
        """
        level = float(level)
        if not (0.0 < level < 1.0):
            raise ValueError(f"level must lie strictly between 0 and 1, got {level}")
        z = float(ndtri(0.5 + level / 2.0))
        half = z * self.rel_stderr
        if not math.isfinite(self.log_value):
            lo_log, hi_log = -math.inf, (math.inf if self.rel_stderr > 0 else self.log_value)
        else:
            lo_log = self.log_value + math.log1p(-half) if half < 1.0 else -math.inf
            hi_log = self.log_value + math.log1p(half) if math.isfinite(half) else math.inf
        if log:
            return lo_log, hi_log
        return _safe_exp(lo_log), _safe_exp(hi_log)


def _safe_exp(x: float) -> float:
    if x == -math.inf:
        return 0.0
    try:
        return math.exp(x)
    except OverflowError:
        return math.inf


def _balance(logA: np.ndarray, n_pad: int, max_sweeps: int = 200, tol: float = 1e-6):
    """Log-domain Sinkhorn scaling of [A; 1_(n_pad × m)] towards doubly stochastic.

    Returns (lx, ly): log row factors of A's rows and log column factors, such
    that B = exp(logA + lx + ly) has rows summing to 1. `logA` is −inf off the
    support. Stops early when the column sums are within `tol` of 1.
    """
    n, m = logA.shape
    ly = np.zeros(m)
    log_k = math.log(n_pad) if n_pad > 0 else -math.inf
    lx = -logsumexp(logA, axis=1)
    for _ in range(max_sweeps):
        ld = -logsumexp(ly) if n_pad > 0 else -math.inf  # log factor of a padding row
        col = np.logaddexp(logsumexp(logA + lx[:, None], axis=0), log_k + ld)
        # col = log(current column sum / y_j): column sums of the scaled matrix are
        # exp(col + ly); stop when they are all ≈ 1
        if np.max(np.abs(col + ly)) < tol:
            break
        ly = -col
        lx = -logsumexp(logA + ly[None, :], axis=1)
    lx = -logsumexp(logA + ly[None, :], axis=1)
    return lx, ly


@numba.njit(cache=True)
def _sis_kernel(B, ly, U, out, picks):  # pragma: no cover - compiled
    """Sequential importance sampling: one log-weight per row of U (see module doc).

    ``picks`` (n_s, n) receives each sample's column per row (for the marginal
    estimates), or has 0 columns when they are not wanted.
    """
    n_s, n = U.shape
    record = picks.shape[1] > 0
    m = B.shape[1]
    free = np.empty(m, dtype=np.bool_)
    for s in range(n_s):
        for j in range(m):
            free[j] = True
        logw = 0.0
        for t in range(n):
            w = 0.0
            for j in range(m):
                if free[j]:
                    w += B[t, j]
            if not w > 0.0:
                logw = -np.inf
                break
            target = U[s, t] * w
            acc = 0.0
            pick = -1
            for j in range(m):
                if free[j] and B[t, j] > 0.0:
                    pick = j
                    acc += B[t, j]
                    if acc > target:
                        break
            free[pick] = False
            if record:
                picks[s, t] = pick
            logw += math.log(w) - ly[pick]
        out[s] = logw


def sample_permanent(
    A, n_samples: int = 10_000, *, rng=None, marginals: bool = False
) -> SampledPermanent:
    r"""Unbiased importance-sampling estimate of Per(A) with a standard error.

    See the module docstring for the estimator (Sinkhorn-balanced sequential
    importance sampling, E[W] = Per(A)) and the measured accuracy (uniform
    20×20, 10⁴ samples: median relative error 0.6 %, rel_stderr ≈ 0.9 %).

    Parameters
    ----------
    A : array_like, shape (n, m), n ≤ m
        non-negative finite entries.
    n_samples : int ≥ 2
        number of independent samples N; the cost is O(N·n·m).
    rng : numpy.random.Generator, int or None
        source of randomness (an int is a seed; None draws fresh entropy).
    marginals : bool
        also estimate every assignment marginal from the same samples (memory
        N·n integers).

    Returns
    -------
    SampledPermanent
        ``log_value``, ``value``, ``rel_stderr``, ``n_samples``,
        ``confidence_interval(level)`` and, with ``marginals=True``,
        ``marginals`` and ``marginals_stderr``.

    Raises
    ------
    ValueError
        bad `A`, `n_samples` or `rng`.
    InfeasibleAssignmentError
        if no assignment of the rows to distinct columns has positive weight.
    """
    A = _matrix(A)
    n_samples = as_int(n_samples, "n_samples", 2)
    gen = as_rng(rng)
    n, m = A.shape
    if n == 0:
        empty = np.zeros((0, m)) if marginals else None
        return SampledPermanent(0.0, 1.0, 0.0, n_samples, float(n_samples), True, empty, empty)

    allowed = _allowed_support(A > 0)  # raises InfeasibleAssignmentError
    order = np.argsort(allowed.sum(axis=1), kind="stable")
    allowed = allowed[order]
    with np.errstate(divide="ignore"):
        logA = np.where(allowed, np.log(np.where(allowed, A[order], 1.0)), -np.inf)
    # Proposal: the power-of-two dual scaling first (best assignment ≈ 1, nothing
    # out of range), then log-space Sinkhorn sweeps. Any positive factors keep the
    # estimator unbiased (the column factors are divided out per pick), so the
    # column scaling is allowed even for n < m.
    er, ec = _scaling_exponents(np.where(allowed, A[order], 0.0))
    ls = logA + (er[:, None] + ec[None, :]) * _LN2
    lx, ly = _balance(ls, m - n)
    lx = lx + er * _LN2
    ly = ly + ec * _LN2
    logB = logA + lx[:, None] + ly[None, :]
    lx = lx - np.max(logB, axis=1)  # every row's largest proposal entry is exactly 1
    B = np.ascontiguousarray(np.exp(logA + lx[:, None] + ly[None, :]))

    logw = np.empty(n_samples)
    picks = np.zeros((n_samples, n if marginals else 0), np.int64)
    chunk = max(1, 1_000_000 // n)
    for start in range(0, n_samples, chunk):
        stop = min(n_samples, start + chunk)
        U = gen.random((stop - start, n))
        _sis_kernel(B, ly, U, logw[start:stop], picks[start:stop])

    shift = float(np.max(logw))
    if shift == -math.inf:
        warnings.warn(
            f"all {n_samples} importance samples hit a dead end (weight 0); the estimate is 0 "
            "although the permanent is positive — use more samples or an exact method",
            RuntimeWarning,
            stacklevel=2,
        )
        return SampledPermanent(-math.inf, 0.0, math.inf, n_samples, 0.0, False)
    w = np.exp(logw - shift)
    mean = float(np.mean(w))
    rel_stderr = float(np.std(w, ddof=1) / (mean * math.sqrt(n_samples)))
    ess = float(np.sum(w) ** 2 / np.sum(w * w))
    converged = ess >= min(50.0, 0.1 * n_samples)
    if not converged:
        warnings.warn(
            f"importance sampling did not converge: effective sample size {ess:.3g} of "
            f"{n_samples} samples; the estimate and its standard error are unreliable — use "
            "more samples or an exact method",
            RuntimeWarning,
            stacklevel=2,
        )
    log_value = shift + math.log(mean) - float(np.sum(lx))
    P = P_err = None
    if marginals:
        P, P_err = _sampled_marginals(w, picks, order, m)
    return SampledPermanent(
        log_value, _safe_exp(log_value), rel_stderr, n_samples, ess, bool(converged), P, P_err
    )


def _sampled_marginals(w, picks, order, m):
    """Self-normalised marginal estimates and their delta-method standard errors."""
    n_s, n = picks.shape
    live = w > 0  # dead ends carry no assignment
    w, picks = w[live], picks[live]
    total = w.sum()
    rows = np.broadcast_to(np.arange(n), picks.shape)
    S1 = np.zeros((n, m))
    S2 = np.zeros((n, m))
    np.add.at(S1, (rows, picks), w[:, None])
    np.add.at(S2, (rows, picks), (w * w)[:, None])
    P = S1 / total
    # Σ_s w_s² ([σ_s(t)=j] − P)² = S2 (1 − 2P) + P² Σ_s w_s²
    var = np.maximum(S2 * (1.0 - 2.0 * P) + P * P * np.sum(w * w), 0.0) / (total * total)
    out, err = np.empty_like(P), np.empty_like(P)
    out[order], err[order] = P, np.sqrt(var)  # undo the row order of the sampler
    return np.clip(out, 0.0, 1.0), err
