"""The frontier DP's planner stops at the budget (issue 31: a 2,000-return burst).

The greedy layer order costs R² · C; a JIPDA tracker's 2,000 tentative tracks on a
2,000-return clutter burst spent 67 s of a 53 s-too-long scan planning both
orientations of a block whose first layer already opened a thousand items, only
for the DP to be refused at ``max_bits``. The plan now stops at the first layer
past ``max_width``; these tests hold it to the full plan's answer.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from jointtrack.assignment import assignment_sum
from jointtrack.assignment._plan import frontier_plan
from jointtrack.assignment.core import _frontier_block
from jointtrack.errors import ExactLimitError

gating = st.integers(1, 9).flatmap(
    lambda r: st.integers(1, 12).flatmap(lambda c: arrays(np.bool_, (r, c)))
)


def _widths(G, order):
    """Items open while each layer of ``order`` is processed (open before + opened)."""
    left = G.sum(axis=0)
    opened = np.zeros(G.shape[1], bool)
    out = []
    for r in order:
        out.append(int(np.sum(opened & (left > 0)) + np.sum(G[r] & ~opened)))
        opened |= G[r]
        left = left - G[r]
    return out


@settings(max_examples=300, deadline=None)
@given(G=gating, max_width=st.integers(0, 12))
def test_a_bounded_plan_is_the_full_plan_or_stops_past_its_bound(G, max_width):
    full = frontier_plan(G)
    order, K = full[0], int(full[1])
    assert sorted(order.tolist()) == list(range(G.shape[0]))
    widths = _widths(G, order)
    assert K == max(widths)  # K is the widest frontier, as the slots say
    bounded = frontier_plan(G, max_width)
    if K <= max_width:
        for a, b in zip(full, bounded, strict=True):
            assert np.array_equal(a, b)
    else:
        # stopped at the first layer past the bound, with that layer's width
        first = next(i for i, w in enumerate(widths) if w > max_width)
        assert np.array_equal(bounded[0], order[:first])
        assert int(bounded[1]) == widths[first] > max_width
        assert bounded[2].size == bounded[3].size == bounded[6].size == 0


def test_a_dense_block_past_the_budget_stops_at_its_first_layer():
    G = np.ones((300, 300), bool)
    order, K, *_ = frontier_plan(G, 24)
    assert order.size == 0 and K == 300


def test_the_orientation_within_the_budget_is_used_when_the_cheaper_one_is_not():
    # one row gating four of twelve columns: as rows the frontier is 4 wide
    # (cost 1 · 2^4 = 16), as columns 1 wide (cost 12 · 2^1 = 24)
    W = np.zeros((1, 12))
    W[0, [3, 4, 8, 11]] = [0.5, 2.0, 1.5, 0.25]
    u, v = np.ones(1), np.ones(12)
    for max_bits in (1, 2, 3):
        pu, pv, pe, lz, K, _ = _frontier_block(W, u, v, True, max_bits, 2**20, False)
        assert K == 1
        # Z = 1 (row unused) + Σ W: the row takes one of its four columns
        assert lz == pytest.approx(math.log(1 + W.sum()), rel=1e-14)
        assert pe[0] == pytest.approx(W[0] / (1 + W.sum()), rel=1e-14)
    with pytest.raises(ExactLimitError, match="at least 2\\^1 subsets.*max_bits = 0"):
        _frontier_block(W, u, v, True, 0, 2**20, False)


def test_a_refused_dense_burst_names_the_budget():
    W = np.random.default_rng(0).uniform(0.5, 2.0, (200, 200))  # no repeated rows
    with pytest.raises(ExactLimitError, match="at least 2\\^200 subsets.*max_bits = 20"):
        assignment_sum(W, np.ones(200), max_bits=20)
