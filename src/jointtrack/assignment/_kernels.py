"""Blocked forward and adjoint kernels of one frontier-DP step.

Step 4 of :mod:`jointtrack.assignment.core`, inner loops. The state is an array
over subsets S of the K frontier slots (bit s of the index = slot s used). A
layer (an item of the non-state side) with unassigned weight u and gated slots
s with weights w_s maps

    y(S) = u·x(S) + Σ_{gated s ∈ S} w_s·x(S∖s),

and an item leaving the frontier with unassigned weight v maps
``y(S) = v·x(S) + x(S∪s)`` for S ∌ s. The backward (adjoint) kernels apply the
transposed maps to the backward messages and, fused in the same sweep, contract
them with the stored forward inputs to give every marginal of the step.

The state array is processed in blocks of 2^kb entries (``kb`` ≤ ``_BLOCK_BITS``
of :mod:`._exact_dp`, L1-sized): slots ≥ kb select a source block, so their
update is a contiguous AXPY between blocks; slots 3..kb-1 are strided AXPYs
inside a block; the three lowest slots use explicit 8-element code. Every kernel
works on a block range [hb0, hb1), so :mod:`._exact_dp` can run it on the whole
array or split the blocks over numba threads; :func:`_split_slots` turns a layer's
slots into the kernels' arguments.
"""

from __future__ import annotations

import numba
import numpy as np

# ``reassoc`` lets LLVM vectorise the floating-point sums. Rule for every kernel
# compiled with it: no loop both stores to an array and accumulates a sum. A loop
# that stores gets a runtime alias check between its arrays (numba cannot say
# they are distinct), and when two small state arrays happen to lie within a
# vector's span of each other in memory the scalar fallback runs instead, which
# sums in another order: the result then depended on where the allocator put the
# arrays, and the same tracker run differed in the last bit from one process to
# the next. Sums therefore run in load-only loops, whose vector/scalar split
# depends only on the trip count.
_FM = {"reassoc", "contract", "nsz", "arcp"}


@numba.njit(cache=True)
def _split_slots(kb, slots, ws):
    """Split a layer's gated slots into block-level (≥ kb), generic in-block (3..kb-1)
    and the three lowest slots (handled with explicit 8-element code)."""
    nl = slots.size
    small = kb >= 3
    nhi = 0
    nlo = 0
    for q in range(nl):
        if slots[q] >= kb:
            nhi += 1
        elif not small or slots[q] >= 3:
            nlo += 1
    his = np.empty(nhi, np.int64)
    hq = np.empty(nhi, np.int64)
    los = np.empty(nlo, np.int64)
    lq = np.empty(nlo, np.int64)
    w3 = np.zeros(3)
    q3 = np.full(3, -1, np.int64)
    a = 0
    b = 0
    for q in range(nl):
        s = slots[q]
        if s >= kb:
            his[a] = s - kb
            hq[a] = q
            a += 1
        elif not small or s >= 3:
            los[b] = s
            lq[b] = q
            b += 1
        else:
            w3[s] = ws[q]
            q3[s] = q
    return his, hq, los, lq, w3, q3, small


@numba.njit(cache=True, inline="always")
def _gather(hb, kb, ws, his, hq, src, wt, qi, adjoint):
    """Source blocks of block hb: (hb ∖ slot) for the forward, (hb ∪ slot) for the
    adjoint; fills src (first index), wt (weight), qi (slot index q); returns the count."""
    na = 0
    for q in range(his.size):
        hbit = 1 << his[q]
        if adjoint:
            if hb & hbit:
                continue
            src[na] = (hb | hbit) << kb
        else:
            if not (hb & hbit):
                continue
            src[na] = (hb ^ hbit) << kb
        wt[na] = ws[hq[q]]
        qi[na] = hq[q]
        na += 1
    return na


@numba.njit(cache=True, fastmath=_FM)
def _fwd_blocks(x, y, kb, u, ws, his, hq, los, lq, w3, small, hb0, hb1):
    """Layer update on blocks [hb0, hb1): y(S) = u·x(S) + Σ_{gated s ∈ S} w_s·x(S∖s).

    Every inner loop is a contiguous pass over L1-resident blocks: the block-level
    slots are fused three or four source blocks per pass over y (the first pass
    also writes u·x), so y is loaded and stored once per four sources instead of
    once per source; in-block slots are strided AXPYs; the three lowest slots use
    explicit 8-element code. Returns Σ y over the blocks (a separate load-only pass).
    """
    B = 1 << kb
    w0 = w3[0]
    w1 = w3[1]
    w2 = w3[2]
    src = np.empty(his.size + 4, np.int64)
    wt = np.empty(his.size + 4)
    qi = np.empty(his.size + 4, np.int64)
    tot = 0.0
    for hb in range(hb0, hb1):
        base = hb << kb
        yb = y[base : base + B]
        xb = x[base : base + B]
        na = _gather(hb, kb, ws, his, hq, src, wt, qi, False)
        i = 0
        if na >= 3:
            a = x[src[0] : src[0] + B]
            b = x[src[1] : src[1] + B]
            c = x[src[2] : src[2] + B]
            wa = wt[0]
            wb = wt[1]
            wc = wt[2]
            for t in range(B):
                yb[t] = u * xb[t] + wa * a[t] + wb * b[t] + wc * c[t]
            i = 3
        elif na == 2:
            a = x[src[0] : src[0] + B]
            b = x[src[1] : src[1] + B]
            wa = wt[0]
            wb = wt[1]
            for t in range(B):
                yb[t] = u * xb[t] + wa * a[t] + wb * b[t]
            i = 2
        elif na == 1:
            a = x[src[0] : src[0] + B]
            wa = wt[0]
            for t in range(B):
                yb[t] = u * xb[t] + wa * a[t]
            i = 1
        else:
            for t in range(B):
                yb[t] = u * xb[t]
        while na - i >= 4:
            a = x[src[i] : src[i] + B]
            b = x[src[i + 1] : src[i + 1] + B]
            c = x[src[i + 2] : src[i + 2] + B]
            d = x[src[i + 3] : src[i + 3] + B]
            wa = wt[i]
            wb = wt[i + 1]
            wc = wt[i + 2]
            wd = wt[i + 3]
            for t in range(B):
                yb[t] += wa * a[t] + wb * b[t] + wc * c[t] + wd * d[t]
            i += 4
        if na - i == 3:
            a = x[src[i] : src[i] + B]
            b = x[src[i + 1] : src[i + 1] + B]
            c = x[src[i + 2] : src[i + 2] + B]
            wa = wt[i]
            wb = wt[i + 1]
            wc = wt[i + 2]
            for t in range(B):
                yb[t] += wa * a[t] + wb * b[t] + wc * c[t]
        elif na - i == 2:
            a = x[src[i] : src[i] + B]
            b = x[src[i + 1] : src[i + 1] + B]
            wa = wt[i]
            wb = wt[i + 1]
            for t in range(B):
                yb[t] += wa * a[t] + wb * b[t]
        elif na - i == 1:
            a = x[src[i] : src[i] + B]
            wa = wt[i]
            for t in range(B):
                yb[t] += wa * a[t]
        for q in range(los.size):
            step = 1 << los[q]
            w = ws[lq[q]]
            for b0 in range(0, B, 2 * step):
                ys = yb[b0 + step : b0 + 2 * step]
                xs = xb[b0 : b0 + step]
                for t in range(step):
                    ys[t] += w * xs[t]
        sb = 0.0
        if small:
            for i8 in range(0, B, 8):
                x0 = xb[i8]
                x1 = xb[i8 + 1]
                x2 = xb[i8 + 2]
                x4 = xb[i8 + 4]
                y1 = yb[i8 + 1] + w0 * x0
                y2 = yb[i8 + 2] + w1 * x0
                y3 = yb[i8 + 3] + (w0 * x2 + w1 * x1)
                y4 = yb[i8 + 4] + w2 * x0
                y5 = yb[i8 + 5] + (w0 * x4 + w2 * x1)
                y6 = yb[i8 + 6] + (w1 * x4 + w2 * x2)
                y7 = yb[i8 + 7] + (w0 * xb[i8 + 6] + w1 * xb[i8 + 5] + w2 * xb[i8 + 3])
                yb[i8 + 1] = y1
                yb[i8 + 2] = y2
                yb[i8 + 3] = y3
                yb[i8 + 4] = y4
                yb[i8 + 5] = y5
                yb[i8 + 6] = y6
                yb[i8 + 7] = y7
        for t in range(B):
            sb += yb[t]
        tot += sb
    return tot


@numba.njit(cache=True, fastmath=_FM)
def _bwd_blocks(F, b, bp, kb, u, ws, his, hq, los, lq, w3, q3, small, hb0, hb1, acc):
    """Adjoint layer update and the marginal contraction, block by block on [hb0, hb1).

    bp(S) = u·b(S) + Σ_{gated s ∉ S} w_s·b(S∪s);  acc[q] += Σ_{S ∌ s_q} F(S)·b(S∪s_q);
    acc[nq] += Σ F·b (the layer-unassigned term); acc[nq+1] = Σ bp. Block-level
    source blocks are taken two or three per pass; each pass is a store loop
    (bp) followed by a load-only loop (the contractions) over the same
    L1-resident block, as the rule above ``_FM`` requires.
    """
    B = 1 << kb
    nq = ws.size
    w0 = w3[0]
    w1 = w3[1]
    w2 = w3[2]
    a0 = 0.0
    a1 = 0.0
    a2 = 0.0
    su = 0.0
    tot = 0.0
    src = np.empty(his.size + 4, np.int64)
    wt = np.empty(his.size + 4)
    qi = np.empty(his.size + 4, np.int64)
    for hb in range(hb0, hb1):
        base = hb << kb
        bb = b[base : base + B]
        pb = bp[base : base + B]
        fb = F[base : base + B]
        na = _gather(hb, kb, ws, his, hq, src, wt, qi, True)
        s0 = 0.0
        i = 0
        if na >= 2:
            c1 = b[src[0] : src[0] + B]
            c2 = b[src[1] : src[1] + B]
            wa = wt[0]
            wb_ = wt[1]
            sa = 0.0
            sb_ = 0.0
            for t in range(B):
                pb[t] = u * bb[t] + wa * c1[t] + wb_ * c2[t]
            for t in range(B):
                f = fb[t]
                s0 += f * bb[t]
                sa += f * c1[t]
                sb_ += f * c2[t]
            acc[qi[0]] += sa
            acc[qi[1]] += sb_
            i = 2
        elif na == 1:
            c1 = b[src[0] : src[0] + B]
            wa = wt[0]
            sa = 0.0
            for t in range(B):
                pb[t] = u * bb[t] + wa * c1[t]
            for t in range(B):
                f = fb[t]
                s0 += f * bb[t]
                sa += f * c1[t]
            acc[qi[0]] += sa
            i = 1
        else:
            for t in range(B):
                pb[t] = u * bb[t]
            for t in range(B):
                s0 += fb[t] * bb[t]
        su += s0
        while na - i >= 3:
            c1 = b[src[i] : src[i] + B]
            c2 = b[src[i + 1] : src[i + 1] + B]
            c3 = b[src[i + 2] : src[i + 2] + B]
            wa = wt[i]
            wb_ = wt[i + 1]
            wc = wt[i + 2]
            sa = 0.0
            sb_ = 0.0
            sc = 0.0
            for t in range(B):
                pb[t] += wa * c1[t] + wb_ * c2[t] + wc * c3[t]
            for t in range(B):
                f = fb[t]
                sa += f * c1[t]
                sb_ += f * c2[t]
                sc += f * c3[t]
            acc[qi[i]] += sa
            acc[qi[i + 1]] += sb_
            acc[qi[i + 2]] += sc
            i += 3
        if na - i == 2:
            c1 = b[src[i] : src[i] + B]
            c2 = b[src[i + 1] : src[i + 1] + B]
            wa = wt[i]
            wb_ = wt[i + 1]
            sa = 0.0
            sb_ = 0.0
            for t in range(B):
                pb[t] += wa * c1[t] + wb_ * c2[t]
            for t in range(B):
                f = fb[t]
                sa += f * c1[t]
                sb_ += f * c2[t]
            acc[qi[i]] += sa
            acc[qi[i + 1]] += sb_
        elif na - i == 1:
            c1 = b[src[i] : src[i] + B]
            wa = wt[i]
            sa = 0.0
            for t in range(B):
                pb[t] += wa * c1[t]
            for t in range(B):
                sa += fb[t] * c1[t]
            acc[qi[i]] += sa
        for q in range(los.size):
            step = 1 << los[q]
            w = ws[lq[q]]
            sq = 0.0
            for b0 in range(0, B, 2 * step):
                ps = pb[b0 : b0 + step]
                fs = fb[b0 : b0 + step]
                bs = bb[b0 + step : b0 + 2 * step]
                for t in range(step):
                    ps[t] += w * bs[t]
                for t in range(step):
                    sq += fs[t] * bs[t]
            acc[lq[q]] += sq
        if small:
            for i8 in range(0, B, 8):
                b1 = bb[i8 + 1]
                b2 = bb[i8 + 2]
                b3 = bb[i8 + 3]
                b4 = bb[i8 + 4]
                b5 = bb[i8 + 5]
                b6 = bb[i8 + 6]
                b7 = bb[i8 + 7]
                pb[i8] += w0 * b1 + w1 * b2 + w2 * b4
                pb[i8 + 1] += w1 * b3 + w2 * b5
                pb[i8 + 2] += w0 * b3 + w2 * b6
                pb[i8 + 3] += w2 * b7
                pb[i8 + 4] += w0 * b5 + w1 * b6
                pb[i8 + 5] += w1 * b7
                pb[i8 + 6] += w0 * b7
            for i8 in range(0, B, 8):
                b7 = bb[i8 + 7]
                f0 = fb[i8]
                a0 += (
                    f0 * bb[i8 + 1]
                    + fb[i8 + 2] * bb[i8 + 3]
                    + fb[i8 + 4] * bb[i8 + 5]
                    + fb[i8 + 6] * b7
                )
                a1 += (
                    f0 * bb[i8 + 2]
                    + fb[i8 + 1] * bb[i8 + 3]
                    + fb[i8 + 4] * bb[i8 + 6]
                    + fb[i8 + 5] * b7
                )
                a2 += (
                    f0 * bb[i8 + 4]
                    + fb[i8 + 1] * bb[i8 + 5]
                    + fb[i8 + 2] * bb[i8 + 6]
                    + fb[i8 + 3] * b7
                )
        sb = 0.0
        for t in range(B):
            sb += pb[t]
        tot += sb
    if small:
        acc[nq + 2] += a0
        acc[nq + 3] += a1
        acc[nq + 4] += a2
    acc[nq] += su
    acc[nq + 1] += tot


@numba.njit(cache=True, fastmath=_FM)
def _leave_fwd(x, y, s, v):
    """Item in slot s leaves: y(S) = v·x(S) + x(S∪s) for S ∌ s, y(S∪s) = 0; returns Σ y."""
    n = x.size
    step = 1 << s
    for b0 in range(0, n, 2 * step):
        for t in range(step):
            y[b0 + t] = v * x[b0 + t] + x[b0 + step + t]
            y[b0 + step + t] = 0.0
    tot = 0.0
    for i in range(n):
        tot += y[i]
    return tot


@numba.njit(cache=True, fastmath=_FM)
def _leave_bwd(F, b, bp, s, v):
    """Adjoint of :func:`_leave_fwd`; returns (Σ_{S∌s} F(S)·b(S), Σ bp)."""
    n = b.size
    step = 1 << s
    for b0 in range(0, n, 2 * step):
        for t in range(step):
            val = b[b0 + t]
            bp[b0 + t] = v * val
            bp[b0 + step + t] = val
    acc = 0.0
    tot = 0.0
    for b0 in range(0, n, 2 * step):
        for t in range(step):
            acc += F[b0 + t] * b[b0 + t]
            tot += b[b0 + t]
    return acc, tot * (1.0 + v)
