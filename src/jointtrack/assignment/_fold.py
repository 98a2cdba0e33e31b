"""Leaf folding on the bipartite gating graph, its inverse, and component splitting.

Steps 1–2 of :mod:`jointtrack.assignment.core`. Rows are tracks, columns are
measurements; ``W[r, c]`` is the (split-float) likelihood ratio of a gated pair,
``u[r]`` a track's unassigned (miss) weight, ``v[c]`` a measurement's unassigned
(clutter) weight. A node with a single gated partner is summed out exactly into
that partner: folding row r (gated only with col c) into c replaces
``v_c ← v_c·u_r + W[r, c]`` and ``W[r', c] ← W[r', c]·u_r``, and columns fold into
rows symmetrically. Repeating this until every node has ≥ 2 partners removes
tree-shaped clusters entirely and shrinks the rest before the subset DP; what
remains splits into independent connected components.

:func:`_prepare` runs everything before the block DPs (split floats, folding,
components); :func:`_finish` undoes the folding on the marginals and assembles
``beta``. All arithmetic is on split floats (:mod:`._scaled`) and only adds and
multiplies non-negative numbers.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from jointtrack.assignment._splitfloat import split_add, split_normalize, split_ratio

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
            lm, le = split_normalize(vm[c] * um[r], ve[c] + ue[r])
            nm, ne = split_add(lm, le, Wm[r, c], We[r, c])
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
                        m2, e2 = split_normalize(Wm[rr, c] * um[r], We[rr, c] + ue[r])
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
            lm, le = split_normalize(um[r] * vm[c], ue[r] + ve[c])
            nm, ne = split_add(lm, le, Wm[r, c], We[r, c])
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
                        m2, e2 = split_normalize(Wm[r, cc] * vm[c], We[r, cc] + ve[c])
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
            pe[r, c] = merged * split_ratio(rec_m[step, 0], rec_e[step, 0], nm, ne)
            pvc = merged * split_ratio(rec_m[step, 1], rec_e[step, 1], nm, ne)
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
            pe[r, c] = merged * split_ratio(rec_m[step, 0], rec_e[step, 0], nm, ne)
            pur = merged * split_ratio(rec_m[step, 1], rec_e[step, 1], nm, ne)
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


@numba.njit(cache=True)
def _prepare(L, miss):
    """Split floats, leaf folding, components (everything before the block DPs).

    Returns ``(folds, graph, ncomp, infeasible, logz)``: ``folds`` = (rk, rn, ro,
    rm, re, kill_t), the fold records that :func:`_finish` takes first;
    ``graph`` = (lab_r, lab_c, E, Wm, We, um, ue, vm, ve), the component labels,
    alive gating graph and split-float weights that
    :func:`~._dual_scaling._block` takes after the block index; ``logz`` the log
    weight of the isolated nodes summed out.
    """
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
        (rk, rn, ro, rm, re, kill_t),
        (lab_r, lab_c, E, Wm, We, um, ue, vm, ve),
        ncomp,
        infeasible,
        logz,
    )


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
