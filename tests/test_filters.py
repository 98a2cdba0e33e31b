"""Kalman, EKF and PDA/JPDA filter steps (jointtrack.filters)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from jointtrack.filters import (
    ekf_innovation,
    ekf_predict_measurement,
    ekf_update,
    innovation,
    log_likelihood,
    pda_ekf_update,
    pda_update,
    predict,
    predict_measurement,
    update,
)
from jointtrack.models import ConstantVelocity, LinearPosition, RangeBearing, wrap_angle

seeds = st.integers(0, 2**32 - 1)


def _spd(rng, d, scale=1.0):
    A = rng.standard_normal((d, d))
    return scale * (A @ A.T + 0.5 * np.eye(d))


def _problem(rng, n, m, N=None):
    """Random SPD prediction and linear model; batched if N is given."""
    if N is None:
        x, P = rng.standard_normal(n), _spd(rng, n)
    else:
        x = rng.standard_normal((N, n))
        P = np.array([_spd(rng, n) for _ in range(N)])
    H = rng.standard_normal((m, n))
    R = _spd(rng, m, 0.5)
    return x, P, H, R


def _kf_reference(x, P, z, H, R):
    """Textbook update with an explicit inverse (test reference only)."""
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    return x + K @ (z - H @ x), P - K @ S @ K.T


def _assert_sym_psd(P, tol=1e-12):
    assert np.array_equal(P, np.swapaxes(P, -1, -2))
    ev = np.linalg.eigvalsh(P)
    assert np.all(ev >= -tol * np.abs(P).max())


# ----------------------------------------------------------------------------- Kalman filter


def test_scalar_update_closed_form():
    """1-D: K = P/(P+R), x⁺ = x + K(z − x), P⁺ = P R/(P+R)."""
    for P, R, x, z in [(2.0, 3.0, 1.0, 4.0), (1e-3, 10.0, -2.0, 5.0), (7.0, 0.25, 0.0, -1.0)]:
        xu, Pu = update([x], [[P]], [z], [[1.0]], [[R]])
        K = P / (P + R)
        np.testing.assert_allclose(xu, [x + K * (z - x)], rtol=1e-15)
        np.testing.assert_allclose(Pu, [[P * R / (P + R)]], rtol=1e-14)


def test_random_walk_steady_state():
    """x_{k+1} = x_k + w (var q), z = x + v (var r): the Riccati recursion converges to
    P⁻ = (q + √(q² + 4qr))/2 and P⁺ = P⁻ r/(P⁻ + r)."""
    q, r = 0.3, 2.0
    x, P = np.zeros(1), np.array([[50.0]])
    rng = np.random.default_rng(0)
    for _ in range(200):
        x, P = predict(x, P, [[1.0]], [[q]])
        Pminus = P[0, 0]
        x, P = update(x, P, rng.standard_normal(1), [[1.0]], [[r]])
    expected = 0.5 * (q + np.sqrt(q * q + 4 * q * r))
    np.testing.assert_allclose(Pminus, expected, rtol=1e-12)
    np.testing.assert_allclose(P[0, 0], expected * r / (expected + r), rtol=1e-12)


def test_predict_formula_and_batching():
    rng = np.random.default_rng(3)
    model = ConstantVelocity(2, 0.4)
    N = 5
    x = rng.standard_normal((N, 4))
    P = np.array([_spd(rng, 4) for _ in range(N)])
    F, Q = model.transition(0.7), model.noise(0.7)
    xp, Pp = predict(x, P, F, Q)
    for i in range(N):
        xi, Pi = predict(x[i], P[i], F, Q)
        np.testing.assert_allclose(xp[i], F @ x[i], rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose(Pp[i], F @ P[i] @ F.T + Q, rtol=1e-13)
        np.testing.assert_allclose(xi, xp[i], rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose(Pi, Pp[i], rtol=1e-14)
    # per-track F, Q (e.g. per-track dt)
    dts = rng.uniform(0.1, 2.0, N)
    xp2, Pp2 = predict(x, P, model.transition(dts), model.noise(dts))
    for i in range(N):
        xi, Pi = predict(x[i], P[i], model.transition(dts[i]), model.noise(dts[i]))
        np.testing.assert_allclose(xp2[i], xi, rtol=1e-14)
        np.testing.assert_allclose(Pp2[i], Pi, rtol=1e-14)
    _assert_sym_psd(Pp2)


@settings(max_examples=60, deadline=None)
@given(seed=seeds, n=st.integers(1, 6), m=st.integers(1, 3))
def test_update_information_form(seed, n, m):
    """P⁺⁻¹ = P⁻¹ + Hᵀ R⁻¹ H and x⁺ = P⁺ (P⁻¹ x + Hᵀ R⁻¹ z) on random SPD problems."""
    rng = np.random.default_rng(seed)
    x, P, H, R = _problem(rng, n, m)
    z = rng.standard_normal(m)
    xu, Pu = update(x, P, z, H, R)
    Pi, Ri = np.linalg.inv(P), np.linalg.inv(R)
    info = Pi + H.T @ Ri @ H
    np.testing.assert_allclose(np.linalg.inv(Pu), info, rtol=1e-8, atol=1e-8 * np.abs(info).max())
    np.testing.assert_allclose(
        xu, np.linalg.solve(info, Pi @ x + H.T @ Ri @ z), rtol=1e-8, atol=1e-9
    )
    xr, Pr = _kf_reference(x, P, z, H, R)
    np.testing.assert_allclose(xu, xr, rtol=1e-9, atol=1e-10)
    _assert_sym_psd(Pu)


def test_update_batched_matches_single_and_per_track_models():
    rng = np.random.default_rng(7)
    N, n, m = 6, 4, 2
    x, P, H, R = _problem(rng, n, m, N)
    z = rng.standard_normal((N, m))
    xu, Pu = update(x, P, z, H, R)
    Hs = rng.standard_normal((N, m, n))
    Rs = np.array([_spd(rng, m) for _ in range(N)])
    xu2, Pu2 = update(x, P, z, Hs, Rs)
    for i in range(N):
        xi, Pi = update(x[i], P[i], z[i], H, R)
        np.testing.assert_allclose(xu[i], xi, rtol=1e-13, atol=1e-14)
        np.testing.assert_allclose(Pu[i], Pi, rtol=1e-13, atol=1e-14)
        xr, Pr = _kf_reference(x[i], P[i], z[i], Hs[i], Rs[i])
        np.testing.assert_allclose(xu2[i], xr, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(Pu2[i], Pr, rtol=1e-9, atol=1e-12)


def test_innovation_and_measurement_prediction():
    rng = np.random.default_rng(11)
    x, P, H, R = _problem(rng, 4, 2, N=3)
    z = rng.standard_normal((3, 2))
    nu, S = innovation(x, P, z, H, R)
    zhat, S2 = predict_measurement(x, P, H, R)
    for i in range(3):
        np.testing.assert_allclose(nu[i], z[i] - H @ x[i], rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose(S[i], H @ P[i] @ H.T + R, rtol=1e-14)
    np.testing.assert_allclose(zhat, z - nu, rtol=1e-14, atol=1e-15)
    np.testing.assert_array_equal(S, S2)
    nu1, S1 = innovation(x[0], P[0], z[0], H, R)
    assert nu1.shape == (2,) and S1.shape == (2, 2)


def test_joseph_form_keeps_symmetric_psd_where_naive_form_fails():
    """Ill-conditioned P (eigenvalues 1e-6 … 1e8) and accurate sensors (R ~ 1e-8):
    the textbook P⁺ = (I − K H) P is visibly asymmetric and indefinite, the Joseph
    form returned by ``update`` is symmetric PSD."""
    rng = np.random.default_rng(2024)
    n = 4
    worst_asym, worst_eig = 0.0, 0.0
    for _ in range(50):
        U, _ = np.linalg.qr(rng.standard_normal((n, n)))
        P = U @ np.diag(10 ** rng.uniform(-6, 8, n)) @ U.T
        P = 0.5 * (P + P.T)
        H = rng.standard_normal((2, n))
        R = np.diag(10 ** rng.uniform(-8, -4, 2))
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        naive = (np.eye(n) - K @ H) @ P
        scale = np.abs(naive).max()
        worst_asym = max(worst_asym, np.abs(naive - naive.T).max() / scale)
        worst_eig = min(worst_eig, np.linalg.eigvalsh(0.5 * (naive + naive.T)).min() / scale)
        _, Pj = update(np.zeros(n), P, np.zeros(2), H, R)
        _assert_sym_psd(Pj, tol=1e-12)
    assert worst_asym > 1e-3  # the naive form loses symmetry …
    assert worst_eig < -1e-3  # … and definiteness


def test_log_likelihood_vs_scipy():
    rng = np.random.default_rng(5)
    for m in (1, 2, 3):
        S = np.array([_spd(rng, m) for _ in range(4)])
        nu = rng.standard_normal((4, m)) * 2
        ll = log_likelihood(nu, S)
        ref = [stats.multivariate_normal(np.zeros(m), S[i]).logpdf(nu[i]) for i in range(4)]
        np.testing.assert_allclose(ll, ref, rtol=1e-12)
        assert isinstance(log_likelihood(nu[0], S[0]), float)
        np.testing.assert_allclose(log_likelihood(nu[0], S[0]), ref[0], rtol=1e-12)
    # track × measurement table by broadcasting
    N, M, m = 3, 5, 2
    S = np.array([_spd(rng, m) for _ in range(N)])
    nu = rng.standard_normal((N, M, m))
    table = log_likelihood(nu, S[:, None])
    assert table.shape == (N, M)
    for i in range(N):
        ref = stats.multivariate_normal(np.zeros(m), S[i]).logpdf(nu[i])
        np.testing.assert_allclose(table[i], ref, rtol=1e-12)


def test_log_likelihood_extreme_scales_stay_finite():
    """|S| = 1e-400 underflows a determinant; the Cholesky form does not."""
    S = np.diag([1e-200, 1e-200])
    nu = np.array([1e-100, -2e-100])
    expected = sum(stats.norm(0, 1e-100).logpdf(v) for v in nu)
    np.testing.assert_allclose(log_likelihood(nu, S), expected, rtol=1e-13)
    S = np.array([[1e200, 0.0], [0.0, 1e200]])
    np.testing.assert_allclose(
        log_likelihood([1e100, 0.0], S), 2 * stats.norm(0, 1e100).logpdf(0) - 0.5, rtol=1e-13
    )


# ----------------------------------------------------------------------------- EKF


def test_ekf_with_linear_model_equals_kf():
    rng = np.random.default_rng(8)
    lp = LinearPosition(2, [[1.0, 0.3], [0.3, 2.0]])
    x, P, _, _ = _problem(rng, 4, 2, N=4)
    z = rng.standard_normal((4, 2))
    for a, b in zip(ekf_update(x, P, z, lp), update(x, P, z, lp.H, lp.R), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-15, atol=1e-15)
    for a, b in zip(ekf_innovation(x, P, z, lp), innovation(x, P, z, lp.H, lp.R), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-15, atol=1e-15)
    for a, b in zip(
        ekf_predict_measurement(x, P, lp), predict_measurement(x, P, lp.H, lp.R), strict=True
    ):
        np.testing.assert_allclose(a, b, rtol=1e-15, atol=1e-15)


def _fd_jacobian(model, x, h=1e-6):
    J = np.zeros((2, x.size))
    for k in range(x.size):
        e = np.zeros(x.size)
        e[k] = h
        J[:, k] = model.residual(model.h(x + e), model.h(x - e)) / (2 * h)
    return J


def test_ekf_range_bearing_vs_finite_difference_reference():
    rng = np.random.default_rng(12)
    rb = RangeBearing([0.5**2, 0.01**2], sensor_position=(-3.0, 4.0))
    N = 5
    x = rng.uniform(-50, 50, (N, 4))
    P = np.array([_spd(rng, 4, 2.0) for _ in range(N)])
    z = rb.h(x) + rng.standard_normal((N, 2)) * [0.5, 0.01]
    xu, Pu = ekf_update(x, P, z, rb)
    for i in range(N):
        J = _fd_jacobian(rb, x[i])
        nu = rb.residual(z[i], rb.h(x[i]))
        xr, Pr = _kf_reference(x[i], P[i], J @ x[i] + nu, J, rb.R)
        np.testing.assert_allclose(xu[i], xr, rtol=1e-6, atol=1e-7)
        np.testing.assert_allclose(Pu[i], Pr, rtol=1e-6, atol=1e-7)
    _assert_sym_psd(Pu)


def test_ekf_bearing_wraps_across_pi():
    """Target just above the −x axis (θ ≈ π − 0.01), measurement just below it
    (θ ≈ −π + 0.01): the innovation is 0.02 rad, not −2π + 0.02."""
    rb = RangeBearing([0.1, 1e-4])
    x = np.array([-100.0 * np.cos(0.01), 100.0 * np.sin(0.01), 0.0, 0.0])
    P = np.diag([4.0, 4.0, 1.0, 1.0])
    z = np.array([100.0, -np.pi + 0.01])
    nu, S = ekf_innovation(x, P, z, rb)
    np.testing.assert_allclose(nu, [0.0, 0.02], atol=1e-12)
    xu, Pu = ekf_update(x, P, z, rb)
    # same update as with the equivalent measurement written without the cut
    z_equiv = np.array([100.0, np.pi + 0.01])
    H = rb.jacobian(x)
    xr, Pr = _kf_reference(x, P, z_equiv - rb.h(x) + H @ x, H, rb.R)
    np.testing.assert_allclose(xu, xr, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(Pu, Pr, rtol=1e-10, atol=1e-12)
    assert xu[1] < x[1]  # pulled across the axis, by a small amount
    assert np.linalg.norm(xu[:2] - x[:2]) < 5.0
    assert -np.pi < wrap_angle(rb.h(xu)[1] - z[1]) < 0.02


# ----------------------------------------------------------------------------- PDA / JPDA


def _mixture_moments(x, P, z, H, R, beta, residual=None, zhat=None):
    """Brute force: moments of β_0 N(x, P) + Σ_j β_j N(KF-update with z_j)."""
    zhat = H @ x if zhat is None else zhat
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    Pc = P - K @ S @ K.T
    means, covs = [x], [P]
    for zj in z:
        nu = zj - zhat if residual is None else residual(zj, zhat)
        means.append(x + K @ nu)
        covs.append(Pc)
    means, covs = np.array(means), np.array(covs)
    mean = np.einsum("j,jd->d", beta, means)
    dev = means - mean
    cov = np.einsum("j,jab->ab", beta, covs) + np.einsum("j,ja,jb->ab", beta, dev, dev)
    return mean, cov


def _random_beta(rng, M, p_zero=0.5):
    b = rng.random(M + 1) * (rng.random(M + 1) > p_zero)
    b[0] += 1e-3 * rng.random()
    return b / b.sum()


@settings(max_examples=60, deadline=None)
@given(seed=seeds, n=st.integers(1, 6), m=st.integers(1, 3), M=st.integers(0, 6))
def test_pda_equals_mixture_moment_match(seed, n, m, M):
    rng = np.random.default_rng(seed)
    x, P, H, R = _problem(rng, n, m)
    z = H @ x + 2 * rng.standard_normal((M, m))
    beta = _random_beta(rng, M)
    xu, Pu = pda_update(x, P, z, H, R, beta)
    mean, cov = _mixture_moments(x, P, z, H, R, beta)
    np.testing.assert_allclose(xu, mean, rtol=0, atol=1e-10)
    np.testing.assert_allclose(Pu, cov, rtol=0, atol=1e-10)
    _assert_sym_psd(Pu)


@settings(max_examples=30, deadline=None)
@given(seed=seeds, N=st.integers(1, 6), M=st.integers(0, 8))
def test_jpda_batched_ragged_equals_per_track(seed, N, M):
    """Full N × (M+1) beta matrix, each track using only its β > 0 measurements."""
    rng = np.random.default_rng(seed)
    n, m = 4, 2
    x, P, H, R = _problem(rng, n, m, N)
    z = 3 * rng.standard_normal((M, m))
    beta = np.array([_random_beta(rng, M, p_zero=0.6) for _ in range(N)])
    xu, Pu = pda_update(x, P, z, H, R, beta)
    for i in range(N):
        gated = np.nonzero(beta[i, 1:] > 0)[0]
        sub = np.concatenate([[beta[i, 0]], beta[i, 1 + gated]])
        xi, Pi = pda_update(x[i], P[i], z[gated], H, R, sub)
        np.testing.assert_allclose(xu[i], xi, rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(Pu[i], Pi, rtol=1e-13, atol=1e-13)
        mean, cov = _mixture_moments(x[i], P[i], z, H, R, beta[i])
        np.testing.assert_allclose(xu[i], mean, rtol=0, atol=1e-10)
        np.testing.assert_allclose(Pu[i], cov, rtol=0, atol=1e-10)


def test_pda_beta0_one_returns_prior():
    rng = np.random.default_rng(1)
    x, P, H, R = _problem(rng, 4, 2, N=3)
    z = rng.standard_normal((5, 2))
    beta = np.zeros((3, 6))
    beta[:, 0] = 1.0
    xu, Pu = pda_update(x, P, z, H, R, beta)
    np.testing.assert_array_equal(xu, x)
    np.testing.assert_array_equal(Pu, P)
    # no measurements at all
    xu, Pu = pda_update(x, P, np.empty((0, 2)), H, R, np.ones((3, 1)))
    np.testing.assert_array_equal(xu, x)
    np.testing.assert_array_equal(Pu, P)
    xu, Pu = pda_update(x[0], P[0], [], H, R, [1.0])
    np.testing.assert_array_equal(xu, x[0])


def test_pda_certain_association_is_kalman_update():
    rng = np.random.default_rng(2)
    N, M = 4, 6
    x, P, H, R = _problem(rng, 4, 2, N=N)
    z = rng.standard_normal((M, 2))
    pick = np.array([3, 0, 5, 3])  # two tracks on the same measurement is fine for PDA
    beta = np.zeros((N, M + 1))
    beta[np.arange(N), 1 + pick] = 1.0
    xu, Pu = pda_update(x, P, z, H, R, beta)
    xk, Pk = update(x, P, z[pick], H, R)
    np.testing.assert_allclose(xu, xk, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(Pu, Pk, rtol=1e-14, atol=1e-14)


@settings(max_examples=30, deadline=None)
@given(seed=seeds, N=st.integers(1, 5), M=st.integers(0, 6))
def test_pda_ekf_range_bearing_moment_match(seed, N, M):
    """Per-track linearisation; bearings near ±π so residuals must wrap."""
    rng = np.random.default_rng(seed)
    rb = RangeBearing([0.3**2, 0.02**2], sensor_position=(1.0, 0.0))
    ang = np.pi + rng.normal(0.0, 0.05, N)
    rng_ = rng.uniform(20.0, 60.0, N)
    x = np.column_stack([1.0 + rng_ * np.cos(ang), rng_ * np.sin(ang), rng.standard_normal((N, 2))])
    P = np.array([_spd(rng, 4, 0.5) for _ in range(N)])
    zr = rng.uniform(20.0, 60.0, M)
    zb = wrap_angle(np.pi + rng.normal(0.0, 0.05, M))
    z = np.column_stack([zr, zb]) if M else np.empty((0, 2))
    beta = np.array([_random_beta(rng, M) for _ in range(N)])
    xu, Pu = pda_ekf_update(x, P, z, rb, beta)
    for i in range(N):
        H = rb.jacobian(x[i])
        mean, cov = _mixture_moments(
            x[i], P[i], z, H, rb.R, beta[i], residual=rb.residual, zhat=rb.h(x[i])
        )
        np.testing.assert_allclose(xu[i], mean, rtol=0, atol=1e-10 * max(1, np.abs(mean).max()))
        np.testing.assert_allclose(Pu[i], cov, rtol=0, atol=1e-10 * max(1, np.abs(cov).max()))
        xi, Pi = pda_ekf_update(x[i], P[i], z, rb, beta[i])
        np.testing.assert_allclose(xi, xu[i], rtol=1e-13, atol=1e-12)
    _assert_sym_psd(Pu, tol=1e-10)


def test_pda_ekf_with_linear_model_equals_pda():
    rng = np.random.default_rng(9)
    lp = LinearPosition(2, 0.7)
    x, P, _, _ = _problem(rng, 4, 2, N=3)
    z = rng.standard_normal((4, 2))
    beta = np.array([_random_beta(rng, 4) for _ in range(3)])
    for a, b in zip(
        pda_ekf_update(x, P, z, lp, beta), pda_update(x, P, z, lp.H, lp.R, beta), strict=True
    ):
        np.testing.assert_allclose(a, b, rtol=1e-15, atol=1e-15)


# ----------------------------------------------------------------------------- bad input


def _batch(N=3, n=4, m=2, seed=0):
    rng = np.random.default_rng(seed)
    x, P, H, R = _problem(rng, n, m, N)
    return x, P, H, R, rng.standard_normal((N, m))


def test_bad_shapes():
    x, P, H, R, z = _batch()
    F = np.eye(4)
    with pytest.raises(ValueError, match="x must be"):
        predict(np.zeros((2, 3, 4)), P, F, F)
    with pytest.raises(ValueError, match="P must have shape"):
        predict(x, P[:2], F, F)
    with pytest.raises(ValueError, match="F must have shape"):
        predict(x, P, np.eye(3), F)
    with pytest.raises(ValueError, match="Q must have shape"):
        predict(x, P, F, np.eye(4)[None].repeat(2, 0))
    with pytest.raises(ValueError, match="H must have shape"):
        update(x, P, z, np.eye(2, 3), R)
    with pytest.raises(ValueError, match="R must have shape"):
        update(x, P, z, H, np.eye(3))
    with pytest.raises(ValueError, match="z must have shape"):
        update(x, P, z[:2], H, R)
    with pytest.raises(ValueError, match="z must have shape"):
        pda_update(x, P, np.zeros((4, 3)), H, R, np.ones((3, 5)) / 5)
    with pytest.raises(ValueError, match="beta must have shape"):
        pda_update(x, P, np.zeros((4, 2)), H, R, np.ones((3, 4)) / 4)
    with pytest.raises(ValueError, match="nu must be"):
        log_likelihood(np.zeros(3), np.eye(2))
    with pytest.raises(ValueError, match="do not broadcast"):
        log_likelihood(np.zeros((3, 2)), np.array([np.eye(2)] * 2))


def test_non_finite_inputs_name_the_track():
    x, P, H, R, z = _batch()
    F = np.eye(4)
    xb = x.copy()
    xb[2, 1] = np.nan
    with pytest.raises(ValueError, match=r"x\[2\] \(track 2\) has non-finite"):
        predict(xb, P, F, F)
    Pb = P.copy()
    Pb[1, 0, 0] = np.inf
    with pytest.raises(ValueError, match=r"P\[1\] \(track 1\) has non-finite"):
        update(x, Pb, z, H, R)
    zb = z.copy()
    zb[1, 0] = np.nan
    with pytest.raises(ValueError, match=r"z\[1\] \(track 1\) has non-finite"):
        update(x, P, zb, H, R)
    with pytest.raises(ValueError, match=r"measurement z\[0\] is not finite"):
        pda_update(x, P, [[np.nan, 0.0]], H, R, np.full((3, 2), 0.5))
    with pytest.raises(ValueError, match="F has non-finite"):
        predict(x, P, np.full((4, 4), np.nan), F)
    with pytest.raises(ValueError, match=r"nu\[1\] has non-finite"):
        log_likelihood([[0.0, 0.0], [np.nan, 1.0]], np.eye(2))


def test_bad_covariances_name_the_problem_and_track():
    x, P, H, R, z = _batch()
    F = np.eye(4)
    Pa = P.copy()
    Pa[1, 0, 1] += 1e-3
    with pytest.raises(ValueError, match=r"P\[1\] \(track 1\) is not symmetric"):
        predict(x, Pa, F, F)
    Pn = P.copy()
    Pn[2] = np.diag([1.0, 1.0, 1.0, -1e-3])
    with pytest.raises(ValueError, match=r"P\[2\] \(track 2\) is not positive semi-definite"):
        update(x, Pn, z, H, R)
    Pn[2] = [[1, 2, 0, 0], [2, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]]
    with pytest.raises(ValueError, match=r"P\[2\] \(track 2\) is not positive semi-definite"):
        predict(x, Pn, F, F)
    with pytest.raises(ValueError, match="Q is not positive semi-definite"):
        predict(x, P, F, -np.eye(4))
    with pytest.raises(ValueError, match="R is not positive definite"):
        update(x, P, z, H, np.diag([1.0, 0.0]))
    Rs = np.array([np.eye(2), np.eye(2), [[1.0, 2.0], [2.0, 1.0]]])
    with pytest.raises(ValueError, match=r"R\[2\] \(track 2\) is not positive definite"):
        update(x, P, z, H, Rs)
    # S = H P Hᵀ + R numerically singular (1e20 against 1)
    Ps = P.copy()
    Ps[1] = np.diag([1e20, 0.0, 1.0, 1.0])
    with pytest.raises(
        ValueError, match=r"innovation covariance S\[1\] \(track 1\) is numerically singular"
    ):
        update(x, Ps, z, np.eye(2, 4), np.eye(2))
    with pytest.raises(ValueError, match=r"S\[1\] \(track 1\) is not positive definite"):
        log_likelihood(np.zeros((2, 2)), np.array([np.eye(2), -np.eye(2)]))
    with pytest.raises(ValueError, match="S is not symmetric"):
        log_likelihood(np.zeros(2), [[1.0, 0.5], [0.0, 1.0]])
    # single track: no track index in the message
    with pytest.raises(ValueError, match=r"^P is not symmetric"):
        update(x[0], Pa[1], z[0], H, R)


def test_bad_beta():
    x, P, H, R, _ = _batch()
    z = np.zeros((2, 2))
    beta = np.full((3, 3), 1 / 3)
    bad = beta.copy()
    bad[1, 2] = 0.5
    with pytest.raises(ValueError, match=r"beta\[1\] \(track 1\) sums to"):
        pda_update(x, P, z, H, R, bad)
    bad = beta.copy()
    bad[2] = [1.2, -0.2, 0.0]
    with pytest.raises(ValueError, match=r"beta\[2\] \(track 2\) has negative"):
        pda_update(x, P, z, H, R, bad)
    bad = beta.copy()
    bad[0, 0] = np.nan
    with pytest.raises(ValueError, match=r"beta\[0\] \(track 0\) has non-finite"):
        pda_update(x, P, z, H, R, bad)
    with pytest.raises(ValueError, match="^beta sums to"):
        pda_update(x[0], P[0], z, H, R, [0.5, 0.1, 0.1])
    # rows that sum to 1 within rounding are accepted
    pda_update(x, P, z, H, R, beta * (1 + 1e-12))


def test_bad_ekf_model():
    x, P, _, _, z = _batch()
    with pytest.raises(ValueError, match="lacks 'h'"):
        ekf_update(x, P, z, object())
    with pytest.raises(ValueError, match="state_dim 6"):
        ekf_update(x, P, z, LinearPosition(2, 1.0, state_dim=6))
    rb = RangeBearing([1.0, 1e-4], sensor_position=(0.0, 0.0))
    x0 = x.copy()
    x0[1, :2] = 0.0
    with pytest.raises(ValueError, match=r"track 1.*sensor position"):
        pda_ekf_update(x0, P, z, rb, np.full((3, 4), 0.25))


def test_empty_batch():
    """A scan with no tracks: every function returns empty arrays."""
    x, P = np.zeros((0, 4)), np.zeros((0, 4, 4))
    lp = LinearPosition(2, 1.0)
    cv = ConstantVelocity()
    assert [a.shape for a in predict(x, P, cv.transition(1.0), cv.noise(1.0))] == [
        (0, 4),
        (0, 4, 4),
    ]
    assert update(x, P, np.zeros((0, 2)), lp.H, lp.R)[1].shape == (0, 4, 4)
    assert pda_update(x, P, np.ones((3, 2)), lp.H, lp.R, np.zeros((0, 4)))[0].shape == (0, 4)
    assert log_likelihood(np.zeros((0, 2)), np.zeros((0, 2, 2))).shape == (0,)


# ----------------------------------------------------------------------------- long gaps


def _assert_sym_pd(P):
    """Symmetric (to 1e-12 relative) and positive definite: Cholesky succeeds."""
    P = np.asarray(P)
    assert np.isfinite(P).all()
    asym = np.abs(P - np.swapaxes(P, -1, -2)).max()
    assert asym <= 1e-12 * np.abs(P).max()
    np.linalg.cholesky(P)  # raises LinAlgError if not positive definite


@st.composite
def _spd_matrices(draw, n):
    """Random SPD matrix from drawn entries: D (A Aᵀ + δ I) D with mixed unit scales."""
    a = draw(st.lists(st.floats(-3.0, 3.0), min_size=n * n, max_size=n * n))
    A = np.array(a).reshape(n, n)
    delta = 10.0 ** draw(st.floats(-3.0, 0.0))
    d = 10.0 ** np.array(draw(st.lists(st.floats(-2.0, 3.0), min_size=n, max_size=n)))
    C = A @ A.T + delta * np.eye(n)
    return d[:, None] * C * d[None, :]


@settings(max_examples=300, deadline=None)
@given(
    data=st.data(),
    accel=st.booleans(),
    dim=st.sampled_from([2, 3]),
    log_dt=st.floats(-6.0, 12.0),
    q=st.one_of(st.just(0.0), st.floats(-3.0, 2.0).map(lambda e: 10.0**e)),
    log_r=st.floats(-2.0, 4.0),
)
def test_long_gap_predict_update_stays_positive_definite(data, accel, dim, log_dt, q, log_r):
    """Any dt from 1e-6 to 1e12, CV and CA, 2-D and 3-D, random SPD P: the prediction,
    the Kalman update and the PDA update are symmetric positive definite."""
    from jointtrack.models import ConstantAcceleration

    model = (ConstantAcceleration if accel else ConstantVelocity)(dim, q)
    n = model.state_dim
    P = data.draw(_spd_matrices(n), label="P")
    dt = 10.0**log_dt
    x = np.zeros(n)
    xp, Pp = predict(x, P, model.transition(dt), model.noise(dt))
    _assert_sym_pd(Pp)
    sensor = LinearPosition(dim, 10.0**log_r, state_dim=n)
    z = sensor.H @ xp + 1.0
    _, Pu = update(xp, Pp, z, sensor.H, sensor.R)
    _assert_sym_pd(Pu)
    zs = np.array([z, z - 3.0, z + 5.0])
    _, Pa = pda_update(xp, Pp, zs, sensor.H, sensor.R, [0.2, 0.5, 0.2, 0.1])
    _assert_sym_pd(Pa)


def test_long_gap_tracker_sequence_regression():
    """NCV 2-D track, P0 = diag(100, 100, 25, 25), a gap of 1e8 s, one position update
    (R = 100 I): the prediction and both updates factorise by Cholesky — also without
    process noise, where F P Fᵀ is singular to working precision."""
    P0 = np.diag([100.0, 100.0, 25.0, 25.0])
    x0 = np.array([0.0, 0.0, 10.0, -5.0])
    H, R = np.eye(2, 4), 100.0 * np.eye(2)
    for q in (0.0, 0.05, 1.0):
        for dt in (1e8, 1e10, 1e12):
            model = ConstantVelocity(2, q)
            xp, Pp = predict(x0, P0, model.transition(dt), model.noise(dt))
            _assert_sym_pd(Pp)
            z = xp[:2] + 7.0
            xu, Pu = update(xp, Pp, z, H, R)
            _assert_sym_pd(Pu)
            assert np.all(np.diag(Pu)[:2] <= np.diag(Pp)[:2])
            # the position variance is P R/(P + R) ≈ R: no cancellation in I − K H
            ppos = Pp[0, 0] * 100.0 / (Pp[0, 0] + 100.0)
            np.testing.assert_allclose(np.diag(Pu)[:2], [ppos, ppos], rtol=1e-9)
            _, Pa = pda_update(xp, Pp, np.array([z, z + 20.0]), H, R, [0.1, 0.6, 0.3])
            _assert_sym_pd(Pa)
            # the next scan (dt = 1 s) keeps it positive definite too
            _, P2 = predict(xu, Pu, model.transition(1.0), model.noise(1.0))
            _assert_sym_pd(update(xu, P2, z, H, R)[1])


def test_long_gap_batched_tracks_positive_definite():
    """Batched predict + PDA update with a mix of scan intervals 1 s … 1e12 s and q = 0."""
    rng = np.random.default_rng(5)
    N, M = 40, 6
    model = ConstantVelocity(2, 0.0)
    x = rng.standard_normal((N, 4))
    P = np.array([_spd(rng, 4, 10.0) for _ in range(N)])
    dts = 10.0 ** rng.uniform(0, 12, N)
    xp, Pp = predict(x, P, model.transition(dts), model.noise(dts))
    _assert_sym_pd(Pp)
    H, R = np.eye(2, 4), 100.0 * np.eye(2)
    z = 30.0 * rng.standard_normal((M, 2))
    beta = np.array([_random_beta(rng, M) for _ in range(N)])
    _, Pu = pda_update(xp, Pp, z, H, R, beta)
    _assert_sym_pd(Pu)


def test_predict_overflow_names_the_time_step():
    model = ConstantVelocity(2, 1.0)
    with pytest.raises(ValueError, match=r"time step dt = 1e\+300 is too large.*largest usable dt"):
        model.noise(1e300)
    F = model.transition(1e200)  # F is finite, but F P Fᵀ is not
    with pytest.raises(ValueError, match=r"predicted covariance overflows.*dt"):
        predict(np.zeros(4), np.eye(4), F, np.zeros((4, 4)))


@pytest.mark.parametrize("accel", [False, True])
@pytest.mark.parametrize("dt", [1e4, 1e8, 1e12])
def test_long_gap_update_is_accurate(accel, dt):
    """With process noise the posterior after a long gap is well conditioned and is
    computed to ~1e-12 in correlation units (reference: the same update in 100-digit
    arithmetic)."""
    mp = pytest.importorskip("mpmath")
    from jointtrack.models import ConstantAcceleration

    model = (ConstantAcceleration if accel else ConstantVelocity)(2, 1.0)
    n = model.state_dim
    P0 = np.diag(np.r_[[100.0, 100.0], np.full(n - 2, 25.0)])
    F, Q = model.transition(dt), model.noise(dt)
    H, R = np.eye(2, n), 100.0 * np.eye(2)
    _, Pp = predict(np.zeros(n), P0, F, Q)
    _, Pu = update(np.zeros(n), Pp, np.array([1.0, 2.0]), H, R)
    with mp.workdps(100):
        Fm, P0m, Qm, Hm, Rm = (mp.matrix(a.tolist()) for a in (F, P0, Q, H, R))
        Pm = Fm * P0m * Fm.T + Qm
        Km = Pm * Hm.T * (Hm * Pm * Hm.T + Rm) ** -1
        Em = Pm - Km * Hm * Pm
        E = np.array([[float(Em[i, j]) for j in range(n)] for i in range(n)])
    s = np.sqrt(np.diag(E))
    np.testing.assert_allclose(Pu / np.outer(s, s), E / np.outer(s, s), rtol=0, atol=1e-12)


@settings(max_examples=150, deadline=None)
@given(
    d=st.integers(1, 4),
    eigen=st.lists(
        st.lists(
            st.one_of(st.just(0.0), st.floats(0.01, 10.0), st.floats(-10.0, -1e-3)),
            min_size=4,
            max_size=4,
        ),
        min_size=1,
        max_size=6,
    ),
    mixing=st.lists(st.floats(-1.0, 1.0), min_size=16, max_size=16),
    log_scales=st.lists(st.floats(-6.0, 6.0), min_size=4, max_size=4),
)
def test_psd_check_names_the_first_matrix_with_a_negative_eigenvalue(d, eigen, mixing, log_scales):
    """The batched PSD check (compiled) against the eigenvalues it certifies.

    P_k = D V diag(w_k) Vᵀ D with drawn eigenvalues w_k (positive, zero or clearly
    negative), a drawn rotation V and drawn axis scales D: the check must name the
    first k with a negative variance, else the first with a negative w_k, and accept
    batches with none, in any units.
    """
    w = np.array([row[:d] for row in eigen])
    V, _ = np.linalg.qr(np.array(mixing).reshape(4, 4)[:d, :d] + 3.0 * np.eye(d))
    D = np.diag(10.0 ** np.array(log_scales[:d]))
    P = np.einsum("ij,kj,jl->kil", D @ V, w, V.T @ D)
    P = 0.5 * (P + np.swapaxes(P, 1, 2))
    x, H, R = np.zeros((len(w), d)), np.eye(d), np.eye(d)
    # a negative variance is named first (the cheap test), then a negative eigenvalue
    negative_variance = np.flatnonzero((np.diagonal(P, axis1=1, axis2=2) < 0).any(axis=1))
    bad = negative_variance if negative_variance.size else np.flatnonzero((w < 0).any(axis=1))
    if bad.size:
        with pytest.raises(ValueError, match=rf"P\[{bad[0]}\] \(track {bad[0]}\) is not positive"):
            predict_measurement(x, P, H, R)
    else:
        z_pred, S = predict_measurement(x, P, H, R)
        np.testing.assert_array_equal(S, 0.5 * ((P + R) + np.swapaxes(P + R, 1, 2)))
