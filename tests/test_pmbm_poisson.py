"""The Poisson part of the PMB/PMBM trackers against its closed form.

García-Fernández, Williams, Granström and Svensson, "Poisson multi-Bernoulli
mixture filter: direct derivation and implementation", *IEEE Transactions on
Aerospace and Electronic Systems* 54(4):1883–1901, 2018:

* prediction (eq. (12)): the undetected intensity's Gaussian components go to
  weights P_S w, means F m, covariances F P Fᵀ + Q, and the birth mixture is
  appended; the uniform density goes to P_S u + b;
* a return z_j meets the undetected targets with
  e_j = Σ_c w_c P_D N(z_j; H m_c, H P_c Hᵀ + R) (eq. (25)) — or P_D u for the
  uniform density — and starts a Bernoulli with existence e_j / (λ_c + e_j)
  whose density is the moment-matched mixture of the per-component Kalman
  posteriors weighted by w_c P_D N(…) (eq. (26), collapsed to one Gaussian);
  for the uniform density it sits at the return with zero-mean velocity of
  per-axis σ = max_speed / 2;
* the update thins the undetected intensity to (1 − P_D) w (and (1 − P_D) u),
  same means and covariances (eq. (19));
* with ``prior_density`` None the uniform density starts at the steady state
  b / (1 − P_S (1 − P_D)) of prediction and thinning, and stays there.

Everything is compared with a direct numpy/scipy computation at 1e-12
(relative, with an absolute floor of 1e-12 × the array's scale). No pruning
or merging (``poisson_prune`` = ``poisson_merge`` = 0) and no gating (p_g = 1)
so that the closed form is the whole story; both trackers share this code
and both are run.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.stats import multivariate_normal

from jointtrack.trackers.pmbm import PMBMConfig, PMBMTracker, PMBTracker


def _finite(lo, hi):
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False, allow_subnormal=False)


def _log_uniform(lo, hi):
    return _finite(lo, hi).map(lambda v: 10.0**v)


@st.composite
def _spd(draw, scale_lo=0, scale_hi=3):
    """A 4 × 4 covariance B Bᵀ + D with drawn entries (positive definite)."""
    B = np.array([[draw(_finite(-3, 3)) for _ in range(4)] for _ in range(4)])
    D = np.diag([draw(_log_uniform(scale_lo, scale_hi)) for _ in range(4)])
    P = B @ B.T + D
    return 0.5 * (P + P.T)


@st.composite
def _gaussians(draw, lo, hi):
    k = draw(st.integers(lo, hi))
    w = np.array([draw(_log_uniform(-3, 1)) for _ in range(k)])
    m = np.array(
        [
            [draw(_finite(-100, 100)), draw(_finite(-100, 100)), draw(_finite(-5, 5)),
             draw(_finite(-5, 5))]
            for _ in range(k)
        ]
    ).reshape(k, 4)  # fmt: skip
    P = np.array([draw(_spd()) for _ in range(k)]).reshape(k, 4, 4)
    return w, m, P


class _Motion:
    """A drawn linear motion model (any F, any SPD Q): the tracker only calls these."""

    state_dim = 4

    def __init__(self, F, Q):
        self.F, self.Q = F, Q

    def transition(self, dt):
        return self.F

    def noise(self, dt):
        return self.Q


def _close(got, want, tol=1e-12):
    want = np.asarray(want, float)
    np.testing.assert_allclose(got, want, rtol=tol, atol=tol * (np.abs(want).max() + 1e-300))


def _kalman(m, P, z, R):
    H = np.eye(2, 4)
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    return m + K @ (z - H @ m), P - K @ S @ K.T


def _new_bernoullis(trk, kind):
    """(r, x, P) of the tracker's Bernoullis (no prior tracks: all are new)."""
    if kind is PMBTracker:
        return trk.existence, trk.x, trk.P
    assert trk.n_hypotheses == 1
    return trk.sth_r, trk.sth_x, trk.sth_P


@pytest.mark.parametrize("kind", [PMBTracker, PMBMTracker])
@settings(max_examples=25, deadline=None)
@given(
    prior=_gaussians(1, 3),
    birth=_gaussians(1, 2),
    F_off=st.lists(_finite(-0.5, 0.5), min_size=16, max_size=16),
    Q=_spd(-2, 1),
    z=st.lists(st.tuples(_finite(-150, 150), _finite(-150, 150)), min_size=1, max_size=4),
    p_d=_finite(0.2, 0.99),
    p_s=_finite(0.5, 1.0),
    lam=_log_uniform(-7, -3),
    R=_log_uniform(0, 2),
)
def test_gaussian_mixture_prediction_and_update(kind, prior, birth, F_off, Q, z, p_d, p_s, lam, R):
    z = np.array(z)
    assume(len({tuple(v) for v in z.tolist()}) == len(z))
    F = np.eye(4) + np.array(F_off).reshape(4, 4)
    bw, bm, bP = birth
    cfg = PMBMConfig(
        p_d=p_d,
        p_g=1.0,
        p_survive=p_s,
        clutter_density=lam,
        measurement_noise=R,
        birth_model="gaussian",
        birth_weights=tuple(bw),
        birth_means=tuple(map(tuple, bm)),
        birth_covs=tuple(tuple(map(tuple, C)) for C in bP),
        prior_weight=3.0,
        poisson_prune=0.0,
        poisson_merge=0.0,
        max_poisson_components=1000,
        r_prune=0.0,
        r_recycle=0.0,  # exact comparisons: no Bernoulli moves into the intensity
    )
    trk = kind(cfg, motion=_Motion(F, Q))
    # the prior intensity: prior_weight spread over the birth mixture's shape
    _close(trk.poisson_w, 3.0 * bw / bw.sum())
    np.testing.assert_array_equal(trk.poisson_m, bm)
    np.testing.assert_array_equal(trk.poisson_P, bP)
    w0, m0, P0 = prior
    trk.poisson_w, trk.poisson_m, trk.poisson_P = w0.copy(), m0.copy(), P0.copy()
    # prediction (eq. (12))
    w = np.concatenate([p_s * w0, bw])
    m = np.concatenate([m0 @ F.T, bm])
    P = np.concatenate([F @ P0 @ F.T + Q, bP])
    Rm = R * np.eye(2)
    H = np.eye(2, 4)
    # P_D w_c N(z_j; H m_c, H P_c Hᵀ + R) per component c (rows) and return j
    A = np.array(
        [p_d * wc * multivariate_normal(H @ mc, H @ Pc @ H.T + Rm).pdf(z)
         for wc, mc, Pc in zip(w, m, P, strict=True)]
    ).reshape(len(w), len(z))  # fmt: skip
    assume((A.sum(axis=0) > 1e-250).all())  # a return nothing explains starts nothing
    trk.time = 0.0
    trk.step(1.0, z)
    # detection of undetected targets (eq. (25)–(26)), one new Bernoulli per return
    r_got, x_got, P_got = _new_bernoullis(trk, kind)
    assert len(r_got) == len(z)
    for j, zj in enumerate(z):
        a = A[:, j]
        e = a.sum()
        post = [_kalman(mc, Pc, zj, Rm) for mc, Pc in zip(m, P, strict=True)]
        mean = sum(ac * xc for ac, (xc, _) in zip(a, post, strict=True)) / e
        cov = (
            sum(
                ac * (Pc + np.outer(xc - mean, xc - mean))
                for ac, (xc, Pc) in zip(a, post, strict=True)
            )
            / e
        )
        assert math.isclose(r_got[j], e / (lam + e), rel_tol=1e-12)
        _close(x_got[j], mean)
        _close(P_got[j], cov)
    # thinning (eq. (19)): same components, weights × (1 − P_D)
    _close(trk.poisson_w, (1.0 - p_d) * w)
    _close(trk.poisson_m, m)
    _close(trk.poisson_P, P)
    np.testing.assert_array_equal(trk.undetected_density, [0.0])


@pytest.mark.parametrize("kind", [PMBTracker, PMBMTracker])
@settings(max_examples=25, deadline=None)
@given(
    p_d=_finite(0.2, 0.99),
    p_s=_finite(0.5, 1.0),
    b=_log_uniform(-9, -4),
    lam=_log_uniform(-7, -3),
    R=_log_uniform(0, 2),
    max_speed=_finite(1.0, 100.0),
    n_empty=st.integers(0, 3),
    z=st.lists(st.tuples(_finite(-150, 150), _finite(-150, 150)), min_size=1, max_size=4),
)
def test_uniform_density_steady_state_and_update(kind, p_d, p_s, b, lam, R, max_speed, n_empty, z):
    z = np.array(z)
    assume(len({tuple(v) for v in z.tolist()}) == len(z))
    cfg = PMBMConfig(
        p_d=p_d,
        p_survive=p_s,
        clutter_density=lam,
        measurement_noise=R,
        birth_density=b,
        max_speed=max_speed,
        r_prune=0.0,
        r_recycle=0.0,  # exact comparisons: no Bernoulli moves into the intensity
    )
    trk = kind(cfg)
    u_pred = b / (1.0 - p_s * (1.0 - p_d))  # fixed point of u ← P_S (1 − P_D) u + b
    assert math.isclose(trk.undetected_density[0], u_pred, rel_tol=1e-15)
    assert len(trk.poisson_w) == 0
    # empty scans: thinned to (1 − P_D) u_pred, predicted back to u_pred
    for k in range(n_empty):
        trk.step(float(k), np.zeros((0, 2)))
        assert math.isclose(trk.undetected_density[0], (1 - p_d) * u_pred, rel_tol=1e-12)
        again = p_s * trk.undetected_density[0] + b
        assert math.isclose(again, u_pred, rel_tol=1e-12)
    trk.step(float(n_empty), z)
    e = p_d * u_pred
    r_got, x_got, P_got = _new_bernoullis(trk, kind)
    assert len(r_got) == len(z)
    np.testing.assert_allclose(r_got, e / (lam + e), rtol=1e-12)
    np.testing.assert_array_equal(x_got[:, :2], z)
    np.testing.assert_array_equal(x_got[:, 2:], 0.0)
    want_P = np.diag([R, R, (max_speed / 2) ** 2, (max_speed / 2) ** 2])
    for Pj in P_got:
        _close(Pj, want_P)
    assert math.isclose(trk.undetected_density[0], (1 - p_d) * u_pred, rel_tol=1e-12)


@pytest.mark.parametrize("kind", [PMBTracker, PMBMTracker])
def test_prior_density_and_birth_region(kind):
    """An explicit prior density is used as is; a return outside birth_region starts nothing."""
    cfg = PMBMConfig(
        p_d=0.8,
        clutter_density=1e-4,
        birth_density=1e-6,
        prior_density=2e-5,
        birth_region=((-100.0, 100.0), (-100.0, 100.0)),
        r_prune=0.0,
        r_recycle=0.0,  # exact comparisons: no Bernoulli moves into the intensity
    )
    trk = kind(cfg)
    assert trk.undetected_density[0] == 2e-5
    trk.step(0.0, np.array([[0.0, 0.0], [500.0, 0.0]]))
    r, x, _ = _new_bernoullis(trk, kind)
    e = 0.8 * 2e-5
    assert len(r) == 1 and math.isclose(r[0], e / (1e-4 + e), rel_tol=1e-12)
    np.testing.assert_array_equal(x[0, :2], [0.0, 0.0])
