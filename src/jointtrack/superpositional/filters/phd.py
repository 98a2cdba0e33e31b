r"""Particle SPS-PHD filter: the PHD filter for superpositional sensors.

S. Nannuru, M. Coates and R. Mahler, "Computationally-tractable approximate PHD
and CPHD filters for superpositional sensors", IEEE J. Sel. Topics Signal
Process. 7(3):410-420, 2013; the ratio R(x) and its Gaussian approximation are
(16)-(20) of S. Nannuru and M. Coates, "Gaussian approximation for
superpositional sensors", technical report, McGill University, 2015.

Update (derivation)
-------------------
The sensor reads :math:`y = \zeta(\Xi) + v`, :math:`\zeta(W) = \sum_{x\in W} g(x)`
(1), :math:`v \sim \mathcal N(0, \Sigma_0)`. Given y, the posterior PHD is, by
Bayes' rule on the set,

.. math::

    D_+(x) = \frac{\mathbb E\big[\sum_{x'\in\Xi}\delta_x(x')\,
             \mathcal N_{\Sigma_0}(y - \zeta(\Xi))\big]}
             {\mathbb E\big[\mathcal N_{\Sigma_0}(y - \zeta(\Xi))\big]}.

Campbell–Mecke: :math:`\mathbb E[\sum_{x\in\Xi} h(x, \Xi\setminus\{x\})] =
\int \mathbb E^{!x}[h(x, \Xi)]\, D(x)\, dx` with the reduced Palm law
:math:`f^{*x}` of (17). For a Poisson predicted RFS (the PHD filter's
assumption) the reduced Palm law is the law itself (Slivnyak), so

.. math::

    D_+(x) = D(x)\, R(x), \qquad
    R(x) = \frac{\int \mathcal N_{\Sigma_0}(y - g(x) - \zeta(W)) f(W)\,\delta W}
                {\int \mathcal N_{\Sigma_0}(y - \zeta(W)) f(W)\,\delta W}

— (16) with :math:`f^{A^*_x} = f`. This is exact; the PHD filter's only
approximation is to take the posterior as Poisson again with intensity
:math:`D_+`. The paper's filter then replaces Q by the Gaussian of Campbell's
theorem, :math:`\mu_Q = \int g D`, :math:`\Sigma_Q = \int g g^\top D` (the
Poisson D̃ of (7) vanishes), giving (20):

.. math::

    R_1(x) = \frac{\mathcal N_{\Sigma_0+\Sigma_Q}(y - g(x) - \mu_Q)}
                  {\mathcal N_{\Sigma_0+\Sigma_Q}(y - \mu_Q)}.

The filter calls :func:`jointtrack.superpositional.likelihood.log_likelihood_ratio`
with the predicted :class:`~jointtrack.superpositional.models.Poisson` and the
configured method, so ``likelihood="saddlepoint"`` or ``"hybrid"`` replace
(20) without touching the filter.

Particle implementation: D is ``mass × Σ_l w_l δ(x − x_l)`` (weights sum to
1); the update multiplies w_l by R(x_l) in log space, the new mass is
``mass × Σ_l w_l R(x_l)``, then ``n_particles`` are drawn by systematic
resampling. The mass is capped at ``max_mass`` (default 100): with (20) a
reading far from μ_Q can multiply it by e^35 in one update (this happens at
the first scan of the acoustic scenario when the filter starts empty), after
which Σ_Q is not representable; capped updates are counted in
``n_mass_clipped``. Prediction: survivors ``p_S D`` moved by the NCV model, plus the
birth intensity (:mod:`._particles`). Estimates: ``round(mass)`` weighted
k-means clusters of the particles.

Examples
--------
>>> import numpy as np
>>> from jointtrack.superpositional.filters import SPSPHDFilter
>>> f = SPSPHDFilter(np.eye(2, 4), 0.01 * np.eye(2), [[0, 10], [0, 10]],
...                  n_particles=200, n_birth_particles=100, rng=0)
>>> f.predict(); f.update([5.0, 5.0])
>>> f.particles.shape
(200, 4)
"""

from __future__ import annotations

import math

import numpy as np

from jointtrack.assignment._checks import as_float
from jointtrack.superpositional.filters._particles import (
    MAX_ESTIMATES,
    ParticleFilterBase,
    birth_particles,
    check_particles,
    cluster_means,
    log_normalise,
    predict_particles,
    systematic_resample,
)

__all__ = ["SPSPHDFilter"]


class SPSPHDFilter(ParticleFilterBase):
    r"""Particle SPS-PHD filter (module docstring for the equations).

    Parameters
    ----------
    measurement : (dy, 4) matrix or measurement object acting on (px, py, vx, vy).
    noise_cov : (dy, dy) positive-definite sensor noise covariance Σ0.
    region : (2, 2) birth region ``[[xmin, xmax], [ymin, ymax]]``.
    likelihood : ``"gaussian"`` (the paper's (20), default), ``"saddlepoint"``,
        ``"hybrid"``, ``"montecarlo"``; passed to ``log_likelihood_ratio``.
    likelihood_options : extra keyword arguments of the method (e.g. ``budget``).
    initial_count : expected number of targets at the start, spread uniformly
        over the region (0: start empty, births only).
    max_mass : cap on the PHD mass after an update (the Gaussian ratio does not
        bound it); ``n_mass_clipped`` counts the updates that hit it.
    rng : seed or numpy Generator.
    **settings : :class:`~jointtrack.superpositional.filters._particles.FilterSettings`
        fields (``dt``, ``process_noise``, ``p_survival``, ``birth_rate``,
        ``birth_speed_std``, ``n_particles``, ``n_birth_particles``).

    Attributes
    ----------
    particles : (L, 4) particle states.
    weights : (L,) normalised weights.
    expected_cardinality : the PHD mass ∫D.
    """

    def __init__(
        self,
        measurement,
        noise_cov,
        region,
        *,
        initial_count: float = 0.0,
        max_mass: float = 100.0,
        **kwargs,
    ):
        super().__init__(measurement, noise_cov, region, **kwargs)
        initial_count = as_float(initial_count, "initial_count", minimum=0.0)
        self.max_mass = as_float(max_mass, "max_mass", minimum=0.0, open_min=True)
        self.n_mass_clipped = 0
        s = self.settings
        self.particles = birth_particles(s.n_particles, s, self.rng)
        self.weights = np.full(s.n_particles, 1.0 / s.n_particles)
        self._log_mass = math.log(initial_count) if initial_count > 0 else -math.inf

    @property
    def expected_cardinality(self) -> float:
        return math.exp(self._log_mass)

    def set_state(self, particles, weights, mass) -> None:
        """Replace the PHD by ``mass × Σ w_l δ(x − x_l)`` (weights normalised here)."""
        p, w = check_particles(particles, weights)
        mass = as_float(mass, "mass", minimum=0.0)
        self.particles, self.weights = p, w
        self._log_mass = math.log(mass) if mass > 0 else -math.inf

    def predict(self) -> None:
        """Survival, NCV motion and births: ``D_pred = p_S (D moved) + b``."""
        s = self.settings
        moved = predict_particles(self.particles, s, self.rng)
        born = birth_particles(s.n_birth_particles, s, self.rng)
        surv = s.p_survival * self.expected_cardinality
        total = surv + s.birth_rate
        if total <= 0:  # nothing survives and nothing is born: an empty PHD
            self.particles, self._log_mass = moved, -math.inf
            return
        w = np.concatenate(
            [
                self.weights * (surv / total),
                np.full(born.shape[0], s.birth_rate / total / born.shape[0]),
            ]
        )
        self.particles = np.concatenate([moved, born])
        self.weights = w
        self._log_mass = math.log(total)

    def update(self, y) -> None:
        """The PHD update ``D_+ = D R`` with R by ``log_likelihood_ratio`` (module docstring)."""
        from jointtrack.superpositional.models import Poisson

        y = self._begin_update(y)
        if self._log_mass == -math.inf:
            return  # an empty Poisson RFS stays empty whatever is read
        model = Poisson.from_particles(self.expected_cardinality, self.particles, self.weights)
        log_r = self._ratio(y, self.particles, model)
        with np.errstate(divide="ignore"):
            log_w = np.log(self.weights) + log_r
        w, log_sum = log_normalise(log_w)
        idx = systematic_resample(w, self.settings.n_particles, self.rng)
        new_particles = self.particles[idx]
        new_log_mass = self._log_mass + log_sum
        clipped = new_log_mass > math.log(self.max_mass)
        if clipped:
            # (20) does not bound ∫D R: a reading far from μ_Q (e.g. a newborn target
            # against a small predicted mass) can give R ~ e^35; the next Σ_Q would then
            # not be representable, so the mass is capped and the event counted
            new_log_mass = math.log(self.max_mass)
        # everything computed: swap
        self.particles = new_particles
        self.weights = np.full(idx.size, 1.0 / idx.size)
        self._log_mass = new_log_mass
        self.n_mass_clipped += int(clipped)

    def estimate(self) -> np.ndarray:
        """``min(round(∫D), MAX_ESTIMATES)`` states ``(n, 4)`` by weighted k-means."""
        # the Gaussian ratio does not bound the mass: cap the number of clusters
        k = int(min(np.floor(self.expected_cardinality + 0.5), MAX_ESTIMATES))
        return cluster_means(self.particles, self.weights, k, self.rng)
