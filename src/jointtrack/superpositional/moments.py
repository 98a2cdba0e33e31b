r"""Campbell moments of the superposed measurement y = Σ_{x ∈ Ξ} g(x) and of its reduced version.

S. Nannuru and M. Coates, "Gaussian approximation for superpositional sensors",
technical report, McGill University, 2015 (equation numbers below are that
report's); S. Nannuru, M. Coates and R. Mahler, "Computationally-tractable
approximate PHD and CPHD filters for superpositional sensors", IEEE J. Sel.
Topics Signal Process. 7(3):410-420, 2013.

Campbell's theorem (4)–(7)
--------------------------
.. math::

    \mu_Q = \int g(x) D(x)\,dx, \qquad
    \Sigma_Q = \int g g^T D\,dx + \iint g(x_1) g(x_2)^T \tilde D(\{x_1, x_2\})\,dx_1 dx_2,
    \qquad \tilde D = D_2 - D \otimes D.

With m₁ = E_p[g], m₂ = E_p[g gᵀ] under a single-target density p:

* IIDC (π, s): D = n̄ s, D₂ = G₂ s ⊗ s, so μ_Q = n̄ m₁ and
  Σ_Q = n̄ m₂ + (G₂ − n̄²) m₁ m₁ᵀ (G₂ = E[n(n − 1)]).
* Poisson: G₂ = n̄², Σ_Q = n̄ m₂.
* Multi-Bernoulli {(r_i, p_i)}: D = Σ r_i p_i, D₂ = Σ_{i≠j} r_i r_j p_i ⊗ p_j, so
  μ_Q = Σ r_i m₁ᵢ and Σ_Q = Σ_i (r_i m₂ᵢ − r_i² m₁ᵢ m₁ᵢᵀ).
* Union of independent parts: D and D̃ add (cross terms of D₂ cancel with
  D ⊗ D), so μ_Q and Σ_Q add.

m₁, m₂ are closed form for a linear g and Gaussian (or uniform) densities,
weighted sums for particle densities, and a deterministic product quadrature
(Gauss–Hermite for Gaussians, Gauss–Legendre for boxes) for a general g.

The reduced density (17) and its moments
----------------------------------------
For one RFS Ξ (B empty in (17)) the reduced density at x is the Palm density
f^{*x}(W) = f({x} ∪ W)/D(x): the law of Ξ \ {x} given a point at x.

* Poisson: f({x} ∪ W) = e^{−λ} λ s(x) Π λ s(w) = D(x) f(W), so f^{*x} = f.
* IIDC: for |W| = n, f({x} ∪ W) = (n + 1)! π(n + 1) s(x) Π s(w) and
  D(x) = n̄ s(x), hence f^{*x}(W) = n! π*(n) Π s(w) with
  π*(n) = (n + 1) π(n + 1)/n̄: again IIDC, same s, independent of x. Its
  n̄* = G₂/n̄ and G₂* = E[n(n − 1)(n − 2)]/n̄.
* Multi-Bernoulli: in f({x} ∪ W) the point x is produced by exactly one
  component i, the points W by the others, so
  f({x} ∪ W) = Σ_i r_i p_i(x) f_{−i}(W) with f_{−i} the multi-Bernoulli set
  without component i. Dividing by D(x) = Σ r_i p_i(x):
  f^{*x} = Σ_i w_i(x) f_{−i}, w_i(x) = r_i p_i(x)/D(x), a mixture of the
  leave-one-out sets. A mixture's moments are
  μ* = Σ w_i μ_{−i}, Σ* = Σ w_i (Σ_{−i} + μ_{−i} μ_{−i}ᵀ) − μ* μ*ᵀ with
  μ_{−i} = μ_Q − r_i m₁ᵢ and Σ_{−i} = Σ_Q − r_i m₂ᵢ + r_i² m₁ᵢ m₁ᵢᵀ.
* Union A ∪ B: f({x} ∪ W) = Σ_{Y ⊆ W} [f_A({x} ∪ Y) f_B(W − Y) +
  f_A(Y) f_B({x} ∪ W − Y)], so f^{*x} = (D_A/D) (A^{*x} ∪ B) + (D_B/D) (A ∪ B^{*x}):
  reduce the part x came from, weighted by D_part(x)/D(x), and add the other
  parts' moments. The report's (17) reduces only part A (x known to come from
  A): ``part=`` selects that.

The Gaussian approximation of (18)–(20) uses a single Gaussian with the
mixture's moments (μ*, Σ*).
"""

from __future__ import annotations

import numpy as np

from jointtrack.assignment._checks import _as_real_array
from jointtrack.superpositional.measurement import as_measurement
from jointtrack.superpositional.models import (
    IIDC,
    MultiBernoulli,
    Poisson,
    Union,
    _normalise_rows,
    check_model,
    reduced_mixture,
)

__all__ = ["campbell_moments", "leave_one_out_moments", "reduced_moments"]


def _moments(model, m) -> tuple[np.ndarray, np.ndarray]:
    if isinstance(model, MultiBernoulli):
        if model.n_components == 0:
            return np.zeros(m.dy), np.zeros((m.dy, m.dy))
        m1, C = _mb_component_moments(model, m)
        r = model.r
        mean = r @ m1
        own = _own_cov(r, m1, C)
        return mean, _sym(own.sum(axis=0))
    if isinstance(model, IIDC | Poisson):
        m1, m2 = model.spatial.g_moments(m)
        nbar, g2 = model.mean_cardinality, model.second_factorial_moment
        return nbar * m1, _sym(nbar * m2 + (g2 - nbar * nbar) * np.outer(m1, m1))
    mean = np.zeros(m.dy)
    cov = np.zeros((m.dy, m.dy))
    for p in model.parts:
        a, b = _moments(p, m)
        mean, cov = mean + a, cov + b
    return mean, cov


def _mb_component_moments(model, m):
    """``(m1 (n, dy), C (n, dy, dy))``: E[g] and Cov[g] under each component's density.

    The covariance, not E[g gᵀ]: with a mean of 1e155 E[g gᵀ] overflows, while a
    component's contribution r(1 − r) m mᵀ is finite when r is small (1e-300).
    """
    if model.means is not None and hasattr(m, "H"):
        H = m.H
        return model.means @ H.T, H @ model.covs @ H.T
    pairs = [c.g_moments(m) for c in model.components]
    m1 = np.array([p[0] for p in pairs])
    return m1, np.array([p[1] for p in pairs]) - m1[:, :, None] * m1[:, None, :]


def _own_cov(r, m1, C):
    """Each component's share r C + r(1 − r) m mᵀ of Σ_Q, the outer product of
    √(r(1 − r)) m with itself so that it overflows only when the share does."""
    v = np.sqrt(r * (1.0 - r))[:, None] * m1
    return r[:, None, None] * C + v[:, :, None] * v[:, None, :]


def _sym(c: np.ndarray) -> np.ndarray:
    return 0.5 * (c + np.swapaxes(c, -1, -2))


def campbell_moments(model, measurement) -> tuple[np.ndarray, np.ndarray]:
    r"""Mean and covariance of y = Σ_{x ∈ Ξ} g(x) from Campbell's theorem (4)–(7).

    Parameters
    ----------
    model : MultiBernoulli, IIDC, Poisson or Union
    measurement : array_like (dy, dx) or LinearMeasurement or FunctionMeasurement

    Returns
    -------
    mean : ndarray, shape (dy,)
    cov : ndarray, shape (dy, dy)

    Examples
    --------
    >>> import numpy as np
    >>> from jointtrack.superpositional import MultiBernoulli
    >>> mb = MultiBernoulli([0.5], [[2.0, 0.0]], [np.eye(2)])
    >>> mean, cov = campbell_moments(mb, [[1.0, 0.0]])
    >>> mean.tolist(), cov.tolist()   # r m, r (1 + m²) − r² m²
    ([1.0], [[1.5]])
    """
    check_model(model)
    return _moments(model, as_measurement(measurement, model.dx))


def leave_one_out_moments(model, measurement) -> tuple[np.ndarray, np.ndarray]:
    r"""Campbell moments of each leave-one-out multi-Bernoulli set MB₋ᵢ.

    μ₋ᵢ = μ_Q − r_i m₁ᵢ and Σ₋ᵢ = Σ_Q − r_i m₂ᵢ + r_i² m₁ᵢ m₁ᵢᵀ (module docstring).

    Parameters
    ----------
    model : MultiBernoulli
    measurement : array_like (dy, dx) or measurement object

    Returns
    -------
    mean : ndarray, shape (n, dy)
    cov : ndarray, shape (n, dy, dy)
    """
    if not isinstance(model, MultiBernoulli):
        raise ValueError(f"model must be a MultiBernoulli, got {type(model).__name__}")
    m = as_measurement(measurement, model.dx)
    n = model.n_components
    if n == 0:
        return np.zeros((0, m.dy)), np.zeros((0, m.dy, m.dy))
    m1, C = _mb_component_moments(model, m)
    r = model.r
    mean_all = r @ m1
    own_cov = _own_cov(r, m1, C)
    cov_all = own_cov.sum(axis=0)
    return mean_all[None] - r[:, None] * m1, _sym(cov_all[None] - own_cov)


def check_states(x, dx: int, name: str = "x") -> np.ndarray:
    """States as a float (L, dx) array (a single (dx,) state becomes (1, dx))."""
    arr = _as_real_array(x, name)
    if arr.ndim == 1:
        arr = arr[None]
    if arr.ndim != 2 or arr.shape[1] != dx:
        raise ValueError(f"{name} must have shape (L, {dx}), got {arr.shape} (dimension mismatch)")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} has a non-finite entry (NaN or inf)")
    return np.ascontiguousarray(arr)


def reduced_moments(model, measurement, x, part: int | None = None):
    r"""Moments (μ*, Σ*) of Q^{A*_x} of (17)–(18) for each state x.

    Parameters
    ----------
    model : MultiBernoulli, IIDC, Poisson or Union
    measurement : array_like (dy, dx) or measurement object
    x : array_like, shape (L, dx)
    part : int, optional
        For a Union, reduce only this part (the report's A in (17)); default:
        the full reduced density, each part weighted by D_part(x)/D(x).

    Returns
    -------
    mean : ndarray, shape (L, dy)
    cov : ndarray, shape (L, dy, dy)

    Notes
    -----
    Derivation in the module docstring. For IIDC and Poisson models the result
    does not depend on x. A multi-Bernoulli set (or a union containing one)
    needs a pointwise density p_i(x) (Gaussian components); with particle
    components use :func:`leave_one_out_moments`.

    Examples
    --------
    >>> import numpy as np
    >>> from jointtrack.superpositional import MultiBernoulli
    >>> mb = MultiBernoulli([0.5, 1.0], [[0.0], [9.0]], [[[1.0]], [[1.0]]])
    >>> mean, cov = reduced_moments(mb, [[1.0]], [[9.0]])  # x is component 2's: only 1 is left
    >>> round(float(mean[0, 0]), 6), round(float(cov[0, 0, 0]), 6)
    (0.0, 0.5)
    """
    check_model(model)
    m = as_measurement(measurement, model.dx)
    x = check_states(x, model.dx)
    if part is not None and not isinstance(model, Union):
        raise ValueError("part is only meaningful for a Union model")
    mean, cov = _reduced(model, m, x, part)
    return np.array(mean), np.array(cov)  # writeable copies of possibly broadcast views


def _reduced(model, m, x, part=None, weight_model=None, total=None):
    """Reduced moments; ``weight_model`` (same structure) supplies the densities p_i(x), D_k(x).

    The Gaussian method's particle-moment option computes moments from a
    particle version of the model but keeps the Gaussian densities for the
    mixture weights, which a particle set cannot evaluate pointwise. ``total``
    (the model's Campbell moments, when the caller has them) saves evaluating g
    again for a Poisson model. x-independent results are read-only broadcast
    views: (L, dy, dy) copies of one matrix would cost more than the rest.
    """
    wm = model if weight_model is None else weight_model
    L = x.shape[0]
    if isinstance(model, MultiBernoulli) and model.n_components > 0:
        lw, _ = reduced_mixture(wm, x)
        means, covs = leave_one_out_moments(model, m)
        return _mix(np.exp(lw), means, covs)
    if isinstance(model, Poisson | IIDC | MultiBernoulli):
        # x-independent: Poisson is its own reduction, IIDC reduces to π*, an empty MB to itself
        if isinstance(model, IIDC):
            mean, cov = _moments(model.reduced(), m)
        else:
            mean, cov = total if total is not None else _moments(model, m)
        return np.broadcast_to(mean, (L, m.dy)), np.broadcast_to(cov, (L, m.dy, m.dy))
    parts = model.parts
    part_moments = [_moments(p, m) for p in parts]
    tot_mean = sum(pm[0] for pm in part_moments)
    tot_cov = sum(pm[1] for pm in part_moments)
    chosen = range(len(parts)) if part is None else [part]
    means = np.empty((len(chosen), L, m.dy))
    covs = np.empty((len(chosen), L, m.dy, m.dy))
    for j, k in enumerate(chosen):
        rm, rc = _reduced(parts[k], m, x, None, wm.parts[k])
        means[j] = rm + (tot_mean - part_moments[k][0])
        covs[j] = rc + (tot_cov - part_moments[k][1])
    if part is not None:
        return means[0], covs[0]
    # a mixture over the parts with weights D_k(x)/D(x), per state
    w = np.exp(_normalise_rows(np.stack([p.log_phd(x) for p in wm.parts], axis=1)))
    mean = np.einsum("lk,kld->ld", w, means)
    second = np.einsum("lk,klde->lde", w, covs + means[..., :, None] * means[..., None, :])
    return mean, _sym(second - mean[:, :, None] * mean[:, None, :])


def _mix(w: np.ndarray, means: np.ndarray, covs: np.ndarray):
    """Moments of the mixture Σ_i w[l, i] N(means[i], covs[i]) for each row l of w."""
    mean = w @ means
    second = np.einsum("li,ide->lde", w, covs + means[:, :, None] * means[:, None, :])
    return mean, _sym(second - mean[:, :, None] * mean[:, None, :])
