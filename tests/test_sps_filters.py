"""SPS-PHD / SPS-CPHD / SPS-MB particle filters: updates vs ground truth, invariants, bad input.

Ground truth is importance sampling of the prior RFS weighted by
N(y − ζ(Ξ); 0, Σ0) (the posterior of the set, no approximation), and, where
the model makes y Gaussian, the closed form. The cases are chosen so that the
filter's approximation is exact or nearly so, and the tolerances are a few
standard deviations of the particle and Monte Carlo noise:

* SPS-CPHD with Gaussian spatial density, linear g: given n, y is exactly
  Gaussian, so the cardinality update and, for a known n, the reduced-IIDC
  ratio (20) are exact; only particles and resampling add noise.
* SPS-MB where the other components exist surely (r = 1, linear g): the
  leave-one-out sum is exactly Gaussian, so r₊ and p₊ are exact.
* SPS-PHD: its update D₊ = D R is exact for a Poisson prior; with the
  ``"montecarlo"`` ratio the filter must match the ground truth.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from scipy.stats import multivariate_normal

from jointtrack.superpositional.filters import (
    FilterSettings,
    SPSCPHDFilter,
    SPSMBFilter,
    SPSPHDFilter,
    systematic_resample,
)
from jointtrack.superpositional.filters.cphd import predict_cardinality
from jointtrack.superpositional.measurement import FunctionMeasurement

# the report's H (11) on the position of (px, py, vx, vy)
H = np.array([[0.1, 0.7, 0, 0], [0.5, 0.5, 0, 0], [0.8, 0.2, 0, 0]])
SIGMA0 = 0.25 * np.eye(3)
REGION = [[-5.0, 5.0], [-5.0, 5.0]]
PRIOR_COV = np.diag([1.0, 1.0, 0.01, 0.01])
FAST = dict(n_birth_particles=10, birth_rate=0.0, p_survival=1.0)
SETTINGS = settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _gauss_particles(mean, n, rng):
    return rng.multivariate_normal(mean, PRIOR_COV, size=n)


def _importance(sets_pos, present, y, rng=None):
    """Normalised weights of prior set samples: N(y − Σ H x) with sets (S, n, 2), mask (S, n)."""
    ys = np.einsum("sni,ji,sn->sj", sets_pos, H[:, :2], present.astype(float))
    lw = multivariate_normal(np.zeros(3), SIGMA0).logpdf(y - ys)
    w = np.exp(lw - lw.max())
    return w / w.sum()


# ----------------------------------------------------------------------------- SPS-CPHD


@SETTINGS
@given(n=st.integers(1, 3), seed=st.integers(0, 2**20))
def test_cphd_update_known_cardinality_matches_importance_sampling(n, seed):
    """pmf δ_n, Gaussian s, linear g: posterior PHD mass in {px > 0} vs importance sampling.

    Exact up to noise: filter 6,000 particles (resampled; sd ≤ 0.03 for n = 3),
    truth 100,000 sets (sd ≈ 0.01); tolerance 0.12.
    """
    rng = np.random.default_rng(seed)
    truth = _gauss_particles(np.zeros(4), n, rng)
    y = H @ truth.sum(axis=0) + rng.multivariate_normal(np.zeros(3), SIGMA0)
    f = SPSCPHDFilter(H, SIGMA0, REGION, max_cardinality=3, n_particles=6000, rng=seed, **FAST)
    pmf = np.zeros(4)
    pmf[n] = 1.0
    f.set_state(pmf, _gauss_particles(np.zeros(4), 6000, rng))
    f.update(y)
    assert f.cardinality_pmf[n] == pytest.approx(1.0)
    mass_filter = n * np.mean(f.particles[:, 0] > 0)

    S = 100_000
    sets = rng.multivariate_normal(np.zeros(2), np.eye(2), size=(S, n))
    w = _importance(sets, np.ones((S, n), bool), y)
    mass_truth = w @ (sets[:, :, 0] > 0).sum(axis=1)
    assert mass_filter == pytest.approx(mass_truth, abs=0.12)


@SETTINGS
@given(seed=st.integers(0, 2**20), n_true=st.integers(0, 3))
def test_cphd_cardinality_update_matches_closed_form_and_sampling(seed, n_true):
    """Uniform pmf on 0..3, Gaussian s: π₊(n) ∝ π(n) N(y; n H m, Σ0 + n H P Hᵀ) exactly.

    The filter's moments come from 6,000 particles (relative moment error ~1 %);
    tolerance 0.04 per entry against the closed form and 0.05 against 100,000
    importance-sampled sets.
    """
    rng = np.random.default_rng(seed)
    m = np.array([1.0, -0.5, 0.0, 0.0])
    truth = _gauss_particles(m, n_true, rng)
    y = H @ truth.sum(axis=0) + rng.multivariate_normal(np.zeros(3), SIGMA0)
    f = SPSCPHDFilter(H, SIGMA0, REGION, max_cardinality=3, n_particles=3000, rng=seed, **FAST)
    f.set_state(np.full(4, 0.25), _gauss_particles(m, 6000, rng))
    f.update(y)
    Hm, HPH = H @ m, H @ PRIOR_COV @ H.T
    lp = np.array([multivariate_normal(n * Hm, SIGMA0 + n * HPH).logpdf(y) for n in range(4)])
    exact = np.exp(lp - lp.max())
    exact /= exact.sum()
    np.testing.assert_allclose(f.cardinality_pmf, exact, atol=0.04)

    S = 100_000
    counts = rng.integers(0, 4, S)
    sets = rng.multivariate_normal(m[:2], np.eye(2), size=(S, 3))
    present = np.arange(3)[None, :] < counts[:, None]
    w = _importance(sets, present, y)
    mc = np.bincount(counts, weights=w, minlength=4)
    np.testing.assert_allclose(f.cardinality_pmf, mc, atol=0.05)


# ----------------------------------------------------------------------------- SPS-PHD


def test_phd_update_with_montecarlo_ratio_matches_importance_sampling():
    """Poisson prior (λ = 1.5, Gaussian s): D₊ = D R is exact, so with the Monte Carlo ratio
    the posterior mean count and the mass in {px > 0} match importance sampling.

    Filter: 1,000 particles, R from 10,000 set samples (log R sd ≈ 0.03);
    truth: 200,000 sets. Tolerance 0.1 (≈ 3 sd of the filter's resampling noise).
    """
    rng = np.random.default_rng(11)
    lam = 1.5
    y = H @ np.array([0.8, 0.3, 0, 0]) + H @ np.array([-1.0, 0.6, 0, 0])
    f = SPSPHDFilter(
        H,
        SIGMA0,
        REGION,
        likelihood="montecarlo",
        likelihood_options={"n_samples": 10_000, "rng": 5},
        n_particles=1000,
        rng=1,
        **FAST,
    )
    f.set_state(_gauss_particles(np.zeros(4), 1000, rng), None, lam)
    f.update(y)
    S, N = 200_000, 10
    counts = np.minimum(rng.poisson(lam, S), N)
    sets = rng.standard_normal((S, N, 2))
    present = np.arange(N)[None, :] < counts[:, None]
    w = _importance(sets, present, y)
    assert f.expected_cardinality == pytest.approx(w @ counts, abs=0.1)
    mass_a = f.expected_cardinality * np.mean(f.particles[:, 0] > 0)
    assert mass_a == pytest.approx(w @ ((sets[:, :, 0] > 0) & present).sum(1), abs=0.1)


def test_phd_gaussian_update_close_when_noise_dominates():
    """With Σ0 = 9 I the Gaussian ratio (20) is within 5 % of the truth's posterior mean count.

    Q (compound Poisson) is far from Gaussian, but convolved with a wide noise
    the likelihood varies slowly over its support; 150,000 importance samples.
    """
    rng = np.random.default_rng(2)
    noise = 9.0 * np.eye(3)
    y = np.array([1.5, 2.0, 2.5])
    f = SPSPHDFilter(H, noise, REGION, n_particles=4000, rng=1, **FAST)
    f.set_state(_gauss_particles(np.zeros(4), 4000, rng), None, 2.0)
    f.update(y)
    S, N = 150_000, 12
    counts = np.minimum(rng.poisson(2.0, S), N)
    sets = rng.standard_normal((S, N, 2))
    present = np.arange(N)[None, :] < counts[:, None]
    ys = np.einsum("sni,ji,sn->sj", sets, H[:, :2], present.astype(float))
    lw = multivariate_normal(np.zeros(3), noise).logpdf(y - ys)
    w = np.exp(lw - lw.max())
    w /= w.sum()
    assert f.expected_cardinality == pytest.approx(w @ counts, rel=0.05)


# ----------------------------------------------------------------------------- SPS-MB


@SETTINGS
@given(r=st.floats(0.05, 0.95), seed=st.integers(0, 2**20))
@example(r=0.5, seed=125)  # off by 0.034 from the closed form: particle noise, not the formula
@example(r=0.25, seed=53)  # off by 0.015: outside the delta-method bound on Â alone
def test_mb_existence_update_matches_exact_and_sampling(r, seed):
    """Components (r, p₁) and (1, p₂): the leave-one-out set of 1 is component 2 (Gaussian y),
    so r₁₊ = r A / ((1 − r) B + r A) is exact given A and B.

    Three checks: the filter equals that formula evaluated on its own particles (A as
    the particle mean of N(y − Hx − μ̂₂; Σ0 + Σ̂₂), μ̂₂, Σ̂₂ the particle moments) to
    1e-9; it is within 4 Monte Carlo standard errors (bootstrap over the 4,000
    particles of both components) + 0.005 of the closed form; and within 4 standard
    errors + 0.005 of 100,000 importance-sampled sets (standard error from the weights).
    """
    rng = np.random.default_rng(seed)
    m1, m2 = np.array([1.0, 1.0, 0, 0]), np.array([-1.0, 0.5, 0, 0])
    exists = rng.random() < r
    y = H @ (_gauss_particles(m2, 1, rng)[0] + exists * _gauss_particles(m1, 1, rng)[0])
    y = y + rng.multivariate_normal(np.zeros(3), SIGMA0)
    f = SPSMBFilter(H, SIGMA0, REGION, n_particles=4000, rng=seed, prune_threshold=0.0, **FAST)
    f_particles = [_gauss_particles(m1, 4000, rng), _gauss_particles(m2, 4000, rng)]
    f.set_state([r, 1.0], f_particles)
    f.update(y)
    x1, x2 = f_particles

    def plug_in_of(x1, x2):
        g2 = x2 @ H.T
        mu2, S2 = g2.mean(0), np.cov(g2.T, bias=True)
        A = multivariate_normal(mu2, SIGMA0 + S2).pdf(y - x1 @ H.T).mean()
        B = multivariate_normal(mu2, SIGMA0 + S2).pdf(y)
        return r * A / ((1 - r) * B + r * A)

    plug_in = plug_in_of(x1, x2)
    assert f.r[0] == pytest.approx(plug_in, abs=1e-9)
    HP = H @ PRIOR_COV @ H.T
    la = multivariate_normal(H @ (m1 + m2), SIGMA0 + 2 * HP).logpdf(y)
    lb = multivariate_normal(H @ m2, SIGMA0 + HP).logpdf(y)
    exact = 1.0 / (1.0 + (1 - r) / r * np.exp(lb - la))
    # Monte Carlo standard error of the plug-in by bootstrap over both particle sets: the
    # moments μ̂₂, Σ̂₂ vary with the particles too (a delta method on Â alone missed that and
    # failed at r = 0.25, seed 53)
    n = len(x1)
    boot = [plug_in_of(x1[rng.integers(0, n, n)], x2[rng.integers(0, n, n)]) for _ in range(100)]
    se = float(np.std(boot))
    assert abs(f.r[0] - exact) <= 4 * se + 0.005
    assert f.r[1] == pytest.approx(1.0)

    S = 100_000
    sets = np.stack(
        [
            rng.multivariate_normal(m1[:2], np.eye(2), S),
            rng.multivariate_normal(m2[:2], np.eye(2), S),
        ],
        1,
    )
    present = np.column_stack([rng.random(S) < r, np.ones(S, bool)])
    w = _importance(sets, present, y)
    mc = w @ present[:, 0]
    mc_se = np.sqrt(np.sum(w**2 * (present[:, 0] - mc) ** 2))
    assert abs(f.r[0] - mc) <= 4 * np.hypot(se, mc_se) + 0.005


def test_mb_posterior_density_matches_importance_sampling():
    """Two sure components: p₁₊ ∝ p₁(x) N(y − Hx; H m₂, Σ0 + H P Hᵀ) is exact; posterior
    mean of component 1's position vs importance sampling, tolerance 0.05 m."""
    rng = np.random.default_rng(4)
    m1, m2 = np.array([1.0, 1.0, 0, 0]), np.array([-1.0, 0.5, 0, 0])
    y = H @ np.array([1.5, 0.2, 0, 0]) + H @ np.array([-0.5, 1.0, 0, 0])
    f = SPSMBFilter(H, SIGMA0, REGION, n_particles=20_000, rng=2, **FAST)
    f.set_state([1.0, 1.0], [_gauss_particles(m1, 20_000, rng), _gauss_particles(m2, 20_000, rng)])
    f.update(y)
    est = f.estimate()
    S = 400_000
    a = rng.multivariate_normal(m1[:2], np.eye(2), S)
    b = rng.multivariate_normal(m2[:2], np.eye(2), S)
    w = _importance(np.stack([a, b], 1), np.ones((S, 2), bool), y)
    np.testing.assert_allclose(est[0, :2], w @ a, atol=0.05)


# ----------------------------------------------------------------------------- invariants


@settings(max_examples=40, deadline=None)
@given(
    w=st.lists(st.floats(0.0, 10.0), min_size=1, max_size=30).filter(lambda v: sum(v) > 1e-3),
    n=st.integers(1, 200),
    seed=st.integers(0, 2**20),
)
def test_systematic_resample_copies_floor_or_ceil(w, n, seed):
    idx = systematic_resample(w, n, np.random.default_rng(seed))
    assert idx.shape == (n,)
    counts = np.bincount(idx, minlength=len(w))
    expected = n * np.asarray(w) / np.sum(w)
    assert np.all(counts >= np.floor(expected - 1e-9)) and np.all(
        counts <= np.ceil(expected + 1e-9)
    )


@settings(max_examples=40, deadline=None)
@given(
    pmf=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=8).filter(lambda v: sum(v) > 1e-3),
    ps=st.floats(0.0, 1.0),
    b=st.floats(0.0, 0.5),
)
def test_predicted_cardinality_is_a_pmf_with_the_right_mean(pmf, ps, b):
    p = np.asarray(pmf) / np.sum(pmf)
    long = np.concatenate([p, np.zeros(30)])
    with np.errstate(divide="ignore"):
        out = np.exp(predict_cardinality(np.log(long), ps, b))
    assert out.sum() == pytest.approx(1.0)
    n = np.arange(long.size)
    assert out @ n == pytest.approx(ps * (p @ n[: p.size]) + b, abs=1e-9)


@pytest.mark.parametrize("cls", [SPSPHDFilter, SPSCPHDFilter])
def test_prediction_mass_survival_and_birth(cls):
    f = cls(
        H,
        SIGMA0,
        REGION,
        n_particles=500,
        n_birth_particles=200,
        p_survival=0.9,
        birth_rate=0.3,
        rng=0,
    )
    rng = np.random.default_rng(0)
    if cls is SPSPHDFilter:
        f.set_state(_gauss_particles(np.zeros(4), 500, rng), None, 2.0)
    else:
        f.set_state([0.0, 0.0, 1.0], _gauss_particles(np.zeros(4), 500, rng))
    f.predict()
    assert f.expected_cardinality == pytest.approx(0.9 * 2.0 + 0.3, abs=1e-6)
    assert f.particles.shape == (700, 4)
    assert f.weights.sum() == pytest.approx(1.0)
    # the birth particles carry b / (p_S n̄ + b) of the spatial mass, all inside the region
    assert f.weights[500:].sum() == pytest.approx(0.3 / 2.1)
    assert np.all(np.abs(f.particles[500:, :2]) <= 5.0)


def test_mb_prediction_adds_a_labelled_birth_component():
    f = SPSMBFilter(
        H,
        SIGMA0,
        REGION,
        n_particles=50,
        n_birth_particles=80,
        p_survival=0.9,
        birth_rate=0.2,
        rng=0,
    )
    f.set_state([0.5], [np.zeros((50, 4))])
    f.predict()
    np.testing.assert_allclose(f.r, [0.45, 0.2])
    assert [p.shape for p in f.particles] == [(50, 4), (80, 4)]
    assert len(set(f.labels.tolist())) == 2


@pytest.mark.parametrize("cls", [SPSPHDFilter, SPSCPHDFilter, SPSMBFilter])
def test_failed_update_leaves_the_state_unchanged(cls):
    broken = {"on": False}

    def g(x):
        out = x[..., :2] @ H[:, :2].T
        return out * np.nan if broken["on"] else out

    meas = FunctionMeasurement(g, dy=3, dx=4)
    f = cls(meas, SIGMA0, REGION, n_particles=100, n_birth_particles=50, rng=0)
    f.predict()
    before = {
        k: (v.copy() if isinstance(v, np.ndarray) else list(v) if isinstance(v, list) else v)
        for k, v in vars(f).items()
        if k in ("particles", "weights", "r", "_log_pmf", "_log_mass")
    }
    broken["on"] = True
    with pytest.raises(ValueError, match="non-finite"):
        f.update([1.0, 2.0, 3.0])
    for k, v in before.items():
        now = getattr(f, k)
        if isinstance(v, list):
            assert all(np.array_equal(a, b) for a, b in zip(v, now, strict=True))
        else:
            assert np.array_equal(v, now)
    with pytest.raises(ValueError, match="y has a non-finite"):
        f.update([1.0, np.nan, 3.0])


# ----------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"noise_cov": -np.eye(3)}, "positive definite"),
        ({"noise_cov": np.eye(2)}, "noise_cov must be"),
        ({"noise_cov": np.eye(3) * (1 + 0j)}, "complex"),
        ({"likelihood": "bogus"}, "likelihood must be"),
        ({"region": [[0, 1]]}, "region"),
        ({"region": [[1, 0], [0, 1]]}, "min < max"),
        ({"p_survival": 1.5}, "p_survival"),
        ({"n_particles": True}, "n_particles"),
        ({"birth_rate": float("nan")}, "birth_rate"),
        ({"likelihood_options": [1]}, "likelihood_options"),
        ({"n_partcles": 10}, "unknown filter setting"),
    ],
)
def test_bad_arguments_name_themselves(kwargs, match):
    args = {"measurement": H, "noise_cov": SIGMA0, "region": REGION} | kwargs
    for cls in (SPSPHDFilter, SPSCPHDFilter, SPSMBFilter):
        with pytest.raises(ValueError, match=match):
            cls(**args)


def test_bad_state_and_readings():
    f = SPSCPHDFilter(H, SIGMA0, REGION, max_cardinality=3)
    with pytest.raises(ValueError, match="initial_pmf must be non-negative and sum to 1"):
        f.set_state([0.5, 0.6], np.zeros((5, 4)))
    with pytest.raises(ValueError, match=r"particles must be \(L, 4\)"):
        f.set_state([1.0], np.zeros((5, 2)))
    with pytest.raises(ValueError, match="y must be a vector of the 3"):
        f.update([1.0, 2.0])
    with pytest.raises(ValueError, match="y holds a boolean|y is boolean"):
        f.update([True, False, True])
    with pytest.raises(ValueError, match="at most max_cardinality"):
        SPSCPHDFilter(H, SIGMA0, REGION, max_cardinality=2, initial_pmf=[0.25] * 4)
    with pytest.raises(ValueError, match="r must be a vector of existence"):
        SPSMBFilter(H, SIGMA0, REGION).set_state([1.2], [np.zeros((3, 4))])
    with pytest.raises(ValueError, match="birth_rate is the birth component"):
        SPSMBFilter(H, SIGMA0, REGION, birth_rate=2.0)
    with pytest.raises(ValueError, match="dx = 4"):
        SPSPHDFilter(np.eye(2), np.eye(2), REGION)
    with pytest.raises(ValueError, match="weights sum to 0"):
        systematic_resample([0.0, 0.0], 3, 0)
    with pytest.raises(ValueError, match="dt"):
        FilterSettings(REGION, dt=0.0)


# ----------------------------------------------------------------------------- acoustic


def _acoustic_ospa(name, seed, n_scans, particles):
    from jointtrack.experiments.acoustic_run import make_filter
    from jointtrack.metrics.ospa import ospa
    from jointtrack.scenarios.acoustic import acoustic

    sc = acoustic(seed=seed)
    f, _ = make_filter(name, sc, seed=seed, particles=particles)
    o, right = [], []
    for k in range(n_scans):
        est = f.step(sc.measurements[k])
        o.append(ospa(sc.truth_positions[k], est[:, :2], c=10.0, p=1))
        right.append(est.shape[0] == sc.truth_positions[k].shape[0])
    return np.asarray(o), np.asarray(right), sc


def test_cphd_keeps_the_acoustic_targets():
    """SPS-CPHD (Gaussian likelihood, 2,000 particles) on acoustic seed 7, first 20 scans
    (three targets 8-20 m apart; the first birth is at scan 20): after a 5-scan burn-in
    the mean OSPA (c = 10 m, p = 1) is below 1.5 m (measured 0.37 m) and the MAP
    cardinality is right on every scan.

    Not tested because it does not hold: with targets closer than ~8 m (seeds 4, 5) the
    Gaussian ratio (20) leaves a blurred spatial density (OSPA 4-5 m), and at a birth the
    newborn target's particles explain the unexplained readings so much better than the
    others that the spatial density collapses onto it (benchmarks/RESULTS.md).
    """
    o, right, sc = _acoustic_ospa("sps-cphd", 7, 20, 2000)
    assert sc.info["born"][3] >= 20
    assert o[5:].mean() < 1.5, o
    assert right[5:].all()


def test_mb_keeps_the_acoustic_targets_through_births():
    """SPS-MB (Gaussian likelihood, 1,000 particles per component and per birth) on acoustic
    seed 1, 30 scans with births at scans 18 and 22: after a 5-scan burn-in mean OSPA
    < 2.5 m (measured 1.58 m) and the number of components with r > 0.5 is right on at
    least 90 % of the scans (measured 100 %)."""
    o, right, sc = _acoustic_ospa("sps-mb", 1, 30, 1000)
    assert sc.info["born"][2:] == [18, 22]
    assert o[5:].mean() < 2.5, o
    assert right[5:].mean() >= 0.9
