"""Exact permanents and assignment marginals in rational arithmetic (the test oracle).

Every float64 is a dyadic rational x = μ·2^e with an integer μ < 2^53, so a row
(or a group of identical rows) multiplied by a power of two becomes a vector of
Python integers of arbitrary size. For an n×m matrix A (n ≤ m) with row scales
2^{r_t} and, when square, column scales 2^{s_j},

    A[t, j] = M[t, j] · 2^{r_t + s_j},   M integer,
    Per(A)  = 2^{Σ_t r_t + [n = m] Σ_j s_j} · Per(M)

(every term of the permanent uses every row once and, when square, every column
once; Schaub eq. 32). Per(M) is then computed *exactly* by a cancellation-free
dynamic programme that only adds and multiplies non-negative integers, and the
result is rounded once at the end. Nothing in the sum is floating point, so the
returned numbers are the correctly rounded values of the exact rationals — the
reference the fast engines in :mod:`jointtrack.permanent` are tested against.

The dynamic programme (also the one behind ``method="multiset"``)
-----------------------------------------------------------------
A compressed matrix W (distinct rows × distinct columns) with group sizes
``row_counts`` m_q and ``col_counts`` n_j stands for the expanded matrix in which
row group q appears m_q times and column group j appears n_j times (Schaub §3-A,
eq. 36–37). Plain input is the special case where every group has size one.

One side is *expanded into items* (visited one at a time); the other side is
kept as *groups* with capacities c_g, and the DP state is the vector d of how
many members of each group are used — Π_g (c_g + 1) states. An item i taking a
member of group g when d_g are already used contributes

    w_i[g] · (c_g − d_g)          (which free member it takes),

so after the last item the DP holds the permanent of the expanded matrix
exactly. Two orientations (the smaller state space wins, cf. eq. 37):

* items = rows (each row must be assigned; state = used counts per column group);
* items = columns (a column may stay unused when n < m; state = used counts
  per row group; the final state must be full).

After i items the state sum σ = |d| lies in a window [lo_i, hi_i]; states are
processed layer by layer (layers = equal σ), each layer a vectorised numpy
``object`` array operation on Python ints.

Marginals
---------
P[t, i] = A[t, i]·Per(A without row t and column i)/Per(A) = A[t,i]·∂Per/∂A[t,i]/Per.
A forward pass F_i (items before i) and a backward pass B_{i+1} (items after i)
of the same DP give, for the first member of every item group,

    num[g] = w_i[g] · Σ_d F_i[d] · (c_g − d_g) · B_{i+1}[d + e_g],

the total weight of the assignments in which item i takes *some* member of group
g; one member of group g gets num[g]/c_g. The compressed marginal is the value
for any one member of the row group × any one member of the column group, an
exact rational rounded once.

Limits
------
Plain input is practical to n ≈ 22 for the permanent (≈ 10–60 s; n = 20 takes a
few seconds) and ≈ 20 for the marginals, which keep every layer in memory.
Compressed input is limited by the number of states, e.g. Schaub's 100×100 case
with column groups 60/30/10 has 61·31·11 = 20,801 states and takes well under a
second. Sizes that would take longer than a few minutes are refused with a
ValueError before any work is done.

References
----------
H. J. Ryser, *Combinatorial Mathematics* (1963) — the permanent.
M. Schaub, "Joint identification of multiple tracked targets", eq. 32–37.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

from jointtrack.errors import InfeasibleAssignmentError
from jointtrack.permanent._validate import check_problem

__all__ = ["reference_log_permanent", "reference_marginals", "reference_permanent"]

#: Largest mixed-radix state space (Π(c_g+1)) the reference allocates.
MAX_STATES = 1 << 23
#: Largest number of state transitions (≈ 0.2–0.4 µs each with big ints) allowed.
MAX_WORK = 400_000_000
#: Marginals keep every DP layer alive: a smaller state-space bound applies.
MAX_STATES_MARGINALS = 1 << 21

# ln 2 split so that k·_LN2_HI is exact for |k| < 2^21 (fdlibm's split).
_LN2_HI = 6.93147180369123816490e-01
_LN2_LO = 1.90821492927058770002e-10


# --------------------------------------------------------------------------- input


def _mantissa_exponent(x: float) -> tuple[int, int]:
    """x = μ·2^e exactly, μ an odd integer (x > 0); (0, 0) for x = 0."""
    if x == 0.0:
        return 0, 0
    num, den = x.as_integer_ratio()  # den is a power of two
    e = -(den.bit_length() - 1)
    tz = (num & -num).bit_length() - 1
    return num >> tz, e + tz


def _integerise(A: np.ndarray, square: bool) -> tuple[list[list[int]], list[int], list[int]]:
    """Integer matrix M and exponents r (rows), s (columns) with A = M·2^{r_t+s_j}.

    Column exponents are only extracted when the (expanded) matrix is square,
    because only then does every term of the permanent use every column.
    """
    g, h = A.shape
    parts = [[_mantissa_exponent(float(A[q, j])) for j in range(h)] for q in range(g)]
    r = []
    for q in range(g):
        exps = [e for (mu, e) in parts[q] if mu]
        r.append(min(exps) if exps else 0)
    # exponent of each entry relative to its row
    rel = [[(mu, e - r[q]) for (mu, e) in parts[q]] for q in range(g)]
    s = [0] * h
    if square:
        for j in range(h):
            exps = [rel[q][j][1] for q in range(g) if rel[q][j][0]]
            s[j] = min(exps) if exps else 0
    M = [[(mu << (e - s[j])) if mu else 0 for j, (mu, e) in enumerate(rel[q])] for q in range(g)]
    return M, r, s


# --------------------------------------------------------------------------- planning


def _layer_sizes(caps: list[int]) -> list[int]:
    """Number of count vectors 0 ≤ d ≤ caps with Σd = σ, for σ = 0..Σcaps."""
    poly = [1]
    for c in caps:
        out = [0] * (len(poly) + c)
        for k, v in enumerate(poly):
            for d in range(c + 1):
                out[k + d] += v
        poly = out
    return poly


class _Plan:
    """One orientation of the multiset DP: items visited in order, groups as state."""

    def __init__(self, items_from_rows: bool, rows: np.ndarray, cols: np.ndarray):
        self.items_from_rows = items_from_rows
        item_counts, caps = (rows, cols) if items_from_rows else (cols, rows)
        self.item_counts = [int(c) for c in item_counts]
        self.caps = [int(c) for c in caps]
        self.L = sum(self.item_counts)  # number of items
        self.T = sum(self.caps)  # total capacity
        # items = rows: every row is assigned (L = n ≤ m = T), no skipping.
        # items = columns: L = m ≥ n = T; a column may stay unused iff m > n.
        self.skip = (not items_from_rows) and self.L > self.T
        self.n_states = math.prod(c + 1 for c in self.caps)
        self.sizes = _layer_sizes(self.caps)
        self.work = sum(
            self.sizes[sig] * len(self.caps) for i in range(self.L) for sig in self.source_layers(i)
        )

    def window(self, i: int) -> tuple[int, int]:
        """Range of state sums σ before item i (i items processed)."""
        if not self.skip:
            return i, i
        return max(0, self.T - (self.L - i)), min(i, self.T)

    def source_layers(self, i: int) -> range:
        lo, hi = self.window(i)
        return range(lo, min(hi, self.T - 1) + 1)


def _choose_plan(rows, cols, marginals: bool) -> _Plan:
    plans = [_Plan(True, rows, cols), _Plan(False, rows, cols)]
    max_states = MAX_STATES_MARGINALS if marginals else MAX_STATES
    ok = [p for p in plans if p.n_states <= max_states and p.work <= MAX_WORK]
    if not ok:
        best = min(plans, key=lambda p: (p.work, p.n_states))
        secs = best.work * (3 if marginals else 1) * 4e-7
        raise ValueError(
            f"matrix too large for the exact reference: the smallest exact dynamic programme "
            f"has {best.n_states:.3g} states and {best.work:.3g} transitions (≈ {secs / 3600:.2g} "
            f"hours in Python integers; limits {max_states:.3g} states, {MAX_WORK:.3g} "
            "transitions). Use a fast method of jointtrack.permanent, or compress repeated "
            "rows/columns with row_counts/col_counts"
        )
    return min(ok, key=lambda p: (p.work, p.n_states))


class _Space:
    """Mixed-radix state space: index = Σ_g d_g·stride_g, layers of equal Σd."""

    def __init__(self, caps: list[int]):
        self.caps = caps
        radix = [c + 1 for c in caps]
        self.strides = [math.prod(radix[:g]) for g in range(len(caps))]
        N = math.prod(radix)
        self.N = N
        idx = np.arange(N, dtype=np.int64)
        sums = np.zeros(N, dtype=np.int64)
        for g, c in enumerate(caps):
            sums += (idx // self.strides[g]) % (c + 1)
        order = np.argsort(sums, kind="stable")
        bounds = np.concatenate(([0], np.cumsum(np.bincount(sums, minlength=sum(caps) + 1))))
        self.layers = [order[bounds[k] : bounds[k + 1]] for k in range(sum(caps) + 1)]
        # position of each state inside its layer (for window snapshots)
        self.pos = np.empty(N, dtype=np.int64)
        for lay in self.layers:
            self.pos[lay] = np.arange(lay.size)
        self._cache: dict[tuple[int, int], tuple] = {}
        self._cache_budget = 4_000_000

    def moves(self, sig: int, g: int):
        """States d in layer σ with d_g < c_g, their successors d + e_g, and (c_g − d_g)."""
        key = (sig, g)
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        lay = self.layers[sig]
        c = self.caps[g]
        digit = (lay // self.strides[g]) % (c + 1)
        ok = digit < c
        src = lay[ok]
        dst = src + self.strides[g]
        mult = None if c == 1 else np.array([int(v) for v in (c - digit[ok])], dtype=object)
        out = (src, dst, mult)
        if self._cache_budget >= src.size:
            self._cache_budget -= src.size
            self._cache[key] = out
        return out


# --------------------------------------------------------------------------- DP passes


def _items(plan: _Plan, M: list[list[int]]) -> tuple[list[list[int]], list[int]]:
    """Weight vectors per item (over the state groups) and the first item of each group."""
    weights, firsts = [], []
    for p, count in enumerate(plan.item_counts):
        w = M[p] if plan.items_from_rows else [M[q][p] for q in range(len(M))]
        firsts.append(len(weights))
        weights.extend([w] * count)
    return weights, firsts


def _step(f: np.ndarray, space: _Space, sig: int, w: list[int], pull: bool = False) -> None:
    """One item with group weights w between layers σ and σ+1 of f (in place).

    Forward: push layer σ into layer σ+1. ``pull``: the adjoint (backward)
    step, pulling layer σ+1 into layer σ.
    """
    for g, wg in enumerate(w):
        if wg == 0:
            continue
        src, dst, mult = space.moves(sig, g)
        if src.size == 0:
            continue
        if pull:
            src, dst = dst, src
        vals = f[src] * wg
        if mult is not None:
            vals *= mult
        f[dst] += vals


def _forward(plan: _Plan, space: _Space, weights, on_item=None) -> int:
    """Exact Per(M) of the expanded integer matrix; calls on_item(i, f) before item i."""
    f = np.zeros(space.N, dtype=object)
    f[0] = 1
    for i, w in enumerate(weights):
        if on_item is not None:
            on_item(i, f)
        layers = plan.source_layers(i)
        for sig in reversed(layers):  # descending: the in-place update keeps the skip term
            _step(f, space, sig, w)
        lo_next = plan.window(i + 1)[0]
        for sig in layers:  # free layers that can no longer complete
            if sig < lo_next:
                f[space.layers[sig]] = 0
    if plan.skip:  # every group must end full
        return int(f[space.N - 1])
    return int(f[space.layers[plan.L]].sum())  # every item assigned (square: the full state)


def _backward(plan: _Plan, space: _Space, weights, wanted: set[int]):
    """B_{i+1} for each wanted item i: completion weights of the items after i.

    Returns a function b(i, states) giving B_{i+1} at the given states (object array).
    """
    b = np.zeros(space.N, dtype=object)
    b[space.N - 1 if plan.skip else space.layers[plan.L]] = 1
    snaps: dict[int, dict[int, np.ndarray]] = {}
    for i in range(plan.L - 1, -1, -1):
        if i in wanted:
            if plan.skip:  # layers overlap in time: keep a copy of the window of B_{i+1}
                lo, hi = plan.window(i + 1)
                snaps[i] = {sig: b[space.layers[sig]].copy() for sig in range(lo, hi + 1)}
        for sig in plan.source_layers(i):  # ascending: pulls read B_{i+1} of layer σ+1
            _step(b, space, sig, weights[i], pull=True)

    def lookup(i: int, states: np.ndarray, sig: int) -> np.ndarray:
        if plan.skip:
            return snaps[i][sig][space.pos[states]]
        return b[states]  # no skipping: layer σ+1 only ever holds B_{i+1}

    return lookup


def _exact_setup(A, row_counts, col_counts):
    A, rows, cols = check_problem(A, row_counts, col_counts)
    n, m = int(rows.sum()), int(cols.sum())
    M, r, s = _integerise(A, square=(n == m))
    exp2 = sum(int(c) * e for c, e in zip(rows, r, strict=True))
    exp2 += sum(int(c) * e for c, e in zip(cols, s, strict=True))
    return A, rows, cols, M, exp2


def _exact_permanent(A, row_counts, col_counts) -> tuple[int, int]:
    """(N, E) with Per = N·2^E exactly."""
    A, rows, cols, M, exp2 = _exact_setup(A, row_counts, col_counts)
    if rows.sum() == 0:
        return 1, 0
    if any(not any(row) for row in M):
        return 0, 0
    plan = _choose_plan(rows, cols, marginals=False)
    space = _Space(plan.caps)
    weights, _ = _items(plan, M)
    return _forward(plan, space, weights), exp2


def _to_float(N: int, E: int) -> float:
    """Correctly rounded N·2^E (inf on overflow, 0.0 or subnormal on underflow)."""
    if N == 0:
        return 0.0
    try:
        return float(N << E) if E >= 0 else N / (1 << -E)
    except OverflowError:
        return math.inf


def _log(N: int, E: int) -> float:
    """log(N·2^E) for a positive integer N, to about one unit in the last place."""
    if N == 0:
        return -math.inf
    shift = max(N.bit_length() - 64, 0)
    top = N >> shift  # relative truncation error < 2^-63
    k = E + shift + top.bit_length() - 1  # N·2^E ≈ f·2^k with f = top/2^(bits-1) ∈ [1, 2)
    f = top / (1 << (top.bit_length() - 1))
    if f > math.sqrt(2.0):
        f /= 2.0
        k += 1
    return math.fsum((k * _LN2_HI, k * _LN2_LO, math.log(f)))


# --------------------------------------------------------------------------- public


def reference_permanent(A, row_counts=None, col_counts=None) -> float:
    r"""Exact permanent of a non-negative matrix, correctly rounded to float64.

    .. math:: \operatorname{Per}(A) = \sum_{\sigma} \prod_{t} A[t, \sigma(t)]

    over injective σ: rows → columns (n ≤ m; Schaub eq. 32). The sum is done in
    exact rational arithmetic (see the module docstring), so the result is the
    float nearest to the true value: 0.0 only if the exact permanent is 0, a
    subnormal or 0.0 if it underflows, ``inf`` if it overflows. Use
    :func:`reference_log_permanent` when the value may leave the float64 range.

    Parameters
    ----------
    A : (n, m) array_like, non-negative, n ≤ m
        The matrix, or the compressed matrix of distinct rows × distinct columns
        when ``row_counts``/``col_counts`` are given.
    row_counts, col_counts : 1-D int array_like, optional
        Group sizes of a compressed matrix (Schaub §3-A): row q of A stands for
        ``row_counts[q]`` identical rows, column j for ``col_counts[j]`` columns.

    Raises
    ------
    ValueError
        on bad input, or if the exact computation would take hours.
    """
    N, E = _exact_permanent(A, row_counts, col_counts)
    return _to_float(N, E)


def reference_log_permanent(A, row_counts=None, col_counts=None) -> float:
    r"""Natural log of the exact permanent; ``-inf`` exactly when Per(A) = 0.

    Per(A) = N·2^E with an exact integer N; the log is assembled as
    log f + k·ln 2 with N·2^E = f·2^k, f ∈ [1/√2, √2], k·ln 2 summed from a
    two-part ln 2 by :func:`math.fsum`, so the result is accurate to about one
    ulp even when Per(A) ≈ 10^-5000 (far outside float64). Same parameters as
    :func:`reference_permanent`.
    """
    N, E = _exact_permanent(A, row_counts, col_counts)
    return _log(N, E)


def reference_marginals(A, row_counts=None, col_counts=None) -> np.ndarray:
    r"""Exact assignment marginals, each correctly rounded to float64.

    .. math:: P[t, i] = \frac{A[t, i]\,\operatorname{Per}(A_{\hat t \hat i})}
                             {\operatorname{Per}(A)}

    (Schaub: P = M ∘ Per(minors)/Per(M)). Row t of P sums to 1 and, for square
    A, so does every column. For compressed input (``row_counts``/``col_counts``)
    P has the compressed shape and P[q, j] is the probability for any *one*
    member of row group q and any *one* member of column group j, so
    ``(P * col_counts).sum(axis=1) == 1``.

    Computed by an exact forward–backward pass of the cancellation-free
    dynamic programme in Python integers; the single rounding is the division.

    Raises
    ------
    jointtrack.errors.InfeasibleAssignmentError
        if Per(A) = 0 (no assignment with positive weight; P would be 0/0).
    ValueError
        on bad input, or if the exact computation would take hours.
    """
    A, rows, cols, M, _ = _exact_setup(A, row_counts, col_counts)
    g, h = A.shape
    if rows.sum() == 0:
        return np.zeros((g, h))
    if any(not any(row) for row in M):
        raise InfeasibleAssignmentError(
            "the permanent is 0 (a row is all zeros): no assignment has positive weight, "
            "so the marginals are undefined"
        )
    plan = _choose_plan(rows, cols, marginals=True)
    space = _Space(plan.caps)
    weights, firsts = _items(plan, M)
    wanted = set(firsts)
    lookup = _backward(plan, space, weights, wanted)
    nums: dict[int, list[int]] = {}

    def contract(i: int, f: np.ndarray) -> None:
        if i not in wanted:
            return
        out = []
        for grp, wg in enumerate(weights[i]):
            total = 0
            if wg:
                for sig in plan.source_layers(i):
                    src, dst, mult = space.moves(sig, grp)
                    if src.size == 0:
                        continue
                    prod = f[src] * lookup(i, dst, sig + 1)
                    if mult is not None:
                        prod *= mult
                    total += int(prod.sum())
            out.append(total * wg)
        nums[i] = out

    per = _forward(plan, space, weights, on_item=contract)
    if per == 0:
        raise InfeasibleAssignmentError(
            "the permanent is 0: no assignment has positive weight (e.g. more rows than "
            "columns they can use), so the marginals are undefined"
        )
    P = np.zeros((g, h))
    for p, i in enumerate(firsts):
        for grp, num in enumerate(nums[i]):
            q, j = (p, grp) if plan.items_from_rows else (grp, p)
            P[q, j] = float(Fraction(num, plan.caps[grp] * per))
    return P
