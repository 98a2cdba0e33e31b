r"""Mixed derivatives of the JPDA generating function: exact on the core, or by the saddle point.

R. L. Streit, "Saddle point method for JPDA and related filters", *Proc. 18th
International Conference on Information Fusion* (FUSION), 2015 — eqs. (14),
(18)–(31). The function Ψ and its coefficients are described in
:mod:`jointtrack.saddle.generating`.

Exact (``method="exact"``)
--------------------------
I = ∂^M Ψ/∂β_1…∂β_M (0) is an assignment sum: rows are the K factors (null
weight f_k0: the factor takes no measurement), columns the M measurements
(a measurement no factor takes is clutter, weight a_m). Dividing column m by
a_m makes an unused column weigh 1, the convention of the assignment-sum core
(:func:`jointtrack.assignment.core.solve_checked`), so

    log I = a_0 + Σ_m log a_m + log Z(W = f_km / a_m, null = f_k0).

Rows are scaled in log space first (a row's scale multiplies every term
once), so coefficients anywhere in the float range are fine.

Saddle point (``method="saddle"``, eqs. 24, 30, 31)
----------------------------------------------------
In u = log r the saddle point minimises the convex function
φ(u) = log Ψ(e^u) − Σ u_m. Its gradient and Hessian have a probabilistic
reading that also gives them cheaply: with s_k = f_k0 + Σ_m f_km e^{u_m},
p_km = f_km e^{u_m}/s_k and λ_m = a_m e^{u_m},

    ∇φ = λ + Σ_k p_k − 1,       ∇²φ = diag(λ) + Σ_k (diag(p_k) − p_k p_kᵀ),

the mean minus one and the covariance of X = Σ_k (one-hot draw of factor k's
measurement, none with probability p_k0) + Poisson(λ) per measurement: Ψ(e^u
β)/Ψ(e^u) is that vector's generating function. So I = Ψ(r̂)/Π r̂ · P(X = 1)
exactly, the saddle point makes 1 the mean of X, and eq. (30) is the Gaussian
density of X at its mean:

    log I ≈ φ(û) − (M/2) log 2π − ½ log det ∇²φ(û).

Newton's method with backtracking on φ runs batched over particles (one numpy
pass per iteration for all L problems), from u = 0, to ‖∇φ‖∞ ≤ 1e-12;
convergence is reported per problem and a problem that has not converged in
``max_iter`` steps raises :class:`SaddlePointError` (or is flagged, with
``raise_on_failure=False``). a_m > 0 makes φ strictly convex and coercive:
the saddle point exists and is unique (Streit §4.2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import logsumexp

from jointtrack.assignment.core import DEFAULT_MAX_BITS, DEFAULT_MAX_MEMORY, solve_checked
from jointtrack.errors import InfeasibleAssignmentError
from jointtrack.saddle.generating import check_coefficients, log_psi

__all__ = [
    "METHODS",
    "SaddlePoint",
    "SaddlePointError",
    "jpda_log_weights",
    "log_mixed_derivative",
    "saddle_point",
]

METHODS = ("exact", "saddle")
_LOG_2PI = math.log(2.0 * math.pi)


class SaddlePointError(ValueError):
    """Newton's method did not reach the saddle point within its iteration budget."""


# --------------------------------------------------------------------------- exact


def _exact_one(a0: float, log_a: np.ndarray, F: np.ndarray) -> float:
    """log I for one (K, M+1) problem by the assignment-sum core."""
    K, M1 = F.shape
    with np.errstate(divide="ignore"):
        logW = np.log(F[:, 1:]) - log_a[None, :]
        lognull = np.log(F[:, 0])
    # a row scale multiplies every term once (the row is used or null): bring each
    # row's largest weight to 1 so nothing overflows, and add the scales back
    shift = np.maximum(logW.max(axis=1, initial=-np.inf), lognull)
    dead = shift == -np.inf  # a factor with no way to be satisfied: Ψ ≡ 0
    if dead.any():
        return -math.inf
    W = np.exp(logW - shift[:, None])
    null = np.exp(lognull - shift)
    try:
        res = solve_checked(
            np.ascontiguousarray(W),
            null,
            np.ones(K, np.int64),
            np.ones(M1 - 1, np.int64),
            False,
            "auto",
            DEFAULT_MAX_BITS,
            DEFAULT_MAX_MEMORY,
            False,
        )
    except InfeasibleAssignmentError:
        return -math.inf
    return a0 + float(log_a.sum()) + res.log_normalizer + float(shift.sum())


def jpda_log_weights(a0, a, b, C) -> np.ndarray:
    """Exact log particle weights of one target, batched: one core call for all particles.

    ``b`` (L, M+1): the particles' own factor; ``C`` (K−1, M+1): the other
    targets' factors (shared). With Z' the assignment sum of the other factors
    and u_m the probability that measurement m is clutter there,

        I_l = T · (b_l0 + Σ_m b_lm u_m / a_m),   T = e^{a0} Π a_m Z',

    because fixing measurement m to the particle removes it from the others'
    problem: Z'_{−m} = Z' u_m / a_m. Cost: one forward–backward pass of the core
    plus O(L M). u_m carries the core's absolute error (~1e-16), so a weight
    dominated by a measurement another target holds almost surely is accurate
    to that absolute level relative to the largest weight.
    """
    a0, a, b, _ = check_coefficients(a0, a, b)
    _, _, C, _ = check_coefficients(a0, a, C)
    log_a = np.log(a)
    if C.shape[0]:
        with np.errstate(divide="ignore"):
            logW = np.log(C[:, 1:]) - log_a[None, :]
            lognull = np.log(C[:, 0])
        shift = np.maximum(logW.max(axis=1, initial=-np.inf), lognull)
        if (shift == -np.inf).any():
            return np.full(b.shape[0], -np.inf)
        try:
            res = solve_checked(
                np.ascontiguousarray(np.exp(logW - shift[:, None])),
                np.exp(lognull - shift),
                np.ones(C.shape[0], np.int64),
                np.ones(a.size, np.int64),
                True,
                "auto",
                DEFAULT_MAX_BITS,
                DEFAULT_MAX_MEMORY,
                False,
            )
        except InfeasibleAssignmentError:
            return np.full(b.shape[0], -np.inf)
        log_T = a0 + float(log_a.sum()) + res.log_normalizer + float(shift.sum())
        unused = np.clip(1.0 - res.P.sum(axis=0), 0.0, 1.0)
    else:
        log_T = a0 + float(log_a.sum())
        unused = np.ones(a.size)
    with np.errstate(divide="ignore"):
        terms = np.concatenate(
            [np.log(b[:, :1]), np.log(b[:, 1:]) + np.log(unused) - log_a], axis=1
        )
    return log_T + logsumexp(terms, axis=1)


# --------------------------------------------------------------------------- saddle point


@dataclass(frozen=True)
class SaddlePoint:
    """Result of :func:`saddle_point` (batched: one entry per problem).

    Attributes
    ----------
    u : (…, M) ndarray
        log of the saddle point r̂ (eq. 24).
    phi : (…,) ndarray
        φ(û) = log Ψ(r̂) − Σ log r̂.
    log_det : (…,) ndarray
        log det ∇²φ(û) (the Hessian of eq. 31 in log coordinates).
    iterations : int
        Newton steps taken (the slowest problem).
    converged : (…,) bool ndarray
        ‖∇φ(û)‖∞ ≤ tol.
    gradient_norm : (…,) ndarray
    """

    u: np.ndarray
    phi: np.ndarray
    log_det: np.ndarray
    iterations: int
    converged: np.ndarray
    gradient_norm: np.ndarray


def _derivatives(u, a, F):
    """φ's gradient and Hessian at u (batched), and the tilted probabilities."""
    r = np.exp(u)
    lam = a * r  # (…, M)
    num = F[..., 1:] * r[..., None, :]  # (…, K, M)
    s = F[..., 0] + num.sum(-1)  # (…, K)
    p = num / s[..., None]
    grad = lam + p.sum(-2) - 1.0
    hess = -np.einsum("...km,...kn->...mn", p, p)
    diag = lam + p.sum(-2)
    idx = np.arange(u.shape[-1])
    hess[..., idx, idx] += diag
    return grad, hess


def saddle_point(
    a0, a, F, *, tol: float = 1e-12, max_iter: int = 100, raise_on_failure: bool = True
) -> SaddlePoint:
    """Minimise φ(u) = log Ψ(e^u) − Σ u by Newton's method, batched over ``F`` (L, K, M+1)."""
    a0, a, F, _ = check_coefficients(a0, a, F)
    M = a.size
    batch = F.shape[:-2]
    u = np.zeros((*batch, M))
    phi = log_psi(u, a0, a, F) - u.sum(-1)
    active = np.ones(batch, bool)
    it = 0
    gnorm = np.full(batch, np.inf)
    for it in range(1, max_iter + 1):
        grad, hess = _derivatives(u, a, F)
        gnorm = np.abs(grad).max(-1) if M else np.zeros(batch)
        active = gnorm > tol
        if not active.any():
            it -= 1
            break
        step = np.zeros_like(u)
        step[active] = -np.linalg.solve(hess[active], grad[active][..., None])[..., 0]
        # backtracking: φ is convex, the Newton direction descends; halve until it does
        t = np.ones(batch)
        for _ in range(60):
            trial = u + t[..., None] * step
            phi_t = log_psi(trial, a0, a, F) - trial.sum(-1)
            ok = ~active | (phi_t <= phi + 1e-4 * t * (grad * step).sum(-1) + 1e-15 * np.abs(phi))
            if ok.all():
                break
            t = np.where(ok, t, 0.5 * t)
        u = np.where(active[..., None], u + t[..., None] * step, u)
        phi = log_psi(u, a0, a, F) - u.sum(-1)
    grad, hess = _derivatives(u, a, F)
    gnorm = np.abs(grad).max(-1) if M else np.zeros(batch)
    converged = gnorm <= max(tol, 1e-9)
    if raise_on_failure and not converged.all():
        bad = np.argwhere(~converged)
        raise SaddlePointError(
            f"the saddle point was not found in {max_iter} Newton steps for "
            f"{len(bad)} problem(s) (first: index {tuple(int(i) for i in bad[0])}, "
            f"gradient norm {float(gnorm[tuple(bad[0])]):.3g})"
        )
    sign, log_det = np.linalg.slogdet(hess) if M else (np.ones(batch), np.zeros(batch))
    return SaddlePoint(u, phi, log_det, it, converged, gnorm)


# --------------------------------------------------------------------------- public face


def log_mixed_derivative(a0, a, F, method: str = "exact"):
    """log of ∂^M Ψ/∂β_1…∂β_M at β = 0 (Streit eq. 18), exactly or by the saddle point.

    Parameters
    ----------
    a0 : float
    a : (M,) array_like, every a_m > 0
        clutter terms a_m = Λ p_Λ(y_m).
    F : (K, M+1) or (L, K, M+1) array_like, ≥ 0
        the linear factors, column 0 the constants; a batch of L problems.
    method : {"exact", "saddle"}
        ``"exact"``: the assignment sum on the core; ``"saddle"``: eq. (30).

    Returns
    -------
    float or (L,) ndarray
        −inf when I = 0 (a factor with f_k0 = 0 and no measurement it can take).

    Examples
    --------
    >>> import numpy as np
    >>> from jointtrack.saddle import log_mixed_derivative
    >>> F = np.array([[1.0, 0.5, 0.2], [1.0, 0.3, 0.9]])   # two factors, M = 2
    >>> a = np.array([0.4, 0.7])
    >>> exact = log_mixed_derivative(0.0, a, F)
    >>> # by hand: (a1 + f11 + f21)(a2 + f12 + f22) − f11 f12 − f21 f22 … expanded:
    >>> brute = 0.4*0.7 + 0.4*(0.2+0.9) + 0.7*(0.5+0.3) + 0.5*0.9 + 0.3*0.2
    >>> bool(np.isclose(np.exp(exact), brute))
    True
    >>> round(float(np.exp(log_mixed_derivative(0.0, a, F, "saddle") - exact)), 2)
    1.12
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    a0, a, F, batched = check_coefficients(a0, a, F)
    M = a.size
    if M == 0:  # the paper omits it: I = e^{a0} Π_k f_k0
        with np.errstate(divide="ignore"):
            out = a0 + np.log(F[..., 0]).sum(-1)
        return out if batched else float(out)
    if method == "exact":
        log_a = np.log(a)
        if batched:
            return np.array([_exact_one(a0, log_a, Fi) for Fi in F])
        return _exact_one(a0, log_a, F)
    # a factor that is identically zero makes Ψ ≡ 0: I = 0 exactly, no saddle point
    zero = (F == 0).all(-1).any(-1)
    sp = saddle_point(a0, a, np.where(zero[..., None, None], 1.0, F))
    out = sp.phi - 0.5 * M * _LOG_2PI - 0.5 * sp.log_det
    out = np.where(zero, -np.inf, out)
    return out if batched else float(out)
