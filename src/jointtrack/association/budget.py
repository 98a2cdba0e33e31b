"""One cluster's association probabilities under a cost budget: exact, then an approximation.

The exact methods ("exact", "enumerate") cost exponentially in the worst case:
the frontier DP of :mod:`jointtrack.assignment.core` needs a state of 2^K
subsets for a block of frontier width K. The policy, shared by the JPDA tracker
(:class:`jointtrack.trackers.JPDATracker`) and the Stone Soup associators
(:mod:`jointtrack.interop.stonesoup`), is:

1. a cluster with more than ``max_tracks`` tracks goes to ``approximation``
   without trying the exact method (reason ``"exact_max_tracks"``);
2. otherwise the exact method runs; if it refuses the cluster because its state
   or memory would exceed the budget (:class:`~jointtrack.errors.ExactLimitError`,
   raised before any work), the cluster goes to ``approximation`` (reason
   ``"refused: …"`` with the engine's message).

3. past every budget — the approximation refuses the cluster too (the dense
   LBP is limited to N + M ≤ 4000), or the cluster is too large for
   an N × M matrix at all (more than :data:`DENSE_MAX_ENTRIES` entries, then no
   dense method is tried) — the cheaper tiers of :func:`fallback_pair_marginals`
   work on the gated pairs only (memory O(pairs)): sparse LBP
   (:func:`~jointtrack.association.lbp.lbp_pair_marginals`, method
   ``"lbp-sparse"``), and where that cannot run (more than ``max_pairs`` pairs)
   per-track PDA (method ``"pda"``), which never fails on a cluster whose every
   track can miss. A tracker step therefore never fails for the size of a
   cluster.

The result says which method (tier) produced each cluster's β and why, so
callers can count and report every fallback.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from jointtrack.association.core import marginals
from jointtrack.errors import ExactLimitError

__all__ = [
    "APPROXIMATIONS",
    "DENSE_MAX_ENTRIES",
    "EXACT_METHODS",
    "MAX_LBP_PAIRS",
    "MAX_LBP_WORK",
    "TIERS",
    "BudgetedMarginals",
    "PairMarginals",
    "budgeted_marginals",
    "fallback_pair_marginals",
    "reason_kind",
]

log = logging.getLogger("jointtrack.association")

EXACT_METHODS = ("exact", "enumerate")
APPROXIMATIONS = ("lbp", "mcmc", "kbest", "pda")
#: The tiers past every budget, cheapest last (methods of :func:`fallback_pair_marginals`).
TIERS = ("lbp-sparse", "pda")
#: Largest cluster (tracks × measurements) handed to the dense methods: 4·10⁶
#: entries, 32 MB per float64 N × M array (the dense LBP's N + M ≤ 4000 fits).
DENSE_MAX_ENTRIES = 4_000_000
#: Largest number of gated pairs for the sparse LBP tier (about 56 bytes each: 470 MB).
MAX_LBP_PAIRS = 2**23
#: Message updates (pairs × sweeps) the sparse LBP tier may spend (a few seconds).
MAX_LBP_WORK = 2**26
#: Sweeps a dense approximation may take (``lbp_marginals``' default ``max_iter``): with
#: the cluster's gated entries, the work bound :func:`budgeted_marginals` holds against
#: ``max_work`` before handing it a cluster.
DENSE_SWEEPS = 1000


@dataclass(frozen=True)
class BudgetedMarginals:
    """β of one cluster and how it was obtained.

    ``beta`` (N, M+1), column 0 = no measurement; ``method`` the method that
    produced it; ``reason`` empty when that is the requested method, else why the
    approximation was used.
    """

    beta: np.ndarray
    method: str
    reason: str


def budgeted_marginals(
    L,
    miss,
    *,
    method: str = "exact",
    approximation: str | None = "lbp",
    max_tracks: int | None = None,
    rng=None,
    exact_options: dict | None = None,
    max_work: int | None = MAX_LBP_WORK,
) -> BudgetedMarginals:
    """JPDA marginals of one cluster by ``method``, falling back to ``approximation``.

    Past the budget of an exact ``method`` the cluster goes to
    ``approximation``; if that (or a non-exact ``method``) refuses the cluster
    too (:class:`~jointtrack.errors.ExactLimitError`, e.g. the dense LBP above
    N + M = 4000), to the tiers of :func:`fallback_pair_marginals` on its
    non-zero entries (``method`` ``"lbp-sparse"`` or ``"pda"`` in the result).
    A dense approximation whose :data:`DENSE_SWEEPS` sweeps of the gated entries
    could exceed ``max_work`` message updates is not started: the cluster goes
    to those tiers directly, within ``max_work``, reason ``"dense_budget: …"``
    (a 2,000-return clutter burst took 85–140 s of dense LBP per scan).

    Parameters
    ----------
    L, miss
        the cluster (:func:`jointtrack.association.marginals` convention).
    method : str
        any of :data:`jointtrack.association.METHODS`; only the exact ones
        ("exact", "enumerate") are subject to ``max_tracks``.
    approximation : str or None
        one of :data:`APPROXIMATIONS`, used past the budget; None raises
        :class:`~jointtrack.errors.ExactLimitError` there instead (no tier is tried).
    max_tracks : int or None
        clusters with more tracks go straight to ``approximation``.
    rng
        random generator for ``"mcmc"`` (either as method or as approximation).
    exact_options : dict or None
        the exact method's budget, e.g. ``{"max_bits": 24, "max_memory": 2**28}``
        (:func:`jointtrack.association.exact.exact_marginals`).
    max_work : int or None
        message updates a dense approximation and the sparse tier may spend on the
        cluster (default :data:`MAX_LBP_WORK`); None: no bound on the dense one.

    Raises
    ------
    ExactLimitError
        past the budget with ``approximation=None``.
    ValueError
        an unknown approximation, or bad ``L``/``miss`` (named by the method).
    """
    if approximation is not None and approximation not in APPROXIMATIONS:
        raise ValueError(
            f"approximation must be one of {', '.join(APPROXIMATIONS)}, got {approximation!r}"
        )
    reason = ""
    n_tracks = np.shape(L)[0] if np.ndim(L) == 2 else 0
    if method in EXACT_METHODS and max_tracks is not None and n_tracks > max_tracks:
        if approximation is None:
            raise ExactLimitError(
                f"a cluster of {n_tracks} tracks is above max_tracks = {max_tracks}"
            )
        method, reason = approximation, "exact_max_tracks"
    over = _dense_work_over(L, method, max_work)
    if over:
        return _dense_fallback(L, miss, over, max_work)
    try:
        options = dict(exact_options or {}) if method == "exact" else _options(method, rng)
        beta = marginals(L, miss, method=method, **options)
    except ExactLimitError as exc:
        if approximation is None:
            raise
        if method in EXACT_METHODS:
            method, reason = approximation, f"refused: {exc}"
            over = _dense_work_over(L, method, max_work)
            if over:
                return _dense_fallback(L, miss, over, max_work)
            try:
                beta = marginals(L, miss, method=method, **_options(method, rng))
                return BudgetedMarginals(beta, method, reason)
            except ExactLimitError as exc2:
                exc = exc2
        reason = f"{reason + '; ' if reason else ''}{method} refused: {exc}"
        return _dense_fallback(L, miss, reason)
    return BudgetedMarginals(beta, method, reason)


def reason_kind(reason: str) -> str:
    """A fallback reason's kind: the part before its first ``:`` or ``;``
    (``"exact_max_tracks"``, ``"refused"``, ``"dense_budget"``, …; ``""`` for none),
    the key runs and logs count fallbacks by."""
    return reason.split(":", 1)[0].split(";", 1)[0]


def _dense_work_over(L, method: str, max_work: int | None) -> str:
    """The ``dense_budget`` reason when the dense approximation ``method`` could take
    more than ``max_work`` message updates on ``L`` (:data:`DENSE_SWEEPS` sweeps of its
    gated entries), else ``""``. Exact methods have budgets of their own, and per-track
    PDA is one pass."""
    if max_work is None or method in EXACT_METHODS or method == "pda" or np.ndim(L) != 2:
        return ""
    try:
        gated = int(np.count_nonzero(L))
    except (TypeError, ValueError):
        return ""  # not an array of numbers: the method's own validation names it
    if gated * DENSE_SWEEPS <= max_work:
        return ""
    n, m = np.shape(L)
    return (
        f"dense_budget: {n} tracks × {m} measurements, {gated} gated pairs: "
        f"{DENSE_SWEEPS} sweeps of the dense {method} could take more than {max_work} "
        "message updates"
    )


def _dense_fallback(L, miss, reason: str, max_work: int | None = None) -> BudgetedMarginals:
    """:func:`fallback_pair_marginals` on the non-zero entries of a dense (validated) cluster."""
    from jointtrack.association._validate import check_cluster

    L, miss = check_cluster(L, miss)
    rows, cols = (a.astype(np.int64) for a in np.nonzero(L))
    res = fallback_pair_marginals(
        rows,
        cols,
        L[rows, cols],
        miss,
        L.shape[1],
        reason=reason,
        max_work=MAX_LBP_WORK if max_work is None else max_work,
    )
    beta = np.zeros((L.shape[0], L.shape[1] + 1))
    beta[:, 0] = res.beta0
    beta[rows, cols + 1] = res.pair_beta
    return BudgetedMarginals(beta, res.method, res.reason)


@dataclass(frozen=True)
class PairMarginals:
    """β of one cluster on its gated pairs, and the tier that produced it.

    ``beta0`` (N,) no-measurement probabilities, ``pair_beta`` (P,) one per
    gated pair; ``method`` one of :data:`TIERS`; ``reason`` why the cluster
    came this far (and, for ``"pda"``, why sparse LBP was not used).
    """

    beta0: np.ndarray
    pair_beta: np.ndarray
    method: str
    reason: str


def fallback_pair_marginals(
    rows,
    cols,
    L_values,
    miss,
    n_measurements: int,
    *,
    reason: str = "",
    max_pairs: int = MAX_LBP_PAIRS,
    max_work: int = MAX_LBP_WORK,
) -> PairMarginals:
    """Marginals of a cluster past every budget, on its gated pairs: sparse LBP, then PDA.

    1. ``"lbp-sparse"``: Williams & Lau BP on the pairs
       (:func:`~jointtrack.association.lbp.lbp_pair_marginals`; memory and
       time per sweep O(P)), when there are at most ``max_pairs`` pairs; at
       most ``max_work / P`` sweeps (between 10 and 1000), the beliefs of the
       last sweep if BP has not converged by then;
    2. ``"pda"``: per-track PDA (Bojilov eqs. (1)–(3),
       :func:`~jointtrack.association.pda.pda_pair_marginals`; O(P), no joint
       constraint) when there are more pairs. Exact for a one-track cluster.

    Each use of the PDA tier is logged (warning). Arguments as
    :func:`~jointtrack.association.lbp.lbp_pair_marginals`; ``reason`` is
    carried into the result.

    Raises
    ------
    ValueError
        bad input.
    InfeasibleAssignmentError
        a ``miss = 0`` track has no gated pair, or (sparse LBP tier) the cluster
        has no feasible joint event.
    """
    from jointtrack.association.lbp import lbp_pair_marginals
    from jointtrack.association.pda import pda_pair_marginals

    n_pairs = int(np.size(rows))
    if n_pairs <= max_pairs:
        sweeps = int(min(1000, max(10, max_work // max(n_pairs, 1))))
        beta0, pair_beta, _info = lbp_pair_marginals(
            rows, cols, L_values, miss, n_measurements, max_iter=sweeps
        )
        return PairMarginals(beta0, pair_beta, "lbp-sparse", reason)
    why = f"{n_pairs} gated pairs > max_pairs = {max_pairs} of the sparse LBP tier"
    log.warning("association: per-track PDA for a cluster (%s)", why)
    beta0, pair_beta = pda_pair_marginals(rows, L_values, miss)
    return PairMarginals(beta0, pair_beta, "pda", f"{reason + '; ' if reason else ''}{why}")


def _options(method: str, rng) -> dict:
    return {"rng": rng} if method == "mcmc" and rng is not None else {}
