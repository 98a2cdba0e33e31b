r"""Particle SPS-CPHD filter: the CPHD filter for superpositional sensors.

S. Nannuru, M. Coates and R. Mahler, "Computationally-tractable approximate PHD
and CPHD filters for superpositional sensors", IEEE J. Sel. Topics Signal
Process. 7(3):410-420, 2013; R(x), the reduced density and the Gaussian
approximation are (16)-(20) of S. Nannuru and M. Coates, "Gaussian
approximation for superpositional sensors", technical report, McGill
University, 2015.

Update (derivation)
-------------------
The predicted RFS is IIDC: cardinality pmf π(n), spatial density s(x),
:math:`D = \bar n s`. With :math:`y = \zeta(\Xi) + v` (1) and n targets i.i.d.
from s, the likelihood of n is

.. math::

    \ell_n(y) = \int \mathcal N_{\Sigma_0}\Big(y - \sum_{i=1}^n g(x_i)\Big)
                \prod_{i=1}^n s(x_i)\, dx_{1:n}, \qquad
    \ell(y) = \sum_n \pi(n)\, \ell_n(y) = I \text{ of (2)}.

*Cardinality.* Bayes' rule on n: :math:`\pi_+(n) = \pi(n)\,\ell_n(y)/\ell(y)`.

*PHD.* Conditioning on n and singling out the target at x,

.. math::

    D_+(x) = \frac{\sum_{n\ge 1} n\,\pi(n)\, s(x)\, \ell_{n-1}(y - g(x))}{\ell(y)}
           = \bar n\, s(x)\, R(x),

with R(x) of (16) for the reduced IIDC :math:`f^{*x}` of (17): cardinality
:math:`\pi^*(n) = (n+1)\pi(n+1)/\bar n`, the same spatial density s. The
CPHD filter keeps the posterior IIDC: :math:`\pi_+` and
:math:`s_+ \propto s\, R`.

*Gaussian approximation (the paper's).* Given n, y is a sum of n i.i.d.
contributions, so by Campbell's theorem (4)-(7) applied to one target
(:math:`\mu_s = \int g s`, :math:`\Sigma_s = \int g g^\top s - \mu_s\mu_s^\top`)

.. math::

    \ell_n(y) \approx \mathcal N_{\Sigma_0 + n\Sigma_s}(y - n\mu_s),

and R(x) ≈ R₁(x) of (20) with the moments of the predicted IIDC and of its
reduced IIDC. The filter gets :math:`\mu_s, \Sigma_s` from
:func:`~jointtrack.superpositional.moments.campbell_moments` of the one-target
IIDC, and R from
:func:`~jointtrack.superpositional.likelihood.log_likelihood_ratio` with the
configured method; for the other methods ℓ_n is
:func:`~jointtrack.superpositional.likelihood.likelihood` of the IIDC with
cardinality fixed at n (ℓ₀ = N(y; 0, Σ0) exactly).

Prediction: :math:`\pi_{pred}(n) = \sum_j \mathrm{Pois}(n-j; \beta)
\sum_l \pi(l)\,\mathrm{Bin}(j; l, p_S)` (survival thinning convolved with
Poisson births), truncated at ``max_cardinality`` and renormalised (the
truncated mass is reported in ``truncated_mass``); spatial
:math:`s_{pred} \propto p_S \bar n\, (\text{moved } s) + \beta\, b`.
Estimates: the MAP cardinality n̂, then n̂ weighted k-means clusters.

Examples
--------
>>> import numpy as np
>>> from jointtrack.superpositional.filters import SPSCPHDFilter
>>> f = SPSCPHDFilter(np.eye(2, 4), 0.01 * np.eye(2), [[0, 10], [0, 10]],
...                   n_particles=200, n_birth_particles=100, max_cardinality=4, rng=0)
>>> f.cardinality_pmf.shape
(5,)
"""

from __future__ import annotations

import numpy as np
from scipy.special import logsumexp
from scipy.stats import binom, poisson

from jointtrack.assignment._checks import _as_real_array, as_int
from jointtrack.superpositional.filters._particles import (
    ParticleFilterBase,
    birth_particles,
    check_measurement_vector,
    check_particles,
    cluster_means,
    log_normalise,
    predict_particles,
    systematic_resample,
)
from jointtrack.superpositional.likelihood import log_gauss_one

__all__ = ["SPSCPHDFilter", "predict_cardinality"]


def predict_cardinality(log_pmf: np.ndarray, p_survival: float, birth_rate: float) -> np.ndarray:
    r"""log π_pred of the survival-thinned, Poisson-birth-convolved pmf, same length, renormalised.

    .. math:: \pi_{pred}(n) = \sum_{j\le n} \mathrm{Pois}(n-j;\beta)
              \sum_{l\ge j} \pi(l)\, \binom{l}{j} p_S^j (1-p_S)^{l-j}

    >>> np.exp(predict_cardinality(np.array([-np.inf, 0.0]), 0.5, 0.0)).round(3).tolist()
    [0.5, 0.5]
    """
    N = log_pmf.size - 1
    n = np.arange(N + 1)
    with np.errstate(divide="ignore"):
        # log Bin(j; l, p_S) as (l, j)
        log_bin = binom.logpmf(n[None, :], n[:, None], p_survival)
        log_surv = logsumexp(log_pmf[:, None] + log_bin, axis=0)  # (j,)
        log_birth = poisson.logpmf(n[:, None] - n[None, :], birth_rate)  # (n, j)
    out = logsumexp(log_surv[None, :] + log_birth, axis=1)
    return out - logsumexp(out)


class SPSCPHDFilter(ParticleFilterBase):
    r"""Particle SPS-CPHD filter (module docstring for the equations).

    Parameters
    ----------
    measurement : (dy, 4) matrix or measurement object acting on (px, py, vx, vy).
    noise_cov : (dy, dy) positive-definite sensor noise covariance Σ0.
    region : (2, 2) birth region.
    max_cardinality : largest number of targets the pmf holds (N).
    initial_pmf : π at the start (length ≤ N + 1, sums to 1); default: all
        mass on 0 targets (births only).
    likelihood, likelihood_options, rng, **settings : as
        :class:`~jointtrack.superpositional.filters.SPSPHDFilter`.

    Attributes
    ----------
    particles, weights : the spatial density s (weights sum to 1).
    cardinality_pmf : (N + 1,) π.
    truncated_mass : the predicted probability of more than N targets dropped
        at the last prediction.
    """

    def __init__(
        self,
        measurement,
        noise_cov,
        region,
        *,
        max_cardinality: int = 12,
        initial_pmf=None,
        **kwargs,
    ):
        super().__init__(measurement, noise_cov, region, **kwargs)
        self.max_cardinality = as_int(max_cardinality, "max_cardinality", minimum=1, maximum=200)
        s = self.settings
        self.particles = birth_particles(s.n_particles, s, self.rng)
        self.weights = np.full(s.n_particles, 1.0 / s.n_particles)
        pmf = np.zeros(self.max_cardinality + 1)
        pmf[0] = 1.0
        if initial_pmf is not None:
            pmf = self._check_pmf(initial_pmf)
        with np.errstate(divide="ignore"):
            self._log_pmf = np.log(pmf)
        self.truncated_mass = 0.0

    def _check_pmf(self, pmf) -> np.ndarray:
        p = _as_real_array(pmf, "initial_pmf")
        if p.ndim != 1 or not 1 <= p.size <= self.max_cardinality + 1:
            raise ValueError(
                f"initial_pmf must be a vector of at most max_cardinality + 1 = "
                f"{self.max_cardinality + 1} probabilities, got shape {p.shape}"
            )
        if not np.isfinite(p).all() or np.any(p < 0) or abs(p.sum() - 1.0) > 1e-9:
            raise ValueError(
                f"initial_pmf must be non-negative and sum to 1 within 1e-9, got sum {p.sum()!r}"
            )
        out = np.zeros(self.max_cardinality + 1)
        out[: p.size] = p / p.sum()
        return out

    @property
    def cardinality_pmf(self) -> np.ndarray:
        p = np.exp(self._log_pmf)
        return p / p.sum()

    @property
    def expected_cardinality(self) -> float:
        return float(self.cardinality_pmf @ np.arange(self.max_cardinality + 1))

    def set_state(self, cardinality_pmf, particles, weights=None) -> None:
        """Replace π and the spatial particles (weights normalised here)."""
        pmf = self._check_pmf(cardinality_pmf)
        p, w = check_particles(particles, weights)
        with np.errstate(divide="ignore"):
            self._log_pmf = np.log(pmf)
        self.particles, self.weights = p, w

    def predict(self) -> None:
        """Cardinality: thinning ⊛ Poisson births; spatial: survivors moved + birth density."""
        s = self.settings
        N = self.max_cardinality
        # the mass that would go above N, for the record, before truncation
        long = np.concatenate([self._log_pmf, np.full(N + 1, -np.inf)])
        full = predict_cardinality(long, s.p_survival, s.birth_rate)
        self.truncated_mass = float(-np.expm1(logsumexp(full[: N + 1])))
        log_pmf = full[: N + 1] - logsumexp(full[: N + 1])
        nbar = self.expected_cardinality
        moved = predict_particles(self.particles, s, self.rng)
        born = birth_particles(s.n_birth_particles, s, self.rng)
        surv = s.p_survival * nbar
        total = surv + s.birth_rate
        if total > 0:
            w = np.concatenate(
                [
                    self.weights * (surv / total),
                    np.full(born.shape[0], s.birth_rate / total / born.shape[0]),
                ]
            )
            self.particles = np.concatenate([moved, born])
            self.weights = w
        else:
            self.particles = moved
        self._log_pmf = log_pmf

    def cardinality_log_likelihoods(self, y) -> np.ndarray:
        """log ℓ_n(y), n = 0..N, for the current spatial density (module docstring)."""
        from jointtrack.superpositional.models import IIDC

        y = check_measurement_vector(y, self.dy)
        N = self.max_cardinality
        out = np.empty(N + 1)
        out[0] = float(log_gauss_one(y, self.noise_cov))
        if self.likelihood == "gaussian":
            from jointtrack.superpositional.moments import campbell_moments

            one = IIDC.from_particles([0.0, 1.0], self.particles, self.weights)
            mu, cov = campbell_moments(one, self._g)
            for n in range(1, N + 1):
                out[n] = float(log_gauss_one(y - n * mu, self.noise_cov + n * cov))
            return out
        for n in range(1, N + 1):
            delta = np.zeros(n + 1)
            delta[n] = 1.0
            out[n] = self._log_likelihood(
                y, IIDC.from_particles(delta, self.particles, self.weights)
            )
        return out

    def update(self, y) -> None:
        """Cardinality by ℓ_n, spatial density by R of the reduced IIDC; then resample."""
        from jointtrack.superpositional.models import IIDC

        y = self._begin_update(y)
        log_l = self.cardinality_log_likelihoods(y)
        log_post = self._log_pmf + log_l
        total = logsumexp(log_post)
        if not np.isfinite(total):
            raise ValueError(
                "every cardinality has zero likelihood; the update cannot be normalised"
            )
        new_log_pmf = log_post - total
        new_particles, new_weights = self.particles, self.weights
        if self.expected_cardinality > 0:
            model = IIDC.from_particles(self.cardinality_pmf, self.particles, self.weights)
            # s₊ ∝ s R (R's denominator, the same for every x, cancels in the normalisation)
            log_r = self._ratio(y, self.particles, model)
            with np.errstate(divide="ignore"):
                log_w = np.log(self.weights) + log_r
            w, _ = log_normalise(log_w)
            idx = systematic_resample(w, self.settings.n_particles, self.rng)
            new_particles = self.particles[idx]
            new_weights = np.full(idx.size, 1.0 / idx.size)
        # everything computed: swap
        self._log_pmf = new_log_pmf
        self.particles, self.weights = new_particles, new_weights

    def map_cardinality(self) -> int:
        """The most probable number of targets."""
        return int(np.argmax(self._log_pmf))

    def estimate(self) -> np.ndarray:
        """MAP-cardinality states ``(n̂, 4)`` by weighted k-means of the particles."""
        return cluster_means(self.particles, self.weights, self.map_cardinality(), self.rng)
