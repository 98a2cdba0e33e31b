"""The IMM's stationary mode and its switching in continuous time (issue 32, Solent).

Exact references: ``fractions.Fraction`` matrix powers for the one-second chain over
whole seconds, the two-mode chain's closed form ``Π(Δt) = 1 π + λ^Δt (I − 1 π)``
(λ = 1 − a − b its second eigenvalue, π its stationary distribution) for any Δt, and
FilterPy's ``IMMEstimator`` for the stationary mode beside CV (per-scan switching,
the modes embedded in the common state as in ``test_imm_filter``).
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from filterpy_bank import filterpy_bank
from jointtrack.filters.imm import (
    IMMModes,
    imm_combine,
    imm_predict,
    imm_update,
    switching_generator,
    switching_over,
)
from jointtrack.models import ConstantVelocity, Stationary
from jointtrack.trackers.base import imm_modes
from jointtrack.trackers.config import TrackerConfig

# time steps from the smallest subnormal to 1e300 seconds
_dt = st.one_of(
    st.floats(min_value=5e-324, max_value=1e300),
    st.sampled_from([5e-324, 1e-300, 1e-9, 0.5, 1.0, 180.0, 1e6, 1e300]),
)
# a two-mode chain's switching probabilities per second (stays above 1/2: embeddable)
_rate = st.one_of(
    st.floats(min_value=5e-324, max_value=0.49),
    st.sampled_from([5e-324, 1e-300, 1e-12, 0.01, 0.3, 0.49]),
)


def _two(a: float, b: float) -> np.ndarray:
    return np.array([[1.0 - a, a], [b, 1.0 - b]])


def _two_exact(a: float, b: float, dt: float) -> np.ndarray:
    """Π(Δt) of the two-mode chain whose one-second matrix is [[1−a, a], [b, 1−b]]
    (as floats: 1 − a rounds), in closed form: π = (b, a)/(a + b), λ = 1 − a − b."""
    P = _two(a, b)
    a, b = P[0, 1], P[1, 0]
    lam_dt = math.exp(dt * math.log1p(-(a + b)))  # λ^Δt without cancellation
    pi = np.array([b, a]) / (a + b)
    limit = np.outer(np.ones(2), pi)
    return limit + lam_dt * (np.eye(2) - limit)


# ----------------------------------------------------------------------- the chain in time


@settings(max_examples=40, deadline=None)
@given(a=_rate, b=_rate, dt=_dt)
@example(a=0.01, b=0.01, dt=1.0)
@example(a=5e-324, b=0.3, dt=1e300)
def test_switching_over_time_is_the_two_mode_closed_form(a, b, dt):
    G = switching_generator(_two(a, b))
    got = switching_over(G, dt)
    want = _two_exact(a, b, dt)
    assert np.all(got >= 0.0)
    np.testing.assert_allclose(got.sum(axis=1), 1.0, rtol=0, atol=4e-16)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


@settings(max_examples=25, deadline=None)
@given(
    st.integers(min_value=2, max_value=4),
    st.floats(min_value=0.55, max_value=0.999),
    st.integers(min_value=0, max_value=40),
)
def test_whole_seconds_are_exact_matrix_powers(r, stay, seconds):
    """Π(n) = Π₁ⁿ, the power taken in exact rationals (and Π(1) is Π₁ itself)."""
    share = (1.0 - stay) / (r - 1)
    P = np.full((r, r), share)
    np.fill_diagonal(P, stay)
    P = P / P.sum(axis=1, keepdims=True)
    exact = [[Fraction(v) for v in row] for row in P]
    power = [[Fraction(int(i == j)) for j in range(r)] for i in range(r)]
    for _ in range(seconds):
        power = [
            [sum(power[i][k] * exact[k][j] for k in range(r)) for j in range(r)] for i in range(r)
        ]
    got = switching_over(switching_generator(P), float(seconds))
    want = np.array([[float(v) for v in row] for row in power])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    if seconds == 1:
        np.testing.assert_allclose(got, P, rtol=0, atol=1e-13)


@settings(max_examples=40, deadline=None)
@given(a=_rate, b=_rate, dt1=_dt, dt2=_dt)
@example(a=0.2, b=0.05, dt1=0.3, dt2=0.7)
def test_switching_composes(a, b, dt1, dt2):
    """Π(dt1) Π(dt2) = Π(dt1 + dt2): splitting an interval changes nothing."""
    G = switching_generator(_two(a, b))
    both = switching_over(G, dt1) @ switching_over(G, dt2)
    np.testing.assert_allclose(both, switching_over(G, dt1 + dt2), rtol=0, atol=1e-12)


def test_zero_time_is_no_switching_and_bad_times_are_refused():
    G = switching_generator(_two(0.1, 0.2))
    assert switching_over(G, 0.0).tolist() == [[1.0, 0.0], [0.0, 1.0]]
    for bad in (-1.0, math.inf, math.nan):
        with pytest.raises(ValueError, match="dt must be finite and ≥ 0"):
            switching_over(G, bad)


@pytest.mark.parametrize(
    "matrix, match",
    [
        ([[0.3, 0.7], [0.6, 0.4]], "positive eigenvalues"),  # eigenvalue −0.3
        ([[0.5, 0.5], [0.5, 0.5]], "positive eigenvalues"),  # eigenvalue 0
        # stays of 0.9 and more, but a cycle no continuous-time chain makes in 1 s
        ([[0.999999, 1e-6, 0.0], [0.0, 0.9, 0.1], [0.05, 0.0, 0.95]], "negative switching rate"),
    ],
)
def test_a_matrix_no_chain_makes_in_a_second_is_refused_naming_the_key(matrix, match):
    with pytest.raises(ValueError, match=f"TrackerConfig: imm_switching.*{match}"):
        TrackerConfig(
            motion="imm",
            imm_modes=["cv", "ct", "stationary"][: len(matrix)],
            imm_switching=matrix,
            imm_switching_per="second",
        )
    # per scan the same matrix is a valid chain
    TrackerConfig(
        motion="imm", imm_modes=["cv", "ct", "stationary"][: len(matrix)], imm_switching=matrix
    )


def test_a_track_between_its_reports_switches_as_time_says():
    """60 s of other targets' reports cut into 200 predictions switch a track's modes
    exactly as one prediction over 60 s does (per second); per scan they would mix the
    modes completely."""
    models = [ConstantVelocity(q=0.1), Stationary(q=0.001)]
    P1 = [[0.999, 0.001], [0.002, 0.998]]
    x0 = np.array([[0.0, 0.0, 0.0, 0.0]])
    P0 = np.diag([25.0, 25.0, 1.0, 1.0])[None]
    once = IMMModes(models, P1, switching_per="second")
    xs, Ps, log_mu = once.initial_states(x0, P0)
    log_mu = np.log([[0.01, 0.99]])
    _, _, one = imm_predict(xs, Ps, log_mu, once, 60.0)
    cut, lm = (xs, Ps), log_mu
    for _ in range(200):
        *cut, lm = imm_predict(*cut, lm, once, 0.3)
    np.testing.assert_allclose(np.exp(lm), np.exp(one), rtol=1e-10)
    want = np.array([0.01, 0.99]) @ _two_exact(0.001, 0.002, 60.0)
    np.testing.assert_allclose(np.exp(one[0]), want, rtol=1e-12)
    per_scan = IMMModes(models, P1)
    lm = log_mu
    cut = (xs, Ps)
    for _ in range(200):
        *cut, lm = imm_predict(*cut, lm, per_scan, 0.3)
    assert np.exp(lm[0, 1]) < 0.7  # ~ the chain's limit 2/3 · …: mixed by other reports
    assert np.exp(one[0, 1]) > 0.85


# ----------------------------------------------------------------------- the stationary model


@settings(max_examples=40, deadline=None)
@given(
    q=st.one_of(st.just(0.0), st.floats(min_value=5e-324, max_value=1e300)),
    a=st.floats(min_value=5e-324, max_value=1e3),
    b=st.floats(min_value=5e-324, max_value=1e3),
    dim=st.integers(min_value=1, max_value=3),
)
def test_stationary_model_is_a_random_walk_that_composes(q, a, b, dim):
    m = Stationary(dim=dim, q=q)
    assert m.state_dim == dim and m.velocity_indices.size == 0
    assert m.transition(a).tolist() == np.eye(dim).tolist()
    Qa, Qb, Qab = m.noise(a), m.noise(b), m.noise(a + b)
    assert np.isfinite(Qab).all()
    # Q(a + b) = F(b) Q(a) F(b)ᵀ + Q(b) = Q(a) + Q(b), exact up to the products' rounding
    # (relative, and absolute in the subnormal range: a few of its steps)
    exact = Fraction(q) * (Fraction(a) + Fraction(b))
    tol = exact * Fraction(1, 2**50) + 3 * Fraction(5e-324)
    assert abs(Fraction(float(Qab[0, 0])) - exact) <= tol
    assert abs(Fraction(float((Qa + Qb)[0, 0])) - exact) <= tol
    assert (Qab - np.diag(np.diag(Qab)) == 0).all()
    stack = m.noise(np.array([a, b]))
    assert stack.shape == (2, dim, dim) and (stack[0] == Qa).all()


@pytest.mark.parametrize(
    "kwargs, dt, match",
    [
        ({"q": -1.0}, 1.0, "noise intensity q"),
        ({"q": 1j}, 1.0, "noise intensity q"),
        ({"dim": 4}, 1.0, "spatial dimension"),
        ({"q": 1e300}, 1e10, "dt = 1e\\+10 is too large"),
        ({}, 0.0, "dt must be finite and > 0"),
        ({}, math.nan, "dt must be finite and > 0"),
    ],
)
def test_stationary_model_bad_input(kwargs, dt, match):
    with pytest.raises(ValueError, match=match):
        Stationary(**kwargs).noise(dt)


def test_stationary_mode_has_zero_velocity_in_the_common_state():
    modes = IMMModes([ConstantVelocity(q=0.1), Stationary(q=0.01)], [[0.9, 0.1], [0.1, 0.9]])
    assert modes.kinds == ("cv", "stationary") and modes.state_dim == 4
    x, P, _ = modes.initial_states(np.array([[1.0, 2.0, 3.0, 4.0]]), 4.0 * np.eye(4)[None])
    assert x[0, 1].tolist() == [1.0, 2.0, 0.0, 0.0]
    assert P[0, 1, 2:].tolist() == [[0.0] * 4] * 2 and P[0, 1, :, 2:].any() == 0
    assert x[0, 0].tolist() == [1.0, 2.0, 3.0, 4.0]
    xp, Pp, _ = imm_predict(x, P, np.log([[0.5, 0.5]]), modes, 10.0)
    assert xp[0, 1, 2:].tolist() == [0.0, 0.0] and not Pp[0, 1, 2:].any()
    # its position: the mixed position, variance grown by q·Δt
    assert Pp[0, 1, 0, 0] > 4.0


@pytest.mark.parametrize("seed", [0, 1])
def test_cv_and_stationary_against_filterpy_imm(seed):
    """A vessel moored for 6 reports, then under way: the combined state, covariance
    and mode probabilities equal FilterPy's IMMEstimator to 1e-12 every cycle, and the
    modes follow the vessel (at rest: the stationary mode; under way: CV)."""
    pytest.importorskip("filterpy")
    from filterpy.kalman import IMMEstimator

    modes = IMMModes([ConstantVelocity(q=0.05), Stationary(q=0.01)], [[0.95, 0.05], [0.05, 0.95]])
    n, dt = modes.state_dim, 10.0
    rng = np.random.default_rng(seed)
    H = np.eye(2, n)
    R = np.array([[4.0, 1.0], [1.0, 9.0]])
    x0 = np.array([0.0, 0.0, 0.0, 0.0])
    P0 = np.diag([16.0, 16.0, 4.0, 4.0])
    bank, xs, Ps = filterpy_bank(modes, dt, H, R, x0, P0)
    imm = IMMEstimator(bank, modes.initial, modes.switching)
    log_mu = modes.log_initial[None].copy()
    for k in range(14):
        truth = np.array([0.0, 0.0]) if k < 6 else np.array([5.0 * (k - 5) * dt, 0.0])
        z = truth + rng.normal(size=2) * 2
        imm.predict()
        imm.update(z)
        xp, Pp, log_cbar = imm_predict(xs, Ps, log_mu, modes, dt)
        xs, Ps, log_mu = imm_update(modes, xp, Pp, log_cbar, z[None], H, R)
        xc, Pc = imm_combine(xs, Ps, log_mu)
        np.testing.assert_allclose(np.exp(log_mu[0]), imm.mu, rtol=1e-12, atol=1e-300)
        assert np.abs(xc[0] - imm.x).max() <= 1e-12 * max(1.0, np.abs(imm.x).max())
        assert np.abs(Pc[0] - imm.P).max() <= 1e-12 * np.abs(imm.P).max()
        if k == 5:
            assert np.exp(log_mu[0, 1]) > 0.5  # at rest: the stationary mode leads
    assert np.exp(log_mu[0, 0]) > 0.99  # under way: CV


# ----------------------------------------------------------------------- configuration


def test_config_builds_per_mode_q_and_per_second_switching():
    c = TrackerConfig.from_dict(
        {
            "motion": "imm",
            "imm_modes": ["cv", "stationary"],
            "imm_process_noise": [0.2, 0.001],
            "imm_switching": [[0.999, 0.001], [0.001, 0.999]],
            "imm_switching_per": "second",
        }
    )
    modes = imm_modes(c)
    assert [type(m).__name__ for m in modes.models] == ["ConstantVelocity", "Stationary"]
    assert [m.q for m in modes.models] == [0.2, 0.001]
    assert modes.switching_per == "second"
    np.testing.assert_allclose(switching_over(modes.generator, 1.0), modes.switching, atol=1e-13)
    # without imm_process_noise every mode takes process_noise, per scan
    d = imm_modes(TrackerConfig(motion="imm", imm_modes=["cv", "stationary"], process_noise=3.0))
    assert [m.q for m in d.models] == [3.0, 3.0] and d.generator is None


@pytest.mark.parametrize(
    "key, value, match",
    [
        ("imm_process_noise", [0.1], "imm_process_noise must have one q per mode"),
        ("imm_process_noise", [0.1, -1.0], "imm_process_noise"),
        ("imm_process_noise", [0.1, True], "imm_process_noise"),
        ("imm_process_noise", [0.1, 1j], "imm_process_noise"),
        ("imm_process_noise", [0.1, 10**400], "imm_process_noise"),
        ("imm_process_noise", "0.1", "imm_process_noise"),
        ("imm_switching_per", "minute", "imm_switching_per must be one of"),
        ("imm_modes", ["cv", "still"], "imm_modes: unknown mode name 'still'"),
    ],
)
def test_bad_settings_name_the_key(key, value, match):
    base = {"motion": "imm", "imm_modes": ["cv", "stationary"], "imm_switching_per": "second"}
    with pytest.raises(ValueError, match=f"TrackerConfig: {match}"):
        TrackerConfig(**{**base, key: value})


# ----------------------------------------------------------------------- in the tracker


def _moored_among_frequent_reports(switching):
    """A vessel at rest reporting every 180 s while another, 50 km off, reports every
    10 s (each of its reports a scan of the asynchronous tracker): the ids of the tracks
    within 100 m of the moored vessel right after each of its reports."""
    from jointtrack.trackers.jpda import JPDATracker

    cfg = TrackerConfig(
        motion="imm",
        imm_modes=("cv", "stationary"),
        imm_process_noise=(0.2, 2e-4),
        imm_switching=switching,
        imm_switching_per="second",
        imm_initial=(0.7, 0.3),
        measurement_noise=2.2,
        max_speed=22.0,
        reporting="async",
        report_interval=11.65,
        p_survive=0.9999,
        p_survive_per="second",
        clutter_density=1.6e-9,
        p_g=0.9999,
        r_delete=1e-4,
    )
    trk = JPDATracker(cfg)
    rng = np.random.default_rng(0)
    events = [(5.5 + 180.0 * k, True) for k in range(4)]
    events += [(1.0 + 10.0 * k, False) for k in range(56)]
    held = []
    for t, moored in sorted(events):
        z = np.array([0.0, 0.0]) if moored else np.array([50000.0 + 5.0 * t, 0.0])
        trk.step(t, (z + rng.normal(0.0, 1.5, 2))[None])
        if moored:
            near = np.linalg.norm(trk.x[:, :2], axis=1) < 100.0
            held.append(set(trk.ids[near & trk.confirmed].tolist()))
    return held


@pytest.mark.parametrize(
    "switching",
    [
        # no switching: the stationary mode alone holds the vessel (the control)
        [[1.0, 0.0], [0.0, 1.0]],
        # with switching: the track is predicted from its last update over the whole
        # interval (one mixing), not mixed at each of the other target's reports
        [[0.999, 0.001], [0.001, 0.999]],
    ],
)
def test_a_moored_vessel_between_other_targets_reports_keeps_one_track(switching):
    held = _moored_among_frequent_reports(switching)
    ids = set.union(*held[1:])
    assert all(len(h) == 1 for h in held[1:]) and len(ids) == 1, held
