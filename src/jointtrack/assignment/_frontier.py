"""Forward–backward frontier subset DP of one dual-scaled block, with checkpointing.

Step 4 of :mod:`jointtrack.assignment.core`, driver. Runs the plan of
:mod:`._exact_plan` (layer steps and item-leave steps) with the block kernels of
:mod:`._exact_kernels`, on the whole state array or, for large states, split over
numba threads (:func:`_fwd_par`, :func:`_bwd_par`): the forward pass stores each
step's input array; the terminal step lets the still-open items leave
(``b_T(S) = Π_{open c ∉ S} v_c``); the backward (adjoint) pass contracts the
stored inputs with the backward messages, giving every marginal for the cost of
about three forward passes. When the stored arrays would exceed the memory budget, only every
``stride``-th forward array is kept and the segments between are recomputed in the
backward pass (``⌈nops/stride⌉ + stride + 1`` arrays, at most one extra forward pass;
:func:`jointtrack.assignment._plan.checkpoint_plan` picks the stride, the cheapest that
fits, so a larger budget never makes the DP slower). The first forward array e_∅ is not
kept, and the segment's arrays double as the forward pass's buffers. Powers of
two renormalise an array only if its sum leaves [2^-600, 2^600]; the exponents are
tracked and added back into log Z and into each contraction's scale.

On the way to the parallel kernels only :func:`frontier_dp` and :func:`frontier_value`
are cached, and they are only called from Python; the ``parallel=True`` kernels and
everything between them and these two (:func:`_op_fwd`, :func:`_layer_fwd`,
:func:`_layer_bwd`) are not cached, so they are always compiled in one piece with
the cached caller. numba records
that a ``parallel=True`` function must start its threading layer when loaded from
the cache, but a caller compiled on a callee that was itself *loaded* from the
cache does not inherit that note: with these kernels cached, ``jointtrack run``
cached ``_op_fwd``, the README's saddle example then compiled ``frontier_value``
on it, and every later load of ``frontier_value`` died with SIGSEGV (numba issues
#8578, #4807; tests/test_numba_cache.py checks the rule on every jitted function).
Serial callees (:mod:`._kernels`) are unaffected and stay cached.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from jointtrack.assignment._kernels import (
    _bwd_blocks,
    _fwd_blocks,
    _leave_bwd,
    _leave_fwd,
    _split_slots,
)

_BLOCK_BITS = 11  # 2048 float64 = 16 KiB: blocks of x and y stay in L1
_RENORM_HI = 2.0**600
_RENORM_LO = 2.0**-600


@numba.njit(parallel=True)
def _fwd_par(x, y, kb, u, ws, his, hq, los, lq, w3, small, nchunk):
    nblk = x.size >> kb
    parts = np.zeros(nchunk)
    for c in numba.prange(nchunk):
        parts[c] = _fwd_blocks(
            x,
            y,
            kb,
            u,
            ws,
            his,
            hq,
            los,
            lq,
            w3,
            small,
            c * nblk // nchunk,
            (c + 1) * nblk // nchunk,
        )
    return parts.sum()


@numba.njit(parallel=True)
def _bwd_par(F, b, bp, kb, u, ws, his, hq, los, lq, w3, q3, small, nchunk):
    nblk = b.size >> kb
    parts = np.zeros((nchunk, ws.size + 5))
    for c in numba.prange(nchunk):
        _bwd_blocks(
            F,
            b,
            bp,
            kb,
            u,
            ws,
            his,
            hq,
            los,
            lq,
            w3,
            q3,
            small,
            c * nblk // nchunk,
            (c + 1) * nblk // nchunk,
            parts[c],
        )
    return parts.sum(axis=0)


@numba.njit
def _layer_fwd(x, y, kb, u, slots, ws, nchunk):
    """One measurement (layer) step of the forward DP; returns Σ y."""
    his, hq, los, lq, w3, q3, small = _split_slots(kb, slots, ws)
    if nchunk > 1:
        return _fwd_par(x, y, kb, u, ws, his, hq, los, lq, w3, small, nchunk)
    return _fwd_blocks(x, y, kb, u, ws, his, hq, los, lq, w3, small, 0, x.size >> kb)


@numba.njit
def _layer_bwd(F, b, bp, kb, u, slots, ws, nchunk):
    """Adjoint of :func:`_layer_fwd` + contraction; returns (acc per slot, Σ F·b, Σ bp)."""
    his, hq, los, lq, w3, q3, small = _split_slots(kb, slots, ws)
    nq = ws.size
    if nchunk > 1:
        acc = _bwd_par(F, b, bp, kb, u, ws, his, hq, los, lq, w3, q3, small, nchunk)
    else:
        acc = np.zeros(nq + 5)
        _bwd_blocks(F, b, bp, kb, u, ws, his, hq, los, lq, w3, q3, small, 0, b.size >> kb, acc)
    out = acc[:nq].copy()
    for s in range(3):
        if q3[s] >= 0:
            out[q3[s]] += acc[nq + 2 + s]
    return out, acc[nq], acc[nq + 1]


@numba.njit(cache=True)
def _renorm(y, tot):
    """Scale y by a power of two if Σ y left [2^-600, 2^600]; return the exponent added."""
    if tot > _RENORM_HI or (tot > 0.0 and tot < _RENORM_LO):
        m, e = math.frexp(tot)
        sc = math.ldexp(1.0, -e)
        for i in range(y.size):
            y[i] *= sc
        return e
    return 0


@numba.njit(cache=True)
def _layer_lists(W, lay_slot, a):
    C = W.shape[1]
    cnt = 0
    for c in range(C):
        if lay_slot[a, c] >= 0:
            cnt += 1
    slots = np.empty(cnt, np.int64)
    ws = np.empty(cnt)
    items = np.empty(cnt, np.int64)
    cnt = 0
    for c in range(C):
        if lay_slot[a, c] >= 0:
            slots[cnt] = lay_slot[a, c]
            ws[cnt] = W[a, c]
            items[cnt] = c
            cnt += 1
    return slots, ws, items


@numba.njit
def _op_fwd(k, a, x, y, kb, nchunk, W, u, v, lay_slot, slot_of):
    if k == 0:
        slots, ws, _ = _layer_lists(W, lay_slot, a)
        return _layer_fwd(x, y, kb, u[a], slots, ws, nchunk)
    return _leave_fwd(x, y, slot_of[a], v[a])


@numba.njit(cache=True)
def frontier_dp(W, u, v, K, op_kind, op_arg, slot_of, lay_slot, term, stride, nchunk):
    """Forward–backward frontier DP for layers = rows of W, items = columns.

    Returns (pl, pi, pe, logZ') with pl[r] = P(layer r unassigned),
    pi[c] = P(item c unassigned), pe[r, c] = P(r ↔ c).
    ``stride`` ≥ 1: only the forward arrays F_stride, F_2·stride, … are kept
    (checkpoints) and each segment between two of them is recomputed in the
    backward pass; :func:`jointtrack.assignment._plan.checkpoint_arrays` state
    arrays in all (``stride`` = 1 keeps every F_t and recomputes nothing).
    """
    R, C = W.shape
    n = np.int64(1) << K
    kb = min(K, _BLOCK_BITS)
    nops = op_kind.size
    ncp = (nops + stride - 1) // stride  # segments; segment sg starts at F_{sg·stride}
    # CP[j - 1] = F_{j·stride}; F_0 = e_∅ is not kept (rebuilt in seg[0] for segment 0).
    # seg holds one segment's recomputed arrays and serves the forward pass as its two
    # rolling buffers and the final array F_nops, so nothing else is allocated for them.
    CP = np.empty((ncp - 1, n))
    seg = np.empty((max(stride, 2), n))
    fe = np.zeros(nops + 1, np.int64)  # power-of-two exponent of each forward array
    # ---- forward
    x = seg[0]
    x[:] = 0.0
    x[0] = 1.0
    xs = 0  # the seg buffer x is in (-1: a checkpoint)
    for t in range(nops):
        if (t + 1) % stride == 0 and t + 1 < nops:
            y = CP[(t + 1) // stride - 1]
            ys = -1
        else:
            ys = 1 if xs == 0 else 0
            y = seg[ys]
        mx = _op_fwd(op_kind[t], op_arg[t], x, y, kb, nchunk, W, u, v, lay_slot, slot_of)
        fe[t + 1] = fe[t] + _renorm(y, mx)
        x = y
        xs = ys
    FT = x
    # ---- terminal: items still open leave with weight v (b_T(S) = Π_{open c ∉ S} v_c)
    b = np.ones(n)
    bp = np.empty(n)
    nt = term.size
    for q in range(nt):
        s = slot_of[term[q]]
        vv = v[term[q]]
        step = np.int64(1) << s
        for b0 in range(0, n, 2 * step):
            for t in range(step):
                b[b0 + t] *= vv
    Zs = 0.0
    for i in range(n):
        Zs += FT[i] * b[i]
    if not (Zs > 0.0):
        return np.zeros(R), np.zeros(C), np.zeros((R, C)), -np.inf
    logZ = math.log(Zs) + fe[nops] * math.log(2.0)
    pl = np.zeros(R)
    pi = np.zeros(C)
    pe = np.zeros((R, C))
    for q in range(nt):
        c = term[q]
        s = slot_of[c]
        step = np.int64(1) << s
        acc = 0.0
        for b0 in range(0, n, 2 * step):
            for t in range(step):
                acc += FT[b0 + t] * b[b0 + t]
        pi[c] = acc / Zs
    be = 0  # exponent of b
    # ---- backward, segment by segment (the forward buffers in seg are free now)
    for sg in range(ncp - 1, -1, -1):
        t0 = sg * stride
        t1 = min(t0 + stride, nops)
        if sg == 0:
            start = seg[0]
            start[:] = 0.0
            start[0] = 1.0
        else:
            start = CP[sg - 1]
        x = start
        for t in range(t0, t1 - 1):
            y = seg[t - t0 + 1]
            _op_fwd(op_kind[t], op_arg[t], x, y, kb, nchunk, W, u, v, lay_slot, slot_of)
            # renormalise exactly as in the forward pass
            e = fe[t + 1] - fe[t]
            if e != 0:
                sc = math.ldexp(1.0, -e)
                for i in range(n):
                    y[i] *= sc
            x = y
        for t in range(t1 - 1, t0 - 1, -1):
            F = start if t == t0 else seg[t - t0]
            k = op_kind[t]
            a = op_arg[t]
            # scale of a contraction F_t · b_{t+1} relative to Z
            lsc = fe[t] + be - fe[nops]
            if k == 0:
                slots, ws, items = _layer_lists(W, lay_slot, a)
                acc, accu, mx = _layer_bwd(F, b, bp, kb, u[a], slots, ws, nchunk)
                pl[a] = math.ldexp(u[a] * accu / Zs, lsc)
                for q in range(items.size):
                    pe[a, items[q]] = math.ldexp(ws[q] * acc[q] / Zs, lsc)
            else:
                acc1, mx = _leave_bwd(F, b, bp, slot_of[a], v[a])
                pi[a] = math.ldexp(v[a] * acc1 / Zs, lsc)
            be += _renorm(bp, mx)
            tmp = b
            b = bp
            bp = tmp
    return pl, pi, pe, logZ


@numba.njit(cache=True)
def frontier_value(W, u, v, K, op_kind, op_arg, slot_of, lay_slot, term, nchunk):
    """Forward pass only: ``log Z'`` of the block, with two state arrays (no marginals)."""
    n = np.int64(1) << K
    kb = min(K, _BLOCK_BITS)
    nops = op_kind.size
    x = np.zeros(n)
    y = np.empty(n)
    x[0] = 1.0
    exponent = 0
    for t in range(nops):
        mx = _op_fwd(op_kind[t], op_arg[t], x, y, kb, nchunk, W, u, v, lay_slot, slot_of)
        exponent += _renorm(y, mx)
        x, y = y, x
    # terminal: still-open items are left unused with weight v
    total = 0.0
    for i in range(n):
        total += x[i]
    for q in range(term.size):
        total = _leave_fwd(x, y, slot_of[term[q]], v[term[q]])
        exponent += _renorm(y, total)
        x, y = y, x
    total = 0.0
    for i in range(n):
        total += x[i]
    if not (total > 0.0):
        return -np.inf
    return math.log(total) + exponent * math.log(2.0)
