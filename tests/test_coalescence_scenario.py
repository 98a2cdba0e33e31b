"""The coalescence scenario (jointtrack.scenarios.coalescence): its statistics, the
paper's filter model in ``info``, argument checks, and ``jointtrack run`` on it.

Statistical checks pool many seeds and state their tolerance in standard errors
of the estimate under the scenario's own model (a bug that moves a moment by
more than that fails them).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from jointtrack.cli import app
from jointtrack.experiments.config import scenario_metric_settings
from jointtrack.scenarios import GENERATORS, coalescence, crossing, ncv_matrices, run_name

Q_PAPER = 0.02
MID = 41  # the midpoint step of 81
SEEDS = range(300)


@pytest.fixture(scope="module")
def many():
    return [coalescence(s) for s in SEEDS]


def _same(a, b) -> bool:
    for f in ("truth_ids", "truth_states", "detections", "origins"):
        for x, y in zip(getattr(a, f), getattr(b, f), strict=True):
            if x.shape != y.shape or not np.array_equal(x, y):
                return False
    return np.array_equal(a.times, b.times)


def _axis_samples(states) -> np.ndarray:
    """(pos, vel) pairs of both axes pooled: (2·N, 2) from (N, 4) [x, y, vx, vy] rows
    (the two axes are independent and identically distributed)."""
    s = np.asarray(states)
    return np.concatenate([s[:, [0, 2]], s[:, [1, 3]]], axis=0)


# ----------------------------------------------------------------------------- structure


def test_registered_and_named():
    assert GENERATORS["coalescence"] is coalescence
    assert run_name("coalescence") == "coalescence"
    sc = coalescence(0)
    assert sc.name == "coalescence" and sc.n_scans == 81 and sc.dim == 2
    np.testing.assert_array_equal(sc.times, np.arange(1.0, 82.0))  # step k at time k
    np.testing.assert_array_equal(sc.region, [[0.0, 300.0], [0.0, 300.0]])
    assert sc.p_d == 0.9 and sc.clutter_rate == 10.0 and sc.process_noise == Q_PAPER
    assert sc.clutter_density == pytest.approx(10.0 / 300.0**2)
    np.testing.assert_array_equal(sc.R, np.eye(2))


def test_target_0_is_gone_from_the_midpoint_step(many):
    for sc in many[:20]:
        for k in range(81):
            step = k + 1
            want = [0, 1, 2, 3] if step < MID else [1, 2, 3]
            assert sc.truth_ids[k].tolist() == want, (sc.seed, step)
            assert sc.truth_states[k].shape == (len(want), 4)
            if step >= MID:
                assert not np.any(sc.origins[k] == 0)  # a dead target is never detected
        assert sc.info["death_step"] == MID and sc.info["midpoint_step"] == MID


def test_midpoint_states_are_drawn_around_150_150(many):
    # the survivors at step 41 are the midpoint draws N([150, 150, 0, 0], 0.1 I)
    X = np.concatenate([sc.truth_states[MID - 1] for sc in many])  # (900, 4)
    n = X.shape[0]
    centre = np.array([150.0, 150.0, 0.0, 0.0])
    assert np.all(np.abs(X - centre) < 6 * math.sqrt(0.1))  # 6σ: P(miss) ≈ 7·10⁻⁶ over all
    se_mean = math.sqrt(0.1 / n)
    np.testing.assert_allclose(X.mean(axis=0), centre, atol=5 * se_mean)
    se_var = 0.1 * math.sqrt(2 / (n - 1))
    np.testing.assert_allclose(X.var(axis=0, ddof=1), 0.1, atol=5 * se_var)
    C = np.cov(X.T)
    off = C[~np.eye(4, dtype=bool)]
    assert np.all(np.abs(off) < 5 * 0.1 / math.sqrt(n))  # independent components


def _moment_check(samples, P):
    """Sample covariance of (pos, vel) pairs against P, each entry within 5 standard
    errors (Var of a sample covariance entry ≈ (P_ii P_jj + P_ij²) / n, Gaussian)."""
    n = samples.shape[0]
    S = np.cov(samples.T)
    se = np.sqrt((np.outer(np.diag(P), np.diag(P)) + P**2) / n)
    assert np.all(np.abs(S - P) < 5 * se), (S, P, se)


def test_forward_and_noisy_backward_spread(many):
    """Step 81 follows x_{k+1} = F x_k + w; step 1 the authors' noisy reverse step
    x_{k-1} = F⁻¹(x_k + w). Their covariances after 40 steps from 0.1 I differ
    from the deterministic backward propagation's (velocity variance 0.9, not 0.1)."""
    F, Q = ncv_matrices(1.0, Q_PAPER, 1)
    F_inv = np.linalg.inv(F)
    P_fwd = 0.1 * np.eye(2)
    P_bwd = 0.1 * np.eye(2)
    for _ in range(MID - 1):
        P_fwd = F @ P_fwd @ F.T + Q
        P_bwd = F_inv @ (P_bwd + Q) @ F_inv.T
    assert P_bwd[1, 1] == pytest.approx(0.1 + 40 * Q_PAPER)
    last = _axis_samples(np.concatenate([sc.truth_states[-1] for sc in many]))
    first = _axis_samples(np.concatenate([sc.truth_states[0] for sc in many]))
    _moment_check(last - [150.0, 0.0], P_fwd)
    _moment_check(first - [150.0, 0.0], P_bwd)
    # the reverse step's position–velocity correlation is negative (the target comes
    # from where its velocity points away from); the forward one's positive
    assert np.cov(first.T)[0, 1] < 0 < np.cov(last.T)[0, 1]


def test_consecutive_states_follow_the_ncv_model(many):
    """Every step's innovation x_{k+1} − F x_k is N(0, Q) on both sides of the midpoint
    (a reversed or shifted join of the two halves would break it at the midpoint)."""
    F, Q = ncv_matrices(1.0, Q_PAPER, 2)
    for steps in ([MID - 2], [MID - 1], range(1, MID - 1), range(MID, 80)):
        W = []
        for sc in many:
            for k in steps:  # 0-based: step k+1 → k+2, survivors only
                a, b = sc.truth_states[k], sc.truth_states[k + 1]
                a = a[np.isin(sc.truth_ids[k], sc.truth_ids[k + 1])]
                W.append(b - a @ F.T)
        W = np.concatenate(W)
        S = np.cov(W.T)
        se = np.sqrt((np.outer(np.diag(Q), np.diag(Q)) + Q**2) / W.shape[0])
        assert np.all(np.abs(S - Q) < 5 * se), (list(steps)[:3], S, Q)
        assert np.all(np.abs(W.mean(axis=0)) < 5 * np.sqrt(np.diag(Q) / W.shape[0]))


# ----------------------------------------------------------------------------- detections


def test_clutter_is_poisson_10_uniform_on_the_square(many):
    counts = np.array([np.sum(o < 0) for sc in many for o in sc.origins])
    n = counts.size  # 300 seeds × 81 scans
    # Poisson(10): mean and variance 10; SE of the mean √(10/n) ≈ 0.02, tolerance 5 SE
    assert abs(counts.mean() - 10.0) < 5 * math.sqrt(10.0 / n)
    # SE of the sample variance of a Poisson(λ): √((λ + 2λ²)/n) ≈ 0.093
    assert abs(counts.var(ddof=1) - 10.0) < 5 * math.sqrt((10.0 + 200.0) / n)
    Z = np.concatenate([sc.detections[k][sc.is_clutter(k)] for sc in many for k in range(81)])
    assert np.all((Z >= 0.0) & (Z <= 300.0))
    # uniform on [0, 300]: mean 150, variance 300²/12 per axis
    se = 300.0 / math.sqrt(12 * Z.shape[0])
    np.testing.assert_allclose(Z.mean(axis=0), 150.0, atol=5 * se)
    np.testing.assert_allclose(Z.var(axis=0), 300.0**2 / 12, rtol=0.02)


def test_target_detections_have_p_d_and_unit_noise(many):
    hits = trials = 0
    err = []
    for sc in many:
        for k in range(81):
            o, Z, ids = sc.origins[k], sc.detections[k], sc.truth_ids[k]
            trials += ids.size
            hits += int(np.sum(o >= 0))
            for j in np.flatnonzero(o >= 0):
                err.append(Z[j] - sc.truth_states[k][ids == o[j], :2][0])
    p = hits / trials
    assert abs(p - 0.9) < 5 * math.sqrt(0.09 / trials)
    E = np.asarray(err)
    n = E.shape[0]
    np.testing.assert_allclose(E.mean(axis=0), 0.0, atol=5 / math.sqrt(n))
    np.testing.assert_allclose(np.cov(E.T), np.eye(2), atol=5 * math.sqrt(2 / n))


# ----------------------------------------------------------------------------- seeds, info


def test_seeds_reproduce():
    a, b, c = coalescence(7), coalescence(7), coalescence(8)
    assert _same(a, b) and not _same(a, c)
    g = coalescence(np.random.default_rng(7))
    assert _same(a, g) and a.seed == 7 and g.seed is None
    assert _same(coalescence(), coalescence(0))  # the default seed is 0


def test_info_is_the_papers_filter_model_and_plain_json():
    sc = coalescence(3)
    info = json.loads(json.dumps(sc.info))  # plain JSON values only
    assert info == sc.info
    cov = np.diag([150.0**2, 150.0**2, 1.0, 1.0]).tolist()
    assert info["birth"] == {"weight": 0.005, "mean": [100.0, 100.0, 0.0, 0.0], "cov": cov}
    assert info["prior"] == {"lambda": 3.0, "mean": [100.0, 100.0, 0.0, 0.0], "cov": cov}
    assert info["p_s"] == 0.99
    assert info["gospa"] == {"c": 10.0, "p": 2.0, "alpha": 2.0}
    assert info["midpoint_mean"] == [150.0, 150.0, 0.0, 0.0]
    assert scenario_metric_settings(sc) == {"c": 10.0, "p": 2.0}
    assert scenario_metric_settings(crossing(0, n_scans=3)) == {}


def test_keywords_change_what_they_say():
    sc = coalescence(1, n_steps=11, dt=2.0, p_d=0.5, clutter_rate=0.0, sigma=3.0)
    np.testing.assert_array_equal(sc.times, 2.0 * np.arange(1, 12))
    assert [ids.size for ids in sc.truth_ids] == [4] * 5 + [3] * 6  # target 0 gone at step 6
    assert sc.info["midpoint_step"] == 6 and sc.info["midpoint_time"] == 12.0
    assert all(np.all(o >= 0) for o in sc.origins)  # no clutter
    np.testing.assert_array_equal(sc.R, 9.0 * np.eye(2))
    still = coalescence(1, n_steps=5, process_noise=0.0)
    F, _ = ncv_matrices(1.0, 0.0, 2)
    for k in range(4):  # q = 0: exact NCV motion through the midpoint, both ways
        a = still.truth_states[k][np.isin(still.truth_ids[k], still.truth_ids[k + 1])]
        np.testing.assert_allclose(still.truth_states[k + 1], a @ F.T, atol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"seed": -1}, "seed"),
        ({"seed": 1.5}, "seed"),
        ({"seed": True}, "seed"),
        ({"n_steps": 80}, "n_steps"),
        ({"n_steps": 1}, "n_steps"),
        ({"n_steps": True}, "n_steps"),
        ({"n_steps": 81.0}, "n_steps"),
        ({"p_d": 0.0}, "p_d"),
        ({"p_d": 1.5}, "p_d"),
        ({"p_d": True}, "p_d"),
        ({"p_d": 1j}, "p_d"),
        ({"clutter_rate": -1.0}, "clutter_rate"),
        ({"clutter_rate": math.nan}, "clutter_rate"),
        ({"clutter_rate": "ten"}, "clutter_rate"),
        ({"clutter_rate": 10**400}, "clutter_rate"),
        ({"clutter_rate": 10**5000}, "clutter_rate"),  # past int → str's digit limit too
        ({"clutter_rate": np.bool_(True)}, "clutter_rate"),
        ({"process_noise": -0.02}, "process_noise"),
        ({"sigma": 0.0}, "sigma"),
        ({"dt": math.inf}, "dt"),
    ],
)
def test_bad_arguments_name_themselves(kwargs, name):
    with pytest.raises(ValueError, match=name):
        coalescence(**kwargs)


# ----------------------------------------------------------------------------- jointtrack run


def test_cli_run_on_coalescence(tmp_path):
    (tmp_path / "small.toml").write_text("[scenario]\nn_steps = 11\n")
    out = tmp_path / "o"
    runner = CliRunner()
    r = runner.invoke(
        app,
        ["run", "--no-progress", "--scenario", "coalescence", "--config",
         str(tmp_path / "small.toml"), "--out", str(out)],
    )  # fmt: skip
    assert r.exit_code == 0, r.output
    for name in ("tracks.csv", "metrics.json", "scene.png", "gospa.png"):
        assert (out / name).is_file(), name
    m = json.loads((out / "metrics.json").read_text())
    assert m["source"]["scenario"] == "coalescence" and m["n_scans"] == 11
    assert m["start"] == "nothing"  # the paper's filter starts from its Poisson prior
    assert m["gospa"]["c"] == 10.0 and m["gospa"]["p"] == 2.0 and m["ospa"]["c"] == 10.0
    assert m["tracks"]["gate"] == 10.0 and m["tracks"]["n_truths"] == 4
    t = m["tracker"]
    assert t["clutter_density"] == pytest.approx(10.0 / 300.0**2)
    assert t["measurement_noise"] == 1.0 and t["process_noise"] == Q_PAPER and t["p_d"] == 0.9
    # [metrics] still wins over the scenario's cut-off
    (tmp_path / "c7.toml").write_text("[scenario]\nn_steps = 5\n[metrics]\nc = 7.0\n")
    r = runner.invoke(
        app,
        ["run", "--no-progress", "--scenario", "coalescence", "--config",
         str(tmp_path / "c7.toml"), "--out", str(tmp_path / "c7")],
    )  # fmt: skip
    assert r.exit_code == 0, r.output
    assert json.loads((tmp_path / "c7" / "metrics.json").read_text())["gospa"]["c"] == 7.0
