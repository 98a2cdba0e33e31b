r"""Particle SPS-MB filter: the multi-Bernoulli filter for superpositional sensors.

S. Nannuru and M. Coates, "Hybrid multi-Bernoulli and CPHD filters for
superpositional sensors", IEEE Trans. Aerosp. Electron. Syst. 51(4), 2015,
building on S. Nannuru, M. Coates and R. Mahler, "Computationally-tractable
approximate PHD and CPHD filters for superpositional sensors", IEEE J. Sel.
Topics Signal Process. 7(3):410-420, 2013; the leave-one-out moments are the
multi-Bernoulli case of (17)-(20) of S. Nannuru and M. Coates, "Gaussian
approximation for superpositional sensors", technical report, McGill
University, 2015.

Update (derivation)
-------------------
The predicted RFS is multi-Bernoulli :math:`\{(r_i, p_i)\}`; :math:`\Xi^{-i}`
is the set without component i (independent of component i) and

.. math::

    \ell^{-i}(z) = \int \mathcal N_{\Sigma_0}(z - \zeta(W))\, f^{-i}(W)\,\delta W

the density of y − (component i's contribution) at z. Conditioning on whether
component i exists and, if so, on its state x, Bayes' rule gives two exact
identities:

.. math::

    D_{i,+}(x) = \frac{r_i\, p_i(x)\, \ell^{-i}(y - g(x))}{\ell(y)}, \qquad
    \ell(y) = (1 - r_i)\, \ell^{-i}(y) + r_i \int p_i(x)\, \ell^{-i}(y - g(x))\,dx,

so, with :math:`A_i = \int p_i(x)\,\ell^{-i}(y - g(x))\,dx` and
:math:`B_i = \ell^{-i}(y)`,

.. math::

    r_{i,+} = \frac{r_i A_i}{(1 - r_i) B_i + r_i A_i}, \qquad
    p_{i,+}(x) \propto p_i(x)\, \ell^{-i}(y - g(x)).

This is R(x) of (16) per component: the reduced density of (17) at a point of
component i is the multi-Bernoulli without component i (a Bernoulli's reduced
density is empty), and :math:`r_{i,+}` and :math:`p_{i,+}` are the mass and
shape of :math:`r_i p_i R_i`. The filter's approximation is to keep the
posterior multi-Bernoulli (independent components) with these marginals.
Writing :math:`\ell(y)` per component, instead of the one Gaussian (9) of the
whole set, keeps :math:`r_{i,+}` in [0, 1] by construction.

*Gaussian approximation (the paper's).* :math:`\ell^{-i}(z) \approx
\mathcal N_{\Sigma_0 + \Sigma^{-i}}(z - \mu^{-i})` with the Campbell moments
of :math:`\Xi^{-i}` from
:func:`~jointtrack.superpositional.moments.leave_one_out_moments` — (20) with
the leave-one-out moments. For the other methods :math:`B_i` and each
:math:`\ell^{-i}(y - g(x_l))` are
:func:`~jointtrack.superpositional.likelihood.likelihood` of the leave-one-out
set (one call per particle: use few particles with them).

Prediction: :math:`r_i \leftarrow p_S r_i`, particles moved by the NCV model,
plus one birth component per scan with existence ``birth_rate`` and the birth
density of :mod:`._particles`. Components with r below ``prune_threshold``
are dropped and at most ``max_components`` (highest r) are kept. Each
component keeps its label from birth, so the estimates (components with
r > 0.5, their weighted means) are tracks.

Examples
--------
>>> import numpy as np
>>> from jointtrack.superpositional.filters import SPSMBFilter
>>> f = SPSMBFilter(np.eye(2, 4), 0.01 * np.eye(2), [[0, 10], [0, 10]],
...                 n_particles=100, n_birth_particles=100, birth_rate=0.1, rng=0)
>>> f.predict(); f.n_components
1
"""

from __future__ import annotations

import numpy as np

from jointtrack.assignment._checks import _as_real_array, as_float, as_int
from jointtrack.superpositional.filters._particles import (
    ParticleFilterBase,
    birth_particles,
    check_particles,
    log_normalise,
    predict_particles,
    systematic_resample,
)
from jointtrack.superpositional.likelihood import log_gauss, log_gauss_one

__all__ = ["SPSMBFilter"]


class SPSMBFilter(ParticleFilterBase):
    r"""Particle SPS-MB filter (module docstring for the equations).

    Parameters
    ----------
    measurement, noise_cov, region, likelihood, likelihood_options, rng :
        as :class:`~jointtrack.superpositional.filters.SPSPHDFilter`.
    prune_threshold : components with existence below this are dropped.
    max_components : most components kept (highest existence first).
    existence_threshold : a component with r above this is reported by
        :meth:`estimate`.
    **settings : ``FilterSettings`` fields; ``birth_rate`` is the existence
        probability of the birth component (≤ 1), ``n_particles`` the
        particles per component after resampling.

    Attributes
    ----------
    r : (n,) existence probabilities.
    particles, weights : lists of the n components' (L_i, 4) particles and
        (L_i,) normalised weights.
    labels : (n,) int64 label of each component (its birth number).
    """

    def __init__(
        self,
        measurement,
        noise_cov,
        region,
        *,
        prune_threshold: float = 1e-3,
        max_components: int = 50,
        existence_threshold: float = 0.5,
        **kwargs,
    ):
        super().__init__(measurement, noise_cov, region, **kwargs)
        if self.settings.birth_rate > 1:
            raise ValueError(
                f"birth_rate is the birth component's existence probability for the MB filter: "
                f"it must be <= 1, got {self.settings.birth_rate}"
            )
        self.prune_threshold = as_float(
            prune_threshold, "prune_threshold", minimum=0.0, maximum=1.0
        )
        self.max_components = as_int(max_components, "max_components", minimum=1)
        self.existence_threshold = as_float(
            existence_threshold, "existence_threshold", minimum=0.0, maximum=1.0
        )
        self.r = np.zeros(0)
        self.particles: list = []
        self.weights: list = []
        self.labels = np.zeros(0, dtype=np.int64)
        self._next_label = 0

    @property
    def n_components(self) -> int:
        return int(self.r.size)

    @property
    def expected_cardinality(self) -> float:
        return float(self.r.sum())

    def set_state(self, r, particles, weights=None) -> None:
        """Replace the components: existence ``r`` (n,), particle sets and weights per component."""
        r = _as_real_array(r, "r")
        if r.ndim != 1 or not np.isfinite(r).all() or np.any((r < 0) | (r > 1)):
            raise ValueError("r must be a vector of existence probabilities in [0, 1]")
        if len(particles) != r.size or (weights is not None and len(weights) != r.size):
            raise ValueError(
                f"particles (and weights) must hold one set per component: {r.size} "
                "(dimension mismatch)"
            )
        sets = [
            check_particles(
                particles[i], None if weights is None else weights[i], f"particles[{i}]"
            )
            for i in range(r.size)
        ]
        self.r = r.copy()
        self.particles = [p for p, _ in sets]
        self.weights = [w for _, w in sets]
        self.labels = np.arange(self._next_label, self._next_label + r.size, dtype=np.int64)
        self._next_label += r.size

    def predict(self) -> None:
        """Survival and motion of every component, then one birth component."""
        s = self.settings
        r = s.p_survival * self.r
        parts = [predict_particles(p, s, self.rng) for p in self.particles]
        weights = list(self.weights)
        labels = self.labels
        if s.birth_rate > 0:
            r = np.append(r, s.birth_rate)
            parts.append(birth_particles(s.n_birth_particles, s, self.rng))
            weights.append(np.full(s.n_birth_particles, 1.0 / s.n_birth_particles))
            labels = np.append(labels, self._next_label)
            self._next_label += 1
        self.r, self.particles, self.weights, self.labels = r, parts, weights, labels

    def _model(self):
        from jointtrack.superpositional.models import MultiBernoulli

        return MultiBernoulli.from_particles(self.r, self.particles, self.weights)

    def _leave_one_out_logs(self, y: np.ndarray, model):
        """Per component: ``log ℓ^{-i}(y − g(x_l))`` (L_i,) and ``log B_i = log ℓ^{-i}(y)``."""
        gx = [self._g(p) for p in self.particles]
        if self.likelihood == "gaussian":
            from jointtrack.superpositional.moments import leave_one_out_moments

            mu, cov = leave_one_out_moments(model, self._g)
            out = []
            for i in range(self.n_components):
                S = self.noise_cov + cov[i]
                log_num = log_gauss(y - gx[i] - mu[i], S)
                log_b = float(log_gauss_one(y - mu[i], S))
                out.append((log_num, log_b))
            return out
        out = []
        for i in range(self.n_components):
            rest = model.leave_one_out(i)
            if rest.n_components == 0:  # nothing else: ℓ^{-i} is the noise density itself
                out.append(
                    (
                        log_gauss(y - gx[i], self.noise_cov),
                        float(log_gauss_one(y, self.noise_cov)),
                    )
                )
                continue
            log_b = self._log_likelihood(y, rest)
            log_num = np.array([self._log_likelihood(y - g, rest) for g in gx[i]])
            out.append((log_num, log_b))
        return out

    def update(self, y) -> None:
        """Per component: r and p by the leave-one-out likelihoods; resample, prune."""
        y = self._begin_update(y)
        if self.n_components == 0:
            return
        logs = self._leave_one_out_logs(y, self._model())
        new_r = np.empty(self.n_components)
        new_parts, new_weights = [], []
        n_keep = self.settings.n_particles
        for i, (log_num, log_b) in enumerate(logs):
            with np.errstate(divide="ignore"):
                log_w = np.log(self.weights[i]) + log_num
            w, log_a = log_normalise(log_w)
            r = self.r[i]
            # r A / ((1 − r) B + r A) in log space; r = 0 or 1 stay put
            with np.errstate(divide="ignore"):
                log_ra = np.log(r) + log_a
                log_rb = np.log1p(-r) + log_b
            denom = np.logaddexp(log_ra, log_rb)
            new_r[i] = float(np.exp(log_ra - denom)) if np.isfinite(denom) else r
            idx = systematic_resample(w, n_keep, self.rng)
            new_parts.append(self.particles[i][idx])
            new_weights.append(np.full(n_keep, 1.0 / n_keep))
        keep = np.flatnonzero(new_r >= self.prune_threshold)
        if keep.size > self.max_components:
            keep = keep[np.argsort(-new_r[keep], kind="stable")[: self.max_components]]
            keep.sort()
        # everything computed: swap
        self.r = new_r[keep]
        self.particles = [new_parts[i] for i in keep]
        self.weights = [new_weights[i] for i in keep]
        self.labels = self.labels[keep]

    def estimate_with_labels(self) -> tuple[np.ndarray, np.ndarray]:
        """States ``(n, 4)`` and labels ``(n,)`` of the components with r > existence_threshold."""
        sel = np.flatnonzero(self.r > self.existence_threshold)
        if sel.size == 0:
            return np.zeros((0, 4)), np.zeros(0, dtype=np.int64)
        states = np.stack([self.weights[i] @ self.particles[i] for i in sel])
        return states, self.labels[sel].copy()

    def estimate(self) -> np.ndarray:
        """States ``(n, 4)`` of the components with r > existence_threshold (weighted means)."""
        return self.estimate_with_labels()[0]
