"""The tracker keeps its promises under faults: atomic steps and safe state files."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import zipfile

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import jointtrack.trackers.base as base_module
import jointtrack.trackers.jpda as jpda_module
from jointtrack.errors import ExactLimitError
from jointtrack.scenarios import crossing
from jointtrack.trackers import JPDATracker, StateFileError, TrackerConfig
from jointtrack.trackers.state_io import read_state, write_state
from state_checks import assert_same_state


def _scenario():
    return crossing(seed=3)


def _config(**kw):
    sc = _scenario()
    base = dict(
        process_noise=max(sc.process_noise, 0.05),
        measurement_noise=float(sc.R[0, 0]),
        p_d=sc.p_d,
        clutter_density=sc.clutter_density,
        max_speed=15.0,
    )
    base.update(kw)
    return TrackerConfig(**base)


def _state_equal(a: JPDATracker, b: JPDATracker) -> None:
    sa, sb = a.state_dict(), b.state_dict()
    assert sa.keys() == sb.keys()
    for k in sa:
        if isinstance(sa[k], np.ndarray):
            np.testing.assert_array_equal(sa[k], sb[k], err_msg=k)
        else:
            assert sa[k] == sb[k], k


def _warm_tracker(n_scans=12, **kw):
    sc = _scenario()
    trk = JPDATracker(_config(**kw))
    for k in range(n_scans):
        trk.step(sc.times[k], sc.detections[k])
    return trk, sc


# every stage of a scan, as the name the tracker module (or the shared tracker layer,
# jointtrack.trackers.base) looks it up by
STAGES = [
    "predict",
    "predict_measurement",
    "gate_pairs",
    "clusters",
    "likelihood_ratio_pairs",
    "cluster_pair_marginals",
    "budgeted_marginals",
    "pda_pairs_update",
    "existence_update",
    "merge_duplicates",
    "pair_returns",
]


class Injected(RuntimeError):
    pass


@pytest.mark.parametrize("stage", STAGES + ["_track_logic", "_initiate", "_cluster_marginals"])
def test_failing_stage_leaves_state_unchanged_and_retry_matches(stage, monkeypatch):
    k = 25  # a scan whose confirmed tracks form a two-track cluster (every stage runs)
    # pair_returns is two-point initiation's stage; the default is one-point
    kw = {"initiation": "two-point"} if stage == "pair_returns" else {}
    trk, sc = _warm_tracker(k, **kw)
    reference, _ = _warm_tracker(k, **kw)
    snapshot = trk.state_dict()

    def boom(*args, **kwargs):
        raise Injected(stage)

    if stage.startswith("_"):
        monkeypatch.setattr(JPDATracker, stage, boom)
    else:
        module = jpda_module if hasattr(jpda_module, stage) else base_module
        monkeypatch.setattr(module, stage, boom)
    with pytest.raises(Injected):
        trk.step(sc.times[k], sc.detections[k])
    monkeypatch.undo()
    after = trk.state_dict()
    assert_same_state(after, snapshot)
    # the retried scan gives exactly what a tracker that never failed gives
    r1 = trk.step(sc.times[k], sc.detections[k])
    r2 = reference.step(sc.times[k], sc.detections[k])
    np.testing.assert_array_equal(r1.x, r2.x)
    np.testing.assert_array_equal(r1.P, r2.P)
    _state_equal(trk, reference)


def test_keyboard_interrupt_mid_step_is_atomic(monkeypatch):
    trk, sc = _warm_tracker()
    snapshot = trk.state_dict()

    def interrupt(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(jpda_module, "pda_pairs_update", interrupt)
    with pytest.raises(KeyboardInterrupt):
        trk.step(sc.times[12], sc.detections[12])
    np.testing.assert_array_equal(trk.P, snapshot["P"])
    assert trk.n_scans == snapshot["n_scans"]


def test_exact_refusal_falls_back_to_the_approximation(monkeypatch):
    import jointtrack.association.budget as budget_module

    real = budget_module.marginals

    def refusing(L, miss, method="exact", **kw):
        if method == "exact":
            raise ExactLimitError("the exact DP needs 2^40 states (injected)")
        return real(L, miss, method=method, **kw)

    trk = JPDATracker(TrackerConfig(clutter_density=1e-4, approximation="lbp"))
    trk.start_tracks(np.array([[0.0, 0, 1, 0], [5.0, 0, 1, 0]]), np.diag([100.0, 100, 1, 1]))
    monkeypatch.setattr(budget_module, "marginals", refusing)
    r = trk.step(1.0, np.array([[1.0, 0], [6.0, 0]]))
    assert r.cluster_methods == ["lbp"]
    assert r.n_fallbacks == 1 and r.cluster_fallbacks[0].startswith("refused: ")
    assert trk.n_scans == 1


def test_size_fallback_is_counted():
    trk = JPDATracker(TrackerConfig(clutter_density=1e-4, exact_max_tracks=1))
    trk.start_tracks(np.array([[0.0, 0, 1, 0], [5.0, 0, 1, 0]]), np.diag([100.0, 100, 1, 1]))
    r = trk.step(1.0, np.array([[1.0, 0], [6.0, 0]]))
    assert r.cluster_fallbacks == ["exact_max_tracks"] and r.n_fallbacks == 1


# ---------------------------------------------------------------- models and miss weight


def test_miss_model_sets_the_no_detection_weight(monkeypatch):
    seen = {}
    real = base_module.budgeted_marginals

    def spy(L, miss, **kw):
        seen["miss"] = np.array(miss)
        return real(L, miss, **kw)

    monkeypatch.setattr(base_module, "budgeted_marginals", spy)
    x0 = np.array([[0.0, 0, 1, 0], [5.0, 0, 1, 0]])
    for model, expected in (("1-pd*pg", 1 - 0.9 * 0.99), ("1-pd", 1 - 0.9)):
        cfg = TrackerConfig(clutter_density=1e-4, p_d=0.9, p_g=0.99, miss_model=model)
        trk = JPDATracker(cfg)
        trk.start_tracks(x0, np.diag([100.0, 100, 1, 1]), existence=1.0)
        trk.step(1.0, np.array([[1.0, 0], [6.0, 0]]))
        np.testing.assert_allclose(seen["miss"], expected, rtol=1e-12)
    with pytest.raises(ValueError, match="miss_model"):
        TrackerConfig(miss_model="1-pg")


def test_model_objects_replace_the_config_strings():
    from jointtrack.models import ConstantVelocity, LinearPosition

    sc = _scenario()
    cfg = _config()
    default = JPDATracker(cfg)
    explicit = JPDATracker(
        cfg,
        motion=ConstantVelocity(dim=2, q=cfg.process_noise),
        sensor=LinearPosition(2, cfg.measurement_noise, state_dim=4),
    )
    for k in range(15):
        a = default.step(sc.times[k], sc.detections[k])
        b = explicit.step(sc.times[k], sc.detections[k])
        np.testing.assert_array_equal(a.x, b.x)
    # a noisier user model changes the result
    noisy = JPDATracker(cfg, motion=ConstantVelocity(dim=2, q=50.0))
    for k in range(15):
        c = noisy.step(sc.times[k], sc.detections[k])
    assert not np.array_equal(c.P, a.P)
    with pytest.raises(ValueError, match="motion model .* has no 'state_dim'"):
        JPDATracker(cfg, motion=object())
    with pytest.raises(ValueError, match="sensor model"):
        JPDATracker(cfg, sensor=object())


# ---------------------------------------------------------------- state files


@settings(max_examples=15, deadline=None)
@given(
    split=st.integers(1, 30),
    association=st.sampled_from(["exact", "mcmc", "lbp"]),
    existence=st.booleans(),
)
def test_save_load_step_is_bit_identical(tmp_path_factory, split, association, existence):
    sc = _scenario()
    cfg = _config(association=association, exact_max_tracks=1, existence=existence)
    a = JPDATracker(cfg)
    for k in range(split):
        a.step(sc.times[k], sc.detections[k])
    path = a.save(tmp_path_factory.mktemp("s") / "state.npz")
    b = JPDATracker.load(path)
    _state_equal(a, b)
    for k in range(split, min(split + 8, len(sc.times))):
        ra = a.step(sc.times[k], sc.detections[k])
        rb = b.step(sc.times[k], sc.detections[k])
        np.testing.assert_array_equal(ra.x, rb.x)
        np.testing.assert_array_equal(ra.ids, rb.ids)
    _state_equal(a, b)


@pytest.fixture
def good_state(tmp_path):
    trk, _ = _warm_tracker()
    return trk, trk.save(tmp_path / "good.npz")


def test_truncations_are_refused(good_state, tmp_path):
    _, path = good_state
    data = path.read_bytes()
    for cut in sorted({0, 1, 3, 10, 100, len(data) // 3, len(data) // 2, len(data) - 1}):
        bad = tmp_path / f"cut{cut}.npz"
        bad.write_bytes(data[:cut])
        with pytest.raises(ValueError, match=str(bad.name)):
            JPDATracker.load(bad)


def test_byte_flips_are_refused_or_harmless(good_state, tmp_path):
    trk, path = good_state
    data = bytearray(path.read_bytes())
    rng = np.random.default_rng(0)
    refused = 0
    for _ in range(300):
        flipped = bytearray(data)
        for pos in rng.integers(0, len(data), size=rng.integers(1, 4)):
            flipped[pos] ^= int(rng.integers(1, 256))
        bad = tmp_path / "flip.npz"
        bad.write_bytes(bytes(flipped))
        try:
            loaded = JPDATracker.load(bad)
        except ValueError as exc:
            assert "flip.npz" in str(exc)
            refused += 1
            continue
        # a flip outside the payload (zip metadata that is never read) changes nothing
        _state_equal(loaded, trk)
    assert refused > 250


def _rewrite(path, out, mutate_arrays=None, mutate_header=None):
    arrays, config, scalars, rng = read_state(path)
    if mutate_arrays:
        mutate_arrays(arrays)
    header = {"config": config, "scalars": scalars, "rng": rng}
    if mutate_header:
        mutate_header(header)
    write_state(out, arrays, header["config"], header["scalars"], header["rng"])
    return out


def _drop(name):
    return lambda a: a.pop(name)


def _nan_x(a):
    a["x"] = a["x"].copy()
    a["x"][0, 0] = np.nan


def _non_psd(a):
    a["P"] = a["P"].copy()
    a["P"][0] = -np.eye(a["P"].shape[1])


def _asym(a):
    a["P"] = a["P"].copy()
    a["P"][0, 0, 1] += 1.0


def _bad_existence(a):
    a["existence"] = a["existence"].copy()
    a["existence"][0] = 1.5


def _float_ids(a):
    a["ids"] = a["ids"].astype(float)


def _dup_ids(a):
    a["ids"] = a["ids"].copy()
    a["ids"][1] = a["ids"][0]


def _short_P(a):
    a["P"] = a["P"][:-1]


@pytest.mark.parametrize(
    "mutate, match",
    [
        (_drop("x"), "missing field 'x'"),
        (_drop("seed_covs"), "missing field 'seed_covs'"),
        (_nan_x, "non-finite"),
        (_non_psd, "positive definite"),
        (_asym, "not symmetric"),
        (_bad_existence, r"outside \[0, 1\]"),
        (_float_ids, "'ids' has dtype"),
        (_dup_ids, "distinct"),
        (_short_P, "'P' has shape"),
    ],
)
def test_invalid_values_are_refused(good_state, tmp_path, mutate, match):
    _, path = good_state
    bad = _rewrite(path, tmp_path / "bad.npz", mutate_arrays=mutate)
    with pytest.raises(ValueError, match=match):
        JPDATracker.load(bad)


@pytest.mark.parametrize(
    "mutate, match",
    [
        (lambda h: h["config"].update(p_d=7.0), "invalid tracker configuration"),
        (lambda h: h["config"].update(bogus=1), "invalid tracker configuration"),
        (lambda h: h["scalars"].update(next_id=-3), "next_id"),
        (lambda h: h["scalars"].update(time="yesterday"), "time"),
        (lambda h: h["rng"].update(state="x"), "random-generator state"),
    ],
)
def test_invalid_header_values_are_refused(good_state, tmp_path, mutate, match):
    _, path = good_state
    bad = _rewrite(path, tmp_path / "bad.npz", mutate_header=mutate)
    with pytest.raises(ValueError, match=match):
        JPDATracker.load(bad)


def test_edited_payload_fails_the_checksum(good_state, tmp_path):
    _, path = good_state
    with np.load(path) as npz:
        arrays = {k: npz[k] for k in npz.files}
    arrays["x"] = arrays["x"] + 1.0  # keep the old header (and its digest)
    bad = tmp_path / "edited.npz"
    np.savez(bad, **arrays)
    with pytest.raises(ValueError, match="checksum"):
        JPDATracker.load(bad)


def test_wrong_version_and_foreign_archives(good_state, tmp_path):
    import json

    _, path = good_state
    with np.load(path) as npz:
        arrays = {k: npz[k] for k in npz.files}
    header = json.loads(arrays["__header__"].tobytes())
    header["version"] = 99
    arrays["__header__"] = np.frombuffer(json.dumps(header).encode(), np.uint8)
    np.savez(tmp_path / "v99.npz", **arrays)
    with pytest.raises(ValueError, match="version 99 is not supported"):
        JPDATracker.load(tmp_path / "v99.npz")
    np.savez(tmp_path / "other.npz", a=np.arange(3))
    with pytest.raises(ValueError, match="no header"):
        JPDATracker.load(tmp_path / "other.npz")
    with zipfile.ZipFile(tmp_path / "zip.npz", "w") as zf:
        zf.writestr("readme.txt", "hello")
    with pytest.raises(ValueError, match="zip.npz"):
        JPDATracker.load(tmp_path / "zip.npz")


class _Exploit:
    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


def test_pickle_that_runs_code_is_refused_and_nothing_runs(tmp_path):
    marker = tmp_path / "pwned"
    exploit = _Exploit()
    exploit.marker = marker
    bad = tmp_path / "evil.npz"
    bad.write_bytes(pickle.dumps({"config": {}, "payload": exploit}))
    with pytest.raises(StateFileError, match="pickle"):
        JPDATracker.load(bad)
    assert not marker.exists()


def test_old_pickle_checkpoint_is_refused_with_reason(tmp_path):
    old = tmp_path / "old.pkl"
    old.write_bytes(pickle.dumps({"version": 2, "config": {}}, protocol=4))
    with pytest.raises(ValueError, match="arbitrary code"):
        JPDATracker.load(old)


def test_save_is_atomic_under_kill(tmp_path):
    """A process killed while saving leaves the previous state file intact."""
    trk, _ = _warm_tracker()
    path = trk.save(tmp_path / "state.npz")
    before = path.read_bytes()
    code = f"""
import os, signal, numpy as np
import jointtrack.trackers.state_io as s
from jointtrack.trackers import JPDATracker
trk = JPDATracker.load({str(path)!r})
real = np.savez
def dying(fh, **arrays):
    real(fh, **arrays)
    os.kill(os.getpid(), signal.SIGKILL)   # after writing the temp file, before rename
s.np.savez = dying
trk.save({str(path)!r})
"""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, timeout=120)
    assert proc.returncode != 0
    assert path.read_bytes() == before
    JPDATracker.load(path)
