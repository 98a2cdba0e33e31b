"""The exact DP's memory plan: checkpoint strides, budgets, and what the tracker takes exactly.

* a larger ``max_memory`` never gives a plan the planner's own cost model predicts
  slower, and the plan always fits its budget (hypothesis over gating patterns and
  budgets); the recomputation the model counts is checked against a direct
  simulation of the DP's segment loop;
* every checkpoint stride gives the same bits as keeping every forward array, and
  the marginals at any budget that is accepted are exact (rational brute force,
  values drawn by hypothesis from subnormal to 1e300 with zeros);
* the engine accepts a block exactly at its own memory estimate and refuses it one
  byte below, naming ``max_memory``; ``JPDATracker`` with default settings takes a
  dense cluster exactly where the estimate fits the engine's default budget.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from jointtrack.assignment import assignment_sum
from jointtrack.assignment._frontier import frontier_dp
from jointtrack.assignment._plan import (
    FRESH_BYTES,
    TOUCH_COST,
    checkpoint_arrays,
    checkpoint_cost,
    checkpoint_plan,
    frontier_plan,
    op_costs,
)
from jointtrack.assignment.core import DEFAULT_MAX_MEMORY
from jointtrack.association.budget import budgeted_marginals
from jointtrack.errors import ExactLimitError
from jointtrack.trackers import JPDATracker, TrackerConfig
from test_assignment_core import check_log, check_marginals, plain_problems, truth

SETTINGS = settings(
    max_examples=20,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

gating = st.integers(1, 8).flatmap(
    lambda r: st.integers(1, 8).flatmap(
        lambda c: arrays(np.bool_, (r, c), elements=st.booleans()).filter(
            lambda G: G.any(axis=1).all() and G.any(axis=0).all()
        )
    )
)


def _plan(G):
    order, K, op_kind, op_arg, slot_of, lay_slot, term = frontier_plan(G)
    return int(K), op_kind, op_arg, slot_of, lay_slot, term


def _recomputed_by_simulation(costs, stride):
    """Σ cost of the operations the backward pass recomputes, by walking its segments."""
    nops = len(costs)
    total = 0
    for t0 in range(0, nops, stride):
        t1 = min(t0 + stride, nops)
        total += sum(int(costs[t]) for t in range(t0, t1 - 1))
    return total


@SETTINGS
@given(
    G=gating,
    budgets=st.lists(st.integers(0, 80), min_size=2, max_size=6),
    width=st.sampled_from([None, 20, 24]),
)
def test_a_larger_budget_never_gives_a_plan_predicted_slower(G, budgets, width):
    K, op_kind, op_arg, _, lay_slot, _ = _plan(G)
    K = K if width is None else width  # large states: the first-touch term counts
    costs = op_costs(op_kind, op_arg, lay_slot)
    per = 8 << K
    nops = len(costs)
    for stride in range(1, nops + 1):
        forward = int(costs.sum())
        arrays_needed = checkpoint_arrays(nops, stride)
        touch = TOUCH_COST * arrays_needed if arrays_needed * per > FRESH_BYTES else 0
        want = 3 * forward + _recomputed_by_simulation(costs, stride) + touch
        assert checkpoint_cost(costs, stride, K) == want
    least = min(checkpoint_arrays(nops, s) for s in range(1, nops + 1)) * per
    previous = None
    for arrays_allowed in sorted(budgets):
        budget = arrays_allowed * per
        stride, need = checkpoint_plan(op_kind, op_arg, lay_slot, K, budget)
        if stride == 0:
            assert budget < least and need == least
            assert previous is None  # a smaller budget cannot have fitted
            continue
        assert need == checkpoint_arrays(nops, stride) * per <= budget
        cost = checkpoint_cost(costs, stride, K)
        # the cheapest plan that fits: no fitting stride is predicted cheaper
        fitting = [
            checkpoint_cost(costs, s, K)
            for s in range(1, nops + 1)
            if checkpoint_arrays(nops, s) * per <= budget
        ]
        assert cost == min(fitting)
        if previous is not None:
            assert cost <= previous
        previous = cost


@settings(max_examples=30, deadline=None)
@given(
    G=gating,
    values=arrays(np.float64, 64, elements=st.floats(0.01, 100.0)),
    null=arrays(np.float64, 8, elements=st.floats(0.0, 2.0)),
)
def test_every_stride_gives_the_bits_of_keeping_every_array(G, values, null):
    R, C = G.shape
    W = np.where(G, values[: R * C].reshape(R, C), 0.0)
    u, v = null[:R].copy(), np.ones(C)
    K, op_kind, op_arg, slot_of, lay_slot, term = _plan(G)
    args = (W, u, v, K, op_kind, op_arg, slot_of, lay_slot, term)
    pl, pi, pe, lz = frontier_dp(*args, 1, 1)
    for stride in range(2, op_kind.size + 2):
        ql, qi, qe, lz2 = frontier_dp(*args, stride, 1)
        assert lz2 == lz
        assert np.array_equal(ql, pl) and np.array_equal(qi, pi) and np.array_equal(qe, pe)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(problem=plain_problems(max_r=4, max_c=5), arrays_allowed=st.integers(0, 12))
def test_marginals_at_any_accepted_budget_are_exact_and_the_same(problem, arrays_allowed):
    W, null = problem
    Z, Pt, Pnt = truth(W, null)
    if Z == 0:
        return
    full = assignment_sum(W, null, method="frontier", max_memory=2**40)
    check_log(full.log_normalizer, Z)
    check_marginals(full.P, full.null, Pt, Pnt, np.ones(W.shape[1]))
    K = full.info["max_frontier"]
    try:
        small = assignment_sum(W, null, method="frontier", max_memory=arrays_allowed * (8 << K))
    except ExactLimitError as exc:
        assert "max_memory" in str(exc)
        return
    assert small.info["state_bytes"] <= arrays_allowed * (8 << K)
    assert small.log_normalizer == full.log_normalizer
    assert np.array_equal(small.P, full.P) and np.array_equal(small.null, full.null)


def _dense(n, m, seed=0):
    rng = np.random.default_rng(seed)
    return 5 * rng.random((n, m)), np.full(n, 0.1)


def test_a_block_is_taken_at_its_memory_estimate_and_refused_one_byte_below():
    L, miss = _dense(10, 14)
    # K = 10 slots (the tracks), 14 measurement layers
    G = np.ascontiguousarray((L > 0).T)
    K, op_kind, op_arg, _, lay_slot, _ = _plan(G)
    nops = op_kind.size
    least = min(checkpoint_arrays(nops, s) for s in range(1, nops + 1)) * (8 << K)
    _, need = checkpoint_plan(op_kind, op_arg, lay_slot, K, least)
    assert need == least < checkpoint_arrays(nops, 1) * (8 << K)
    res = assignment_sum(L, miss, max_memory=need)
    assert res.info["state_bytes"] == need
    ref = assignment_sum(L, miss)
    assert np.array_equal(res.P, ref.P) and np.array_equal(res.null, ref.null)
    with pytest.raises(ExactLimitError, match="max_memory"):
        assignment_sum(L, miss, max_memory=need - 1)
    # the tracker's policy: exact where it fits, the approximation (with the reason) below
    got = budgeted_marginals(L, miss, method="exact", exact_options={"max_memory": need})
    assert got.method == "exact" and got.reason == ""
    below = budgeted_marginals(L, miss, method="exact", exact_options={"max_memory": need - 1})
    assert below.method != "exact" and "max_memory" in below.reason


def test_the_default_tracker_takes_a_dense_cluster_exactly_where_the_estimate_fits():
    tracker = JPDATracker(TrackerConfig())
    n = tracker.config.exact_max_tracks
    L, miss = _dense(n, 2 * n)
    G = np.ascontiguousarray((L > 0).T)  # the cheaper orientation: the tracks are the slots
    K, op_kind, op_arg, _, lay_slot, _ = _plan(G)
    stride, need = checkpoint_plan(op_kind, op_arg, lay_slot, K, DEFAULT_MAX_MEMORY)
    assert stride >= 1 and need <= DEFAULT_MAX_MEMORY
    beta, method, reason, _ = tracker._cluster_marginals(L, miss, True)
    assert method == "exact" and reason == ""
    np.testing.assert_array_equal(beta, assignment_sum(L, miss).beta)
    # one track more is above the tracker's exact_max_tracks, whatever the memory
    L1, miss1 = _dense(n + 1, 2 * n)
    _, method1, reason1, _ = tracker._cluster_marginals(L1, miss1, True)
    assert method1 != "exact" and reason1 == "exact_max_tracks"
