"""Motion and measurement models (jointtrack.models)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate, linalg

from jointtrack.models import (
    ConstantAcceleration,
    ConstantVelocity,
    LinearPosition,
    RangeBearing,
    ca_noise,
    ca_transition,
    cv_noise,
    cv_transition,
    wrap_angle,
)

# ----------------------------------------------------------------------------- motion


def _continuous_system(order: int, dim: int):
    """A, G of the continuous kinematic model in the blocked layout [pos, vel(, acc)]."""
    k = order + 1
    A1 = np.diag(np.ones(k - 1), 1)  # each derivative drives the one below it
    G1 = np.zeros((k, 1))
    G1[-1, 0] = 1.0  # white noise on the highest derivative
    return np.kron(A1, np.eye(dim)), np.kron(G1, np.eye(dim))


def _integral_Q(A, G, q, dt):
    """q ∫₀^dt e^{Aτ} G Gᵀ e^{Aᵀτ} dτ by adaptive quadrature."""

    def f(t):
        E = linalg.expm(A * t)
        return E @ G @ G.T @ E.T

    val, err = integrate.quad_vec(f, 0.0, dt, epsabs=1e-13, epsrel=1e-12)
    return q * val


@pytest.mark.parametrize("dim", [1, 2, 3])
@pytest.mark.parametrize("dt", [0.1, 1.0, 3.7])
def test_cv_matches_continuous_definition(dim, dt):
    q = 0.7
    A, G = _continuous_system(1, dim)
    np.testing.assert_allclose(cv_transition(dt, dim), linalg.expm(A * dt), rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(
        cv_noise(dt, q, dim), _integral_Q(A, G, q, dt), rtol=1e-9, atol=1e-13
    )


@pytest.mark.parametrize("dim", [1, 2, 3])
@pytest.mark.parametrize("dt", [0.1, 1.0, 3.7])
def test_ca_matches_continuous_definition(dim, dt):
    q = 0.3
    A, G = _continuous_system(2, dim)
    np.testing.assert_allclose(ca_transition(dt, dim), linalg.expm(A * dt), rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(
        ca_noise(dt, q, dim), _integral_Q(A, G, q, dt), rtol=1e-9, atol=1e-13
    )


@settings(max_examples=40, deadline=None)
@given(
    a=st.floats(1e-3, 10.0),
    b=st.floats(1e-3, 10.0),
    dim=st.integers(1, 3),
    accel=st.booleans(),
)
def test_semigroup_property(a, b, dim, accel):
    """Exact discretisation: F(a+b) = F(b)F(a), Q(a+b) = F(b)Q(a)F(b)ᵀ + Q(b)."""
    model = ConstantAcceleration(dim, 0.9) if accel else ConstantVelocity(dim, 0.9)
    Fa, Fb, Fab = model.transition(a), model.transition(b), model.transition(a + b)
    Qa, Qb, Qab = model.noise(a), model.noise(b), model.noise(a + b)
    np.testing.assert_allclose(Fb @ Fa, Fab, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(Fb @ Qa @ Fb.T + Qb, Qab, rtol=1e-9, atol=1e-12 * np.abs(Qab).max())
    assert np.array_equal(Qab, Qab.T)
    assert np.linalg.eigvalsh(Qab).min() >= -1e-12 * np.abs(Qab).max()


def test_layout_and_indices():
    cv = ConstantVelocity(dim=3, q=2.0)
    assert cv.state_dim == 6
    assert list(cv.position_indices) == [0, 1, 2]
    assert list(cv.velocity_indices) == [3, 4, 5]
    F = cv.transition(2.0)
    x = np.array([1.0, 2.0, 3.0, 0.5, -1.0, 2.0])
    np.testing.assert_allclose(F @ x, [2.0, 0.0, 7.0, 0.5, -1.0, 2.0])
    ca = ConstantAcceleration(dim=2)
    assert ca.state_dim == 6
    assert list(ca.acceleration_indices) == [4, 5]
    x = np.array([0.0, 0.0, 1.0, 2.0, 2.0, -2.0])
    np.testing.assert_allclose(ca.transition(1.0) @ x, [2.0, 1.0, 3.0, 0.0, 2.0, -2.0])
    # H of a position measurement picks exactly the position indices
    for model in (cv, ca, ConstantVelocity(2)):
        H = LinearPosition(model.dim, 1.0, state_dim=model.state_dim).H
        np.testing.assert_array_equal(np.nonzero(H)[1], model.position_indices)


def test_vector_dt_gives_stack():
    dts = np.array([0.5, 1.0, 2.0])
    F = cv_transition(dts, 2)
    Q = ca_noise(dts, 1.5, 3)
    assert F.shape == (3, 4, 4) and Q.shape == (3, 9, 9)
    for k, dt in enumerate(dts):
        np.testing.assert_array_equal(F[k], cv_transition(dt, 2))
        np.testing.assert_array_equal(Q[k], ca_noise(dt, 1.5, 3))


def test_zero_noise_allowed():
    assert not ConstantVelocity(2, 0.0).noise(1.0).any()


@pytest.mark.parametrize("dt", [0.0, -1.0, np.nan, np.inf, [1.0, 0.0], [[1.0]], "x"])
def test_bad_dt(dt):
    with pytest.raises(ValueError, match="dt"):
        ConstantVelocity().transition(dt)
    with pytest.raises(ValueError, match="dt"):
        ConstantAcceleration().noise(dt)


def test_bad_dt_names_track():
    with pytest.raises(ValueError, match=r"dt\[2\] \(track 2\)"):
        cv_noise([1.0, 2.0, -1.0], 1.0, 2)


@pytest.mark.parametrize("kw", [{"dim": 0}, {"dim": 4}, {"dim": 1.5}, {"q": -1.0}, {"q": np.nan}])
def test_bad_motion_parameters(kw):
    with pytest.raises(ValueError):
        ConstantVelocity(**kw)
    with pytest.raises(ValueError):
        ConstantAcceleration(**kw)


def test_models_are_frozen():
    m = ConstantVelocity()
    with pytest.raises(AttributeError):
        m.q = 3.0
    lp = LinearPosition(2, 1.0)
    with pytest.raises(ValueError):
        lp.R[0, 0] = 5.0  # read-only array


# ----------------------------------------------------------------------------- measurement


def test_linear_position():
    lp = LinearPosition(2, [1.0, 4.0], state_dim=6)
    np.testing.assert_array_equal(lp.H, np.eye(2, 6))
    np.testing.assert_array_equal(lp.R, np.diag([1.0, 4.0]))
    x = np.arange(12.0).reshape(2, 6)
    np.testing.assert_array_equal(lp.h(x), x[:, :2])
    assert lp.jacobian(x).shape == (2, 2, 6)
    assert lp == LinearPosition(2, np.diag([1.0, 4.0]), state_dim=6)
    assert lp != LinearPosition(2, 1.0, state_dim=6)
    assert LinearPosition(3, 2.0).state_dim == 6
    np.testing.assert_array_equal(LinearPosition(2, 2.0).R, 2.0 * np.eye(2))


@pytest.mark.parametrize(
    "R, msg",
    [
        ([[1.0, 0.5], [0.0, 1.0]], "not symmetric"),
        ([[1.0, 2.0], [2.0, 1.0]], "not positive definite"),
        ([[1.0, 0.0], [0.0, 0.0]], "positive definite"),
        ([[1.0, 1.0], [1.0, 1.0 + 1e-17]], "positive definite|singular"),
        ([[1.0, np.nan], [np.nan, 1.0]], "non-finite"),
        (np.eye(3), "shape"),
        ([1.0, 2.0, 3.0], "shape"),
        (-1.0, "positive definite"),
    ],
)
def test_bad_R(R, msg):
    with pytest.raises(ValueError, match=msg):
        LinearPosition(2, R)
    with pytest.raises(ValueError, match=msg):
        RangeBearing(R)


def test_bad_linear_position_args():
    with pytest.raises(ValueError, match="dim"):
        LinearPosition(0, 1.0)
    with pytest.raises(ValueError, match="state_dim"):
        LinearPosition(3, 1.0, state_dim=2)
    with pytest.raises(ValueError, match="last dimension 4"):
        LinearPosition(2, 1.0).h(np.zeros(6))


def test_range_bearing_values():
    rb = RangeBearing([1.0, 1e-4], sensor_position=(1.0, -1.0))
    x = np.array([[4.0, 3.0, 7.0, 7.0], [1.0, 1.0, 0.0, 0.0], [-1.0, -1.0, 0.0, 0.0]])
    z = rb.h(x)
    np.testing.assert_allclose(z[:, 0], [5.0, 2.0, 2.0])
    np.testing.assert_allclose(z[:, 1], [np.arctan2(4.0, 3.0), np.pi / 2, np.pi])
    np.testing.assert_allclose(rb.to_position(z), x[:, :2], atol=1e-14)
    assert rb == RangeBearing(np.diag([1.0, 1e-4]), [1.0, -1.0])


@settings(max_examples=60, deadline=None)
@given(
    px=st.floats(-1e3, 1e3),
    py=st.floats(-1e3, 1e3),
    sx=st.floats(-10, 10),
    sy=st.floats(-10, 10),
)
def test_range_bearing_jacobian_vs_finite_differences(px, py, sx, sy):
    rb = RangeBearing([1.0, 1e-4], sensor_position=(sx, sy), state_dim=4)
    x = np.array([px, py, 3.0, -2.0])
    r = np.hypot(px - sx, py - sy)
    if r < 1e-2:
        return
    J = rb.jacobian(x)
    np.testing.assert_array_equal(rb.H(x), J)
    h = 1e-6 * max(r, 1.0)
    Jfd = np.zeros((2, 4))
    for k in range(4):
        e = np.zeros(4)
        e[k] = h
        # central difference of the wrapped residual (bearing may cross ±π)
        Jfd[:, k] = rb.residual(rb.h(x + e), rb.h(x - e)) / (2 * h)
    # rounding of h(x ± e) (values up to r) divided by the step bounds the FD error
    atol = 1e-8 / max(r, 1.0) + 16 * np.finfo(float).eps * max(r, np.pi) / h
    np.testing.assert_allclose(J, Jfd, rtol=1e-6, atol=atol)


def test_range_bearing_jacobian_at_sensor_raises():
    rb = RangeBearing([1.0, 1e-4], sensor_position=(2.0, 3.0))
    with pytest.raises(ValueError, match=r"track 1.*sensor position"):
        rb.jacobian(np.array([[0.0, 0.0, 0, 0], [2.0, 3.0, 1.0, 1.0]]))


def test_wrap_angle():
    a = np.array([0.0, np.pi, -np.pi, 3 * np.pi, -3 * np.pi, 2 * np.pi, 7.0, -7.0, 1e-300])
    w = wrap_angle(a)
    assert np.all(w > -np.pi) and np.all(w <= np.pi)
    np.testing.assert_allclose(
        w, [0.0, np.pi, np.pi, np.pi, np.pi, 0.0, 7 - 2 * np.pi, -7 + 2 * np.pi, 1e-300], atol=1e-15
    )
    assert isinstance(wrap_angle(4.0), float)
    # values that round to the cut still land in (−π, π]
    for v in (np.nextafter(np.pi, 4), np.nextafter(-np.pi, -4), np.nextafter(-np.pi, 0)):
        assert -np.pi < wrap_angle(v) <= np.pi


@settings(max_examples=100, deadline=None)
@given(st.floats(-1e4, 1e4))
def test_wrap_angle_property(a):
    w = wrap_angle(a)
    assert -np.pi < w <= np.pi
    k = (a - w) / (2 * np.pi)
    assert abs(k - round(k)) < 1e-9


def test_residual_wraps_bearing_across_pi():
    rb = RangeBearing([1.0, 1e-4])
    z = np.array([10.0, -np.pi + 0.01])
    zp = np.array([10.5, np.pi - 0.02])
    np.testing.assert_allclose(rb.residual(z, zp), [-0.5, 0.03], atol=1e-12)
    np.testing.assert_allclose(rb.residual(zp, z), [0.5, -0.03], atol=1e-12)


@pytest.mark.parametrize("accel", [False, True])
@pytest.mark.parametrize("q", [0.0, 1e-300, 0.05, 1.0, 1e300])
def test_max_dt_is_the_overflow_limit(accel, q):
    """F, Q finite up to and including max_dt; one float beyond it raises a ValueError
    naming dt and the limit (NCV: q Δt³/3 overflows; CA: q Δt⁵/20 or Δt²/2)."""
    model = (ConstantAcceleration if accel else ConstantVelocity)(2, q)
    dt = model.max_dt
    assert 0 < dt < np.inf
    with np.errstate(all="raise"):
        assert np.isfinite(model.transition(dt)).all()
        assert np.isfinite(model.noise(dt)).all()
        assert np.isfinite(model.noise(np.array([1.0, dt]))).all()
    if q > 0:  # the Q limit, from the logarithm of the largest entry
        k, c = (5, 20.0) if accel else (3, 3.0)
        expect = np.exp((np.log(np.finfo(float).max) + np.log(c) - np.log(q)) / k)
        if not accel or expect < np.sqrt(2.0) * np.sqrt(np.finfo(float).max):
            np.testing.assert_allclose(dt, expect, rtol=1e-12)
    beyond = np.nextafter(dt, np.inf)
    if np.isfinite(beyond):
        with pytest.raises(ValueError, match=r"dt = .* too large.*beyond dt = .*largest usable dt"):
            model.transition(beyond) if q == 0 else model.noise(beyond)


def test_huge_dt_message_names_dt_and_limit():
    with pytest.raises(ValueError, match=r"dt = 1e\+300 .*beyond dt = 8\.1397.*e\+102"):
        ConstantVelocity(2, 1.0).noise(1e300)
    with pytest.raises(
        ValueError, match=r"dt\[1\] \(track 1\) = 1e\+300.*beyond dt = 1\.89615e\+154"
    ):
        ConstantAcceleration(3, 1.0).transition([1.0, 1e300])
    with pytest.raises(ValueError, match=r"constant-acceleration process noise Q.*q = 1"):
        ConstantAcceleration(3, 1.0).noise(1e100)
