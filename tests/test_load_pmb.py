"""PMB on the ``many`` scene (issue 34): the Poisson intensity's greedy merge compiled.

``poisson.prune_and_merge``'s rounds (Vo & Ma 2006, Table II; each candidate's
distance in its own covariance) were a Python loop of numpy calls, half of PMB's
step on ``many`` (≈ 150 components and rounds a scan). The compiled rounds must
group exactly as that loop did — here against it, kept as the reference, on full
covariances, repeated means, zero, huge and tiny values; the exact rational
grouping is tests/test_pmb_birth_merge.py's.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from jointtrack.trackers.poisson import _greedy_groups, moment_match, prune_and_merge


def _reference_groups(w, m, P, merge):
    """The Python rounds of 831ecfa, verbatim but for the return."""
    order = list(np.argsort(-w, kind="stable"))
    group = np.full(len(w), -1)
    g = 0
    with np.errstate(over="ignore"):
        inv = np.linalg.inv(P)
    while order:
        lead = order[0]
        rest = np.array(order)
        d = m[rest] - m[lead]
        with np.errstate(invalid="ignore", over="ignore"):
            d2 = np.einsum("ki,kij,kj->k", d, inv[rest], d)
        close = rest[(d2 <= merge) | ~d.any(axis=1)]
        group[close] = g
        g += 1
        taken = set(close.tolist())
        order = [i for i in order if i not in taken]
    return group, g


coordinate = st.sampled_from([0.0, 1.0, -3.0, 2.5, 1e-300, 1e150, -1e300])
scale = st.sampled_from([1e-300, 1e-6, 1.0, 30.0, 1e6, 1e300])


@st.composite
def mixtures(draw):
    k = draw(st.integers(1, 12))
    n = draw(st.sampled_from([2, 4]))
    w = np.array([draw(st.sampled_from([0.1, 0.5, 1.0, 3.0])) for _ in range(k)])
    m = np.array([[draw(coordinate) for _ in range(n)] for _ in range(k)])
    if k > 1 and draw(st.booleans()):  # a repeated mean
        m[-1] = m[0]
    P = []
    for _ in range(k):
        A = np.array([[draw(st.integers(-2, 2)) for _ in range(n)] for _ in range(n)], float)
        P.append((A @ A.T + np.eye(n)) * draw(scale))
    return w, m, np.array(P), draw(st.sampled_from([0.5, 4.0, 16.0]))


@settings(max_examples=50, deadline=None)
@given(mixtures())
def test_compiled_rounds_group_as_the_python_rounds(case):
    w, m, P, merge = case
    want, n_want = _reference_groups(w, m, P, merge)
    with np.errstate(over="ignore"):
        inv = np.linalg.inv(P)
    got, n_got = _greedy_groups(np.argsort(-w, kind="stable").astype(np.int64), m, inv, merge)
    assert n_got == n_want
    np.testing.assert_array_equal(got, want)
    with np.errstate(all="ignore"):
        w2, m2, P2 = prune_and_merge(w, m, P, prune=0.0, merge=merge, cap=100)
        tw, tm, tP = moment_match(w, want, m, P, n_want)
    np.testing.assert_array_equal(w2, tw)
    np.testing.assert_array_equal(m2, tm)
    np.testing.assert_array_equal(P2, tP)
