"""Murty's k-best ranking (compiled kernel) against exact rational brute force.

Every joint event of a small cluster is enumerated and weighed exactly in
``fractions.Fraction`` (each float is a rational); ``kbest_hypotheses`` must
return the k heaviest, best first, with the right ``exhausted`` flag, for any
k from 1 to two past the number of events, on clusters drawn by hypothesis
with zeros, subnormals and weights up to 1e300. The kernel's input check must
accept and refuse exactly what ``check_cluster`` does, with its messages.
"""

from __future__ import annotations

import itertools
import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from jointtrack.association._validate import check_cluster
from jointtrack.association.kbest import _pairwise_sum, kbest_hypotheses
from jointtrack.errors import InfeasibleAssignmentError

SUBNORMAL = 5e-324

l_entry = st.one_of(
    st.just(0.0),
    st.floats(min_value=SUBNORMAL, max_value=1e300),
    st.sampled_from([SUBNORMAL, 1e-310, 1e-300, 1.0, 2.0, 1e300]),
)
miss_entry = st.one_of(
    st.just(0.0),
    st.floats(min_value=0.0, max_value=1.0),
    st.sampled_from([SUBNORMAL, 1e-300, 0.5, 1.0]),
)


@st.composite
def clusters(draw, l_values=l_entry, miss_values=miss_entry, n_max=4, m_max=4):
    n = draw(st.integers(1, n_max))
    m = draw(st.integers(0, m_max))
    L = np.array(draw(st.lists(l_values, min_size=n * m, max_size=n * m)), float).reshape(n, m)
    miss = np.array(draw(st.lists(miss_values, min_size=n, max_size=n)), float)
    return L, miss


def exact_events(L, miss):
    """{event: exact weight} over every event of positive weight (beta layout)."""
    n, m = L.shape
    ext = [[Fraction(float(miss[i]))] + [Fraction(float(x)) for x in L[i]] for i in range(n)]
    out = {}
    for event in itertools.product(range(m + 1), repeat=n):
        used = [a for a in event if a > 0]
        if len(used) != len(set(used)):
            continue
        w = math.prod(ext[i][a] for i, a in enumerate(event))
        if w > 0:
            out[event] = w
    return out


def log_fraction(w: Fraction) -> float:
    """log w to a few ulp of |log w|: w = r · 2^e exactly with r in (1/2, 2)."""
    e = w.numerator.bit_length() - w.denominator.bit_length()
    r = w / 2**e if e >= 0 else w * 2**-e
    return math.log(float(r)) + e * math.log(2.0)


def log_tolerance(L, miss, event) -> float:
    """Rounding bound of a float64 log weight: n logs (≤ 4 ulp each) and their sum."""
    n = L.shape[0]
    logs = [math.log(miss[i] if a == 0 else L[i, a - 1]) for i, a in enumerate(event)]
    return (4 + n) * 2.3e-16 * (1.0 + sum(abs(x) for x in logs))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(cl=clusters(), data=st.data())
def test_kbest_are_the_k_heaviest_events_exactly(cl, data):
    L, miss = cl
    n = L.shape[0]
    events = exact_events(L, miss)
    k = data.draw(st.integers(1, len(events) + 2), label="k")
    if not events:
        with pytest.raises(InfeasibleAssignmentError):
            kbest_hypotheses(L, miss, k=k)
        return
    hyp = kbest_hypotheses(L, miss, k=k)
    kk = min(k, len(events))
    assert hyp.assignments.shape == (kk, n) and hyp.log_weights.shape == (kk,)
    assert hyp.exhausted == (len(events) < k)
    got = [tuple(int(a) for a in row) for row in hyp.assignments]
    assert len(set(got)) == kk  # distinct events …
    assert all(e in events for e in got)  # … each feasible (positive weight)
    assert np.all(np.diff(hyp.log_weights) <= 0)  # best first
    top = sorted(events.values(), reverse=True)[:kk]
    mine = sorted((events[e] for e in got), reverse=True)
    worst = max(log_tolerance(L, miss, e) for e in events)
    for w_got, w_top in zip(mine, top, strict=True):
        # the k heaviest weights exactly, unless two events are so close that their
        # float64 log weights cannot order them
        assert w_got == w_top or abs(log_fraction(w_got / w_top)) <= 2 * worst
    for e, lw in zip(got, hyp.log_weights, strict=True):
        # each reported log weight is the log of that event's exact weight
        assert abs(lw - log_fraction(events[e])) <= log_tolerance(L, miss, e)


def test_ties_and_exhaustion_on_a_flat_cluster():
    # all 7 events of a 2×2 cluster with every weight 1 tie: each is found once
    hyp = kbest_hypotheses(np.ones((2, 2)), np.ones(2), k=10**18)
    assert hyp.exhausted and len(hyp.log_weights) == 7
    assert set(map(tuple, hyp.assignments.tolist())) == set(
        exact_events(np.ones((2, 2)), np.ones(2))
    )
    np.testing.assert_array_equal(hyp.log_weights, np.zeros(7))
    hyp = kbest_hypotheses(np.ones((2, 2)), np.ones(2), k=7)
    assert not hyp.exhausted and len(hyp.log_weights) == 7


bad_l = st.one_of(l_entry, st.sampled_from([np.nan, np.inf, -np.inf, -1.0, -SUBNORMAL, -0.0]))
bad_miss = st.one_of(miss_entry, st.sampled_from([np.nan, np.inf, -0.5, 1.0000000000000002, 2.0]))


@settings(max_examples=300, deadline=None)
@given(cl=clusters(l_values=bad_l, miss_values=bad_miss))
def test_compiled_check_refuses_what_check_cluster_refuses(cl):
    L, miss = cl
    try:
        check_cluster(L, miss)
    except (ValueError, InfeasibleAssignmentError) as exc:
        with pytest.raises(type(exc)) as got:
            kbest_hypotheses(L, miss, k=3)
        assert str(got.value) == str(exc)
        return
    events = exact_events(L, miss)
    if events:
        assert len(kbest_hypotheses(L, miss, k=3).log_weights) == min(3, len(events))
    else:
        with pytest.raises(InfeasibleAssignmentError):
            kbest_hypotheses(L, miss, k=3)


def test_non_float64_and_non_contiguous_input_give_the_same_events():
    rng = np.random.default_rng(5)
    L = rng.uniform(0, 5, (5, 8))
    L[rng.uniform(size=L.shape) < 0.3] = 0
    miss = rng.uniform(0.1, 0.9, 5)
    ref = kbest_hypotheses(L, miss, k=40)
    for L2, m2 in [
        (L.tolist(), miss.tolist()),
        (np.asfortranarray(L), miss),
        (np.repeat(L, 2, axis=1)[:, ::2], np.repeat(miss, 2)[::2]),  # strided views
        (L.astype(">f8"), miss.astype(">f8")),
    ]:
        hyp = kbest_hypotheses(L2, m2, k=40)
        np.testing.assert_array_equal(hyp.assignments, ref.assignments)
        np.testing.assert_array_equal(hyp.log_weights, ref.log_weights)


@settings(max_examples=200, deadline=None)
@given(
    values=st.lists(
        st.floats(allow_nan=False, allow_infinity=False, min_value=-1e300, max_value=1e300),
        min_size=0,
        max_size=700,
    )
)
def test_pairwise_sum_is_numpys_sum_bit_for_bit(values):
    # the kernel ranks by the sums numpy computed before, so ties break the same way
    a = np.array(values, float)
    assert _pairwise_sum(a, len(a)) == a.sum()
