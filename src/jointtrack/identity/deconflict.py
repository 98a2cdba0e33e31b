r"""Identity deconfliction: track-to-identity probabilities from the filter-bank coefficients.

Schaub's posterior probability that identity i sits on track t is a ratio of
permanents (D. E. Schaub, "Joint identification of multiple tracked targets",
*Journal of Advances in Information Fusion* 12(1), 2017; eqs. 31/80):

.. math::

    P_{t,i} = M_{t,i}\,\frac{\operatorname{Per} M(t; i)}{\operatorname{Per} M},
    \qquad M = [\,A \mid B J\,]

with A the |T|×|I| coefficients a[t, i] of the filter banks (eqs. 27–29), B =
diag(b_t) the false-alarm products and J a |T|×(|T|−|I|) block of ones (eq. 77):
the |T|−|I| tracks that hold no identity take one of the J columns. Every entry
of P is an assignment marginal of M, so ``method="exact"`` is one call of the
assignment-sum core (:mod:`jointtrack.assignment`): the group-count DP takes
hidden tracks (identical rows) and identity classes (identical columns) as
counts — Schaub's modified Ryser formula (36)/(101) solves the same sum; as
printed it has typos (the binomial must read C(n_j, d_j) with d_j running from 0
to n_j) that do not concern us, since the core's DP has no alternating signs and
needs no 300-bit arithmetic.

The J block is one column group of size |T| − |I| holding b_t in row t; its
marginal, times that size, is the probability that track t holds no identity
(``P_false``). When b_t = 0 (a measurement with zero false-alarm probability
came on track t, Appendix B) the track is certain to hold an identity; more
certain tracks than identities make Per(M) = 0, which is refused with an error
naming the certain tracks.

Methods (all on the same M, all with the same result type)
-----------------------------------------------------------
``"exact"``      the permanent marginals above (core DP; error ≈ (|T|+|I|)·2⁻⁵³).
``"sinkhorn"``   Schaub's "belief matrix" P_DS = D₁ M D₂ (55): M scaled to
                 doubly stochastic (:func:`jointtrack.assignment.sinkhorn`, in log space).
``"local"``      track-level JTC, P_TL = D M (54): each row normalised alone
                 (over the identity columns and the J group, with their counts).
``"maxweight"``  the maximum-weight matching (57), one-hot (56) — via the one
                 assignment solver (:func:`jointtrack.assignment.linear_assignment`).
``"bethe"``      Bethe (belief-propagation) marginals (§3-C; Vontobel 2010).
``"sampling"``   sequential-importance-sampling marginals with standard errors
                 (§3-C's polynomial-time route; ``info["stderr"]``).

``log_normalizer`` is each method's value for log Per(M) (Schaub's normaliser,
eq. 79 up to (|T|−|I|)!): exact for ``"exact"``; for the others an estimate or
bound, said in ``info["log_normalizer_kind"]``: ``"local"`` gives log Π_t Σ_j
M_tj, an upper bound; ``"maxweight"`` the log weight of the best matching, a
lower bound; ``"sinkhorn"`` −log Π d₁ Π d₂ + log(n!/nⁿ), a lower bound (van der
Waerden: Per of a doubly stochastic n×n matrix is ≥ n!/nⁿ, and ≤ 1);
``"bethe"`` log per_B ≤ log Per ≤ log per_B + (n/2) log 2; ``"sampling"`` the
log of an unbiased estimate, with ``info["rel_stderr"]``.

Matrices outside the float range
--------------------------------
a[t, i] is a running product of hundreds of likelihoods; pass ``log_M`` (and
``log_b``) instead of ``M``. Rows and columns are first scaled by the dual of
the best matching in log space (:func:`jointtrack.assignment.scaling.from_log_weights`,
the core's one scaling), which changes no probability; no Cromwell floor is
needed (Schaub floors at 1e-100).

Examples
--------
>>> import numpy as np
>>> from jointtrack.identity import deconflict
>>> M = np.array([[4.0, 1.0], [1.0, 1.0]])
>>> deconflict(M).P.round(3).tolist()
[[0.8, 0.2], [0.2, 0.8]]
>>> deconflict(M, method="local").P.round(3).tolist()
[[0.8, 0.2], [0.5, 0.5]]
>>> r = deconflict(log_M=[[-2000.0, -2001.0], [-2001.0, -2000.0]])  # e^-2000: out of range
>>> r.P.round(3).tolist(), round(r.log_normalizer, 3)
([[0.881, 0.119], [0.119, 0.881]], -3999.873)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.special import gammaln, logsumexp

from jointtrack.assignment._checks import (
    as_counts,
    as_int,
    as_log_weights,
    as_null_weights,
    as_rng,
    as_weights,
)
from jointtrack.assignment.core import (
    DEFAULT_MAX_BITS,
    DEFAULT_MAX_MEMORY,
    solve_checked,
)
from jointtrack.assignment.scaling import from_log_weights
from jointtrack.errors import InfeasibleAssignmentError

__all__ = ["METHODS", "Deconfliction", "deconflict"]

METHODS = ("exact", "sinkhorn", "local", "maxweight", "bethe", "sampling")


@dataclass(frozen=True)
class Deconfliction:
    """Result of :func:`deconflict` (one type for every method).

    Attributes
    ----------
    P : ndarray (track groups × identity groups)
        Probability that a given member of track group t holds a given member of
        identity group i (without counts: track t holds identity i). Rows, with
        ``P_false``, sum to one over the expanded identities:
        ``P @ col_counts + P_false = 1``; columns sum to one over the expanded
        tracks: ``row_counts @ P = 1``.
    P_false : ndarray (track groups,)
        Probability that a member of track group t holds no identity (a false
        track; 0 when |T| = |I|).
    log_normalizer : float
        The method's value of log Per(M) (see the module docstring for what it
        is for each method: ``info["log_normalizer_kind"]``).
    method : str
    converged : bool
        False when an iterative method stopped early (Bethe) or the importance
        weights degenerated (sampling).
    info : dict
        ``log_normalizer_kind`` and method diagnostics: ``stderr`` (sampling: the
        standard error of every P entry), ``rel_stderr``, ``iterations``,
        ``assignment`` (maxweight: identity group of each expanded track, −1 for
        a J column), ``engine`` (exact: the core's method).
    """

    P: np.ndarray
    P_false: np.ndarray
    log_normalizer: float
    method: str
    converged: bool = True
    info: dict = field(default_factory=dict)


# --------------------------------------------------------------------------- input


def _problem(M, log_M, b, log_b, row_counts, col_counts):
    """Validated ``(log_A, log_b, rows, cols, n_tracks, n_identities)``."""
    if (M is None) == (log_M is None):
        raise ValueError("give exactly one of M (coefficients) and log_M (their logarithms)")
    if M is not None:
        A = as_weights(M, "M")
        with np.errstate(divide="ignore"):
            log_A = np.log(A)
    else:
        log_A = as_log_weights(log_M, "log_M")
    T, C = log_A.shape
    rows = as_counts(row_counts, T, "row_counts")
    cols = as_counts(col_counts, C, "col_counts")
    n_tracks, n_ids = int(rows.sum()), int(cols.sum())
    if n_tracks < n_ids:
        raise ValueError(
            f"M has {n_tracks} tracks for {n_ids} identities; every identity must sit on some "
            "track — add hidden tracks (a row group of never-observed tracks with a = 1, "
            "Schaub eq. 1)"
        )
    if b is not None and log_b is not None:
        raise ValueError("give at most one of b and log_b")
    lb = None
    if b is not None:
        with np.errstate(divide="ignore"):
            lb = np.log(as_null_weights(b, T, "b"))  # scalar or one per track group, ≥ 0
    elif log_b is not None:
        lb = as_log_weights(log_b, "log_b", np.ndim(log_b))
        if lb.ndim == 0:
            lb = np.full(T, float(lb))
        if lb.shape != (T,):
            raise ValueError(f"log_b must have one entry per track group ({T}), got {lb.shape}")
    if n_tracks > n_ids and lb is None:
        raise ValueError(
            f"{n_tracks} tracks for {n_ids} identities: {n_tracks - n_ids} tracks hold no "
            "identity, so the false-alarm products b (or log_b) are needed (Schaub eq. 77: "
            "M = [A | B·J])"
        )
    return log_A, lb, rows, cols, n_tracks, n_ids


def _square(log_A, lb, rows, cols, n_tracks, n_ids):
    """``[A | B·J]`` in log space, with the J block as one column group (eq. 77)."""
    if n_tracks == n_ids:
        return log_A, cols
    L = np.column_stack([log_A, lb])
    return np.ascontiguousarray(L), np.append(cols, n_tracks - n_ids)


def _check_certain(log_A, lb, rows, n_ids):
    """Per(M) = 0 because more tracks are certain to exist than there are identities."""
    if lb is None:
        return
    certain = np.flatnonzero(lb == -np.inf)
    n_certain = int(rows[certain].sum())
    if n_certain > n_ids:
        shown = ", ".join(str(int(t)) for t in certain[:20]) + (" …" if certain.size > 20 else "")
        raise InfeasibleAssignmentError(
            f"{n_certain} tracks are certain to exist (b = 0: a measurement with zero "
            f"false-alarm probability; track groups {shown}) but there are only {n_ids} "
            "identities, so no assignment is possible (Per(M) = 0, Schaub Appendix B): "
            "a zero false-alarm probability was given to a measurement that cannot be "
            "from a target"
        )


def _infeasible(what: str) -> InfeasibleAssignmentError:
    return InfeasibleAssignmentError(
        f"no assignment of identities to tracks has positive weight (Per(M) = 0{what}): "
        "every way of placing each identity on its own track uses a zero coefficient"
    )


# --------------------------------------------------------------------------- methods


def _split(Pfull, C, n_tracks, n_ids):
    """(P over identity groups, P_false per track group) from the square problem's marginals."""
    if n_tracks == n_ids:
        return Pfull[:, :C], np.zeros(Pfull.shape[0])
    return Pfull[:, :C], np.clip(Pfull[:, C] * (n_tracks - n_ids), 0.0, 1.0)


def _exact(L, rows, cols):
    W, null, shift, ok = from_log_weights(L, np.full(L.shape[0], -np.inf), rows, cols)
    if not ok:
        raise _infeasible("")
    res = solve_checked(
        W, null, rows, cols, True, "auto", DEFAULT_MAX_BITS, DEFAULT_MAX_MEMORY, False
    )
    return res.P, res.log_normalizer + shift, True, {"engine": res.method, **res.info}


def _local(L, rows, cols):
    # each row alone (54): P[t, j] = M[t, j] / Σ_j' n_j' M[t, j']
    lse = logsumexp(L + np.log(cols)[None, :], axis=1)
    if np.any(lse == -np.inf):
        t = int(np.flatnonzero(lse == -np.inf)[0])
        raise _infeasible(f": track group {t} has only zero coefficients")
    P = np.exp(L - lse[:, None])
    return P, float(np.dot(rows, lse)), True, {"log_normalizer_kind": "upper bound"}


def _expand(L, rows, cols):
    ri = np.repeat(np.arange(L.shape[0]), rows)
    ci = np.repeat(np.arange(L.shape[1]), cols)
    return np.ascontiguousarray(L[np.ix_(ri, ci)]), ri, ci


def _compress(Pexp, ri, ci, shape, rows, cols):
    """Per-member probabilities of groups from an expanded marginal matrix."""
    P = np.zeros(shape)
    np.add.at(P, (ri[:, None], ci[None, :]), Pexp)
    return P / (rows[:, None] * cols[None, :])


def _maxweight(L, rows, cols):
    from jointtrack.assignment.lsap import linear_assignment

    Lx, ri, ci = _expand(L, rows, cols)
    try:
        sol = linear_assignment(Lx, maximize=True)
    except InfeasibleAssignmentError:
        raise _infeasible("") from None
    onehot = np.zeros(Lx.shape)
    onehot[sol.rows, sol.cols] = 1.0
    info = {"log_normalizer_kind": "lower bound", "assignment": ci[sol.cols[np.argsort(sol.rows)]]}
    return _compress(onehot, ri, ci, L.shape, rows, cols), sol.cost, True, info


def _sinkhorn(L, rows, cols):
    from jointtrack.assignment._sinkhorn import sinkhorn_log

    # in log space throughout: exponentiating M first flushed entries far below the
    # largest to 0, and a strictly positive M then "lacked total support"
    try:
        lr, B, lc = sinkhorn_log(L, row_counts=rows, col_counts=cols)
    except InfeasibleAssignmentError:
        raise _infeasible("") from None
    except ValueError as exc:
        raise ValueError(
            f"the belief matrix (Sinkhorn scaling of M) does not exist: {exc}"
        ) from None
    n = int(rows.sum())
    scale = float(np.dot(rows, lr) + np.dot(cols, lc))  # log Π d₁ Π d₂
    # Per(M) = Per(B) / (Π d₁ Π d₂) with n!/nⁿ ≤ Per(B) ≤ 1 (van der Waerden)
    lower = gammaln(n + 1) - n * math.log(n) - scale
    info = {"log_normalizer_kind": "lower bound", "log_normalizer_upper": -scale}
    return B, lower, True, info


def _bethe(L, rows, cols):
    from jointtrack.permanent.bethe import bethe_permanent

    W, _, shift, ok = from_log_weights(L, np.full(L.shape[0], -np.inf), rows, cols)
    if not ok:
        raise _infeasible("")
    Wx, ri, ci = _expand(W, rows, cols)
    res = bethe_permanent(Wx)
    n = Wx.shape[0]
    info = {
        "log_normalizer_kind": "lower bound (Bethe)",
        "log_normalizer_upper": res.log_value + shift + 0.5 * n * math.log(2.0),
        "iterations": res.iterations,
    }
    P = _compress(np.asarray(res.marginals), ri, ci, L.shape, rows, cols)
    return P, res.log_value + shift, bool(res.converged), info


def _sampling(L, rows, cols, n_samples, rng):
    from jointtrack.permanent.sampling import sample_permanent

    W, _, shift, ok = from_log_weights(L, np.full(L.shape[0], -np.inf), rows, cols)
    if not ok:
        raise _infeasible("")
    Wx, ri, ci = _expand(W, rows, cols)
    res = sample_permanent(Wx, n_samples, rng=rng, marginals=True)
    if res.marginals is None:
        raise ValueError(
            f"every one of the {n_samples} importance samples hit a dead end; no marginal "
            "can be estimated — use more samples or method='exact'"
        )
    P = _compress(res.marginals, ri, ci, L.shape, rows, cols)
    # a group member's marginal is the mean of its members' estimates; their errors
    # are correlated, so report the largest member error (conservative)
    err = np.zeros(L.shape)
    np.maximum.at(err, (ri[:, None], ci[None, :]), res.marginals_stderr)
    info = {
        "log_normalizer_kind": "estimate (unbiased for Per(M))",
        "rel_stderr": res.rel_stderr,
        "effective_sample_size": res.effective_sample_size,
        "stderr": err,
    }
    return P, res.log_value + shift, bool(res.converged), info


# --------------------------------------------------------------------------- entry point


def deconflict(
    M=None,
    method: str = "exact",
    *,
    row_counts=None,
    col_counts=None,
    log_M=None,
    b=None,
    log_b=None,
    n_samples: int = 10_000,
    rng=None,
) -> Deconfliction:
    r"""Track-to-identity probabilities P = M ∘ Per(minors)/Per(M) (Schaub eq. 31/80).

    Parameters
    ----------
    M : (T, I) array_like, optional
        Non-negative identity coefficients a[t, i] of the filter banks (compressed
        when counts are given). Give ``log_M`` instead for coefficients outside
        the float range (every a[t, i] after a few hundred updates).
    method : {"exact", "sinkhorn", "local", "maxweight", "bethe", "sampling"}
        See the module docstring.
    row_counts, col_counts : array_like of positive int, optional
        Sizes of groups of identical tracks (hidden tracks, eq. 1) and identical
        identities (equivalence classes, §2-C).
    log_M : (T, I) array_like, optional
        ``log M`` (−inf for 0).
    b, log_b : (T,) array_like, optional
        False-alarm products b_t (eq. 29) per track group, needed when the
        expanded tracks outnumber the identities: the J block of eq. (77).
        b_t = 0 marks a track certain to exist.
    n_samples, rng :
        For ``"sampling"``: number of importance samples and the random source.

    Returns
    -------
    Deconfliction
        ``P``, ``P_false``, ``log_normalizer``, ``method``, ``converged``, ``info``.

    Raises
    ------
    ValueError
        bad input, named (complex, bool, NaN, +inf, negative, wrong shapes, fewer
        tracks than identities, missing b); a problem beyond the exact engine's
        budget (``ExactLimitError``).
    InfeasibleAssignmentError
        Per(M) = 0 — e.g. more tracks certain to exist than identities (the
        message names them).
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    log_A, lb, rows, cols, n_tracks, n_ids = _problem(M, log_M, b, log_b, row_counts, col_counts)
    _check_certain(log_A, lb, rows, n_ids)
    C = log_A.shape[1]
    L, cols_sq = _square(log_A, lb, rows, cols, n_tracks, n_ids)
    if n_tracks == 0:
        return Deconfliction(np.zeros((0, C)), np.zeros(0), 0.0, method, True, {})
    if method == "exact":
        Pfull, logZ, converged, info = _exact(L, rows, cols_sq)
        info["log_normalizer_kind"] = "exact"
    elif method == "local":
        Pfull, logZ, converged, info = _local(L, rows, cols_sq)
    elif method == "maxweight":
        Pfull, logZ, converged, info = _maxweight(L, rows, cols_sq)
        a = info["assignment"]
        info["assignment"] = np.where(a < C, a, -1)
    elif method == "sinkhorn":
        Pfull, logZ, converged, info = _sinkhorn(L, rows, cols_sq)
    elif method == "bethe":
        Pfull, logZ, converged, info = _bethe(L, rows, cols_sq)
    else:
        n_samples = as_int(n_samples, "n_samples", 2)
        Pfull, logZ, converged, info = _sampling(L, rows, cols_sq, n_samples, as_rng(rng))
        if n_tracks > n_ids:
            info["stderr_false"] = info["stderr"][:, C] * (n_tracks - n_ids)
        info["stderr"] = info["stderr"][:, :C]
    P, P_false = _split(np.clip(Pfull, 0.0, 1.0), C, n_tracks, n_ids)
    return Deconfliction(
        np.ascontiguousarray(P), P_false, float(logZ), method, bool(converged), info
    )
