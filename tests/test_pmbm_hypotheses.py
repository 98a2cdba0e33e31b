"""PMBM global hypotheses after one update against the exact enumeration of all events.

The PMBM update (A. F. García-Fernández, J. L. Williams, K. Granström and
L. Svensson, "Poisson multi-Bernoulli mixture filter: direct derivation and
implementation", *IEEE Transactions on Aerospace and Electronic Systems*
54(4):1883–1901, 2018): every prior global hypothesis h (weight w_h) with its
single-target hypotheses (STH; existence r, Gaussian) yields one new global
hypothesis per association event — each present track missed (weight
1 − r P_D, child existence r(1 − P_D)/(1 − r P_D), eq. (20)–(21)) or detected
by one distinct return j (weight r P_D g_j, child r = 1 with the Kalman
posterior, eq. (22)–(23)); a return no track takes starts a new track
(weight ρ_j = λ_c + e_j, existence e_j / ρ_j, eq. (24)–(27)), a return taken
leaves the new track j absent. Weight of the new hypothesis: w_h × the product
(eq. (28)).

The tests set a prior by hand (2–3 tracks, 1–2 STHs each, 1–2 global
hypotheses), step once, identify every posterior STH with its closed-form
child (which checks r, mean and covariance at 1e-9), and compare the set of
global hypotheses and their normalised weights with the exact rational
enumeration (:class:`fractions.Fraction` of the float likelihoods):

* ``max_hypotheses`` = 10**6, no pruning, p_g = 1: "k = ∞" — every event of
  every prior hypothesis, weights to 1e-12 relative. (k = ∞ needs
  ⌈10⁶ w_h⌉ ≥ the number of events of h, at most 73 here: prior weights are
  drawn ≥ 0.05.) Events whose exact normalised weight is below 1e-290 may be
  missing or imprecise: their likelihood ratios underflow float64 in the tracker.
* a small ``max_hypotheses`` K with gating (p_g = 0.99) and tracks in
  separate clusters (plus one that gates nothing): the ⌈K w_h⌉ best events of
  each prior hypothesis (Murty per cluster, clusters combined), then the K
  best overall — the enumeration ranked the same way (ties drawn away).
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.stats import chi2, multivariate_normal

from brute import _matchings, log_fraction
from jointtrack.trackers.pmbm import PMBMConfig, PMBMTracker

LN2 = math.log(2.0)
MAX_SPEED = 50.0
#: normalised log weight below which a hypothesis may be missing (see _check_against)
FLOOR = -290 * math.log(10.0)


def fraction_exp(log_value: float) -> Fraction:
    """exp(log_value) as an exact rational, with no underflow (2^k · exp(rest))."""
    k = math.floor(log_value / LN2)
    return Fraction(math.exp(log_value - k * LN2)) * Fraction(2) ** k


def _finite(lo, hi):
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False, allow_subnormal=False)


def _log_uniform(lo, hi):
    return _finite(lo, hi).map(lambda v: 10.0**v)


def _cov(draw, lo=0, hi=3):
    sx, sy = draw(_log_uniform(lo, hi)), draw(_log_uniform(lo, hi))
    c = draw(_finite(-0.9, 0.9))
    sv = draw(_log_uniform(-1, 2))
    k = 0.3 * math.sqrt(1.0 - c * c)  # c² + k² < 1: positive definite
    P = np.diag([sx, sy, sv, sv])
    P[0, 1] = P[1, 0] = c * math.sqrt(sx * sy)
    P[0, 2] = P[2, 0] = k * math.sqrt(sx * sv)
    return P


@st.composite
def pmbm_prior(draw, centres=(0.0,), spread=150.0, quiet=False):
    """Tracks, STHs, global hypotheses, returns and model numbers.

    Each track and each return sits in one of the ``centres`` (x offsets) within
    ``spread``; ``quiet`` adds a track far from everything.
    """
    T = draw(st.integers(2, 3))
    M = draw(st.integers(2, 4))
    sth_track, r, x, P = [], [], [], []
    for t in range(T + quiet):
        centre = 1e6 if t == T else draw(st.sampled_from(centres))
        for _ in range(draw(st.integers(1, 2))):
            sth_track.append(t)
            r.append(draw(st.one_of(st.just(1.0), _finite(1e-3, 1.0))))
            x.append(
                [
                    centre + draw(_finite(-spread, spread)),
                    draw(_finite(-spread, spread)),
                    draw(_finite(-5, 5)),
                    draw(_finite(-5, 5)),
                ]
            )
            P.append(_cov(draw))
    x = np.array(x)
    T += quiet
    # STHs of one track distinct (so that their children can be told apart)
    for a in range(len(r)):
        for b in range(a):
            assume(np.abs(x[a] - x[b]).max() > 1e-3)
    H = draw(st.integers(1, 2))
    options = [[-1] + [s for s, tt in enumerate(sth_track) if tt == t] for t in range(T)]
    hyp = np.array([[draw(st.sampled_from(o)) for o in options] for _ in range(H)], np.int64)
    assume(len({tuple(row) for row in hyp.tolist()}) == H)
    w = [1.0] if H == 1 else [draw(_finite(0.05, 0.95))]
    if H == 2:
        w.append(1.0 - w[0])
    z = np.array(
        [
            [draw(st.sampled_from(centres)) + draw(_finite(-spread, spread)),
             draw(_finite(-spread, spread))]
            for _ in range(M)
        ]
    )  # fmt: skip
    for a in range(M):
        for b in range(a):
            assume(np.abs(z[a] - z[b]).max() > 1e-3)
    return {
        "T": T,
        "sth_track": np.array(sth_track, np.int64),
        "r": r,
        "x": x,
        "P": np.array(P),
        "hyp": hyp,
        "w": w,
        "z": z,
        "p_d": draw(_finite(0.3, 0.99)),
        "lam": draw(_log_uniform(-7, -2)),
        "u": draw(_log_uniform(-8, -3)),
        "R": draw(_log_uniform(0, 2)),
    }


def _tracker(sc, **kw):
    cfg = PMBMConfig(
        p_d=sc["p_d"],
        clutter_density=sc["lam"],
        measurement_noise=sc["R"],
        prior_density=sc["u"],
        max_speed=MAX_SPEED,
        r_prune=0.0,
        r_recycle=0.0,  # exact comparisons: no Bernoulli moves into the intensity
        hypothesis_prune=0.0,
        poisson_prune=0.0,
        **kw,
    )
    trk = PMBMTracker(cfg)
    trk.sth_r = np.array(sc["r"], float)
    trk.sth_x, trk.sth_P = sc["x"].copy(), sc["P"].copy()
    trk.sth_track = sc["sth_track"].copy()
    trk.sth_born, trk.sth_reports = np.zeros(len(sc["r"])), np.zeros(len(sc["r"]))
    trk.track_ids = np.arange(1, sc["T"] + 1, dtype=np.int64)
    trk.track_reported = np.zeros(sc["T"], bool)
    trk.next_id = sc["T"] + 1
    trk.hyp = sc["hyp"].copy()
    logw = np.log(sc["w"])
    trk.hyp_logw = logw - logw.max()
    return trk


def _kalman(x, P, z, R):
    H = np.eye(2, 4)
    S = H @ P @ H.T + R * np.eye(2)
    K = P @ H.T @ np.linalg.inv(S)
    return x + K @ (z - H @ x), P - K @ S @ K.T


def _children(sc):
    """Closed-form children: {track: [(label, r, x, P)]}; new tracks under ("new", j)."""
    pd, R = sc["p_d"], sc["R"]
    out = {}
    for s, t in enumerate(sc["sth_track"]):
        r, x, P = sc["r"][s], sc["x"][s], sc["P"][s]
        kids = out.setdefault(int(t), [])
        kids.append((("miss", s), r * (1 - pd) / (1 - r * pd), x, P))
        for j, zj in enumerate(sc["z"]):
            kids.append((("det", s, j), 1.0, *_kalman(x, P, zj, R)))
    e = pd * sc["u"]
    P_new = np.diag([R, R, (MAX_SPEED / 2) ** 2, (MAX_SPEED / 2) ** 2])
    for j, zj in enumerate(sc["z"]):
        out[("new", j)] = [(("new", j), e / (sc["lam"] + e), np.r_[zj, 0.0, 0.0], P_new)]
    return out


def _close(a, b):
    scale = 1e-9 * (1.0 + np.abs(b).max())
    return np.allclose(a, b, rtol=1e-9, atol=scale)


def _identify(trk, sc):
    """Label of every posterior STH, by matching its (r, x, P) with one closed-form child."""
    kids = _children(sc)
    T = sc["T"]
    labels = []
    for s in range(len(trk.sth_r)):
        tid = int(trk.track_ids[trk.sth_track[s]])
        if tid <= T:
            pool = kids[tid - 1]
        else:  # a new track: which return started it
            pool = [k for j in range(len(sc["z"])) for k in kids[("new", j)]]
        hits = [
            lab
            for lab, r, x, P in pool
            if math.isclose(trk.sth_r[s], r, rel_tol=1e-9)
            and _close(trk.sth_x[s], x)
            and _close(trk.sth_P[s], P)
        ]
        assert len(hits) == 1, (tid, trk.sth_r[s], trk.sth_x[s], hits)
        labels.append(hits[0])
    return labels


def _tracker_hypotheses(trk, sc):
    """{key: normalised log weight} of the tracker's global hypotheses."""
    labels = _identify(trk, sc)
    T = sc["T"]
    logw = trk.hyp_logw - np.logaddexp.reduce(trk.hyp_logw)
    out = {}
    for row, lw in zip(trk.hyp, logw, strict=True):
        old = [None] * T
        new = set()
        for col, s in enumerate(row):
            if s < 0:
                continue
            tid = int(trk.track_ids[col])
            if tid <= T:
                old[tid - 1] = labels[s]
            else:
                new.add(labels[s][1])
        key = (tuple(old), frozenset(new))
        assert key not in out, key  # one row per distinct hypothesis
        out[key] = lw
    return out


def _gate_mask(sc, p_g):
    if p_g >= 1.0:
        return np.ones((len(sc["r"]), len(sc["z"])), bool)
    gamma = chi2.ppf(p_g, 2)
    mask = np.zeros((len(sc["r"]), len(sc["z"])), bool)
    for s in range(len(sc["r"])):
        S = sc["P"][s][:2, :2] + sc["R"] * np.eye(2)
        d = sc["z"] - sc["x"][s][:2]
        d2 = np.einsum("ki,ij,kj->k", d, np.linalg.inv(S), d)
        assume(np.all(np.abs(d2 - gamma) > 1e-6 * gamma))  # no pair on the gate boundary
        mask[s] = d2 <= gamma
    return mask


def _enumerate(sc, p_g=1.0):
    """Per prior hypothesis: [(key, exact weight)] of all its events (Fractions)."""
    pd = Fraction(sc["p_d"])
    M = len(sc["z"])
    r = [Fraction(v) for v in sc["r"]]
    R = sc["R"] * np.eye(2)
    gated = _gate_mask(sc, p_g)
    # only gated pairs are hypotheses (and 2^-(10^12) is no number to build)
    g = [
        [
            fraction_exp(float(multivariate_normal(x[:2], P[:2, :2] + R).logpdf(zj)))
            if gated[s, j]
            else None
            for j, zj in enumerate(sc["z"])
        ]
        for s, (x, P) in enumerate(zip(sc["x"], sc["P"], strict=True))
    ]
    e = pd * Fraction(sc["u"])
    rho = Fraction(sc["lam"]) + e
    per_h = []
    for h, row in enumerate(sc["hyp"]):
        present = [(t, int(s)) for t, s in enumerate(row) if s >= 0]
        events = []
        for sigma in _matchings(len(present), M, [True] * len(present)):
            w = Fraction(sc["w"][h])
            old = [None] * sc["T"]
            for (t, s), j in zip(present, sigma, strict=True):
                if j is None:
                    w *= 1 - r[s] * pd
                    old[t] = ("miss", s)
                elif gated[s, j]:
                    w *= r[s] * pd * g[s][j]
                    old[t] = ("det", s, j)
                else:
                    w = Fraction(0)
            if w == 0:
                continue
            free = frozenset(j for j in range(M) if j not in sigma)
            w *= rho ** len(free)
            events.append(((tuple(old), free), w))
        per_h.append(events)
    return per_h


def _check_against(trk, sc, exact):
    """Tracker hypotheses == ``exact`` {key: weight}, weights relative to 1e-12.

    The tracker adds log weights: a normalised log weight ℓ carries an absolute
    rounding error of a few ε·|ℓ|, so the bound is 1e-12 · max(1, |ℓ|) on ℓ —
    1e-12 relative on every weight above e⁻¹, 1e-12 relative on the log of
    the smaller ones. Hypotheses below e^FLOOR (≈ 1e-290) are exempt: the
    tracker's likelihood ratios are float64 numbers (Murty's algorithm takes
    them, not their logs), subnormal below 2.2e-308 and 0 below 5e-324, so
    such hypotheses may be missing or imprecise — and in a truncated list, replaced:
    an event whose float ratio underflowed is invisible to the ranking, so the K-th
    place may go to one further down (found: e^−967.6 kept for e^−745.8, whose
    ratio e^−745.8 is below 5e-324, the two detections of the kept one each within
    range and their product taken in logs).
    """
    got = _tracker_hypotheses(trk, sc)
    total = sum(exact.values())
    for key, lw in got.items():
        if lw < FLOOR and key not in exact:
            continue
        assert key in exact, key
        want = log_fraction(exact[key] / total)
        if want >= FLOOR:
            assert abs(lw - want) <= 1e-12 * max(1.0, abs(want)), (key, lw, want)
    for key, w in exact.items():
        if log_fraction(w / total) >= FLOOR:
            assert key in got, key


@settings(max_examples=40, deadline=None)
@given(sc=pmbm_prior())
def test_k_infinity_equals_the_full_enumeration(sc):
    trk = _tracker(sc, p_g=1.0, max_hypotheses=10**6)
    exact = {}
    for events in _enumerate(sc):
        for key, w in events:  # identical hypotheses are one (the tracker merges them)
            exact[key] = exact.get(key, Fraction(0)) + w
    result = trk.step(0.0, sc["z"])
    _check_against(trk, sc, exact)
    # estimator 1: the Bernoullis of the most probable hypothesis with r ≥ r_estimate
    ranked = sorted(exact.values(), reverse=True)
    assume(len(ranked) == 1 or ranked[1] < ranked[0] * (1 - Fraction(1, 10**6)))
    best = max(exact, key=exact.get)
    kids = _children(sc)
    reported = []
    for t, lab in enumerate(best[0]):
        if lab is not None:
            r = next(k[1] for k in kids[t] if k[0] == lab)
            if r >= trk.config.r_estimate:
                reported.append((t + 1, r))
    n_old = len(reported)
    for j in sorted(best[1]):
        r = kids[("new", j)][0][1]
        if r >= trk.config.r_estimate:
            reported.append((None, r))
    assert len(result.ids) == len(reported)
    np.testing.assert_array_equal(result.ids[:n_old], [t for t, _ in reported[:n_old]])
    assert (result.ids[n_old:] > sc["T"]).all()
    np.testing.assert_allclose(result.existence, [r for _, r in reported], rtol=1e-9)


def _top(events, k):
    """The k heaviest (key, weight); the k-th strictly heavier than the next."""
    events = sorted(events, key=lambda kw: kw[1], reverse=True)
    if len(events) > k:
        assume(events[k][1] < events[k - 1][1] * (1 - Fraction(1, 10**6)))
    return events[:k]


@settings(max_examples=40, deadline=None)
@given(
    sc=pmbm_prior(centres=(0.0, 5000.0), spread=30.0, quiet=True),
    K=st.integers(1, 12),
)
def test_k_best_per_cluster_equals_the_ranked_enumeration(sc, K):
    """Gated clusters, a quiet track, ⌈K w_h⌉ per prior hypothesis, K overall."""
    trk = _tracker(sc, p_g=0.99, max_hypotheses=K)
    k_h = np.maximum(1, np.ceil(K * trk.hypothesis_weights())).astype(int)
    kept = [kw for events, k in zip(_enumerate(sc, 0.99), k_h, strict=True)
            for kw in _top(events, int(k))]  # fmt: skip
    kept = _top(kept, K)
    exact = {}
    for key, w in kept:
        exact[key] = exact.get(key, Fraction(0)) + w
    trk.step(0.0, sc["z"])
    _check_against(trk, sc, exact)
    assert trk.n_hypotheses == len(exact)


def test_prior_weight_is_carried_into_the_children():
    """A sharp case: two prior hypotheses 0.9/0.1 over one track present or absent."""
    sc = {
        "T": 2,
        "sth_track": np.array([0, 1]),
        "r": [0.9, 0.6],
        "x": np.array([[0.0, 0, 1, 0], [40.0, 0, 0, 1]]),
        "P": np.stack([np.diag([50.0, 50, 4, 4])] * 2),
        "hyp": np.array([[0, 1], [0, -1]]),
        "w": [0.9, 0.1],
        "z": np.array([[2.0, 1.0], [35.0, -2.0]]),
        "p_d": 0.9,
        "lam": 1e-4,
        "u": 1e-6,
        "R": 25.0,
    }
    trk = _tracker(sc, p_g=1.0, max_hypotheses=10**6)
    exact = {}
    for events in _enumerate(sc):
        for key, w in events:
            exact[key] = exact.get(key, Fraction(0)) + w
    trk.step(0.0, sc["z"])
    _check_against(trk, sc, exact)
    # 1 + 2 + 2 + 2 = 7 events with the second track, 3 without it
    assert trk.n_hypotheses == 10
    # a uniform prior (0.5/0.5) would give other weights: the comparison is sharp
    flat = dict(sc, w=[0.5, 0.5])
    other = {}
    for events in _enumerate(flat):
        for key, w in events:
            other[key] = other.get(key, Fraction(0)) + w
    got = _tracker_hypotheses(trk, sc)
    total = sum(other.values())
    assert max(abs(lw - log_fraction(other[k] / total)) for k, lw in got.items()) > 0.1


def test_hypotheses_far_below_the_best_keep_finite_exact_log_weights(tmp_path):
    """Regression: merging duplicates took a logsumexp relative to 0, not to the group max.

    A hypothesis with normalised log weight ℓ < −708 came out of the merge as
    log(exp(ℓ)) with exp(ℓ) subnormal (relative error ~1e-9 at ℓ ≈ −726) or,
    for ℓ < −745, as −inf — a state that ``load`` then refuses (non-finite
    'hyp_logw'). With ``hypothesis_prune = 0`` nothing prunes them. Here two
    far tracks each detect a far return (log likelihood ratio ≈ −400 against
    the miss, well inside float64), so "both detected" has ℓ ≈ −800.
    """
    sc = {
        "T": 2,
        "sth_track": np.array([0, 1]),
        "r": [1.0, 1.0],
        "x": np.array([[0.0, 0.0, 0.0, 0.0], [1000.0, 0.0, 0.0, 0.0]]),
        "P": np.stack([np.eye(4)] * 2),
        "hyp": np.array([[0, 1]]),
        "w": [1.0],
        "z": np.array([[0.0, 93.0], [1000.0, 93.5]]),
        "p_d": 0.5,
        "lam": 1e-2,
        "u": 1e-3,
        "R": 10.0,
    }
    trk = _tracker(sc, p_g=1.0, max_hypotheses=10**6)
    exact = {key: w for events in _enumerate(sc) for key, w in events}
    trk.step(0.0, sc["z"])
    assert np.isfinite(trk.hyp_logw).all(), trk.hyp_logw
    assert trk.hyp_logw.min() < -760  # "both detected" is there, at its weight
    _check_against(trk, sc, exact)
    # the cross pairs (track 0 with the return at x = 1000, …) underflow: 4 events
    assert trk.n_hypotheses == 4
    path = trk.save(tmp_path / "far.npz")
    np.testing.assert_array_equal(PMBMTracker.load(path).hyp_logw, trk.hyp_logw)
