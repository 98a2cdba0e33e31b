"""Layer order and frontier slot assignment for the frontier subset DP.

Step 4 of :mod:`jointtrack.assignment.core`, planning part. Layers (rows of a
boolean gating matrix) are processed one at a time; the DP state is the subset of
the *open* items (columns seen and still gated by an unprocessed layer) that are
already used, so its width is the largest number of simultaneously open items.
:func:`frontier_plan` picks a greedy layer order that keeps this frontier small, gives
each open item a bit position (slot) in the state index, reusing freed slots, and
records when each item leaves the frontier (is summed out). The DP's cost is about
``layers · 2^K`` for a frontier of K slots, so the caller plans both orientations
and keeps the cheaper one.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def frontier_plan(G, max_width=-1):
    """Greedy layer order and slot assignment for layers = rows of boolean ``G``.

    Picks next the layer that opens the fewest new items net of the items it
    closes. Returns ``(order, K, op_kind, op_arg, slot_of, lay_slot(R×C),
    term_items)``: ``op_kind`` 0 = process layer ``op_arg``, 1 = item ``op_arg``
    leaves the frontier; items still open after the last layer are ``term_items``.

    ``K`` is the largest number of items open while a layer is processed (open
    before it plus the ones it opens): first-fit slots never need more. With
    ``max_width`` ≥ 0 the plan stops at the first layer that takes the frontier
    past it and returns that width as ``K`` (a lower bound of the full plan's,
    so above ``max_width`` too) with empty operations: the greedy order costs
    R² · C, 33 s for a 2,000 × 2,000 clutter burst whose first layer already
    opens a thousand items.
    """
    R, C = G.shape
    rem = np.zeros(C, np.int64)
    for r in range(R):
        for c in range(C):
            if G[r, c]:
                rem[c] += 1
    opened = np.zeros(C, np.bool_)
    done = np.zeros(R, np.bool_)
    order = np.empty(R, np.int64)
    n_open = 0  # items opened and still gated by an unprocessed layer
    for step in range(R):
        best = -1
        bkey0 = 1 << 60
        bkey1 = 1 << 60
        for r in range(R):
            if done[r]:
                continue
            new = 0
            close = 0
            for c in range(C):
                if G[r, c]:
                    if not opened[c]:
                        new += 1
                    if rem[c] == 1:
                        close += 1
            k0 = new - close
            if k0 < bkey0 or (k0 == bkey0 and new < bkey1):
                bkey0 = k0
                bkey1 = new
                best = r
        width = n_open + bkey1
        if max_width >= 0 and width > max_width:
            return (
                order[:step],
                width,
                np.empty(0, np.int64),
                np.empty(0, np.int64),
                np.full(C, -1, np.int64),
                np.full((0, C), -1, np.int64),
                np.empty(0, np.int64),
            )
        done[best] = True
        order[step] = best
        for c in range(C):
            if G[best, c]:
                if not opened[c]:
                    opened[c] = True
                    n_open += 1
                rem[c] -= 1
                if rem[c] == 0:
                    n_open -= 1
    # slot simulation
    slot_of = np.full(C, -1, np.int64)
    slot_free = np.ones(C + 1, np.bool_)
    left = np.zeros(C, np.int64)
    for r in range(R):
        for c in range(C):
            if G[r, c]:
                left[c] += 1
    lay_slot = np.full((R, C), -1, np.int64)
    op_kind = np.empty(R + C, np.int64)
    op_arg = np.empty(R + C, np.int64)
    nops = 0
    K = 0
    nopen = 0
    for step in range(R):
        r = order[step]
        for c in range(C):
            if G[r, c] and slot_of[c] < 0:
                s = 0
                while not slot_free[s]:
                    s += 1
                slot_free[s] = False
                slot_of[c] = s
                nopen += 1
                if s + 1 > K:
                    K = s + 1
        for c in range(C):
            if G[r, c]:
                lay_slot[r, c] = slot_of[c]
        op_kind[nops] = 0
        op_arg[nops] = r
        nops += 1
        for c in range(C):
            if G[r, c]:
                left[c] -= 1
        if step < R - 1:
            for c in range(C):
                if G[r, c] and left[c] == 0:
                    op_kind[nops] = 1
                    op_arg[nops] = c
                    nops += 1
                    slot_free[slot_of[c]] = True
                    nopen -= 1
    nterm = 0
    term = np.empty(C, np.int64)
    last_r = order[R - 1]
    # items open at the end are exactly the items gated by the final layer
    for c in range(C):
        if G[last_r, c]:
            term[nterm] = c
            nterm += 1
    return order, K, op_kind[:nops], op_arg[:nops], slot_of, lay_slot, term[:nterm]


# --------------------------------------------------------------------------- checkpointing

#: Cost of one state array's first touch (page faults, the kernel zeroing the pages), in
#: the unit of :func:`op_costs` (one pass over the states). Measured on the dense 24×48
#: (benchmarks/RESULTS.md, issue 34): keeping all 48 forward arrays (51 arrays, 6.4 GiB)
#: took 40.3 CPU-s against 35.2 for every 7th (18 arrays) with 41 layers recomputed, in the
#: same run: 0.35 s per 128 MiB array against 6.2 ms per pass, ≈ 56 passes.
TOUCH_COST = 56
#: Plans of at most this many bytes pay no first touch: glibc's malloc serves them from
#: memory freed by earlier calls (its largest mmap threshold, 32 MiB on 64-bit), while
#: larger ones are mapped afresh, and fault page by page, on every call.
FRESH_BYTES = 32 * 2**20


def op_costs(op_kind, op_arg, lay_slot):
    """Forward cost of each planned operation, in passes over the 2^K states.

    A layer with d gated slots reads its input once and adds d shifted copies
    (1 + d); an item leaving the frontier is one pass (1). The adjoint of an
    operation costs twice its forward (the transposed map and the contraction).
    """
    deg = (np.asarray(lay_slot) >= 0).sum(axis=1)
    layer = np.asarray(op_kind) == 0  # op_arg is a layer there, an item elsewhere
    costs = np.ones(layer.size, np.int64)
    costs[layer] = 1 + deg[np.asarray(op_arg)[layer]]
    return costs


def checkpoint_arrays(nops, stride):
    """State arrays ``frontier_dp`` allocates with this stride.

    ``⌈nops/stride⌉ − 1`` checkpoints (F_0 is not kept), ``max(stride, 2)`` segment
    arrays (also the forward pass's buffers and its last array) and the two backward
    messages.
    """
    return -(-nops // stride) - 1 + max(stride, 2) + 2


def checkpoint_cost(costs, stride, K):
    """Predicted cost (passes over the 2^K states) of the forward–backward DP with this stride.

    Forward, the recomputed operations of every segment (all but its last), the
    adjoint (twice the forward), and :data:`TOUCH_COST` per state array when the plan
    needs more than :data:`FRESH_BYTES`.
    """
    nops = len(costs)
    total = int(np.sum(costs))
    # segment [t0, t1) recomputes t0 .. t1 − 2: everything but each segment's last op
    recompute = 0
    if stride > 1:
        recompute = total - int(np.sum(costs[stride - 1 :: stride]))
        if nops % stride:
            recompute -= int(costs[-1])
    arrays = checkpoint_arrays(nops, stride)
    touch = TOUCH_COST * arrays if arrays * (8 << K) > FRESH_BYTES else 0
    return 3 * total + recompute + touch


def checkpoint_plan(op_kind, op_arg, lay_slot, K, max_memory):
    """``(stride, state_bytes)`` of the cheapest checkpointing of this plan within ``max_memory``.

    The cheapest by :func:`checkpoint_cost` among the strides whose
    :func:`checkpoint_arrays` fit (ties: the least memory), so a larger budget, which
    only adds candidates, never gives a plan predicted slower. ``stride`` is 0 when
    none fits; ``state_bytes`` is then the least memory any stride needs.
    """
    nops = op_kind.size
    per = 8 << K
    need = checkpoint_arrays(nops, 1) * per
    if need <= max_memory and need <= FRESH_BYTES:
        # no first touch and nothing recomputed: every other stride costs more. The
        # tracker's small clusters take this path, with no numpy call per block.
        return 1, need
    costs = op_costs(op_kind, op_arg, lay_slot)
    best = None
    least = None
    for stride in range(1, max(nops, 1) + 1):
        need = checkpoint_arrays(nops, stride) * per
        least = need if least is None else min(least, need)
        if need > max_memory:
            continue
        key = (checkpoint_cost(costs, stride, K), need, stride)
        if best is None or key < best:
            best = key
    if best is None:
        return 0, least
    return best[2], best[1]
