"""The compiled PMBM hypothesis kernels against exact rational brute force (issue 34).

:func:`~jointtrack.trackers.pmbm_hypotheses.rank_tuples` must return, for every
tuple of single-target hypotheses (STHs), the k heaviest association events —
weighed exactly in ``fractions.Fraction`` over every event of positive weight —
best first, with each track's child STH and the return it takes; values drawn
by hypothesis with zeros, subnormals and likelihood ratios up to 1e300.
:func:`~jointtrack.trackers.pmbm_hypotheses.combine_events` must return, for
every prior hypothesis, the k_h best combinations of its clusters' ranked lists
(exact sums of the drawn log weights), as rows of child STHs, in the order of a
stable sort of the whole grid. Bad input to the wrappers is refused with the
argument named before any kernel runs.
"""

from __future__ import annotations

import itertools
import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from brute import log_fraction
from jointtrack.trackers.pmbm_hypotheses import (
    RankedLists,
    check_pair_weights,
    combine_events,
    distinct_rows,
    merge_identical,
    rank_tuples,
    track_clusters,
)

SUBNORMAL = 5e-324

l_entry = st.one_of(
    st.just(0.0),
    st.floats(min_value=SUBNORMAL, max_value=1e300),
    st.sampled_from([SUBNORMAL, 1e-310, 1.0, 2.0, 1e300]),
)
miss_entry = st.one_of(
    st.just(0.0),
    st.floats(min_value=0.0, max_value=1.0),
    st.sampled_from([SUBNORMAL, 1e-300, 0.5, 1.0]),
)


@st.composite
def scans(draw):
    """STHs of ``n`` tracks (1–3 each) with gated pairs to ``m`` returns, and tuples."""
    n = draw(st.integers(1, 4))
    m = draw(st.integers(0, 4))
    per_track = [draw(st.integers(1, 3)) for _ in range(n)]
    sth_track = np.repeat(np.arange(n), per_track)
    S = len(sth_track)
    rows, cols = [], []
    for s in range(S):
        for j in sorted(draw(st.sets(st.integers(0, m - 1), max_size=m)) if m else []):
            rows.append(s)
            cols.append(j)
    L = np.array(draw(st.lists(l_entry, min_size=len(rows), max_size=len(rows))), float)
    miss = np.array(draw(st.lists(miss_entry, min_size=S, max_size=S)), float)
    rows, cols = np.array(rows, np.int64), np.array(cols, np.int64)
    start = np.searchsorted(rows, np.arange(S + 1)).astype(np.int64)
    first = np.searchsorted(sth_track, np.arange(n))
    tuples = []
    for _ in range(draw(st.integers(1, 4))):
        pick = [draw(st.integers(-1, per_track[t] - 1)) for t in range(n)]
        tuples.append([first[t] + p if p >= 0 else -1 for t, p in enumerate(pick)])
    tuples = np.array(tuples, np.int64)
    ks = np.array([draw(st.integers(1, 30)) for _ in tuples], np.int64)
    return start, cols, L, miss, m, tuples, ks


def exact_events(tup, start, cols, L, miss):
    """{(child per track): exact weight} of every event of positive weight of ``tup``."""
    options = []
    for s in tup:
        if s < 0:
            options.append([(int(s), -1, Fraction(1))])
            continue
        opts = [(int(s), -1, Fraction(float(miss[s])))]
        opts += [(p, int(cols[p]), Fraction(float(L[p]))) for p in range(start[s], start[s + 1])]
        options.append(opts)
    out = {}
    for choice in itertools.product(*options):
        taken = [j for _, j, _ in choice if j >= 0]
        if len(taken) != len(set(taken)):
            continue
        w = math.prod(f for _, _, f in choice)
        if w > 0:
            out[
                tuple(
                    choice[t][0] if choice[t][1] < 0 else -2 - choice[t][0] for t in range(len(tup))
                )
            ] = w
    return out


def event_key(child_row, S):
    """A kernel event in the key of :func:`exact_events` (−2 − pair for a detection)."""
    return tuple(int(c) if c < S else -2 - int(c - S) for c in child_row)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scan=scans())
def test_rank_tuples_are_the_k_heaviest_events_exactly(scan):
    start, cols, L, miss, m, tuples, ks = scan
    S = len(miss)
    pairs = check_pair_weights(start, cols, L, miss, m)
    out = rank_tuples(tuples, ks, pairs)
    assert out.ptr[0] == 0 and out.ptr[-1] == len(out.w)
    for u, tup in enumerate(tuples):
        exact = exact_events(tup, start, cols, L, miss)
        lo, hi = out.ptr[u], out.ptr[u + 1]
        assert hi - lo == min(int(ks[u]), len(exact))
        keys = [event_key(out.child[e], S) for e in range(lo, hi)]
        assert len(set(keys)) == len(keys)  # distinct events
        best = sorted(exact.values(), reverse=True)[: hi - lo]
        assert np.all(np.diff(out.w[lo:hi]) <= 0)  # best first
        for e, key, top in zip(range(lo, hi), keys, best, strict=True):
            assert key in exact
            truth = log_fraction(exact[key])
            tol = 1e-13 * (1.0 + sum(abs(math.log(x)) for x in L if x > 0) + 750 * len(tup))
            # the kernel's weight is this event's, and as heavy as the e-th heaviest
            assert abs(out.w[e] - truth) <= tol
            assert abs(truth - log_fraction(top)) <= 2 * tol
            # each track: its own STH, or the detection child of a pair of its STH
            for t, s in enumerate(tup):
                c = out.child[e, t]
                if out.taken[e, t] < 0:
                    assert c == s
                else:
                    p = c - S
                    assert s >= 0 and start[s] <= p < start[s + 1] and cols[p] == out.taken[e, t]


log_w = st.one_of(
    st.floats(min_value=-2000.0, max_value=700.0),
    st.sampled_from([0.0, -1.0, -745.0, 700.0]),  # repeated values: ties
)


@st.composite
def combinations(draw):
    """Clusters of ranked lists (drawn log weights, sorted) and prior hypotheses."""
    H = draw(st.integers(1, 3))
    C = draw(st.integers(0, 3))
    T = C + 1  # one track per cluster and one quiet track
    M = C
    clusters = []
    next_child = 100
    for c in range(C):
        U = draw(st.integers(1, 3))
        lens = [draw(st.integers(0, 5)) for _ in range(U)]
        ptr = np.concatenate([[0], np.cumsum(lens)]).astype(np.int64)
        ws = [sorted(draw(st.lists(log_w, min_size=k, max_size=k)), reverse=True) for k in lens]
        w = np.array([x for lst in ws for x in lst], float)
        E = len(w)
        child = (next_child + np.arange(E, dtype=np.int64))[:, None]  # unique per event
        next_child += E
        taken = np.array([draw(st.sampled_from([-1, c])) for _ in range(E)], np.int64)[:, None]
        inv = np.array([draw(st.integers(0, U - 1)) for _ in range(H)], np.int64)
        clusters.append((np.array([c], np.int64), inv, RankedLists(ptr, w, child, taken)))
    hyp = np.array([[draw(st.integers(-1, 5)) for _ in range(T)] for _ in range(H)], np.int64)
    base = np.array([draw(st.one_of(log_w, st.just(-np.inf))) for _ in range(H)], float)
    k_h = np.array([draw(st.integers(1, 12)) for _ in range(H)], np.int64)
    new_track_hyp = np.arange(50, 50 + M, dtype=np.int64)
    return hyp, base, k_h, new_track_hyp, clusters


@settings(max_examples=50, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case=combinations())
def test_combine_events_are_the_k_best_sums_exactly(case):
    hyp, base, k_h, new_track_hyp, clusters = case
    H, T = hyp.shape
    rows, logw, n_events = combine_events(hyp, base, k_h, new_track_hyp, clusters)
    assert len(rows) == len(logw) == n_events.sum()
    at = 0
    for h in range(H):
        # every combination of h's lists, summed exactly
        lists = []
        for _tracks, inv, r in clusters:
            lo, hi = r.ptr[inv[h]], r.ptr[inv[h] + 1]
            lists.append(range(lo, hi))
        combos = {}
        if np.isfinite(base[h]):
            for pick in itertools.product(*lists):
                total = sum((Fraction(float(clusters[c][2].w[e])) for c, e in enumerate(pick)),
                            Fraction(0))  # fmt: skip
                combos[pick] = total
        E = min(int(k_h[h]), len(combos))
        assert n_events[h] == E
        best = sorted(combos.values(), reverse=True)[:E]
        seen = set()
        for e in range(E):
            row = rows[at + e]
            pick = tuple(int(row[c]) - 100 - sum(len(x[2].w) for x in clusters[:c])
                         for c in range(len(clusters)))  # fmt: skip
            # the row: the prior's quiet track, each cluster's event child, −1 where taken
            assert row[T - 1] == hyp[h, T - 1]
            for c, (_t, _inv, r) in enumerate(clusters):
                g = pick[c]
                assert r.ptr[clusters[c][1][h]] <= g < r.ptr[clusters[c][1][h] + 1]
                assert row[T + c] == (-1 if r.taken[g, 0] >= 0 else new_track_hyp[c])
            assert pick not in seen
            seen.add(pick)
            exact = float(combos[pick])
            scale = 1e-13 * (1.0 + abs(base[h]) + sum(abs(float(x)) for x in best) + 2000 * 3)
            assert abs(logw[at + e] - (base[h] + exact)) <= scale
            assert abs(exact - float(best[e])) <= scale
        assert np.all(np.diff(logw[at : at + E]) <= 0)
        at += E


@settings(max_examples=30, deadline=None)
@given(
    a=st.lists(log_w, min_size=2, max_size=8),
    b=st.lists(log_w, min_size=2, max_size=8),
    k=st.integers(1, 70),
)
def test_two_lists_combine_in_stable_grid_order(a, b, k):
    """Ties are broken as a stable sort of the whole grid breaks them (the former
    ``_combine_ranked``'s order): by the index in the first list, then the second."""
    a = np.sort(np.array(a))[::-1].copy()
    b = np.sort(np.array(b))[::-1].copy()

    def cluster(t, w):
        n = len(w)
        ranked = RankedLists(np.array([0, n]), w, np.arange(n)[:, None], np.full((n, 1), -1))
        return np.array([t], np.int64), np.zeros(1, np.int64), ranked

    rows, logw, _ = combine_events(
        np.full((1, 2), -1, np.int64), np.zeros(1), np.array([k]), np.zeros(0, np.int64),
        [cluster(0, a), cluster(1, b)],
    )  # fmt: skip
    # the first list is added to the sum 0.0, then the second: the same floats
    grid = ((0.0 + a)[:, None] + b[None, :]).ravel()
    order = np.argsort(-grid, kind="stable")[:k]
    i, j = np.divmod(order, len(b))
    np.testing.assert_array_equal(rows[:, 0], i)
    np.testing.assert_array_equal(rows[:, 1], j)
    np.testing.assert_array_equal(logw, 0.0 + 0.0 + grid[order])


def _pairs():
    return (np.array([0, 1, 2], np.int64), np.array([0, 1], np.int64), np.array([0.5, 2.0]),
            np.array([0.1, 0.2]), 2)  # fmt: skip


@pytest.mark.parametrize(
    "change, error, words",
    [
        ({0: np.array([0, 1, 2], np.int32)}, TypeError, "start"),
        ({1: [0, 1]}, TypeError, "cols"),
        ({2: np.array([0.5, np.nan])}, ValueError, "L must hold finite"),
        ({2: np.array([0.5, -1.0])}, ValueError, "L must hold finite"),
        ({2: np.array([0.5, 1j])}, TypeError, "L"),
        ({3: np.array([0.1, 1.5])}, ValueError, "miss must hold weights in [0, 1]"),
        ({1: np.array([0, 2], np.int64)}, ValueError, "cols must name returns"),
        ({0: np.array([0, 2, 1], np.int64)}, ValueError, "start must run"),
        ({4: True}, ValueError, "n_returns"),
        ({4: -1}, ValueError, "n_returns"),
        ({2: np.array([0.5])}, ValueError, "one entry per pair"),
    ],
)
def test_bad_pair_arrays_are_refused_naming_the_argument(change, error, words):
    args = list(_pairs())
    for i, v in change.items():
        args[i] = v
    with pytest.raises(error, match=words.replace("[", r"\[").replace("]", r"\]")):
        check_pair_weights(*args)


def test_bad_tuples_and_lists_are_refused_before_the_kernels():
    pairs = check_pair_weights(*_pairs())
    with pytest.raises(ValueError, match="STH indices"):
        rank_tuples(np.array([[2]], np.int64), np.array([1], np.int64), pairs)
    with pytest.raises(ValueError, match="ks must be"):
        rank_tuples(np.array([[0]], np.int64), np.array([0], np.int64), pairs)
    with pytest.raises(TypeError, match="pairs"):
        rank_tuples(np.array([[0]], np.int64), np.array([1], np.int64), tuple(pairs))
    ranked = rank_tuples(np.array([[0]], np.int64), np.array([2], np.int64), pairs)
    hyp = np.zeros((1, 1), np.int64)
    ok = (np.array([0], np.int64), np.zeros(1, np.int64), ranked)
    with pytest.raises(ValueError, match="inverse"):
        combine_events(hyp, np.zeros(1), np.ones(1, np.int64), np.zeros(2, np.int64),
                       [(ok[0], np.array([1], np.int64), ranked)])  # fmt: skip
    with pytest.raises(ValueError, match="k_h"):
        combine_events(hyp, np.zeros(1), np.zeros(1, np.int64), np.zeros(2, np.int64), [ok])
    with pytest.raises(ValueError, match="base_logw"):
        combine_events(hyp, np.array([np.nan]), np.ones(1, np.int64), np.zeros(2, np.int64), [ok])
    with pytest.raises(ValueError, match="taken"):  # a return the scan does not have
        combine_events(hyp, np.zeros(1), np.ones(1, np.int64), np.zeros(0, np.int64), [ok])


@settings(max_examples=40, deadline=None)
@given(
    rows=st.lists(st.lists(st.integers(-1, 2), min_size=3, max_size=3), min_size=1, max_size=12),
    data=st.data(),
)
def test_merge_identical_sums_the_copies_of_each_row(rows, data):
    """Distinct rows in lexicographic order; each one's log weight is log Σ exp of its
    copies' (exact sum of the exponentials, as Fractions, for weights down to e^−2000)."""
    rows = np.array(rows, np.int64)
    logw = np.array(
        data.draw(st.lists(log_w | st.just(-np.inf), min_size=len(rows), max_size=len(rows))),
        float,
    )
    out, merged = merge_identical(rows, logw)
    distinct, inverse = distinct_rows(rows)
    np.testing.assert_array_equal(distinct, out)
    np.testing.assert_array_equal(distinct[inverse], rows)
    groups = {}
    for r, lw in zip(map(tuple, rows.tolist()), logw, strict=True):
        groups.setdefault(r, []).append(lw)
    assert [tuple(r) for r in out.tolist()] == sorted(groups)
    for r, got in zip(sorted(groups), merged, strict=True):
        finite = [x for x in groups[r] if x > -np.inf]
        if not finite:
            assert got == -np.inf
            continue
        top = max(finite)
        # Σ exp(x − top) ≥ 1: exact enough in floats, then the log
        truth = top + math.log(math.fsum(math.exp(x - top) for x in finite))
        assert abs(got - truth) <= 1e-13 * (1.0 + abs(truth))


def test_merge_identical_refuses_bad_weights():
    rows = np.zeros((2, 1), np.int64)
    with pytest.raises(ValueError, match="logw"):
        merge_identical(rows, np.array([0.0, np.nan]))
    with pytest.raises(ValueError, match="logw must have one entry per row"):
        merge_identical(rows, np.zeros(3))
    with pytest.raises(TypeError, match="rows"):
        merge_identical(rows.astype(float), np.zeros(2))


@settings(max_examples=40, deadline=None)
@given(
    T=st.integers(0, 6),
    M=st.integers(0, 6),
    data=st.data(),
)
def test_track_clusters_are_the_connected_components(T, M, data):
    """Clusters of tracks through shared returns, against a breadth-first search: the
    same partition, tracks and returns ascending, clusters ordered by first track."""
    pairs = (
        data.draw(
            st.lists(
                st.tuples(st.integers(0, max(T - 1, 0)), st.integers(0, max(M - 1, 0))), max_size=12
            )
        )
        if T and M
        else []
    )
    pair_track = np.array([t for t, _ in pairs], np.int64)
    cols = np.array([j for _, j in pairs], np.int64)
    out = track_clusters(pair_track, cols, T, M)
    # breadth-first search over tracks and returns
    near = {("t", t): set() for t in range(T)} | {("r", j): set() for j in range(M)}
    for t, j in pairs:
        near[("t", t)].add(("r", j))
        near[("r", j)].add(("t", t))
    seen, expected = set(), []
    for t in sorted({t for t, _ in pairs}):
        if ("t", t) in seen:
            continue
        todo, comp = [("t", t)], set()
        while todo:
            v = todo.pop()
            if v not in comp:
                comp.add(v)
                todo.extend(near[v])
        seen |= comp
        expected.append(
            (sorted(i for k, i in comp if k == "t"), sorted(i for k, i in comp if k == "r"))
        )
    got = [
        (out.tracks[out.track_ptr[c] : out.track_ptr[c + 1]].tolist(),
         out.returns[out.return_ptr[c] : out.return_ptr[c + 1]].tolist())
        for c in range(len(out.track_ptr) - 1)
    ]  # fmt: skip
    assert got == expected


def test_track_clusters_refuses_bad_indices():
    with pytest.raises(ValueError, match="pair_track must name tracks"):
        track_clusters(np.array([3], np.int64), np.array([0], np.int64), 3, 1)
    with pytest.raises(ValueError, match="cols must name returns"):
        track_clusters(np.array([0], np.int64), np.array([1], np.int64), 3, 1)
    with pytest.raises(ValueError, match="n_returns"):
        track_clusters(np.array([0], np.int64), np.array([0], np.int64), 3, True)
    with pytest.raises(TypeError, match="cols"):
        track_clusters(np.array([0], np.int64), np.array([0.0]), 3, 1)
