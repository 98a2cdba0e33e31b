r"""Particle JPDA: a known set of targets, each a particle set, weighted by Streit's derivatives.

R. L. Streit, "Saddle point method for JPDA and related filters", *Proc. 18th
International Conference on Information Fusion* (FUSION), Washington DC, 2015.
Equation numbers below are that paper's.

The filter
----------
JPDA keeps one marginal distribution per target (§2.4). Here target n's is a
set of L particles drawn from its predicted density μ_n (eq. 3). Per scan:

1. **Predict**: every particle moves by the motion model with a sampled
   process noise (x' = F x + w, w ~ N(0, Q)), so the predicted particles are
   draws from μ_n.
2. **Likelihoods**: p(y_m | x) of the linear-Gaussian position sensor
   (y = H x + v, v ~ N(0, R)) for every particle and measurement, and P_D(x)
   (a constant or a function of the state).
3. **Weights**: the weight of particle x of target n is the mixed derivative
   (18) of Ψ_JPDA(n) (14) with the coefficients (7) — the particle's own factor
   b_n·(x) and the other targets' particle-set integrals c_j· — built by
   :func:`jointtrack.saddle.jpda_coefficients`. The particles are draws from
   μ_n, so μ_n(x) is *not* multiplied into b (it is already in the sampling;
   see that function's docstring). ``weights="exact"`` computes all L weights
   of a target from one assignment-sum core call
   (:func:`jointtrack.saddle.jpda_log_weights`); ``"saddle"`` (eqs. 24, 30, 31)
   and ``"saddle-corrected"`` (when :mod:`jointtrack.saddle` provides it) run
   one batched :func:`jointtrack.saddle.log_mixed_derivative` over the L
   particles of a target. The weights are normalised in log space (the saddle
   point's global scale factor, §6, cancels there).
4. **Estimate**: the weighted mean and covariance of each target's particles
   (before resampling) — the track reported for the scan.
5. **Resample**: systematic resampling of every target's set, every scan.
   Every scan (not when the effective sample size drops): the particle-set
   integrals c_j of eq. (7) are plain averages over equally weighted
   particles (:func:`jointtrack.saddle.jpda_coefficients`), which is what the
   sets are after resampling. The effective sample size before resampling is
   reported per target (:attr:`ParticleScanResult.ess`).

Targets are known and fixed (JPDA's assumption, §2): the tracker is started
from given states and covariances (:meth:`ParticleJPDATracker.start`, e.g. the
truth at the first scan) and tracks are never born, confirmed or deleted.

Exact simplifications
---------------------
* *Column scaling*: multiplying a_m and every f_km of one measurement m by
  s_m > 0 multiplies every assignment term — and the saddle-point value
  (30), since Ψ(β) ↦ Ψ(s β) — by s_m once. Each measurement's column is
  scaled so its largest term is 1, so likelihoods far below the float range
  in absolute terms are no problem; a clutter term e^{-708} times smaller
  than the column's largest likelihood is held at the smallest normal float
  (eq. (7) requires a_m > 0).
* *Components*: a measurement that no particle of any target can have made
  (likelihood 0 after scaling) is clutter for every particle: a global factor
  a_m, dropped. The rest splits into connected components of targets and the
  measurements their particles reach; Ψ_JPDA(n) factorises over components,
  and the factors of components without target n are the same for all of
  target n's particles (also for the saddle-point value: φ is separable and
  its Hessian block diagonal), so target n's weights use its component only.

Gating (``p_g`` < 1) sets p(y_m | x) = 0 when the Mahalanobis distance of y_m
from the particle's predicted measurement exceeds γ = χ²_d⁻¹(p_g): each
particle's likelihood is truncated to its gate of probability p_g, so the
result changes by at most the 1 − p_g of likelihood mass cut off. ``p_g = 1``
(the default) gates nothing: the result is the ungated one to rounding.

Reproducible: all randomness (initial draws, process noise, resampling) comes
from one :class:`numpy.random.Generator` seeded by ``config.seed``, and the
generator is part of the state. :meth:`ParticleJPDATracker.step` is atomic:
it computes into temporaries and assigns the new particles, time, counter and
generator only at the end, so a step that raises leaves the tracker exactly
as it was.
"""

from __future__ import annotations

import copy
import math
import numbers
import time as _time
from dataclasses import asdict, dataclass, field

import numpy as np
from scipy.special import logsumexp

from jointtrack.assignment._checks import _as_real_array, as_float
from jointtrack.association.gating import gate_threshold
from jointtrack.models import LinearPosition
from jointtrack.saddle import (
    jpda_coefficients,
    jpda_log_weights,
    log_mixed_derivative,
)
from jointtrack.trackers.base import motion_model
from jointtrack.trackers.config import _check_noise, check_field, config_from_dict

__all__ = [
    "WEIGHT_METHODS",
    "ParticleConfig",
    "ParticleDegeneracyError",
    "ParticleJPDATracker",
    "ParticleScanResult",
    "ScanWeights",
    "available_weight_methods",
    "jpda_particle_log_weights",
    "systematic_resample",
]

#: Particle weight methods: the exact mixed derivative, Streit's saddle point (30),
#: and the corrected saddle point of :mod:`jointtrack.saddle` (when it provides it).
WEIGHT_METHODS = ("exact", "saddle", "saddle-corrected")


def available_weight_methods() -> tuple[str, ...]:
    """The entries of :data:`WEIGHT_METHODS` this installation's :mod:`jointtrack.saddle` has."""
    from jointtrack.saddle import derivative

    return tuple(m for m in WEIGHT_METHODS if m in derivative.METHODS)


def _check_weights_method(method) -> str:
    if not isinstance(method, str) or method not in WEIGHT_METHODS:
        raise ValueError(f"weights must be one of {', '.join(WEIGHT_METHODS)}, got {method!r}")
    have = available_weight_methods()
    if method not in have:
        raise ValueError(
            f"weights = {method!r} needs the method {method!r} of jointtrack.saddle, which "
            f"this installation does not provide (it has: {', '.join(have)})"
        )
    return method


class ParticleDegeneracyError(ValueError):
    """Every particle of a target has weight 0: the measurements rule out its whole set."""


# ----------------------------------------------------------------------------- configuration


@dataclass(frozen=True)
class ParticleConfig:
    """Everything that defines a :class:`ParticleJPDATracker`; plain numbers, TOML-friendly.

    Attributes
    ----------
    particles : int ≥ 1
        L, particles per target.
    weights : {"exact", "saddle", "saddle-corrected"}
        how a particle's weight (the mixed derivative (18)) is computed.
    dim : 2 or 3
        spatial dimension; measurements are positions ``[x, y(, z)]``.
    motion : ``"cv"`` or ``"ca"``
        nearly constant velocity or constant acceleration
        (:mod:`jointtrack.models.motion`), with ``process_noise`` q.
    process_noise : float > 0
        q of the motion model (m²/s³ for CV, m²/s⁵ for CA).
    measurement_noise : float, per-axis sequence or dim × dim matrix
        R of the position sensor (as :class:`~jointtrack.trackers.TrackerConfig`).
    p_d : float in (0, 1]
        constant detection probability (a state-dependent P_D is given to the
        tracker as a function, see :class:`ParticleJPDATracker`).
    p_g : float in (0, 1]
        gate probability of each particle's likelihood (1: no gate; see the
        module docstring).
    clutter_density : float > 0, or None
        λ, false returns per unit volume (the clutter term Λ p_Λ(y) = λ of a
        uniform clutter density). None: the tracker must be given a
        ``clutter`` function.
    seed : int ≥ 0 or None
        seed of the tracker's random generator.

    Every field is checked on construction; a bad value raises ValueError
    naming it.
    """

    particles: int = 1000
    weights: str = "exact"
    dim: int = 2
    motion: str = "cv"
    process_noise: float = 1.0
    measurement_noise: float | tuple = 100.0
    p_d: float = 0.9
    p_g: float = 1.0
    clutter_density: float | None = None
    seed: int | None = 0

    def __post_init__(self):
        p = self.particles
        if isinstance(p, bool | np.bool_) or not isinstance(p, numbers.Integral) or p < 1:
            raise ValueError(f"ParticleConfig: particles must be an integer ≥ 1, got {p!r}")
        object.__setattr__(self, "particles", int(p))
        if not isinstance(self.weights, str) or self.weights not in WEIGHT_METHODS:
            raise ValueError(
                f"ParticleConfig: weights must be one of {', '.join(WEIGHT_METHODS)}, "
                f"got {self.weights!r}"
            )
        try:
            # the TrackerConfig rules for the fields the two trackers share
            for name in ParticleConfig.FROM_TRACKER:
                object.__setattr__(self, name, check_field(name, getattr(self, name)))
            object.__setattr__(
                self, "measurement_noise", _check_noise(self.measurement_noise, self.dim)
            )
        except ValueError as exc:
            raise ValueError(str(exc).replace("TrackerConfig:", "ParticleConfig:")) from None

    def measurement_covariance(self) -> np.ndarray:
        """R as a (dim, dim) array."""
        R = np.asarray(self.measurement_noise, dtype=np.float64)
        if R.ndim == 0:
            return float(R) * np.eye(self.dim)
        if R.ndim == 1:
            return np.diag(R)
        return R.copy()

    #: the :class:`~jointtrack.trackers.TrackerConfig` fields a particle tracker uses
    FROM_TRACKER = (
        "dim",
        "motion",
        "process_noise",
        "measurement_noise",
        "p_d",
        "p_g",
        "clutter_density",
        "seed",
    )

    @classmethod
    def from_tracker_config(cls, cfg, **overrides) -> ParticleConfig:
        """The fields :data:`FROM_TRACKER` of a ``TrackerConfig`` plus ``overrides``."""
        d = {name: getattr(cfg, name) for name in cls.FROM_TRACKER}
        d.update(overrides)
        return cls(**d)

    @classmethod
    def from_dict(cls, d: dict) -> ParticleConfig:
        """Build from a mapping; unknown keys are an error naming them."""
        return config_from_dict(cls, d, "particle tracker")

    def to_dict(self) -> dict:
        return asdict(self)


# ----------------------------------------------------------------------------- weights


@dataclass(frozen=True)
class ScanWeights:
    """Result of :func:`jpda_particle_log_weights`.

    Attributes
    ----------
    log_weights : (N, L) ndarray
        unnormalised log weights; each row is defined up to its own constant.
    components : list of (int, int)
        (targets, measurements) of every connected component that holds a
        measurement (see the module docstring).
    coefficient_seconds, derivative_seconds : float
        time spent building the coefficients (7) — with the column scaling
        and the components — and in the derivatives (core calls or saddle
        points).
    """

    log_weights: np.ndarray
    components: list
    coefficient_seconds: float
    derivative_seconds: float


def _components(touch: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Component labels of targets (N,) and measurements (M,) of the bipartite graph
    ``touch`` (N, M); a measurement no target touches gets label −1."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    N, M = touch.shape
    r, c = np.nonzero(touch)
    g = coo_matrix((np.ones(r.size), (r, N + c)), shape=(N + M, N + M))
    _, labels = connected_components(g, directed=False)
    tgt, meas = labels[:N], labels[N:].copy()
    meas[~touch.any(axis=0)] = -1
    return tgt, meas


def jpda_particle_log_weights(log_clutter, p_d, log_likelihood, method: str = "exact"):
    """Log weights of every particle of every target for one scan (eqs. 7, 14, 18).

    Parameters
    ----------
    log_clutter : (M,) array_like
        log(Λ p_Λ(y_m)), finite.
    p_d : (N, L) array_like
        P_D at each particle, in [0, 1].
    log_likelihood : (N, L, M) array_like
        log p(y_m | x) of each particle; −inf where the measurement is outside
        the particle's gate.
    method : {"exact", "saddle", "saddle-corrected"}
        ``"exact"``: :func:`jointtrack.saddle.jpda_log_weights` (one core call
        per target); otherwise :func:`jointtrack.saddle.log_mixed_derivative`
        with that method, batched over the target's L particles.

    Returns
    -------
    ScanWeights
        ``log_weights`` (N, L), each row up to a constant (the particles are
        taken as draws from μ_n: μ_n is not multiplied in).

    Raises
    ------
    ParticleDegeneracyError
        when every particle of a target has weight 0 (e.g. P_D = 1 and no
        measurement any of its particles can have made).
    """
    method = _check_weights_method(method)
    log_a = _as_real_array(log_clutter, "log_clutter")
    pd = _as_real_array(p_d, "p_d")
    loglik = _as_real_array(log_likelihood, "log_likelihood")
    if log_a.ndim != 1 or pd.ndim != 2 or loglik.ndim != 3:
        raise ValueError(
            "log_clutter must be (M,), p_d (N, L) and log_likelihood (N, L, M); got shapes "
            f"{log_a.shape}, {pd.shape}, {loglik.shape}"
        )
    N, L = pd.shape
    M = log_a.size
    if loglik.shape != (N, L, M):
        raise ValueError(f"log_likelihood must have shape {(N, L, M)}, got {loglik.shape}")
    if not np.isfinite(log_a).all():
        raise ValueError("log_clutter must be finite (every clutter term a_m > 0, Streit §4.2)")
    if not np.isfinite(pd).all() or ((pd < 0) | (pd > 1)).any():
        raise ValueError("p_d must lie in [0, 1]")
    if np.isnan(loglik).any() or (loglik == np.inf).any():
        raise ValueError("log_likelihood must be finite or −inf")
    if M == 0:
        # no β at all: I = e^{a0} b_n0(x) Π_j c_j0, and only b_n0 = 1 − P_D(x) varies
        with np.errstate(divide="ignore"):
            out = np.log1p(-pd)
        _check_alive(out)
        return ScanWeights(out, [], 0.0, 0.0)

    t0 = _time.perf_counter()
    # column scaling (exact, see the module docstring): every column's largest term is 1
    shift = np.maximum(log_a, loglik.max(axis=(0, 1), initial=-np.inf))
    a = np.maximum(np.exp(log_a - shift), np.finfo(float).tiny)
    lik = np.exp(loglik - shift)
    touch = (lik > 0).any(axis=1)
    tgt_label, meas_label = _components(touch)
    out = np.empty((N, L))
    components = []
    coef_s = deriv_s = 0.0
    for lab in np.unique(tgt_label):
        members = np.flatnonzero(tgt_label == lab)
        ms = np.flatnonzero(meas_label == lab)
        if ms.size == 0:
            with np.errstate(divide="ignore"):
                out[members] = np.log1p(-pd[members])
            continue
        components.append((int(members.size), int(ms.size)))
        lik_c = lik[members][:, :, ms]
        a_c = a[ms]
        for i, n in enumerate(members):
            others = [j for j in range(members.size) if j != i]
            t1 = _time.perf_counter()
            a0, aa, F = jpda_coefficients(
                a_c,
                pd[n],
                lik_c[i],
                [pd[members[j]] for j in others],
                [lik_c[j] for j in others],
            )
            t2 = _time.perf_counter()
            if method == "exact":
                out[n] = jpda_log_weights(a0, aa, F[:, 0, :], F[0, 1:, :])
            else:
                out[n] = log_mixed_derivative(a0, aa, F, method)
            t3 = _time.perf_counter()
            coef_s += t2 - t1
            deriv_s += t3 - t2
    if np.isnan(out).any():
        raise ValueError("a particle weight is NaN (the coefficients are not a JPDA problem)")
    _check_alive(out)
    # the components' bookkeeping counts as coefficient work (§7's overhead)
    coef_s = (_time.perf_counter() - t0) - deriv_s
    return ScanWeights(out, components, coef_s, deriv_s)


def _check_alive(log_w: np.ndarray) -> None:
    dead = ~np.isfinite(log_w).any(axis=1) if log_w.shape[1] else np.zeros(len(log_w), bool)
    if dead.any():
        n = int(np.flatnonzero(dead)[0])
        raise ParticleDegeneracyError(
            f"every particle of target {n} has weight 0: no particle can explain the scan "
            "(P_D = 1 with no measurement within reach of its particles?); the track is lost"
        )


# ----------------------------------------------------------------------------- resampling


def systematic_resample(weights, rng) -> np.ndarray:
    """Systematic resampling: indices of the particles kept, per row of ``weights``.

    Parameters
    ----------
    weights : (L,) or (N, L) array_like
        normalised weights (each row ≥ 0, summing to 1 up to rounding).
    rng : numpy.random.Generator
        one uniform draw per row.

    Returns
    -------
    (L,) or (N, L) int ndarray
        ancestor indices, sorted; particle i appears ⌊L w_i⌋ or ⌊L w_i⌋ + 1
        times and E[count_i] = L w_i (Kitagawa 1996; Douc, Cappé & Moulines 2005).
    """
    w = _as_real_array(weights, "weights")
    flat = w.ndim == 1
    w = np.atleast_2d(w)
    if w.ndim != 2 or w.shape[1] < 1:
        raise ValueError(f"weights must be (L,) or (N, L) with L ≥ 1, got shape {w.shape}")
    if not np.isfinite(w).all() or (w < 0).any():
        raise ValueError("weights must be finite and ≥ 0")
    s = w.sum(axis=1)
    if (np.abs(s - 1.0) > 1e-9).any():
        raise ValueError(f"every row of weights must sum to 1, got sums {s}")
    N, L = w.shape
    u = (rng.random(N)[:, None] + np.arange(L)) / L
    cum = np.cumsum(w, axis=1)
    cum[:, -1] = 1.0  # rounding must not leave the last pointer past the end
    idx = np.empty((N, L), np.int64)
    for n in range(N):
        idx[n] = np.searchsorted(cum[n], u[n], side="right")
    np.minimum(idx, L - 1, out=idx)
    return idx[0] if flat else idx


# ----------------------------------------------------------------------------- the tracker


@dataclass(frozen=True)
class ParticleScanResult:
    """What one call of :meth:`ParticleJPDATracker.step` did.

    ``ids`` (N,), ``x`` (N, n) and ``P`` (N, n, n): every target's weighted
    particle mean and covariance (before resampling); ``existence`` (N,) is
    1 (targets are known). ``particles`` (N, L, n) are the predicted particles
    and ``weights`` (N, L) their normalised weights, ``ess`` (N,) the effective
    sample size 1/Σw² before resampling. ``weight_seconds`` = coefficients +
    derivatives (:class:`ScanWeights`); ``components`` the (targets,
    measurements) of each component solved.
    """

    time: float
    ids: np.ndarray
    x: np.ndarray
    P: np.ndarray
    existence: np.ndarray
    n_measurements: int
    ess: np.ndarray
    particles: np.ndarray
    weights: np.ndarray
    coefficient_seconds: float
    derivative_seconds: float
    components: list = field(default_factory=list)

    @property
    def weight_seconds(self) -> float:
        return self.coefficient_seconds + self.derivative_seconds


def _noise_factor(Q: np.ndarray) -> np.ndarray:
    """G with G Gᵀ = Q (Cholesky; eigen-decomposition when Q is only semidefinite)."""
    try:
        return np.linalg.cholesky(Q)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(0.5 * (Q + Q.T))
        return V * np.sqrt(np.clip(w, 0.0, None))


class ParticleJPDATracker:
    """Particle JPDA tracker of a known, fixed set of targets (see the module docstring).

    Parameters
    ----------
    config : ParticleConfig, optional
    motion : optional
        any object with ``state_dim``, ``transition(dt)`` and ``noise(dt)``
        (default :class:`~jointtrack.models.ConstantVelocity` /
        :class:`~jointtrack.models.ConstantAcceleration` from ``config``).
    sensor : optional
        a linear position model with ``H`` (d, n) and ``R`` (d, d) (default
        :class:`~jointtrack.models.LinearPosition` from ``config``).
    p_d : float or callable, optional
        overrides ``config.p_d``; a callable maps states (..., n) to P_D
        values (...) in [0, 1].
    clutter : callable, optional
        maps measurements (M, d) to the clutter terms Λ p_Λ(y_m) > 0 (M,);
        default the constant ``config.clutter_density``.

    Examples
    --------
    >>> import numpy as np
    >>> cfg = ParticleConfig(particles=200, clutter_density=1e-4, seed=1)
    >>> trk = ParticleJPDATracker(cfg)
    >>> ids = trk.start([[0.0, 0.0, 10.0, 0.0], [0.0, 100.0, 10.0, 0.0]], 25.0 * np.eye(4))
    >>> for t in range(1, 4):
    ...     z = np.array([[10.0 * t, 0.0], [10.0 * t, 100.0]])
    ...     result = trk.step(float(t), z)     # estimates in result.ids / result.x / result.P
    >>> bool(np.all(np.abs(result.x[:, 0] - 30.0) < 15.0))
    True
    """

    def __init__(
        self,
        config: ParticleConfig | None = None,
        *,
        motion=None,
        sensor=None,
        p_d=None,
        clutter=None,
    ):
        c = self.config = config or ParticleConfig()
        if not isinstance(c, ParticleConfig):
            raise TypeError(f"config must be a ParticleConfig, got {type(c).__name__}")
        _check_weights_method(c.weights)
        self._motion = motion = motion_model(c, motion)
        n = int(motion.state_dim)
        if sensor is None:
            sensor = LinearPosition(c.dim, c.measurement_covariance(), state_dim=n)
        H = getattr(sensor, "H", None)
        if callable(H) or H is None or not hasattr(sensor, "R"):
            raise ValueError(
                "the particle tracker needs a linear-Gaussian sensor with an H matrix and R "
                f"(e.g. LinearPosition), got {type(sensor).__name__}"
            )
        self._H = np.asarray(H, dtype=float)
        R = np.asarray(sensor.R, dtype=float)
        d = self._H.shape[0]
        if self._H.shape != (d, n) or R.shape != (d, d):
            raise ValueError(
                f"sensor H must be (d, {n}) and R (d, d), got {self._H.shape}, {R.shape}"
            )
        Lr = np.linalg.cholesky(R)
        self._whiten = np.linalg.inv(Lr)  # ‖W (y − Hx)‖² is the Mahalanobis distance
        self._log_norm = -0.5 * d * math.log(2 * math.pi) - float(np.log(np.diag(Lr)).sum())
        self._gamma = math.inf if c.p_g >= 1 else gate_threshold(c.p_g, d)
        self._mdim = d
        if p_d is None:
            p_d = c.p_d
        if not callable(p_d):
            p_d = check_field("p_d", p_d)
        self._p_d = p_d
        if clutter is None:
            if c.clutter_density is None:
                raise ValueError(
                    "the particle tracker needs the clutter intensity: set "
                    "ParticleConfig.clutter_density (λ > 0 per unit volume) or pass clutter="
                )
        elif not callable(clutter):
            raise ValueError("clutter must be a function of the measurements (M, d) → (M,)")
        self._clutter = clutter
        self.rng = np.random.default_rng(c.seed)
        self.time: float | None = None
        self.n_scans = 0
        self.ids = np.zeros(0, np.int64)
        self.particles = np.zeros((0, c.particles, n))

    @property
    def state_dim(self) -> int:
        """Length of a target state (from the motion model)."""
        return int(self._motion.state_dim)

    # ------------------------------------------------------------------ start
    def start(self, x0, P0, *, ids=None, time: float | None = None) -> np.ndarray:
        """Draw every target's L particles from N(x0, P0); returns the target ids.

        ``x0`` (N, n) states, ``P0`` (N, n, n) or (n, n) symmetric positive
        definite covariances, ``ids`` (default 1…N), ``time``: the time of x0
        (default None: the first scan's time, with no prediction before it).
        Replaces any targets the tracker had; uses the tracker's generator.
        """
        n, L = self.state_dim, self.config.particles
        x0 = np.atleast_2d(_as_real_array(x0, "x0"))
        if x0.ndim != 2 or x0.shape[1] != n or x0.shape[0] < 1:
            raise ValueError(f"x0 must have shape (N, {n}) with N ≥ 1, got {x0.shape}")
        N = x0.shape[0]
        P0 = _as_real_array(P0, "P0")
        if P0.shape not in ((n, n), (N, n, n)):
            raise ValueError(f"P0 must have shape ({n}, {n}) or ({N}, {n}, {n}), got {P0.shape}")
        P0 = np.broadcast_to(P0, (N, n, n))
        if not (np.isfinite(x0).all() and np.isfinite(P0).all()):
            raise ValueError("x0 and P0 must be finite")
        if not np.allclose(P0, P0.transpose(0, 2, 1), rtol=1e-10, atol=0.0):
            raise ValueError("every P0 must be symmetric")
        try:
            G = np.linalg.cholesky(P0)
        except np.linalg.LinAlgError:
            raise ValueError("every P0 must be symmetric positive definite") from None
        if ids is None:
            ids = np.arange(1, N + 1, dtype=np.int64)
        else:
            ids = np.asarray(ids)
            if ids.shape != (N,) or ids.dtype.kind not in "iu" or np.unique(ids).size != N:
                raise ValueError(f"ids must be {N} distinct integers")
            ids = ids.astype(np.int64)
        if time is not None:
            time = float(time)
            if not math.isfinite(time):
                raise ValueError(f"time must be finite, got {time}")
        rng = copy.deepcopy(self.rng)
        eps = rng.standard_normal((N, L, n))
        particles = x0[:, None, :] + np.einsum("nij,nlj->nli", G, eps)
        self.particles, self.ids, self.time, self.rng = particles, ids, time, rng
        self.n_scans = 0
        return ids.copy()

    # ------------------------------------------------------------------ scan
    def step(self, t, z) -> ParticleScanResult:
        """Process the measurements ``z`` (M, d) taken at time ``t`` (seconds).

        Atomic: if anything raises (bad input, a failing P_D or clutter
        function, a degenerate particle set, an interrupt), the tracker is
        left exactly as it was — particles, time, scan counter and random
        generator — and the same scan can be retried.
        """
        t = as_float(t, "scan time")
        z = _as_real_array(z, "measurements")
        d = self._mdim
        if z.size == 0:
            z = z.reshape(0, d)
        if z.ndim != 2 or z.shape[1] != d:
            raise ValueError(f"measurements must have shape (M, {d}), got {z.shape}")
        if not np.isfinite(z).all():
            raise ValueError(f"scan at t={t} has a non-finite measurement")
        if not len(self.ids):
            raise ValueError("the tracker has no targets: call start(x0, P0) first")
        if self.time is not None and not t > self.time:
            raise ValueError(f"scan times must increase: got t={t} after t={self.time}")

        rng = copy.deepcopy(self.rng)  # the state's generator advances only on success
        X = self.particles
        if self.time is not None:
            dt = t - self.time
            F = self._motion.transition(dt)
            G = _noise_factor(np.asarray(self._motion.noise(dt), dtype=float))
            X = X @ F.T + rng.standard_normal(X.shape) @ G.T
        pd = self._detection(X)
        log_lik = self._log_likelihood(X, z)
        log_a = self._log_clutter(z)
        sw = jpda_particle_log_weights(log_a, pd, log_lik, self.config.weights)
        w = np.exp(sw.log_weights - logsumexp(sw.log_weights, axis=1, keepdims=True))
        x_hat = np.einsum("nl,nli->ni", w, X)
        dev = X - x_hat[:, None, :]
        P = np.einsum("nl,nli,nlj->nij", w, dev, dev)
        P = 0.5 * (P + P.transpose(0, 2, 1))
        ess = 1.0 / (w**2).sum(axis=1)
        idx = systematic_resample(w, rng)
        resampled = np.take_along_axis(X, idx[:, :, None], axis=1)
        result = ParticleScanResult(
            time=t,
            ids=self.ids.copy(),
            x=x_hat,
            P=P,
            existence=np.ones(len(self.ids)),
            n_measurements=int(len(z)),
            ess=ess,
            particles=X,
            weights=w,
            coefficient_seconds=sw.coefficient_seconds,
            derivative_seconds=sw.derivative_seconds,
            components=sw.components,
        )
        # commit: plain assignments, nothing here can fail
        self.particles, self.time, self.rng = resampled, t, rng
        self.n_scans += 1
        return result

    def _detection(self, X: np.ndarray) -> np.ndarray:
        if not callable(self._p_d):
            return np.full(X.shape[:2], float(self._p_d))
        pd = _as_real_array(self._p_d(X), "p_d(x)")
        if pd.shape != X.shape[:2]:
            try:
                pd = np.broadcast_to(pd, X.shape[:2])
            except ValueError:
                raise ValueError(
                    f"p_d(x) must return one value per particle, shape {X.shape[:2]}, "
                    f"got {pd.shape}"
                ) from None
        if not np.isfinite(pd).all() or ((pd < 0) | (pd > 1)).any():
            raise ValueError("p_d(x) must return values in [0, 1]")
        return pd

    def _log_likelihood(self, X: np.ndarray, z: np.ndarray) -> np.ndarray:
        """log N(y_m; H x, R) per particle (N, L, M); −inf outside a particle's gate."""
        pos = X @ self._H.T  # (N, L, d)
        diff = z[None, None, :, :] - pos[:, :, None, :]  # (N, L, M, d)
        d2 = ((diff @ self._whiten.T) ** 2).sum(axis=-1)
        out = self._log_norm - 0.5 * d2
        if math.isfinite(self._gamma):
            out[d2 > self._gamma] = -np.inf
        return out

    def _log_clutter(self, z: np.ndarray) -> np.ndarray:
        if self._clutter is None:
            return np.full(len(z), math.log(self.config.clutter_density))
        a = _as_real_array(self._clutter(z), "clutter(z)")
        if a.shape != (len(z),):
            raise ValueError(f"clutter(z) must return {len(z)} values, got shape {a.shape}")
        if not np.isfinite(a).all() or (a <= 0).any():
            raise ValueError(
                "clutter(z) must return finite values > 0 (every measurement needs a clutter "
                "term, Streit §4.2)"
            )
        return np.log(a)

    # ------------------------------------------------------------------ state
    def state_dict(self) -> dict:
        """Copies of everything a step reads and changes (particles, ids, time, counter, RNG)."""
        return {
            "particles": self.particles.copy(),
            "ids": self.ids.copy(),
            "time": self.time,
            "n_scans": self.n_scans,
            "rng": copy.deepcopy(self.rng.bit_generator.state),
            "config": self.config.to_dict(),
        }

    def estimates(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(ids, x, P)`` of the current (equally weighted, resampled) particle sets."""
        x = self.particles.mean(axis=1)
        dev = self.particles - x[:, None, :]
        P = np.einsum("nli,nlj->nij", dev, dev) / self.particles.shape[1]
        return self.ids.copy(), x, P
