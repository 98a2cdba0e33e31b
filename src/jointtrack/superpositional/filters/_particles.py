r"""Particle machinery shared by the SPS-PHD, SPS-CPHD and SPS-MB filters.

One copy of what the three particle filters do alike: the settings and their
checks, nearly-constant-velocity prediction, the birth model, systematic
resampling, clustering into state estimates, and the Gaussian log density the
updates evaluate. The update equations themselves live in :mod:`.phd`,
:mod:`.cphd` and :mod:`.mb`.

Motion model (the NCV model of :mod:`jointtrack.scenarios.simulate`): state
``x = (px, py, vx, vy)``, per scan interval T

.. math::

    x_{k+1} = F x_k + w_k,\quad F = \begin{bmatrix} I & T I\\ 0 & I\end{bmatrix},\quad
    w_k \sim \mathcal{N}\!\left(0,\ q \begin{bmatrix} T^3/3\, I & T^2/2\, I\\
    T^2/2\, I & T\, I\end{bmatrix}\right).

Birth model: new targets appear at the rate ``birth_rate`` per scan (the mass
of the birth intensity), uniformly over the surveillance region, with velocity
``N(0, birth_speed_std² I)``:

.. math::

    b(x) = \beta\, \frac{\mathbf 1_{\mathcal R}(p)}{|\mathcal R|}\,
    \mathcal N(v;\, 0,\, \sigma_b^2 I).

Survival: each target survives a scan with probability ``p_survival``,
independently of its state.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
from scipy.cluster.vq import kmeans2
from scipy.special import logsumexp

from jointtrack.assignment._checks import _as_real_array, as_float, as_int, as_rng

__all__ = [
    "MAX_ESTIMATES",
    "METHODS",
    "FilterSettings",
    "ParticleFilterBase",
    "birth_particles",
    "check_measurement_vector",
    "check_method",
    "check_noise_cov",
    "check_particles",
    "cluster_means",
    "log_normalise",
    "predict_particles",
    "systematic_resample",
]

#: Most state estimates one scan may report (a cap on the clustering's k).
MAX_ESTIMATES = 100

#: Likelihood methods a filter accepts (dispatched by ``log_likelihood_ratio``).
METHODS = ("gaussian", "saddlepoint", "hybrid", "montecarlo", "exact")


@dataclass(frozen=True)
class FilterSettings:
    """Motion, survival, birth and particle-count settings, checked on construction.

    Parameters
    ----------
    region : (2, 2) box ``[[xmin, xmax], [ymin, ymax]]`` where targets are born.
    dt : scan interval T (s).
    process_noise : NCV acceleration spectral density q of the filter (m²/s³).
    p_survival : probability that a target survives one scan, in [0, 1].
    birth_rate : expected number of new targets per scan (≥ 0); for the MB
        filter the existence probability of the birth component (≤ 1).
    birth_speed_std : velocity standard deviation of a new target (m/s).
    n_particles : particles kept after resampling (PHD, CPHD: in total; MB: per
        Bernoulli component).
    n_birth_particles : particles drawn for the birth intensity each scan.
    """

    region: np.ndarray
    dt: float = 1.0
    process_noise: float = 0.01
    p_survival: float = 0.99
    birth_rate: float = 0.05
    birth_speed_std: float = 0.3
    n_particles: int = 4000
    n_birth_particles: int = 1000

    def __post_init__(self):
        region = _as_real_array(self.region, "region")
        if region.shape != (2, 2) or not np.isfinite(region).all():
            raise ValueError(
                f"region must be a finite (2, 2) box [[xmin, xmax], [ymin, ymax]], "
                f"got shape {region.shape}"
            )
        if np.any(region[:, 1] <= region[:, 0]):
            raise ValueError(
                f"region rows must be [min, max] with min < max, got {region.tolist()}"
            )
        region = region.copy()
        region.flags.writeable = False
        object.__setattr__(self, "region", region)
        object.__setattr__(self, "dt", as_float(self.dt, "dt", minimum=0.0, open_min=True))
        object.__setattr__(
            self, "process_noise", as_float(self.process_noise, "process_noise", minimum=0.0)
        )
        object.__setattr__(
            self, "p_survival", as_float(self.p_survival, "p_survival", minimum=0.0, maximum=1.0)
        )
        object.__setattr__(self, "birth_rate", as_float(self.birth_rate, "birth_rate", minimum=0.0))
        object.__setattr__(
            self, "birth_speed_std", as_float(self.birth_speed_std, "birth_speed_std", minimum=0.0)
        )
        object.__setattr__(self, "n_particles", as_int(self.n_particles, "n_particles", minimum=1))
        object.__setattr__(
            self,
            "n_birth_particles",
            as_int(self.n_birth_particles, "n_birth_particles", minimum=1),
        )

    @property
    def transition(self) -> tuple[np.ndarray, np.ndarray]:
        """``(F, L)``: the NCV transition matrix and a factor ``L`` of its noise ``L Lᵀ = Q``."""
        from jointtrack.scenarios.simulate import _noise_factor, ncv_matrices

        F, Q = ncv_matrices(self.dt, self.process_noise, 2)
        return F, _noise_factor(Q)


def check_method(method) -> str:
    """The likelihood method name, or ValueError naming ``likelihood``."""
    if not isinstance(method, str) or method not in METHODS:
        raise ValueError(f"likelihood must be one of {', '.join(METHODS)}, got {method!r}")
    return method


def check_noise_cov(noise_cov, dy: int) -> np.ndarray:
    """``noise_cov`` as a symmetric positive-definite (dy, dy) array, or ValueError."""
    S = _as_real_array(noise_cov, "noise_cov")
    if S.shape != (dy, dy):
        raise ValueError(f"noise_cov must be ({dy}, {dy}) to match the measurement, got {S.shape}")
    if not np.isfinite(S).all():
        raise ValueError("noise_cov has a non-finite entry (NaN or inf)")
    if not np.allclose(S, S.T, rtol=1e-10, atol=1e-12 * max(1.0, float(np.abs(S).max()))):
        raise ValueError("noise_cov must be symmetric")
    if np.linalg.eigvalsh(S).min() <= 0:
        raise ValueError("noise_cov must be positive definite (it has an eigenvalue <= 0)")
    S = S.copy()
    S.flags.writeable = False
    return S


def check_measurement_vector(y, dy: int) -> np.ndarray:
    """A scan's readings ``y`` as a finite real (dy,) vector, or ValueError naming ``y``."""
    y = _as_real_array(y, "y")
    if y.shape != (dy,):
        raise ValueError(f"y must be a vector of the {dy} sensor readings, got shape {y.shape}")
    if not np.isfinite(y).all():
        raise ValueError("y has a non-finite reading (NaN or inf)")
    return y


def predict_particles(particles: np.ndarray, settings: FilterSettings, rng) -> np.ndarray:
    """NCV prediction of every particle: ``F x + w``, ``w ~ N(0, Q)`` (a new array)."""
    F, L = settings.transition
    noise = rng.standard_normal(particles.shape) @ L.T
    return particles @ F.T + noise


def birth_particles(n: int, settings: FilterSettings, rng) -> np.ndarray:
    """``n`` draws ``(n, 4)`` from the normalised birth density (module docstring)."""
    B = settings.region
    pos = B[:, 0] + rng.random((n, 2)) * (B[:, 1] - B[:, 0])
    vel = settings.birth_speed_std * rng.standard_normal((n, 2))
    return np.column_stack([pos, vel])


def systematic_resample(weights, n: int, rng) -> np.ndarray:
    """Indices of ``n`` particles drawn by systematic resampling of normalised ``weights``.

    One uniform offset ``u ~ U[0, 1/n)``, points ``u + j/n``; particle i is
    copied ``⌊n w_i⌋`` or ``⌈n w_i⌉`` times, so the resampled set has the
    lowest variance of the standard schemes (Douc, Cappé & Moulines 2005).

    >>> systematic_resample([0.5, 0.0, 0.5], 4, np.random.default_rng(0)).tolist()
    [0, 0, 2, 2]
    """
    w = _as_real_array(weights, "weights")
    n = as_int(n, "n", minimum=1)
    if w.ndim != 1 or w.size == 0:
        raise ValueError(f"weights must be a non-empty 1-D array, got shape {w.shape}")
    if not np.isfinite(w).all() or np.any(w < 0):
        raise ValueError("weights must be finite and non-negative")
    total = float(w.sum())
    if not total > 0:
        raise ValueError("weights sum to 0; nothing to resample")
    rng = as_rng(rng)
    cdf = np.cumsum(w / total)
    cdf[-1] = 1.0  # rounding must not leave the last points without a particle
    points = (rng.random() + np.arange(n)) / n
    return np.minimum(np.searchsorted(cdf, points, side="right"), w.size - 1)


def cluster_means(particles: np.ndarray, weights: np.ndarray, k: int, rng) -> np.ndarray:
    """``k`` state estimates ``(k, dx)``: weighted k-means on the positions, then cluster means.

    The k-means (scipy's ``kmeans2``, k-means++ start) runs on at most 2,000
    particles drawn by systematic resampling of ``weights``; every particle is
    then assigned to its nearest centre and each estimate is the weighted mean
    of the full states of its cluster (an empty cluster keeps its centre).
    """
    k = as_int(k, "k", minimum=0, maximum=MAX_ESTIMATES)
    if k == 0 or particles.shape[0] == 0:
        return np.zeros((0, particles.shape[1]))
    rng = as_rng(rng)
    pos = particles[:, :2]
    idx = systematic_resample(weights, min(2000, max(50 * k, 200)), rng)
    sample = pos[idx]
    if k == 1 or np.unique(sample, axis=0).shape[0] <= k:
        centres = _weighted_means(pos, weights, np.zeros(pos.shape[0], dtype=np.intp), 1)[0][:, :2]
        centres = np.repeat(centres, k, axis=0)
    else:
        seed = int(rng.integers(2**31 - 1))
        centres, _ = kmeans2(sample, k, minit="++", seed=seed)
    d2 = ((pos[:, None, :] - centres[None, :, :]) ** 2).sum(-1)
    label = np.argmin(d2, axis=1)
    means, mass = _weighted_means(particles, weights, label, k)
    empty = mass <= 0
    means[empty, :2] = centres[empty]
    means[empty, 2:] = 0.0
    return means


def _weighted_means(x: np.ndarray, w: np.ndarray, label: np.ndarray, k: int):
    mass = np.bincount(label, weights=w, minlength=k)
    sums = np.stack(
        [np.bincount(label, weights=w * x[:, j], minlength=k) for j in range(x.shape[1])], 1
    )
    with np.errstate(invalid="ignore", divide="ignore"):
        means = np.where(mass[:, None] > 0, sums / np.where(mass > 0, mass, 1.0)[:, None], 0.0)
    return means, mass


def log_normalise(log_w: np.ndarray) -> tuple[np.ndarray, float]:
    """``(w, log Σ exp(log_w))`` with ``w`` the normalised weights; ValueError if all −inf."""
    total = float(logsumexp(log_w))
    if not np.isfinite(total):
        raise ValueError(
            "every particle has zero likelihood (log weights all -inf or NaN); "
            "the update cannot be normalised"
        )
    return np.exp(log_w - total), total


class _LastCall:
    """A callable that returns its last result again when called with equal input."""

    def __init__(self, g):
        self.g = g
        self.x = None
        self.out = None

    def __call__(self, x):
        x = np.asarray(x, dtype=np.float64)
        last = self.x
        if last is not None and last.shape == x.shape and np.array_equal(last, x):
            return self.out
        out = np.asarray(self.g(x), dtype=np.float64)
        out.flags.writeable = False  # shared between callers: nobody may change it
        self.x, self.out = x.copy(), out
        return out


def _last_call_cached(measurement):
    """``(measurement remembering its last evaluation, the cache)``; FunctionMeasurement only."""
    from jointtrack.superpositional.measurement import FunctionMeasurement

    if not isinstance(measurement, FunctionMeasurement):
        return measurement, None  # g(x) = Hx: closed-form moments, cheap to evaluate
    cache = _LastCall(measurement)
    return FunctionMeasurement(cache, dy=measurement.dy, dx=measurement.dx), cache


class ParticleFilterBase:
    """What the three filters share: measurement, noise, settings, likelihood method, rng.

    Subclasses implement ``predict()``, ``update(y)`` and ``estimate()``;
    :meth:`step` is predict, update, estimate. ``update`` computes the new
    particles, weights and cardinality into new arrays and assigns them only
    at the end, so an update that raises leaves the filter as it was.
    """

    def __init__(
        self,
        measurement,
        noise_cov,
        region,
        *,
        likelihood: str = "gaussian",
        likelihood_options=None,
        rng=None,
        **settings,
    ):
        from jointtrack.superpositional.measurement import as_measurement

        self.measurement = as_measurement(measurement)
        # an update evaluates g on the same particles several times (the moments of the
        # model, of its reduced model, of one target, and g(x) itself): remember the last
        self._g, self._g_cache = _last_call_cached(self.measurement)
        if self.measurement.dx is not None and self.measurement.dx != 4:
            raise ValueError(
                f"measurement must act on (px, py, vx, vy) states (dx = 4), got dx = "
                f"{self.measurement.dx}"
            )
        self.noise_cov = check_noise_cov(noise_cov, self.measurement.dy)
        known = {f.name for f in fields(FilterSettings)} - {"region"}
        unknown = sorted(set(settings) - known)
        if unknown:
            raise ValueError(
                f"unknown filter setting(s) {', '.join(unknown)} "
                f"(known: {', '.join(sorted(known))})"
            )
        self.settings = FilterSettings(region, **settings)
        self.likelihood = check_method(likelihood)
        if likelihood_options is None:
            likelihood_options = {}
        if not isinstance(likelihood_options, dict):
            raise ValueError(
                f"likelihood_options must be a dict, got {type(likelihood_options).__name__}"
            )
        self.likelihood_options = dict(likelihood_options)
        self.rng = as_rng(rng)

    def _begin_update(self, y) -> np.ndarray:
        """Check the readings and empty the g cache (it lives within one update)."""
        if self._g_cache is not None:
            self._g_cache.x = self._g_cache.out = None
        return check_measurement_vector(y, self.dy)

    @property
    def dy(self) -> int:
        return self.measurement.dy

    def _ratio(self, y, x, model) -> np.ndarray:
        """log R(x) of (16)/(20) by the configured method (finite or −inf, never NaN)."""
        from jointtrack.superpositional.likelihood import log_likelihood_ratio

        out = np.asarray(
            log_likelihood_ratio(
                y,
                x,
                model,
                self._g,
                self.noise_cov,
                method=self.likelihood,
                **self.likelihood_options,
            ),
            dtype=np.float64,
        )
        if out.shape != (x.shape[0],) or np.isnan(out).any():
            raise ValueError(
                f"log_likelihood_ratio ({self.likelihood}) returned NaN or a wrong shape "
                f"{out.shape} for {x.shape[0]} particles"
            )
        return out

    def _log_likelihood(self, y, model) -> float:
        """log I of (2)-(3) by the configured method."""
        from jointtrack.superpositional.likelihood import likelihood

        res = likelihood(
            y, model, self._g, self.noise_cov, method=self.likelihood, **self.likelihood_options
        )
        value = float(res.log_value)
        if np.isnan(value):
            raise ValueError(f"likelihood ({self.likelihood}) returned NaN")
        return value

    def step(self, y) -> np.ndarray:
        """Predict, update with the readings ``y`` (dy,), return the estimates ``(n, 4)``."""
        self.predict()
        self.update(y)
        return self.estimate()


def check_particles(particles, weights, name: str = "particles") -> tuple[np.ndarray, np.ndarray]:
    """``(particles (L, 4), normalised weights (L,))`` copies, or ValueError naming the argument."""
    p = _as_real_array(particles, name)
    if p.ndim != 2 or p.shape[1] != 4 or p.shape[0] == 0:
        raise ValueError(
            f"{name} must be (L, 4) states (px, py, vx, vy) with L >= 1, got {p.shape}"
        )
    if not np.isfinite(p).all():
        raise ValueError(f"{name} has a non-finite entry (NaN or inf)")
    wname = "weights" if name == "particles" else f"{name} weights"
    w = np.full(p.shape[0], 1.0) if weights is None else _as_real_array(weights, wname)
    if w.shape != (p.shape[0],):
        raise ValueError(f"{wname} must have shape ({p.shape[0]},) to match {name}, got {w.shape}")
    if not np.isfinite(w).all() or np.any(w < 0) or not w.sum() > 0:
        raise ValueError(f"{wname} must be finite, non-negative and not all zero")
    return np.array(p, dtype=np.float64), w / w.sum()
