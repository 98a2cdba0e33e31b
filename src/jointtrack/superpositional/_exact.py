r"""The exact likelihood I (2)–(3) and ratio R(x) (16) by Gaussian-mixture enumeration.

S. Nannuru and M. Coates, "Gaussian approximation for superpositional sensors",
technical report, McGill University, 2015 (equation numbers are that report's).

With g(x) = Hx and Gaussian single-target densities, y = Σ_{x ∈ Ξ} Hx given
which components produced the points is Gaussian, so Q of (3) is a finite
Gaussian mixture and

.. math::

    I = \sum_t c_t\, \mathcal N(y_0;\ \textstyle\sum_k n_{tk} H m_k,\
        \Sigma_0 + \sum_k n_{tk} H P_k H^T),

a sum over *terms* t, each a vector of counts n_{tk} of points drawn from
basis Gaussian k:

* multi-Bernoulli {(r_i, N(m_i, P_i))}: the 2ⁿ subsets S (n_{ti} ∈ {0, 1}),
  c = Π_{i∈S} r_i Π_{i∉S} (1 − r_i). Components with r_i = 1 are always present
  and r_i = 0 never, so only the components with 0 < r_i < 1 are enumerated.
* IIDC (π, Σ_k w_k N(m_k, P_k)): every cardinality n and composition
  n_{t1} + … + n_{tK} = n, c = π(n) · n!/Π n_{tk}! · Π w_k^{n_{tk}} (multinomial);
  Σ_n C(n + K − 1, K − 1) terms.
* Poisson: as IIDC with the Poisson pmf truncated where its tail is below
  1e-16 (the dropped mass is reported in ``info["truncated_mass"]``).
* Union: the product of the parts' term sets (counts concatenated, c multiplied).

The terms are evaluated by a numba kernel (one Cholesky per term, a streaming
log-sum-exp over terms), so I never underflows to 0 before the logarithm. The
ratio uses the reduced mixture of :func:`~jointtrack.superpositional.models.reduced_mixture`:
log R(x) = log Σ_k w_k(x) I_k(y0 − Hx) − log I(y0).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from scipy.special import gammaln, logsumexp

from jointtrack._numba_linalg import cholesky_lower, mahalanobis_sq
from jointtrack.assignment._checks import as_int
from jointtrack.errors import ExactLimitError
from jointtrack.superpositional.models import (
    IIDC,
    MultiBernoulli,
    Poisson,
    reduced_mixture,
)

__all__ = ["DEFAULT_MAX_TERMS", "log_likelihood", "log_likelihood_ratio", "n_terms"]

#: default budget of mixture terms for method "exact"
DEFAULT_MAX_TERMS = 2**20
_LOG_2PI = math.log(2.0 * math.pi)


# ----------------------------------------------------------------------------- kernels


@numba.njit(cache=True)
def _compositions(n, K):
    """All compositions of n into K non-negative parts, (C(n+K−1, K−1), K) int64.

    int64, not a narrower type: a Poisson cardinality near a mean of 1e5 exceeds 2^15.
    """
    count = 1
    for j in range(1, K):
        count = count * (n + j) // j
    out = np.zeros((count, K), np.int64)
    a = np.zeros(K, np.int64)
    a[0] = n
    for row in range(count):
        for k in range(K):
            out[row, k] = a[k]
        if K == 1 or a[K - 1] == n:
            break
        h = K - 2
        while a[h] == 0:
            h -= 1
        t = a[K - 1]
        a[K - 1] = 0
        a[h] -= 1
        a[h + 1] = t + 1
    return out


@numba.njit(cache=True)
def _logsumexp_terms(counts, log_coef, bmean, bcov, base_cov, Y):
    """log Σ_t exp(log_coef[t]) N(Y[l]; counts[t] @ bmean, base_cov + Σ_k counts[t,k] bcov[k]).

    Y holds the targets (y0 minus any fixed offset), one row per evaluation point.
    """
    T, K = counts.shape
    L, d = Y.shape
    run_max = np.full(L, -np.inf)
    run_sum = np.zeros(L)
    mu = np.empty(d)
    C = np.empty((d, d))
    z = np.empty(d)
    half_d_log2pi = 0.5 * d * math.log(2.0 * math.pi)
    for t in range(T):
        lc = log_coef[t]
        if lc == -np.inf:
            continue
        for i in range(d):
            mu[i] = 0.0
            for j in range(d):
                C[i, j] = base_cov[i, j]
        for k in range(K):
            c = counts[t, k]
            if c != 0:
                for i in range(d):
                    mu[i] += c * bmean[k, i]
                    for j in range(i + 1):
                        C[i, j] += c * bcov[k, i, j]
        ok, logdet = cholesky_lower(C, C)  # in place
        if not ok:
            # the noise covariance is validated positive definite and the rest is a sum of
            # PSD covariances, so only rounding of an ill-conditioned sum gets here: an
            # error, as method "gaussian" gives, rather than a NaN likelihood
            raise ValueError("a mixture term's covariance is not positive definite in float")
        const = lc - 0.5 * logdet - half_d_log2pi
        for ell in range(L):
            val = const - 0.5 * mahalanobis_sq(C, Y[ell], mu, z)
            m = run_max[ell]
            if val > m:
                run_sum[ell] = run_sum[ell] * math.exp(m - val) + 1.0
                run_max[ell] = val
            else:
                run_sum[ell] += math.exp(val - m)
    out = np.empty(L)
    for ell in range(L):
        out[ell] = run_max[ell] + math.log(run_sum[ell]) if run_sum[ell] > 0 else -np.inf
    return out


# ----------------------------------------------------------------------------- term sets


class _Terms:
    """A Gaussian mixture in y-space: counts (T, K) over basis Gaussians, log coefficients (T,)."""

    __slots__ = ("counts", "log_coef", "bmean", "bcov", "offset_mean", "offset_cov", "info")

    def __init__(self, counts, log_coef, bmean, bcov, offset_mean, offset_cov, info=None):
        self.counts, self.log_coef = counts, log_coef
        self.bmean, self.bcov = bmean, bcov
        self.offset_mean, self.offset_cov = offset_mean, offset_cov
        self.info = info or {}


def _require_gaussian(model, m):
    if not hasattr(m, "H"):
        raise ValueError(
            "method 'exact' needs a linear measurement g(x) = Hx; use 'montecarlo', "
            "'saddlepoint' or 'gaussian' for a FunctionMeasurement"
        )


def n_terms(model) -> int:
    """Number of mixture terms the exact method would enumerate for ``model``."""
    if isinstance(model, MultiBernoulli):
        return 2 ** int(((model.r > 0.0) & (model.r < 1.0)).sum())
    if isinstance(model, IIDC | Poisson):
        _check_spatial(model)
        pmf = _pmf(model)[0]
        K = int((model.spatial.weights > 0).sum())
        return sum(math.comb(n + K - 1, K - 1) for n in np.flatnonzero(pmf > 0))
    return math.prod(n_terms(p) for p in model.parts)


def _check_spatial(model):
    if model.spatial.kind != "gaussian":
        raise ValueError(
            f"method 'exact' needs Gaussian-mixture spatial densities; this {type(model).__name__} "
            f"has a {model.spatial.kind} one (use 'montecarlo')"
        )


def _pmf(model):
    if isinstance(model, Poisson):
        return model.cardinality_pmf_truncated()
    return model.cardinality_pmf, 0.0


def _terms(model, m) -> _Terms:
    H = m.H
    dy = H.shape[0]
    if isinstance(model, MultiBernoulli):
        if model.means is None:
            raise ValueError(
                "method 'exact' needs Gaussian multi-Bernoulli components; this one has particle "
                "components (use 'montecarlo')"
            )
        r = model.r
        frac = np.flatnonzero((r > 0.0) & (r < 1.0))
        sure = np.flatnonzero(r == 1.0)
        bmean = model.means @ H.T
        bcov = H @ model.covs @ H.T
        n = frac.size
        bits = ((np.arange(2**n)[:, None] >> np.arange(n)[None]) & 1).astype(np.int64)
        lr, l1r = np.log(r[frac]), np.log1p(-r[frac])
        log_coef = bits @ (lr - l1r) + l1r.sum()
        return _Terms(
            bits,
            log_coef,
            bmean[frac],
            bcov[frac],
            bmean[sure].sum(axis=0) if sure.size else np.zeros(dy),
            bcov[sure].sum(axis=0) if sure.size else np.zeros((dy, dy)),
            {"subsets": 2**n},
        )
    if isinstance(model, IIDC | Poisson):
        _check_spatial(model)
        pmf, tail = _pmf(model)
        sp = model.spatial
        keep = np.flatnonzero(sp.weights > 0)
        lw = np.log(sp.weights[keep])
        K = keep.size
        blocks, coefs = [], []
        for n in np.flatnonzero(pmf > 0):
            comp = _compositions(int(n), K)
            lc = math.log(pmf[n]) + gammaln(n + 1.0) - gammaln(comp + 1.0).sum(axis=1) + comp @ lw
            blocks.append(comp)
            coefs.append(lc)
        counts = np.concatenate(blocks, axis=0) if blocks else np.zeros((1, K), np.int64)
        log_coef = np.concatenate(coefs) if coefs else np.array([-np.inf])
        return _Terms(
            counts,
            log_coef,
            sp.means[keep] @ H.T,
            H @ sp.covs[keep] @ H.T,
            np.zeros(dy),
            np.zeros((dy, dy)),
            {"truncated_mass": tail} if isinstance(model, Poisson) else {},
        )
    out = None
    for p in model.parts:
        t = _terms(p, m)
        out = t if out is None else _product(out, t)
    return out


def _product(a: _Terms, b: _Terms) -> _Terms:
    Ta, Tb = a.counts.shape[0], b.counts.shape[0]
    counts = np.concatenate([np.repeat(a.counts, Tb, axis=0), np.tile(b.counts, (Ta, 1))], axis=1)
    log_coef = (a.log_coef[:, None] + b.log_coef[None, :]).ravel()
    info = dict(a.info)
    if "truncated_mass" in b.info:
        info["truncated_mass"] = info.get("truncated_mass", 0.0) + b.info["truncated_mass"]
    return _Terms(
        counts,
        log_coef,
        np.concatenate([a.bmean, b.bmean]),
        np.concatenate([a.bcov, b.bcov]),
        a.offset_mean + b.offset_mean,
        a.offset_cov + b.offset_cov,
        info,
    )


def _budget(model, max_terms) -> int:
    max_terms = as_int(max_terms, "max_terms", minimum=1)
    need = n_terms(model)
    if need > max_terms:
        raise ExactLimitError(
            f"method 'exact' would enumerate {need} mixture terms, more than the budget "
            f"max_terms = {max_terms}; raise max_terms or use 'hybrid'/'montecarlo'"
        )
    return need


def _evaluate(model, m, noise_cov, Y) -> tuple[np.ndarray, dict]:
    t = _terms(model, m)
    Yc = np.ascontiguousarray(Y - t.offset_mean[None])
    base = np.ascontiguousarray(noise_cov + t.offset_cov)
    out = _logsumexp_terms(
        np.ascontiguousarray(t.counts),
        np.ascontiguousarray(t.log_coef, dtype=np.float64),
        np.ascontiguousarray(t.bmean, dtype=np.float64),
        np.ascontiguousarray(t.bcov, dtype=np.float64),
        base,
        Yc,
    )
    return out, {"terms": int(t.counts.shape[0]), **t.info}


def log_likelihood(y0, model, measurement, noise_cov, *, max_terms=DEFAULT_MAX_TERMS):
    """``(log I, info)`` by enumeration of the Gaussian mixture (module docstring)."""
    _require_gaussian(model, measurement)
    _budget(model, max_terms)
    out, info = _evaluate(model, measurement, noise_cov, y0[None])
    return float(out[0]), info


def log_likelihood_ratio(
    y0, x, model, measurement, noise_cov, *, max_terms=DEFAULT_MAX_TERMS, part=None
):
    """log R(x) (16) for states x (L, dx): reduced-mixture numerator over log I."""
    _require_gaussian(model, measurement)
    _budget(model, max_terms)
    lw, subs = reduced_mixture(model, x, part)
    for s in subs:
        _budget(s, max_terms)
    den = _evaluate(model, measurement, noise_cov, y0[None])[0][0]
    Y = y0[None] - measurement(x)
    num = np.stack([_evaluate(s, measurement, noise_cov, Y)[0] for s in subs], axis=1)
    return logsumexp(lw + num, axis=1) - den
