"""JPDA/JIPDA with an interacting multiple model (``motion = "imm"``): configuration,
a coordinated turn held with one id, equivalence with the CV tracker, saved state."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from jointtrack.trackers import JPDATracker, StateFileError, TrackerConfig
from jointtrack.trackers import jpda as jpda_module
from jointtrack.trackers.config import check_field
from jointtrack.trackers.pmbm import PMBTracker
from jointtrack.trackers.pmbm_config import PMBMConfig
from jointtrack.trackers.state_io import read_state, write_state
from state_checks import assert_same_state

# ----------------------------------------------------------------------------- scenario

SPEED, TURN_DEG, STRAIGHT, SCANS, SIGMA = 30.0, 5.0, 10, 45, 10.0
CLUTTER_PER_SCAN, HALF_WIDTH = 5.0, 2000.0


def _turn(seed: int):
    """One target: 10 s straight at 30 m/s, then a 5°/s coordinated turn (radius
    344 m); P_D 0.9, σ = 10 m, 5 clutter returns per scan on a 4 km square."""
    rng = np.random.default_rng(seed)
    w = np.deg2rad(TURN_DEG)
    radius = SPEED / w
    scans = []
    for k in range(SCANS):
        t = float(k)
        if k < STRAIGHT:
            p = np.array([SPEED * t, 0.0])
        else:
            th = w * (t - STRAIGHT)
            p = np.array([SPEED * STRAIGHT + radius * np.sin(th), radius * (1 - np.cos(th))])
        z = [p + rng.normal(size=2) * SIGMA] if rng.random() < 0.9 else []
        n_clutter = rng.poisson(CLUTTER_PER_SCAN)
        z += list(rng.uniform(-HALF_WIDTH, HALF_WIDTH, size=(n_clutter, 2)))
        scans.append((t, np.array(z).reshape(-1, 2)))
    return scans


def _config(**kw):
    base = dict(
        clutter_density=CLUTTER_PER_SCAN / (2 * HALF_WIDTH) ** 2,
        measurement_noise=SIGMA**2,
        process_noise=0.5,
    )
    base.update(kw)
    return TrackerConfig(**base)


def _run(trk, scans):
    for t, z in scans:
        res = trk.step(t, z)
    return res


@pytest.mark.parametrize("seed", [0, 1])
def test_five_degree_turn_cv_fragments_imm_holds_one_id(seed):
    """The reason for the IMM: a CV JIPDA loses the 5°/s turn every few scans and
    starts new ids (4+ on these runs); the CV + CT IMM JIPDA follows it with one id
    reported at ≥ 85% of the scans, its CT mode the likelier one in the turn."""
    scans = _turn(seed)
    cv = JPDATracker(_config(motion="cv"))
    _run(cv, scans)
    imm = JPDATracker(_config(motion="imm"))
    res = _run(imm, scans)
    h_cv, h_imm = cv.history(), imm.history()
    assert len(h_cv.track_ids) >= 4, h_cv.track_ids
    assert len(h_imm.track_ids) == 1, h_imm.track_ids
    assert (h_imm.track_id == h_imm.track_ids[0]).sum() >= 0.85 * SCANS
    assert res.mode_names == ("cv", "ct")
    assert res.mode_probabilities.shape == (1, 2)
    assert res.mode_probabilities[0, 1] > 0.5  # in the turn: CT likelier
    np.testing.assert_allclose(res.mode_probabilities.sum(axis=1), 1.0, rtol=1e-14)
    # the report keeps the usual layout: [x, y, vx, vy]
    assert res.x.shape == (1, 4) and res.P.shape == (1, 4, 4) and h_imm.state_dim == 4
    # the history holds the mode probabilities too, as mode_<name> columns
    assert h_imm.mode_names == ("cv", "ct")
    np.testing.assert_array_equal(h_imm.mode_probabilities[-1], res.mode_probabilities[0])
    table = h_imm.to_dict()
    assert list(table)[-2:] == ["mode_cv", "mode_ct"]
    back = type(h_imm).from_dict(table)
    np.testing.assert_array_equal(back.mode_probabilities, h_imm.mode_probabilities)
    assert h_cv.mode_names == () and h_cv.mode_probabilities is None


def test_single_cv_mode_imm_is_the_cv_tracker():
    """An IMM with the one mode "cv" is the CV JIPDA: same ids, states to 1e-9."""
    scans = _turn(3)[:30]
    cv = JPDATracker(_config(motion="cv"))
    imm = JPDATracker(_config(motion="imm", imm_modes=["cv"], imm_switching=1.0))
    for t, z in scans:
        a, b = cv.step(t, z), imm.step(t, z)
        np.testing.assert_array_equal(a.ids, b.ids)
        np.testing.assert_allclose(b.x, a.x, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(b.P, a.P, rtol=1e-9, atol=1e-9)
        np.testing.assert_array_equal(b.mode_probabilities, np.ones((len(b.ids), 1)))
    np.testing.assert_array_equal(cv.ids, imm.ids)
    np.testing.assert_allclose(cv.existence, imm.existence, rtol=1e-9)


def test_cv_ca_ct_modes_and_mn_logic_run():
    """Three modes (CV, CT, CA) with M-of-N logic: finite, normalised mode probabilities."""
    trk = JPDATracker(
        _config(
            motion="imm",
            imm_modes=["cv", "ct", "ca"],
            imm_switching=[[0.9, 0.05, 0.05], [0.05, 0.9, 0.05], [0.1, 0.1, 0.8]],
            imm_initial=[0.5, 0.25, 0.25],
            existence=False,
        )
    )
    res = _run(trk, _turn(4)[:25])
    assert len(res.ids) >= 1
    assert trk.mode_x.shape[1:] == (3, 7)  # [x, y, vx, vy, ax, ay, ω]
    assert np.isfinite(trk.mode_log_prob).all()
    np.testing.assert_allclose(np.exp(trk.mode_log_prob).sum(axis=1), 1.0, rtol=1e-12)


# ----------------------------------------------------------------------------- state


def _warm(k=20):
    trk = JPDATracker(_config(motion="imm"))
    scans = _turn(5)
    _run(trk, scans[:k])
    return trk, scans


def test_save_load_continues_identically(tmp_path):
    trk, scans = _warm()
    path = trk.save(tmp_path / "imm.npz")
    loaded = JPDATracker.load(path)
    assert_same_state(loaded.state_dict(), trk.state_dict())
    for t, z in scans[20:30]:
        a, b = trk.step(t, z), loaded.step(t, z)
        np.testing.assert_array_equal(a.x, b.x)
        np.testing.assert_array_equal(a.mode_probabilities, b.mode_probabilities)


def _rewrite(path, out, mutate):
    arrays, config, scalars, rng = read_state(path)
    mutate(arrays, config)
    write_state(out, arrays, config, scalars, rng)
    return out


def _set(name, fn):
    def mutate(arrays, config):
        arrays[name] = fn(arrays[name].copy())

    return mutate


@pytest.mark.parametrize(
    "mutate, match",
    [
        (_set("mode_log_prob", lambda a: a + 0.5), "mode_log_prob"),
        (_set("mode_log_prob", lambda a: np.where(a < 0, np.nan, a)), "mode_log_prob"),
        (_set("mode_x", lambda a: a[:, :1]), "mode_x"),
        (_set("mode_x", lambda a: a + 1.0), "outside its model"),  # CV mode's ω ≠ 0
        (_set("mode_P", lambda a: a * -1.0), "mode_P"),
        (lambda arrays, config: arrays.pop("mode_P"), "missing field 'mode_P'"),
        (lambda arrays, config: config.update(imm_modes=["cv", "ca"]), "mode_x"),
    ],
)
def test_damaged_mode_fields_are_refused_naming_them(tmp_path, mutate, match):
    trk, _ = _warm()
    path = trk.save(tmp_path / "imm.npz")
    bad = _rewrite(path, tmp_path / "bad.npz", mutate)
    with pytest.raises(StateFileError, match=match):
        JPDATracker.load(bad)


def test_version_4_state_loads_with_zero_modes(tmp_path):
    """A state written before the IMM (version 4, no mode fields, no IMM settings)
    loads and continues as the CV tracker it was."""
    import json

    trk = JPDATracker(_config(motion="cv"))
    scans = _turn(6)
    _run(trk, scans[:10])
    path = trk.save(tmp_path / "cv.npz")
    arrays, config, scalars, rng = read_state(path)
    for name in ("mode_x", "mode_P", "mode_log_prob"):
        arrays.pop(name)
    for key in ("imm_modes", "imm_switching", "imm_initial", "turn_rate_std", "max_turn_rate"):
        config.pop(key)
    from jointtrack.trackers import state_io

    old = state_io.VERSION
    try:
        state_io.VERSION = 4
        write_state(tmp_path / "v4.npz", arrays, config, scalars, rng)
    finally:
        state_io.VERSION = old
    with np.load(tmp_path / "v4.npz") as npz:
        assert json.loads(npz["__header__"].tobytes())["version"] == 4
    loaded = JPDATracker.load(tmp_path / "v4.npz")
    assert loaded.mode_x.shape == (len(loaded.ids), 0, 0)
    for t, z in scans[10:15]:
        np.testing.assert_array_equal(trk.step(t, z).x, loaded.step(t, z).x)


@pytest.mark.parametrize(
    "stage", ["imm_predict", "imm_pda_pairs_update", "imm_pair_log_likelihoods"]
)
def test_failing_imm_stage_leaves_state_unchanged(stage, monkeypatch):
    trk, scans = _warm()
    reference, _ = _warm()
    snapshot = trk.state_dict()

    def boom(*args, **kwargs):
        raise RuntimeError(stage)

    monkeypatch.setattr(jpda_module, stage, boom)
    with pytest.raises(RuntimeError, match=stage):
        trk.step(*scans[20])
    monkeypatch.undo()
    assert_same_state(trk.state_dict(), snapshot)
    a, b = trk.step(*scans[20]), reference.step(*scans[20])
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.mode_probabilities, b.mode_probabilities)


# ----------------------------------------------------------------------------- configuration


@pytest.mark.parametrize(
    "kw, match",
    [
        ({"imm_modes": ["cv", "turn"]}, "imm_modes: unknown mode name 'turn'"),
        ({"imm_modes": []}, "imm_modes must be a non-empty list"),
        ({"imm_modes": ["cv", "cv"]}, "imm_modes .*each at most once"),
        ({"imm_modes": "cv"}, "imm_modes must be"),
        ({"imm_switching": [[0.9, 0.2], [0.1, 0.9]]}, "imm_switching is not a stochastic"),
        ({"imm_switching": [[1.0, 0.0], [1.0, 0.0]]}, "imm_switching: column 1 is all zero"),
        ({"imm_switching": [[0.9, 0.1, 0.0]]}, "imm_switching must be"),
        ({"imm_switching": [[1.0]]}, "imm_switching must be a 2 × 2 matrix"),
        ({"imm_switching": [[1.5, -0.5], [0.1, 0.9]]}, "imm_switching must be"),
        ({"imm_switching": 0.0}, "imm_switching must be"),
        ({"imm_switching": True}, "imm_switching must be"),
        ({"imm_switching": 1j}, "imm_switching must be"),
        ({"imm_initial": [1.0, 0.0]}, "imm_initial must be .*probability 0"),
        ({"imm_initial": [0.5, -0.5]}, "imm_initial must be"),
        ({"imm_initial": [0.7, 0.7]}, "imm_initial must sum to 1"),
        ({"imm_initial": [1.0]}, "imm_initial must have one probability per mode"),
        ({"turn_rate_std": -0.1}, "turn_rate_std must be"),
        ({"max_turn_rate": 0.0}, "max_turn_rate must be"),
        ({"imm_modes": ["cv", "ct"], "dim": 3}, "imm_modes: the coordinated-turn mode 'ct' is 2-D"),
        ({"motion": "turn"}, "motion must be one of"),
    ],
)
@pytest.mark.parametrize("config", [TrackerConfig, PMBMConfig])  # one validation, shared
def test_bad_imm_settings_name_the_key(kw, match, config):
    with pytest.raises(ValueError, match=match):
        config(**{"motion": "imm", **kw})


def test_imm_settings_unused_without_imm_are_not_cross_checked():
    # a 3-D CV tracker keeps working with the default imm_modes (which include 'ct')
    assert TrackerConfig(dim=3, motion="cv").imm_modes == ("cv", "ct")


def test_stay_probability_and_toml_round_trip():
    text = """
    motion = "imm"
    imm_modes = ["cv", "ct", "ca"]
    imm_switching = 0.9
    imm_initial = [0.5, 0.3, 0.2]
    turn_rate_std = 0.05
    max_turn_rate = 0.3
    """
    cfg = TrackerConfig.from_dict(tomllib.loads(text))
    np.testing.assert_allclose(
        cfg.imm_switching_matrix(),
        [[0.9, 0.05, 0.05], [0.05, 0.9, 0.05], [0.05, 0.05, 0.9]],
        rtol=4e-16,
    )
    assert TrackerConfig.from_dict(cfg.to_dict(), complete=True) == cfg
    matrix = TrackerConfig.from_dict(
        tomllib.loads('motion = "imm"\nimm_switching = [[0.9, 0.1], [0.2, 0.8]]')
    )
    assert matrix.imm_switching == ((0.9, 0.1), (0.2, 0.8))
    assert TrackerConfig.from_dict(matrix.to_dict(), complete=True) == matrix
    assert check_field("imm_modes", ["ct"]) == ("ct",)


def test_pmb_takes_imm():
    """Since issue 32 the PMB/PMBM trackers take motion = "imm" (tests/test_pmbm_imm.py)."""
    trk = PMBTracker(PMBMConfig(motion="imm", clutter_density=1e-6))
    res = trk.step(0.0, np.zeros((1, 2)))
    assert trk.mode_log_prob.shape == (len(trk.ids), 2) and res.mode_names == ("cv", "ct")


# ----------------------------------------------------------------------------- run outputs


def test_run_writes_mode_columns_and_resumes_exactly(tmp_path):
    """``jointtrack run`` with motion = "imm": tracks.csv has mode_cv, mode_ct (each
    row summing to 1); a run stopped at scan 8 and resumed from its checkpoint
    writes the same file as an uninterrupted run."""
    from jointtrack.experiments.run import run_scenario
    from jointtrack.io import read_tracks

    kw = dict(seed=2, scenario_kwargs={"n_scans": 16}, plots=False)
    run_scenario("crossing", {"motion": "imm"}, tmp_path / "full", **kw)
    cols = read_tracks(tmp_path / "full" / "tracks.csv")
    assert list(cols)[-2:] == ["mode_cv", "mode_ct"]
    assert len(cols["time"]) > 0
    np.testing.assert_allclose(cols["mode_cv"] + cols["mode_ct"], 1.0, rtol=1e-12)
    ck = tmp_path / "ck.npz"
    part = tmp_path / "part"
    run_scenario("crossing", {"motion": "imm"}, part, checkpoint=ck, max_scans=8, **kw)
    run_scenario("crossing", {"motion": "imm"}, part, resume=ck, checkpoint=ck, **kw)
    assert (part / "tracks.csv").read_bytes() == (tmp_path / "full" / "tracks.csv").read_bytes()


def test_imm_modes_object_of_another_dimension_is_refused():
    from jointtrack.filters import IMMModes
    from jointtrack.models import ConstantVelocity

    modes = IMMModes([ConstantVelocity(dim=2)], [[1.0]])
    with pytest.raises(ValueError, match="IMM modes are 2-D, but dim = 3"):
        JPDATracker(TrackerConfig(dim=3, motion="imm", imm_modes=["cv"]), motion=modes)


@pytest.mark.parametrize("tracker", ["pmb", "pmbm"])
def test_pmb_run_with_imm_writes_mode_columns_and_resumes_exactly(tmp_path, tracker):
    """``jointtrack run --tracker pmb|pmbm`` with motion = "imm": the mode columns, and a
    run stopped at scan 6 and resumed writes the uninterrupted run's tracks file."""
    from jointtrack.experiments.run import run_scenario
    from jointtrack.io import read_tracks

    kw = dict(seed=2, scenario_kwargs={"n_scans": 12}, plots=False, tracker=tracker)
    run_scenario("crossing", {"motion": "imm"}, tmp_path / "full", **kw)
    cols = read_tracks(tmp_path / "full" / "tracks.csv")
    assert list(cols)[-2:] == ["mode_cv", "mode_ct"] and len(cols["time"]) > 0
    np.testing.assert_allclose(cols["mode_cv"] + cols["mode_ct"], 1.0, rtol=1e-12)
    ck, part = tmp_path / "ck.npz", tmp_path / "part"
    run_scenario("crossing", {"motion": "imm"}, part, checkpoint=ck, max_scans=6, **kw)
    run_scenario("crossing", {"motion": "imm"}, part, resume=ck, checkpoint=ck, **kw)
    assert (part / "tracks.csv").read_bytes() == (tmp_path / "full" / "tracks.csv").read_bytes()
