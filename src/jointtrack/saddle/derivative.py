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
once), so coefficients anywhere in the float range are fine; only row
scalings are free (the core's unused column weighs 1). A factor whose ratios
f_km/a_m and f_k0 span more than e^700 is scaled by the best assignment's
dual instead: what cannot change I by 3e-20 relative is dropped and the rest
centred in e^±650 (no silent flush to 0); what still spans more than e^1300
raises :class:`ExactRangeError`.

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

Its error is that of a Gaussian density standing in for a lattice
probability: about (e/√(2π))^M globally (Table 1), a few % per problem.

Where the approximations hold
-----------------------------
Both need X spread out at the saddle point. With small clutter against factors
that (nearly) must take the measurements (Hall-tight), a coordinate's variance
or an eigenvalue of X's correlation matrix goes to 0 and they fail (eq. 30 was
89× off at a = [1e-10], F = [[1, 1]]; the corrected method 5.9× on three
factors of ones with a_m = 1e-6). Such problems (variance or eigenvalue below
0.1) are computed on the core when that is cheap (min(K, M) ≤ 16), else
flagged: ``log_mixed_derivative(..., full_output=True).info["bound_holds"]``
is False exactly where :data:`ERROR_BOUNDS` is not claimed.

Corrected saddle point (``method="saddle-corrected"``)
------------------------------------------------------
The same saddle point, and log I ≈ φ(û) + log P(X = 1) with P(X = 1) from
:mod:`jointtrack.saddle.corrections`: every single coordinate P(X_m = 1) and
pair P(X_m = 1, X_n = 1) exact (closed forms of the tilted law), the
dependence of three or more coordinates by the Gaussian and second-order
Edgeworth terms that the singles and pairs do not already carry. No global
bias; on Table 1's setup within 0.41 % in mean and 0.35 % in spread in every
cell (eq. 30: +45…+234 % and up to 1.6 %), exact for M ≤ 2 and for K = 0.
Cost O(K M³ + K² M²) per problem after the saddle point (O(K M³) for the
pairs' complement sums, a matrix product); for L = 1000 problems of K = 7,
M = 15 about 2.3× the plain saddle point, 4.5× at M = 30.

Newton's method
---------------
One compiled call for the whole batch (:mod:`jointtrack.saddle._newton`),
each problem from u_m = −log(a_m + Σ_k f̃_km) (f̃ each factor scaled to
largest coefficient 1: every tilted mean starts within a factor M + 1 of 1,
whatever the scale of the coefficients) or from the previous problem's saddle
point when that has the smaller φ, with Armijo backtracking on φ
evaluated in log space, to ‖∇φ‖∞ ≤ 1e-12; convergence is reported per
problem and a problem that has not converged in ``max_iter`` steps raises
:class:`SaddlePointError` (or is flagged, with ``raise_on_failure=False``).

When there is no interior saddle point. a_m > 0 makes φ strictly convex;
it is coercive unless some factors with f_k0 = 0 can only take as many
measurements as there are of them (Hall-tight; Streit §4.2 assumes this
away). φ's infimum is then approached with λ → 0 on those measurements and
Newton's method stops there at ‖∇φ‖ ≤ 1e-12, where X lives on a sublattice
(Σ of those coordinates fixed). Eq. (30) is meaningless there (it raises
when det ∇²φ underflows, else returns what the Gaussian formula gives). The
corrected method is exact for a tight block of one or two measurements (its
singles and pairs); a block of three or more shows as a numerically
singular correlation matrix, and those problems alone are handed to the
exact core (a Gaussian remainder on a sublattice was 40–60 % off for 3×3 to
5×5 blocks). With *more* such factors than measurements, I = 0: Newton's
method cannot converge and :func:`log_mixed_derivative` returns −inf after a
matching check of those problems only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import logsumexp

from jointtrack.assignment._checks import _as_real_array, as_float, as_int
from jointtrack.assignment.core import DEFAULT_MAX_BITS, DEFAULT_MAX_MEMORY, solve_checked
from jointtrack.errors import InfeasibleAssignmentError
from jointtrack.saddle._newton import newton_batch
from jointtrack.saddle.corrections import log_unit_probability, tilt
from jointtrack.saddle.generating import check_coefficients

__all__ = [
    "ERROR_BOUNDS",
    "METHODS",
    "ExactRangeError",
    "MixedDerivative",
    "SaddlePoint",
    "SaddlePointError",
    "jpda_log_weights",
    "log_mixed_derivative",
    "saddle_point",
]

METHODS = ("exact", "saddle", "saddle-corrected")
_LOG_2PI = math.log(2.0 * math.pi)


class SaddlePointError(ValueError):
    """Newton's method did not reach the saddle point within its iteration budget."""


# --------------------------------------------------------------------------- exact

# a row whose log weights span at most this keeps its largest weight at 1 (nothing it
# holds goes below e^-700, a normal float); wider rows are centred instead
_ROW_SPAN = 700.0
# the widest span of weights that can matter which one row can hold, centred: e^±650
# keeps every weight, and a row sum of many of them, finite and normal
_MAX_SPAN = 1300.0
# an entry whose reduced cost (from the best assignment's dual) is above log N + this
# changes I by less than e^-45 ≈ 3e-20 relative (N: the number of assignments)
_NEGLIGIBLE = 45.0


class ExactRangeError(ValueError):
    """``method="exact"``: weights that matter span more than the float range within one factor."""


def _core_problem(log_a: np.ndarray, F: np.ndarray):
    """The core's (W, null, log scale) for one (K, M+1) problem, or None when I = 0.

    The core weighs an unused column 1, so column m is divided by a_m (a free
    factor Π a_m) and only row scalings remain free: a row scale multiplies
    every term once. A row whose ratios f_km/a_m, f_k0 span ≤ e^700 is scaled to
    largest weight 1. A wider row is scaled by its best-assignment dual
    (:func:`jointtrack.assignment.scaling.group_log_scales`): an entry whose
    reduced cost exceeds log N + 45 (N assignments) changes I by < 3e-20
    relative and is dropped; the rest is centred in e^±650. If what remains
    still spans more than e^1300 no float problem holds it, and
    :class:`ExactRangeError` says so (never a silent flush to 0).
    """
    K = F.shape[0]
    with np.errstate(divide="ignore"):
        logW = np.log(F[:, 1:]) - log_a[None, :]
        lognull = np.log(F[:, 0])
    top = np.maximum(logW.max(axis=1, initial=-np.inf), lognull)
    if (top == -np.inf).any():  # a factor with no way to be satisfied: Ψ ≡ 0
        return None
    if (top - _row_low(logW, lognull) <= _ROW_SPAN).all():
        shift = top
    else:
        logW, lognull, shift = _centre_wide_rows(logW, lognull)
        if shift is None:
            return None
    W = np.exp(logW - shift[:, None])
    null = np.exp(lognull - shift)
    return np.ascontiguousarray(W), null, float(shift.sum()), K


def _row_low(logW, lognull):
    """Each row's smallest positive weight (log), null included."""
    low = np.where(np.isfinite(logW), logW, np.inf).min(axis=1, initial=np.inf)
    return np.minimum(low, np.where(np.isfinite(lognull), lognull, np.inf))


def _centre_wide_rows(logW, lognull):
    """Row shifts for rows wider than e^700: drop what cannot matter, centre the rest."""
    from jointtrack.assignment.scaling import group_log_scales

    K, M = logW.shape
    alpha, gamma, ok = group_log_scales(logW, lognull, np.ones(K, np.int64), np.ones(M, np.int64))
    if not ok:
        return logW, lognull, None
    cut = K * math.log(M + 1.0) + _NEGLIGIBLE  # log N ≤ K log(M + 1)
    with np.errstate(invalid="ignore"):
        keepW = -(logW + alpha[:, None] + gamma[None, :]) <= cut
        keep0 = -(lognull + alpha) <= cut
    logW = np.where(keepW, logW, -np.inf)
    lognull = np.where(keep0, lognull, -np.inf)
    top = np.maximum(logW.max(axis=1, initial=-np.inf), lognull)
    low = _row_low(logW, lognull)
    wide = top - low > _MAX_SPAN
    if wide.any():
        k = int(np.flatnonzero(wide)[0])
        raise ExactRangeError(
            f"method='exact': within factor F[{k}] the ratios f_km/a_m and f_k0 that can "
            f"matter span e^{top[k] - low[k]:.0f}, more than a float problem can hold "
            f"(e^{_MAX_SPAN:.0f}); rescaling the whole problem does not help (only the "
            "spread within one factor counts)"
        )
    shift = np.where(top - low <= _ROW_SPAN, top, 0.5 * (top + low))
    return logW, lognull, shift


def _log_sum(log_a: np.ndarray, F: np.ndarray, marginals: bool = False):
    """``(log(I e^{-a0}), core result)`` for one (K, M+1) problem; ``(-inf, None)`` when I = 0."""
    prob = _core_problem(log_a, F)
    if prob is None:
        return -math.inf, None
    W, null, scale, K = prob
    try:
        res = solve_checked(
            W,
            null,
            np.ones(K, np.int64),
            np.ones(W.shape[1], np.int64),
            marginals,
            "auto",
            DEFAULT_MAX_BITS,
            DEFAULT_MAX_MEMORY,
            False,
        )
    except InfeasibleAssignmentError:
        return -math.inf, None
    if res.log_normalizer == -math.inf:
        return -math.inf, None
    return float(log_a.sum()) + res.log_normalizer + scale, res


def _exact_one(a0: float, log_a: np.ndarray, F: np.ndarray) -> float:
    """log I for one (K, M+1) problem by the assignment-sum core."""
    return a0 + _log_sum(log_a, F)[0]


# a measurement the other targets leave unused with probability below this gets its
# unused mass from a leave-one-out sum: 1 − Σ_k P_km would lose its digits
_UNUSED_DIRECT = 1.0 / 16.0


def jpda_log_weights(a0, a, b, C) -> np.ndarray:
    """Exact log particle weights of one target, batched: one core call for all particles.

    ``b`` (L, M+1): the particles' own factor; ``C`` (K−1, M+1): the other
    targets' factors (shared). With I' the mixed derivative of the other
    factors alone and I'_{−m} the same without measurement m,

        I_l = e^{a0} (b_l0 I' + Σ_m b_lm I'_{−m}),

    since a particle that takes measurement m leaves the others the problem
    without it. One forward–backward pass of the core gives I' and the
    probability u_m that the others leave m unused, I'_{−m} = I' u_m / a_m;
    u_m = 1 − Σ_k P_km is accurate only while it is not small, so a
    measurement the others use with probability above 15/16 gets I'_{−m} from
    its own core call instead (no cancellation: every weight is accurate
    relative to itself, not merely to the largest). Cost: one pass plus O(L M),
    plus one value-only core call per such measurement.
    """
    a0, a, b, _ = check_coefficients(a0, a, b)
    _, _, C, _ = check_coefficients(a0, a, C)
    log_a = np.log(a)
    if a.size == 0:  # I_l = e^{a0} b_l0 Π_j c_j0 (and the core is not asked about 0 columns)
        with np.errstate(divide="ignore"):
            return a0 + np.log(C[:, 0]).sum() + np.log(b[:, 0])
    if C.shape[0]:
        log_rest, res = _log_sum(log_a, C, marginals=True)
        if res is None:  # I' = 0, and with a measurement fewer too
            return np.full(b.shape[0], -np.inf)
        used = res.P.sum(axis=0)
        with np.errstate(divide="ignore"):
            log_without = log_rest + np.log(np.clip(1.0 - used, 0.0, 1.0)) - log_a
        for m in np.flatnonzero(1.0 - used < _UNUSED_DIRECT):
            log_without[m] = _log_sum(np.delete(log_a, m), np.delete(C, m + 1, axis=1))[0]
    else:
        log_rest = float(log_a.sum())
        log_without = log_rest - log_a
    with np.errstate(divide="ignore"):
        terms = np.concatenate(
            [np.log(b[:, :1]) + log_rest, np.log(b[:, 1:]) + log_without[None, :]], axis=1
        )
    return a0 + logsumexp(terms, axis=1)


# --------------------------------------------------------------------------- saddle point


@dataclass(frozen=True)
class SaddlePoint:
    """Result of :func:`saddle_point` (batched: one entry per problem).

    Attributes
    ----------
    u : (…, M) ndarray
        log of the saddle point r̂ (eq. 24).
    phi : (…,) ndarray
        φ(û) = log Ψ(r̂) − Σ n_m log r̂_m (n = ``counts``, 1 for eq. 24).
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


def _start(a, F):
    """Newton's starting point: every coordinate's tilted mean within a factor M + 1 of 1.

    With each factor scaled to largest coefficient 1 (p is unchanged by that),
    u_m = −log(a_m + Σ_k f̃_km) gives s_k ∈ [1, M + 1] for a factor whose
    largest coefficient is a measurement's, so λ_m + Σ_k p_km ∈ [1/(M+1), 1]:
    the search starts a bounded distance from the saddle point whatever the
    scale of the coefficients (1e±300 included), where u = 0 could be hundreds
    of Newton steps away.
    """
    top = F.max(-1, keepdims=True)
    Ft = F[..., 1:] / np.where(top > 0, top, 1.0)
    return -np.log(a + Ft.sum(-2))


def saddle_point(
    a0,
    a,
    F,
    *,
    tol: float = 1e-12,
    max_iter: int = 100,
    raise_on_failure: bool = True,
    counts=None,
) -> SaddlePoint:
    """Minimise φ(u) = log Ψ(e^u) − Σ n_m u_m by Newton's method, batched over ``F`` (L, K, M+1).

    ``counts`` n (default 1: eq. 24, the mixed derivative) gives the saddle
    point of the coefficient [β^{n−1}]·… of the contour integrand Ψ(β)/Π β^{n}
    in θ: ∇φ = E[X] − n (module docstring). Figure 1's f(z) = e^z (1+10z)^4
    z^{−6} (M = 1, four factors 1 + 10z, a = 1, n = 6) has its saddle point at
    the positive root of 10z² − 19z − 6 = 0:

    >>> import numpy as np
    >>> sp = saddle_point(0.0, [1.0], [[1.0, 10.0]] * 4, counts=[6.0])
    >>> round(float(np.exp(sp.u[0])), 10), round((19 + 601**0.5) / 20, 10)
    (2.1757650672, 2.1757650672)

    Newton's direction with Armijo backtracking on φ (convex), the test
    allowing φ's own rounding (1e-14 times the size of its terms), so that near
    the minimum, where the decrease of a Newton step is below that rounding,
    the full step is taken and the iteration does not stall short of ``tol``.
    Raises :class:`SaddlePointError` (unless ``raise_on_failure=False``) when a
    problem has ‖∇φ‖∞ > max(tol, 1e-9) after ``max_iter`` steps; ValueError
    naming the argument for a ``tol`` that is not a finite number > 0, a
    ``max_iter`` that is not a whole number ≥ 1, or a ``raise_on_failure``
    that is not a bool.
    """
    a0, a, F, _ = check_coefficients(a0, a, F)
    tol = as_float(tol, "tol", minimum=0.0, open_min=True)
    max_iter = as_int(max_iter, "max_iter", minimum=1)
    if not isinstance(raise_on_failure, bool | np.bool_):
        raise ValueError(f"raise_on_failure must be True or False, got {raise_on_failure!r}")
    M = a.size
    if counts is None:
        n = np.ones(M)
    else:
        n = _as_real_array(counts, "counts")
        if n.shape != (M,) or not np.isfinite(n).all() or (n <= 0).any():
            raise ValueError(f"counts must be {M} finite numbers > 0, got {counts!r}")
    if (F == 0).all(-1).any():
        raise ValueError("F has a factor with every coefficient 0: Ψ ≡ 0, no saddle point")
    batch = F.shape[:-2]
    K = F.shape[-2]
    Ff = F.reshape(math.prod(batch), K, M + 1)
    with np.errstate(divide="ignore"):
        logF = np.log(Ff)
    u = np.ascontiguousarray(_start(a, Ff)) if M else np.zeros((Ff.shape[0], 0))
    # one compiled call runs Newton's method for every problem (module _newton)
    phi, gnorm, steps, log_det = newton_batch(
        float(a0), a, np.ascontiguousarray(logF), n, u, float(tol), int(max_iter)
    )
    it = int(steps.max(initial=0))
    odd = np.isnan(log_det)
    if odd.any():
        # ∇²φ(û) not positive definite in float (near-singular): LAPACK's slogdet says
        # how small its determinant is (−inf when it underflows)
        with np.errstate(divide="ignore", invalid="ignore"):
            _, log_det[odd] = np.linalg.slogdet(tilt(u[odd], a, Ff[odd]).cov)
    converged = gnorm <= max(tol, 1e-9)
    u = u.reshape(*batch, M)
    phi, gnorm, converged = phi.reshape(batch), gnorm.reshape(batch), converged.reshape(batch)
    log_det = log_det.reshape(batch)
    if raise_on_failure and not converged.all():
        bad = np.argwhere(~converged)
        where = f"index {tuple(int(i) for i in bad[0])}, " if batch else ""
        raise SaddlePointError(
            f"the saddle point was not found in max_iter = {max_iter} Newton steps for "
            f"{len(bad)} problem(s) ({where}gradient norm "
            f"{float(gnorm[tuple(bad[0])]):.3g} > tol = {max(tol, 1e-9):.3g}); raise max_iter, "
            "or the problem has none (e.g. more factors with f_k0 = 0 than measurements "
            "they can take: I = 0)"
        )
    return SaddlePoint(u, phi, log_det, it, converged, gnorm)


# --------------------------------------------------------------------------- public face


def log_mixed_derivative(
    a0, a, F, method: str = "exact", *, exact_fallback: bool = True, full_output: bool = False
):
    """log of ∂^M Ψ/∂β_1…∂β_M at β = 0 (Streit eq. 18), exactly or by the saddle point.

    Parameters
    ----------
    a0 : float
    a : (M,) array_like, every a_m > 0
        clutter terms a_m = Λ p_Λ(y_m).
    F : (K, M+1) or (L, K, M+1) array_like, ≥ 0
        the linear factors, column 0 the constants; a batch of L problems.
    method : {"exact", "saddle", "saddle-corrected"}
        ``"exact"``: the assignment sum on the core; ``"saddle"``: eq. (30);
        ``"saddle-corrected"``: φ(û) + log P(X = 1) with exact single and pair
        lattice terms and the Gaussian–Edgeworth remainder
        (:mod:`jointtrack.saddle.corrections`), no global bias.
    exact_fallback : bool
        A problem outside the approximations' stated accuracy (see
        :data:`ERROR_BOUNDS`: a coordinate of X with variance below 0.1, or its
        correlation matrix with an eigenvalue below 0.1, at the saddle point —
        small clutter against factors that (nearly) must take the measurements)
        is computed on the exact core when that is cheap (min(K, M) ≤ 16);
        False leaves it approximate and flags it in ``info["bound_holds"]``.
    full_output : bool
        Return a :class:`MixedDerivative` (value, ``converged``, ``method``,
        ``info``) instead of the bare value.

    Returns
    -------
    float or (L,) ndarray, or MixedDerivative
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
    >>> # exact up to the dependence of ≥ 3 measurements: here (M = 2) exact
    >>> round(float(np.exp(log_mixed_derivative(0.0, a, F, "saddle-corrected") - exact)), 12)
    1.0
    """
    if not isinstance(method, str) or method not in METHODS:
        raise ValueError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    for name, flag in (("exact_fallback", exact_fallback), ("full_output", full_output)):
        if not isinstance(flag, bool | np.bool_):
            raise ValueError(f"{name} must be True or False, got {flag!r}")
    a0, a, F, batched = check_coefficients(a0, a, F)
    out, converged, holds, on_core, bound = _mixed_derivative(a0, a, F, method, exact_fallback)
    if not batched:
        out, converged, holds, on_core = (
            float(out),
            bool(converged),
            bool(holds),
            bool(on_core),
        )
    if not full_output:
        return out
    info = {"bound_holds": holds, "exact": on_core, "error_bound": bound}
    return MixedDerivative(out, method, converged, info)


# a coordinate of X with less variance than this, or a correlation matrix of X with a
# smallest eigenvalue below this, at the saddle point: outside the stated accuracy
_MIN_VARIANCE = 0.1
_MIN_CORRELATION_EIGENVALUE = 0.1
# exact on the core is cheap when its frontier holds at most 2^16 subsets
_CHEAP_EXACT = 16

#: Stated accuracy of the approximations where ``info["bound_holds"]``: the largest
#: |log(approximation / I)| (for ``"saddle"`` after removing its known global bias
#: M·log(e/√(2π)), Table 1). Measured on draws with coefficients from 1e-8 to 1e3
#: (zeros included), clutter from 1e-12 to 1e3, K, M ≤ 4, plus Table 1 and JPDA-like
#: draws (4 000 problems): worst 0.80 and 0.34 outside the flagged regime, against
#: 4.5 (89×) and 1.8 (5.9×) inside it.
ERROR_BOUNDS = {"saddle": 1.0, "saddle-corrected": 0.5, "exact": 0.0}


@dataclass(frozen=True)
class MixedDerivative:
    """Result of :func:`log_mixed_derivative` with ``full_output=True``.

    Attributes
    ----------
    log_normalizer : float or (L,) ndarray
        log I (−inf when I = 0).
    method : str
        The method asked for.
    converged : bool or (L,) bool ndarray
        Newton's method reached the saddle point (True for values on the core).
    info : dict
        ``bound_holds`` (bool or (L,)): the value is within ``error_bound`` of
        log I (after the known bias M·log(e/√(2π)) for ``"saddle"``), because
        it is exact or its problem is inside the approximation's regime;
        ``exact`` (bool or (L,)): computed on the exact core (the method, the
        fallback, or a problem without an interior saddle point);
        ``error_bound``: :data:`ERROR_BOUNDS` of the method, in nats.
    """

    log_normalizer: float | np.ndarray
    method: str
    converged: bool | np.ndarray
    info: dict


def _outside_regime(tl) -> np.ndarray:
    """Problems whose X at the saddle point is too narrow for the stated accuracy."""
    var = tl.var
    s = np.sqrt(np.where(var > 0, var, 1.0))
    R = tl.cov / (s[..., :, None] * s[..., None, :])
    M = var.shape[-1]
    R[..., np.arange(M), np.arange(M)] = 1.0
    finite = np.isfinite(R).all((-1, -2))
    R[~finite] = np.eye(M)
    narrow = var.min(-1) < _MIN_VARIANCE
    try:
        # R − τI positive definite ⇔ every eigenvalue above τ: one batched Cholesky
        # (10× faster than eigvalsh) decides the usual case where no problem is near
        np.linalg.cholesky(R - _MIN_CORRELATION_EIGENVALUE * np.eye(M))
        return narrow | ~finite
    except np.linalg.LinAlgError:
        pass
    try:
        lmin = np.linalg.eigvalsh(R)[..., 0]
    except np.linalg.LinAlgError:  # a batch LAPACK would not diagonalise: all flagged
        lmin = np.zeros(var.shape[:-1])
    return narrow | (lmin < _MIN_CORRELATION_EIGENVALUE) | ~finite


def _mixed_derivative(a0, a, F, method, exact_fallback):
    """``(log I, converged, bound_holds, on_core, error_bound)`` for checked arguments."""
    batch = F.shape[:-2]
    K, M1 = F.shape[-2:]
    M = M1 - 1
    bound = ERROR_BOUNDS[method]
    yes = np.ones(batch, bool)
    if M == 0:  # the paper omits it: I = e^{a0} Π_k f_k0
        with np.errstate(divide="ignore"):
            out = a0 + np.log(F[..., 0]).sum(-1)
        return out, yes, yes, yes, bound
    log_a = np.log(a)
    if method == "exact":
        if batch:
            return np.array([_exact_one(a0, log_a, Fi) for Fi in F]), yes, yes, yes, bound
        return _exact_one(a0, log_a, F), yes, yes, yes, bound
    cheap = exact_fallback and min(K, M) <= _CHEAP_EXACT
    # a factor that is identically zero makes Ψ ≡ 0: I = 0 exactly, no saddle point
    zero = np.array((F == 0).all(-1).any(-1))
    Fs = np.where(zero[..., None, None], 1.0, F)
    sp = saddle_point(a0, a, Fs, raise_on_failure=False)
    failed = ~sp.converged & ~zero
    if failed.any():
        # no saddle point: I = 0 when the factors with f_k0 = 0 cannot all get a
        # measurement of their own (Hall); otherwise a genuine failure
        from jointtrack.assignment.feasibility import is_feasible

        for i in zip(*np.nonzero(failed), strict=True) if batch else [()]:
            if not is_feasible(F[i][:, 1:], F[i][:, 0]):
                zero[i] = True
        failed &= ~zero
        if failed.any():
            bad = tuple(int(i) for i in np.argwhere(failed)[0])
            raise SaddlePointError(
                f"the saddle point was not found for {int(failed.sum())} problem(s) "
                f"({'index ' + str(bad) + ', ' if batch else ''}gradient norm "
                f"{float(sp.gradient_norm[bad]):.3g} after {sp.iterations} Newton steps)"
            )
    tl = tilt(sp.u, a, Fs)
    outside = _outside_regime(tl) & ~zero
    if method == "saddle":
        singular = ~np.isfinite(sp.log_det) & ~zero
        if singular.any() and not cheap:
            # (30) needs det ∇²φ(û) > 0; it underflows when factors with f_k0 = 0
            # are confined to as many measurements (X then lives on a sublattice)
            raise SaddlePointError(
                f"eq. (30) is undefined for {int(singular.sum())} problem(s): the Hessian "
                "at the saddle point is singular (factors with f_k0 = 0 confined to as "
                "many measurements); method='saddle-corrected' or 'exact' handle it"
            )
        with np.errstate(invalid="ignore"):
            out = sp.phi - 0.5 * M * _LOG_2PI - 0.5 * sp.log_det
    else:
        logp, singular = log_unit_probability(tl, with_flags=True)
        out = sp.phi + logp
        singular &= ~zero
    # on the core: problems without an interior saddle point (no Gaussian to expand
    # at; the corrected method always, eq. 30 only when cheap), and, when cheap, the
    # problems outside the stated accuracy
    on_core = singular | (outside & cheap)
    out = np.array(out, dtype=float)
    for i in zip(*np.nonzero(on_core), strict=True) if batch else [()] * bool(on_core):
        out[i] = _exact_one(a0, log_a, F[i])
    out = np.where(zero, -np.inf, out)
    holds = ~outside | on_core | zero
    return out, np.asarray(sp.converged | zero), holds, on_core | zero, bound
