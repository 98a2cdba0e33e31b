"""The kept-apart PMB update's parts against brute force (issue 33, item 3).

:func:`~jointtrack.trackers.pmbm._best_event_owners` (the MAP association event
per cluster, by the package's one assignment solver) against exact rational
enumeration of every event, and :func:`~jointtrack.trackers.pmbm._apart_weights`
(the state update's weights) against their definition.
"""

from __future__ import annotations

import itertools
from fractions import Fraction

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from jointtrack.association import clusters
from jointtrack.trackers.pmbm import _apart_weights, _best_event_owners


@st.composite
def _problems(draw):
    n = draw(st.integers(2, 4))
    m = draw(st.integers(1, 4))
    mask = np.array(draw(st.lists(st.booleans(), min_size=n * m, max_size=n * m))).reshape(n, m)
    vals = draw(
        st.lists(
            st.floats(min_value=5e-324, max_value=1e300),
            min_size=n * m,
            max_size=n * m,
        )
    )
    L = np.where(mask, np.array(vals).reshape(n, m), 0.0)
    miss = np.array(
        draw(st.lists(st.floats(min_value=5e-324, max_value=1.0), min_size=n, max_size=n))
    )
    return L, miss


def _brute_best(L, miss):
    """The events of maximum weight (exact rationals; within 1e-9 relative of it, as
    the solver compares float logs) of the cluster convention: track i takes column
    a_i − 1 or nothing (a_i = 0), no column twice."""
    n, m = L.shape
    events = []
    for a in itertools.product(range(m + 1), repeat=n):
        cols = [j for j in a if j]
        if len(cols) != len(set(cols)) or any(j and L[i, j - 1] == 0 for i, j in enumerate(a)):
            continue
        w = Fraction(1)
        for i, j in enumerate(a):
            w *= Fraction(L[i, j - 1]) if j else Fraction(miss[i])
        events.append((w, a))
    best = max(w for w, _ in events)
    return [a for w, a in events if w >= best * (1 - Fraction(1, 10**9))]


@settings(max_examples=40, deadline=None)
@given(_problems())
def test_best_event_owners_is_a_map_event(problem):
    """The owners are the assignment of an event of maximum weight (exact rational
    brute force over all events), for the whole problem split into its clusters."""
    L, miss = problem
    n, m = L.shape
    rows, cols = np.nonzero(L)
    pairs = (n, m, rows.astype(np.int64), cols.astype(np.int64))
    groups = clusters(pairs)
    owner = _best_event_owners(groups, rows, cols, L[rows, cols], miss, m)
    a = np.zeros(n, np.int64)
    taken = owner >= 0
    # owners only in clusters of ≥ 2 Bernoullis: the lone ones' events are independent
    lone = [c.tracks[0] for c in groups if len(c.tracks) == 1]
    a[owner[taken]] = np.flatnonzero(taken) + 1
    best = _brute_best(L, miss)
    assert any(all(a[i] == e[i] for i in range(n) if i not in lone) for e in best), (
        a.tolist(),
        best,
    )


@settings(max_examples=40, deadline=None)
@given(st.data())
def test_apart_weights_keep_detection_probability(data):
    """Pairs whose return the MAP event gives to another Bernoulli get 0; a Bernoulli's
    kept pairs are its own in proportion and sum to what all its pairs summed (its
    probability of detection given existence, 1 − b0); with no pair kept it is
    updated as missed. Weights drawn from 0 and subnormals to 1."""
    n = data.draw(st.integers(1, 4))
    m = data.draw(st.integers(1, 4))
    rows, cols = np.divmod(np.arange(n * m), m)
    w = np.array(data.draw(st.lists(st.floats(0.0, 1.0), min_size=n * m, max_size=n * m)))
    # each Bernoulli's pairs sum to at most 0.8: its b0 = 1 − Σ is a probability
    w = w / max(1.0, float(np.bincount(rows, w, minlength=n).max()) * 1.25)
    b0 = 1.0 - np.bincount(rows, w, minlength=n)
    owner = np.array(data.draw(st.lists(st.integers(-1, n - 1), min_size=m, max_size=m)))
    b0_s, w_s = _apart_weights(b0, w, rows, cols, owner)
    other = (owner[cols] >= 0) & (owner[cols] != rows)
    assert (w_s[other] == 0).all()
    for i in range(n):
        own = (rows == i) & ~other
        kept = np.bincount(rows, np.where(other, 0.0, w), minlength=n)[i]
        if other.any() and kept > 0:
            assert b0_s[i] == b0[i]
            total = np.bincount(rows, w, minlength=n)[i]  # = 1 − b0 up to rounding
            want = [float(Fraction(v) / Fraction(kept) * Fraction(total)) for v in w[own]]
            np.testing.assert_allclose(w_s[own], want, rtol=1e-12, atol=1e-320)
        elif other.any():
            assert b0_s[i] == 1.0 and (w_s[rows == i] == 0).all()
        np.testing.assert_allclose(b0_s[i] + w_s[rows == i].sum(), 1.0, rtol=1e-12)
