"""Property tests of the assignment-sum core against exact rational brute force.

Every matrix entry is drawn by hypothesis itself (no seeded random generator
inside the strategy), so a failure shrinks to a minimal matrix. Entries mix
zeros, arbitrary floats from the subnormal range up to 1e300 and powers of ten
spread over the whole exponent range; null weights are None, zeros, subnormal,
in [1e-300, 1], ones, or a per-row mixture.

Tolerances (the core's documented accuracy is (rows + columns)·2⁻⁵³):

* ``log Z``: ``|got − true| ≤ 1e-12 · max(1, |true|)`` — a relative error of
  1e-12, read as an absolute one when |log Z| < 1 (a relative error of a log
  near 0 means nothing); exactly ``-inf`` when Z = 0;
* every marginal: absolute error ≤ 1e-12; rows sum to 1 within 1e-12;
* never NaN.
"""

from __future__ import annotations

import math
import os
import warnings
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import HealthCheck, given, note, settings
from hypothesis import strategies as st

from brute import brute_assignment, brute_grouped, expand, log_fraction
from jointtrack.assignment import assignment_sum
from jointtrack.association import exact_jpda
from jointtrack.errors import ExactLimitError, InfeasibleAssignmentError
from jointtrack.permanent import assignment_marginals, log_permanent, permanent

TOL_LOG = 1e-12
TOL_P = 1e-12
TOL_GLYNN = 1e-10
EXACT = ("frontier", "groups", "auto")
PERMANENT_EXACT = ("dp", "multiset", "auto", "reference")
SMALLEST = 2.0**-1074  # smallest subnormal: one unit of absolute error for a subnormal value

#: JT_ASSIGNMENT_EXAMPLES=2000 for a long bug hunt; the default keeps the file well under 60 s
SETTINGS = settings(
    max_examples=int(os.environ.get("JT_ASSIGNMENT_EXAMPLES", "60")),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

# --------------------------------------------------------------------------- strategies

#: arbitrary floats from the subnormal range to 1e300 (0.0 first: shrinks there)
FLOAT_ENTRY = st.one_of(
    st.just(0.0), st.floats(min_value=1e-320, max_value=1e300, allow_subnormal=True)
)
#: powers of ten over the whole exponent range (10.0**-320 is subnormal)
WIDE_ENTRY = st.integers(-320, 300).map(lambda e: 10.0**e)
#: small repeated values so that rows/columns repeat (the "auto" group path)
TIE_ENTRY = st.sampled_from([1.0, 2.0])
ENTRY = st.one_of(FLOAT_ENTRY, WIDE_ENTRY, TIE_ENTRY)

NULL_VALUES = {
    "zeros": st.just(0.0),
    "subnormal": st.floats(
        min_value=5e-324,
        max_value=2.2250738585072014e-308,
        exclude_max=True,
        allow_subnormal=True,
    ),
    "range": st.floats(min_value=1e-300, max_value=1.0),
    "ones": st.just(1.0),
}


@st.composite
def nulls(draw, n):
    """None, a scalar, or a length-n vector of null weights of one kind (or mixed)."""
    kind = draw(st.sampled_from(["none", "zeros", "subnormal", "range", "ones", "mixed"]))
    if kind == "none":
        return None
    if kind == "mixed":
        values = draw(st.lists(st.one_of(*NULL_VALUES.values()), min_size=n, max_size=n))
        return np.array(values, dtype=float)
    if draw(st.booleans()):
        return float(draw(NULL_VALUES[kind]))
    return np.array(draw(st.lists(NULL_VALUES[kind], min_size=n, max_size=n)), dtype=float)


def matrix(draw, R, C, entry=ENTRY):
    rows = draw(st.lists(st.lists(entry, min_size=C, max_size=C), min_size=R, max_size=R))
    return np.array(rows, dtype=float).reshape(R, C)


@st.composite
def plain_problems(draw, max_r=4, max_c=5, with_null=True, square=False, r_le_c=False):
    R = draw(st.integers(1, max_r))
    if square:
        C = R
    elif r_le_c:
        C = draw(st.integers(R, max_c))
    else:
        C = draw(st.integers(1, max_c))
    W = matrix(draw, R, C)
    null = draw(nulls(R)) if with_null else None
    return W, null


@st.composite
def counts(draw, n, budget, max_each=4):
    """n group sizes ≥ 1 with sum ≤ budget (n ≤ budget)."""
    out = []
    for i in range(n):
        left = budget - sum(out) - (n - i - 1)  # keep 1 for every later group
        out.append(draw(st.integers(1, min(max_each, left))))
    return np.array(out, dtype=np.int64)


@st.composite
def compressed_problems(draw, max_expanded=8, with_null=True):
    R0 = draw(st.integers(1, 4))
    C0 = draw(st.integers(1, 5))
    rows = draw(counts(R0, max_expanded))
    cols = draw(counts(C0, max_expanded))
    W = matrix(draw, R0, C0)
    null = draw(nulls(R0)) if with_null else None
    return W, null, rows, cols


# --------------------------------------------------------------------------- reference + checks

_CACHE: dict = {}


def truth(W, null, rows=None, cols=None):
    """(Z, P, Pnull) exactly; cached so the parametrised tests enumerate once."""
    key = (
        W.shape,
        W.tobytes(),
        None if null is None else np.asarray(null, float).tobytes(),
        None if rows is None else tuple(int(x) for x in rows),
        None if cols is None else tuple(int(x) for x in cols),
    )
    if key not in _CACHE:
        if len(_CACHE) > 5000:
            _CACHE.clear()
        if rows is None and cols is None:
            _CACHE[key] = brute_assignment(W, null)
        else:
            _CACHE[key] = brute_grouped(W, null, rows, cols)
    return _CACHE[key]


def fl(x: Fraction) -> float:
    return float(x)


def check_log(got: float, Z: Fraction, what: str = "log_normalizer") -> None:
    assert not math.isnan(got), f"{what} is NaN"
    if Z == 0:
        assert got == -math.inf, f"{what}: Z = 0 exactly but got {got}"
        return
    true = log_fraction(Z)
    err = abs(got - true)
    assert err <= TOL_LOG * max(1.0, abs(true)), (
        f"{what}: got {got!r}, true {true!r} (error {err:.3g})"
    )


def check_marginals(P, pnull, Pt, Pnt, cols) -> None:
    Pt = np.array([[fl(x) for x in row] for row in Pt])
    Pnt = np.array([fl(x) for x in Pnt])
    assert P.shape == Pt.shape, (P.shape, Pt.shape)
    assert pnull.shape == Pnt.shape, (pnull.shape, Pnt.shape)
    assert not np.isnan(P).any(), f"NaN in P:\n{P}"
    assert not np.isnan(pnull).any(), f"NaN in null: {pnull}"
    errP = np.abs(P - Pt).max()
    errn = np.abs(pnull - Pnt).max()
    assert errP <= TOL_P, f"P error {errP:.3g}:\ngot\n{P!r}\ntrue\n{Pt!r}"
    assert errn <= TOL_P, f"null error {errn:.3g}: got {pnull!r}, true {Pnt!r}"
    rowsum = pnull + P @ np.asarray(cols, float)
    assert np.abs(rowsum - 1.0).max() <= TOL_P, f"rows do not sum to 1: {rowsum!r}"
    assert (P >= 0).all() and (P <= 1).all() and (pnull >= 0).all() and (pnull <= 1).all()


def check_core(W, null, method, marginals, rows=None, cols=None):
    """Run assignment_sum and compare with the exact truth; returns the result (or None)."""
    Z, Pt, Pnt = truth(W, null, rows, cols)
    note(f"Z = {float(Z) if Z < 2**1000 else 'huge'}; log Z = {log_fraction(Z)}")
    kwargs = dict(row_counts=rows, col_counts=cols, marginals=marginals, method=method)
    if Z == 0 and marginals:
        with pytest.raises(InfeasibleAssignmentError):
            assignment_sum(W, null, **kwargs)
        return None
    res = assignment_sum(W, null, **kwargs)
    note(f"method ran: {res.method}; log Z = {res.log_normalizer!r}")
    check_log(res.log_normalizer, Z)
    if not marginals:
        assert res.P is None and res.null is None
        return res
    c = np.ones(W.shape[1]) if cols is None else cols
    check_marginals(res.P, res.null, Pt, Pnt, c)
    beta = res.beta
    assert beta.shape == (W.shape[0], W.shape[1] + 1)
    assert np.array_equal(beta[:, 0], res.null) and np.array_equal(beta[:, 1:], res.P)
    return res


def true_value_or_none(Z: Fraction):
    """float(Z) if it is a finite non-zero float64 after rounding (or Z == 0), else None."""
    if Z == 0:
        return 0.0
    try:
        f = float(Z)
    except OverflowError:
        return None
    if f == 0.0 or math.isinf(f):
        return None
    return f


def check_value(got: float, Z: Fraction) -> None:
    f = true_value_or_none(Z)
    assert f is not None
    if f == 0.0:
        assert got == 0.0
        return
    assert abs(got - f) <= TOL_LOG * abs(f) + SMALLEST, f"value: got {got!r}, true {f!r}"


# --------------------------------------------------------------------------- plain input


@pytest.mark.parametrize("marginals", [True, False], ids=["marginals", "value"])
@pytest.mark.parametrize("method", EXACT)
@SETTINGS
@given(problem=plain_problems())
def test_plain_matches_brute(problem, method, marginals):
    W, null = problem
    check_core(W, null, method, marginals)


@pytest.mark.parametrize("method", EXACT)
@SETTINGS
@given(problem=plain_problems(max_r=3, max_c=4))
def test_plain_scale_invariance(problem, method):
    """Scaling a row by 2^k multiplies Z by 2^k (only when the null is scaled too)."""
    W, null = problem
    nul = np.zeros(W.shape[0]) if null is None else np.broadcast_to(null, W.shape[:1]).copy()
    Z = truth(W, nul)[0]
    if Z == 0:
        return
    k = 40
    W2, n2 = W.copy(), nul.copy()
    with np.errstate(over="ignore"):
        W2[0] *= 2.0**k
        n2[0] *= 2.0**k
    if not (np.isfinite(W2).all() and np.isfinite(n2).all()):
        return
    a = assignment_sum(W, nul, method=method, marginals=False).log_normalizer
    b = assignment_sum(W2, n2, method=method, marginals=False).log_normalizer
    assert abs((b - a) - k * math.log(2.0)) <= 2 * TOL_LOG * max(1.0, abs(a), abs(b))


# --------------------------------------------------------------------------- Glynn / Ryser


@pytest.mark.parametrize("method", ["glynn", "ryser"])
@SETTINGS
@given(problem=plain_problems(with_null=False, r_le_c=True))
def test_inclusion_exclusion_value(problem, method):
    """Glynn/Ryser (value only, null=None): accurate to 1e-10 or a RuntimeWarning says not."""
    W, _ = problem
    Z = truth(W, None)[0]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = assignment_sum(W, None, marginals=False, method=method)
    warned = any(issubclass(w.category, RuntimeWarning) for w in caught)
    lz = res.log_normalizer
    assert not math.isnan(lz)
    if Z == 0:
        assert lz == -math.inf, f"Per = 0 but {method} gave log {lz!r} (warned={warned})"
        return
    true = log_fraction(Z)
    err = abs(lz - true)
    assert warned or err <= TOL_GLYNN * max(1.0, abs(true)), (
        f"{method}: log {lz!r}, true {true!r}, error {err:.3g}, no warning"
    )


@pytest.mark.parametrize("method", ["glynn", "ryser"])
def test_inclusion_exclusion_rejects_marginals_and_null(method):
    W = np.array([[1.0, 2.0], [3.0, 4.0]])
    with pytest.raises(ValueError, match=method):
        assignment_sum(W, None, marginals=True, method=method)
    with pytest.raises(ValueError, match=method):
        assignment_sum(W, [0.5, 0.5], marginals=False, method=method)


# --------------------------------------------------------------------------- compressed input


@SETTINGS
@given(problem=compressed_problems(max_expanded=5))
def test_brute_grouped_equals_brute_expansion(problem):
    """The count-matrix reference equals enumeration of the expanded matchings."""
    W, null, rows, cols = problem
    a = brute_grouped(W, null, rows, cols)
    b = brute_assignment(W, null, rows, cols)
    assert a[0] == b[0]
    assert a[1] == b[1] and a[2] == b[2]


@pytest.mark.parametrize("marginals", [True, False], ids=["marginals", "value"])
@pytest.mark.parametrize("method", EXACT)
@SETTINGS
@given(problem=compressed_problems())
def test_compressed_matches_brute_and_expansion(problem, method, marginals):
    W, null, rows, cols = problem
    res = check_core(W, null, method, marginals, rows, cols)
    # the compressed answer equals that of the expanded matrix, member by member
    Wx = expand(W, rows, cols)
    nx = None if null is None else np.repeat(np.broadcast_to(null, (W.shape[0],)), rows)
    Z = truth(W, null, rows, cols)[0]
    if Z == 0 and marginals:
        with pytest.raises(InfeasibleAssignmentError):
            assignment_sum(Wx, nx, marginals=True, method="frontier")
        return
    ex = assignment_sum(Wx, nx, marginals=marginals, method="frontier")
    assert (
        abs(ex.log_normalizer - res.log_normalizer)
        <= 2 * TOL_LOG * max(1.0, abs(res.log_normalizer))
        or ex.log_normalizer == res.log_normalizer
    )
    if marginals:
        assert np.abs(ex.P - expand(res.P, rows, cols)).max() <= 2 * TOL_P
        assert np.abs(ex.null - np.repeat(res.null, rows)).max() <= 2 * TOL_P


@pytest.mark.parametrize("method", EXACT)
@SETTINGS
@given(problem=plain_problems(max_r=3, max_c=4))
def test_unit_counts_equal_plain(problem, method):
    """Explicit all-one group counts change nothing."""
    W, null = problem
    R, C = W.shape
    Z = truth(W, null)[0]
    kw = dict(method=method, marginals=Z != 0)
    a = assignment_sum(W, null, **kw)
    b = assignment_sum(W, null, row_counts=[1] * R, col_counts=np.ones(C, int), **kw)
    check_log(b.log_normalizer, Z)
    if Z != 0:
        assert np.abs(a.P - b.P).max() <= 2 * TOL_P
        assert np.abs(a.null - b.null).max() <= 2 * TOL_P


def test_empty_problem():
    res = assignment_sum(np.zeros((0, 3)))
    assert res.log_normalizer == 0.0
    assert res.P.shape == (0, 3) and res.null.shape == (0,)


# --------------------------------------------------------------------------- the faces


def in_range(Z: Fraction) -> bool:
    return true_value_or_none(Z) is not None


@pytest.mark.parametrize("method", PERMANENT_EXACT)
@SETTINGS
@given(problem=plain_problems(with_null=False, r_le_c=True))
def test_permanent_value_or_overflow(problem, method):
    """permanent() is the true value, and raises OverflowError exactly when it leaves float64."""
    W, _ = problem
    Z = truth(W, None)[0]
    check_log(log_permanent(W, method), Z, f"log_permanent({method})")
    if in_range(Z):
        check_value(permanent(W, method), Z)
    else:
        with pytest.raises(OverflowError, match="log_permanent"):
            permanent(W, method)


@SETTINGS
@given(problem=plain_problems(with_null=False, r_le_c=True))
def test_permanent_is_jpda_with_zero_miss(problem):
    """Per(A) = exp(JPDA log normaliser with miss 0); marginals = JPDA beta[:, 1:]."""
    A, _ = problem
    Z, Pt, Pnt = truth(A, None)
    miss = np.zeros(A.shape[0])
    lp = log_permanent(A)
    check_log(lp, Z, "log_permanent")
    if Z == 0:
        with pytest.raises(InfeasibleAssignmentError):
            exact_jpda(A, miss)
        with pytest.raises(InfeasibleAssignmentError):
            assignment_marginals(A)
        assert permanent(A) == 0.0
        return
    jp = exact_jpda(A, miss)
    check_log(jp.log_normalizer, Z, "exact_jpda.log_normalizer")
    assert abs(lp - jp.log_normalizer) <= 2 * TOL_LOG * max(1.0, abs(lp))
    if in_range(Z):
        value = permanent(A)
        via_jpda = math.exp(jp.log_normalizer)
        assert abs(value - via_jpda) <= 2 * TOL_LOG * max(1.0, abs(lp)) * value + SMALLEST
    P = assignment_marginals(A)
    no_miss = jp.beta[:, 0]
    assert np.array_equal(no_miss, np.zeros(A.shape[0])) or np.abs(no_miss).max() <= TOL_P
    assert np.abs(P - jp.beta[:, 1:]).max() <= 2 * TOL_P
    check_marginals(P, np.zeros(A.shape[0]), Pt, Pnt, np.ones(A.shape[1]))


@SETTINGS
@given(problem=compressed_problems(with_null=False))
def test_permanent_faces_compressed(problem):
    W, _, rows, cols = problem
    if rows.sum() > cols.sum():
        with pytest.raises(ValueError, match="more rows than columns"):
            log_permanent(W, row_counts=rows, col_counts=cols)
        return
    Z, Pt, Pnt = truth(W, None, rows, cols)
    for method in ("dp", "multiset", "auto"):
        check_log(log_permanent(W, method, row_counts=rows, col_counts=cols), Z, method)
    if Z == 0:
        with pytest.raises(InfeasibleAssignmentError):
            assignment_marginals(W, rows, cols)
        return
    P = assignment_marginals(W, rows, cols)
    check_marginals(P, np.zeros(W.shape[0]), Pt, Pnt, cols)


# --------------------------------------------------------------------------- closed forms


def elementary_symmetric(values, k) -> Fraction:
    """e_k of Fractions (e_0 = 1), by the usual O(n k) recursion."""
    e = [Fraction(1)] + [Fraction(0)] * k
    for v in values:
        for j in range(k, 0, -1):
            e[j] += e[j - 1] * v
    return e[k]


@st.composite
def rank_one(draw):
    """A = outer(a, b) exactly: a_t powers of two, b_i in [1e-100, 1e100] (no rounding)."""
    n = draw(st.integers(1, 4))
    m = draw(st.integers(n, 5))
    a = [2.0 ** draw(st.integers(-600, 600)) for _ in range(n)]
    b = draw(
        st.lists(
            st.one_of(
                st.floats(min_value=1e-100, max_value=1e100),
                st.integers(-100, 100).map(lambda e: 10.0**e),
            ),
            min_size=m,
            max_size=m,
        )
    )
    return np.array(a), np.array(b)


@SETTINGS
@given(ab=rank_one())
def test_rank_one_closed_form(ab):
    """Per(outer(a, b)) = Π a · n! · e_n(b); P[t, i] = b_i e_{n-1}(b without i) / (n e_n(b)).

    (b_i e_{n-1}(b without i) / e_n(b) alone is the probability that column i is
    used by *some* row: it sums to n over i. One given row takes column i with
    1/n of it, which is 1/n for every entry of a square rank-one matrix.)
    """
    a, b = ab
    n, m = a.size, b.size
    A = np.outer(a, b)
    Fa = [Fraction(float(x)) for x in a]
    Fb = [Fraction(float(x)) for x in b]
    assert all(Fraction(float(A[t, i])) == Fa[t] * Fb[i] for t in range(n) for i in range(m))
    prod_a = Fraction(1)
    for x in Fa:
        prod_a *= x
    en = elementary_symmetric(Fb, n)
    Z = prod_a * math.factorial(n) * en
    for method in ("dp", "multiset", "auto"):
        check_log(log_permanent(A, method), Z, f"log_permanent({method})")
    P = assignment_marginals(A)
    if n == m:
        expected = np.full((n, m), 1.0 / n)
    else:
        row = [
            float(Fb[i] * elementary_symmetric(Fb[:i] + Fb[i + 1 :], n - 1) / (n * en))
            for i in range(m)
        ]
        expected = np.tile(row, (n, 1))
    err = np.abs(P - expected).max()
    assert err <= TOL_P, f"rank-one marginals: error {err:.3g}\n{P!r}\n{expected!r}"
    res = assignment_sum(A)
    assert np.abs(res.P - expected).max() <= TOL_P


def fibonacci(k: int) -> int:
    a, b = 0, 1
    for _ in range(k):
        a, b = b, a + b
    return a


@pytest.mark.parametrize("method", ["dp", "auto"])
@pytest.mark.parametrize("n", [40, 100])
def test_tridiagonal_permanent_is_fibonacci(n, method):
    A = np.eye(n) + np.eye(n, k=1) + np.eye(n, k=-1)
    true = log_fraction(Fraction(fibonacci(n + 1)))
    got = log_permanent(A, method)
    assert abs(got - true) <= 1e-13 * abs(true), (got, true)
    # the work, not the clock: the band keeps the DP's frontier at a few subsets, so the
    # core solves it within 2^3 states (an unbanded DP over n columns would be refused)
    banded = assignment_sum(A, np.zeros(n), marginals=False, max_bits=3)
    assert abs(banded.log_normalizer - true) <= 1e-13 * abs(true)
    value = permanent(A, method)
    assert abs(value - fibonacci(n + 1)) <= 1e-13 * fibonacci(n + 1)


def test_small_fibonacci_values():
    for n in range(1, 12):
        A = np.eye(n) + np.eye(n, k=1) + np.eye(n, k=-1)
        assert permanent(A) == fibonacci(n + 1)


# --------------------------------------------------------------------------- argument checks

FACES = {
    "permanent": lambda A, **kw: permanent(A, **kw),
    "log_permanent": lambda A, **kw: log_permanent(A, **kw),
    "assignment_marginals": lambda A, **kw: assignment_marginals(A, **kw),
}


@pytest.mark.parametrize("face", sorted(FACES))
@pytest.mark.parametrize(
    "A",
    [
        np.array([[1.0 + 1.0j, 2.0]]),
        [[1 + 0j, 2.0]],
        np.array([[True, False], [False, True]]),
        [[True, True]],
        [[True, 2.0]],
        [[10**400]],
        [[1.0, 10**400]],
        [[-(10**400), 1.0]],
    ],
    ids=[
        "complex-array",
        "complex-list",
        "bool-array",
        "bool-list",
        "bool-mixed-list",
        "int-1e400",
        "mixed-int-1e400",
        "neg-int-1e400",
    ],
)
def test_bad_matrix_is_named_value_error(face, A):
    with pytest.raises(ValueError, match=r"\bA\b"):
        FACES[face](A)


@pytest.mark.parametrize("face", sorted(FACES))
@pytest.mark.parametrize(
    "kw, name",
    [
        (dict(row_counts=[True], col_counts=[2, 1]), "row_counts"),
        (dict(row_counts=np.array([True]), col_counts=[2, 1]), "row_counts"),
        (dict(row_counts=[1], col_counts=[2.5, 1]), "col_counts"),
        (dict(row_counts=[2.5], col_counts=[3, 1]), "row_counts"),
        (dict(row_counts=[1], col_counts=[10**20, 1]), "col_counts"),
        (dict(row_counts=[10**20], col_counts=[1, 1]), "row_counts"),
        (dict(row_counts=[1], col_counts=[np.int64(2), True]), "col_counts"),
    ],
    ids=["bool-list", "bool-array", "col-2.5", "row-2.5", "col-1e20", "row-1e20", "mixed-bool"],
)
def test_bad_counts_are_named_value_errors(face, kw, name):
    A = [[1.0, 2.0]]
    with pytest.raises(ValueError, match=name):
        FACES[face](A, **kw)


@pytest.mark.parametrize("fn", [permanent, log_permanent])
@pytest.mark.parametrize("method", ["DP", "glyn", "exact", "", None, "frontier"])
def test_method_typo_is_named_value_error(fn, method):
    with pytest.raises(ValueError, match="method"):
        fn([[1.0, 2.0], [3.0, 4.0]], method)


@pytest.mark.parametrize("method", ["dp", "Frontier", "glyn", ""])
def test_core_method_typo_is_named_value_error(method):
    with pytest.raises(ValueError, match="method"):
        assignment_sum([[1.0]], method=method)


@pytest.mark.parametrize("method", ["auto", "glynn", "ryser", "frontier"])
def test_dense_problem_past_max_bits_is_refused_not_run(method):
    # a dense 40×40 needs 2^39 Glynn terms or 2^40 DP states; under max_bits = 20 every
    # method refuses at once (before, "auto" and "glynn" ran Glynn's formula for hours)
    W = np.random.default_rng(0).uniform(0.5, 2.0, (40, 40))
    with pytest.raises(ExactLimitError, match="max_bits = 20"):
        assignment_sum(W, marginals=False, method=method, max_bits=20)


def test_glynn_within_max_bits_still_serves_auto():
    W = np.random.default_rng(1).uniform(0.5, 2.0, (16, 16))
    assert assignment_sum(W, marginals=False, max_bits=15).method == "glynn"  # 2^15 terms
    with pytest.raises(ExactLimitError):  # neither 2^15 Glynn terms nor 2^16 DP states fit
        assignment_sum(W, marginals=False, max_bits=14)
