"""JPDA*: JPDA association probabilities that avoid track coalescence.

H. A. P. Blom and E. A. Bloem, "Probabilistic data association avoiding track
coalescence", *IEEE Transactions on Automatic Control* 45(2), 2000, pp. 247–259.

JPDA averages over joint events that differ only by *which* of two close
targets took *which* of their two returns. When the targets are closer than
the measurement noise those permutations weigh about the same, each track is
pulled to the mean of both returns, and the two tracks coalesce — after which
their ids are a coin toss. JPDA* keeps, among the joint events that detect the
same set of targets with the same set of measurements (the events a permutation
of the measurement-to-target assignment turns into each other), only the most
likely one, and normalises over the events kept. The tracks then follow the
best permutation each scan and stay apart.

With the DESIGN.md cluster convention (likelihood ratios ``L``, miss weights
``miss``) an event H assigns track i the column ``a_i`` (0: none) with weight
``w(H) = Π_{i: a_i>0} L[i, a_i − 1] · Π_{i: a_i=0} miss[i]``. Events of one
class (detected tracks D, measurements S) share the miss factors, so "most
likely" compares ``Π_{i∈D} L[i, a_i − 1]``; that comparison is exact (products
of the float inputs as rationals) wherever the float weights are within
rounding of each other. Events that tie exactly share their class's weight
equally — the symmetric choice, so that the result does not depend on the
order in which the tracks are listed. A class of one detected track has one
event: JPDA* differs from JPDA only where two or more tracks are detected.

The events come from Bojilov's enumeration
(:func:`~jointtrack.association.hypotheses.iter_hypotheses`, probabilities in
log space against the exact JPDA normaliser of the assignment-sum core); there
is no DP for the class maxima, so the cost is the number of feasible events,
bounded by ``max_hypotheses``.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from jointtrack.assignment._checks import as_int
from jointtrack.association._validate import check_cluster
from jointtrack.association.hypotheses import iter_hypotheses
from jointtrack.errors import ExactLimitError, InfeasibleAssignmentError

__all__ = ["JPDA_STAR_MAX_HYPOTHESES", "JPDAStarResult", "jpda_star", "jpda_star_marginals"]

#: default bound on the feasible joint events one cluster may enumerate
JPDA_STAR_MAX_HYPOTHESES = 20_000
#: float weights of a class within this relative distance of its largest are
#: compared exactly (log-space rounding: ≤ N·745·ε ≈ 1.3e-12 relative for N = 8 tracks)
_NEAR = 1e-9


@dataclass(frozen=True)
class JPDAStarResult:
    """Result of :func:`jpda_star`.

    Attributes
    ----------
    beta : ndarray (N, M+1)
        JPDA* association probabilities; column 0 = no measurement; rows sum to 1.
    log_normalizer : float
        Natural log of the summed weight of the events kept (the DESIGN.md
        weights, as :func:`~jointtrack.association.exact.exact_log_normalizer`'s).
    n_hypotheses : int
        Feasible joint events enumerated.
    n_kept : int
        Events kept (one per class, or each of a class's exact ties).
    """

    beta: np.ndarray
    log_normalizer: float
    n_hypotheses: int
    n_kept: int


def _exact_product(L, a) -> Fraction:
    """``Π_{i: a_i>0} L[i, a_i − 1]`` as an exact rational."""
    p = Fraction(1)
    for i, col in enumerate(a.tolist()):
        if col:
            p *= Fraction(float(L[i, col - 1]))
    return p


def jpda_star(L, miss, *, max_hypotheses: int | None = JPDA_STAR_MAX_HYPOTHESES) -> JPDAStarResult:
    """JPDA* association probabilities of one cluster (Blom & Bloem 2000; module docstring).

    Parameters
    ----------
    L : array (N, M)
        Likelihood ratios ``P_D g_ij / λ`` (0 = not gated).
    miss : array (N,)
        ``1 − P_D P_G`` per track.
    max_hypotheses : int or None
        Refuse clusters with more feasible joint events than this (counted
        first, without enumerating); None = no limit.

    Returns
    -------
    JPDAStarResult

    Raises
    ------
    ValueError
        bad ``L``/``miss`` (named) or a bad ``max_hypotheses``.
    ExactLimitError
        more feasible joint events than ``max_hypotheses``.
    InfeasibleAssignmentError
        no feasible joint event.
    """
    if max_hypotheses is not None:
        max_hypotheses = as_int(max_hypotheses, "max_hypotheses", 1)
    L, miss = check_cluster(L, miss)
    N, M = L.shape
    if N == 0:
        return JPDAStarResult(np.zeros((0, M + 1)), 0.0, 1, 1)
    # classes: (detected tracks, measurements used) → [(event, probability)]
    classes: dict = {}
    n_hyp = 0
    events = iter_hypotheses(L, miss, max_hypotheses=max_hypotheses)
    try:
        first = next(events)
    except InfeasibleAssignmentError:
        raise
    except ValueError as exc:  # the inputs are checked: the event count is over the limit
        raise ExactLimitError(f"jpda_star: {exc}") from None
    for a, p in itertools.chain([first], events):
        n_hyp += 1
        key = ((a > 0).tobytes(), np.sort(a[a > 0]).tobytes())
        classes.setdefault(key, []).append((a, p))
    acc = np.zeros((N, M + 1))
    rows = np.arange(N)
    total = 0.0
    n_kept = 0
    p_best, a_best = 0.0, None
    for events in classes.values():
        p_max = max(p for _, p in events)
        if p_max == 0.0:  # below the float range relative to the best event: adds nothing
            continue
        near = [(a, p) for a, p in events if p >= p_max * (1.0 - _NEAR)]
        if len(near) > 1:
            exact = [_exact_product(L, a) for a, _ in near]
            top = max(exact)
            near = [e for e, x in zip(near, exact, strict=True) if x == top]
        share = 1.0 / len(near)
        for a, p in near:
            w = p * share
            acc[rows, a] += w
            total += w
        n_kept += len(near)
        if p_max > p_best:
            p_best, a_best = p_max, near[0][0]
    beta = acc / total
    beta /= beta.sum(axis=1, keepdims=True)
    # log Z* = log w(best) + log(total / p(best)): the best event's weight in log space
    # (no second normaliser solve; p(best) ≥ 1/n_hyp, so the ratio is a plain float)
    with np.errstate(divide="ignore"):
        taken = L[rows, np.maximum(a_best - 1, 0)] if M else np.ones(N)
        log_w = np.where(a_best > 0, np.log(taken), np.log(miss))
    log_z = math.fsum(log_w.tolist()) + math.log(total / p_best)
    return JPDAStarResult(beta, float(log_z), n_hyp, n_kept)


def jpda_star_marginals(
    L, miss, *, max_hypotheses: int | None = JPDA_STAR_MAX_HYPOTHESES
) -> np.ndarray:
    """JPDA* marginals ``beta`` (N × (M+1)); see :func:`jpda_star`."""
    return jpda_star(L, miss, max_hypotheses=max_hypotheses).beta
