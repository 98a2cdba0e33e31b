"""OSPA and GOSPA distances between finite sets of points, and GOSPA over time.

Notation: X = {x_1, …, x_n} (e.g. the true targets) and Y = {y_1, …, y_m} (the
estimates) are finite sets of points in ℝ^d, given as ``(n, d)`` and ``(m, d)``
arrays (either may be empty; an empty set may also be given as shape ``(0,)``).
The base distance is Euclidean, ``d(x, y) = ‖x − y‖``, and
``d^(c)(x, y) = min(d(x, y), c)`` is the distance cut off at ``c > 0``.

OSPA (Schuhmacher, Vo & Vo, "A consistent metric for performance evaluation of
multi-object filters", IEEE Trans. Signal Process. 56(8), 2008). For n ≤ m,

    d_p^(c)(X, Y) = ( (1/m) · [ min_π Σ_{i=1}^{n} d^(c)(x_i, y_π(i))^p + c^p (m − n) ] )^{1/p},

π over injections {1..n} → {1..m}; symmetric (swap X and Y when n > m);
``0`` when both sets are empty; ``c`` when exactly one is empty.

GOSPA (Rahmathullah, García-Fernández & Svensson, "Generalized optimal
sub-pattern assignment metric", FUSION 2017). For n ≤ m and 0 < α ≤ 2,

    d_p^(c,α)(X, Y) = ( min_π Σ_{i=1}^{n} d^(c)(x_i, y_π(i))^p + (c^p/α)(m − n) )^{1/p}.

It is a metric for p ≥ 1. For α = 2 (the recommended value) the optimum is the
same as that of the assignment form (their Proposition 1)

    d_p^(c,2)(X, Y)^p = min_γ [ Σ_{(i,j)∈γ} d(x_i, y_j)^p + (c^p/2)(n − |γ|) + (c^p/2)(m − |γ|) ],

γ over partial assignments whose pairs all have ``d(x_i, y_j) < c``: the p-th
power splits into a **localisation** cost (assigned pairs), a **missed** cost
(c^p/2 per unassigned x — a missed target) and a **false** cost (c^p/2 per
unassigned y — a false target). Both are computed with
:func:`jointtrack.assignment.linear_assignment` (the package's one assignment
solver) on the rectangular cost matrix
``min(d, c)^p``: it assigns min(n, m) pairs, and a pair at the cut-off costs
exactly c^p = c^p/2 + c^p/2, i.e. it is a missed *and* a false target.

OSPA of order p = ∞ (Schuhmacher et al., the limit p → ∞; Stone Soup's
``OSPAMetric`` with ``p = inf``):

    d_∞^(c)(X, Y) = c if n ≠ m,  0 if n = m = 0,  else min_π max_i d^(c)(x_i, y_π(i)),

a *bottleneck* assignment, solved exactly here by a binary search over the
sorted distinct cut-off distances with :func:`jointtrack.assignment.is_feasible`
as the test "is there a perfect matching using only pairs with d^(c) ≤ t?".
For finite p, N^(−1/p)·d_∞ ≤ d_p ≤ d_∞ (N = max(n, m)), so d_p → d_∞.
GOSPA is defined for finite p only (as p → ∞ it loses α and its missed/false
decomposition and becomes d_∞ above); :func:`gospa` and :func:`gospa_series`
raise ValueError for p = ∞.

Numerics: every distance is computed without squaring overflow (‖x − y‖ as
M·‖(x − y)/M‖ with M the largest coordinate difference), and every p-th-power
sum Σ v_i^p is evaluated in scaled form T^p · Σ (v_i/T)^p with T the largest
term, so ``ospa``, ``gospa(...).total`` and ``gospa_series(...).total`` are
accurate at any finite scale (1e-300 … 1e300): no d^p overflows or
underflows. The assignment is solved on the scaled costs (min(d, c)/s)^p with
s the largest cut-off distance (an order-preserving rescaling of min(d, c)^p);
when the optimum found is below 2^-100 of that scale (huge and tiny distances in
one problem, where tiny costs could underflow), every pair costing more than the
whole assignment found is excluded and the problem is re-solved at the smaller
scale. The p-th-power *terms* reported by :class:`GOSPA` and
:class:`GOSPASeries` (``localisation``, ``missed``, ``false``, ``switch_cost``)
are plain floats: they overflow to ``inf`` (underflow to 0) when the p-th power
itself is outside the float range, while the totals stay accurate.

Relation used in the tests: with α = 1 and N = max(n, m) > 0,
``gospa(X, Y, c, p, alpha=1).total ** p == N * ospa(X, Y, c, p) ** p``
(scale-safe form: ``gospa(...).total == N ** (1/p) * ospa(...)``).

Over time (:func:`gospa_series`): GOSPA per scan between truth and estimated
tracks, and the trajectory-level value

    D = ( Σ_k d_p^(c,2)(X_k, Y_k)^p  +  γ^p · N_switch )^{1/p}

where N_switch counts *identity switches* of the per-scan optimal GOSPA
assignments (a truth is assigned at scan k when it has a partner track with
d < c), under one of two conventions (``switch_convention``):

* ``"partner"`` (default): one switch when a truth's partner is a different
  track from the partner it had the last time it was assigned; a truth that is
  temporarily unassigned (missed, or its track broke) keeps its previous
  partner, so only genuine changes of partner are charged.
* ``"stonesoup"``: Stone Soup's ``GOSPAMetric`` (``switching_penalty``, after
  MATLAB's ``trackGOSPAMetric``): a change of partner track is a full switch
  (γ^p) and a change between assigned and unassigned — in either direction —
  is half a switch (γ^p/2). A truth's state is its partner track or
  "unassigned"; it is updated at every scan where the truth is present and
  left alone while it is absent; a truth starts being followed at the first
  scan where it is assigned (being unassigned before that costs nothing).
  A truth present at a scan with *no* tracks is unassigned there (Stone Soup
  1.9.1 records no association at such a scan — an artefact of its empty-set
  shortcut — so the two differ only when a scan has truths but no tracks).

This is the "per-scan switch count × γ^p" penalty, a simplification in the
spirit of García-Fernández, Rahmathullah & Svensson, "A metric on the space of
finite sets of trajectories for evaluation of multi-target tracking
algorithms", IEEE Trans. Signal Process. 68 (2020): their metric minimises the
assignments *jointly* over time with a linear programme and charges γ^p per
full switch and γ^p/2 per change between assigned and unassigned; here the
per-scan assignments are the per-scan optima (no joint minimisation). D is
therefore *not* a metric in the strict sense when γ > 0; with γ = 0 it is the
ℓ_p sum over scans of the GOSPA metric.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from jointtrack.assignment import is_feasible, linear_assignment
from jointtrack.assignment._checks import _as_real_array, as_float

__all__ = ["GOSPA", "GOSPASeries", "gospa", "gospa_series", "ospa"]

SWITCH_CONVENTIONS = ("partner", "stonesoup")

# re-solve the assignment at a smaller scale when the optimum found is below
# this fraction of the largest scaled cost (tiny costs may have underflowed)
_RESOLVE_BELOW = 2.0**-100


# ----------------------------------------------------------------------------- checks


def _points(X, name: str, d: int | None = None) -> np.ndarray:
    """``X`` as a float64 ``(n, d)`` array (``(0,)`` or ``[]`` → ``(0, d)``)."""
    # the package's check: complex entries (whose imaginary part float64 would drop),
    # booleans, strings and huge integers are refused with a message naming ``name``
    A = _as_real_array(X, name)
    if A.ndim == 1 and A.size == 0:
        A = A.reshape(0, 0 if d is None else d)
    if A.ndim != 2:
        raise ValueError(f"{name} must be a 2-D (n, d) array of points, got shape {A.shape}")
    if not np.all(np.isfinite(A)):
        i = int(np.argwhere(~np.isfinite(A))[0, 0])
        raise ValueError(f"{name} has a non-finite coordinate in point {i}: {A[i].tolist()}")
    return A


def _pair(X, Y) -> tuple[np.ndarray, np.ndarray]:
    X = _points(X, "X")
    Y = _points(Y, "Y")
    # an empty set carries no dimension: adopt the other set's
    if X.shape[0] == 0 and X.shape[1] != Y.shape[1]:
        X = X.reshape(0, Y.shape[1])
    if Y.shape[0] == 0 and Y.shape[1] != X.shape[1]:
        Y = Y.reshape(0, X.shape[1])
    if X.shape[1] != Y.shape[1]:
        raise ValueError(f"X and Y must have the same dimension, got X {X.shape} and Y {Y.shape}")
    return X, Y


def _number(x, name: str, ok, requirement: str) -> float:
    """``x`` as a float; ValueError naming ``name`` if it is not a real number (complex,
    bool, string: :func:`~jointtrack.assignment._checks.as_float`'s rules, but ±inf and
    NaN pass to ``ok``) or fails ``ok``."""
    if not (isinstance(x, float | np.floating) and not math.isfinite(x)):
        x = as_float(x, name)
    x = float(x)
    if not ok(x):
        raise ValueError(f"{name} must be {requirement}, got {x}")
    return x


def _check_c(c) -> float:
    return _number(c, "cut-off c", lambda v: math.isfinite(v) and v > 0, "finite and > 0")


def _check_p(p) -> float:
    """Order p of OSPA: ``1 <= p <= inf``."""
    return _number(p, "order p", lambda v: v >= 1, ">= 1 (metric requirement) or inf")


def _check_p_finite(p) -> float:
    """Order p of GOSPA: ``1 <= p < inf``."""
    p = _check_p(p)
    if math.isinf(p):
        raise ValueError(
            "GOSPA needs a finite order p (1 <= p < inf), got inf: as p → ∞ GOSPA loses α "
            "and its localisation/missed/false decomposition and becomes OSPA of order ∞ "
            "— use ospa(X, Y, c, p=inf) for the max-distance form"
        )
    return p


def _check_alpha(alpha) -> float:
    return _number(alpha, "alpha", lambda v: 0 < v <= 2, "in (0, 2]")


# ----------------------------------------------------------------------------- numerics


def _distances(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """Euclidean distances ``(n, m)`` without overflow or underflow of the squares.

    ``√Σ (x − y)²`` where that sum is finite and ≥ 2^-960 (no square overflowed,
    and any square that underflowed is negligible); elsewhere
    ``M · ‖(x − y)/M‖`` with ``M`` the power of two just above the largest
    absolute coordinate difference (exact scaling: the same rounding as in range).
    A difference beyond the float range gives ``inf`` (a distance beyond every
    finite cut-off).
    """
    n, m, d = X.shape[0], Y.shape[0], X.shape[1]
    if n == 0 or m == 0 or d == 0:
        return np.zeros((n, m))
    with np.errstate(over="ignore", under="ignore", invalid="ignore"):
        diff = X[:, None, :] - Y[None, :, :]
        D2 = np.einsum("ijk,ijk->ij", diff, diff)
        D = np.sqrt(D2)
        redo = ~(D2 >= 2.0**-960) | ~np.isfinite(D2)
        if redo.any():
            A = np.abs(diff[redo])
            # a power of two: dividing by it is exact, so the result rounds exactly
            # as √Σ(x − y)² would in range, and scaling the input by 2^k scales it exactly
            M = np.ldexp(1.0, np.frexp(A.max(axis=1))[1])
            M = np.where(np.isfinite(A.max(axis=1)), M, np.inf)
            M[A.max(axis=1) == 0] = 0.0
            ok = (M > 0) & np.isfinite(M)
            R = A / np.where(ok, M, 1.0)[:, None]
            Dr = M * np.sqrt(np.einsum("ij,ij->i", R, R))
            Dr[~ok] = M[~ok]  # 0 stays 0, an overflowing difference stays inf
            D[redo] = Dr
    return D


def _power_sum(values, weights, p: float) -> tuple[float, float]:
    """``(T, S)`` with ``Σ w_i v_i^p = T^p · S`` and no overflow or underflow.

    ``T`` is the largest ``v_i`` with ``w_i > 0`` (``S`` ≥ its weight); ``(0, 0)``
    if there is no such term or all are 0.
    """
    v = np.asarray(values, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    use = w > 0
    if not use.any():
        return 0.0, 0.0
    v, w = v[use], w[use]
    T = float(v.max())
    if T == 0.0:
        return 0.0, 0.0
    with np.errstate(under="ignore"):
        S = float(np.sum(w * (v / T) ** p))
    return T, S


def _root(T: float, S: float, p: float) -> float:
    """``(T^p · S)^{1/p}`` = ``T · S^{1/p}``."""
    return T * S ** (1.0 / p) if T > 0 else 0.0


def _pth(T: float, S: float, p: float) -> float:
    """``T^p · S`` as a float (``inf`` / 0 outside the float range)."""
    if T == 0.0 or S == 0.0:
        return 0.0
    with np.errstate(over="ignore", under="ignore"):
        return float(np.power(np.float64(T), p) * S)


def _cutoff_assignment(X: np.ndarray, Y: np.ndarray, c: float, p: float):
    """Optimal assignment of ``min(n, m)`` pairs under cost ``min(d, c)^p``.

    Solved on the scaled costs ``(min(d, c)/s)^p``, ``s`` the largest allowed
    cut-off distance. If the assignment found costs less than ``2^-100`` (tiny
    costs may have underflowed), every pair whose cost exceeds the whole
    assignment found — it cannot be in an optimum — is excluded and the
    problem re-solved at the smaller scale (``s`` strictly decreases, so this
    ends). Returns ``(rows, cols, dist)`` with ``dist`` the (uncut) Euclidean
    distance of each pair.
    """
    if X.shape[0] == 0 or Y.shape[0] == 0:
        e = np.zeros(0, dtype=np.intp)
        return e, e, np.zeros(0)
    D = _distances(X, Y)
    Dc = np.minimum(D, c)
    allowed = None
    while True:
        s = float(Dc.max() if allowed is None else Dc[allowed].max())
        if s == 0.0:
            cost = np.zeros_like(Dc)
        else:
            with np.errstate(over="ignore", under="ignore"):
                cost = (Dc / s) ** p  # excluded pairs may overflow: masked below
        if allowed is not None:
            cost = np.where(allowed, cost, np.inf)
        res = linear_assignment(cost)
        rows, cols = res.rows, res.cols
        a = Dc[rows, cols]
        T, S = _power_sum(a, np.ones(a.size), p)
        if T == 0.0:
            break  # an assignment of cost 0 is optimal
        R = max(_root(T, S, p), T)  # ℓ_p norm of the assignment found
        ratio = R / s  # the assignment found costs ratio^p in scaled units
        if ratio > 0 and p * math.log2(ratio) >= math.log2(_RESOLVE_BELOW):
            break
        # an optimal assignment has Σ d^p ≤ R^p, so none of its pairs exceeds R
        allowed = Dc <= R * (1 + 1e-12)
    return rows, cols, D[rows, cols]


# ----------------------------------------------------------------------------- OSPA


def _ospa_inf(X: np.ndarray, Y: np.ndarray, c: float) -> float:
    """OSPA of order ∞: ``c`` if ``n ≠ m``, else the bottleneck assignment value."""
    n, m = X.shape[0], Y.shape[0]
    if n != m:
        return c
    if n == 0:
        return 0.0
    Dc = np.minimum(_distances(X, Y), c)
    vals = np.unique(Dc)  # sorted; the largest admits every pair, so it is feasible
    lo, hi = 0, vals.size - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if is_feasible((Dc <= vals[mid]).astype(np.float64)):
            hi = mid
        else:
            lo = mid + 1
    return float(vals[lo])


def ospa(X, Y, c: float, p: float = 1) -> float:
    """OSPA distance d_p^(c)(X, Y) (Schuhmacher, Vo & Vo 2008).

    ``(1/m)·[min_π Σ min(d, c)^p + c^p (m − n)]`` to the power 1/p for n ≤ m
    (see the module docstring). ``X`` is ``(n, d)``, ``Y`` is ``(m, d)``; either
    may be empty. ``p`` ≥ 1 or ``p = inf`` — the max form: ``c`` if n ≠ m, else
    the smallest achievable largest cut-off distance (bottleneck assignment).
    Returns a float in ``[0, c]``, accurate at any finite scale.
    """
    X, Y = _pair(X, Y)
    c = _check_c(c)
    p = _check_p(p)
    n, m = X.shape[0], Y.shape[0]
    big = max(n, m)
    if big == 0:
        return 0.0
    if math.isinf(p):
        return _ospa_inf(X, Y, c)
    _, _, dist = _cutoff_assignment(X, Y, c, p)
    a = np.minimum(dist, c)
    T, S = _power_sum(np.append(a, c), np.append(np.ones(a.size), abs(m - n)), p)
    return float(min(_root(T, S / big, p), c))


# ----------------------------------------------------------------------------- GOSPA


@dataclass(frozen=True, eq=False)
class GOSPA:
    """Result of :func:`gospa`.

    ``total`` is the GOSPA distance d_p^(c,α)(X, Y), accurate at any finite
    scale. The cost terms are on the p-th-power scale, so
    ``total ** p == localisation + missed + false`` (they overflow to ``inf`` or
    underflow to 0 when that p-th power is outside the float range):

    * ``localisation`` — Σ d(x_i, y_j)^p over the assigned pairs,
    * ``missed`` — (c^p/α) × ``n_missed`` (points of X left unassigned),
    * ``false`` — (c^p/α) × ``n_false`` (points of Y left unassigned).

    For α = 2 a pair is *assigned* only when d < c (a pair at or beyond the
    cut-off is a missed plus a false target); for α < 2 the decomposition into
    missed and false targets is not defined by the paper, and the min(n, m)
    optimal pairs are all counted as assigned with cost min(d, c)^p, the
    cardinality mismatch |n − m| as missed (n > m) or false (m > n).

    ``assignment`` is a ``(n_assigned, 2)`` int array of index pairs
    ``(i, j)`` (x_i ↔ y_j); ``distances`` their Euclidean distances.
    """

    total: float
    localisation: float
    missed: float
    false: float
    n_assigned: int
    n_missed: int
    n_false: int
    assignment: np.ndarray
    distances: np.ndarray
    c: float
    p: float
    alpha: float


def gospa(X, Y, c: float, p: float = 2, alpha: float = 2) -> GOSPA:
    """GOSPA distance d_p^(c,α)(X, Y) with its decomposition (Rahmathullah et al. 2017).

    Parameters
    ----------
    X, Y : (n, d) and (m, d) arrays of points (either may be empty).
    c : cut-off distance, > 0. With α = 2 a missed or false target costs c^p/2.
    p : order, 1 ≤ p < ∞ (GOSPA is not defined for p = ∞; see the module
        docstring — ``ospa(X, Y, c, p=inf)`` is the max-distance form).
    alpha : in (0, 2]; α = 2 gives the localisation / missed / false split.

    Returns
    -------
    GOSPA
        ``total`` and the p-th-power cost terms (``total**p`` = their sum).

    Examples
    --------
    One missed target costs c^p/2: ``gospa([[0, 0]], [], c=10).total == sqrt(50)``.
    """
    X, Y = _pair(X, Y)
    c = _check_c(c)
    p = _check_p_finite(p)
    alpha = _check_alpha(alpha)
    n, m = X.shape[0], Y.shape[0]
    rows, cols, dist = _cutoff_assignment(X, Y, c, p)
    if alpha == 2.0:
        keep = dist < c
    else:
        keep = np.ones(dist.shape, dtype=bool)
    rows, cols, dist = rows[keep], cols[keep], dist[keep]
    k = int(rows.size)
    n_missed, n_false = n - k, m - k
    a = np.minimum(dist, c)
    T, S = _power_sum(np.append(a, c), np.append(np.ones(k), (n_missed + n_false) / alpha), p)
    total = _root(T, S, p)
    Tl, Sl = _power_sum(a, np.ones(k), p)
    cp_alpha = _pth(c, 1.0, p) / alpha
    return GOSPA(
        total=float(total),
        localisation=_pth(Tl, Sl, p),
        missed=float(cp_alpha * n_missed) if n_missed else 0.0,
        false=float(cp_alpha * n_false) if n_false else 0.0,
        n_assigned=k,
        n_missed=int(n_missed),
        n_false=int(n_false),
        assignment=np.column_stack([rows, cols]).astype(np.intp).reshape(k, 2),
        distances=dist.astype(np.float64),
        c=c,
        p=p,
        alpha=alpha,
    )


# ----------------------------------------------------------------------------- over time


def _table(times, ids, pos, name: str):
    t = _as_real_array(times, f"{name} times")
    P = _as_real_array(pos, f"{name} positions")
    i_raw = np.asarray(ids)
    if i_raw.size and i_raw.dtype.kind not in "iuf":  # complex, bool, strings, objects
        raise ValueError(f"{name}: ids must be integers, got dtype {i_raw.dtype}")
    if t.ndim != 1 or i_raw.ndim != 1:
        raise ValueError(f"{name}: times and ids must be 1-D, got shapes {t.shape}, {i_raw.shape}")
    if P.ndim == 1 and P.size == 0:
        P = P.reshape(0, 0)
    if P.ndim != 2:
        raise ValueError(f"{name}: positions must be a 2-D (n, d) array, got shape {P.shape}")
    if not (t.shape[0] == i_raw.shape[0] == P.shape[0]):
        raise ValueError(
            f"{name}: times ({t.shape[0]}), ids ({i_raw.shape[0]}) and positions "
            f"({P.shape[0]}) must have the same number of rows"
        )
    if not np.all(np.isfinite(t)):
        raise ValueError(f"{name}: times must be finite")
    if not np.all(np.isfinite(P)):
        r = int(np.argwhere(~np.isfinite(P))[0, 0])
        raise ValueError(f"{name}: non-finite position in row {r}: {P[r].tolist()}")
    ids_f = i_raw.astype(np.float64)
    if i_raw.size and (not np.all(np.isfinite(ids_f)) or np.any(ids_f != np.round(ids_f))):
        raise ValueError(f"{name}: ids must be integers")
    ids_i = i_raw.astype(np.int64)
    return t, ids_i, P


def _pair_tables(truth, tracks):
    tt, ti, tp = _table(*truth, "truth")
    et, ei, ep = _table(*tracks, "tracks")
    if tp.shape[0] == 0:
        tp = tp.reshape(0, ep.shape[1])
    if ep.shape[0] == 0:
        ep = ep.reshape(0, tp.shape[1])
    if tp.shape[1] != ep.shape[1]:
        raise ValueError(
            f"truth positions are {tp.shape[1]}-D but track positions are {ep.shape[1]}-D"
        )
    for t, i, name in ((tt, ti, "truth"), (et, ei, "tracks")):
        key = np.stack([t, i.astype(np.float64)], axis=1)
        if key.shape[0] and np.unique(key, axis=0).shape[0] != key.shape[0]:
            raise ValueError(f"{name}: an id appears twice at the same time")
    return (tt, ti, tp), (et, ei, ep)


def _scans(truth, tracks):
    """Yield ``(time, truth rows, track rows)`` per distinct time (union of both)."""
    tt = truth[0]
    et = tracks[0]
    times = np.unique(np.concatenate([tt, et]))
    o1 = np.argsort(tt, kind="stable")
    o2 = np.argsort(et, kind="stable")
    s1 = np.searchsorted(tt[o1], times, side="left")
    e1 = np.searchsorted(tt[o1], times, side="right")
    s2 = np.searchsorted(et[o2], times, side="left")
    e2 = np.searchsorted(et[o2], times, side="right")
    for k, t in enumerate(times):
        yield k, t, o1[s1[k] : e1[k]], o2[s2[k] : e2[k]]


def _scan_gospa_present(truth, tracks, c: float, p: float):
    """Per scan, GOSPA (α = 2) between the truths and tracks present.

    Yields ``(k, time, g, present, rows, track_ids)``: ``g`` the :class:`GOSPA`
    of scan k, ``present`` the truth-table rows at scan k, ``rows`` the
    truth-table rows of its assigned pairs and ``track_ids`` their partner
    track ids.
    """
    for k, t, r1, r2 in _scans(truth, tracks):
        g = gospa(truth[2][r1], tracks[2][r2], c, p, 2)
        yield k, t, g, r1, r1[g.assignment[:, 0]], tracks[1][r2[g.assignment[:, 1]]]


def _scan_gospa(truth, tracks, c: float, p: float):
    """:func:`_scan_gospa_present` without the ``present`` rows:
    ``(k, time, g, rows, track_ids)``."""
    for k, t, g, _present, rows, partners in _scan_gospa_present(truth, tracks, c, p):
        yield k, t, g, rows, partners


def _count_switches(last: dict, truth_ids: np.ndarray, track_ids: np.ndarray) -> int:
    """Partner convention: update ``last`` (truth id → last partner track id);
    return the new switches (changes of partner)."""
    n = 0
    for a, b in zip(truth_ids.tolist(), track_ids.tolist(), strict=True):
        prev = last.get(a)
        if prev is not None and prev != b:
            n += 1
        last[a] = b
    return n


def _count_switches_stonesoup(
    last: dict, present_ids: np.ndarray, truth_ids: np.ndarray, track_ids: np.ndarray
) -> tuple[int, int]:
    """Stone Soup convention: ``(full, half)`` switches at one scan.

    ``last`` maps a followed truth id to its partner track id or ``None``
    (unassigned). Every truth present (``present_ids``) is updated: its partner
    is given by ``truth_ids``/``track_ids`` or ``None``. A change of partner
    track is a full switch, a change between assigned and unassigned half a
    switch; a truth is followed from its first assignment (as Stone Soup's
    ``_SwitchingLoss.add_associations``).
    """
    partner = dict(zip(truth_ids.tolist(), track_ids.tolist(), strict=True))
    full = half = 0
    for a in present_ids.tolist():
        b = partner.get(a)
        if a not in last:
            if b is not None:
                last[a] = b
            continue
        prev = last[a]
        if prev != b:
            if prev is not None and b is not None:
                full += 1
            else:
                half += 1
            last[a] = b
    return full, half


@dataclass(frozen=True, eq=False)
class GOSPASeries:
    """Result of :func:`gospa_series` (α = 2), one entry per scan.

    ``times`` (K,) are the distinct time stamps of truth ∪ tracks; ``gospa``
    (K,) the per-scan GOSPA d_p^(c,2)(X_k, Y_k); ``localisation``, ``missed``,
    ``false`` (K,) its p-th-power terms (``gospa**p`` = their sum);
    ``n_missed``, ``n_false`` (K,) the counts; ``switches`` (K,) the identity
    switches counted at each scan, in units of a full switch:
    ``full_switches + half_switches / 2`` (int for the ``"partner"``
    convention, which has no half switches; float for ``"stonesoup"``).
    ``total`` is the trajectory-level value
    ``(Σ_k gospa_k^p + switch_penalty^p · Σ_k switches_k)^{1/p}`` (accurate at
    any finite scale); ``switch_cost`` = ``switch_penalty^p · Σ_k switches_k``.
    ``switch_convention`` names how switches were counted (module docstring).
    """

    times: np.ndarray
    gospa: np.ndarray
    localisation: np.ndarray
    missed: np.ndarray
    false: np.ndarray
    n_missed: np.ndarray
    n_false: np.ndarray
    switches: np.ndarray
    total: float
    switch_cost: float
    c: float
    p: float
    switch_penalty: float
    switch_convention: str = "partner"
    full_switches: np.ndarray | None = None
    half_switches: np.ndarray | None = None

    @property
    def mean(self) -> float:
        """Mean per-scan GOSPA (NaN with no scans)."""
        return float(np.mean(self.gospa)) if self.gospa.size else float("nan")

    def as_dict(self) -> dict:
        """Parameters, totals and switch counts as a plain dict (for JSON reports)."""
        full = self.full_switches if self.full_switches is not None else self.switches
        half = self.half_switches if self.half_switches is not None else 0 * self.switches
        return {
            "c": self.c,
            "p": self.p,
            "alpha": 2.0,
            "switch_penalty": self.switch_penalty,
            "switch_convention": self.switch_convention,
            "n_scans": int(self.times.size),
            "mean": self.mean,
            "total": self.total,
            "switch_cost": self.switch_cost,
            "n_switches": float(np.sum(self.switches)),
            "n_full_switches": int(np.sum(full)),
            "n_half_switches": int(np.sum(half)),
        }


def gospa_series(
    truth_times,
    truth_ids,
    truth_positions,
    track_times,
    track_ids,
    track_positions,
    c: float,
    p: float = 2,
    switch_penalty: float = 0.0,
    switch_convention: str = "partner",
) -> GOSPASeries:
    """GOSPA (α = 2) per scan between truth and tracks, with a switching penalty.

    Both inputs are flat tables, one row per (object, time): ``*_times`` (R,),
    ``*_ids`` (R,) integers and ``*_positions`` (R, d). Scans are the distinct
    time values of both tables, matched *exactly* (produce tracks at the scan
    time stamps of the truth). A track present at a time with no truth is a
    false target there, and vice versa.

    ``switch_penalty`` γ ≥ 0: each identity switch adds γ^p to the p-th power
    of the total. ``switch_convention`` (see the module docstring):

    * ``"partner"`` (default) — a switch is a change of a truth's partner track
      from its previous partner (unassigned scans in between are free);
    * ``"stonesoup"`` — Stone Soup's ``GOSPAMetric``: a change of partner is a
      full switch, a change between assigned and unassigned half a switch.
    """
    c = _check_c(c)
    p = _check_p_finite(p)
    gamma = _number(
        switch_penalty, "switch_penalty", lambda v: math.isfinite(v) and v >= 0, "finite and >= 0"
    )
    if switch_convention not in SWITCH_CONVENTIONS:
        raise ValueError(
            f"switch_convention must be one of {', '.join(map(repr, SWITCH_CONVENTIONS))}, "
            f"got {switch_convention!r}"
        )
    truth, tracks = _pair_tables(
        (truth_times, truth_ids, truth_positions), (track_times, track_ids, track_positions)
    )
    times = np.unique(np.concatenate([truth[0], tracks[0]]))
    K = times.size
    out = {k: np.zeros(K) for k in ("gospa", "localisation", "missed", "false")}
    n_missed = np.zeros(K, dtype=np.int64)
    n_false = np.zeros(K, dtype=np.int64)
    full = np.zeros(K, dtype=np.int64)
    half = np.zeros(K, dtype=np.int64)
    last: dict = {}
    for k, _t, g, present, rows, partners in _scan_gospa_present(truth, tracks, c, p):
        out["gospa"][k] = g.total
        out["localisation"][k] = g.localisation
        out["missed"][k] = g.missed
        out["false"][k] = g.false
        n_missed[k] = g.n_missed
        n_false[k] = g.n_false
        if switch_convention == "partner":
            if g.n_assigned:
                full[k] = _count_switches(last, truth[1][rows], partners)
        else:
            full[k], half[k] = _count_switches_stonesoup(
                last, truth[1][present], truth[1][rows], partners
            )
    switches = full if switch_convention == "partner" else full + 0.5 * half
    n_switch = float(switches.sum())
    switch_cost = _pth(gamma, n_switch, p)
    T, S = _power_sum(np.append(out["gospa"], gamma), np.append(np.ones(K), n_switch), p)
    return GOSPASeries(
        times=times,
        gospa=out["gospa"],
        localisation=out["localisation"],
        missed=out["missed"],
        false=out["false"],
        n_missed=n_missed,
        n_false=n_false,
        switches=switches,
        total=float(_root(T, S, p)),
        switch_cost=switch_cost,
        c=c,
        p=p,
        switch_penalty=gamma,
        switch_convention=switch_convention,
        full_switches=full,
        half_switches=half,
    )
