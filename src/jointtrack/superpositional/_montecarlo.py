r"""Monte Carlo estimates of the likelihood I (2)–(3) and ratio R(x) (16).

S. Nannuru and M. Coates, "Gaussian approximation for superpositional sensors",
technical report, McGill University, 2015 (equation numbers are that report's).

.. math::

    \hat I = \frac1N \sum_{s=1}^N \mathcal N_{\Sigma_0}(y_0 - y_s), \qquad
    y_s = \zeta(\Xi_s) \sim Q,

with the y_s drawn by :func:`~jointtrack.superpositional.models.sample_superposition`
(vectorised, seeded). The standard error of log Î is the delta-method value
sd(w)/(√N · mean(w)) of the weights w_s = N_{Σ0}(y0 − y_s), computed in log
space. The ratio's numerator is Σ_k w_k(x) Î_k(y0 − g(x)) over the reduced
mixture of :func:`~jointtrack.superpositional.models.reduced_mixture`, one set of
samples per mixture member shared by all states x.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import logsumexp

from jointtrack.assignment._checks import as_int, as_rng
from jointtrack.superpositional.models import reduced_mixture

__all__ = ["DEFAULT_SAMPLES", "log_likelihood", "log_likelihood_ratio", "log_weights"]

#: default number of sampled sets
DEFAULT_SAMPLES = 100_000
#: entries of one (states × samples) block of the ratio's numerator
_BLOCK = 4_000_000
_LOG_2PI = math.log(2.0 * math.pi)


def log_weights(Y: np.ndarray, ys: np.ndarray, noise_cov: np.ndarray) -> np.ndarray:
    """log N_{Σ0}(Y[l] − ys[s]) as an (L, S) array, in blocks of ``_BLOCK`` entries."""
    chol = np.linalg.cholesky(noise_cov)
    d = Y.shape[1]
    const = -np.log(np.diag(chol)).sum() - 0.5 * d * _LOG_2PI
    # whiten once: N(Y - y) depends on L⁻¹Y − L⁻¹y
    inv = np.linalg.inv(chol).T
    zY, zs = Y @ inv, ys @ inv
    out = np.empty((Y.shape[0], ys.shape[0]))
    step = max(1, _BLOCK // max(1, ys.shape[0]))
    for a in range(0, Y.shape[0], step):
        diff = zY[a : a + step, None, :] - zs[None]
        out[a : a + step] = const - 0.5 * np.einsum("lsd,lsd->ls", diff, diff)
    return out


def _estimate(lw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row: log of the sample mean of exp(lw) and the delta-method std error of that log."""
    n = lw.shape[1]
    top = lw.max(axis=1, keepdims=True)
    top = np.where(np.isfinite(top), top, 0.0)
    w = np.exp(lw - top)
    mean = w.mean(axis=1)
    sd = w.std(axis=1, ddof=1) if n > 1 else np.zeros(lw.shape[0])
    with np.errstate(divide="ignore", invalid="ignore"):
        log_mean = np.log(mean) + top[:, 0]
        se = np.where(mean > 0, sd / (math.sqrt(n) * mean), np.inf)
    return log_mean, se


def _samples(model, m, n, rng):
    return model._sample_y(m, n, rng)


def log_likelihood(y0, model, measurement, noise_cov, *, n_samples=DEFAULT_SAMPLES, rng=None):
    """``(log Î, info)`` with ``info["std_error"]`` the standard error of log Î."""
    n = as_int(n_samples, "n_samples", minimum=2)
    rng = as_rng(rng)
    ys = _samples(model, measurement, n, rng)
    log_mean, se = _estimate(log_weights(y0[None], ys, noise_cov))
    return float(log_mean[0]), {"std_error": float(se[0]), "n_samples": n}


def log_likelihood_ratio(
    y0, x, model, measurement, noise_cov, *, n_samples=DEFAULT_SAMPLES, rng=None, part=None
):
    """log R(x) (16) for states x (L, dx) by Monte Carlo (numerator and denominator sampled)."""
    n = as_int(n_samples, "n_samples", minimum=2)
    rng = as_rng(rng)
    den = log_likelihood(y0, model, measurement, noise_cov, n_samples=n, rng=rng)[0]
    lw, subs = reduced_mixture(model, x, part)
    Y = y0[None] - measurement(x)
    num = np.empty(lw.shape)
    for k, s in enumerate(subs):
        if not np.isfinite(lw[:, k]).any():
            num[:, k] = -np.inf
            continue
        num[:, k] = _estimate(log_weights(Y, _samples(s, measurement, n, rng), noise_cov))[0]
    return logsumexp(lw + num, axis=1) - den
