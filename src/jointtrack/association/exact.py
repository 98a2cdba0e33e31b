"""Exact JPDA marginals without enumerating joint hypotheses.

The JPDA association probabilities of a cluster are ratios of sums over joint
association events (Bojilov et al., eqs. (5)–(7) and the marginal sum
``p_ij = Σ_{l ∈ L_j} P(H_l)`` after (6)). With the DESIGN.md convention
(likelihood ratios ``L`` and miss weights ``miss``, i.e. (7) with the common
factor ``β^{N_M}`` removed) an event's weight is

    w(H) = Π_{(i,j) ∈ H} L[i, j] · Π_{tracks i unassigned in H} miss[i],

measurements not assigned in ``H`` are clutter (weight 1), and

    beta[i, 0] = Σ_{H: i unassigned} w(H) / Z,   beta[i, j+1] = Σ_{H ∋ (i,j)} w(H) / Z,

with ``Z = Σ_H w(H)`` the normaliser of (6).

How it is computed (never enumerating events):

1. **Leaf folding.** A measurement gated by a single track, or a track gating a
   single measurement, is summed out exactly into its neighbour (the neighbour's
   "unassigned" weight absorbs the leaf's alternatives); repeated until every
   remaining node has ≥ 2 gated partners. Tree-shaped clusters disappear entirely.
   Done on split floats (mantissa, power-of-two exponent), so nothing
   over/underflows and nothing loses precision to exp(log(·)).
2. **Independent blocks.** What remains splits into connected components.
3. **Dual scaling.** Per block, the optimal dual of the max-weight association
   (a shortest-augmenting-path assignment solve on log weights) gives row and
   column scale factors, rounded to powers of two (exact), after which every
   factor is ≤ ~1 and the best event has weight ≈ 1. Every event that matters
   (≥ 1e-300 of the best) then has all partial products ≥ ~1e-300 — no underflow
   anywhere in the DP, for any scale of L (a DP merely normalised per layer by
   its maximum loses such paths; see the tests).
4. **Frontier subset DP, forward–backward.** One side (tracks or measurements,
   whichever gives the smaller frontier) is the state: the subset of the *open*
   items (seen and still gated by an unprocessed item of the other side) that
   are already used. Items of the other side are processed one layer at a time
   in a greedy order that keeps the frontier small; an item leaving the frontier
   is summed out. The forward pass stores its layer inputs; the backward (adjoint)
   pass contracts them with the backward messages, giving every marginal for the
   cost of about three forward passes. The state array is processed in
   cache-sized blocks so that every inner loop is a contiguous AXPY or dot
   product. Powers of two renormalise a layer only if it leaves [2^-600, 2^600].

The DP only adds and multiplies non-negative numbers: the result is exact to
rounding (relative error of order (layers + items)·1e-16 on every marginal).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from jointtrack.association._validate import check_cluster
from jointtrack.errors import InfeasibleAssignmentError

__all__ = [
    "ExactResult",
    "exact_jpda",
    "exact_log_normalizer",
    "exact_marginals",
]

_FM = {"reassoc", "contract", "nsz", "arcp"}
_BLOCK_BITS = 11  # 2048 float64 = 16 KiB: blocks of x and y stay in L1
_RENORM_HI = 2.0**600
_RENORM_LO = 2.0**-600
_PAR_MIN_BITS = 16  # use the multi-thread kernels from 2^16 states up
DEFAULT_MAX_BITS = 30
DEFAULT_MAX_MEMORY = 2 * 1024**3


@dataclass(frozen=True)
class ExactResult:
    """Result of :func:`exact_jpda`.

    Attributes
    ----------
    beta : ndarray (N, M+1)
        Association probabilities; column 0 = no measurement (Bojilov's p_i0).
    log_normalizer : float
        ``log Z``, natural log of the sum of (7)-weights of all feasible joint
        events (the denominator of (6)).
    n_components : int
        Independent blocks solved by the subset DP after leaf folding.
    max_frontier : int
        Largest DP state width (bits) over the blocks (0 if everything folded).
    n_folded : int
        Nodes (tracks + measurements) summed out by leaf folding.
    state_bytes : int
        Bytes of DP state arrays allocated at the peak (the dominant memory).
    """

    beta: np.ndarray
    log_normalizer: float
    n_components: int
    max_frontier: int
    n_folded: int
    state_bytes: int


# ---------------------------------------------------------------------------
# split floats: value = m · 2^e with m ∈ [0.5, 1) (or m = 0): no over/underflow,
# one rounding per operation whatever the magnitude.
# ---------------------------------------------------------------------------


@numba.njit(cache=True)
def _sn(m, e):
    if m == 0.0:
        return 0.0, np.int64(0)
    f, k = math.frexp(m)
    return f, e + k


@numba.njit(cache=True)
def _sadd(m1, e1, m2, e2):
    if m1 == 0.0:
        return m2, e2
    if m2 == 0.0:
        return m1, e1
    if e1 >= e2:
        d = e2 - e1
        return _sn(m1 + (math.ldexp(m2, d) if d > -1100 else 0.0), e1)
    d = e1 - e2
    return _sn(m2 + (math.ldexp(m1, d) if d > -1100 else 0.0), e2)


@numba.njit(cache=True)
def _sratio(m1, e1, m2, e2):
    """(m1·2^e1) / (m2·2^e2) as a float (m2 > 0)."""
    d = e1 - e2
    if d < -1100:
        return 0.0
    return math.ldexp(m1 / m2, d)


# ---------------------------------------------------------------------------
# 1. leaf folding on the bipartite gating graph (rows = tracks, cols = measurements)
# ---------------------------------------------------------------------------

_ISO_ROW, _ISO_COL, _FOLD_ROW, _FOLD_COL = 0, 1, 2, 3


@numba.njit(cache=True)
def _fold_leaves(Wm, We, um, ue, vm, ve):
    """Sum out degree-≤1 nodes of the gating graph, in place, on split floats.

    ``W = Wm·2^We`` (R×C, 0 = not gated), ``u`` (R, a row's unassigned weight),
    ``v`` (C). Folding row r (gated only with col c) into c replaces
    ``v_c ← v_c·u_r + W[r, c]`` and ``W[r', c] ← W[r', c]·u_r``; columns fold
    into rows symmetrically. Returns the fold records, the kill step of every
    edge, the alive masks and an infeasibility flag.
    """
    R, C = Wm.shape
    deg_r = np.zeros(R, np.int64)
    deg_c = np.zeros(C, np.int64)
    big = np.int64(1) << 62
    kill_t = np.full((R, C), big, np.int64)
    for r in range(R):
        for c in range(C):
            if Wm[r, c] > 0.0:
                deg_r[r] += 1
                deg_c[c] += 1
            else:
                kill_t[r, c] = -1
    alive_r = np.ones(R, np.bool_)
    alive_c = np.ones(C, np.bool_)
    nrec_max = R + C
    rec_kind = np.empty(nrec_max, np.int64)
    rec_node = np.empty(nrec_max, np.int64)
    rec_other = np.empty(nrec_max, np.int64)
    rec_m = np.empty((nrec_max, 3))  # W[r,c], old unassigned·leaf, new unassigned
    rec_e = np.empty((nrec_max, 3), np.int64)
    nrec = 0
    queue = np.empty(4 * (R + C) + 4, np.int64)  # id < R: row, else column id − R
    qh = 0
    qt = 0
    for r in range(R):
        if deg_r[r] <= 1:
            queue[qt] = r
            qt += 1
    for c in range(C):
        if deg_c[c] <= 1:
            queue[qt] = R + c
            qt += 1
    infeasible = False
    while qh < qt:
        node = queue[qh]
        qh += 1
        if node < R:
            r = node
            if not alive_r[r] or deg_r[r] > 1:
                continue
            step = nrec
            nrec += 1
            rec_node[step] = r
            if deg_r[r] == 0:
                if um[r] == 0.0:
                    infeasible = True
                alive_r[r] = False
                rec_kind[step] = _ISO_ROW
                rec_other[step] = -1
                continue
            c = -1
            for cc in range(C):
                if kill_t[r, cc] > step:
                    c = cc
                    break
            lm, le = _sn(vm[c] * um[r], ve[c] + ue[r])
            nm, ne = _sadd(lm, le, Wm[r, c], We[r, c])
            rec_kind[step] = _FOLD_ROW
            rec_other[step] = c
            rec_m[step, 0] = Wm[r, c]
            rec_e[step, 0] = We[r, c]
            rec_m[step, 1] = lm
            rec_e[step, 1] = le
            rec_m[step, 2] = nm
            rec_e[step, 2] = ne
            vm[c] = nm
            ve[c] = ne
            for rr in range(R):
                if rr != r and kill_t[rr, c] > step:
                    if um[r] == 0.0:
                        kill_t[rr, c] = step
                        deg_r[rr] -= 1
                        deg_c[c] -= 1
                        if deg_r[rr] <= 1:
                            queue[qt] = rr
                            qt += 1
                    else:
                        m2, e2 = _sn(Wm[rr, c] * um[r], We[rr, c] + ue[r])
                        Wm[rr, c] = m2
                        We[rr, c] = e2
            kill_t[r, c] = step
            deg_r[r] = 0
            deg_c[c] -= 1
            alive_r[r] = False
            if deg_c[c] <= 1:
                queue[qt] = R + c
                qt += 1
        else:
            c = node - R
            if not alive_c[c] or deg_c[c] > 1:
                continue
            step = nrec
            nrec += 1
            rec_node[step] = c
            if deg_c[c] == 0:
                if vm[c] == 0.0:
                    infeasible = True
                alive_c[c] = False
                rec_kind[step] = _ISO_COL
                rec_other[step] = -1
                continue
            r = -1
            for rr in range(R):
                if kill_t[rr, c] > step:
                    r = rr
                    break
            lm, le = _sn(um[r] * vm[c], ue[r] + ve[c])
            nm, ne = _sadd(lm, le, Wm[r, c], We[r, c])
            rec_kind[step] = _FOLD_COL
            rec_other[step] = r
            rec_m[step, 0] = Wm[r, c]
            rec_e[step, 0] = We[r, c]
            rec_m[step, 1] = lm
            rec_e[step, 1] = le
            rec_m[step, 2] = nm
            rec_e[step, 2] = ne
            um[r] = nm
            ue[r] = ne
            for cc in range(C):
                if cc != c and kill_t[r, cc] > step:
                    if vm[c] == 0.0:
                        kill_t[r, cc] = step
                        deg_c[cc] -= 1
                        deg_r[r] -= 1
                        if deg_c[cc] <= 1:
                            queue[qt] = R + cc
                            qt += 1
                    else:
                        m2, e2 = _sn(Wm[r, cc] * vm[c], We[r, cc] + ve[c])
                        Wm[r, cc] = m2
                        We[r, cc] = e2
            kill_t[r, c] = step
            deg_c[c] = 0
            deg_r[r] -= 1
            alive_c[c] = False
            if deg_r[r] <= 1:
                queue[qt] = r
                qt += 1
    return (
        rec_kind[:nrec],
        rec_node[:nrec],
        rec_other[:nrec],
        rec_m[:nrec],
        rec_e[:nrec],
        kill_t,
        alive_r,
        alive_c,
        infeasible,
    )


@numba.njit(cache=True)
def _unfold(rec_kind, rec_node, rec_other, rec_m, rec_e, kill_t, pu, pv, pe):
    """Undo :func:`_fold_leaves` on the marginals, in reverse order (in place).

    Only non-negative sums: P(leaf unassigned) is rebuilt as the sum of the
    neighbour's other alternatives, not as 1 − P(pair).
    """
    R, C = pe.shape
    for step in range(len(rec_kind) - 1, -1, -1):
        k = rec_kind[step]
        if k == _ISO_ROW:
            pu[rec_node[step]] = 1.0
        elif k == _ISO_COL:
            pv[rec_node[step]] = 1.0
        elif k == _FOLD_ROW:
            r = rec_node[step]
            c = rec_other[step]
            merged = pv[c]
            nm = rec_m[step, 2]
            ne = rec_e[step, 2]
            pe[r, c] = merged * _sratio(rec_m[step, 0], rec_e[step, 0], nm, ne)
            pvc = merged * _sratio(rec_m[step, 1], rec_e[step, 1], nm, ne)
            pv[c] = pvc
            s = pvc
            for rr in range(R):
                if rr != r and kill_t[rr, c] > step:
                    s += pe[rr, c]
            pu[r] = s
        else:
            c = rec_node[step]
            r = rec_other[step]
            merged = pu[r]
            nm = rec_m[step, 2]
            ne = rec_e[step, 2]
            pe[r, c] = merged * _sratio(rec_m[step, 0], rec_e[step, 0], nm, ne)
            pur = merged * _sratio(rec_m[step, 1], rec_e[step, 1], nm, ne)
            pu[r] = pur
            s = pur
            for cc in range(C):
                if cc != c and kill_t[r, cc] > step:
                    s += pe[r, cc]
            pv[c] = s


@numba.njit(cache=True)
def _components(E, alive_r, alive_c):
    """Connected components of the alive gating graph ``E`` (bool R×C): row and col labels."""
    R, C = E.shape
    lab_r = np.full(R, -1, np.int64)
    lab_c = np.full(C, -1, np.int64)
    stack = np.empty(R + C, np.int64)
    ncomp = 0
    for r0 in range(R):
        if not alive_r[r0] or lab_r[r0] >= 0:
            continue
        lab_r[r0] = ncomp
        sp = 0
        stack[sp] = r0
        sp += 1
        while sp > 0:
            sp -= 1
            node = stack[sp]
            if node < R:
                for c in range(C):
                    if alive_c[c] and lab_c[c] < 0 and E[node, c]:
                        lab_c[c] = ncomp
                        stack[sp] = R + c
                        sp += 1
            else:
                c = node - R
                for r in range(R):
                    if alive_r[r] and lab_r[r] < 0 and E[r, c]:
                        lab_r[r] = ncomp
                        stack[sp] = r
                        sp += 1
        ncomp += 1
    return lab_r, lab_c, ncomp


# ---------------------------------------------------------------------------
# 3. dual scaling: shortest augmenting path assignment with potentials
# ---------------------------------------------------------------------------


@numba.njit(cache=True)
def _lsap_duals(cost):
    """Min-cost perfect matching of a square cost matrix (inf = forbidden).

    Shortest augmenting paths with potentials (Jonker–Volgenant / Crouse form).
    Returns ``(u, v, ok)`` with ``cost[i, j] − u[i] − v[j] ≥ 0`` everywhere and
    equality on the optimal matching; ``ok`` is False if no finite matching exists.
    """
    n = cost.shape[0]
    u = np.zeros(n)
    v = np.zeros(n)
    spc = np.empty(n)
    path = np.full(n, -1, np.int64)
    col4row = np.full(n, -1, np.int64)
    row4col = np.full(n, -1, np.int64)
    SR = np.zeros(n, np.bool_)
    SC = np.zeros(n, np.bool_)
    remaining = np.empty(n, np.int64)
    for cur in range(n):
        min_val = 0.0
        i = cur
        num_rem = n
        for it in range(n):
            remaining[it] = n - it - 1
        SR[:] = False
        SC[:] = False
        spc[:] = np.inf
        sink = -1
        while sink == -1:
            index = -1
            lowest = np.inf
            SR[i] = True
            for it in range(num_rem):
                j = remaining[it]
                r = min_val + cost[i, j] - u[i] - v[j]
                if r < spc[j]:
                    path[j] = i
                    spc[j] = r
                if spc[j] < lowest or (spc[j] == lowest and row4col[j] == -1):
                    lowest = spc[j]
                    index = it
            min_val = lowest
            if min_val == np.inf or index < 0:
                return u, v, False
            j = remaining[index]
            if row4col[j] == -1:
                sink = j
            else:
                i = row4col[j]
            SC[j] = True
            num_rem -= 1
            remaining[index] = remaining[num_rem]
        u[cur] += min_val
        for ii in range(n):
            if SR[ii] and ii != cur:
                u[ii] += min_val - spc[col4row[ii]]
        for jj in range(n):
            if SC[jj]:
                v[jj] -= min_val - spc[jj]
        j = sink
        while True:
            i = path[j]
            row4col[j] = i
            tmp = col4row[i]
            col4row[i] = j
            j = tmp
            if i == cur:
                break
    return u, v, True


@numba.njit(cache=True)
def _dual_scale(lw, lu, lv):
    """Row/column log scale factors (α, γ) making every factor ≤ 1 and the best event = 1.

    The association problem is embedded in an (R+C)×(C+R) assignment problem
    (row r ↔ col c, row r ↔ its own "unassigned" dummy, col c ↔ its dummy, dummy ↔
    dummy where (r, c) is gated); its optimal dual gives the scales. Returns
    ``(alpha, gamma, log_best, ok)``.
    """
    R, C = lw.shape
    n = R + C
    cost = np.full((n, n), np.inf)
    for r in range(R):
        for c in range(C):
            if lw[r, c] > -np.inf:
                cost[r, c] = -lw[r, c]
                cost[R + c, C + r] = 0.0
        if lu[r] > -np.inf:
            cost[r, C + r] = -lu[r]
    for c in range(C):
        if lv[c] > -np.inf:
            cost[R + c, c] = -lv[c]
    u, v, ok = _lsap_duals(cost)
    alpha = np.empty(R)
    gamma = np.empty(C)
    for r in range(R):
        alpha[r] = u[r] + v[C + r]
    for c in range(C):
        gamma[c] = v[c] + u[R + c]
    return alpha, gamma, -(u.sum() + v.sum()), ok


# ---------------------------------------------------------------------------
# 4. the frontier subset DP
# ---------------------------------------------------------------------------


@numba.njit(cache=True)
def _plan(G):
    """Greedy layer order and slot assignment for layers = rows of boolean ``G``.

    Picks next the layer that opens the fewest new items net of the items it
    closes. Returns ``(order, K, op_kind, op_arg, lay_slot(R×C), term_items)``:
    ``op_kind`` 0 = process layer ``op_arg``, 1 = item ``op_arg`` leaves the
    frontier; items still open after the last layer are ``term_items``.
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
        done[best] = True
        order[step] = best
        for c in range(C):
            if G[best, c]:
                opened[c] = True
                rem[c] -= 1
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


@numba.njit(cache=True, parallel=True)
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


@numba.njit(cache=True, parallel=True)
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


@numba.njit(cache=True)
def _layer_fwd(x, y, kb, u, slots, ws, nchunk):
    """One measurement (layer) step of the forward DP; returns Σ y."""
    his, hq, los, lq, w3, q3, small = _split_slots(kb, slots, ws)
    if nchunk > 1:
        return _fwd_par(x, y, kb, u, ws, his, hq, los, lq, w3, small, nchunk)
    return _fwd_blocks(x, y, kb, u, ws, his, hq, los, lq, w3, small, 0, x.size >> kb)


@numba.njit(cache=True)
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


@numba.njit(cache=True)
def _op_fwd(k, a, x, y, kb, nchunk, W, u, v, lay_slot, slot_of):
    if k == 0:
        slots, ws, _ = _layer_lists(W, lay_slot, a)
        return _layer_fwd(x, y, kb, u[a], slots, ws, nchunk)
    return _leave_fwd(x, y, slot_of[a], v[a])


@numba.njit(cache=True)
def _dp_run(W, u, v, K, op_kind, op_arg, slot_of, lay_slot, term, stride, nchunk):
    """Forward–backward frontier DP for layers = rows of W, items = columns.

    Returns (pl, pi, pe, logZ') with pl[r] = P(layer r unassigned),
    pi[c] = P(item c unassigned), pe[r, c] = P(r ↔ c).
    ``stride`` > 1 keeps only every stride-th forward array and recomputes
    segments in the backward pass (memory ∝ nops/stride + stride).
    """
    R, C = W.shape
    n = np.int64(1) << K
    kb = min(K, _BLOCK_BITS)
    nops = op_kind.size
    ncp = (nops + stride - 1) // stride
    CP = np.empty((ncp, n))
    fe = np.zeros(nops + 1, np.int64)  # power-of-two exponent of each forward array
    # ---- forward
    CP[0, :] = 0.0
    CP[0, 0] = 1.0
    if stride == 1:
        FT = np.empty(n)
        for t in range(nops):
            y = CP[t + 1] if t + 1 < nops else FT
            mx = _op_fwd(op_kind[t], op_arg[t], CP[t], y, kb, nchunk, W, u, v, lay_slot, slot_of)
            fe[t + 1] = fe[t] + _renorm(y, mx)
        seg = np.empty((0, n))
    else:
        buf = np.empty((2, n))
        FT = np.empty(n)
        x = CP[0]
        for t in range(nops):
            if t + 1 == nops:
                y = FT
            elif (t + 1) % stride == 0:
                y = CP[(t + 1) // stride]
            else:
                y = buf[t % 2]
            mx = _op_fwd(op_kind[t], op_arg[t], x, y, kb, nchunk, W, u, v, lay_slot, slot_of)
            fe[t + 1] = fe[t] + _renorm(y, mx)
            x = y
        seg = np.empty((stride, n))
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
    # ---- backward, segment by segment
    nseg = ncp
    for sg in range(nseg - 1, -1, -1):
        t0 = sg * stride
        t1 = min(t0 + stride, nops)
        if stride > 1:
            seg[0, :] = CP[sg]
            for t in range(t0, t1 - 1):
                _op_fwd(
                    op_kind[t],
                    op_arg[t],
                    seg[t - t0],
                    seg[t - t0 + 1],
                    kb,
                    nchunk,
                    W,
                    u,
                    v,
                    lay_slot,
                    slot_of,
                )
                # renormalise exactly as in the forward pass
                e = fe[t + 1] - fe[t]
                if e != 0:
                    sc = math.ldexp(1.0, -e)
                    for i in range(n):
                        seg[t - t0 + 1, i] *= sc
        for t in range(t1 - 1, t0 - 1, -1):
            F = CP[t] if stride == 1 else seg[t - t0]
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
def _prepare(L, miss):
    """Split floats, leaf folding, components (everything before the block DPs)."""
    N, M = L.shape
    Wm = np.empty((N, M))
    We = np.empty((N, M), np.int64)
    for r in range(N):
        for c in range(M):
            m, e = math.frexp(L[r, c])
            Wm[r, c] = m
            We[r, c] = e
    um = np.empty(N)
    ue = np.empty(N, np.int64)
    for r in range(N):
        m, e = math.frexp(miss[r])
        um[r] = m
        ue[r] = e
    vm = np.full(M, 0.5)
    ve = np.ones(M, np.int64)
    rk, rn, ro, rm, re, kill_t, alive_r, alive_c, infeasible = _fold_leaves(Wm, We, um, ue, vm, ve)
    ln2 = math.log(2.0)
    logz = 0.0
    for q in range(rk.size):
        if rk[q] == _ISO_ROW:
            logz += math.log(um[rn[q]]) + ue[rn[q]] * ln2 if um[rn[q]] > 0 else -np.inf
        elif rk[q] == _ISO_COL:
            logz += math.log(vm[rn[q]]) + ve[rn[q]] * ln2 if vm[rn[q]] > 0 else -np.inf
    E = kill_t > rk.size
    lab_r, lab_c, ncomp = _components(E, alive_r, alive_c)
    return (
        Wm,
        We,
        um,
        ue,
        vm,
        ve,
        rk,
        rn,
        ro,
        rm,
        re,
        kill_t,
        infeasible,
        logz,
        E,
        lab_r,
        lab_c,
        ncomp,
    )


@numba.njit(cache=True)
def _block(k, lab_r, lab_c, E, Wm, We, um, ue, vm, ve):
    """Extract block k, dual-scale it by exact powers of two.

    Returns (rows, cols, W, u, v, shift, ok): every scaled factor ≤ ~1, the best
    event ≈ 1, ``shift`` = log of the scale removed (add back to log Z).
    """
    rows = np.flatnonzero(lab_r == k)
    cols = np.flatnonzero(lab_c == k)
    R = rows.size
    C = cols.size
    ln2 = math.log(2.0)
    lw = np.full((R, C), -np.inf)
    lu = np.full(R, -np.inf)
    lv = np.full(C, -np.inf)
    for a in range(R):
        r = rows[a]
        if um[r] > 0:
            lu[a] = math.log(um[r]) + ue[r] * ln2
        for b in range(C):
            c = cols[b]
            if E[r, c] and Wm[r, c] > 0:
                lw[a, b] = math.log(Wm[r, c]) + We[r, c] * ln2
    for b in range(C):
        c = cols[b]
        if vm[c] > 0:
            lv[b] = math.log(vm[c]) + ve[c] * ln2
    alpha, gamma, _, ok = _dual_scale(lw, lu, lv)
    W = np.zeros((R, C))
    u = np.zeros(R)
    v = np.zeros(C)
    ka = np.empty(R, np.int64)
    kg = np.empty(C, np.int64)
    for a in range(R):
        ka[a] = np.int64(np.rint(alpha[a] / ln2)) if ok else 0
    for b in range(C):
        kg[b] = np.int64(np.rint(gamma[b] / ln2)) if ok else 0
    # exact power-of-two scales (a row/column scaling leaves the marginals unchanged)
    for a in range(R):
        r = rows[a]
        u[a] = math.ldexp(um[r], ue[r] + ka[a])
        for b in range(C):
            c = cols[b]
            if E[r, c]:
                W[a, b] = math.ldexp(Wm[r, c], We[r, c] + ka[a] + kg[b])
    for b in range(C):
        c = cols[b]
        v[b] = math.ldexp(vm[c], ve[c] + kg[b])
    shift = (ka.sum() + kg.sum()) * ln2
    return rows, cols, W, u, v, shift, ok


@numba.njit(cache=True)
def _scatter(rows, cols, bu, bv, be, pu, pv, pe):
    for a in range(rows.size):
        pu[rows[a]] = bu[a]
        for b in range(cols.size):
            pe[rows[a], cols[b]] = be[a, b]
    for b in range(cols.size):
        pv[cols[b]] = bv[b]


@numba.njit(cache=True)
def _finish(rk, rn, ro, rm, re, kill_t, pu, pv, pe):
    """Unfold the leaves and assemble beta = [pu | pe], rows renormalised to sum 1."""
    _unfold(rk, rn, ro, rm, re, kill_t, pu, pv, pe)
    N, M = pe.shape
    beta = np.empty((N, M + 1))
    for r in range(N):
        s = pu[r]
        for c in range(M):
            s += pe[r, c]
        beta[r, 0] = pu[r] / s
        for c in range(M):
            beta[r, c + 1] = pe[r, c] / s
    return beta


_INFEASIBLE_MSG = (
    "no feasible joint association event: tracks with miss = 0 (certainly detected) "
    "cannot all be given distinct gated measurements"
)


def _solve_block(W, u, v, max_bits, max_memory, parallel=False):
    """Forward–backward DP of one dual-scaled block (rows = tracks, cols = measurements).

    Returns (pu, pv, pe, logZ', K, state_bytes) with pu/pv the rows'/cols'
    unassigned probabilities and pe[r, c] the pair probabilities.
    """
    G = W > 0.0
    R, C = G.shape
    # orientation: state over columns (layers = rows) or over rows (layers = cols)
    plan_a = _plan(G)
    plan_b = _plan(np.ascontiguousarray(G.T))
    # cost ≈ layers · 2^K (layers = rows for plan_a, columns for plan_b)
    transpose = C * 2.0 ** plan_b[1] < R * 2.0 ** plan_a[1]
    if transpose:
        W, u, v = np.ascontiguousarray(W.T), v, u
        plan = plan_b
    else:
        plan = plan_a
    _, K, op_kind, op_arg, slot_of, lay_slot, term = plan
    if K > max_bits:
        raise ValueError(
            f"exact JPDA needs a DP state of 2^{K} subsets for this cluster "
            f"({R} tracks, {C} measurements in one inseparable block), above the "
            f"limit 2^{max_bits}; use method='lbp', 'mcmc' or 'kbest', or raise max_bits"
        )
    n = 1 << K
    nops = op_kind.size
    per = 8 * n
    stride = 1
    if (nops + 3) * per > max_memory:
        stride = max(2, int(math.ceil(math.sqrt(nops))))
        if (math.ceil(nops / stride) + stride + 4) * per > max_memory:
            raise ValueError(
                f"exact JPDA for this block needs more than max_memory = {max_memory} bytes "
                f"(2^{K} states × {nops} layers even with checkpointing); use method='lbp', "
                "'mcmc' or 'kbest'"
            )
    if stride == 1:
        state_bytes = (nops + 3) * per
    else:
        state_bytes = (math.ceil(nops / stride) + stride + 4) * per
    nchunk = 1
    if parallel and K >= _PAR_MIN_BITS and numba.get_num_threads() > 1:
        nchunk = 4 * numba.get_num_threads()
    pl, pi, pe, logZ = _dp_run(W, u, v, K, op_kind, op_arg, slot_of, lay_slot, term, stride, nchunk)
    if not np.isfinite(logZ):
        raise InfeasibleAssignmentError(_INFEASIBLE_MSG)
    if transpose:
        return pi, pl, np.ascontiguousarray(pe.T), logZ, K, state_bytes
    return pl, pi, pe, logZ, K, state_bytes


def _solve(L, miss, max_bits=DEFAULT_MAX_BITS, max_memory=DEFAULT_MAX_MEMORY, parallel=False):
    L, miss = check_cluster(L, miss)
    N, M = L.shape
    if N == 0:
        return ExactResult(np.zeros((0, M + 1)), 0.0, 0, 0, 0, 0)
    (
        Wm,
        We,
        um,
        ue,
        vm,
        ve,
        rk,
        rn,
        ro,
        rm,
        re,
        kill_t,
        infeasible,
        logZ,
        E,
        lab_r,
        lab_c,
        ncomp,
    ) = _prepare(L, miss)
    if infeasible:
        raise InfeasibleAssignmentError(_INFEASIBLE_MSG)
    pu = np.zeros(N)
    pv = np.zeros(M)
    pe = np.zeros((N, M))
    kmax = 0
    peak = 0
    for k in range(ncomp):
        rows, cols, W, u, v, shift, ok = _block(k, lab_r, lab_c, E, Wm, We, um, ue, vm, ve)
        if not ok:
            raise InfeasibleAssignmentError(_INFEASIBLE_MSG)
        bu, bv, be, lz, K, sb = _solve_block(W, u, v, max_bits, max_memory, parallel)
        _scatter(rows, cols, bu, bv, be, pu, pv, pe)
        logZ += lz - shift
        kmax = max(kmax, K)
        peak = max(peak, sb)
    beta = _finish(rk, rn, ro, rm, re, kill_t, pu, pv, pe)
    return ExactResult(beta, float(logZ), int(ncomp), int(kmax), int(len(rk)), int(peak))


def exact_jpda(
    L,
    miss,
    *,
    max_bits: int = DEFAULT_MAX_BITS,
    max_memory: int = DEFAULT_MAX_MEMORY,
    parallel: bool = False,
) -> ExactResult:
    """Exact JPDA association probabilities and normaliser (Bojilov eqs. (5)–(7)).

    Computes ``p_ij = Σ_{l ∈ L_j} P(H_l)`` (the marginal sum following (6)) for
    every track i and measurement j, and p_i0, exactly, by the leaf-folding +
    frontier subset DP described in the module docstring — never enumerating
    joint hypotheses.

    Parameters
    ----------
    L : array (N, M)
        Likelihood ratios ``P_D g_ij / λ`` (0 = not gated).
    miss : array (N,)
        ``1 − P_D P_G`` per track.
    max_bits : int
        Refuse blocks whose DP state would exceed 2^max_bits subsets.
    max_memory : int
        Byte budget for the DP state arrays; above it the forward pass is
        checkpointed (one extra forward pass), and beyond that refused.
    parallel : bool
        Split large layers (≥ 2^16 states) over numba's threads. Off by default:
        the kernels are memory-bound and, on a machine whose cores are busy,
        thread barriers cost more than they save.

    Returns
    -------
    ExactResult

    Raises
    ------
    ValueError
        bad input (see :func:`~jointtrack.association._validate.check_cluster`),
        or a block too large for ``max_bits`` / ``max_memory``.
    InfeasibleAssignmentError
        no feasible joint event (certainly-detected tracks cannot all be served).
    """
    return _solve(L, miss, max_bits, max_memory, parallel)


def exact_marginals(
    L,
    miss,
    *,
    max_bits: int = DEFAULT_MAX_BITS,
    max_memory: int = DEFAULT_MAX_MEMORY,
    parallel: bool = False,
) -> np.ndarray:
    """Exact JPDA marginals ``beta`` (N × (M+1)), Bojilov eqs. (5)–(7) and the sum after (6).

    ``beta[i, 0]`` is the probability that track i has no measurement,
    ``beta[i, j+1]`` that measurement j is track i's. Rows sum to 1. See
    :func:`exact_jpda` for the parameters and errors.
    """
    return _solve(L, miss, max_bits, max_memory, parallel).beta


def exact_log_normalizer(
    L, miss, *, max_bits: int = DEFAULT_MAX_BITS, max_memory: int = DEFAULT_MAX_MEMORY
) -> float:
    """``log Σ_H P'(H)``: natural log of the normaliser of Bojilov eq. (6) with (7) weights.

    With ``L = (L > 0)`` and ``miss = (miss > 0)`` this is the log of the number
    of feasible joint hypotheses (used by :func:`count_hypotheses`).
    """
    return _solve(L, miss, max_bits, max_memory).log_normalizer
