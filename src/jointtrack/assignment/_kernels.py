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


@numba.njit(cache=True, fastmath=_FM)
def _fwd_blocks(x, y, kb, u, ws, his, hq, los, lq, w3, small, hb0, hb1):
    """Layer update on blocks [hb0, hb1): y(S) = u·x(S) + Σ_{gated s ∈ S} w_s·x(S∖s).

    Every inner loop is a contiguous AXPY on L1-resident blocks; the three
    lowest slots use explicit 8-element code. Returns Σ y over the blocks.
    """
    B = 1 << kb
    w0 = w3[0]
    w1 = w3[1]
    w2 = w3[2]
    tot = 0.0
    for hb in range(hb0, hb1):
        base = hb << kb
        yb = y[base : base + B]
        xb = x[base : base + B]
        for t in range(B):
            yb[t] = u * xb[t]
        for q in range(his.size):
            hbit = 1 << his[q]
            if hb & hbit:
                src = (hb ^ hbit) << kb
                xs = x[src : src + B]
                w = ws[hq[q]]
                for t in range(B):
                    yb[t] += w * xs[t]
        for q in range(los.size):
            step = 1 << los[q]
            w = ws[lq[q]]
            for b0 in range(0, B, 2 * step):
                ys = yb[b0 + step : b0 + 2 * step]
                xs = xb[b0 : b0 + step]
                for t in range(step):
                    ys[t] += w * xs[t]
        if small:
            for i in range(0, B, 8):
                x0 = xb[i]
                x1 = xb[i + 1]
                x2 = xb[i + 2]
                x4 = xb[i + 4]
                yb[i + 1] += w0 * x0
                yb[i + 2] += w1 * x0
                yb[i + 3] += w0 * x2 + w1 * x1
                yb[i + 4] += w2 * x0
                yb[i + 5] += w0 * x4 + w2 * x1
                yb[i + 6] += w1 * x4 + w2 * x2
                yb[i + 7] += w0 * xb[i + 6] + w1 * xb[i + 5] + w2 * xb[i + 3]
        sb = 0.0
        for t in range(B):
            sb += yb[t]
        tot += sb
    return tot


@numba.njit(cache=True, fastmath=_FM)
def _bwd_blocks(F, b, bp, kb, u, ws, his, hq, los, lq, w3, q3, small, hb0, hb1, acc):
    """Adjoint layer update fused with the marginal contraction, on blocks [hb0, hb1).

    bp(S) = u·b(S) + Σ_{gated s ∉ S} w_s·b(S∪s);  acc[q] += Σ_{S ∌ s_q} F(S)·b(S∪s_q);
    acc[nq] += Σ F·b (the layer-unassigned term); acc[nq+1] = Σ bp.
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
    for hb in range(hb0, hb1):
        base = hb << kb
        bb = b[base : base + B]
        pb = bp[base : base + B]
        fb = F[base : base + B]
        s0 = 0.0
        for t in range(B):
            bv = bb[t]
            pb[t] = u * bv
            s0 += fb[t] * bv
        su += s0
        for q in range(his.size):
            hbit = 1 << his[q]
            if not (hb & hbit):
                src = (hb | hbit) << kb
                bs = b[src : src + B]
                w = ws[hq[q]]
                sq = 0.0
                for t in range(B):
                    bv = bs[t]
                    pb[t] += w * bv
                    sq += fb[t] * bv
                acc[hq[q]] += sq
        for q in range(los.size):
            step = 1 << los[q]
            w = ws[lq[q]]
            sq = 0.0
            for b0 in range(0, B, 2 * step):
                ps = pb[b0 : b0 + step]
                fs = fb[b0 : b0 + step]
                bs = bb[b0 + step : b0 + 2 * step]
                for t in range(step):
                    bv = bs[t]
                    ps[t] += w * bv
                    sq += fs[t] * bv
            acc[lq[q]] += sq
        if small:
            for i in range(0, B, 8):
                b1 = bb[i + 1]
                b2 = bb[i + 2]
                b3 = bb[i + 3]
                b4 = bb[i + 4]
                b5 = bb[i + 5]
                b6 = bb[i + 6]
                b7 = bb[i + 7]
                f0 = fb[i]
                f1 = fb[i + 1]
                f2 = fb[i + 2]
                f4 = fb[i + 4]
                pb[i] += w0 * b1 + w1 * b2 + w2 * b4
                pb[i + 1] += w1 * b3 + w2 * b5
                pb[i + 2] += w0 * b3 + w2 * b6
                pb[i + 3] += w2 * b7
                pb[i + 4] += w0 * b5 + w1 * b6
                pb[i + 5] += w1 * b7
                pb[i + 6] += w0 * b7
                a0 += f0 * b1 + f2 * b3 + f4 * b5 + fb[i + 6] * b7
                a1 += f0 * b2 + f1 * b3 + f4 * b6 + fb[i + 5] * b7
                a2 += f0 * b4 + f1 * b5 + f2 * b6 + fb[i + 3] * b7
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
    tot = 0.0
    for b0 in range(0, n, 2 * step):
        for t in range(step):
            val = v * x[b0 + t] + x[b0 + step + t]
            y[b0 + t] = val
            y[b0 + step + t] = 0.0
            tot += val
    return tot


@numba.njit(cache=True, fastmath=_FM)
def _leave_bwd(F, b, bp, s, v):
    """Adjoint of :func:`_leave_fwd`; returns (Σ_{S∌s} F(S)·b(S), Σ bp)."""
    n = b.size
    step = 1 << s
    acc = 0.0
    tot = 0.0
    for b0 in range(0, n, 2 * step):
        for t in range(step):
            val = b[b0 + t]
            bp[b0 + t] = v * val
            bp[b0 + step + t] = val
            acc += F[b0 + t] * val
            tot += val
    return acc, tot * (1.0 + v)
