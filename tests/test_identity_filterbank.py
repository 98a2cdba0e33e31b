"""Identity database and per-track filter banks (jointtrack.identity.database, .filterbank).

References are built here independently of the package: the transition and the
noise gain of Schaub's eqs. (44)–(46) are written out by hand, Monte Carlo
samples the acceleration noise itself, and the multi-step check integrates the
stacked Gaussian of all measurements over the flat position prior in closed
form.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from jointtrack.identity.database import Identity, IdentityDatabase
from jointtrack.identity.filterbank import FilterBank, IdentityBank

INF = np.inf
FAST = settings(max_examples=25, deadline=None)


# ----------------------------------------------------------------------------- references


def _F(dt, dim):
    """Eq. (45) for a step dt: [[I, dt I], [0, I]]."""
    eye = np.eye(dim)
    return np.block([[eye, dt * eye], [np.zeros((dim, dim)), eye]])


def _G(dt, dim):
    """The noise gain of eq. (44) for a step dt: [dt²/2 I; dt I]."""
    return np.vstack([0.5 * dt * dt * np.eye(dim), dt * np.eye(dim)])


def _flat_prior_log_evidence(times, zs, Rs, A, sigma_p, V):
    """log ∫ p(z_1, …, z_K | p) dp: the joint density of all measurements of one
    identity, integrated over a flat (unit-density) position at t_1, with velocity
    N(0, V) at t_1, acceleration noise N(0, Σ_P) held over each step (eq. 44) and
    measurement z_j = [position; A] + N(0, R_j) (eq. 47). ∞ on R's diagonal marks an
    unmeasured component. Built as one stacked Gaussian Z = B p + c + noise."""
    dim = V.shape[0]
    blocks = []  # (step, component) of every stacked row
    for j, R in enumerate(Rs):
        blocks += [(j, r) for r in np.flatnonzero(np.isfinite(np.diagonal(R)))]
    N = len(blocks)
    B, c, Dv = np.zeros((N, dim)), np.zeros(N), np.zeros((N, dim))
    Dw = np.zeros((len(times), N, dim))  # Dw[l]: effect of the noise of step l
    Z = np.array([zs[j][r] for j, r in blocks])
    for row, (j, r) in enumerate(blocks):
        if r >= dim:
            c[row] = A[r - dim]
            continue
        B[row, r] = 1.0
        Dv[row, r] = times[j] - times[0]
        for step in range(1, j + 1):
            h = times[step] - times[step - 1]
            Dw[step, row, r] = (times[j] - times[step]) * h + 0.5 * h * h
    Sigma = Dv @ V @ Dv.T + sum(D @ sigma_p @ D.T for D in Dw)
    at = 0
    for R in Rs:
        obs = np.flatnonzero(np.isfinite(np.diagonal(R)))
        Sigma[at : at + obs.size, at : at + obs.size] += R[np.ix_(obs, obs)]
        at += obs.size
    Si = np.linalg.inv(Sigma)
    M = B.T @ Si @ B
    r = Z - c
    quad = r @ Si @ r - (B.T @ Si @ r) @ np.linalg.solve(M, B.T @ Si @ r)
    logdet = np.linalg.slogdet(Sigma)[1] + np.linalg.slogdet(M)[1]
    return -0.5 * (N - dim) * np.log(2 * np.pi) - 0.5 * logdet - 0.5 * quad


# ----------------------------------------------------------------------------- strategies

variances = st.floats(0.5, 4.0)
coords = st.floats(-3.0, 3.0)
noise_levels = st.one_of(st.just(0.0), st.floats(0.05, 2.0))


@st.composite
def spd(draw, d, lo=0.5, hi=2.0):
    """A symmetric positive definite matrix L Lᵀ with a drawn lower factor."""
    L = np.zeros((d, d))
    for i in range(d):
        L[i, i] = draw(st.floats(lo, hi))
        for j in range(i):
            L[i, j] = draw(st.floats(-0.6, 0.6))
    return L @ L.T


def _unmeasure(R, comps):
    R = R.copy()
    for k in comps:
        R[k, :] = R[:, k] = 0.0
        R[k, k] = INF
    return R


def _db(*specs, dim=2):
    """IdentityDatabase from (process_noise, attribute) pairs named i0, i1, …"""
    return IdentityDatabase(
        [Identity(f"i{k}", q, a) for k, (q, a) in enumerate(specs)],
        dim=dim,
    )


# ----------------------------------------------------------------------------- database


def test_classes_group_identical_models_in_first_appearance_order():
    db = IdentityDatabase(
        [
            Identity("a", 1.0, 3.0),
            Identity("b", 0.0, 3.0),
            Identity("c", np.eye(2), [3.0]),  # σ² I and the scalar σ² are one model
            Identity("d", 1.0, 4.0),  # a different attribute: a different class
            Identity("e", 0.0, 3.0, label="other label"),  # labels do not split classes
            Identity("f", 1.0, 3.0, p_d=0.5),  # a different p_d does
        ]
    )
    assert db.classes.tolist() == [0, 1, 0, 2, 1, 3]
    assert db.class_counts.tolist() == [2, 2, 1, 1]
    assert db.representatives.tolist() == [0, 1, 3, 5]
    assert db.index("d") == 3 and db.class_of("e") == 1
    assert db.members(0).tolist() == [0, 2]
    assert db.attributes.tolist() == [[3.0], [3.0], [4.0], [3.0]]
    assert db.p_d.tolist() == [1.0, 1.0, 1.0, 0.5]
    with pytest.raises(KeyError, match="zz"):
        db.index("zz")


def test_process_noise_is_g_sigma_gt():
    sigma = np.array([[2.0, 0.3], [0.3, 1.0]])
    db = IdentityDatabase([Identity("a", sigma), Identity("z", 0.0)])
    Q = db.process_noise_cov(1.0)
    # Tables I–III print Q(1) = [[Σ/4, Σ/2], [Σ/2, Σ]]
    assert np.array_equal(Q[0], np.block([[sigma / 4, sigma / 2], [sigma / 2, sigma]]))
    assert np.array_equal(Q[1], np.zeros((4, 4)))
    G = _G(0.7, 2)
    assert np.allclose(db.process_noise_cov(0.7)[0], G @ sigma @ G.T, rtol=1e-14, atol=0)
    assert np.array_equal(db.process_noise_cov(0.0), np.zeros((2, 4, 4)))


def test_per_class_values():
    db = _db((1.0, 1.0), (1.0, 1.0), (0.0, 1.0))
    assert db.per_class([0.5, 0.5, 0.9], "p_d").tolist() == [0.5, 0.9]
    with pytest.raises(ValueError, match=r"p_d differs inside identity class 0"):
        db.per_class([0.5, 0.6, 0.9], "p_d")


# ----------------------------------------------------------------------------- one step


@FAST
@given(
    q=noise_levels,
    a=coords,
    v=st.one_of(st.just(0.0), st.floats(0.05, 1.0)),
    dt=st.floats(0.2, 2.0),
    r1=st.tuples(variances, variances, variances),
    r2=st.tuples(variances, variances, variances),
    z1=st.tuples(coords, coords, coords),
    z2=st.tuples(coords, coords, coords),
    attribute_seen=st.booleans(),
)
def test_one_step_likelihood_matches_monte_carlo(q, a, v, dt, r1, r2, z1, z2, attribute_seen):
    """log K of one update equals log ∫ g(x) pred(x) dx, with the prediction sampled
    from the start posterior and the acceleration noise itself (eq. 44).

    Tolerance: 6 standard errors of the Monte Carlo mean (2·10⁵ samples)."""
    db = _db((q, a), (0.0, 0.0))  # the second identity never accelerates
    bank = FilterBank(db, velocity_cov=v)
    R1, R2 = np.diag(r1), np.diag(r2)
    if not attribute_seen:
        R2 = _unmeasure(R2, [2])
    bank.start(0.0, z1, R1)
    before = bank.log_a
    bank.update(dt, z2, R2)
    log_k = bank.log_a - before

    rng = np.random.default_rng(0)
    n = 200_000
    pos = np.asarray(z1[:2]) + rng.standard_normal((n, 2)) * np.sqrt(r1[:2])
    vel = rng.standard_normal((n, 2)) * np.sqrt(v)
    x1 = np.hstack([pos, vel])
    obs = [0, 1, 2] if attribute_seen else [0, 1]
    for c, (qc, ac) in enumerate([(q, a), (0.0, 0.0)]):
        w = rng.standard_normal((n, 2)) * np.sqrt(qc)
        x2 = x1 @ _F(dt, 2).T + w @ _G(dt, 2).T
        zhat = np.hstack([x2[:, :2], np.full((n, 1), ac)])[:, obs]
        log_g = stats.multivariate_normal(np.zeros(len(obs)), R2[np.ix_(obs, obs)]).logpdf(
            np.asarray(z2)[obs] - zhat
        )
        top = log_g.max()
        g = np.exp(log_g - top)
        got = log_k[db.classes[c]]  # identity c (both may be one class)
        assert abs(np.exp(got - top) - g.mean()) <= 6 * g.std() / np.sqrt(n) + 1e-12


def test_one_step_closed_form_zero_noise_zero_velocity():
    """A zero-noise identity with a Dirac initial velocity: the prediction is the start
    position exactly, so K = N(z2; [z1_pos; A], R1_pos ⊕ 0 + R2)."""
    db = _db((0.0, 2.0), (0.0, -1.0))
    bank = FilterBank(db)
    R1 = np.diag([1.0, 2.0, 3.0])
    R2 = np.array([[1.5, 0.2, 0.1], [0.2, 1.0, -0.3], [0.1, -0.3, 2.0]])
    z1, z2 = np.array([1.0, -1.0, 2.5]), np.array([1.4, -0.2, 0.5])
    bank.start(0.0, z1, R1)
    start = bank.log_a
    bank.update(3.0, z2, R2)
    for c, a in enumerate([2.0, -1.0]):
        assert start[c] == pytest.approx(stats.norm(a, np.sqrt(3.0)).logpdf(2.5), abs=1e-13)
        S = R2 + np.diag([1.0, 2.0, 0.0])
        want = stats.multivariate_normal([1.0, -1.0, a], S).logpdf(z2)
        assert bank.log_a[c] - start[c] == pytest.approx(want, abs=1e-12)
    assert np.array_equal(bank.mean[:, 2:], np.zeros((2, 2)))  # velocity stays exactly 0
    assert np.array_equal(bank.cov[:, 2:, :], np.zeros((2, 2, 4)))


# ----------------------------------------------------------------------------- many steps


@FAST
@given(
    q=noise_levels,
    q_off=st.floats(-0.3, 0.3),
    attrs=st.tuples(coords, coords),
    v=st.one_of(st.just(0.0), st.floats(0.05, 1.0)),
    steps=st.lists(st.floats(0.1, 2.0), min_size=1, max_size=5),
    Rs=st.lists(spd(3), min_size=6, max_size=6),
    zs=st.lists(st.tuples(coords, coords, coords), min_size=6, max_size=6),
    seen=st.lists(st.booleans(), min_size=6, max_size=6),
    p_d=st.floats(0.05, 1.0),
)
def test_running_product_is_the_joint_predictive_density(
    q, q_off, attrs, v, steps, Rs, zs, seen, p_d
):
    """Σ log K over start + updates = log p(z_1, …, z_K) of the stacked Gaussian built
    directly from F, Q, H, R (full R correlating position and attribute; the attribute
    unmeasured at some steps), plus K log p_d."""
    sigma_p = np.array([[q, q_off * q], [q_off * q, q]])  # PSD for |q_off| < 1, 0 if q = 0
    db = _db((sigma_p, attrs[0]), (0.0, attrs[1]))
    bank = FilterBank(db, velocity_cov=v * np.eye(2))
    times = np.concatenate([[0.0], np.cumsum(steps)])
    Rs = [R if s else _unmeasure(R, [2]) for R, s in zip(Rs, seen, strict=True)][: times.size]
    zs = [np.asarray(z) for z in zs][: times.size]
    bank.start(times[0], zs[0], Rs[0], p_d=p_d)
    for t, z, R in zip(times[1:], zs[1:], Rs[1:], strict=True):
        bank.update(t, z, R, p_d=p_d)
    for i, (sig, a) in enumerate([(sigma_p, attrs[0]), (np.zeros((2, 2)), attrs[1])]):
        want = _flat_prior_log_evidence(times, zs, Rs, [a], sig, v * np.eye(2))
        want += times.size * np.log(p_d)
        assert bank.log_a[db.classes[i]] == pytest.approx(want, rel=1e-9, abs=1e-9)
    assert bank.log_b == -INF  # p_f = 0: the track is certain to exist


def test_vector_attribute_in_one_dimension():
    """dim = 1 with a 2-vector attribute, one attribute component unmeasured."""
    db = IdentityDatabase([Identity("a", 0.3, [1.0, -2.0]), Identity("b", 0.3, [0.0, 0.0])], dim=1)
    bank = FilterBank(db, velocity_cov=0.5)
    times = np.array([0.0, 1.0, 2.5])
    R = np.array([[2.0, 0.3, 0.0], [0.3, 1.0, 0.2], [0.0, 0.2, 1.5]])
    Rs = [R, _unmeasure(R, [1]), R]
    zs = [np.array([0.5, 0.7, -1.0]), np.array([1.0, np.nan, -2.5]), np.array([2.0, 1.2, -1.5])]
    bank.start(times[0], zs[0], Rs[0])
    for t, z, Rj in zip(times[1:], zs[1:], Rs[1:], strict=True):
        bank.update(t, z, Rj)
    for c, a in enumerate([[1.0, -2.0], [0.0, 0.0]]):
        want = _flat_prior_log_evidence(times, zs, Rs, a, np.array([[0.3]]), np.array([[0.5]]))
        assert bank.log_a[c] == pytest.approx(want, rel=1e-10, abs=1e-10)


# ----------------------------------------------------------------------------- classes


def test_identical_models_give_bitwise_equal_columns():
    db = IdentityDatabase(
        [
            Identity("a", 0.5, 1.0),
            Identity("b", 0.0, 2.0),
            Identity("c", 0.5 * np.eye(2), 1.0),
            Identity("d", 0.5, 1.0 + 1e-6),  # any difference makes another class
        ]
    )
    assert db.classes.tolist() == [0, 1, 0, 2]
    bank = IdentityBank(db, n_hidden=1)
    bank.add_track("x", 0.0, [0.0, 0.0, 1.1], np.eye(3))
    bank.step(1.0, {"x": ([0.2, 0.1, 0.9], np.eye(3))})
    log_A, _, _, cols = bank.log_M()
    full = log_A[:, db.classes]  # one column per identity
    assert np.array_equal(full[:, 0], full[:, 2])
    assert not np.array_equal(full[:, 0], full[:, 3])
    assert cols.tolist() == [2, 1, 1]


@FAST
@given(
    a1=coords,
    a2=coords,
    r_attr=variances,
    zs=st.lists(st.tuples(coords, coords, st.floats(-20.0, 20.0)), min_size=2, max_size=5),
)
def test_attribute_far_from_a_lowers_log_a_by_the_gaussian_log_ratio(a1, a2, r_attr, zs):
    """Kinematic twins with attributes A1, A2 and R not correlating attribute and
    position: log a differs by exactly Σ_k [log N(z_k; A2, r) − log N(z_k; A1, r)]."""
    db = _db((0.4, a1), (0.4, a2))
    bank = FilterBank(db)
    R = np.diag([1.0, 2.0, r_attr])
    bank.start(0.0, zs[0], R)
    for k, z in enumerate(zs[1:], start=1):
        bank.update(float(k), z, R)
    za = np.array([z[2] for z in zs])
    want = np.sum(((za - a1) ** 2 - (za - a2) ** 2) / (2 * r_attr))
    log_a = bank.log_a[db.classes]  # per identity (A1 = A2 is one class)
    got = log_a[1] - log_a[0]
    assert got == pytest.approx(want, rel=1e-10, abs=1e-10 * (1 + np.abs(za).max() ** 2))


@FAST
@given(a1=coords, a2=coords, zs=st.lists(st.tuples(coords, coords, coords), min_size=2))
def test_unmeasured_attribute_leaves_kinematic_twins_equal(a1, a2, zs):
    db = _db((0.4, a1), (0.4, a2))
    bank = FilterBank(db, velocity_cov=0.2)
    R = np.array([[1.0, 0.2, 0.0], [0.2, 1.0, 0.0], [0.0, 0.0, INF]])
    bank.start(0.0, zs[0], R)
    for k, z in enumerate(zs[1:], start=1):
        bank.update(float(k), z, R)
    c = db.classes
    assert bank.log_a[c[0]] == bank.log_a[c[1]]
    assert np.array_equal(bank.mean[c[0]], bank.mean[c[1]])
    assert np.array_equal(bank.cov[c[0]], bank.cov[c[1]])


def test_fully_unmeasured_update_only_predicts_and_scores_p_d():
    db = _db((0.3, 1.0), (0.0, 2.0))
    bank = FilterBank(db, velocity_cov=0.1)
    bank.start(0.0, [0.0, 0.0, 1.5], np.eye(3), p_f=0.1)
    ref = FilterBank(db, velocity_cov=0.1)
    ref.start(0.0, [0.0, 0.0, 1.5], np.eye(3))
    ref.predict(2.0)
    before = bank.log_a
    bank.update(2.0, [np.nan] * 3, [INF] * 3, p_d=0.25, p_f=0.5)
    assert np.allclose(bank.log_a - before, np.log(0.5 + 0.25), rtol=0, atol=1e-15)
    assert np.array_equal(bank.mean, ref.mean) and np.array_equal(bank.cov, ref.cov)
    assert bank.log_b == np.log(0.1) + np.log(0.5)


# ----------------------------------------------------------------------------- false alarms


@FAST
@given(
    p_f=st.lists(st.floats(1e-6, 0.99), min_size=1, max_size=4),
    p_d=st.floats(0.01, 1.0),
    z=st.tuples(coords, coords, coords),
    a=coords,
    q=noise_levels,
)
def test_false_alarms(p_f, p_d, z, a, q):
    """log K = log(p_f + p_d N) (N from a textbook Kalman prediction), log b = Σ log p_f,
    and the moment-matched posterior has the mixture mean."""
    db = _db((q, a), (0.0, 0.0))
    bank = FilterBank(db, velocity_cov=0.3)
    R = np.diag([1.0, 2.0, 0.5])
    bank.start(0.0, [0.0, 0.0, 0.0], R, p_f=p_f[0], p_d=p_d)
    log_b = np.log(p_f[0])
    assert bank.log_b == log_b
    for k, pf in enumerate(p_f, start=1):
        mean, cov, before = bank.mean, bank.cov, bank.log_a
        bank.update(float(k), z, R, p_d=p_d, p_f=pf)
        H = np.hstack([np.eye(2), np.zeros((2, 2))])
        for i, (qc, ac) in enumerate([(q, a), (0.0, 0.0)]):
            c = db.classes[i]
            m = _F(1.0, 2) @ mean[c]
            G = _G(1.0, 2)
            P = _F(1.0, 2) @ cov[c] @ _F(1.0, 2).T + qc * G @ G.T
            S = H @ P @ H.T + R[:2, :2]
            n_pos = stats.multivariate_normal(H @ m, S).logpdf(z[:2])
            n_att = stats.norm(ac, np.sqrt(0.5)).logpdf(z[2])
            want = np.logaddexp(np.log(pf), np.log(p_d) + n_pos + n_att)
            assert bank.log_a[c] - before[c] == pytest.approx(want, rel=1e-9, abs=1e-9)
            gain = P @ H.T @ np.linalg.inv(S)
            w1 = np.exp(np.log(p_d) + n_pos + n_att - want)
            post = (1 - w1) * m + w1 * (m + gain @ (np.asarray(z[:2]) - H @ m))
            assert np.allclose(bank.mean[c], post, rtol=1e-8, atol=1e-8)
        log_b += np.log(pf)
        assert bank.log_b == pytest.approx(log_b, rel=1e-15)
    bank.update(len(p_f) + 1.0, z, R)  # one certain measurement: b = 0 for good
    assert bank.log_b == -INF
    bank.update(len(p_f) + 2.0, z, R, p_f=0.5)
    assert bank.log_b == -INF


# ----------------------------------------------------------------------------- M and mixtures


def test_log_m_layout_hidden_group_and_floor():
    db = _db((0.5, 1.0), (0.5, 1.0), (0.0, 5.0))
    bank = IdentityBank(db, n_hidden=3)
    R = np.diag([1.0, 1.0, 0.01])
    bank.add_track("near", 0.0, [0.0, 0.0, 1.0], R)
    bank.add_track("far", 0.0, [9.0, 9.0, 60.0], R)
    bank.add_track("maybe", 0.0, [5.0, 5.0, 5.0], R, p_f=0.1)
    log_A, log_b, rows, cols = bank.log_M()
    assert log_A.shape == (4, 2) and rows.tolist() == [1, 1, 1, 3] and cols.tolist() == [2, 1]
    assert np.array_equal(log_A[3], [0.0, 0.0])
    assert log_b.tolist() == [-INF, -INF, np.log(0.1), 0.0]
    assert log_A[1, 0] < np.log(1e-100)  # A = 1 at 59/0.1 standard deviations
    assert log_A[2].min() >= np.log(0.1)  # K = p_f + p_d N ≥ p_f
    floored = bank.log_M(floor=1e-100)[0]
    assert np.array_equal(floored, np.maximum(log_A, np.log(1e-100)))
    assert floored[1, 0] == np.log(1e-100)
    bank.n_hidden = 0
    assert bank.log_M()[0].shape == (3, 2) and bank.n_tracks == 3


def test_mixture_matches_moments_by_class():
    db = _db((0.5, 1.0), (0.5, 1.0), (0.0, 5.0))
    bank = FilterBank(db, velocity_cov=0.4)
    bank.start(0.0, [0.0, 0.0, 2.0], np.diag([1.0, 1.0, 2.0]))
    bank.update(1.0, [1.0, 0.5, 3.0], np.diag([1.0, 1.0, 2.0]))
    mean, cov = bank.mixture([0.1, 0.2, 0.5])
    w = np.array([0.3, 0.5]) / 0.8
    m = w @ bank.mean
    d = bank.mean - m
    want = sum(w[c] * (bank.cov[c] + np.outer(d[c], d[c])) for c in range(2))
    assert np.allclose(mean, m) and np.allclose(cov, want)


def test_step_is_all_or_nothing():
    db = _db((0.5, 1.0), (0.0, 2.0))
    bank = IdentityBank(db)
    bank.add_track(0, 0.0, [0.0, 0.0, 1.0], np.eye(3))
    bank.add_track(1, 0.0, [5.0, 5.0, 2.0], np.eye(3))
    before = bank.log_M()
    with pytest.raises(ValueError, match=r"measurements\[1\].*R"):
        bank.step(1.0, {0: ([0.0, 0.0, 1.0], np.eye(3)), 1: ([5.0, 5.0, 2.0], -np.eye(3))})
    for a, b in zip(before, bank.log_M(), strict=True):
        assert np.array_equal(a, b)
    assert bank.tracks[0].time == 0.0


# ----------------------------------------------------------------------------- hostile input

GOOD_R = np.eye(3)


def _started():
    bank = FilterBank(_db((0.5, 1.0), (0.5, 1.0), (0.0, 2.0)))
    bank.start(0.0, [0.0, 0.0, 1.0], GOOD_R)
    return bank


BAD_IDENTITIES = [
    (lambda: Identity("", 1.0), "name"),
    (lambda: Identity(3, 1.0), "name"),
    (lambda: Identity("a", 1j), "process_noise"),
    (lambda: Identity("a", True), "process_noise"),
    (lambda: Identity("a", np.nan), "process_noise"),
    (lambda: Identity("a", -1.0), "process_noise"),
    (lambda: Identity("a", 10**400), "process_noise"),
    (lambda: Identity("a", [[1.0, 2.0], [0.0, 1.0]]), "process_noise"),
    (lambda: Identity("a", [[1.0, 2.0], [2.0, 1.0]]), "process_noise"),
    (lambda: Identity("a", [1.0, 2.0]), "process_noise"),
    (lambda: Identity("a", "1.0"), "process_noise"),
    (lambda: Identity("a", 1.0, 1 + 2j), "attribute"),
    (lambda: Identity("a", 1.0, np.inf), "attribute"),
    (lambda: Identity("a", 1.0, False), "attribute"),
    (lambda: Identity("a", 1.0, [[1.0]]), "attribute"),
    (lambda: Identity("a", 1.0, []), "attribute"),
    (lambda: Identity("a", 1.0, -(10**400)), "attribute"),
    (lambda: Identity("a", 1.0, label=3), "label"),
    (lambda: Identity("a", 1.0, p_d=0.0), "p_d"),
    (lambda: Identity("a", 1.0, p_d=1.5), "p_d"),
    (lambda: Identity("a", 1.0, p_d=np.nan), "p_d"),
    (lambda: Identity("a", 1.0, p_d=True), "p_d"),
    (lambda: IdentityDatabase([]), "identities"),
    (lambda: IdentityDatabase("ab"), "identities"),
    (lambda: IdentityDatabase([1.0]), "identities"),
    (lambda: IdentityDatabase([Identity("a", 1.0), Identity("a", 2.0)]), "name"),
    (lambda: IdentityDatabase([Identity("a", np.eye(3))]), "process_noise"),
    (lambda: IdentityDatabase([Identity("a", 1.0, 1.0), Identity("b", 1.0)]), "attribute"),
    (lambda: IdentityDatabase([Identity("a", 1.0, 1.0), Identity("b", 1.0, [1, 2])]), "attribute"),
    (lambda: IdentityDatabase([Identity("a", 1.0)], dim=4), "dim"),
    (lambda: IdentityDatabase([Identity("a", 1.0)], dim=True), "dim"),
    (lambda: _db((1.0, 1.0)).process_noise_cov(-1.0), "dt"),
    (lambda: _db((1.0, 1.0)).process_noise_cov(1e100), "dt"),
    (lambda: FilterBank("db"), "database"),
    (lambda: FilterBank(_db((1.0, 1.0)), velocity_cov=-1.0), "velocity_cov"),
    (lambda: FilterBank(_db((1.0, 1.0)), velocity_cov=[[1, 2], [2, 1]]), "velocity_cov"),
    (lambda: FilterBank(_db((1.0, 1.0)), velocity_cov=np.nan), "velocity_cov"),
    (lambda: FilterBank(_db((1.0, 1.0))).start(0.0, [0, 0, 1], [INF, 1.0, 1.0]), "R"),
    (lambda: IdentityBank(_db((1.0, 1.0)), n_hidden=-1), "n_hidden"),
    (lambda: IdentityBank(_db((1.0, 1.0)), n_hidden=1.5), "n_hidden"),
    (lambda: IdentityBank(_db((1.0, 1.0)), n_hidden=True), "n_hidden"),
    (lambda: IdentityBank(_db((1.0, 1.0))).step(0.0, {"x": ([0, 0, 0], GOOD_R)}), "measurements"),
    (lambda: IdentityBank(_db((1.0, 1.0))).step(0.0, [([0, 0, 0], GOOD_R)]), "measurements"),
    (lambda: IdentityBank(_db((1.0, 1.0))).log_M(floor=0.0), "floor"),
    (lambda: IdentityBank(_db((1.0, 1.0))).log_M(floor=np.nan), "floor"),
    (lambda: _started().mixture([0.5, 0.5]), "P_row"),
    (lambda: _started().mixture([0.5, -0.5, 0.1]), "P_row"),
    (lambda: _started().mixture([0.0, 0.0, 0.0]), "P_row"),
]


@pytest.mark.parametrize("make, name", BAD_IDENTITIES)
def test_bad_construction_raises_value_error_naming_the_argument(make, name):
    with pytest.raises(ValueError, match=name):
        make()


def test_adding_a_track_twice_is_refused():
    bank = IdentityBank(_db((1.0, 1.0)))
    bank.add_track("x", 0.0, [0.0, 0.0, 1.0], GOOD_R)
    with pytest.raises(ValueError, match="key"):
        bank.add_track("x", 0.0, [0.0, 0.0, 1.0], GOOD_R)
    with pytest.raises(ValueError, match="key"):
        bank.add_track(["unhashable"], 0.0, [0.0, 0.0, 1.0], GOOD_R)


BAD_UPDATES = [
    (dict(t=-1.0), "t"),
    (dict(t=np.nan), "t"),
    (dict(t=1j), "t"),
    (dict(t=True), "t"),
    (dict(t=1e300), "dt"),  # the prediction overflows
    (dict(z=[0.0, 0.0, 1j]), "z"),
    (dict(z=[0.0, 0.0, True]), "z"),
    (dict(z=[0.0, np.nan, 1.0]), "z"),
    (dict(z=[0.0, 0.0]), "attribute"),  # attribute dimension mismatch
    (dict(z=[0.0, 0.0, 1.0, 2.0]), "attribute"),
    (dict(z=[0.0, 0.0, 10**400]), "z"),
    (dict(z="abc"), "z"),
    (dict(R=-np.eye(3)), "R"),
    (dict(R=[[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), "R"),
    (dict(R=[[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), "R"),
    (dict(R=np.zeros((3, 3))), "R"),
    (dict(R=np.full((3, 3), np.nan)), "R"),
    (dict(R=[[1.0, INF, 0.0], [INF, 1.0, 0.0], [0.0, 0.0, 1.0]]), "R"),
    (dict(R=[[1.0, 0.0, 0.5], [0.0, 1.0, 0.0], [0.5, 0.0, INF]]), "R"),
    (dict(R=np.eye(2)), "R"),
    (dict(R=np.eye(3) * 1j), "R"),
    (dict(R=[1.0, 1.0, -INF]), "R"),
    (dict(R=np.eye(3, dtype=bool)), "R"),
    (dict(R=[1.0, 1.0, 10**400]), "R"),
    (dict(R=np.eye(3) * 1e-300), "z, R"),  # S numerically singular
    (dict(z=None), "z"),
    (dict(p_d=0.0), "p_d"),
    (dict(p_d=1.1), "p_d"),
    (dict(p_d=np.nan), "p_d"),
    (dict(p_d=0.5 + 0j), "p_d"),
    (dict(p_d=True), "p_d"),
    (dict(p_d=[0.5, 0.6, 1.0]), "p_d differs inside identity class 0"),
    (dict(p_d=[0.5, 0.5]), "p_d"),
    (dict(p_f=-0.1), "p_f"),
    (dict(p_f=1.0), "p_f"),
    (dict(p_f=np.nan), "p_f"),
    (dict(p_f=[0.1]), "p_f"),
]


@pytest.mark.parametrize("change, name", BAD_UPDATES)
def test_bad_update_raises_and_leaves_the_bank_unchanged(change, name):
    bank = _started()
    bank.update(1.0, [0.1, 0.2, 1.1], GOOD_R, p_f=0.2)
    snapshot = (bank.time, bank.mean, bank.cov, bank.log_a, bank.log_b)
    args = dict(t=2.0, z=[0.0, 0.0, 1.0], R=GOOD_R, p_d=None, p_f=0.0) | change
    t, z, R = args.pop("t"), args.pop("z"), args.pop("R")
    with pytest.raises(ValueError, match=name):
        bank.update(t, z, R, **args)
    after = (bank.time, bank.mean, bank.cov, bank.log_a, bank.log_b)
    for a, b in zip(snapshot, after, strict=True):
        assert np.array_equal(a, b)


def test_bad_predict_leaves_the_bank_unchanged():
    bank = _started()
    mean = bank.mean
    for t in (-1.0, np.nan, 1e300):
        with pytest.raises(ValueError, match="t|dt"):
            bank.predict(t)
    assert np.array_equal(bank.mean, mean) and bank.time == 0.0
    with pytest.raises(RuntimeError, match="start"):
        FilterBank(_db((1.0, 1.0))).update(0.0, [0.0, 0.0, 1.0], GOOD_R)


# ----------------------------------------------------------------------------- batched steps


def _batch_scene(seed):
    """A database with kinematic twins, a never-accelerating identity (its zero velocity
    variance makes its filter covariance singular) and vector attributes, and a random
    measurement generator: R full or diagonal, attribute or a position axis unmeasured."""
    rng = np.random.default_rng(seed)
    db = IdentityDatabase(
        [
            Identity("a", 0.5, [1.0, 0.0]),
            Identity("b", 0.5, [1.0, 0.0]),  # a's twin: one class
            Identity("c", 0.0, [2.0, 1.0]),  # never accelerates
            Identity("d", np.array([[1.0, 0.3], [0.3, 0.5]]), [0.0, -1.0], p_d=0.7),
        ]
    )

    def measurement(first=False):
        L = np.tril(rng.normal(scale=0.4, size=(4, 4)), -1) + np.diag(rng.uniform(0.6, 2.0, 4))
        R = L @ L.T if rng.random() < 0.5 else np.diag(rng.uniform(0.5, 3.0, 4))
        z = rng.normal(scale=3.0, size=4)
        kind = rng.integers(4)
        if kind == 1:  # attribute unmeasured
            R, z[2:] = _unmeasure(R, [2, 3]), np.nan
        elif kind == 2:
            R = _unmeasure(R, [3])
        elif kind == 3 and not first:  # a position axis unmeasured
            R = _unmeasure(R, [1])
        return z, R

    return rng, db, measurement


def _assert_same_bank(got, want):
    assert got.time == want.time and got.log_b == want.log_b
    for name in ("mean", "cov", "log_a"):
        a, b = getattr(got, name), getattr(want, name)
        # the batched Kalman routines may round differently for a batch of one filter
        # (BLAS matrix-vector vs matrix-matrix products): equal to rounding
        assert np.allclose(a, b, rtol=1e-12, atol=1e-12 * (1 + np.abs(b).max())), name


@pytest.mark.parametrize("seed", range(8))
def test_batched_step_equals_per_track_updates(seed):
    """IdentityBank.step on many tracks at once (mixed measured components, correlated R,
    p_f > 0, equal times, tracks left out) = FilterBank.update on each track in turn."""
    rng, db, measurement = _batch_scene(seed)
    velocity_cov = [0.0, 0.2][seed % 2]
    bank = IdentityBank(db, n_hidden=2, velocity_cov=velocity_cov)
    ref = {}
    first = {
        k: (0.5 * rng.integers(3), *measurement(first=True), 0.2 * (k % 3 == 0)) for k in range(9)
    }
    for t0 in sorted({v[0] for v in first.values()}):
        for p_f in (0.0, 0.2):
            batch = {k: (z, R) for k, (t, z, R, pf) in first.items() if t == t0 and pf == p_f}
            bank.add_tracks(t0, batch, p_f=p_f)
    for k, (t0, z, R, p_f) in first.items():
        ref[k] = FilterBank(db, velocity_cov=velocity_cov)
        ref[k].start(t0, z, R, p_f=p_f)
    t = 1.0
    for _ in range(6):
        t += float(rng.choice([0.0, 0.7, 1.0]))  # 0.0: a second measurement at the same time
        listed = {k: measurement() for k in range(9) if rng.random() < 0.7}
        p_f = float(rng.choice([0.0, 0.15]))
        p_d = None if rng.random() < 0.5 else rng.choice([0.5, 0.9], size=4)[[0, 0, 2, 3]]
        before = {k: (b.time, b.mean, b.cov, b.log_a) for k, b in bank.tracks.items()}
        bank.step(t, listed, p_d=p_d, p_f=p_f)
        for k, (z, R) in listed.items():
            ref[k].update(t, z, R, p_d=p_d, p_f=p_f)
        for k, bank_k in bank.tracks.items():
            _assert_same_bank(bank_k, ref[k])
            if k not in listed:  # untouched: not even predicted
                assert bank_k.time == before[k][0]
                for a, b in zip(
                    before[k][1:], (bank_k.mean, bank_k.cov, bank_k.log_a), strict=True
                ):
                    assert np.array_equal(a, b)
    log_A, log_b, rows, _ = bank.log_M()  # rows in the order the tracks were added
    assert np.allclose(log_A[:9], [ref[k].log_a for k in bank.tracks], rtol=1e-12, atol=1e-12)
    assert log_b.tolist() == [ref[k].log_b for k in bank.tracks] + [0.0]
    assert rows.tolist() == [1] * 9 + [2]


def _many_tracks(n=8):
    db = _db((0.5, 1.0), (0.5, 1.0), (0.0, 2.0))
    bank = IdentityBank(db, n_hidden=1)
    bank.add_tracks(0.0, {k: ([5.0 * k, 0.0, 1.0], GOOD_R) for k in range(n)})
    bank.step(1.0, {k: ([5.0 * k, 0.2, 1.1], [1.0, 1.0, INF if k % 2 else 1.0]) for k in range(n)})
    return bank


def _snapshot(bank):
    return {k: (b.time, b.mean, b.cov, b.log_a, b.log_b) for k, b in bank.tracks.items()}


def _assert_unchanged(bank, snapshot):
    assert list(bank.tracks) == list(snapshot)
    for k, b in bank.tracks.items():
        for a, c in zip(snapshot[k], (b.time, b.mean, b.cov, b.log_a, b.log_b), strict=True):
            assert np.array_equal(a, c)


@pytest.mark.parametrize(
    "bad, name",
    [
        (([0.0, 0.0, 1.0], [[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), "symmetric"),
        (([0.0, np.nan, 1.0], GOOD_R), "z"),
        (([0.0, 0.0, 1.0], -GOOD_R), "negative"),
        (([0.0, 0.0, 1.0], GOOD_R * 1e-300), "z, R"),  # S numerically singular: a kalman error
        (([0.0, 0.0, 1.0, 2.0], GOOD_R), "attribute"),
        ("not a pair", "pair"),
    ],
)
def test_step_with_one_bad_track_among_many_changes_nothing(bad, name):
    """The error is the bad track's own (as FilterBank.update raises it), named by its key,
    and no track changes, not even those listed before it."""
    bank = _many_tracks()
    snapshot = _snapshot(bank)
    listed = {k: ([5.0 * k, 0.4, 1.0], GOOD_R) for k in range(8)}
    listed[5] = bad
    with pytest.raises(ValueError, match=name) as err:
        bank.step(2.0, listed, p_f=0.1)
    assert str(err.value).startswith("measurements[5]")
    if isinstance(bad, tuple):
        with pytest.raises(ValueError) as alone:
            bank.tracks[5].update(2.0, *bad, p_f=0.1)
        assert str(err.value) == f"measurements[5]: {alone.value}"
    _assert_unchanged(bank, snapshot)


def test_step_names_the_first_bad_track_in_order():
    bank = _many_tracks()
    snapshot = _snapshot(bank)
    listed = {k: ([5.0 * k, 0.4, 1.0], GOOD_R) for k in (7, 3, 1, 0)}  # mapping order
    listed[3] = ([0.0, 0.0, 1.0], -GOOD_R)
    listed[1] = ([0.0, np.nan, 1.0], GOOD_R)
    with pytest.raises(ValueError, match=r"^measurements\[3\]: R\[0, 0\]"):
        bank.step(2.0, listed)
    with pytest.raises(ValueError, match=r"^measurements\[7\]: p_f"):
        bank.step(2.0, listed, p_f=1.5)  # a shared argument: the first listed track
    bank.tracks[0].update(3.0, [0.0, 0.4, 1.0], GOOD_R)
    snapshot = _snapshot(bank)
    with pytest.raises(ValueError, match=r"^measurements\[0\]: t = 2 is earlier"):
        bank.step(2.0, {k: ([5.0 * k, 0.4, 1.0], GOOD_R) for k in range(8)})
    with pytest.raises(ValueError, match=r"^measurements\['x'\]: no track"):
        bank.step(2.0, {1: ([5.0, 0.4, 1.0], GOOD_R), "x": ([0.0, 0.0, 1.0], GOOD_R)})
    _assert_unchanged(bank, snapshot)
    bank.step(2.0, {})  # nothing listed: nothing checked, nothing changed
    _assert_unchanged(bank, snapshot)


def test_add_tracks_equals_add_track_and_is_all_or_nothing():
    _, db, measurement = _batch_scene(0)
    listed = {k: measurement(first=True) for k in range(6)}
    one, many = IdentityBank(db, velocity_cov=0.3), IdentityBank(db, velocity_cov=0.3)
    for k, (z, R) in listed.items():
        one.add_track(k, 0.5, z, R, p_f=0.1)
    many.add_tracks(0.5, listed, p_f=0.1)
    assert list(many.tracks) == list(range(6))
    for k in listed:
        _assert_same_bank(many.tracks[k], one.tracks[k])
    snapshot = _snapshot(many)
    with pytest.raises(ValueError, match=r"^measurements\[2\]: key 2 is already a track"):
        many.add_tracks(1.0, {"new": listed[0], 2: listed[2]})
    with pytest.raises(ValueError, match=r"^measurements\['new2'\]: R: starting a track needs"):
        many.add_tracks(1.0, {"new": listed[0], "new2": ([0.0, 0.0, 1.0, 1.0], [INF, 1, 1, 1])})
    _assert_unchanged(many, snapshot)


@pytest.mark.parametrize("i, j", [(0, 2), (2, 0)])
def test_a_covariance_linking_an_unmeasured_attribute_is_refused_either_way(i, j):
    db = IdentityDatabase([Identity("a", 1.0, attribute=0.0)])
    R = np.diag([1.0, 1.0, np.inf])
    R[i, j] = 0.5
    with pytest.raises(ValueError, match="links the unmeasured component 2"):
        FilterBank(db).start(0.0, [0.0, 0.0, np.nan], R)
