r"""The assignment sum: one exact engine under permanents, JPDA, particle weights and identities.

For a non-negative weight matrix W (R rows × C columns), per-row null weights u
(0 for a permanent, the JPDA miss weight 1 − P_D·P_G otherwise) and columns that
weigh 1 when unused, the engine computes

.. math::

    Z = \sum_{\sigma} \prod_{r:\,\sigma(r) \ne \varnothing} W_{r\sigma(r)}
        \prod_{r:\,\sigma(r) = \varnothing} u_r ,

the sum over partial matchings σ (each row takes at most one column, each column
at most one row), together with every marginal

.. math::

    P_{rc} = \frac{1}{Z} \sum_{\sigma \ni (r, c)} w(\sigma), \qquad
    P_{r\varnothing} = \frac{1}{Z} \sum_{\sigma:\, \sigma(r) = \varnothing} w(\sigma).

With u = 0 and R ≤ C, Z is the permanent of W (Schaub eq. 32) and P its
normalised minors (eq. 33); with u = miss, Z is the JPDA normaliser of
Bojilov's eq. (6) with the weights of (7) and ``[P_{r∅} | P]`` is the JPDA
β; Streit's exact particle weights are the same sum (his eq. 14). Repeated
rows/columns (hidden tracks, identity classes) are given as group counts.

How it is computed
------------------
1. **Validation** (:mod:`._checks`): one set of checks for every face.
2. **Leaf folding** (:mod:`._fold`, on split floats :mod:`._splitfloat`): rows or
   columns with a single partner are summed out exactly; trees vanish.
3. **Components**: what remains splits into independent blocks.
4. **Dual scaling** (:mod:`.scaling`, with the one assignment solver
   :mod:`.lsap`): exact power-of-two row/column scales that make every factor
   ≤ ~1 and the best assignment ≈ 1, so no path that matters can underflow.
5. **Frontier DP** (:mod:`._plan`, :mod:`._kernels`, :mod:`._frontier`): a subset
   DP over the *open* items of the smaller-frontier side, forward–backward,
   giving every marginal for about three forward passes; banded and
   block-sparse problems cost ``layers·2^frontier``, not ``2^n``.
6. **Group-count DP** (:mod:`._groups`) for repeated rows/columns: Π(n_j + 1)
   states in the cheaper orientation (Schaub eq. 36–37).
7. **Glynn / Ryser** (:mod:`._inclusion_exclusion`) for the value of a dense
   square permanent, where their n·2^(n−1) beats the DP; they run on the
   scaled, Sinkhorn-balanced matrix with double-double sums and measure their
   own rounding error, and the DP is used whenever that estimate is too large.

Every DP only adds and multiplies non-negative numbers: the log normaliser has a
relative error of order (rows + columns)·2⁻⁵³ and every marginal an absolute
error of the same order, on any finite non-negative input.

References
----------
.. [1] S. Bojilov, K. Alexiev and P. Konstantinova, "One particular program
   realization of JPDA algorithm", *Information & Security* 9, 2002.
.. [2] M. Schaub, "Joint identification of multiple tracked targets",
   *IEEE Transactions on Aerospace and Electronic Systems*, 2021 (report).
.. [3] R. L. Streit, "Saddle point method for JPDA and related filters",
   *Proc. 18th International Conference on Information Fusion*, 2015.
.. [4] D. G. Glynn, "The permanent of a square matrix", *European Journal of
   Combinatorics* 31(7), 1887–1891, 2010.
.. [5] H. J. Ryser, *Combinatorial Mathematics*, Carus Mathematical
   Monographs 14, 1963.
.. [6] R. Jonker and A. Volgenant, "A shortest augmenting path algorithm for
   dense and sparse linear assignment problems", *Computing* 38, 325–340, 1987.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from jointtrack.assignment import _inclusion_exclusion as _ie
from jointtrack.assignment._checks import as_counts, as_int, as_null_weights, as_weights
from jointtrack.assignment._fold import _finish, _prepare
from jointtrack.assignment._frontier import frontier_dp, frontier_value
from jointtrack.assignment._groups import group_dp, state_count
from jointtrack.assignment._plan import checkpoint_plan, frontier_plan
from jointtrack.assignment.scaling import (
    group_exponents,
    scale_problem,
    scaled_block,
    scatter_block,
)
from jointtrack.errors import ExactLimitError, InfeasibleAssignmentError

__all__ = ["METHODS", "AssignmentResult", "assignment_sum"]

METHODS = ("auto", "frontier", "groups", "glynn", "ryser")
_LN2 = math.log(2.0)
_U = 2.0**-53
#: Glynn/Ryser are accepted when four times their measured error estimate is below this.
GLYNN_TOLERANCE = 1e-11
#: Largest square matrix handed to Glynn/Ryser (2^39 Gray-code steps is hours already).
GLYNN_MAX = 40
#: Below this size the frontier DP is as fast as Glynn on any matrix.
GLYNN_MIN = 15
DEFAULT_MAX_BITS = 30
DEFAULT_MAX_MEMORY = 2 * 1024**3
_PAR_MIN_BITS = 16  # frontier layers from 2^16 states up may use numba's threads
# The state is split into this many chunks whatever the thread count: each chunk's
# partial sum is added in chunk order, so a parallel result has the same bits on
# every machine and with any NUMBA_NUM_THREADS (a Dask sweep's workers agree).
_PAR_CHUNKS = 64

_INFEASIBLE = (
    "no feasible assignment: the rows with null weight 0 cannot all be given distinct "
    "columns with positive weight, so every assignment weighs 0"
)


@dataclass(frozen=True)
class AssignmentResult:
    """Result of :func:`assignment_sum` (and of every exact face on it).

    Attributes
    ----------
    log_normalizer : float
        ``log Z``; ``-inf`` when no assignment has positive weight.
    P : ndarray (row groups × column groups) or None
        Probability that a given member of row group r takes a given member of
        column group c (plain input: every group has one member). None when only
        the value was asked for.
    null : ndarray (row groups,) or None
        Probability that a member of row group r stays unassigned.
    method : str
        What ran: ``"frontier"``, ``"groups"``, ``"glynn"``, ``"ryser"`` or
        ``"trivial"``.
    converged : bool
        Always True for the exact engine (kept for one convention with the
        approximations).
    info : dict
        Diagnostics: ``n_components``, ``max_frontier`` (bits), ``n_folded``,
        ``state_bytes``, ``states`` (group DP), ``error_estimate`` (Glynn/Ryser).
    """

    log_normalizer: float
    P: np.ndarray | None
    null: np.ndarray | None
    method: str
    converged: bool = True
    info: dict = field(default_factory=dict)

    @property
    def beta(self) -> np.ndarray:
        """``[null | P]``: the JPDA layout, column 0 = unassigned."""
        if self.P is None:
            raise ValueError("the marginals were not computed (marginals=False)")
        return np.column_stack([self.null, self.P])


# --------------------------------------------------------------------------- plain input


def _frontier_block(W, u, v, marginals, max_bits, max_memory, parallel):
    """DP of one dual-scaled block in its cheaper orientation.

    Returns ``(pu, pv, pe, logZ', K, state_bytes)`` (marginal arrays empty when
    only the value is wanted).
    """
    G = W > 0.0
    R, C = G.shape
    # a plan stops at the first layer past max_bits (its K is then a lower bound)
    plan_a = frontier_plan(G, max_bits)
    plan_b = frontier_plan(np.ascontiguousarray(G.T), max_bits)
    ka, kb = int(plan_a[1]), int(plan_b[1])
    if ka > max_bits and kb > max_bits:
        raise ExactLimitError(
            f"the exact DP needs a state of at least 2^{min(ka, kb)} subsets for a block of "
            f"{R}×{C} that does not separate further, above max_bits = {max_bits}; use an "
            "approximation"
        )
    # the cheaper orientation within the budget; cost ≈ layers · 2^K (layers = rows for
    # plan_a, columns for plan_b), Python ints: exact, no overflow at 1024+ items
    transpose = ka > max_bits or (kb <= max_bits and C << kb < R << ka)
    if transpose:
        W, u, v = np.ascontiguousarray(W.T), v, u
    _, K, op_kind, op_arg, slot_of, lay_slot, term = plan_b if transpose else plan_a
    if not marginals:
        stride, state_bytes = 0, 2 * (8 << K)
        if state_bytes > max_memory:
            raise ExactLimitError(
                f"the exact DP for a {R}×{C} block needs 2 × 2^{K} states "
                f"({state_bytes / 2**30:.3g} GiB), above max_memory = {max_memory} bytes"
            )
    else:
        # the cheapest checkpoint stride that fits (a larger budget is never slower)
        stride, state_bytes = checkpoint_plan(op_kind, op_arg, lay_slot, K, max_memory)
        if stride == 0:
            raise ExactLimitError(
                f"the exact DP for a {R}×{C} block needs at least {state_bytes / 2**30:.3g} GiB "
                f"(2^{K} states × {state_bytes >> (K + 3)} arrays with checkpointing), above "
                f"max_memory = {max_memory} bytes"
            )
    # Items whose every weight underflowed in the scaling never enter the
    # frontier: they are unused in every assignment that matters, and their
    # unused weight multiplies Z.
    isolated = slot_of < 0
    log_isolated = 0.0
    for c in np.flatnonzero(isolated):
        log_isolated += math.log(v[c]) if v[c] > 0.0 else -math.inf
    nchunk = 1
    if parallel and K >= _PAR_MIN_BITS:
        nchunk = _PAR_CHUNKS
    if not marginals:
        lz = frontier_value(W, u, v, K, op_kind, op_arg, slot_of, lay_slot, term, nchunk)
        return None, None, None, lz + log_isolated, K, state_bytes
    pl, pi, pe, lz = frontier_dp(
        W, u, v, K, op_kind, op_arg, slot_of, lay_slot, term, stride, nchunk
    )
    pi[isolated] = 1.0
    lz += log_isolated
    if transpose:
        return pi, pl, np.ascontiguousarray(pe.T), lz, K, state_bytes
    return pl, pi, pe, lz, K, state_bytes


def _frontier(W, null, marginals, max_bits, max_memory, parallel) -> AssignmentResult:
    """Fold, split, scale and solve plain input (every group of size one)."""
    R, C = W.shape
    folds, graph, ncomp, infeasible, logZ = _prepare(W, null)
    info = {"n_components": int(ncomp), "max_frontier": 0, "n_folded": len(folds[0])}
    if infeasible:
        return _infeasible("frontier", marginals, info)
    pu, pv, pe = np.zeros(R), np.zeros(C), np.zeros((R, C))
    peak = 0
    for k in range(ncomp):
        rows, cols, Wb, ub, vb, shift, ok = scaled_block(k, *graph)
        if not ok:
            return _infeasible("frontier", marginals, info)
        bu, bv, be, lz, K, sb = _frontier_block(
            Wb, ub, vb, marginals, max_bits, max_memory, parallel
        )
        if lz == -math.inf:
            return _infeasible("frontier", marginals, info)
        if marginals:
            scatter_block(rows, cols, bu, bv, be, pu, pv, pe)
        logZ += lz - shift
        info["max_frontier"] = max(info["max_frontier"], int(K))
        peak = max(peak, sb)
    info["state_bytes"] = int(peak)
    if not marginals:
        return AssignmentResult(float(logZ), None, None, "frontier", True, info)
    beta = _finish(*folds, pu, pv, pe)
    return AssignmentResult(float(logZ), beta[:, 1:], beta[:, 0], "frontier", True, info)


def _infeasible(method, marginals, info) -> AssignmentResult:
    if marginals:
        raise InfeasibleAssignmentError(_INFEASIBLE)
    return AssignmentResult(-math.inf, None, None, method, True, info)


def _glynn_value(W, kind, warn) -> AssignmentResult | None:
    """Glynn's or Ryser's formula on the scaled, balanced matrix; None if not accurate enough."""
    from jointtrack.assignment._sinkhorn import balance_exponents

    n = W.shape[0]
    B, _, _, log_shift, ok = scale_problem(W, np.zeros(n))
    if not ok:
        return AssignmentResult(-math.inf, None, None, kind, True, {})
    fr, fc = balance_exponents(B)
    B = np.ldexp(B, fr[:, None] + fc[None, :])
    log_shift += int(fr.sum() + fc.sum()) * _LN2
    kernel = _ie.glynn_kernel if kind == "glynn" else _ie.ryser_kernel
    value, _, l2 = kernel(B, 12)
    estimate = 4.0 * math.sqrt(n) * _U * l2 / value if value > 0.0 else math.inf
    info = {"error_estimate": estimate}
    if not estimate <= GLYNN_TOLERANCE:
        if warn:
            warnings.warn(
                f"{kind}: estimated relative rounding error {estimate:.2g} is above "
                f"{GLYNN_TOLERANCE:g}; the cancellation-free DP's value is returned instead",
                RuntimeWarning,
                stacklevel=4,
            )
        return None
    return AssignmentResult(math.log(value) - log_shift, None, None, kind, True, info)


def _glynn_wins(W, max_bits: int) -> bool:
    """For a square permanent value: is Glynn's n·2^(n−1) cheaper than the frontier DP,
    and within the budget (its 2^(n−1) terms count against ``max_bits`` like DP states)?"""
    n = W.shape[0]
    if n < GLYNN_MIN or n > GLYNN_MAX or n - 1 > max_bits:
        return False
    if (W > 0.0).all():  # dense: the frontier is n wide whichever way (and no plan is loaded)
        return True
    return _pow2_cost(n, n - 1) < _frontier_cost(W)


# --------------------------------------------------------------------------- repeated rows/columns


def _group_cost(rows, cols):
    """(states × items × groups, items are rows?) of the cheaper group-DP orientation."""
    by_rows = state_count(cols) * rows.sum() * len(cols)
    by_cols = state_count(rows) * cols.sum() * len(rows)
    return min(by_rows, by_cols), bool(by_rows <= by_cols)


def _groups(W, null, rows, cols, marginals, max_memory) -> AssignmentResult:
    cost, items_are_rows = _group_cost(rows, cols)
    er, ec, ok = group_exponents(W, null, rows, cols)
    if not ok:
        return _infeasible("groups", marginals, {})
    B = np.ldexp(W, er[:, None] + ec[None, :])
    u = np.ldexp(null, er)
    v = np.ldexp(1.0, ec)
    shift = float(np.dot(rows, er) + np.dot(cols, ec)) * _LN2
    if items_are_rows:
        Wi, a, cap, t, item_counts = B, u, cols, v, rows
    else:
        Wi, a, cap, t, item_counts = np.ascontiguousarray(B.T), v, rows, u, cols
    items = np.repeat(np.arange(Wi.shape[0]), item_counts).astype(np.int64)
    states = state_count(cap)
    # two rolling arrays (+ three for the backward pass), and with marginals the
    # forward windows: one layer per item when no item may stay null
    layers = 2 + ((3 + (1 if not a.any() else items.size + 1)) if marginals else 0)
    need = 8 * states * layers
    if need > max_memory:
        raise ExactLimitError(
            f"the repeated-row/column DP needs {states:.3g} states × {layers} layers "
            f"({need / 2**30:.3g} GiB), above max_memory = {max_memory} bytes "
            "(Schaub eq. 37); use an approximation"
        )
    info = {"states": int(states), "state_bytes": int(need), "items_are_rows": items_are_rows}
    logZ, item_null, item_take, unused = group_dp(
        np.ascontiguousarray(Wi),
        items,
        np.ascontiguousarray(a),
        cap.astype(np.int64),
        np.ascontiguousarray(t),
        marginals,
    )
    if logZ == -math.inf:
        return _infeasible("groups", marginals, info)
    logZ -= shift
    if not marginals:
        return AssignmentResult(float(logZ), None, None, "groups", True, info)
    # members of one item group have equal marginals: average them
    ng = Wi.shape[0]
    take = np.zeros((ng, cap.size))
    np.add.at(take, items, item_take)
    take /= item_counts[:, None]
    per_member = take / cap[None, :]
    if items_are_rows:
        nul = np.zeros(ng)
        np.add.at(nul, items, item_null)
        P, null_p = per_member, nul / item_counts
    else:
        P, null_p = per_member.T, unused
    return AssignmentResult(float(logZ), _clip(P), _clip(null_p), "groups", True, info)


def _clip(x):
    # rounding can leave probabilities a few ulps outside [0, 1]
    return np.clip(np.ascontiguousarray(x), 0.0, 1.0)


def find_repeats(W):
    """Group identical rows and columns: ``(V, rows, cols, row_of, col_of)`` or None.

    ``W == V[row_of][:, col_of]``; lets ``"auto"`` give plain input with repeated
    rows or columns to the group-count DP (Schaub eq. 36–37).
    """
    V, row_of, rows = np.unique(W, axis=0, return_inverse=True, return_counts=True)
    V, col_of, cols = np.unique(V, axis=1, return_inverse=True, return_counts=True)
    if len(rows) == W.shape[0] and len(cols) == W.shape[1]:
        return None
    return (
        np.ascontiguousarray(V),
        rows.astype(np.int64),
        cols.astype(np.int64),
        row_of.ravel(),
        col_of.ravel(),
    )


# --------------------------------------------------------------------------- entry point


def assignment_sum(
    W,
    null=None,
    *,
    row_counts=None,
    col_counts=None,
    marginals: bool = True,
    method: str = "auto",
    max_bits: int = DEFAULT_MAX_BITS,
    max_memory: int = DEFAULT_MAX_MEMORY,
    parallel: bool = False,
) -> AssignmentResult:
    """Sum over partial matchings of a non-negative matrix, and all its marginals.

    Parameters
    ----------
    W : (R, C) array_like
        Non-negative finite weights (0 = not allowed). With group counts, the
        compressed matrix: row group r appears ``row_counts[r]`` times, column
        group c ``col_counts[c]`` times.
    null : scalar or (R,) array_like, optional
        Weight of leaving a row unassigned (default 0: every row is assigned,
        as in a permanent). Unused columns weigh 1.
    row_counts, col_counts : (R,), (C,) array_like of positive ints, optional
        Group sizes of repeated rows / columns (Schaub eq. 36).
    marginals : bool
        Also compute ``P`` and ``null`` (one forward–backward pass); False
        computes only ``log_normalizer``, in less memory.
    method : {"auto", "frontier", "groups", "glynn", "ryser"}
        ``"auto"`` picks the cheapest exact method. ``"glynn"``/``"ryser"``
        apply to the value of a square problem without null weights only; when
        their measured rounding error is too large the DP's value is returned
        with a warning.
    max_bits, max_memory : int
        Refuse DP states above 2^max_bits subsets or max_memory bytes; Glynn's
        and Ryser's 2^(n−1) terms count against ``max_bits`` too (``"auto"``
        does not pick them past it, an explicit ``method`` is refused).
    parallel : bool
        Split large frontier layers over numba's threads.

    Returns
    -------
    AssignmentResult

    Raises
    ------
    ValueError
        bad input (named), an unknown method, or a problem beyond the limits.
    InfeasibleAssignmentError
        ``marginals=True`` and no assignment has positive weight.

    Examples
    --------
    >>> import numpy as np
    >>> from jointtrack.assignment import assignment_sum
    >>> r = assignment_sum([[1.0, 2.0], [3.0, 4.0]])          # permanent 1·4 + 2·3
    >>> round(float(np.exp(r.log_normalizer)), 9), r.P.round(2).tolist()
    (10.0, [[0.4, 0.6], [0.6, 0.4]])
    >>> r = assignment_sum([[2.0]], null=[1.0])                # JPDA: miss 1, L = 2
    >>> r.beta.round(3).tolist()
    [[0.333, 0.667]]
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    W = as_weights(W, "W")
    R, C = W.shape
    null = as_null_weights(null, R, "null")
    rows = as_counts(row_counts, R, "row_counts")
    cols = as_counts(col_counts, C, "col_counts")
    max_bits = as_int(max_bits, "max_bits", 0, 62)
    max_memory = as_int(max_memory, "max_memory", 0)
    return solve_checked(
        W, null, rows, cols, marginals, method, max_bits, max_memory, bool(parallel)
    )


def solve_checked(W, null, rows, cols, marginals, method, max_bits, max_memory, parallel):
    """:func:`assignment_sum` on arguments a face has already validated.

    ``W`` C-contiguous float64 (R, C) ≥ 0 finite; ``null`` float64 (R,) ≥ 0
    finite; ``rows``/``cols`` int64 group sizes ≥ 1; ``method`` one of
    :data:`METHODS`. Saves the second validation on the tracker's hot path.
    """
    R, C = W.shape
    if R == 0:
        empty = np.zeros((0, C))
        return AssignmentResult(
            0.0,
            empty if marginals else None,
            np.zeros(0) if marginals else None,
            "trivial",
            True,
            {},
        )
    if C == 0:
        # no columns: every row is unassigned, Z = Π null (the DP's plans assume a
        # column to visit; zero columns reached uninitialised memory there)
        if not (null > 0).all():
            return _infeasible("trivial", marginals, {})
        logZ = float(np.dot(rows, np.log(null)))
        if not marginals:
            return AssignmentResult(logZ, None, None, "trivial", True, {})
        return AssignmentResult(logZ, np.zeros((R, 0)), np.ones(R), "trivial", True, {})
    compressed = bool((rows > 1).any() or (cols > 1).any())
    if not compressed and method == "auto":
        repeats = find_repeats(W) if R * C <= 1_000_000 else None
        if repeats is not None and np.unique(null).size == 1:
            V, r_cnt, c_cnt, row_of, col_of = repeats
            if _group_cost(r_cnt, c_cnt)[0] < _frontier_cost(W):
                res = _groups(V, np.full(len(r_cnt), null[0]), r_cnt, c_cnt, marginals, max_memory)
                if not marginals:
                    return res
                return AssignmentResult(
                    res.log_normalizer,
                    res.P[row_of][:, col_of],
                    res.null[row_of],
                    res.method,
                    True,
                    res.info,
                )
    if compressed:
        if method in ("auto", "groups"):
            if method == "groups" or _group_cost(rows, cols)[0] < _frontier_cost_expanded(
                rows, cols
            ):
                return _groups(W, null, rows, cols, marginals, max_memory)
        return _expanded(W, null, rows, cols, marginals, method, max_bits, max_memory, parallel)
    if method == "groups":
        return _groups(W, null, rows, cols, marginals, max_memory)
    if method in ("glynn", "ryser") and R < C and not null.any() and not marginals:
        # Per([A; J]) = (C−R)!·Per(A) for J the (C−R)×C all-ones block: square it
        padded = np.vstack([W, np.ones((C - R, C))])
        res = assignment_sum(
            padded,
            marginals=False,
            method=method,
            max_bits=max_bits,
            max_memory=max_memory,
            parallel=parallel,
        )
        return AssignmentResult(
            res.log_normalizer - math.lgamma(C - R + 1), None, None, res.method, True, res.info
        )
    square_permanent = R == C and not null.any()
    if method in ("glynn", "ryser"):
        if marginals or not square_permanent:
            raise ValueError(
                f"method={method!r} computes only the value of a square problem without null "
                "weights (marginals=False, null=None); use method='auto'"
            )
        if R > GLYNN_MAX:
            raise ValueError(f"{method} on a {R}×{R} matrix would take 2^{R - 1} steps")
        if R - 1 > max_bits:
            # the same work budget as the DP's states: a dense 40×40 would otherwise run
            # for hours instead of being refused
            raise ExactLimitError(
                f"{method} on a {R}×{R} matrix sums 2^{R - 1} terms, above max_bits = "
                f"{max_bits}; raise max_bits or use an approximation"
            )
        res = _glynn_value(W, method, warn=True)
        if res is not None:
            return res
    elif method == "auto" and not marginals and square_permanent and _glynn_wins(W, max_bits):
        res = _glynn_value(W, "glynn", warn=False)
        if res is not None:
            return res
    return _frontier(W, null, marginals, max_bits, max_memory, parallel)


def _frontier_cost(W) -> float:
    """Operations of the frontier DP in its cheaper orientation: layers · 2^width · degree."""
    G = W > 0.0
    R, C = G.shape
    ka = frontier_plan(G)[1]
    kb = frontier_plan(np.ascontiguousarray(G.T))[1]
    return min(_pow2_cost(R, ka), _pow2_cost(C, kb)) * max(1.0, G.sum() / max(R, 1))


def _frontier_cost_expanded(rows, cols) -> float:
    # dense expanded problem: the frontier is the smaller side
    R, C = int(rows.sum()), int(cols.sum())
    return _pow2_cost(max(R, C), min(R, C)) * min(R, C)


def _pow2_cost(m, k) -> float:
    """m · 2^k as a float, inf past the float range (a cost, only ever compared).

    ``2.0 ** k`` raises OverflowError from k = 1024 on: a block of 1024 columns.
    """
    m, k = int(m), int(k)
    return math.ldexp(float(m), k) if m.bit_length() + k < 1020 else math.inf


def _expanded(W, null, rows, cols, marginals, method, max_bits, max_memory, parallel):
    """Solve compressed input on its expansion, then read back one member per group."""
    Wx = np.repeat(np.repeat(W, rows, axis=0), cols, axis=1)
    nx = np.repeat(null, rows)
    res = assignment_sum(
        Wx,
        nx,
        marginals=marginals,
        method=method,
        max_bits=max_bits,
        max_memory=max_memory,
        parallel=parallel,
    )
    if not marginals:
        return res
    first_r = np.concatenate([[0], np.cumsum(rows)[:-1]])
    first_c = np.concatenate([[0], np.cumsum(cols)[:-1]])
    return AssignmentResult(
        res.log_normalizer,
        res.P[first_r][:, first_c],
        res.null[first_r],
        res.method,
        True,
        res.info,
    )
