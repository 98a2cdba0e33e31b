r"""Likelihood I of a superpositional measurement (2)–(3) and the update ratio R(x) (16)–(20).

S. Nannuru and M. Coates, "Gaussian approximation for superpositional sensors",
technical report, McGill University, 2015 (equation numbers below are that
report's); S. Nannuru, M. Coates and R. Mahler, "Computationally-tractable
approximate PHD and CPHD filters for superpositional sensors", IEEE J. Sel.
Topics Signal Process. 7(3):410-420, 2013.

.. math::

    I = \int \mathcal N_{\Sigma_0}(y_0 - \zeta(W)) f_\Xi(W)\,\delta W
      = \int \mathcal N_{\Sigma_0}(y_0 - y) Q(y)\,dy, \qquad
    R(x) = \frac{\int \mathcal N_{\Sigma_0}(y_0 - g(x) - y^*) Q^{*x}(y^*)\,dy^*}{I}.

Methods (one dispatcher, validation done once here):

``"gaussian"``
    Q replaced by the Gaussian with Campbell moments: I₁ = N_{Σ0+Σ_Q}(y0 − μ_Q) (9)
    and R₁ of (20). Option ``moment_particles`` (int) with ``rng``: the moments
    from that many sampled particles per spatial density (the report's N_v
    estimator) instead of the closed form.
``"exact"``
    Gaussian-mixture enumeration (linear g, Gaussian components): 2ⁿ subsets
    of a multi-Bernoulli set, the multinomial compositions of every cardinality
    of an IIDC mixture, products for a union. ``max_terms`` (default 2²⁰) bounds
    the mixture size; beyond it :class:`jointtrack.errors.ExactLimitError`.
``"montecarlo"``
    Seeded sample average over y = ζ(Ξ) (``n_samples``, ``rng``); reports the
    standard error of log I (delta method).
``"saddlepoint"``, ``"hybrid"``
    From :mod:`jointtrack.superpositional.saddlepoint` and
    :mod:`jointtrack.superpositional.hybrid` (imported when asked for; a
    missing module raises NotImplementedError).

Examples
--------
>>> import numpy as np
>>> from jointtrack.superpositional import MultiBernoulli, likelihood
>>> mb = MultiBernoulli([0.5], [[0.0]], [[[1.0]]])
>>> res = likelihood([0.0], mb, [[1.0]], [[1.0]], method="exact")
>>> # 0.5 N(0; 0, 1) + 0.5 N(0; 0, 2)
>>> bool(np.isclose(np.exp(res.log_value), 0.5 / np.sqrt(2 * np.pi) + 0.5 / np.sqrt(4 * np.pi)))
True
"""

from __future__ import annotations

import functools
import importlib
import inspect
import math
from dataclasses import dataclass, field

import numpy as np

from jointtrack.assignment._checks import _as_real_array, as_int
from jointtrack.superpositional.measurement import as_measurement
from jointtrack.superpositional.models import IIDC, Poisson, Union, check_covariance, check_model
from jointtrack.superpositional.moments import _reduced, campbell_moments, check_states

__all__ = ["METHODS", "LikelihoodResult", "likelihood", "log_likelihood_ratio"]

#: every method name the dispatcher knows, and the module implementing it
METHODS = {
    "gaussian": None,
    "exact": "jointtrack.superpositional._exact",
    "montecarlo": "jointtrack.superpositional._montecarlo",
    "saddlepoint": "jointtrack.superpositional.saddlepoint",
    "hybrid": "jointtrack.superpositional.hybrid",
}
_LOG_2PI = math.log(2.0 * math.pi)


@dataclass(frozen=True)
class LikelihoodResult:
    """One likelihood value I of (2)–(3), in log space.

    Attributes
    ----------
    log_value : float
        log I (finite, or −inf when I underflows below the smallest float even in log space).
    method : str
    std_error : float or None
        Standard error of ``log_value`` (Monte Carlo only).
    info : dict
        Method details (mixture size, samples, truncation mass, …).
    """

    log_value: float
    method: str
    std_error: float | None = None
    info: dict = field(default_factory=dict)

    @property
    def value(self) -> float:
        """I itself (may underflow to 0.0; prefer ``log_value``)."""
        return math.exp(self.log_value) if self.log_value < 709.0 else math.inf


def check_method(method) -> str:
    """``method`` if it is a known method name, else ValueError listing them."""
    if not isinstance(method, str) or method not in METHODS:
        raise ValueError(f"method must be one of {sorted(METHODS)}, got {method!r}")
    return method


def _method_module(method: str):
    try:
        return importlib.import_module(METHODS[method])
    except ModuleNotFoundError as exc:
        raise NotImplementedError(f"method {method!r} is not available ({exc})") from None


@functools.cache
def _option_names(fn) -> frozenset | None:
    """Keyword options ``fn`` accepts (None: it takes ``**options``)."""
    params = inspect.signature(fn).parameters.values()
    if any(p.kind is p.VAR_KEYWORD for p in params):
        return None
    return frozenset(p.name for p in params if p.kind is p.KEYWORD_ONLY)


def _call(method: str, name: str, *args, **options):
    fn = getattr(_method_module(method), name)
    known = _option_names(fn)
    if known is not None and not set(options) <= known:
        raise ValueError(
            f"unknown option(s) for method {method!r}: {sorted(set(options) - known)}; "
            f"it accepts {sorted(known)}"
        )
    return fn(*args, **options)


def check_vector(y, d: int, name: str = "y0") -> np.ndarray:
    """A finite real vector of length d."""
    arr = _as_real_array(y, name)
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.shape != (d,):
        raise ValueError(f"{name} must have shape ({d},), got {arr.shape} (dimension mismatch)")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} has a non-finite entry (NaN or inf)")
    return np.array(arr, dtype=np.float64)


def _validate(y0, model, H, noise_cov):
    check_model(model)
    m = as_measurement(H, model.dx)
    y0 = check_vector(y0, m.dy, "y0")
    noise_cov, _ = check_covariance(noise_cov, "noise_cov", m.dy)
    return y0, model, m, noise_cov


def log_gauss(d: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """log N(d; 0, cov) for rows d (L, dy) and one (dy, dy) or per-row (L, dy, dy) covariances.

    ValueError (not numpy's LinAlgError) when a covariance is not positive definite.
    """
    try:
        chol = np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        raise ValueError(
            "a Gaussian covariance (Σ0 + Σ_Q) is not positive definite in float"
        ) from None
    if chol.ndim == 2:
        z = d @ np.linalg.inv(chol).T
        logdet = 2.0 * np.log(np.diag(chol)).sum()
    else:
        z = np.linalg.solve(chol, d[..., None])[..., 0]
        logdet = 2.0 * np.log(np.diagonal(chol, axis1=-2, axis2=-1)).sum(-1)
    return -0.5 * ((z**2).sum(-1) + logdet + d.shape[-1] * _LOG_2PI)


def log_gauss_one(d: np.ndarray, cov: np.ndarray) -> float:
    """log N(d; 0, cov) for one vector d (dy,)."""
    return float(log_gauss(np.asarray(d, dtype=float)[None], cov)[0])


def _gaussian_model(model, options):
    """The model the Gaussian method takes its moments from (the N_v estimator: particles)."""
    from jointtrack.assignment._checks import as_rng

    n = options.pop("moment_particles", None)
    rng = options.pop("rng", None)
    if options:
        raise ValueError(f"unknown option(s) for method 'gaussian': {sorted(options)}")
    if n is None:
        return model
    return model.to_particles(as_int(n, "moment_particles", minimum=1), as_rng(rng))


def likelihood(y0, model, H, noise_cov, method: str = "gaussian", **options) -> LikelihoodResult:
    r"""log I of (2)–(3): the density of the reading y0 = ζ(Ξ) + noise, noise ~ N(0, Σ0).

    Parameters
    ----------
    y0 : array_like, shape (dy,)
    model : MultiBernoulli, IIDC, Poisson or Union
    H : array_like (dy, dx) or LinearMeasurement or FunctionMeasurement
        The measurement function g (g(x) = Hx for a matrix).
    noise_cov : array_like, shape (dy, dy)
        Σ0, positive definite.
    method : {"gaussian", "exact", "montecarlo", "saddlepoint", "hybrid"}
    **options
        Passed to the method (module docstring).

    Returns
    -------
    LikelihoodResult
    """
    method = check_method(method)
    y0, model, m, noise_cov = _validate(y0, model, H, noise_cov)
    if method == "gaussian":
        src = _gaussian_model(model, dict(options))
        mean, cov = campbell_moments(src, m)
        log_value = float(log_gauss((y0 - mean)[None], noise_cov + cov)[0])
        info = {"mean": mean, "cov": cov}
        return LikelihoodResult(log_value, method, None, info)
    log_value, info = _call(method, "log_likelihood", y0, model, m, noise_cov, **options)
    info = dict(info)
    std_error = info.pop("std_error", None)
    log_value = float(log_value)
    if math.isnan(log_value):
        raise ValueError(f"method {method!r} produced NaN for log I")
    return LikelihoodResult(log_value, method, std_error, info)


def _reduction_is_x_independent(model, part) -> bool:
    """True when the reduced moments (17) do not depend on x: Poisson, IIDC, or such a part."""
    if isinstance(model, Poisson | IIDC):
        return True
    return (
        isinstance(model, Union)
        and part is not None
        and isinstance(model.parts[part], Poisson | IIDC)
    )


def log_likelihood_ratio(
    y0, x, model, H, noise_cov, method: str = "gaussian", **options
) -> np.ndarray:
    r"""log R(x) of (16) (by ``"gaussian"``: log R₁ of (20)) for states x (L, dx).

    Parameters
    ----------
    y0 : array_like, shape (dy,)
    x : array_like, shape (L, dx)
    model : MultiBernoulli, IIDC, Poisson or Union
    H : array_like (dy, dx) or measurement object
    noise_cov : array_like, shape (dy, dy)
    method : str
    **options
        Passed to the method; ``part`` (int) reduces only that part of a Union
        (the report's A in (17)).

    Returns
    -------
    ndarray, shape (L,)

    Examples
    --------
    >>> import numpy as np
    >>> from jointtrack.superpositional import Poisson
    >>> ppp = Poisson(2.0, [1.0], [[0.0]], [[[1.0]]])
    >>> lr = log_likelihood_ratio([1.0], [[1.0]], ppp, [[1.0]], [[0.5]])
    >>> lr.shape
    (1,)
    """
    method = check_method(method)
    y0, model, m, noise_cov = _validate(y0, model, H, noise_cov)
    x = check_states(x, model.dx)
    part = options.get("part")
    if part is not None:
        if not hasattr(model, "parts"):
            raise ValueError("part is only meaningful for a Union model")
        # checked here for every method (the Gaussian path indexed with it unchecked:
        # part=True, −1 accepted, 5 an IndexError)
        part = options["part"] = as_int(part, "part", 0, len(model.parts) - 1)
    if method == "gaussian":
        opts = dict(options)
        opts.pop("part", None)
        src = _gaussian_model(model, opts)
        mean, cov = campbell_moments(src, m)
        den = log_gauss((y0 - mean)[None], noise_cov + cov)[0]
        rmean, rcov = _reduced(src, m, x, part, model, total=(mean, cov))
        if _reduction_is_x_independent(model, part):
            # one covariance for every x (Poisson / IIDC): one Cholesky instead of L
            num = log_gauss(y0[None] - m(x) - rmean, noise_cov + rcov[0])
        else:
            num = log_gauss(y0[None] - m(x) - rmean, noise_cov[None] + rcov)
        out = num - den
    else:
        out = _call(method, "log_likelihood_ratio", y0, x, model, m, noise_cov, **options)
    out = np.asarray(out, dtype=np.float64)
    if np.isnan(out).any():
        raise ValueError(f"method {method!r} produced NaN in log R(x)")
    return out
