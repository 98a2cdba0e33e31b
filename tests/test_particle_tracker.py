"""The particle JPDA tracker (Streit's mixed-derivative weights) and ``jointtrack run``'s use of it.

Small particle counts and a shortened crossing keep the file well under a minute.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.special import logsumexp
from typer.testing import CliRunner

import jointtrack.trackers.particle as particle_mod
from cli_checks import one_line_error
from jointtrack.cli import app
from jointtrack.experiments.config import steady_state_covariance
from jointtrack.io import read_tracks
from jointtrack.saddle import jpda_coefficients, log_mixed_derivative
from jointtrack.scenarios import crossing
from jointtrack.trackers.particle import (
    ParticleConfig,
    ParticleDegeneracyError,
    ParticleJPDATracker,
    available_weight_methods,
    jpda_particle_log_weights,
    systematic_resample,
)

SADDLE_METHODS = [m for m in available_weight_methods() if m != "exact"]


def _normalised(log_w):
    return np.exp(log_w - logsumexp(log_w, axis=-1, keepdims=True))


def _tracker(sc, method="exact", particles=300, seed=0, **over):
    cfg = ParticleConfig(
        particles=particles,
        weights=method,
        process_noise=sc.process_noise,
        measurement_noise=100.0,
        p_d=sc.p_d,
        p_g=over.pop("p_g", 0.99),
        clutter_density=sc.clutter_density,
        seed=seed,
        **over,
    )
    trk = ParticleJPDATracker(cfg)
    trk.start(sc.truth_states[0], steady_state_covariance(1.0, cfg.process_noise, 100.0, 2))
    return trk


def _random_problem(seed, N=3, L=25, M=4):
    """Clutter, P_D and log-likelihoods of a small scan; some pairs out of reach (−inf)."""
    rng = np.random.default_rng(seed)
    log_a = np.log(rng.uniform(0.05, 0.5, M))
    pd = rng.uniform(0.6, 0.95, (N, L))
    log_lik = np.log(rng.random((N, L, M)))
    log_lik[rng.random((N, L, M)) < 0.3] = -np.inf
    return log_a, pd, log_lik


def _full_coefficients(log_a, pd, log_lik, n):
    """(a0, a, F) of target n on the whole scan (no scaling, no components)."""
    N = pd.shape[0]
    lik = np.exp(log_lik)
    others = [j for j in range(N) if j != n]
    return jpda_coefficients(
        np.exp(log_a), pd[n], lik[n], [pd[j] for j in others], [lik[j] for j in others]
    )


# ----------------------------------------------------------------------------- tracking


@pytest.mark.parametrize("method", ["exact", *SADDLE_METHODS])
def test_keeps_both_tracks_through_the_crossing(method):
    # 31 scans: the targets cross at t = 15 and are 2·10·15·sin(22.5°) ≈ 115 m apart at the end
    for seed in (0, 1, 2):
        sc = crossing(seed=seed, n_scans=31)
        trk = _tracker(sc, method, seed=seed)
        for k, t in enumerate(sc.times):
            res = trk.step(t, sc.detections[k])
        err = np.linalg.norm(res.x[:, :2] - sc.truth_states[-1][:, :2], axis=1)
        # within 3σ (σ = 10 m) of its own target: no swap, no loss
        assert (err < 30.0).all(), (method, seed, err)
        assert res.ids.tolist() == [1, 2]


def test_bootstrap_filter_with_one_target_no_clutter_and_pd_1():
    # I = a·(1 − P_D) + P_D·p(y|x) = p(y|x) exactly: the weights are the plain likelihood
    cfg = ParticleConfig(particles=200, p_d=1.0, clutter_density=1e-300, seed=4)
    trk = ParticleJPDATracker(cfg)
    trk.start([[0.0, 0.0, 5.0, 1.0]], np.diag([100.0, 100.0, 4.0, 4.0]))
    R = cfg.measurement_covariance()
    for t in range(4):
        z = np.array([[5.0 * t + 3.0, t - 2.0]])
        res = trk.step(float(t), z)
        d = z[0] - res.particles[0, :, :2]
        log_lik = -0.5 * np.einsum("li,ij,lj->l", d, np.linalg.inv(R), d)
        np.testing.assert_allclose(res.weights[0], _normalised(log_lik), rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_exact_weights_from_one_core_call_equal_per_particle_derivatives(seed):
    log_a, pd, log_lik = _random_problem(seed)
    got = jpda_particle_log_weights(log_a, pd, log_lik, "exact").log_weights
    for n in range(pd.shape[0]):
        a0, a, F = _full_coefficients(log_a, pd, log_lik, n)
        ref = np.array([log_mixed_derivative(a0, a, F[l], "exact") for l in range(len(F))])
        # column scaling and components change each row by a constant only
        np.testing.assert_allclose(_normalised(got[n]), _normalised(ref), rtol=1e-10, atol=1e-14)


@pytest.mark.parametrize("method", SADDLE_METHODS)
def test_batched_saddle_equals_per_particle_saddle(method):
    log_a, pd, log_lik = _random_problem(7)
    got = jpda_particle_log_weights(log_a, pd, log_lik, method).log_weights
    for n in range(pd.shape[0]):
        a0, a, F = _full_coefficients(log_a, pd, log_lik, n)
        batched = log_mixed_derivative(a0, a, F, method)
        one = np.array([log_mixed_derivative(a0, a, F[l], method) for l in range(len(F))])
        np.testing.assert_allclose(batched, one, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(_normalised(got[n]), _normalised(one), rtol=1e-8, atol=1e-14)


def test_state_dependent_pd_and_gating_close_to_one_change_nothing():
    sc = crossing(seed=3, n_scans=4)
    base = _tracker(sc, p_g=1.0)
    same = ParticleJPDATracker(base.config, p_d=lambda x: np.full(x.shape[:-1], sc.p_d))
    same.start(sc.truth_states[0], steady_state_covariance(1.0, sc.process_noise, 100.0, 2))
    gated = _tracker(sc, p_g=1.0 - 1e-12)  # γ ≈ 55: cuts only likelihoods below e^{-27}
    for k, t in enumerate(sc.times):
        r0, r1, r2 = (trk.step(t, sc.detections[k]) for trk in (base, same, gated))
        np.testing.assert_array_equal(r0.particles, r1.particles)
        np.testing.assert_allclose(r1.weights, r0.weights, rtol=1e-12, atol=1e-300)
        np.testing.assert_allclose(r2.weights, r0.weights, rtol=1e-9, atol=1e-12)


def test_reproducible_with_a_seed():
    sc = crossing(seed=5, n_scans=6)
    runs = []
    for seed in (11, 11, 12):
        trk = _tracker(sc, seed=seed, particles=100)
        scans = zip(sc.times, sc.detections, strict=True)
        runs.append(np.stack([trk.step(t, z).x for t, z in scans]))
    np.testing.assert_array_equal(runs[0], runs[1])
    assert not np.array_equal(runs[0], runs[2])


# ----------------------------------------------------------------------------- resampling


def test_systematic_resampling_is_unbiased_and_keeps_the_count():
    rng = np.random.default_rng(0)
    w = np.array([0.31, 0.0, 0.05, 0.19, 0.2, 0.001, 0.249])
    L = w.size
    reps = 20_000
    counts = np.zeros((reps, L))
    for r in range(reps):
        idx = systematic_resample(w, rng)
        assert idx.shape == (L,)
        counts[r] = np.bincount(idx, minlength=L)
    assert (counts.sum(axis=1) == L).all()
    # each particle is kept ⌊L w⌋ or ⌊L w⌋ + 1 times; a zero weight never
    floor = np.floor(L * w)
    assert ((counts == floor) | (counts == floor + 1)).all()
    assert (counts[:, 1] == 0).all()
    # E[count] = L w: the frequency of the extra copy is the fractional part
    se = np.sqrt(0.25 / reps)
    np.testing.assert_allclose(counts.mean(axis=0), L * w, atol=5 * se)
    # one row per target, each its own uniform draw
    many = systematic_resample(np.tile(w, (3, 1)), rng)
    assert many.shape == (3, L) and (np.diff(many, axis=1) >= 0).all()


def test_resampling_refuses_bad_weights():
    rng = np.random.default_rng(0)
    for bad in ([0.5, 0.6], [1.5, -0.5], [np.nan, 1.0], np.zeros((2, 0))):
        with pytest.raises(ValueError):
            systematic_resample(bad, rng)


# ----------------------------------------------------------------------------- hostile input


@pytest.mark.parametrize("bad", [0, -3, 1.5, True, "10", None])
def test_particles_must_be_an_integer_at_least_1(bad):
    with pytest.raises(ValueError, match="particles"):
        ParticleConfig(particles=bad, clutter_density=1e-4)


@pytest.mark.parametrize("bad", ["bogus", "Exact", None, 3])
def test_unknown_weights_method(bad):
    with pytest.raises(ValueError, match="weights"):
        ParticleConfig(weights=bad, clutter_density=1e-4)
    with pytest.raises(ValueError, match="weights must be one of"):
        jpda_particle_log_weights(np.zeros(1), np.full((1, 2), 0.5), np.zeros((1, 2, 1)), bad)


def test_saddle_corrected_is_used_by_name_or_refused():
    if "saddle-corrected" in available_weight_methods():
        ParticleJPDATracker(ParticleConfig(weights="saddle-corrected", clutter_density=1e-4))
    else:
        with pytest.raises(ValueError, match="does not provide"):
            ParticleJPDATracker(ParticleConfig(weights="saddle-corrected", clutter_density=1e-4))


def test_hostile_measurements_and_starts():
    trk = ParticleJPDATracker(ParticleConfig(particles=20, clutter_density=1e-4))
    with pytest.raises(ValueError, match="no targets"):
        trk.step(0.0, np.zeros((1, 2)))
    with pytest.raises(ValueError, match="complex"):
        trk.start(np.zeros((1, 4)) + 1j, np.eye(4))
    with pytest.raises(ValueError, match="x0"):
        trk.start(np.zeros((1, 3)), np.eye(4))
    with pytest.raises(ValueError, match="positive definite"):
        trk.start(np.zeros((1, 4)), -np.eye(4))
    with pytest.raises(ValueError, match="finite"):
        trk.start(np.full((1, 4), np.nan), np.eye(4))
    trk.start(np.zeros((2, 4)), np.eye(4))
    for z, match in (
        (np.array([[1.0 + 2.0j, 0.0]]), "complex"),
        (np.array([[np.nan, 0.0]]), "non-finite"),
        (np.array([[np.inf, 0.0]]), "non-finite"),
        (np.zeros((2, 3)), "shape"),
        (np.zeros(2), "shape"),
        ([[1.0, 2.0], [3.0]], "measurements"),
        ("1,2", "measurements"),
    ):
        with pytest.raises(ValueError, match=match):
            trk.step(1.0, z)
    for t in (np.nan, np.inf, "1", None):
        with pytest.raises(ValueError, match="scan time"):
            trk.step(t, np.zeros((0, 2)))
    trk.step(1.0, np.zeros((0, 2)))
    with pytest.raises(ValueError, match="increase"):
        trk.step(1.0, np.zeros((0, 2)))


def test_hostile_models_and_clutter():
    with pytest.raises(ValueError, match="clutter"):
        ParticleJPDATracker(ParticleConfig(particles=10))  # no clutter intensity at all
    for bad in (np.nan, 0.0, -1.0, 2.0):
        with pytest.raises(ValueError, match="p_d"):
            ParticleConfig(p_d=bad, clutter_density=1e-4)
    cfg = ParticleConfig(particles=10, clutter_density=1e-4)
    for p_d, match in ((lambda x: 1.5, "p_d"), (lambda x: np.ones(3), "p_d")):
        trk = ParticleJPDATracker(cfg, p_d=p_d)
        trk.start(np.zeros((2, 4)), np.eye(4))
        with pytest.raises(ValueError, match=match):
            trk.step(0.0, np.zeros((1, 2)))
    trk = ParticleJPDATracker(cfg, clutter=lambda z: -np.ones(len(z)))
    trk.start(np.zeros((1, 4)), np.eye(4))
    with pytest.raises(ValueError, match="clutter"):
        trk.step(0.0, np.zeros((1, 2)))


def test_pd_one_and_no_reachable_measurement_is_a_lost_track():
    trk = ParticleJPDATracker(ParticleConfig(particles=50, p_d=1.0, p_g=0.99, clutter_density=1e-4))
    trk.start(np.zeros((1, 4)), np.eye(4))
    before = trk.state_dict()
    with pytest.raises(ParticleDegeneracyError, match="target 0"):
        trk.step(0.0, np.array([[1e4, 1e4]]))
    _assert_same_state(trk.state_dict(), before)


# ----------------------------------------------------------------------------- atomic step


def _assert_same_state(a, b):
    assert a.keys() == b.keys()
    np.testing.assert_array_equal(a["particles"], b["particles"])
    np.testing.assert_array_equal(a["ids"], b["ids"])
    assert (a["time"], a["n_scans"], a["rng"]) == (b["time"], b["n_scans"], b["rng"])


def test_a_failing_step_leaves_the_state_unchanged(monkeypatch):
    sc = crossing(seed=2, n_scans=5)
    trk, twin = _tracker(sc, particles=100), _tracker(sc, particles=100)
    for k in range(2):
        trk.step(sc.times[k], sc.detections[k])
        twin.step(sc.times[k], sc.detections[k])
    before = trk.state_dict()
    calls = {"n": 0}
    real = particle_mod.jpda_log_weights

    def fail_on_second_target(*args):
        calls["n"] += 1
        if calls["n"] == 2:  # after the prediction drew noise and target 1 was weighted
            raise RuntimeError("injected failure")
        return real(*args)

    monkeypatch.setattr(particle_mod, "jpda_log_weights", fail_on_second_target)
    with pytest.raises(RuntimeError, match="injected"):
        trk.step(sc.times[2], sc.detections[2])
    assert calls["n"] == 2
    _assert_same_state(trk.state_dict(), before)
    monkeypatch.setattr(particle_mod, "jpda_log_weights", real)
    # the retried scan continues exactly as a tracker that never failed
    for k in range(2, 5):
        r, r_twin = (
            trk.step(sc.times[k], sc.detections[k]),
            twin.step(sc.times[k], sc.detections[k]),
        )
        np.testing.assert_array_equal(r.x, r_twin.x)
    _assert_same_state(trk.state_dict(), twin.state_dict())


def test_an_interrupt_in_a_user_function_leaves_the_state_unchanged():
    sc = crossing(seed=2, n_scans=3)
    state = {"raise": False}

    def p_d(x):
        if state["raise"]:
            raise KeyboardInterrupt
        return np.full(x.shape[:-1], 0.9)

    trk = ParticleJPDATracker(_tracker(sc, particles=50).config, p_d=p_d)
    trk.start(sc.truth_states[0], 100.0 * np.eye(4))
    trk.step(sc.times[0], sc.detections[0])
    before = trk.state_dict()
    state["raise"] = True
    with pytest.raises(KeyboardInterrupt):
        trk.step(sc.times[1], sc.detections[1])
    _assert_same_state(trk.state_dict(), before)


# ----------------------------------------------------------------------------- jointtrack run

runner = CliRunner()


def _run(*args):
    return runner.invoke(app, ["run", "--no-progress", *map(str, args)])


def test_cli_particle_run_writes_the_outputs(tmp_path):
    out = tmp_path / "o"
    r = _run(
        "--tracker",
        "particle",
        "--weights",
        "saddle",
        "--scenario",
        "crossing",
        "--max-scans",
        "5",
        "--out",
        out,
    )
    assert r.exit_code == 0, r.output
    for name in ("tracks.csv", "metrics.json", "scene.png", "gospa.png"):
        assert (out / name).is_file(), name
    m = json.loads((out / "metrics.json").read_text(encoding="utf-8"))
    assert m["tracker"]["kind"] == "particle" and m["tracker"]["weights"] == "saddle"
    assert m["particle"]["particles"] == 1000 and m["n_scans"] == 5
    assert m["start"] == "truth" and "association" not in m
    assert np.isfinite(m["gospa"]["mean"]) and np.isfinite(m["ospa"]["mean"])
    assert m["tracks"]["n_truths_tracked"] == 2
    tr = read_tracks(out / "tracks.csv")
    assert sorted(set(tr["track_id"].tolist())) == [1, 2] and len(tr["time"]) == 10


def test_cli_particle_run_from_a_config_file(tmp_path):
    cfg = tmp_path / "p.toml"
    cfg.write_text(
        '[tracker]\nkind = "particle"\nparticles = 50\nseed = 3\n[scenario]\nn_scans = 4\n',
        encoding="utf-8",
    )
    out = tmp_path / "o"
    r = _run("--config", cfg, "--out", out)  # Bojilov's five targets
    assert r.exit_code == 0, r.output
    m = json.loads((out / "metrics.json").read_text(encoding="utf-8"))
    assert m["tracker"]["particles"] == 50 and m["tracker"]["weights"] == "exact"
    assert m["tracker"]["seed"] == 3 and m["tracks"]["n_truths_tracked"] == 5


@pytest.mark.parametrize(
    ("args", "needles"),
    [
        (["--weights", "saddle"], ["--weights", "particle tracker only"]),
        (["--particles", "10"], ["--particles", "particle tracker only"]),
        (["--tracker", "jpda", "--weights", "exact"], ["--tracker jpda"]),
        (["--tracker", "kalman"], ["--tracker must be jpda or jipda or pmb or pmbm or particle"]),
        (["--tracker", "particle", "--weights", "fast"], ["--weights must be one of"]),
        (["--tracker", "particle", "--particles", "0"], ["--particles", "≥ 1"]),
        (["--tracker", "particle", "--scenario", "many"], ["born or die"]),
        (["--tracker", "particle", "--start-from", "nothing"], ["--start-from nothing"]),
        (["--tracker", "particle", "--checkpoint", "ck.npz"], ["--checkpoint", "no checkpoints"]),
        (["--tracker", "particle", "--checkpoint-every", "2"], ["--checkpoint-every"]),
        (["--tracker", "particle", "--resume", "ck.npz"], ["--resume", "no checkpoints"]),
    ],
)
def test_cli_refuses_options_that_make_no_sense_together(tmp_path, args, needles):
    r = _run(*args, "--out", tmp_path / "o")
    one_line_error(r, *needles)
    assert not (tmp_path / "o" / "tracks.csv").exists()


def test_cli_refuses_kalman_settings_and_detections_for_the_particle_tracker(tmp_path):
    cfg = tmp_path / "p.toml"
    cfg.write_text('[tracker]\nkind = "particle"\nassociation = "lbp"\n', encoding="utf-8")
    one_line_error(_run("--config", cfg, "--out", tmp_path / "o"), "association", "Kalman")
    cfg.write_text('[tracker]\nkind = "particle"\nclutter_density = "estimate"\n', encoding="utf-8")
    one_line_error(_run("--config", cfg, "--out", tmp_path / "o"), "estimate")
    cfg.write_text('[tracker]\nweights = "saddle"\n', encoding="utf-8")
    one_line_error(_run("--config", cfg, "--out", tmp_path / "o"), "weights", "particle")
    dets = tmp_path / "d.csv"
    dets.write_text("time,x,y\n0,1,2\n", encoding="utf-8")
    one_line_error(
        _run("--tracker", "particle", "--detections", dets, "--out", tmp_path / "o"),
        "--detections",
    )
