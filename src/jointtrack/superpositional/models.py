r"""Random finite set models for superpositional sensors: multi-Bernoulli, IIDC, Poisson, unions.

S. Nannuru and M. Coates, "Gaussian approximation for superpositional sensors",
technical report, McGill University, 2015 (equation numbers below are that
report's); the filters that use these models: S. Nannuru, M. Coates and
R. Mahler, "Computationally-tractable approximate PHD and CPHD filters for
superpositional sensors", IEEE J. Sel. Topics Signal Process. 7(3):410-420, 2013.

Every model is immutable and validated on construction. A model has a state
dimension ``dx``, its mean cardinality n̄ (``mean_cardinality``) and second
factorial moment G₂ = E[n(n − 1)] (``second_factorial_moment``), its PHD
``log_phd(x)`` (where the spatial densities have a density), a sampler of its
sets (``sample``) and the fast path of the report's Monte Carlo,
:func:`sample_superposition`, which draws y = Σ_{x ∈ Ξ} g(x) (1) directly.

Single-target (spatial) densities are one of three kinds: a Gaussian mixture
(weights, means, covariances; covariances must be positive definite), a
weighted particle set (a Dirac mixture, the particle filters' representation)
and a uniform density over an axis-aligned box (the IIDC part of the report's
Table III).

Examples
--------
>>> import numpy as np
>>> mb = MultiBernoulli([0.5, 0.9], [[0.0, 0.0], [5.0, 5.0]], [np.eye(2), np.eye(2)])
>>> round(mb.mean_cardinality, 6), round(mb.second_factorial_moment, 6)
(1.4, 0.9)
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import gammaln, logsumexp

from jointtrack.assignment._checks import _as_real_array, as_float, as_int, as_rng

__all__ = [
    "IIDC",
    "GaussianMixtureDensity",
    "MultiBernoulli",
    "ParticleDensity",
    "Poisson",
    "UniformBoxDensity",
    "Union",
    "reduced_mixture",
    "sample_superposition",
]

#: a cardinality pmf must sum to 1 within this
PMF_TOL = 1e-9
#: relative asymmetry tolerated in a covariance matrix
SYMMETRY_TOL = 1e-9
_LOG_2PI = math.log(2.0 * math.pi)


# ----------------------------------------------------------------------------- checks


def _finite_array(value, name: str, ndim: int) -> np.ndarray:
    arr = _as_real_array(value, name)
    if arr.ndim != ndim:
        raise ValueError(f"{name} must be {ndim}-D, got an array of shape {arr.shape}")
    if not np.isfinite(arr).all():
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(arr))[0])
        raise ValueError(f"{name} has a non-finite entry ({arr[bad]}) at {bad}")
    return np.array(arr, dtype=np.float64, copy=True)


def check_covariances(covs, name: str, n: int, d: int) -> tuple[np.ndarray, np.ndarray]:
    """``(covs (n, d, d), cholesky factors)``: symmetric positive definite or ValueError."""
    arr = _finite_array(covs, name, 3)
    if arr.shape != (n, d, d):
        raise ValueError(
            f"{name} must have shape {(n, d, d)}, got {arr.shape} (dimension mismatch)"
        )
    scale = np.abs(arr).max(axis=(1, 2), initial=0.0)
    asym = np.abs(arr - np.swapaxes(arr, 1, 2)).max(axis=(1, 2), initial=0.0)
    bad = np.flatnonzero(asym > SYMMETRY_TOL * np.maximum(scale, 1e-300))
    if bad.size:
        raise ValueError(
            f"{name}[{bad[0]}] is not symmetric (largest |C - C^T| = {asym[bad[0]]:.3g})"
        )
    arr = 0.5 * (arr + np.swapaxes(arr, 1, 2))
    chol = np.empty_like(arr)
    for i in range(n):
        try:
            chol[i] = np.linalg.cholesky(arr[i])
        except np.linalg.LinAlgError:
            low = float(np.linalg.eigvalsh(arr[i]).min())
            raise ValueError(
                f"{name}[{i}] is not positive definite (smallest eigenvalue {low:.3g})"
            ) from None
    return arr, chol


def check_covariance(cov, name: str, d: int) -> tuple[np.ndarray, np.ndarray]:
    """One (d, d) symmetric positive definite matrix and its Cholesky factor."""
    arr = _finite_array(cov, name, 2)
    if arr.shape != (d, d):
        raise ValueError(f"{name} must have shape {(d, d)}, got {arr.shape} (dimension mismatch)")
    c, chol = check_covariances(arr[None], name, 1, d)
    return c[0], chol[0]


def _check_probabilities(r, name: str) -> np.ndarray:
    arr = _finite_array(r, name, 1)
    bad = np.flatnonzero((arr < 0.0) | (arr > 1.0))
    if bad.size:
        raise ValueError(f"{name}[{bad[0]}] = {arr[bad[0]]} is outside [0, 1]")
    return arr


def _check_weights(w, name: str, n: int) -> np.ndarray:
    arr = _finite_array(w, name, 1)
    if arr.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},), got {arr.shape} (dimension mismatch)")
    bad = np.flatnonzero(arr < 0.0)
    if bad.size:
        raise ValueError(f"{name}[{bad[0]}] = {arr[bad[0]]} is negative; weights are ≥ 0")
    total = arr.sum()
    if not total > 0.0:
        raise ValueError(f"{name} sums to 0; at least one weight must be positive")
    return arr / total


def _check_pmf(pmf, name: str = "cardinality_pmf") -> np.ndarray:
    arr = _finite_array(pmf, name, 1)
    if arr.size == 0:
        raise ValueError(f"{name} is empty; it needs π(0), π(1), …")
    bad = np.flatnonzero(arr < 0.0)
    if bad.size:
        raise ValueError(f"{name}[{bad[0]}] = {arr[bad[0]]} is negative")
    total = math.fsum(arr.tolist())
    if abs(total - 1.0) > PMF_TOL:
        raise ValueError(f"{name} sums to {total!r}, not 1 (tolerance {PMF_TOL:g})")
    return arr / total


def _frozen(*arrays):
    for a in arrays:
        if isinstance(a, np.ndarray):
            a.flags.writeable = False


def _dim_of(means, name: str) -> tuple[np.ndarray, int]:
    arr = _finite_array(means, name, 2)
    if arr.shape[1] < 1:
        raise ValueError(f"{name} must have at least one state dimension, got shape {arr.shape}")
    return arr, int(arr.shape[1])


class _Immutable:
    __slots__ = ()

    def __setattr__(self, name, value):
        raise AttributeError(f"{type(self).__name__} is immutable")

    def _set(self, **kw):
        for k, v in kw.items():
            _frozen(v)
            object.__setattr__(self, k, v)


# ----------------------------------------------------------------------------- spatial densities


def _gauss_hermite(d: int):
    """Probabilists' Gauss–Hermite product rule for N(0, I_d): ``(nodes (P, d), weights (P,))``."""
    order = _quadrature_order(d)
    z, w = np.polynomial.hermite_e.hermegauss(order)
    w = w / math.sqrt(2.0 * math.pi)
    grids = np.meshgrid(*([z] * d), indexing="ij")
    wg = np.meshgrid(*([w] * d), indexing="ij")
    nodes = np.stack([g.ravel() for g in grids], axis=1)
    weights = np.prod(np.stack([g.ravel() for g in wg], axis=1), axis=1)
    return nodes, weights


def _gauss_legendre(d: int):
    """Gauss–Legendre product rule on [0, 1]^d: ``(nodes (P, d), weights (P,))``."""
    order = _quadrature_order(d)
    z, w = np.polynomial.legendre.leggauss(order)
    z, w = 0.5 * (z + 1.0), 0.5 * w
    grids = np.meshgrid(*([z] * d), indexing="ij")
    wg = np.meshgrid(*([w] * d), indexing="ij")
    nodes = np.stack([g.ravel() for g in grids], axis=1)
    weights = np.prod(np.stack([g.ravel() for g in wg], axis=1), axis=1)
    return nodes, weights


def _quadrature_order(d: int) -> int:
    """Points per dimension of the product rules: 9 (d ≤ 3), 7 (d ≤ 4), 5 (d ≤ 6), else 3."""
    if d <= 3:
        return 9
    if d <= 4:
        return 7
    if d <= 6:
        return 5
    return 3


class GaussianMixtureDensity(_Immutable):
    r"""A Gaussian mixture density Σ_k w_k N(x; m_k, P_k) with positive definite P_k.

    Moments of g under it are exact for a :class:`LinearMeasurement` and use a
    deterministic Gauss–Hermite product rule (9 points per dimension up to
    dx = 3, 7 for dx = 4, 5 up to dx = 6, 3 beyond) for a general g.
    """

    __slots__ = ("weights", "log_weights", "means", "covs", "chol", "chol_inv", "log_dets", "dx")

    def __init__(self, weights, means, covs, *, prefix: str = ""):
        means, dx = _dim_of(means, prefix + "means")
        k = means.shape[0]
        if k < 1:
            raise ValueError(f"{prefix}means must hold at least one component")
        w = _check_weights(weights, prefix + "weights", k)
        covs, chol = check_covariances(covs, prefix + "covs", k, dx)
        with np.errstate(divide="ignore"):
            lw = np.log(w)
        self._set(
            weights=w,
            log_weights=lw,
            means=means,
            covs=covs,
            chol=chol,
            chol_inv=np.linalg.inv(chol),
            log_dets=2.0 * np.log(np.diagonal(chol, axis1=1, axis2=2)).sum(axis=1),
            dx=dx,
        )

    @property
    def kind(self) -> str:
        return "gaussian"

    def sample(self, n: int, rng) -> np.ndarray:
        comp = np.searchsorted(np.cumsum(self.weights), rng.random(n) * self.weights.sum())
        comp = np.minimum(comp, len(self.weights) - 1)
        z = rng.standard_normal((n, self.dx))
        return self.means[comp] + np.einsum("nij,nj->ni", self.chol[comp], z)

    def log_pdf(self, x: np.ndarray) -> np.ndarray:
        """log density at the rows of x (L, dx)."""
        # whitening with the inverse Cholesky factors (small dx: cheaper than K triangular solves)
        z = np.einsum("kij,lkj->lki", self.chol_inv, x[:, None, :] - self.means[None])
        q = np.einsum("lki,lki->lk", z, z)
        lp = self.log_weights[None] - 0.5 * (q + self.log_dets[None] + self.dx * _LOG_2PI)
        return logsumexp(lp, axis=1) if lp.shape[1] > 1 else lp[:, 0]

    def g_moments(self, measurement) -> tuple[np.ndarray, np.ndarray]:
        """``(E[g(x)], E[g(x) g(x)^T])`` under the mixture."""
        m1, m2 = self.component_g_moments(measurement)
        return self.weights @ m1, np.einsum("k,kij->ij", self.weights, m2)

    def component_g_moments(self, measurement) -> tuple[np.ndarray, np.ndarray]:
        """Per component: ``(E_k[g] (K, dy), E_k[g g^T] (K, dy, dy))``."""
        H = getattr(measurement, "H", None)
        if H is not None:
            m1 = self.means @ H.T
            m2 = H @ self.covs @ H.T + m1[:, :, None] * m1[:, None, :]
            return m1, m2
        nodes, w = _gauss_hermite(self.dx)
        pts = self.means[:, None, :] + np.einsum("kij,pj->kpi", self.chol, nodes)
        gv = measurement(pts)  # (K, P, dy)
        m1 = np.einsum("p,kpi->ki", w, gv)
        m2 = np.einsum("p,kpi,kpj->kij", w, gv, gv)
        return m1, m2

    def to_particles(self, n: int, rng) -> ParticleDensity:
        return ParticleDensity(self.sample(n, rng), np.ones(n))


class ParticleDensity(_Immutable):
    r"""A weighted particle set Σ_l w_l δ(x − x_l) (weights normalised to sum 1)."""

    __slots__ = ("particles", "weights", "dx")

    def __init__(self, particles, weights=None, *, prefix: str = ""):
        p, dx = _dim_of(particles, prefix + "particles")
        if p.shape[0] < 1:
            raise ValueError(f"{prefix}particles must hold at least one particle")
        w = np.ones(p.shape[0]) if weights is None else weights
        w = _check_weights(w, prefix + "weights", p.shape[0])
        self._set(particles=p, weights=w, dx=dx)

    @property
    def kind(self) -> str:
        return "particles"

    def sample(self, n: int, rng) -> np.ndarray:
        idx = np.searchsorted(np.cumsum(self.weights), rng.random(n))
        return self.particles[np.minimum(idx, len(self.weights) - 1)]

    def log_pdf(self, x: np.ndarray) -> np.ndarray:
        raise ValueError(
            "a particle density has no pointwise density value; the multi-Bernoulli weights "
            "r_i p_i(x)/D(x) need Gaussian (or uniform) components, or use leave_one_out_moments "
            "per component"
        )

    def g_moments(self, measurement) -> tuple[np.ndarray, np.ndarray]:
        gv = measurement(self.particles)
        wg = self.weights[:, None] * gv
        return wg.sum(axis=0), wg.T @ gv

    def component_g_moments(self, measurement):
        m1, m2 = self.g_moments(measurement)
        return m1[None], m2[None]

    def to_particles(self, n: int, rng) -> ParticleDensity:
        return self


class UniformBoxDensity(_Immutable):
    r"""The uniform density over the box [low, high] (product of intervals).

    Moments of g are exact for a :class:`LinearMeasurement` (mean H(l + h)/2,
    covariance H diag((h − l)²/12) Hᵀ) and use a Gauss–Legendre product rule
    (same orders as the Gaussian rule) for a general g.
    """

    __slots__ = ("low", "high", "dx", "log_volume")

    def __init__(self, low, high):
        lo = _finite_array(low, "low", 1)
        hi = _finite_array(high, "high", 1)
        if lo.shape != hi.shape or lo.size < 1:
            raise ValueError(
                f"low and high must be 1-D of equal length, got {lo.shape}, {hi.shape}"
            )
        bad = np.flatnonzero(~(hi > lo))
        if bad.size:
            raise ValueError(
                f"high[{bad[0]}] = {hi[bad[0]]} must exceed low[{bad[0]}] = {lo[bad[0]]}"
            )
        self._set(low=lo, high=hi, dx=int(lo.size), log_volume=float(np.log(hi - lo).sum()))

    @property
    def kind(self) -> str:
        return "uniform"

    def sample(self, n: int, rng) -> np.ndarray:
        return self.low + (self.high - self.low) * rng.random((n, self.dx))

    def log_pdf(self, x: np.ndarray) -> np.ndarray:
        inside = ((x >= self.low) & (x <= self.high)).all(axis=1)
        return np.where(inside, -self.log_volume, -np.inf)

    def g_moments(self, measurement):
        H = getattr(measurement, "H", None)
        if H is not None:
            mid = 0.5 * (self.low + self.high)
            var = (self.high - self.low) ** 2 / 12.0
            m1 = H @ mid
            return m1, (H * var) @ H.T + np.outer(m1, m1)
        nodes, w = _gauss_legendre(self.dx)
        gv = measurement(self.low + (self.high - self.low) * nodes)
        return w @ gv, np.einsum("p,pi,pj->ij", w, gv, gv)

    def component_g_moments(self, measurement):
        m1, m2 = self.g_moments(measurement)
        return m1[None], m2[None]

    def to_particles(self, n: int, rng) -> ParticleDensity:
        return ParticleDensity(self.sample(n, rng), np.ones(n))


# ----------------------------------------------------------------------------- RFS models


class MultiBernoulli(_Immutable):
    r"""A multi-Bernoulli RFS {(r_i, p_i)}: component i exists with probability r_i.

    Parameters
    ----------
    r : array_like, shape (n,)
        Existence probabilities in [0, 1].
    means : array_like, shape (n, dx)
    covs : array_like, shape (n, dx, dx)
        One Gaussian p_i = N(means[i], covs[i]) per component (positive definite).

    Notes
    -----
    PHD D(x) = Σ_i r_i p_i(x), n̄ = Σ r_i and G₂ = Σ_{i≠j} r_i r_j.
    ``from_particles`` gives components represented by weighted particles.
    """

    __slots__ = ("r", "components", "dx", "means", "covs")

    def __init__(self, r, means, covs):
        r = _check_probabilities(r, "r")
        means, dx = _dim_of(means, "means")
        if means.shape[0] != r.size:
            raise ValueError(
                f"means has {means.shape[0]} rows but r has {r.size} entries (dimension mismatch)"
            )
        covs, _ = check_covariances(covs, "covs", r.size, dx)
        comps = tuple(
            GaussianMixtureDensity(
                [1.0], means[i : i + 1], covs[i : i + 1], prefix=f"component {i} "
            )
            for i in range(r.size)
        )
        self._set(r=r, components=comps, dx=dx, means=means, covs=covs)

    @classmethod
    def from_particles(cls, r, particles, weights=None) -> MultiBernoulli:
        """Components given as weighted particle sets.

        Parameters
        ----------
        r : array_like, shape (n,)
        particles : sequence of n arrays (L_i, dx)
        weights : sequence of n arrays (L_i,), optional
            Non-negative; normalised per component. Uniform when omitted.
        """
        r = _check_probabilities(r, "r")
        if isinstance(particles, np.ndarray) and particles.ndim == 3:
            particles = list(particles)
        if len(particles) != r.size:
            raise ValueError(
                f"particles holds {len(particles)} components but r has {r.size} "
                "(dimension mismatch)"
            )
        if weights is not None and len(weights) != r.size:
            raise ValueError(
                f"weights holds {len(weights)} components but r has {r.size} (dimension mismatch)"
            )
        comps = tuple(
            ParticleDensity(
                particles[i], None if weights is None else weights[i], prefix=f"component {i} "
            )
            for i in range(r.size)
        )
        return cls._from_components(r, comps, _common_dx(comps, "particles"))

    @classmethod
    def _from_components(cls, r, comps, dx) -> MultiBernoulli:
        self = object.__new__(cls)
        r = np.array(r, dtype=np.float64)
        gauss = all(c.kind == "gaussian" and len(c.weights) == 1 for c in comps)
        means = np.array([c.means[0] for c in comps]).reshape(len(comps), dx) if gauss else None
        covs = np.array([c.covs[0] for c in comps]).reshape(len(comps), dx, dx) if gauss else None
        self._set(r=r, components=tuple(comps), dx=int(dx), means=means, covs=covs)
        return self

    @property
    def n_components(self) -> int:
        return int(self.r.size)

    def component(self, i: int):
        """The spatial density of component i (Gaussian or particle density)."""
        return self.components[as_int(i, "i", 0, self.n_components - 1)]

    @property
    def mean_cardinality(self) -> float:
        return float(self.r.sum())

    @property
    def second_factorial_moment(self) -> float:
        s = self.r.sum()
        return float(s * s - (self.r**2).sum())

    def leave_one_out(self, i: int) -> MultiBernoulli:
        """The multi-Bernoulli set without component i."""
        keep = [j for j in range(self.n_components) if j != i]
        return MultiBernoulli._from_components(
            self.r[keep], [self.components[j] for j in keep], self.dx
        )

    def component_log_pdf(self, x: np.ndarray) -> np.ndarray:
        """log p_i(x) for each state (L, dx) and component: (L, n)."""
        return np.stack([c.log_pdf(x) for c in self.components], axis=1).reshape(len(x), -1)

    def log_phd(self, x: np.ndarray) -> np.ndarray:
        with np.errstate(divide="ignore"):
            lr = np.log(self.r)
        if self.n_components == 0:
            return np.full(len(x), -np.inf)
        return logsumexp(lr[None] + self.component_log_pdf(x), axis=1)

    def sample(self, n_samples: int, rng=None) -> list[np.ndarray]:
        rng = as_rng(rng)
        n_samples = as_int(n_samples, "n_samples", minimum=0)
        exist = rng.random((n_samples, self.n_components)) < self.r
        pts = [c.sample(n_samples, rng) for c in self.components]
        return [
            np.array([pts[i][s] for i in range(self.n_components) if exist[s, i]]).reshape(
                -1, self.dx
            )
            for s in range(n_samples)
        ]

    def _sample_y(self, measurement, n: int, rng) -> np.ndarray:
        y = np.zeros((n, measurement.dy))
        for i, c in enumerate(self.components):
            exist = np.flatnonzero(rng.random(n) < self.r[i])
            if exist.size:
                y[exist] += measurement(c.sample(exist.size, rng))
        return y

    def to_particles(self, n_particles: int, rng=None) -> MultiBernoulli:
        rng = as_rng(rng)
        comps = [c.to_particles(n_particles, rng) for c in self.components]
        return MultiBernoulli._from_components(self.r, comps, self.dx)

    def __repr__(self) -> str:
        return f"MultiBernoulli(n={self.n_components}, dx={self.dx})"


def _common_dx(comps, name) -> int:
    dims = {c.dx for c in comps}
    if len(dims) > 1:
        raise ValueError(f"{name}: components have different state dimensions {sorted(dims)}")
    if not dims:
        raise ValueError(f"{name}: at least one component is needed to know the state dimension")
    return dims.pop()


class _IIDLike(_Immutable):
    """Shared code of IIDC and Poisson: n points drawn iid from one spatial density."""

    __slots__ = ()

    @property
    def weights(self):
        return getattr(self.spatial, "weights", None) if self.spatial.kind == "gaussian" else None

    @property
    def means(self):
        return self.spatial.means if self.spatial.kind == "gaussian" else None

    @property
    def covs(self):
        return self.spatial.covs if self.spatial.kind == "gaussian" else None

    def log_phd(self, x: np.ndarray) -> np.ndarray:
        if self.mean_cardinality == 0.0:
            return np.full(len(x), -np.inf)
        return math.log(self.mean_cardinality) + self.spatial.log_pdf(x)

    def sample(self, n_samples: int, rng=None) -> list[np.ndarray]:
        rng = as_rng(rng)
        n_samples = as_int(n_samples, "n_samples", minimum=0)
        counts = self._sample_counts(n_samples, rng)
        pts = self.spatial.sample(int(counts.sum()), rng)
        return np.split(pts, np.cumsum(counts)[:-1]) if n_samples else []

    def _sample_y(self, measurement, n: int, rng) -> np.ndarray:
        counts = self._sample_counts(n, rng)
        total = int(counts.sum())
        y = np.zeros((n, measurement.dy))
        if total:
            gv = measurement(self.spatial.sample(total, rng))
            owner = np.repeat(np.arange(n), counts)
            for j in range(measurement.dy):
                y[:, j] = np.bincount(owner, weights=gv[:, j], minlength=n)
        return y


class IIDC(_IIDLike):
    r"""An independent identically distributed cluster RFS: cardinality pmf π and spatial density s.

    Parameters
    ----------
    cardinality_pmf : array_like, shape (N + 1,)
        π(0), …, π(N); non-negative, summing to 1 within 1e-9.
    weights, means, covs : array_like
        The Gaussian-mixture spatial density s(x) = Σ_k w_k N(x; m_k, P_k)
        (weights normalised internally).

    Notes
    -----
    PHD D(x) = n̄ s(x), second factorial moment density G₂ s(x₁) s(x₂) with
    G₂ = Σ n(n − 1) π(n), so D̃ of (7) is (G₂ − n̄²) s s.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.stats import poisson
    >>> pmf = poisson.pmf(np.arange(16), 8.0); pmf /= pmf.sum()
    >>> m = IIDC(pmf, [1.0], [[0.0, 0.0]], [np.eye(2)])
    >>> round(m.mean_cardinality, 2), round(m.second_factorial_moment, 1)
    (7.93, 62.3)
    """

    __slots__ = ("cardinality_pmf", "spatial", "dx", "mean_cardinality", "second_factorial_moment")

    def __init__(self, cardinality_pmf, weights, means, covs):
        self._init(_check_pmf(cardinality_pmf), GaussianMixtureDensity(weights, means, covs))

    def _init(self, pmf, spatial):
        n = np.arange(pmf.size, dtype=np.float64)
        self._set(
            cardinality_pmf=pmf,
            spatial=spatial,
            dx=spatial.dx,
            mean_cardinality=float(pmf @ n),
            second_factorial_moment=float(pmf @ (n * (n - 1.0))),
        )

    @classmethod
    def _make(cls, pmf, spatial) -> IIDC:
        self = object.__new__(cls)
        self._init(pmf, spatial)
        return self

    @classmethod
    def uniform(cls, cardinality_pmf, low, high) -> IIDC:
        """An IIDC whose spatial density is uniform over the box [low, high]."""
        return cls._make(_check_pmf(cardinality_pmf), UniformBoxDensity(low, high))

    @classmethod
    def from_particles(cls, cardinality_pmf, particles, weights=None) -> IIDC:
        """An IIDC whose spatial density is the weighted particle set (L, dx), (L,)."""
        return cls._make(_check_pmf(cardinality_pmf), ParticleDensity(particles, weights))

    @property
    def max_cardinality(self) -> int:
        return int(self.cardinality_pmf.size - 1)

    def reduced(self) -> IIDC:
        r"""The reduced IIDC of (17): π*(n) = (n + 1) π(n + 1) / n̄, the same spatial density."""
        if self.mean_cardinality == 0.0:
            # D ≡ 0: the reduced density is never weighted; take the empty set
            return IIDC._make(np.array([1.0]), self.spatial)
        n = np.arange(1, self.cardinality_pmf.size, dtype=np.float64)
        pmf = n * self.cardinality_pmf[1:] / self.mean_cardinality
        if pmf.size == 0:
            pmf = np.array([1.0])
        return IIDC._make(pmf / pmf.sum(), self.spatial)

    def _sample_counts(self, n: int, rng) -> np.ndarray:
        cdf = np.cumsum(self.cardinality_pmf)
        c = np.searchsorted(cdf, rng.random(n) * cdf[-1], side="right")
        return np.minimum(c, self.cardinality_pmf.size - 1)

    def to_particles(self, n_particles: int, rng=None) -> IIDC:
        return IIDC._make(self.cardinality_pmf, self.spatial.to_particles(n_particles, as_rng(rng)))

    def __repr__(self) -> str:
        return f"IIDC(max n={self.max_cardinality}, spatial={self.spatial.kind}, dx={self.dx})"


class Poisson(_IIDLike):
    r"""A Poisson RFS with mean count λ and spatial density s (PHD λ s); it is its own reduction.

    Parameters
    ----------
    mean_count : float
        λ ≥ 0.
    weights, means, covs : array_like
        The Gaussian-mixture spatial density.

    Notes
    -----
    G₂ = λ², so D̃ of (7) vanishes and Σ_Q = λ E_s[g gᵀ].
    """

    __slots__ = ("spatial", "dx", "mean_cardinality", "second_factorial_moment")

    def __init__(self, mean_count, weights, means, covs):
        self._init(
            as_float(mean_count, "mean_count", minimum=0.0),
            GaussianMixtureDensity(weights, means, covs),
        )

    def _init(self, lam, spatial):
        self._set(
            spatial=spatial, dx=spatial.dx, mean_cardinality=lam, second_factorial_moment=lam * lam
        )

    @classmethod
    def from_particles(cls, mean_count, particles, weights=None) -> Poisson:
        """A Poisson RFS whose spatial density is the weighted particle set."""
        self = object.__new__(cls)
        self._init(
            as_float(mean_count, "mean_count", minimum=0.0), ParticleDensity(particles, weights)
        )
        return self

    @classmethod
    def uniform(cls, mean_count, low, high) -> Poisson:
        """A Poisson RFS uniform over the box [low, high]."""
        self = object.__new__(cls)
        self._init(as_float(mean_count, "mean_count", minimum=0.0), UniformBoxDensity(low, high))
        return self

    @property
    def mean_count(self) -> float:
        """λ, the mean number of points (same as ``mean_cardinality``)."""
        return self.mean_cardinality

    def cardinality_pmf_truncated(self, tail: float = 1e-16) -> tuple[np.ndarray, float]:
        """``(π(0..N), mass above N)``: N is the first count whose upper tail is below ``tail``."""
        from scipy.stats import poisson

        lam = self.mean_cardinality
        if lam == 0.0:
            return np.array([1.0]), 0.0
        n_max = int(poisson.isf(tail, lam)) + 1
        n = np.arange(n_max + 1, dtype=np.float64)
        pmf = np.exp(n * math.log(lam) - lam - gammaln(n + 1.0))
        return pmf, float(poisson.sf(n_max, lam))

    def _sample_counts(self, n: int, rng) -> np.ndarray:
        return rng.poisson(self.mean_cardinality, n)

    def to_particles(self, n_particles: int, rng=None) -> Poisson:
        self2 = object.__new__(Poisson)
        self2._init(self.mean_cardinality, self.spatial.to_particles(n_particles, as_rng(rng)))
        return self2

    def __repr__(self) -> str:
        return (
            f"Poisson(mean_count={self.mean_cardinality}, spatial={self.spatial.kind}, "
            f"dx={self.dx})"
        )


_MODEL_TYPES = (MultiBernoulli, IIDC, Poisson)


class Union(_Immutable):
    r"""The union of independent RFSs; y is the sum of the parts' y, so moments add.

    Parameters
    ----------
    *parts : MultiBernoulli, IIDC, Poisson or Union
        Independent parts with the same state dimension (nested unions are flattened).
    """

    __slots__ = ("parts", "dx", "mean_cardinality", "second_factorial_moment")

    def __init__(self, *parts):
        flat = []
        for i, p in enumerate(parts):
            if isinstance(p, Union):
                flat.extend(p.parts)
            elif isinstance(p, _MODEL_TYPES):
                flat.append(p)
            else:
                raise ValueError(
                    f"parts[{i}] must be a MultiBernoulli, IIDC, Poisson or Union, "
                    f"got {type(p).__name__}"
                )
        if not flat:
            raise ValueError("Union needs at least one part")
        dims = {p.dx for p in flat}
        if len(dims) > 1:
            raise ValueError(
                f"parts have different state dimensions {sorted(dims)} (dimension mismatch)"
            )
        nbar = sum(p.mean_cardinality for p in flat)
        # G₂ of a union: Σ G₂_k + Σ_{k≠l} n̄_k n̄_l
        g2 = (
            sum(p.second_factorial_moment for p in flat)
            + nbar**2
            - sum(p.mean_cardinality**2 for p in flat)
        )
        self._set(
            parts=tuple(flat),
            dx=dims.pop(),
            mean_cardinality=float(nbar),
            second_factorial_moment=float(g2),
        )

    def log_phd(self, x: np.ndarray) -> np.ndarray:
        return logsumexp(np.stack([p.log_phd(x) for p in self.parts], axis=1), axis=1)

    def sample(self, n_samples: int, rng=None) -> list[np.ndarray]:
        rng = as_rng(rng)
        per = [p.sample(n_samples, rng) for p in self.parts]
        return [np.concatenate([s[k] for s in per], axis=0) for k in range(len(per[0]))]

    def _sample_y(self, measurement, n: int, rng) -> np.ndarray:
        return sum(p._sample_y(measurement, n, rng) for p in self.parts)

    def to_particles(self, n_particles: int, rng=None) -> Union:
        rng = as_rng(rng)
        return Union(*[p.to_particles(n_particles, rng) for p in self.parts])

    def __repr__(self) -> str:
        return f"Union({', '.join(repr(p) for p in self.parts)})"


MODEL_TYPES = (*_MODEL_TYPES, Union)


def check_model(model, name: str = "model"):
    """``model`` if it is one of the RFS models, else ValueError."""
    if not isinstance(model, MODEL_TYPES):
        raise ValueError(
            f"{name} must be a MultiBernoulli, IIDC, Poisson or Union, got {type(model).__name__}"
        )
    return model


def sample_superposition(model, g, n_samples: int, rng=None) -> np.ndarray:
    r"""Samples of y = Σ_{x ∈ Ξ} g(x) (1), vectorised: ``(n_samples, dy)``.

    Parameters
    ----------
    model : MultiBernoulli, IIDC, Poisson or Union
    g : array_like (dy, dx) or measurement object
    n_samples : int
    rng : None, int or numpy.random.Generator

    Examples
    --------
    >>> import numpy as np
    >>> mb = MultiBernoulli([1.0], [[1.0, 2.0]], [1e-12 * np.eye(2)])
    >>> np.round(sample_superposition(mb, [[1.0, 1.0]], 2, rng=0), 3).tolist()
    [[3.0], [3.0]]
    """
    from jointtrack.superpositional.measurement import as_measurement

    check_model(model)
    m = as_measurement(g, model.dx)
    n = as_int(n_samples, "n_samples", minimum=0)
    return model._sample_y(m, n, as_rng(rng))


def reduced_mixture(model, x, part: int | None = None):
    r"""The reduced RFS of (17) at states x as a mixture of RFS models with x-dependent weights.

    Returns ``(log_weights (L, K), submodels)``: the reduced density
    f^{*x}(W) = f({x} ∪ W) / D(x) equals Σ_k w_k(x) f_k(W).

    * Poisson: itself (K = 1).
    * IIDC: the IIDC with cardinality π*(n) = (n + 1) π(n + 1)/n̄ and the same
      spatial density (K = 1).
    * Multi-Bernoulli: the leave-one-out sets MB₋ᵢ with w_i(x) = r_i p_i(x)/D(x).
    * Union: for each part k, the part's reduced mixture united with the other
      parts, weighted by D_k(x)/D(x). With ``part`` given, only that part is
      reduced (the report's A of (17), the other parts B unchanged).

    States where D(x) = 0 get uniform weights over the mixture, and an empty
    model reduces to itself: the reduced density is undefined there, and the
    filters multiply R(x) by D(x) = 0.
    """
    x = np.asarray(x, dtype=np.float64)
    L = x.shape[0]
    if isinstance(model, Poisson):
        return np.zeros((L, 1)), [model]
    if isinstance(model, IIDC):
        return np.zeros((L, 1)), [model.reduced()]
    if isinstance(model, MultiBernoulli):
        if model.n_components == 0:
            return np.zeros((L, 1)), [model]  # D ≡ 0: never weighted; the empty set
        with np.errstate(divide="ignore"):
            lw = np.log(model.r)[None] + model.component_log_pdf(x)
        return _normalise_rows(lw), [model.leave_one_out(i) for i in range(model.n_components)]
    parts = model.parts
    chosen = range(len(parts)) if part is None else [as_int(part, "part", 0, len(parts) - 1)]
    blocks, subs = [], []
    for k in chosen:
        lw_k, sub_k = reduced_mixture(parts[k], x)
        rest = [p for j, p in enumerate(parts) if j != k]
        lphd = parts[k].log_phd(x)[:, None] if part is None else 0.0
        blocks.append(lw_k + lphd)
        subs.extend(Union(s, *rest) if rest else s for s in sub_k)
    return _normalise_rows(np.concatenate(blocks, axis=1)), subs


def _normalise_rows(lw: np.ndarray) -> np.ndarray:
    tot = logsumexp(lw, axis=1, keepdims=True)
    bad = ~np.isfinite(tot[:, 0])
    out = lw - np.where(np.isfinite(tot), tot, 0.0)
    if bad.any():
        out[bad] = -math.log(lw.shape[1])
    return out
