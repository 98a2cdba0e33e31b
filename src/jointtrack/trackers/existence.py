"""Track existence: JIPDA update, adaptive birth, duplicate merging, deaths in time.

The tracker finds targets by itself in clutter with three pieces (1–3), chosen on
measured evidence (issue 11; numbers from ``jointtrack bench quality`` and the
abreast scene of :func:`jointtrack.scenarios.abreast`: 5 targets 20 units
apart at 1 unit/s, σ = 5, P_D = 0.9, 60 clutter returns per scan):

1. **Integrated existence for every track; tentative tracks see every
   return.** Each track carries the probability r that its target exists;
   the likelihood ratio of a gated return is P_D r g / λ and the miss weight
   1 − r P_D P_G, so a weak tentative track barely competes with an
   established one (JIPDA: D. Mušicki and R. Evans, "Joint integrated
   probabilistic data association: JIPDA", *IEEE Transactions on Aerospace
   and Electronic Systems* 40(3), 2004). Confirmed tracks are associated
   first, among themselves (their clusters stay the small, exact ones of
   Bojilov's experiment); tentative tracks then see *every* return, its
   likelihood ratio scaled by the probability that no confirmed track took
   it. Measured on the abreast scene, 10 seeds: tentative tracks limited to
   the returns no confirmed gate held (the old rule) let a confirmed track
   that drifted between two lanes keep both lanes' returns, and the target it
   abandoned went unfound (targets held in 50–87 % of their scans); one joint
   association of all tracks held 99.3 % but glued Bojilov's β = 1 clutter
   into clusters of 120–190 tracks (solved approximately); the chosen
   two-pass form holds 99.1 % (worst target 90 %) with the same false-track
   rate (0.10 per scan). Independent IPDA for tentative tracks confirmed
   faster but let duplicates confirm (14–32 identity switches, worst target
   held 76 %).
2. **One-point births on every return, weighted by how unexplained it is**
   (the adaptive birth of the labelled multi-Bernoulli filter: S. Reuter,
   B.-T. Vo, B.-N. Vo and K. Dietmayer, "The labeled multi-Bernoulli
   filter", *IEEE Transactions on Signal Processing* 62(12), 2014, §IV-C).
   A return z starts a tentative track with r₀(z) = r_init · (1 − P(z came
   from an existing track)), zero mean velocity and per-axis σ_v =
   max_speed / 2 (a speed uniform up to max_speed in a random direction has
   that per-axis spread), the velocity gating that the measurement noise
   alone cannot give when σ ≫ speed · dt. Starting tracks only on returns no
   gate held (the old rule) left a target untracked for tens of scans once a
   clutter-born track held its returns, and two-point differencing with
   σ = 5, speed 1 gave velocities with σ_v ≈ 7 — gates that swallowed the
   neighbouring lanes (median 7–44 scans to confirm; one-point with the
   speed prior: 5).
3. **Merging duplicates.** Two tracks whose states are statistically the
   same, (x₁ − x₂)ᵀ (P₁ + P₂)⁻¹ (x₁ − x₂) < ``merge_threshold``, follow one
   target (a clutter-born track next to a target's own, both fed by the
   same returns); JIPDA's one-return-per-target rule makes them split the
   evidence and neither confirms. The one kept is confirmed before
   tentative, then more probable, then older; it takes the union
   1 − (1 − r₁)(1 − r₂) of the two existences. The threshold is far below
   the χ² distance of two targets one gate apart, so neighbours never merge.
   Two *confirmed* tracks are never merged: crossing targets come within
   d² < 1 for a scan or two (two targets 10° apart at 10 m/s lost one of
   their tracks in every seed), while leaving confirmed duplicates alone cost
   nothing measurable on the abreast scene (12 seeds: same times to confirm
   and targets held, false tracks 0.110 → 0.122 per scan).

4. **Reporting targets die in continuous time** (``reporting = "async"``,
   :func:`silence_outcomes`). A target reports as a Gamma–Poisson process of its
   own rate (hazard k/(b + u) u seconds into a scan interval) and dies at the
   rate μ = −log p_survive per second, at any moment. Each scan interval then
   ends with the target alive and unheard (probability a), heard before it died
   (e) or dead unheard (d = 1 − a − e); the tracker predicts the existence to
   r(a + e) and misses with 1 − P_D·P_G = a/(a + e), so a missed scan leaves
   r a / (1 − r e), the exact posterior of the two-state (alive, dead) chain
   observed "nothing heard". Such posteriors compose: a silence cut into any
   number of scans by other targets' reports costs exactly what it costs as one
   scan. Applying the survival p_survive^Δt before each scan's miss (the model
   before issue 31) put every death at the start of its interval: at
   p_survive = 0.9999 per second a 300 s silence left 10–14 times more existence
   cut into 500 scans than as one. A report ends the silence: it is detected
   with the existence r(a + e) at its time.

5. **Tentative tracks as alternatives** (``tentative_association =
   "alternatives"``, issue 33; off by default). Started on every return (point
   2), several tentative tracks follow one target; in one joint association
   (point 1) they compete for its returns and split its evidence, so no one of
   them gains existence as fast as a lone IPDA on those returns would
   (Bojilov's scene from nothing: the best track's existence 0.04 → 0.31 →
   0.16 …, 2–15 tentative tracks within 20 m of each target, one cluster of
   94–198 tracks solved by LBP). They are alternative hypotheses of one target,
   not competing targets: each is then associated alone — single-target IPDA,
   exact PDA — on the returns weighted by the probability that no confirmed
   track took them, and its existence follows the lone IPDA's; its *state*
   follows one history, the Kalman update on its most probable event
   (:func:`most_probable_event`), while the other histories are the other
   alternatives (every return starts one). The PDA update instead collapses the
   histories of a track's first scans into one Gaussian: in 93 % clutter such a
   track confirmed with a 4–7 m/s velocity error and held it. What keeps the
   alternatives from all confirming is the returns' history, not the state
   distance (lanes 2σ apart look alike in state): a track reaching r_confirm
   whose likelihood lies at least ``DUPLICATE_SHARE`` (of
   :mod:`jointtrack.trackers.jpda`) on returns that confirmed tracks explain
   stays tentative, so a target confirms once while a target in the next
   lane, whose likelihood lies on its own returns, confirms beside it; merged
   duplicates keep the larger existence (the union would count one target's
   returns twice). Measured (``benchmarks/RESULTS.md``, issue 33): on the
   Bojilov scene from nothing GOSPA 56.8 → 49.2 (seeds 0–4) and 57.2 → 45.4
   (held-out 5–9), median confirmation 28 → 14–18 scans, coverage 0.40–0.58 →
   0.60–0.80, runs ~50 times faster (no LBP); still far above the start-up floor
   (25.9) with 6–28 identity switches a run, and the abreast scene 0–8 % worse
   than joint — so not the default.

Confirmation and deletion are thresholds on r (``r_confirm``, ``r_delete``):
the JIPDA odds update is Wald's sequential probability ratio test, so the
distance logit(r_confirm) − logit(r_init) sets the false-confirmation rate
(≤ r_init(1 − r_confirm) / ((1 − r_init) r_confirm) per started track).
A confirmed track is *reported* while r ≥ ``r_report``: a target that died
stops being reported after two or three missed scans instead of coasting
until its existence falls to ``r_delete``, while a confirmed track that
reappears keeps its identity.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy.spatial import cKDTree

from jointtrack.association.gating import slab_count

__all__ = ["existence_update", "merge_duplicates", "most_probable_event", "silence_outcomes"]


def existence_update(r, beta0, weights, rows, pdg, missed=None):
    """JIPDA posterior existence and β conditioned on existence (Mušicki & Evans 2004).

    ``r`` (n,) predicted existence, ``beta0`` (n,) and ``weights`` (pairs) the
    association marginals of the joint events (a track's "no return" includes
    "does not exist"), ``rows`` the track of each pair, ``pdg`` the P_D·P_G
    of the miss weight and ``missed`` its complement 1 − P_D·P_G where the caller
    has it more accurately than by the subtraction (default ``1 − pdg``).
    Returns ``(r_post, beta0_given_exists,
    weights_given_exists)``; the β given existence of each track sum to one to
    rounding. ``r_post`` is never raised to a floor: a track whose existence
    underflows to 0 has none, and its owner deletes it (``r_delete > 0``).
    """
    # P(exists, no return) = β₀ · r(1 − P_D P_G) / (1 − r P_D P_G): the share of
    # "no return" in which the target exists but was missed
    missed = 1.0 - pdg if missed is None else missed
    # r = 1 with P_D·P_G = 1: "no return" has probability 0 (it was 0/0 = NaN)
    exists_missed = _missed_share(beta0 * r * missed, (1.0 - r) + r * missed)
    # P(a return is the track's) from the pair weights themselves, not as 1 − β₀:
    # for a track of existence ~1e-12 the weights are ~1e-12 and 1 − β₀ keeps only
    # their first few digits, so β₀ and the weights given existence summed to
    # 1 ± 1e-5 (a JIPDA run with r_delete = 1e-12 died on it at report 513)
    detected = np.bincount(rows, weights, minlength=len(beta0))
    total = exists_missed + detected
    r_post = np.minimum(total, 1.0)
    # r = 0 (survival per second over a long gap underflows) and no return taken:
    # total = 0; given existence, such a track took nothing (β₀ = 1), never 0/0 = NaN
    none = total <= 0.0
    if none.any():
        safe = np.where(none, 1.0, total)
        return r_post, np.where(none, 1.0, exists_missed / safe), weights / safe[rows]
    return r_post, exists_missed / total, weights / total[rows]


def most_probable_event(beta0, weights, rows):
    """Each track's most probable association event as β of 0 and 1 (point 5).

    ``beta0`` (n,) and ``weights`` (pairs, track ``rows``) are one track's
    probabilities of "no return" and of each gated return. Returns ``(beta0,
    weights)`` with 1 on the largest of them (a return only when it is strictly
    more probable than "no return"; among equal returns the first pair) and 0
    elsewhere: the PDA update with these β is the Kalman update on that return,
    or none.
    """
    beta0 = np.asarray(beta0, float)
    weights = np.asarray(weights, float)
    rows = np.asarray(rows, np.int64)
    chosen = np.zeros(len(weights))
    if len(weights):
        # pairs by track, the largest weight first (stable: the first pair on ties)
        order = np.lexsort((-weights, rows))
        first = order[np.r_[True, rows[order][1:] != rows[order][:-1]]]
        take = first[weights[first] > beta0[rows[first]]]
        chosen[take] = 1.0
    hit = np.bincount(rows, chosen, minlength=len(beta0)) > 0
    return np.where(hit, 0.0, 1.0), chosen


def _missed_share(top, bottom):
    """``top / bottom`` of a missed target's existence, 0 where ``bottom`` is 0 (a
    target of existence 1 that is always detected is never missed: 0/0 was NaN)."""
    top, bottom = np.asarray(top, float), np.asarray(bottom, float)
    return np.divide(top, bottom, out=np.zeros(np.broadcast(top, bottom).shape), where=bottom > 0)


#: Gauss–Legendre rules of the panels of :func:`_log_concave_integral`: 16 points,
#: or 6 on a panel over which ψ changes by at most ``_SMALL_DROP``.
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(16)
_GL6_NODES, _GL6_WEIGHTS = np.polynomial.legendre.leggauss(6)
_SMALL_DROP = 0.1
#: Panels end where the integrand is e^-50 below its peak (the rest is < e^-50 of it).
_TAIL = 50.0
#: Most panels marched on each side of the peak (the step rules need far fewer).
_MAX_PANELS = 200


def silence_outcomes(k, b, duration, death_rate):
    """How an interval of ``duration`` seconds ends for a target alive at its start.

    The continuous-time model of reporting targets (see the module docstring,
    point 4): the target reports as a Gamma–Poisson process whose hazard at
    ``u`` seconds into the interval is h(u) = k / (b + u) (so nothing is
    reported in (0, u] with probability Q(u) = (1 + u/b)^−k), and dies at the
    constant rate μ = ``death_rate`` per second. Returns three arrays that sum
    to one:

    * ``silent`` = e^−μS Q(S): alive at the end and not heard;
    * ``reported`` = ∫₀^S h(u) e^−μu Q(u) du: heard (first report) before dying;
    * ``died`` = ∫₀^S μ e^−μu Q(u) du: died before being heard.

    ``k`` ≥ 0, ``b`` > 0, ``duration`` S ≥ 0 (arrays of one shape or scalars),
    ``death_rate`` μ ≥ 0. With τ = log(1 + u/b) and c = μb the two integrals are
    ``c ∫ exp((1 − k)τ − c(e^τ − 1)) dτ`` and ``k ∫ exp(−kτ − c(e^τ − 1)) dτ``
    over [0, log(1 + S/b)] — incomplete gamma functions of order 1 − k and −k,
    negative whenever the track has reported more than once, which scipy does not
    evaluate — so both are computed by composite Gauss–Legendre quadrature of
    their log-concave integrands (:func:`_log_concave_integral`, relative error
    below 1e-14 against 30-digit mpmath over k ∈ [1e-3, 3e4], b ∈ [1e-3, 1e7],
    S ∈ [1e-9, 1e8], μ ∈ [1e-14, 10]) and scaled to sum to 1 − silent exactly.
    Without deaths (μ = 0) they are closed forms.
    """
    k, b, S = (np.asarray(v, float) for v in (k, b, duration))
    if not k.shape == b.shape == S.shape:
        k, b, S = np.broadcast_arrays(k, b, S)
    shape = k.shape
    k, b, S = (np.ascontiguousarray(v).reshape(-1) for v in (k, b, S))
    silent, reported, died = np.empty(len(k)), np.empty(len(k)), np.empty(len(k))
    rules = (_GL_NODES, _GL_WEIGHTS, _GL6_NODES, _GL6_WEIGHTS)
    _silence_kernel(k, b, S, float(death_rate), rules, silent, reported, died)
    return silent.reshape(shape), reported.reshape(shape), died.reshape(shape)


@njit(cache=True)
def _silence_kernel(k, b, S, mu, rules, silent, reported, died):  # pragma: no cover
    """:func:`silence_outcomes` per element, into ``silent``, ``reported``, ``died``."""
    for i in range(len(k)):
        T = math.log1p(S[i] / b[i])  # ∞ when S/b overflows
        x = mu * S[i] + (k[i] * T if k[i] > 0.0 else 0.0)  # −log silent; may be ∞
        silent[i] = math.exp(-x)
        not_silent = -math.expm1(-x)
        reported[i], died[i] = not_silent, 0.0
        c = mu * b[i]
        if not (T > 0.0 and c > 0.0):  # no deaths, or none on the interval's time scale
            continue
        d = _log_concave_integral(math.log(c), 1.0 - k[i], c, T, rules)
        e = 0.0
        if k[i] > 0.0:
            e = _log_concave_integral(math.log(k[i]), -k[i], c, T, rules)
        if d + e > 0.0:  # scaled to sum to 1 − silent exactly
            reported[i], died[i] = e * (not_silent / (d + e)), d * (not_silent / (d + e))


@njit(cache=True)
def _psi(w, a, c, tau):  # pragma: no cover
    """ψ(τ) = w + aτ − c(e^τ − 1) (−∞ where c·e^τ overflows)."""
    return w + a * tau - c * math.expm1(tau)


@njit(cache=True)
def _log_concave_integral(w, a, c, T, rules):  # pragma: no cover
    """∫₀^T exp(ψ(τ)) dτ, ψ(τ) = w + aτ − c(e^τ − 1), for c > 0, T > 0.

    ψ is concave, so the integrand has one peak (at τ = log(a/c) if that lies in
    (0, T), else at an end) and falls off on both sides. Panels are marched out
    from the peak until the integrand is e^−50 below it (the rest is then below
    e^−50 of the integral, by concavity) or the interval ends, each integrated by
    Gauss–Legendre (``rules``: 16 and 6 points with their weights). A panel is at most
    ``min(1, 8 / |a|, 2 / v)`` long (v = c·e^τ at its end farther from the
    peak, bounded by e·v at the nearer end), or, where v is small,
    ``min(8 / |a|, 0.45 log(4 / v))``: each keeps ψ within ~20 of its panel
    value on the Bernstein ellipse ρ = 8 around the panel, which bounds the
    16-point rule's relative error by ~e^20 · 8^−32 < 1e-15 (Trefethen,
    *Approximation Theory and Approximation Practice*, 2013, Thm. 19.3). The
    second rule lets panels grow geometrically over a long flat stretch (c tiny:
    a long rate prior and a slow death rate), so a few dozen panels always do.
    A panel at most 1 long over which ψ changes by at most 0.1 ((|a| + max v)·length,
    which then also bounds every derivative of ψ on it scaled to [−1, 1]: they
    are a·h − v·h and −v·h^m, h ≤ 1/2 the half-length) takes the 6-point rule
    (relative error below 1e-25): a scan interval of a second or so is one such
    panel, a fifth of the work.
    """
    nodes16, weights16, nodes6, weights6 = rules
    size = abs(a)
    peak = min(math.log(a / c), T) if a > c else 0.0
    top = _psi(w, a, c, peak)
    total = 0.0
    for direction in (1.0, -1.0):
        tau = peak
        end = T if direction > 0 else 0.0
        for _ in range(_MAX_PANELS):
            if tau == end or _psi(w, a, c, tau) <= top - _TAIL and tau != peak:
                break
            v = c * math.exp(tau) * (math.e if direction > 0 else 1.0)
            length = min(1.0, 2.0 / v) if v > 0.0 else 1.0
            if size > 0.0:
                length = min(length, 8.0 / size)
            if v < 4.0:
                far = 0.45 * math.log(4.0 / max(v, 1e-300))
                if size > 0.0:
                    far = min(far, 8.0 / size)
                length = max(length, far)
            t1 = min(tau + length, T) if direction > 0 else max(tau - length, 0.0)
            half, mid = 0.5 * abs(t1 - tau), 0.5 * (t1 + tau)
            drop = (size + c * math.exp(max(tau, t1))) * 2.0 * half
            small = drop <= _SMALL_DROP and half <= 0.5
            nodes, weights = (nodes6, weights6) if small else (nodes16, weights16)
            panel = 0.0
            for j in range(len(nodes)):
                panel += weights[j] * math.exp(_psi(w, a, c, mid + half * nodes[j]))
            total += half * panel
            tau = t1
    return total


#: Largest number of candidate pairs listed for merging; past it each track is
#: compared with its nearest neighbours only.
_MAX_PAIRS = 2**22


def merge_duplicates(x, P, ids, existence, confirmed, dim, threshold, *, alternatives=False):
    """Which tracks to keep after merging statistical duplicates (see the module docstring).

    A pair is merged when d² < ``threshold`` and at least one of the two is
    tentative (two confirmed tracks may be crossing targets).

    Returns ``(keep, existence)``: a boolean mask and the updated existences
    (the survivors of merges hold the union of the pair's existences, or with
    ``alternatives`` — tracks that each saw all of one target's returns, point 5 —
    the larger of the two: the union would count the same returns twice).
    """
    n = len(ids)
    keep = np.ones(n, bool)
    if n < 2 or threshold <= 0:
        return keep, existence
    # candidate pairs by position; a duplicate is within a few σ of its twin
    var = np.einsum("nii->n", P[:, :dim, :dim])
    radius = 3.0 * np.sqrt(2.0 * threshold * np.quantile(var, 0.99))
    tree = cKDTree(x[:, :dim])
    # count before listing: tracks piled on one spot would give n²/2 pairs (a slab
    # count along x bounds the ball counts cheaply; the tree counts only past it)
    n_pairs = n * (n - 1) // 2
    if n_pairs > _MAX_PAIRS:
        n_pairs = (slab_count(x[:, 0], x[:, 0], radius) - n) // 2
    if n_pairs > _MAX_PAIRS:
        n_pairs = (
            int(tree.query_ball_point(x[:, :dim], radius, return_length=True).sum()) - n
        ) // 2
    if n_pairs <= _MAX_PAIRS:
        pairs = tree.query_pairs(radius, output_type="ndarray")
    else:  # each track against its nearest neighbours only (memory O(n·k))
        k = max(2, min(_MAX_PAIRS // n, n))
        d, nb = tree.query(x[:, :dim], k=k)
        a = np.repeat(np.arange(n), k - 1)
        b = nb[:, 1:].ravel()
        ok = (d[:, 1:].ravel() <= radius) & (b < n) & (a != b)
        pairs = np.unique(np.sort(np.stack([a[ok], b[ok]], axis=1), axis=1), axis=0)
    if len(pairs) == 0:
        return keep, existence
    i, j = pairs[:, 0], pairs[:, 1]
    diff = x[i] - x[j]
    d2 = np.einsum("ki,ki->k", diff, np.linalg.solve(P[i] + P[j], diff[..., None])[..., 0])
    close = d2 < threshold
    if not close.any():
        return keep, existence
    existence = existence.copy()
    order = np.argsort(d2[close])  # closest pairs first
    for a, b in zip(i[close][order], j[close][order], strict=True):
        if not (keep[a] and keep[b]) or (confirmed[a] and confirmed[b]):
            continue
        rank_a = (confirmed[a], existence[a], -ids[a])
        rank_b = (confirmed[b], existence[b], -ids[b])
        win, lose = (a, b) if rank_a >= rank_b else (b, a)
        if alternatives:
            existence[win] = max(existence[win], existence[lose])
        else:
            existence[win] = existence[win] + existence[lose] - existence[win] * existence[lose]
        keep[lose] = False
    return keep, existence
