"""PMB association marginals against the exact enumeration of all association events.

The track-oriented PMB update (J. L. Williams, "Marginal multi-Bernoulli
filters: RFS derivation of MHT, JIPDA, and association-based MeMBer", *IEEE
Transactions on Aerospace and Electronic Systems* 51(3):1664–1687, 2015) with
Bernoullis i (existence r_i, Gaussian density) and returns j: an association
event maps each Bernoulli to "missed" (weight 1 − r_i P_D) or to one distinct
return j (weight r_i P_D g_ij); every return no Bernoulli takes contributes
ρ_j = λ_c + e_j (clutter or the first detection of an undetected target,
e_j = P_D ∫ g_j D). The tests enumerate these events in exact rational
arithmetic (:class:`fractions.Fraction` of the float Gaussian likelihoods) and
compare

* the marginals β of :meth:`ScanTracker._pair_marginals` on the tracker's
  likelihood ratios L_ij = r_i P_D g_ij / ρ_j and miss weights 1 − r_i P_D;
* end to end, one :meth:`PMBTracker.step` from a hand-set state with no gating
  (p_g = 1): the posterior existences r_i' = P(i exists | data), the merged
  means and covariances (Williams 2015 eq. (58)–(60)), and the existences of
  the new Bernoullis r_new_j = P(j unassigned) e_j / ρ_j.

Tolerance: 1e-9 relative (a float pipeline against exact values), plus
1e-13 · e_j/ρ_j absolute on r_new_j — the tracker forms it as 1 − Σ_i β_ij,
whose rounding (~1e-16 absolute) is all that is left when Σ_i β_ij ≈ 1.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.stats import multivariate_normal

from brute import _matchings, brute_assignment
from jointtrack.trackers.pmbm import PMBMConfig, PMBTracker

LN2 = math.log(2.0)


def fraction_exp(log_value: float) -> Fraction:
    """exp(log_value) as an exact rational, with no underflow (2^k · exp(rest))."""
    k = math.floor(log_value / LN2)
    return Fraction(math.exp(log_value - k * LN2)) * Fraction(2) ** k


def _finite(lo, hi):
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False, allow_subnormal=False)


def _log_uniform(lo, hi):
    return _finite(lo, hi).map(lambda v: 10.0**v)


@st.composite
def pmb_scene(draw):
    """Bernoullis, returns and model numbers; likelihoods from vanishing to dominant."""
    n = draw(st.integers(1, 3))
    m = draw(st.integers(1, 4))
    r = [draw(st.one_of(st.just(1.0), _finite(1e-3, 1.0))) for _ in range(n)]
    x = np.array(
        [
            [draw(_finite(-150, 150)), draw(_finite(-150, 150)), draw(_finite(-5, 5)), 0.0]
            for _ in range(n)
        ]
    )
    P = np.zeros((n, 4, 4))
    for i in range(n):
        sx, sy = draw(_log_uniform(0, 3)), draw(_log_uniform(0, 3))
        c = draw(_finite(-0.9, 0.9)) * math.sqrt(sx * sy)
        P[i, :2, :2] = [[sx, c], [c, sy]]
        P[i, 2, 2] = P[i, 3, 3] = draw(_log_uniform(-1, 2))
        # position–velocity correlation k with c² + k² < 1: positive definite
        k = 0.3 * math.sqrt(1.0 - (c * c) / (sx * sy))
        P[i, 0, 2] = P[i, 2, 0] = k * math.sqrt(sx * P[i, 2, 2])
    z = np.array([[draw(_finite(-150, 150)), draw(_finite(-150, 150))] for _ in range(m)])
    assume(len({tuple(row) for row in z.tolist()}) == m)  # coincident returns are merged
    return {
        "r": r,
        "x": x,
        "P": P,
        "z": z,
        "p_d": draw(_finite(0.3, 0.99)),
        "lam": draw(_log_uniform(-7, -2)),
        "u": draw(_log_uniform(-8, -3)),
        "R": draw(_log_uniform(0, 2.5)),
    }


def _likelihoods(sc):
    """g_ij = N(z_j; H x_i, H P_i Hᵀ + R) as exact rationals (scipy's log-density)."""
    R = sc["R"] * np.eye(2)
    return [
        [
            fraction_exp(float(multivariate_normal(xi[:2], Pi[:2, :2] + R).logpdf(zj)))
            for zj in sc["z"]
        ]
        for xi, Pi in zip(sc["x"], sc["P"], strict=True)
    ]


def _kalman(x, P, z, R):
    H = np.eye(2, 4)
    S = H @ P @ H.T + R * np.eye(2)
    K = P @ H.T @ np.linalg.inv(S)
    return x + K @ (z - H @ x), P - K @ S @ K.T


def _enumerate(sc):
    """Exact event probabilities of the PMB association (ρ convention, Fractions).

    Returns ``(beta, beta0, free, rho, e)``: β_ij, β_i0 (missed or absent),
    P(return j unassigned), ρ_j and e_j.
    """
    n, m = len(sc["r"]), len(sc["z"])
    pd = Fraction(sc["p_d"])
    r = [Fraction(v) for v in sc["r"]]
    g = _likelihoods(sc)
    e = [pd * Fraction(sc["u"])] * m
    rho = [Fraction(sc["lam"]) + ej for ej in e]
    beta = [[Fraction(0)] * m for _ in range(n)]
    beta0 = [Fraction(0)] * n
    free = [Fraction(0)] * m
    total = Fraction(0)
    for sigma in _matchings(n, m, [True] * n):
        w = Fraction(1)
        for i, j in enumerate(sigma):
            w *= 1 - r[i] * pd if j is None else r[i] * pd * g[i][j]
        for j in range(m):
            if j not in sigma:
                w *= rho[j]
        total += w
        for i, j in enumerate(sigma):
            if j is None:
                beta0[i] += w
            else:
                beta[i][j] += w
        for j in range(m):
            if j not in sigma:
                free[j] += w
    beta = [[b / total for b in row] for row in beta]
    beta0 = [b / total for b in beta0]
    free = [f / total for f in free]
    return beta, beta0, free, rho, e


def _config(sc, **kw):
    return PMBMConfig(
        p_d=sc["p_d"],
        p_g=1.0,
        clutter_density=sc["lam"],
        measurement_noise=sc["R"],
        prior_density=sc["u"],
        r_prune=0.0,
        r_recycle=0.0,  # exact comparisons: no Bernoulli moves into the intensity
        # the textbook update the enumeration defines (Williams 2015 eq. (58)–(60)): each
        # Bernoulli's whole mixture merged, no Bernoullis merged with each other
        keep_apart=False,
        duplicate_distance=0.0,
        **kw,
    )


def _tracker(sc, **kw):
    trk = PMBTracker(_config(sc, **kw))
    n = len(sc["r"])
    trk.x, trk.P = sc["x"].copy(), sc["P"].copy()
    trk.ids = np.arange(1, n + 1, dtype=np.int64)
    trk.existence = np.array(sc["r"], float)
    trk.reported = np.zeros(n, bool)
    trk.born, trk.report_count = np.zeros(n), np.zeros(n)
    trk.next_id = n + 1
    return trk


@settings(max_examples=60, deadline=None)
@given(sc=pmb_scene())
def test_pair_marginals_equal_the_rational_enumeration(sc):
    """β from the tracker's L, miss (``_pair_weights``) and ``_pair_marginals`` = brute force."""
    trk = _tracker(sc)
    z = sc["z"]
    rho, e, _, _ = trk._poisson_detection(z)
    g = trk._gate(trk.x, trk.P, z)
    n, m = len(sc["r"]), len(z)
    assert len(g.rows) == n * m  # p_g = 1: every pair is a hypothesis
    L, miss = trk._pair_weights(trk.existence, g, rho)
    beta0, pair_beta, _, _ = trk._pair_marginals(trk.ids, g, L, miss, True)
    beta, beta0_exact, _, rho_exact, _ = _enumerate(sc)
    np.testing.assert_allclose(rho, [float(v) for v in rho_exact], rtol=1e-15)
    np.testing.assert_allclose(beta0, [float(v) for v in beta0_exact], rtol=1e-9, atol=1e-300)
    got = np.zeros((n, m))
    got[g.rows, g.cols] = pair_beta
    want = np.array([[float(v) for v in row] for row in beta])
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-300)
    # the cluster convention itself: brute force over the tracker's own L and miss
    Lmat = np.zeros((n, m))
    Lmat[g.rows, g.cols] = L
    _, P_b, P0_b = brute_assignment(Lmat, null=miss)
    # atol: a subnormal β (below 2.2e-308) holds fewer than 53 bits, one ulp (5e-324)
    # of 1.5e-315 is 3e-9 relative
    want = [[float(v) for v in row] for row in P_b]
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-300)
    np.testing.assert_allclose(beta0, [float(v) for v in P0_b], rtol=1e-9, atol=1e-300)


@settings(max_examples=60, deadline=None)
@given(sc=pmb_scene())
def test_pmb_step_posterior_equals_the_rational_enumeration(sc):
    """One PMB step: r_i', merged moments and r_new_j against the exact events."""
    trk = _tracker(sc)
    n, m = len(sc["r"]), len(sc["z"])
    pd = Fraction(sc["p_d"])
    beta, beta0, free, rho, e = _enumerate(sc)
    trk.step(0.0, sc["z"])
    # prior Bernoullis keep their ids and order; new ones follow
    np.testing.assert_array_equal(trk.ids[:n], np.arange(1, n + 1))
    for i in range(n):
        ri = Fraction(sc["r"][i])
        missed = beta0[i] * ri * (1 - pd) / (1 - ri * pd)  # exists and was missed
        r_post = missed + sum(beta[i])
        assert math.isclose(trk.existence[i], float(r_post), rel_tol=1e-9)
        # Williams 2015 eq. (58)–(60): the existence-weighted mixture, merged
        comps = [(float(missed / r_post), sc["x"][i], sc["P"][i])]
        for j in range(m):
            xj, Pj = _kalman(sc["x"][i], sc["P"][i], sc["z"][j], sc["R"])
            comps.append((float(beta[i][j] / r_post), xj, Pj))
        mean = sum(w * xc for w, xc, _ in comps)
        cov = sum(w * (Pc + np.outer(xc - mean, xc - mean)) for w, xc, Pc in comps)
        scale = 1.0 + np.abs(mean).max()
        np.testing.assert_allclose(trk.x[i], mean, rtol=1e-9, atol=1e-9 * scale)
        np.testing.assert_allclose(trk.P[i], cov, rtol=1e-9, atol=1e-9 * np.abs(cov).max())
    # new Bernoullis: one per return with r_new > 0, at the return (uniform birth)
    new_x = trk.x[n:, :2]
    assert len(new_x) <= m
    born = []
    for j in range(m):
        r_exact = free[j] * e[j] / rho[j]
        share = float(e[j] / rho[j])
        hit = np.flatnonzero((new_x == sc["z"][j]).all(axis=1))
        assert len(hit) <= 1
        if len(hit) == 0:  # 1 − Σβ rounded to 0: only allowed when it is negligible
            assert float(r_exact) <= 1e-13 * share
            continue
        born.append(hit[0])
        got = trk.existence[n + hit[0]]
        assert abs(got - float(r_exact)) <= 1e-9 * float(r_exact) + 1e-13 * share, (
            got,
            float(r_exact),
        )
    assert sorted(born) == list(range(len(new_x)))  # every new Bernoulli is some return's
    np.testing.assert_array_equal(trk.ids[n:], n + 1 + np.arange(len(new_x)))


def test_enumeration_detects_a_wrong_miss_weight():
    """The comparison is sharp: a miss weight without r (1 − P_D) gives other marginals."""
    sc = {
        "r": [0.3, 0.8],
        "x": np.array([[0.0, 0.0, 0.0, 0.0], [20.0, 0.0, 0.0, 0.0]]),
        "P": np.stack([np.diag([100.0, 100.0, 1.0, 1.0])] * 2),
        "z": np.array([[5.0, 0.0], [15.0, 1.0]]),
        "p_d": 0.9,
        "lam": 1e-4,
        "u": 1e-5,
        "R": 25.0,
    }
    trk = _tracker(sc)
    rho, _, _, _ = trk._poisson_detection(sc["z"])
    g = trk._gate(trk.x, trk.P, sc["z"])
    L, _ = trk._pair_weights(trk.existence, g, rho)
    wrong = np.full(2, 1.0 - sc["p_d"])
    beta0, _, _, _ = trk._pair_marginals(trk.ids, g, L, wrong, True)
    _, beta0_exact, _, _, _ = _enumerate(sc)
    assert not np.allclose(beta0, [float(v) for v in beta0_exact], rtol=1e-3)
