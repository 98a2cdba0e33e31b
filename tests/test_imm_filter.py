"""The IMM filter core (jointtrack.filters.imm) and the coordinated-turn model.

Exact references: ``fractions.Fraction`` for the mixing, mixed initial conditions,
mode update and combined estimate; ``mpmath`` (60 digits) where probabilities
are logarithms far below the float range; FilterPy's ``IMMEstimator`` (an
independent implementation of Bar-Shalom et al. §11.6.6) on linear modes.
"""

from __future__ import annotations

from fractions import Fraction

import mpmath as mp
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from filterpy_bank import filterpy_bank
from jointtrack.filters import (
    IMMModes,
    imm_combine,
    imm_mix,
    imm_mixing,
    imm_mode_update,
    imm_pda_pairs_update,
    imm_predict,
    imm_update,
)
from jointtrack.models import (
    ConstantAcceleration,
    ConstantVelocity,
    CoordinatedTurn,
    cv_noise,
    cv_transition,
)

# probabilities from subnormal to 1 (zeros allowed in Π off its diagonal)
_prob = st.one_of(
    st.floats(min_value=5e-324, max_value=1.0),
    st.sampled_from([5e-324, 1e-300, 1e-30, 0.5, 1.0]),
)


@st.composite
def _switching(draw, r):
    rows = []
    for i in range(r):
        w = [draw(st.one_of(st.just(0.0), _prob)) for _ in range(r)]
        w[i] = draw(_prob)  # a positive diagonal: every mode can be entered
        tot = Fraction(sum(Fraction(v) for v in w))
        rows.append([float(Fraction(v) / tot) for v in w])
    return rows


def _exact_rows(pi):
    """The switching matrix as the function uses it: each row divided by its sum."""
    out = []
    for row in pi:
        tot = sum(Fraction(v) for v in row)
        out.append([Fraction(v) / tot for v in row])
    return out


@st.composite
def _mixing_case(draw):
    r = draw(st.integers(1, 4))
    pi = draw(_switching(r))
    w = [draw(st.floats(min_value=1e-300, max_value=1.0)) for _ in range(r)]
    tot = sum(Fraction(v) for v in w)
    mu = [float(Fraction(v) / tot) for v in w]
    mu = [max(v, 5e-324) for v in mu]
    return r, pi, mu


def _close(a: float, b: Fraction | float, rel: float) -> bool:
    b = float(b)
    return abs(a - b) <= rel * max(abs(b), 1e-300)


@settings(max_examples=40, deadline=None)
@given(_mixing_case())
@example((2, [[0.9, 0.1], [0.2, 0.8]], [0.6, 0.4]))
@example((3, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.5, 0.0, 0.5]], [5e-324, 1e-300, 1.0]))
@example((3, [[1.0, 0.0, 0.0], [0.0, 1.0, 1e-300], [0.0, 0.0, 1.0]], [0.5, 0.5, 5e-301]))
def test_mixing_probabilities_exact(case):
    r, pi, mu = case
    log_mu = np.log(np.asarray(mu))[None]
    log_mu = log_mu - np.log(np.exp(log_mu).sum())  # the float normalisation the input needs
    mu_exact = [Fraction(v) for v in np.exp(log_mu[0])]
    tot = sum(mu_exact)
    mu_exact = [v / tot for v in mu_exact]
    P = _exact_rows(pi)
    log_cbar, log_mix = imm_mixing(log_mu, np.asarray(pi))
    assert np.isfinite(log_cbar).all() and not np.isnan(log_mix).any()
    eps = np.finfo(float).eps
    for j in range(r):
        cbar = sum(P[i][j] * mu_exact[i] for i in range(r))
        assert cbar > 0
        # eq. 11.6.6-7 in logarithms: a log of magnitude L carries L·ε absolute
        # error, i.e. exp of it L·ε relative (L = 744 for a subnormal probability);
        # every term log π_ij μ_i of column j enters c̄_j and each μ_{i|j}
        terms = [abs(np.log(pi[i][j]) + log_mu[0, i]) for i in range(r) if pi[i][j] > 0]
        tol = 8 * r * eps * (1.0 + max(terms))
        assert _close(float(np.exp(log_cbar[0, j])), cbar, tol), (j, cbar)
        for i in range(r):
            exact = P[i][j] * mu_exact[i] / cbar
            got = float(np.exp(log_mix[0, i, j]))
            if exact == 0:
                assert got == 0.0
            elif float(exact) > 1e-290:
                assert _close(got, exact, tol), (i, j, got, exact)
        assert abs(np.exp(log_mix[0, :, j]).sum() - 1.0) < 2e-12


def test_mixing_far_below_the_float_range():
    """log μ of −1e5 (μ = e^{-100000}, far below the smallest float): log c̄ against
    60-digit arithmetic, finite, never NaN."""
    mp.mp.dps = 60
    log_mu = np.array([[-1e5, 0.0, -745.5]])
    log_mu = log_mu - np.log(np.exp(log_mu).sum())
    pi = np.array([[0.98, 0.01, 0.01], [0.0, 0.999, 0.001], [0.3, 0.3, 0.4]])
    log_cbar, log_mix = imm_mixing(log_mu, pi)
    for j in range(3):
        exact = mp.log(sum(mp.mpf(pi[i, j]) * mp.e ** mp.mpf(log_mu[0, i]) for i in range(3)))
        assert abs(log_cbar[0, j] - float(exact)) < 1e-12
        for i in range(3):
            if pi[i, j] > 0:
                want = mp.log(mp.mpf(pi[i, j])) + mp.mpf(log_mu[0, i]) - exact
                assert abs(log_mix[0, i, j] - float(want)) <= 1e-12 * max(1.0, abs(float(want)))
    assert np.isfinite(log_cbar).all()


@settings(max_examples=30, deadline=None)
@given(
    st.integers(1, 3),
    st.integers(1, 3),
    st.data(),
)
def test_mix_and_combine_exact(r, n, data):
    """Mixed initial conditions (eq. 11.6.6-8/9) and the combined estimate
    (eq. 11.6.6-16/17) against Fractions, weights and states drawn."""
    ints = st.integers(-(10**6), 10**6)
    x = np.array([[[data.draw(ints) / 64 for _ in range(n)] for _ in range(r)]], float)
    P = np.zeros((1, r, n, n))
    for i in range(r):
        A = np.array([[data.draw(ints) / 1024 for _ in range(n)] for _ in range(n)])
        P[0, i] = A @ A.T + np.eye(n)
    pscale = float(np.abs(P).max())  # rounding is relative to the largest entry
    pi = data.draw(_switching(r))
    mu = [data.draw(st.floats(min_value=1e-6, max_value=1.0)) for _ in range(r)]
    log_mu = np.log(np.asarray(mu) / np.sum(mu))[None]
    log_cbar, log_mix = imm_mixing(log_mu, np.asarray(pi))
    x0, P0 = imm_mix(x, P, log_mix)
    w = [[Fraction(float(np.exp(log_mix[0, i, j]))) for j in range(r)] for i in range(r)]
    X = [[Fraction(v) for v in x[0, i]] for i in range(r)]
    for j in range(r):
        m = [sum(w[i][j] * X[i][k] for i in range(r)) for k in range(n)]
        scale = max(1.0, max(abs(float(v)) for row in X for v in row))
        for k in range(n):
            assert abs(x0[0, j, k] - float(m[k])) <= 1e-14 * scale
            for l in range(n):
                pv = sum(
                    w[i][j] * (Fraction(P[0, i, k, l]) + (X[i][k] - m[k]) * (X[i][l] - m[l]))
                    for i in range(r)
                )
                assert abs(P0[0, j, k, l] - float(pv)) <= 1e-13 * max(1.0, scale**2, pscale)
    # combined estimate with the drawn mode probabilities
    xc, Pc = imm_combine(x, P, log_mu)
    mw = [Fraction(float(v)) for v in np.exp(log_mu[0])]
    m = [sum(mw[i] * X[i][k] for i in range(r)) for k in range(n)]
    scale = max(1.0, max(abs(float(v)) for row in X for v in row))
    for k in range(n):
        assert abs(xc[0, k] - float(m[k])) <= 1e-14 * scale
        for l in range(n):
            pv = sum(
                mw[i] * (Fraction(P[0, i, k, l]) + (X[i][k] - m[k]) * (X[i][l] - m[l]))
                for i in range(r)
            )
            assert abs(Pc[0, k, l] - float(pv)) <= 1e-13 * max(1.0, scale**2, pscale)


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(min_value=1e-300, max_value=1.0), min_size=1, max_size=4),
    st.data(),
)
def test_mode_update_exact(cbar, data):
    """μ_j = c̄_j Λ_j / Σ_l c̄_l Λ_l (eq. 11.6.6-15) against Fractions; Λ from
    subnormal to 1e300."""
    r = len(cbar)
    lam = [data.draw(st.floats(min_value=5e-324, max_value=1e300)) for _ in range(r)]
    log_cbar = np.log(np.asarray(cbar) / np.sum(cbar))[None]
    log_mu = imm_mode_update(log_cbar, np.log(np.asarray(lam))[None])
    c = [Fraction(float(v)) for v in np.exp(log_cbar[0])]
    tot = sum(c[j] * Fraction(lam[j]) for j in range(r))
    for j in range(r):
        exact = c[j] * Fraction(lam[j]) / tot
        assert np.isfinite(log_mu[0, j])
        if float(exact) > 1e-290:
            # log of a subnormal Λ carries its few significant bits: 1e-12 relative
            tol = 1e-12 if lam[j] > 1e-300 else 1e-9
            assert _close(float(np.exp(log_mu[0, j])), exact, tol), (j, exact)


def test_mode_update_never_zero_or_nan():
    """Likelihoods e^{-2000} apart (underflow in linear space): finite log μ."""
    log_cbar = np.log([[0.5, 0.5]])
    log_mu = imm_mode_update(log_cbar, np.array([[0.0, -2000.0]]))
    assert np.isfinite(log_mu).all()
    assert log_mu[0, 1] == pytest.approx(-2000.0, abs=1e-9)
    with pytest.raises(ValueError, match="likelihood 0"):
        imm_mode_update(log_cbar, np.array([[-np.inf, -np.inf]]))


# ----------------------------------------------------------------------------- FilterPy


@pytest.mark.parametrize(
    "models, switching, initial",
    [
        ([ConstantVelocity(q=0.05), ConstantVelocity(q=20.0)], [[0.95, 0.05], [0.1, 0.9]], None),
        (
            [ConstantVelocity(q=0.1), ConstantAcceleration(q=0.5)],
            [[0.9, 0.1], [0.2, 0.8]],
            [0.6, 0.4],
        ),
        (
            [ConstantVelocity(q=0.1), ConstantAcceleration(q=2.0), ConstantVelocity(q=9.0)],
            [[0.8, 0.1, 0.1], [0.05, 0.9, 0.05], [0.0, 0.3, 0.7]],
            [0.2, 0.3, 0.5],
        ),
    ],
)
@pytest.mark.parametrize("seed", [0, 1])
def test_against_filterpy_imm(models, switching, initial, seed):
    """Twelve predict/update cycles of a manoeuvring target: the combined state,
    covariance and mode probabilities equal FilterPy's IMMEstimator to 1e-12."""
    pytest.importorskip("filterpy")
    from filterpy.kalman import IMMEstimator

    modes = IMMModes(models, switching, initial=initial)
    n, dt = modes.state_dim, 0.8
    rng = np.random.default_rng(seed)
    H = np.zeros((2, n))
    H[0, 0] = H[1, 1] = 1.0
    R = np.array([[4.0, 1.0], [1.0, 9.0]])
    x0 = rng.normal(size=n) * 5
    A = rng.normal(size=(n, n))
    P0 = A @ A.T + 10 * np.eye(n)
    bank, xs, Ps = filterpy_bank(modes, dt, H, R, x0, P0)
    imm = IMMEstimator(bank, modes.initial, modes.switching)
    log_mu = modes.log_initial[None].copy()
    for k in range(12):
        # a target that turns after scan 5: the modes' probabilities move
        truth = np.array([3.0 * k, 0.2 * max(0, k - 5) ** 2])
        z = truth + rng.normal(size=2) * 2
        cbar = imm.cbar.copy()  # FilterPy's c̄ of this cycle, formed after the last update
        imm.predict()
        imm.update(z)
        xp, Pp, log_cbar = imm_predict(xs, Ps, log_mu, modes, dt)
        np.testing.assert_allclose(np.exp(log_cbar[0]), cbar, rtol=1e-12, atol=0)
        xs, Ps, log_mu = imm_update(modes, xp, Pp, log_cbar, z[None], H, R)
        xc, Pc = imm_combine(xs, Ps, log_mu)
        np.testing.assert_allclose(np.exp(log_mu[0]), imm.mu, rtol=1e-12, atol=1e-300)
        assert np.abs(xc[0] - imm.x).max() <= 1e-12 * np.abs(imm.x).max()
        assert np.abs(Pc[0] - imm.P).max() <= 1e-12 * np.abs(imm.P).max()
        for j, kf in enumerate(bank):
            assert np.abs(xs[0, j] - kf.x).max() <= 1e-12 * max(1.0, np.abs(kf.x).max())


def test_pda_update_with_one_sure_pair_is_the_imm_update():
    """IMM-PDA with β = (0, 1) is the IMM update: modes, states, probabilities."""
    modes = IMMModes(
        [ConstantVelocity(q=0.1), CoordinatedTurn(q=0.1, turn_rate_std=0.02)],
        [[0.9, 0.1], [0.1, 0.9]],
    )
    x0 = np.array([[0.0, 0.0, 10.0, 1.0], [50.0, 5.0, -3.0, 4.0]])
    P0 = np.broadcast_to(np.diag([4.0, 4.0, 9.0, 9.0]), (2, 4, 4))
    xs, Ps, log_mu = modes.initial_states(x0, P0, turn_rate_var=0.01)
    xp, Pp, log_cbar = imm_predict(xs, Ps, log_mu, modes, 1.0)
    H = np.zeros((2, 5))
    H[0, 0] = H[1, 1] = 1.0
    R = 4.0 * np.eye(2)
    z = np.array([[10.5, 1.7], [46.0, 9.5]])
    want = imm_update(modes, xp, Pp, log_cbar, z, H, R)
    got = imm_pda_pairs_update(
        modes, xp, Pp, log_cbar, z, np.zeros(2), [0, 1], [0, 1], [1.0, 1.0], H=H, R=R
    )
    for a, b in zip(got, want, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)


def test_pda_update_mode_probabilities_sum_and_far_returns():
    """IMM-PDA: mode-conditioned β sum to one; a return 1e3 σ away leaves finite
    log μ (likelihood ratios e^{-5e5}) and no NaN anywhere."""
    modes = IMMModes(
        [ConstantVelocity(q=0.1), CoordinatedTurn(q=0.1, turn_rate_std=0.02)],
        [[0.95, 0.05], [0.05, 0.95]],
    )
    x0 = np.array([[0.0, 0.0, 10.0, 0.0]])
    xs, Ps, log_mu = modes.initial_states(x0, np.diag([1.0, 1.0, 1.0, 1.0])[None], 0.04)
    xp, Pp, log_cbar = imm_predict(xs, Ps, log_mu, modes, 1.0)
    H = np.zeros((2, 5))
    H[0, 0] = H[1, 1] = 1.0
    z = np.array([[10.0, 0.3], [10.0, 2000.0]])
    with np.errstate(over="raise", invalid="raise"):
        xu, Pu, log_post = imm_pda_pairs_update(
            modes, xp, Pp, log_cbar, z, [0.2], [0, 0], [0, 1], [0.5, 0.3], H=H, R=np.eye(2)
        )
    assert np.isfinite(log_post).all() and np.isfinite(xu).all() and np.isfinite(Pu).all()
    assert abs(np.exp(log_post).sum() - 1.0) < 1e-14


# ----------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    "switching, initial, match",
    [
        ([[0.9, 0.2], [0.1, 0.9]], None, "not a stochastic matrix: row 0"),
        ([[1.0, 0.0], [1.0, 0.0]], None, "column 1 is all zero"),
        ([[1.1, -0.1], [0.1, 0.9]], None, "probabilities ≥ 0"),
        ([[0.9, 0.1]], None, "2 × 2 matrix"),
        ([[0.9, 0.1], [0.1, 0.9]], [1.0, 0.0], "initial must hold probabilities > 0"),
        ([[0.9, 0.1], [0.1, 0.9]], [0.7, 0.7], "initial must sum to 1"),
        ([[0.9, 0.1], [0.1, 0.9]], [0.5, 0.5j], "initial"),
        ([[0.9, 0.1], [0.1, np.nan]], None, "switching"),
    ],
)
def test_bad_modes_name_the_argument(switching, initial, match):
    with pytest.raises(ValueError, match=match):
        IMMModes([ConstantVelocity(), CoordinatedTurn()], switching, initial=initial)


def test_bad_models_and_states():
    with pytest.raises(ValueError, match="models\\[1\\]"):
        IMMModes([ConstantVelocity(), "ct"], [[0.5, 0.5], [0.5, 0.5]])
    with pytest.raises(ValueError, match="one spatial dimension"):
        IMMModes([ConstantVelocity(dim=3), CoordinatedTurn()], [[0.5, 0.5], [0.5, 0.5]])
    modes = IMMModes([ConstantVelocity(), CoordinatedTurn()], [[0.5, 0.5], [0.5, 0.5]])
    xs, Ps, log_mu = modes.initial_states(np.zeros((1, 4)), np.eye(4)[None], 0.01)
    with pytest.raises(ValueError, match="not finite"):
        imm_predict(xs, Ps, np.array([[0.0, -np.inf]]), modes, 1.0)
    with pytest.raises(ValueError, match="sum to"):
        imm_predict(xs, Ps, np.log([[0.5, 0.6]]), modes, 1.0)
    with pytest.raises(ValueError, match="common state has 5"):
        imm_predict(xs[:, :, :4], Ps[:, :, :4, :4], log_mu, modes, 1.0)


def test_bad_pairs_and_association_probabilities_name_them():
    modes = IMMModes([ConstantVelocity(), CoordinatedTurn()], [[0.9, 0.1], [0.1, 0.9]])
    xs, Ps, log_mu = modes.initial_states(np.zeros((1, 4)), np.eye(4)[None], 0.01)
    H = np.eye(2, 5)
    z = np.zeros((2, 2))
    args = (modes, xs, Ps, log_mu, z)
    for b0, rows, cols, w, match in [
        ([0.5], [0], [2], [0.5], "cols indexes outside the 2 measurements"),
        ([0.5], [1], [0], [0.5], "rows indexes outside the 1 tracks"),
        ([0.5], [0.5], [0], [0.5], "rows must hold integer indices"),
        ([0.5], [0], [0], [-0.5], "finite and ≥ 0"),
        ([0.5], [0], [0], [0.7], "sum to 1.2"),
        ([0.5], [0], [0], [0.5j], "weights has complex entries"),
        ([True], [0], [0], [0.0], "beta0 is boolean"),
    ]:
        with pytest.raises(ValueError, match=match):
            imm_pda_pairs_update(*args, b0, rows, cols, w, H=H, R=np.eye(2))


# ----------------------------------------------------------------------------- coordinated turn


def _ct_exact(x, dt, omega):
    """f(x) and ∂f/∂ω of a coordinated turn in 60-digit arithmetic."""
    mp.mp.dps = 60
    t, w = mp.mpf(dt), mp.mpf(omega)
    vx, vy = mp.mpf(x[2]), mp.mpf(x[3])
    th = w * t
    if w == 0:  # the limits: a = Δt, b = 0, a' = 0, b' = Δt²/2
        a, b, da, db = t, mp.mpf(0), mp.mpf(0), t * t / 2
    else:
        a, b = mp.sin(th) / w, (1 - mp.cos(th)) / w
        if abs(th) < mp.mpf("1e-20"):  # series: the closed forms cancel at 60 digits
            da, db = -t * t * th / 3, t * t / 2 - t * t * th * th / 8
        else:
            da = t * t * (th * mp.cos(th) - mp.sin(th)) / (th * th)
            db = t * t * (th * mp.sin(th) - (1 - mp.cos(th))) / (th * th)
    f = [
        mp.mpf(x[0]) + a * vx - b * vy,
        mp.mpf(x[1]) + b * vx + a * vy,
        mp.cos(th) * vx - mp.sin(th) * vy,
        mp.sin(th) * vx + mp.cos(th) * vy,
    ]
    dfdw = [da * vx - db * vy, db * vx + da * vy]
    dfdw += [-t * (mp.sin(th) * vx + mp.cos(th) * vy), t * (mp.cos(th) * vx - mp.sin(th) * vy)]
    return [float(v) for v in f], [float(v) for v in dfdw]


@settings(max_examples=50, deadline=None)
@given(
    st.one_of(
        st.sampled_from([0.0, 5e-324, -5e-324, 1e-300, 1e-8, 0.999, 1.001, -2.5]),
        st.floats(min_value=-3.0, max_value=3.0),
    ),
    st.floats(min_value=0.01, max_value=5.0),
)
@example(omega=1.0 / 1.7 - 1e-12, dt=1.7)  # |θ| just below the series switch
def test_coordinated_turn_against_exact(omega, dt):
    m = CoordinatedTurn(q=0.5, turn_rate_std=0.01)
    x = np.array([3.0, -2.0, 12.0, -5.0, omega])
    f, dfdw = _ct_exact(x, dt, omega)
    got = m.propagate(x, dt)
    assert np.abs(got[:4] - f).max() <= 4e-15 * max(1.0, np.abs(f).max())
    assert got[4] == omega
    J = m.jacobian(x, dt)
    assert np.abs(J[:4, 4] - dfdw).max() <= 1e-14 * max(1.0, np.abs(dfdw).max())
    assert np.isfinite(J).all()


def test_coordinated_turn_at_zero_rate_is_constant_velocity():
    m = CoordinatedTurn(q=0.7, turn_rate_std=0.03)
    x = np.array([[1.0, 2.0, 3.0, -4.0, 0.0], [0.0, 1.0, -1.0, 2.0, 0.0]])
    dt = np.array([0.5, 2.0])
    F = cv_transition(dt, 2)
    np.testing.assert_array_equal(m.propagate(x, dt)[:, :4], np.einsum("nij,nj->ni", F, x[:, :4]))
    np.testing.assert_array_equal(m.jacobian(x, dt)[:, :4, :4], F)
    Q = m.noise(dt)
    np.testing.assert_array_equal(Q[:, :4, :4], cv_noise(dt, 0.7, 2))
    np.testing.assert_array_equal(Q[:, 4, 4], 0.03**2 * dt)


@pytest.mark.parametrize(
    "kwargs, match",
    [({"q": -1.0}, "noise intensity q"), ({"turn_rate_std": np.nan}, "turn_rate_std")],
)
def test_coordinated_turn_bad_parameters(kwargs, match):
    with pytest.raises(ValueError, match=match):
        CoordinatedTurn(**kwargs)


def test_coordinated_turn_bad_states():
    m = CoordinatedTurn()
    with pytest.raises(ValueError, match="shape"):
        m.propagate(np.zeros(4), 1.0)
    with pytest.raises(ValueError, match="non-finite"):
        m.jacobian([0.0, 0.0, 1.0, np.inf, 0.0], 1.0)
    with pytest.raises(ValueError, match="dt"):
        m.propagate(np.zeros(5), -1.0)


@settings(max_examples=20, deadline=None)
@given(
    st.lists(st.tuples(st.floats(-30.0, 30.0), st.floats(-30.0, 30.0)), min_size=0, max_size=4),
    st.floats(0.05, 0.99),
    st.floats(1e-6, 1e-2),
    st.floats(0.05, 0.95),
)
def test_imm_pda_is_each_modes_own_pdaf(offsets, p_d, clutter, mu_cv):
    """One track, β from the mixture likelihood (single-track PDA): every mode's
    update equals that mode's own PDAF (its β from its own likelihoods, Bar-Shalom
    et al. §11.6.6 IMM-PDAF) and μ_j ∝ c̄_j [(1 − P_D) + P_D/λ Σ_k g_jk]."""
    from jointtrack.filters import imm_pair_log_likelihoods, pda_update

    modes = IMMModes(
        [ConstantVelocity(q=0.2), CoordinatedTurn(q=0.2, turn_rate_std=0.05)],
        [[0.9, 0.1], [0.1, 0.9]],
    )
    x0 = np.array([[0.0, 0.0, 10.0, 2.0]])
    xs, Ps, _ = modes.initial_states(x0, np.diag([9.0, 9.0, 4.0, 4.0])[None], 0.01)
    log_mu = np.log([[mu_cv, 1.0 - mu_cv]])
    xp, Pp, log_cbar = imm_predict(xs, Ps, log_mu, modes, 1.0)
    H, R = np.eye(2, 5), 4.0 * np.eye(2)
    z = np.array([[10.0 + a, 2.0 + b] for a, b in offsets]).reshape(-1, 2)
    M = len(z)
    rows, cols = np.zeros(M, np.int64), np.arange(M)
    log_g, log_g_mode = imm_pair_log_likelihoods(modes, xp, Pp, log_cbar, z, rows, cols, H=H, R=R)
    L = p_d * np.exp(log_g) / clutter
    miss = 1.0 - p_d
    beta0, beta = miss / (miss + L.sum()), L / (miss + L.sum())
    xu, Pu, log_post = imm_pda_pairs_update(
        modes, xp, Pp, log_cbar, z, [beta0], rows, cols, beta, H=H, R=R
    )
    cbar = np.exp(log_cbar[0])
    lam = miss + p_d / clutter * np.exp(log_g_mode).sum(axis=0)  # Λ_j up to a constant
    np.testing.assert_allclose(np.exp(log_post[0]), cbar * lam / (cbar * lam).sum(), rtol=1e-12)
    for j in range(2):
        Lj = p_d * np.exp(log_g_mode[:, j]) / clutter
        bj = np.concatenate([[miss], Lj]) / (miss + Lj.sum())
        xj, Pj = modes.to_mode(j, xp[:, j], Pp[:, j])
        Hj = modes.mode_measurement(j, H, R)["H"]
        want_x, want_P = pda_update(xj[0], Pj[0], z, Hj, R, bj)
        got_x, got_P = modes.to_mode(j, xu[:, j], Pu[:, j])
        np.testing.assert_allclose(got_x[0], want_x, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(got_P[0], want_P, rtol=1e-10, atol=1e-10)
