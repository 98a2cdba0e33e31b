"""Compiled kernels of the PMBM global-hypothesis update: ranking and combination.

The update of :class:`~jointtrack.trackers.pmbm.PMBMTracker` (A. F. García-Fernández,
J. L. Williams, K. Granström and L. Svensson, "Poisson multi-Bernoulli mixture
filter: direct derivation and implementation", *IEEE Transactions on Aerospace and
Electronic Systems* 54(4):1883–1901, 2018, §V) takes from each prior global
hypothesis h the k_h best association events. Tracks that share no gated return
are independent, so the events are ranked per cluster of tracks and per distinct
tuple of single-target hypotheses (STHs) the cluster holds across the global
hypotheses, and the ranked lists of a hypothesis' clusters are combined exactly.

Kernels do that over flat arrays, with no per-hypothesis Python object:

* :func:`track_clusters` — the clusters: tracks connected through the gated
  returns of any of their STHs (union–find);
* :func:`rank_tuples` — the k best events of every tuple of one cluster: one
  Bernoulli by sorting its options, several by Murty's algorithm
  (:func:`jointtrack.association.kbest._murty`, the package's one ranking
  kernel over its one LSAP kernel, called directly);
* :func:`combine_events` — for every prior hypothesis the k_h best sums of its
  clusters' ranked lists (a best-first search over the grid of two ranked lists,
  cluster after cluster), written out as rows of child-STH indices;
* :func:`merge_identical` — hypotheses that became identical (after pruning and
  recycling) are one, with the log of their summed weights.

Both are exact: the events of :func:`rank_tuples` are those of Murty's ranking
(ties in its creation order), the sums of :func:`combine_events` are the k best
in the order (−sum, index in the first list, index in the second), which is the
order of a stable sort of the whole grid. Their inputs are checked here, at the
boundary (:func:`check_pair_weights`, and the per-call checks of both wrappers):
a kernel never sees an unchecked array.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from jointtrack.association.kbest import _murty, _pairwise_sum, _stable_order_decreasing

__all__ = [
    "PairWeights",
    "RankedLists",
    "TrackClusters",
    "check_pair_weights",
    "combine_events",
    "distinct_rows",
    "merge_identical",
    "rank_tuples",
    "track_clusters",
]


class PairWeights(NamedTuple):
    """The gated (STH, return) pairs of one scan, checked (:func:`check_pair_weights`).

    ``start[s] .. start[s + 1] − 1``: the pairs of STH s (pairs sorted by STH);
    ``cols`` each pair's return; ``L``, ``log_L`` its likelihood ratio and log;
    ``miss``, ``log_miss`` each STH's miss weight and log; ``n_returns`` the
    scan's returns.
    """

    start: np.ndarray
    cols: np.ndarray
    L: np.ndarray
    log_L: np.ndarray
    miss: np.ndarray
    log_miss: np.ndarray
    n_returns: int


class RankedLists(NamedTuple):
    """Ranked event lists of one cluster, one per distinct tuple, flat.

    ``ptr[u] .. ptr[u + 1] − 1``: the events of tuple u, best first; ``w`` their
    log weights; ``child`` (E, n) each track's child STH (its own index when
    missed or absent, S + pair when it takes a return), ``taken`` (E, n) the
    return it takes (−1: none).
    """

    ptr: np.ndarray
    w: np.ndarray
    child: np.ndarray
    taken: np.ndarray


def _int_array(a, name, ndim):
    if type(a) is not np.ndarray or a.dtype != np.int64 or a.ndim != ndim:
        raise TypeError(f"{name} must be a {ndim}-D int64 numpy array")
    return np.ascontiguousarray(a)


def _float_array(a, name):
    if type(a) is not np.ndarray or a.dtype != np.float64 or a.ndim != 1:
        raise TypeError(f"{name} must be a 1-D float64 numpy array")
    return np.ascontiguousarray(a)


def check_pair_weights(start, cols, L, miss, n_returns) -> PairWeights:
    """Check one scan's pair arrays once and take their logs; the result is what the
    kernels read.

    Raises
    ------
    TypeError
        an array of the wrong type, dtype or dimension.
    ValueError
        inconsistent lengths, pairs not sorted by STH, a return index outside
        [0, n_returns), a likelihood ratio that is negative or not finite, or a
        miss weight outside [0, 1].
    """
    start, cols = _int_array(start, "start", 1), _int_array(cols, "cols", 1)
    L, miss = _float_array(L, "L"), _float_array(miss, "miss")
    if type(n_returns) is not int or n_returns < 0:
        raise ValueError(f"n_returns must be a whole number ≥ 0, got {n_returns!r}")
    n_pairs, n_sth = len(cols), len(miss)
    if len(L) != n_pairs:
        raise ValueError(f"L must have one entry per pair ({n_pairs}), got {len(L)}")
    if len(start) != n_sth + 1:
        raise ValueError(f"start must have one entry more than miss ({n_sth}), got {len(start)}")
    if start[0] != 0 or start[-1] != n_pairs or (np.diff(start) < 0).any():
        raise ValueError("start must run from 0 to the number of pairs, non-decreasing")
    if n_pairs and (cols.min() < 0 or cols.max() >= n_returns):
        raise ValueError(f"cols must name returns in [0, {n_returns})")
    if not ((L >= 0) & (L < np.inf)).all():
        raise ValueError("L must hold finite likelihood ratios ≥ 0")
    if not ((miss >= 0) & (miss <= 1)).all():
        raise ValueError("miss must hold weights in [0, 1]")
    with np.errstate(divide="ignore"):  # log 0 = −inf: an option of no weight
        log_L, log_miss = np.log(L), np.log(miss)
    return PairWeights(start, cols, L, log_L, miss, log_miss, n_returns)


@numba.njit(cache=True)
def _event_bound(tup, k, start, miss):
    """min(k, Π options): at most how many events tuple ``tup`` has (options: the
    gated returns of each STH, and the miss where it may miss)."""
    bound = 1
    for t in range(tup.shape[0]):
        s = tup[t]
        if s < 0:
            continue
        options = start[s + 1] - start[s] + (1 if miss[s] > 0 else 0)
        if options == 0:
            return 0
        bound *= options
        if bound >= k:
            return k
    return min(bound, k)


@numba.njit(cache=True)
def _rank_one(tup, k, S, start, cols, L, log_L, miss, log_miss, w_out, child_out, taken_out, at):
    """The ``k`` best events of one tuple into rows ``at …`` of the outputs; returns how
    many (0 when the tuple has no event of positive weight)."""
    n = tup.shape[0]
    n_here = 0
    n_pairs = 0
    for t in range(n):
        if tup[t] >= 0:
            n_here += 1
            n_pairs += start[tup[t] + 1] - start[tup[t]]
    here = np.empty(n_here, np.int64)
    i = 0
    for t in range(n):
        if tup[t] >= 0:
            here[i] = t
            i += 1
    if n_pairs == 0:  # every Bernoulli missed: one event (none when one must be detected)
        vals = np.empty(n_here)
        for i in range(n_here):
            vals[i] = log_miss[tup[here[i]]]
        w = _pairwise_sum(vals, n_here)
        if not np.isfinite(w):
            return 0
        w_out[at] = w
        for t in range(n):
            child_out[at, t] = tup[t]
            taken_out[at, t] = -1
        return 1
    if n_here == 1:  # one Bernoulli: its options sorted
        s = tup[here[0]]
        lo = start[s]
        opts = np.empty(1 + n_pairs)
        opts[0] = log_miss[s]
        for q in range(n_pairs):
            opts[1 + q] = log_L[lo + q]
        order = _stable_order_decreasing(opts)
        found = 0
        for e in range(min(k, 1 + n_pairs)):
            o = order[e]
            if not np.isfinite(opts[o]):
                continue
            r = at + found
            w_out[r] = opts[o]
            for t in range(n):
                child_out[r, t] = tup[t]
                taken_out[r, t] = -1
            if o > 0:
                child_out[r, here[0]] = S + lo + o - 1
                taken_out[r, here[0]] = cols[lo + o - 1]
            found += 1
        return found
    # several Bernoullis: Murty's ranking on the tuple's returns (sorted, distinct)
    ms = np.empty(n_pairs, np.int64)
    q = 0
    for i in range(n_here):
        s = tup[here[i]]
        for p in range(start[s], start[s + 1]):
            ms[q] = cols[p]
            q += 1
    ms = np.unique(ms)
    m = ms.shape[0]
    Lc = np.zeros((n_here, m))
    log_ext = np.zeros((n_here, m + 1))  # log of [miss | L], 0 where a weight is 0
    miss_c = np.empty(n_here)
    pair_of = np.full((n_here, m), -1, np.int64)
    for i in range(n_here):
        s = tup[here[i]]
        miss_c[i] = miss[s]
        if miss[s] > 0:
            log_ext[i, 0] = log_miss[s]
        for p in range(start[s], start[s + 1]):
            j = np.searchsorted(ms, cols[p])
            Lc[i, j] = L[p]
            pair_of[i, j] = p
            if L[p] > 0:
                log_ext[i, j + 1] = log_L[p]
    assignments, log_weights, found = _murty(Lc, miss_c, log_ext, k)
    for e in range(found):
        r = at + e
        w_out[r] = log_weights[e]
        for t in range(n):
            child_out[r, t] = tup[t]
            taken_out[r, t] = -1
        for i in range(n_here):
            a = assignments[e, i]
            if a > 0:
                p = pair_of[i, a - 1]
                child_out[r, here[i]] = S + p
                taken_out[r, here[i]] = cols[p]
    return found


@numba.njit(cache=True)
def _rank_tuples(tuples, ks, S, start, cols, L, log_L, miss, log_miss):
    U, n = tuples.shape
    bound = np.empty(U, np.int64)
    total = 0
    for u in range(U):
        bound[u] = _event_bound(tuples[u], ks[u], start, miss)
        total += bound[u]
    w = np.empty(total)
    child = np.empty((total, n), np.int64)
    taken = np.empty((total, n), np.int64)
    ptr = np.zeros(U + 1, np.int64)
    at = 0
    for u in range(U):
        if bound[u] > 0:
            at += _rank_one(
                tuples[u], ks[u], S, start, cols, L, log_L, miss, log_miss, w, child, taken, at
            )
        ptr[u + 1] = at
    return ptr, w[:at].copy(), child[:at].copy(), taken[:at].copy()


def rank_tuples(tuples, ks, pairs: PairWeights) -> RankedLists:
    """The ``ks[u]`` best association events of each cluster tuple ``tuples[u]``, best first.

    ``tuples`` (U, n) int64: an STH index per track of the cluster (−1: the
    track has no Bernoulli in it); ``pairs`` the scan's checked pair weights. A
    tuple of one Bernoulli ranks its options by sorting (miss first among
    equals), several by Murty's algorithm (the miss weight is the Bernoulli's
    ``miss``, the return j's weight its pair's ``L``); a tuple with no event of
    positive weight gets an empty list.

    Raises
    ------
    TypeError, ValueError
        ``tuples`` or ``ks`` of the wrong type or shape, an STH index outside
        [−1, S), or a k below 1.
    """
    if type(pairs) is not PairWeights:
        raise TypeError("pairs must come from check_pair_weights")
    tuples, ks = _int_array(tuples, "tuples", 2), _int_array(ks, "ks", 1)
    S = len(pairs.miss)
    if len(ks) != len(tuples):
        raise ValueError(f"ks must have one entry per tuple ({len(tuples)}), got {len(ks)}")
    if tuples.size and (tuples.min() < -1 or tuples.max() >= S):
        raise ValueError(f"tuples must hold STH indices in [-1, {S})")
    if len(ks) and ks.min() < 1:
        raise ValueError("ks must be ≥ 1")
    p = pairs
    return RankedLists(
        *_rank_tuples(tuples, ks, S, p.start, p.cols, p.L, p.log_L, p.miss, p.log_miss)
    )


@numba.njit(cache=True)
def _heap_before(vw, vi, vj, a, b):
    # best first: the larger sum, then the smaller index in the first list, then the second
    if vw[a] != vw[b]:
        return vw[a] > vw[b]
    if vi[a] != vi[b]:
        return vi[a] < vi[b]
    return vj[a] < vj[b]


@numba.njit(cache=True)
def _sift_up(heap, i, vw, vi, vj):
    while i > 0:
        up = (i - 1) // 2
        if _heap_before(vw, vi, vj, heap[i], heap[up]):
            heap[i], heap[up] = heap[up], heap[i]
            i = up
        else:
            break


@numba.njit(cache=True)
def _sift_down(heap, size, vw, vi, vj):
    i = 0
    while True:
        left = 2 * i + 1
        if left >= size:
            break
        best = left
        if left + 1 < size and _heap_before(vw, vi, vj, heap[left + 1], heap[left]):
            best = left + 1
        if _heap_before(vw, vi, vj, heap[best], heap[i]):
            heap[i], heap[best] = heap[best], heap[i]
            i = best
        else:
            break


@numba.njit(cache=True)
def _combine_two(a_w, A, b_w, B, k, out_i, out_j, out_w):
    """The min(k, A·B) best sums a_w[i] + b_w[j] of two lists sorted descending, in the
    order (−sum, i, j); returns how many. Best-first over the grid: cell (i, j) enters
    the frontier when (i, j − 1) — or for j = 0, (i − 1, 0) — leaves it, a cell no
    later in that order (float addition is monotone), so each cell enters once."""
    want = min(k, A * B)
    cap = 2 * want + 2
    vw = np.empty(cap)
    vi = np.empty(cap, np.int64)
    vj = np.empty(cap, np.int64)
    heap = np.empty(cap, np.int64)
    vw[0], vi[0], vj[0] = a_w[0] + b_w[0], 0, 0
    heap[0] = 0
    size, made, found = 1, 1, 0
    while found < want:
        top = heap[0]
        size -= 1
        heap[0] = heap[size]
        _sift_down(heap, size, vw, vi, vj)
        i, j = vi[top], vj[top]
        out_i[found], out_j[found], out_w[found] = i, j, vw[top]
        found += 1
        if j + 1 < B:
            vw[made], vi[made], vj[made] = a_w[i] + b_w[j + 1], i, j + 1
            heap[size] = made
            _sift_up(heap, size, vw, vi, vj)
            size += 1
            made += 1
        if j == 0 and i + 1 < A:
            vw[made], vi[made], vj[made] = a_w[i + 1] + b_w[0], i + 1, 0
            heap[size] = made
            _sift_up(heap, size, vw, vi, vj)
            size += 1
            made += 1
    return found


@numba.njit(cache=True)
def _combine_events(
    hyp, base_logw, k_h, new_track_hyp, track_ptr, tracks, list_of, list_ptr, ev_w, ev_ofs,
    ev_child, ev_taken,
):  # fmt: skip
    H, T = hyp.shape
    C = track_ptr.shape[0] - 1
    M = new_track_hyp.shape[0]
    # events per hypothesis: min(k_h, Π list lengths) (each combination truncates to k_h)
    n_events = np.zeros(H, np.int64)
    for h in range(H):
        if not np.isfinite(base_logw[h]):
            continue
        count = 1
        for c in range(C):
            lst = list_of[c, h]
            length = list_ptr[lst + 1] - list_ptr[lst]
            count = min(k_h[h], count * length)
            if count == 0:
                break
        n_events[h] = count
    total = 0
    k_max = 1
    for h in range(H):
        total += n_events[h]
        k_max = max(k_max, n_events[h])
    rows = np.empty((total, T + M), np.int64)
    logw = np.empty(total)
    # the combined events of one hypothesis: sum of the varying clusters' weights and
    # the event chosen in each cluster (global event index), and the next round's
    cur_w = np.empty(k_max)
    cur_sel = np.empty((k_max, C), np.int64)
    nxt_w = np.empty(k_max)
    nxt_sel = np.empty((k_max, C), np.int64)
    pick_i = np.empty(k_max, np.int64)
    pick_j = np.empty(k_max, np.int64)
    at = 0
    for h in range(H):
        E = n_events[h]
        if E == 0:
            continue
        # clusters with one event are constants of the hypothesis, summed in cluster
        # order; the others' lists are combined in cluster order from the sum 0.0
        w_const = 0.0
        cur_w[0] = 0.0
        A = 1
        for c in range(C):
            lst = list_of[c, h]
            lo = list_ptr[lst]
            B = list_ptr[lst + 1] - lo
            if B == 1:
                w_const += ev_w[lo]
                for e in range(A):
                    cur_sel[e, c] = lo
                continue
            got = _combine_two(cur_w, A, ev_w[lo:], B, k_h[h], pick_i, pick_j, nxt_w)
            for e in range(got):
                for c2 in range(C):
                    nxt_sel[e, c2] = cur_sel[pick_i[e], c2]
                nxt_sel[e, c] = lo + pick_j[e]
            cur_w, nxt_w = nxt_w, cur_w
            cur_sel, nxt_sel = nxt_sel, cur_sel
            A = got
        base = base_logw[h] + w_const
        for e in range(E):
            r = at + e
            logw[r] = base + cur_w[e]
            for t in range(T):
                rows[r, t] = hyp[h, t]
            for j in range(M):
                rows[r, T + j] = new_track_hyp[j]
            for c in range(C):
                g = cur_sel[e, c]
                o = ev_ofs[g]
                for q in range(track_ptr[c + 1] - track_ptr[c]):
                    rows[r, tracks[track_ptr[c] + q]] = ev_child[o + q]
                    taken = ev_taken[o + q]
                    if taken >= 0:
                        rows[r, T + taken] = -1
        at += E
    return rows, logw, n_events


def combine_events(hyp, base_logw, k_h, new_track_hyp, clusters):
    """The ``k_h[h]`` best events of every prior global hypothesis h, combined across clusters.

    ``hyp`` (H, T) the prior hypotheses' STH per track; ``base_logw`` (H,) each
    one's log weight with the constants of its tracks that gate nothing (−inf:
    the hypothesis has no event); ``new_track_hyp`` (M,) the STH each return's
    new track holds when no prior track takes the return; ``clusters`` a list of
    ``(tracks, inverse, ranked)``: the cluster's tracks, each hypothesis' tuple
    (H,) and the :class:`RankedLists` of its tuples.

    Returns ``(rows (E, T + M), log weights (E,), n_events (H,))``: the new
    hypotheses in the order of their prior ones, each prior's best first; row
    entries are child STH indices (a track takes its event's child; a new track
    whose return a prior track took holds −1). The log weight of an event is
    ``base_logw[h]`` + the one-event clusters' weights + the combined sum of the
    others', added in cluster order.

    Raises
    ------
    TypeError, ValueError
        arrays of the wrong type or shape, indices out of range, k below 1.
    """
    hyp = _int_array(hyp, "hyp", 2)
    base_logw = _float_array(base_logw, "base_logw")
    k_h, new_track_hyp = _int_array(k_h, "k_h", 1), _int_array(new_track_hyp, "new_track_hyp", 1)
    H, T = hyp.shape
    M = len(new_track_hyp)
    if len(base_logw) != H or len(k_h) != H:
        raise ValueError(f"base_logw and k_h must have one entry per hypothesis ({H})")
    if H and k_h.min() < 1:
        raise ValueError("k_h must be ≥ 1")
    if np.isnan(base_logw).any() or (base_logw == np.inf).any():
        raise ValueError("base_logw must be finite or −inf")
    track_ptr, list_ptr, ev_ofs = [0], [0], []
    parts = {"tracks": [], "list_of": [], "w": [], "child": [], "taken": []}
    seen = np.zeros(T, bool)
    for tracks, inverse, ranked in clusters:
        tracks, inverse = _int_array(tracks, "tracks", 1), _int_array(inverse, "inverse", 1)
        if type(ranked) is not RankedLists:
            raise TypeError("ranked must be RankedLists")
        n = len(tracks)
        U = len(ranked.ptr) - 1
        if (tracks.min(initial=0) < 0 or tracks.max(initial=0) >= T) or seen[tracks].any():
            raise ValueError("cluster tracks must be distinct tracks in [0, T) of one cluster")
        seen[tracks] = True
        if len(inverse) != H or (H and (inverse.min() < 0 or inverse.max() >= U)):
            raise ValueError(f"inverse must name one of the cluster's {U} lists per hypothesis")
        E = len(ranked.w)
        if ranked.child.shape != (E, n) or ranked.taken.shape != (E, n):
            raise ValueError("ranked child and taken must be (events, cluster tracks)")
        if ranked.ptr[0] != 0 or ranked.ptr[-1] != E or (np.diff(ranked.ptr) < 0).any():
            raise ValueError("ranked ptr must run from 0 to the number of events")
        if E and ((ranked.taken < -1) | (ranked.taken >= M)).any():
            raise ValueError(f"ranked taken must name returns in [-1, {M})")
        base = len(list_ptr) - 1
        parts["list_of"].append(inverse + base)
        list_ptr.extend((list_ptr[-1] + ranked.ptr[1:]).tolist())
        ev_ofs.append(sum(len(a) for a in parts["child"]) + n * np.arange(E))
        parts["tracks"].append(tracks)
        parts["w"].append(ranked.w)
        parts["child"].append(ranked.child.reshape(-1))
        parts["taken"].append(ranked.taken.reshape(-1))
        track_ptr.append(track_ptr[-1] + n)

    def cat(name, dtype):
        return np.concatenate(parts[name]).astype(dtype) if parts[name] else np.zeros(0, dtype)

    list_of = np.stack(parts["list_of"]) if clusters else np.zeros((0, H), np.int64)
    ev_ofs = np.concatenate(ev_ofs).astype(np.int64) if ev_ofs else np.zeros(0, np.int64)
    return _combine_events(
        hyp, base_logw, k_h, new_track_hyp, np.asarray(track_ptr, np.int64),
        cat("tracks", np.int64), np.ascontiguousarray(list_of, np.int64),
        np.asarray(list_ptr, np.int64), cat("w", np.float64), ev_ofs,
        cat("child", np.int64), cat("taken", np.int64),
    )  # fmt: skip


@numba.njit(cache=True)
def _row_less(rows, a, b):
    for t in range(rows.shape[1]):
        if rows[a, t] != rows[b, t]:
            return rows[a, t] < rows[b, t]
    return False


@numba.njit(cache=True)
def _group_rows(rows, logw):
    """Distinct rows in lexicographic order, each row's group and each group's largest
    log weight (equal rows keep their order)."""
    n = rows.shape[0]
    # lexicographic and stable: numpy's stable sort (mergesort) by each column, the
    # last first — the least significant key sorted first, as in an LSD radix sort
    order = np.arange(n)
    for t in range(rows.shape[1] - 1, -1, -1):
        order = order[np.argsort(rows[order, t], kind="mergesort")]
    inverse = np.empty(n, np.int64)
    first = np.empty(n, np.int64)
    top = np.empty(n)
    g = -1
    for q in range(n):
        i = order[q]
        if g < 0 or _row_less(rows, first[g], i):
            g += 1
            first[g] = i
            top[g] = logw[i]
        elif logw[i] > top[g]:
            top[g] = logw[i]
        inverse[i] = g
    G = g + 1
    out = np.empty((G, rows.shape[1]), np.int64)
    for g in range(G):
        for t in range(rows.shape[1]):
            out[g, t] = rows[first[g], t]
    return out, inverse, top[:G].copy()


def distinct_rows(rows):
    """``(distinct rows, inverse)`` as ``np.unique(rows, axis=0, return_inverse=True)``:
    the distinct rows of a 2-D int64 array in lexicographic order and each row's index
    among them."""
    rows = _int_array(rows, "rows", 2)
    out, inverse, _ = _group_rows(rows, np.zeros(len(rows)))
    return out, inverse


def merge_identical(rows, logw):
    """Hypotheses with the same rows are one: ``(rows (G, ·), log weights (G,))``.

    The distinct rows in lexicographic order (as ``np.unique(rows, axis=0)``), each
    with log Σ exp of its copies' log weights, taken relative to the copies' largest
    (log weights far below 0 do not underflow to −inf); the copies are added in
    their order in ``rows``.

    Raises
    ------
    TypeError, ValueError
        ``rows`` not 2-D int64, ``logw`` not float64 of one entry per row, or a log
        weight that is NaN or +inf.
    """
    rows, logw = _int_array(rows, "rows", 2), _float_array(logw, "logw")
    if len(logw) != len(rows):
        raise ValueError(f"logw must have one entry per row ({len(rows)}), got {len(logw)}")
    if np.isnan(logw).any() or (logw == np.inf).any():
        raise ValueError("logw must hold log weights below +inf (no NaN)")
    out, inverse, top = _group_rows(rows, logw)
    with np.errstate(invalid="ignore"):  # a group whose copies are all −inf stays −inf
        rel = np.exp(logw - top[inverse])
    rel[logw == -np.inf] = 0.0
    acc = np.bincount(inverse, rel, minlength=len(out))
    with np.errstate(divide="ignore"):
        return out, np.where(top == -np.inf, -np.inf, top + np.log(acc))


class TrackClusters(NamedTuple):
    """Clusters of tracks that share gated returns, ordered by their first track.

    ``tracks[track_ptr[c] : track_ptr[c + 1]]`` the tracks of cluster c (ascending),
    ``returns[return_ptr[c] : return_ptr[c + 1]]`` the returns they gate (ascending).
    Tracks that gate nothing are in no cluster.
    """

    track_ptr: np.ndarray
    tracks: np.ndarray
    return_ptr: np.ndarray
    returns: np.ndarray


@numba.njit(cache=True)
def _root(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]  # path halving
        i = parent[i]
    return i


@numba.njit(cache=True)
def _track_clusters(pair_track, cols, T, M):
    parent = np.arange(T + M)
    gates = np.zeros(T, np.bool_)
    gated = np.zeros(M, np.bool_)
    for p in range(pair_track.shape[0]):
        gates[pair_track[p]] = True
        gated[cols[p]] = True
        a, b = _root(parent, pair_track[p]), _root(parent, T + cols[p])
        if a != b:
            parent[max(a, b)] = min(a, b)
    # clusters numbered by their first track; tracks and returns ascending in each
    cluster_of_root = np.full(T + M, -1, np.int64)
    n_tracks = np.zeros(T + 1, np.int64)
    C = 0
    for t in range(T):
        if gates[t]:
            r = _root(parent, t)
            if cluster_of_root[r] < 0:
                cluster_of_root[r] = C
                C += 1
            n_tracks[cluster_of_root[r] + 1] += 1
    n_returns = np.zeros(C + 1, np.int64)
    for j in range(M):
        if gated[j]:
            n_returns[cluster_of_root[_root(parent, T + j)] + 1] += 1
    track_ptr = np.cumsum(n_tracks[: C + 1])
    return_ptr = np.cumsum(n_returns)
    tracks = np.empty(track_ptr[C], np.int64)
    returns = np.empty(return_ptr[C], np.int64)
    fill = track_ptr[:C].copy()
    for t in range(T):
        if gates[t]:
            c = cluster_of_root[_root(parent, t)]
            tracks[fill[c]] = t
            fill[c] += 1
    fill = return_ptr[:C].copy()
    for j in range(M):
        if gated[j]:
            c = cluster_of_root[_root(parent, T + j)]
            returns[fill[c]] = j
            fill[c] += 1
    return track_ptr, tracks, return_ptr, returns


def track_clusters(pair_track, cols, n_tracks, n_returns) -> TrackClusters:
    """Clusters of the tracks connected through gated pairs ``(pair_track[p], cols[p])``.

    Raises
    ------
    TypeError, ValueError
        arrays not 1-D int64 of one length, or a track or return index outside
        [0, n_tracks) or [0, n_returns).
    """
    pair_track, cols = _int_array(pair_track, "pair_track", 1), _int_array(cols, "cols", 1)
    for name, v in (("n_tracks", n_tracks), ("n_returns", n_returns)):
        if type(v) is not int or v < 0:
            raise ValueError(f"{name} must be a whole number ≥ 0, got {v!r}")
    if len(pair_track) != len(cols):
        raise ValueError(
            f"pair_track and cols must have one length ({len(pair_track)}, {len(cols)})"
        )
    if len(cols) and not (0 <= pair_track.min() and pair_track.max() < n_tracks):
        raise ValueError(f"pair_track must name tracks in [0, {n_tracks})")
    if len(cols) and not (0 <= cols.min() and cols.max() < n_returns):
        raise ValueError(f"cols must name returns in [0, {n_returns})")
    return TrackClusters(*_track_clusters(pair_track, cols, n_tracks, n_returns))
