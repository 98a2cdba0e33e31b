"""Identity deconfliction (Schaub eq. 31/80) against exact rational enumeration."""

from __future__ import annotations

import itertools
import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from brute import log_fraction
from jointtrack.errors import InfeasibleAssignmentError
from jointtrack.identity import deconflict
from jointtrack.identity.metrics import (
    aggregate_classes,
    asymptotic_matrix,
    expand_columns,
    kl_rows,
    max_kl,
)

# ------------------------------------------------------------------ exact reference


def brute(entries, b, rows, cols):
    """Exact ``(log Per, P, P_false)`` of M = [A | b·J] by enumerating permutations.

    ``entries[q][c]`` and ``b[q]`` are Fractions (exact powers of two times
    mantissas: far outside the float range when the test wants it).
    """
    R = [q for q in range(len(rows)) for _ in range(rows[q])]
    Cg = [c for c in range(len(cols)) for _ in range(cols[c])]
    n, n_ids = len(R), len(Cg)
    J = n - n_ids
    col_of = Cg + [-1] * J  # −1: a J column
    total = Fraction(0)
    acc = {}
    for perm in itertools.permutations(range(n)):
        w = Fraction(1)
        for r, c in enumerate(perm):
            g = col_of[c]
            w *= entries[R[r]][g] if g >= 0 else b[R[r]]
            if w == 0:
                break
        if w == 0:
            continue
        total += w
        for r, c in enumerate(perm):
            acc[(r, col_of[c])] = acc.get((r, col_of[c]), Fraction(0)) + w
    if total == 0:
        return -math.inf, None, None
    first = np.concatenate([[0], np.cumsum(rows)[:-1]]).astype(int)
    P = np.array(
        [[float(acc.get((r, c), 0) / total) / cols[c] for c in range(len(cols))] for r in first]
    )
    Pf = np.array([float(acc.get((r, -1), 0) / total) for r in first])
    return log_fraction(total), P, Pf


@st.composite
def problems(draw):
    """Compressed M = [A | b·J] with hidden tracks and classes; values drawn, not seeded.

    Entries are m·2^e with m a drawn float in [0, 1] (zeros included) and e an
    integer exponent up to ±15000 (products of hundreds of likelihoods), given as log M — far
    outside the float range — and to the reference as exact Fractions.
    """
    n_obs = draw(st.integers(1, 3))
    hidden = draw(st.integers(0, 2))
    cols = draw(st.lists(st.integers(1, 2), min_size=1, max_size=3))
    rows = [1] * n_obs + ([hidden] if hidden else [])
    n_tracks, n_ids = sum(rows), sum(cols)
    if n_tracks < n_ids:
        rows = rows + [n_ids - n_tracks] if not hidden else rows[:-1] + [hidden + n_ids - n_tracks]
        n_tracks = n_ids
    extra = draw(st.integers(0, max(0, 6 - n_tracks)))
    if extra:
        rows = rows + [extra]
    spread = draw(st.sampled_from([0, 3, 60, 1200, 15000]))  # 15000 bits ≈ 10⁴ nats
    mant = st.one_of(st.just(0.0), st.floats(1e-3, 1.0), st.just(5e-324))
    R, C = len(rows), len(cols)
    m = [[draw(mant) for _ in range(C)] for _ in range(R)]
    e = [[draw(st.integers(-spread, spread)) for _ in range(C)] for _ in range(R)]
    mb = [draw(mant) for _ in range(R)]
    eb = [draw(st.integers(-spread, spread)) for _ in range(R)]
    entries = [[Fraction(m[q][c]) * Fraction(2) ** e[q][c] for c in range(C)] for q in range(R)]
    bF = [Fraction(mb[q]) * Fraction(2) ** eb[q] for q in range(R)]
    with np.errstate(divide="ignore"):
        log_M = np.log(np.array(m)) + np.array(e) * math.log(2)
        log_b = np.log(np.array(mb)) + np.array(eb) * math.log(2)
    return entries, bF, log_M, log_b, np.array(rows), np.array(cols)


@settings(max_examples=150, deadline=None)
@given(problems())
def test_exact_matches_rational_enumeration(case):
    entries, bF, log_M, log_b, rows, cols = case
    n_tracks, n_ids = rows.sum(), cols.sum()
    want_log, P, Pf = brute(entries, bF, rows.tolist(), cols.tolist())
    kw = dict(log_M=log_M, row_counts=rows, col_counts=cols)
    if n_tracks > n_ids:
        kw["log_b"] = log_b
    if P is None:
        with pytest.raises(InfeasibleAssignmentError):
            deconflict(**kw)
        return
    r = deconflict(**kw)
    assert r.log_normalizer == pytest.approx(want_log, rel=1e-12, abs=1e-10)
    # every marginal to ~1e-12 (entries that weigh < 1e-300 of the best flush to 0)
    assert np.abs(r.P - P).max() <= 1e-12
    if n_tracks > n_ids:
        assert np.abs(r.P_false - Pf).max() <= 1e-12
    else:
        assert np.all(r.P_false == 0)
    # left stochastic over the expanded identities (+ no identity), doubly when square
    np.testing.assert_allclose(r.P @ cols + r.P_false, 1.0, atol=1e-12)
    np.testing.assert_allclose(rows @ r.P, 1.0, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.lists(
            st.one_of(st.just(0.0), st.floats(5e-324, 1e300, allow_subnormal=True)),
            min_size=4,
            max_size=4,
        ),
        min_size=4,
        max_size=4,
    )
)
def test_plain_matrix_from_subnormal_to_1e300(rows):
    M = np.array(rows)
    F = [[Fraction(float(x)) for x in row] for row in M]
    want_log, P, _ = brute(F, [Fraction(0)] * 4, [1] * 4, [1] * 4)
    if P is None:
        with pytest.raises(InfeasibleAssignmentError, match="Per\\(M\\) = 0"):
            deconflict(M)
        return
    r = deconflict(M)
    assert np.abs(r.P - P).max() <= 1e-12
    assert r.log_normalizer == pytest.approx(want_log, rel=1e-12, abs=1e-10)


def test_indistinguishable_identities_get_identical_columns():
    rng = np.random.default_rng(1)
    A = rng.random((5, 3))
    M = A[:, [0, 1, 1, 2, 2]]  # identities 1–2 and 3–4 are twins
    P = deconflict(M).P
    assert np.array_equal(P[:, 1], P[:, 2]) or np.abs(P[:, 1] - P[:, 2]).max() < 1e-15
    assert np.abs(P[:, 3] - P[:, 4]).max() < 1e-15
    # the compressed problem gives the same per-member probabilities
    Pc = deconflict(A, col_counts=[1, 2, 2]).P
    np.testing.assert_allclose(Pc, P[:, [0, 1, 3]], atol=1e-14)


def test_hidden_tracks_as_row_group_equal_expanded_rows():
    rng = np.random.default_rng(2)
    A = rng.random((3, 6))
    hidden = np.ones((1, 6))
    r = deconflict(np.vstack([A, hidden]), row_counts=[1, 1, 1, 3])
    full = deconflict(np.vstack([A, np.ones((3, 6))]))
    np.testing.assert_allclose(r.P, full.P[:4], atol=1e-14)


# ------------------------------------------------------------------ zero false alarms


def test_certain_tracks_beyond_identities_are_refused_by_name():
    A = np.ones((4, 2))
    with pytest.raises(InfeasibleAssignmentError, match=r"3 tracks are certain.*0, 1, 3.*only 2"):
        deconflict(A, b=[0.0, 0.0, 0.5, 0.0])


def test_zero_false_alarm_limit_is_the_limit_of_small_b():
    # Appendix B: P at b = 0 equals the limit b → 0⁺ (here b = 1e-200, exact otherwise)
    rng = np.random.default_rng(3)
    A = rng.random((4, 2))
    at_zero = deconflict(A, b=[0.0, 0.0, 0.3, 0.7])
    near = deconflict(log_M=np.log(A), log_b=[-460.0, -460.0, math.log(0.3), math.log(0.7)])
    np.testing.assert_allclose(at_zero.P, near.P, atol=1e-12)
    assert at_zero.P_false[0] == 0.0 and at_zero.P_false[1] == 0.0
    # the two certain tracks hold both identities between them
    np.testing.assert_allclose(at_zero.P[:2].sum(), 2.0, atol=1e-12)


# ------------------------------------------------------------------ baselines


def test_local_is_row_normalised_and_sinkhorn_doubly_stochastic():
    rng = np.random.default_rng(4)
    M = rng.random((6, 6)) ** 4
    loc = deconflict(M, "local")
    np.testing.assert_allclose(loc.P, M / M.sum(axis=1, keepdims=True), rtol=1e-14)
    sk = deconflict(M, "sinkhorn")
    np.testing.assert_allclose(sk.P.sum(axis=0), 1.0, atol=1e-10)
    np.testing.assert_allclose(sk.P.sum(axis=1), 1.0, atol=1e-10)
    # P_DS = D1 M D2: rank-one ratio structure
    ratio = sk.P / M
    np.testing.assert_allclose(ratio / ratio[:1] / (ratio[:, :1] / ratio[0, 0]), 1.0, rtol=1e-9)


def test_normaliser_bounds_hold():
    rng = np.random.default_rng(5)
    for _ in range(5):
        M = rng.random((7, 7))
        exact = deconflict(M).log_normalizer
        assert deconflict(M, "local").log_normalizer >= exact - 1e-12  # Π row sums
        assert deconflict(M, "maxweight").log_normalizer <= exact + 1e-12
        sk = deconflict(M, "sinkhorn")
        assert sk.log_normalizer <= exact + 1e-9 <= sk.info["log_normalizer_upper"] + 2e-9
        be = deconflict(M, "bethe")
        assert be.log_normalizer <= exact + 1e-9 <= be.info["log_normalizer_upper"] + 2e-9


def test_maxweight_is_the_best_permutation():
    rng = np.random.default_rng(6)
    for _ in range(5):
        M = rng.random((5, 5))
        best = max(itertools.permutations(range(5)), key=lambda p: np.prod(M[range(5), p]))
        r = deconflict(M, "maxweight")
        assert r.P.argmax(axis=1).tolist() == list(best)
        assert r.log_normalizer == pytest.approx(np.log(np.prod(M[range(5), best])), rel=1e-12)


def test_maxweight_with_classes_and_false_tracks():
    A = np.array([[1.0, 1e-3], [1e-3, 1.0], [1e-3, 1e-3]])
    r = deconflict(A, "maxweight", col_counts=[1, 1], b=[1e-6, 1e-6, 1.0])
    assert r.info["assignment"].tolist() == [0, 1, -1]
    assert r.P_false.tolist() == [0.0, 0.0, 1.0]


def test_sampling_marginals_within_their_standard_errors():
    rng = np.random.default_rng(7)
    M = rng.random((8, 8))
    exact = deconflict(M).P
    r = deconflict(M, "sampling", n_samples=20_000, rng=11)
    err = r.info["stderr"]
    assert err.max() < 0.02
    # a 5σ band on every one of the 64 entries
    assert np.all(np.abs(r.P - exact) <= 5 * err + 1e-12)


def test_bethe_marginals_close_to_exact_on_dense_matrices():
    # measured: max |P_Bethe − P| ≤ 0.03 on uniform 8×8 (stated tolerance 0.06)
    rng = np.random.default_rng(8)
    for _ in range(3):
        M = rng.random((8, 8))
        r = deconflict(M, "bethe")
        assert r.converged
        assert np.abs(r.P - deconflict(M).P).max() < 0.06


# ------------------------------------------------------------------ KL metric (58)


def test_kl_against_v_with_classes_and_one_hot():
    classes = np.array([0, 0, 1, 2])
    V = asymptotic_matrix([0, 1, 2, 3], classes)
    assert V.tolist()[0] == [0.5, 0.5, 0.0, 0.0]
    onehot = np.eye(4)
    assert math.isinf(max_kl(V, onehot))  # a one-hot answer never matches a 2-member class
    Va, Pa = aggregate_classes(V, classes), aggregate_classes(onehot, classes)
    assert max_kl(Va, Pa) == 0.0
    wrong = aggregate_classes(np.eye(4)[[2, 1, 0, 3]], classes)
    assert math.isinf(max_kl(Va, wrong))
    P = np.full((4, 4), 0.25)
    np.testing.assert_allclose(kl_rows(V, P)[2], math.log(4))  # V one-hot on identity 2
    np.testing.assert_allclose(kl_rows(V, P)[0], math.log(2))  # V ½, ½ on the twins


def test_expand_columns_and_local_stall_at_ln2():
    # two kinematic twins, the attribute seen only on track 1: local stays 50/50 on
    # track 0 (KL ln 2), the permanent resolves it from track 1's evidence
    M = np.array([[1.0, 1.0, 1e-9], [1.0, 1e-30, 1e-9], [1e-9, 1e-9, 1.0]])
    V = asymptotic_matrix([1, 0, 2], np.arange(3))
    assert max_kl(V, deconflict(M, "local").P) == pytest.approx(math.log(2), abs=1e-8)
    assert max_kl(V, deconflict(M).P) < 1e-8
    P = deconflict(np.ones((3, 2)), col_counts=[1, 2]).P
    assert expand_columns(P, [1, 2]).shape == (3, 3)


# ------------------------------------------------------------------ bad input


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(M=[[1 + 1j, 1.0], [1.0, 1.0]]), "M has complex"),
        (dict(M=[[True, 1.0], [1.0, 1.0]]), "M holds a boolean"),
        (dict(M=[[math.nan, 1.0], [1.0, 1.0]]), "M has a non-finite"),
        (dict(M=[[-1.0, 1.0], [1.0, 1.0]]), "M has a negative"),
        (dict(M=[[10**400, 1], [1, 1]]), "M holds an integer too large"),
        (dict(log_M=[[math.inf, 0.0], [0.0, 0.0]]), "log_M has an entry inf"),
        (dict(log_M=[[math.nan, 0.0], [0.0, 0.0]]), "log_M has an entry nan"),
        (dict(M=[[1.0, 1.0]]), "1 tracks for 2 identities"),
        (dict(M=[[1.0], [1.0]]), "false-alarm products b"),
        (dict(M=[[1.0], [1.0]], b=[1.0]), "b must have one entry per row"),
        (dict(M=[[1.0], [1.0]], b=[1.0, -1.0]), "b\\[1\\] = -1.0 is negative"),
        (dict(M=[[1.0]], row_counts=[0]), "row_counts"),
        (dict(M=[[1.0]], method="hungarian"), "unknown method 'hungarian'"),
        (dict(M=[[1.0]], log_M=[[0.0]]), "exactly one of M"),
        (dict(M=[1.0, 2.0]), "M must be 2-D"),
    ],
)
def test_bad_input_is_named(kwargs, message):
    with pytest.raises(ValueError, match=message):
        deconflict(**kwargs)


def test_exact_has_the_lowest_expected_log_loss_when_truth_follows_the_prior():
    # Bayes optimality (what "exact is never worse" can mean): with the identity
    # assignment drawn from the uniform prior and M the data likelihoods, the exact
    # marginals minimise the expected log loss −log P[t, σ(t)] (a proper scoring
    # rule); local and belief-matrix probabilities lose on average. 400 problems.
    rng = np.random.default_rng(12)
    n, means = 5, np.arange(5) * 1.2
    loss = {"exact": [], "local": [], "sinkhorn": []}
    for _ in range(400):
        sigma = rng.permutation(n)
        y = means[sigma] + rng.standard_normal(n)
        M = np.exp(-0.5 * (y[:, None] - means[None, :]) ** 2)
        for m in loss:
            P = deconflict(M, m).P
            loss[m].append(-np.log(P[np.arange(n), sigma]).mean())
    mean = {m: float(np.mean(v)) for m, v in loss.items()}
    se = {m: float(np.std(np.subtract(v, loss["exact"])) / np.sqrt(400)) for m, v in loss.items()}
    # measured: exact 0.73, sinkhorn 0.81, local 0.94 nats (standard errors of the gaps 0.01)
    assert mean["exact"] < mean["sinkhorn"] - 3 * se["sinkhorn"]
    assert mean["exact"] < mean["local"] - 3 * se["local"]
