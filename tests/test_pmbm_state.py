"""PMB and PMBM trackers keep their promises under faults, as the JPDA tracker does.

* a step is atomic: an exception in any stage leaves the state unchanged, and
  the retried scan gives exactly what a tracker that never failed gives;
* save → load continues identically (bit-identical results and state);
* damaged, truncated, edited, foreign, wrong-version or wrong-kind files and
  values a tracker cannot hold (existence 1.5, hypothesis index out of range,
  a covariance that is not SPD, missing fields, …) raise
  :class:`~jointtrack.trackers.StateFileError` (a ValueError) naming the file;
* a process running a PMBM tracker that saves its state every scan, killed
  with SIGKILL at a random moment, resumes from the file to the final
  estimates of an uninterrupted run.
"""

from __future__ import annotations

import copy
import functools
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import jointtrack.trackers.base as base_module
import jointtrack.trackers.pmbm as pmbm_module
from jointtrack.scenarios import crossing
from jointtrack.trackers import JPDATracker, StateFileError, TrackerConfig
from jointtrack.trackers.pmbm import PMBMConfig, PMBMTracker, PMBTracker
from jointtrack.trackers.state_io import read_state, write_state
from state_checks import assert_same_state

KINDS = [PMBTracker, PMBMTracker]


def _scenario():
    return crossing(seed=3)


def _config(**kw):
    sc = _scenario()
    base = dict(
        process_noise=0.05,
        measurement_noise=float(sc.R[0, 0]),
        p_d=sc.p_d,
        clutter_density=sc.clutter_density,
        max_speed=15.0,
        birth_density=1e-6,
    )
    base.update(kw)
    return PMBMConfig(**base)


@functools.cache
def _warm_cached(kind, n_scans):
    sc = _scenario()
    trk = kind(_config())
    for k in range(n_scans):
        trk.step(sc.times[k], sc.detections[k])
    return trk, sc


def _warm(kind, n_scans=12):
    """A tracker after ``n_scans`` scans of the crossing (a private copy: computed once)."""
    trk, sc = _warm_cached(kind, n_scans)
    return copy.deepcopy(trk), sc


def _state_equal(a, b) -> None:
    sa, sb = a.state_dict(), b.state_dict()
    assert sa.keys() == sb.keys()
    for k in sa:
        if isinstance(sa[k], np.ndarray):
            np.testing.assert_array_equal(sa[k], sb[k], err_msg=k)
        else:
            assert sa[k] == sb[k], k


def _results_equal(ra, rb) -> None:
    np.testing.assert_array_equal(ra.ids, rb.ids)
    np.testing.assert_array_equal(ra.x, rb.x)
    np.testing.assert_array_equal(ra.P, rb.P)
    np.testing.assert_array_equal(ra.existence, rb.existence)


class Injected(RuntimeError):
    pass


# every stage of a scan, as the name the tracker module (or the shared layer) looks up
COMMON = ["predict", "gate_pairs", "predict_measurement", "likelihood_ratio_pairs",
          "moment_match", "prune_and_merge", "_poisson_detection", "_thin_and_prune_poisson",
          "_predict_poisson", "_pair_weights"]  # fmt: skip
STAGES = [(PMBTracker, s) for s in COMMON + ["existence_update", "pda_pairs_update",
          "cluster_pair_marginals", "budgeted_marginals", "_pair_marginals"]] + [
    (PMBMTracker, s) for s in COMMON + ["update", "check_pair_weights", "track_clusters",
                                        "_hypotheses_after", "rank_tuples", "combine_events"]
]  # fmt: skip


@pytest.mark.parametrize("kind, stage", STAGES, ids=lambda v: getattr(v, "__name__", v))
def test_failing_stage_leaves_state_unchanged_and_retry_matches(kind, stage, monkeypatch):
    k = 29  # the crossing: both targets' tracks in one cluster
    trk, sc = _warm(kind, k)
    reference, _ = _warm(kind, k)
    snapshot = trk.state_dict()

    def boom(*args, **kwargs):
        raise Injected(stage)

    if stage.startswith("_") and hasattr(kind, stage):
        monkeypatch.setattr(kind, stage, boom)
    elif hasattr(pmbm_module, stage):
        monkeypatch.setattr(pmbm_module, stage, boom)
    else:
        monkeypatch.setattr(base_module, stage, boom)
    with pytest.raises(Injected):
        trk.step(sc.times[k], sc.detections[k])
    monkeypatch.undo()
    after = trk.state_dict()
    assert_same_state(after, snapshot)
    _results_equal(trk.step(sc.times[k], sc.detections[k]),
                   reference.step(sc.times[k], sc.detections[k]))  # fmt: skip
    _state_equal(trk, reference)


@pytest.mark.parametrize("kind", KINDS)
def test_keyboard_interrupt_mid_step_is_atomic(kind, monkeypatch):
    trk, sc = _warm(kind)
    snapshot = trk.state_dict()

    def interrupt(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(pmbm_module, "prune_and_merge", interrupt)
    with pytest.raises(KeyboardInterrupt):
        trk.step(sc.times[12], sc.detections[12])
    assert trk.n_scans == snapshot["n_scans"] and trk.time == snapshot["time"]
    np.testing.assert_array_equal(trk.undetected_density, snapshot["undetected_density"])


# ---------------------------------------------------------------- round trip


@settings(max_examples=6, deadline=None)
@given(kind=st.sampled_from(KINDS), split=st.integers(1, 40), gaussian=st.booleans())
def test_save_load_step_is_bit_identical(tmp_path_factory, kind, split, gaussian):
    sc = _scenario()
    kw = {}
    if gaussian:  # a Gaussian birth mixture: the Poisson components are state too
        cov = tuple(tuple(v) for v in np.diag([1e4, 1e4, 25.0, 25.0]))
        kw = dict(birth_model="gaussian", birth_weights=(0.05,), prior_weight=1.0,
                  birth_means=((-300.0, 0.0, 10.0, 0.0),), birth_covs=(cov,))  # fmt: skip
    a = kind(_config(**kw))
    for k in range(split):
        a.step(sc.times[k], sc.detections[k])
    d = tmp_path_factory.mktemp("s")
    path = a.save(d / "state.npz")
    b = kind.load(path)
    _state_equal(a, b)
    for k in range(split, min(split + 8, len(sc.times))):
        _results_equal(a.step(sc.times[k], sc.detections[k]), b.step(sc.times[k], sc.detections[k]))
    _state_equal(a, b)
    # and the files they write next are the same bytes
    assert a.save(d / "a.npz").read_bytes() == b.save(d / "b.npz").read_bytes()


# ---------------------------------------------------------------- damaged files


@pytest.fixture(params=KINDS, ids=lambda k: k.__name__)
def good_state(request, tmp_path):
    trk, _ = _warm(request.param, 30)
    return trk, trk.save(tmp_path / "good.npz")


def test_truncations_are_refused(good_state, tmp_path):
    trk, path = good_state
    data = path.read_bytes()
    for cut in sorted({0, 1, 3, 10, 100, len(data) // 3, len(data) // 2, len(data) - 1}):
        bad = tmp_path / f"cut{cut}.npz"
        bad.write_bytes(data[:cut])
        with pytest.raises(StateFileError, match=bad.name):
            type(trk).load(bad)


def test_byte_flips_are_refused_or_harmless(good_state, tmp_path):
    trk, path = good_state
    data = bytearray(path.read_bytes())
    rng = np.random.default_rng(0)
    refused = 0
    for _ in range(200):
        flipped = bytearray(data)
        for pos in rng.integers(0, len(data), size=rng.integers(1, 4)):
            flipped[pos] ^= int(rng.integers(1, 256))
        bad = tmp_path / "flip.npz"
        bad.write_bytes(bytes(flipped))
        try:
            loaded = type(trk).load(bad)
        except StateFileError as exc:
            assert "flip.npz" in str(exc)
            refused += 1
            continue
        _state_equal(loaded, trk)  # a flip in zip metadata nobody reads changes nothing
    assert refused > 150


def _rewrite(path, out, mutate_arrays=None, mutate_header=None):
    arrays, config, scalars, rng = read_state(path)
    if mutate_arrays:
        mutate_arrays(arrays)
    header = {"config": config, "scalars": scalars, "rng": rng}
    if mutate_header:
        mutate_header(header)
    write_state(out, arrays, header["config"], header["scalars"], header["rng"])
    return out


def _set(name, index, value):
    def mutate(a):
        a[name] = a[name].copy()
        a[name][index] = value

    return mutate


def _drop(name):
    return lambda a: a.pop(name)


def _non_spd(name):
    def mutate(a):
        a[name] = a[name].copy()
        a[name][0] = -np.eye(a[name].shape[1])

    return mutate


def _asym(name):
    def mutate(a):
        a[name] = a[name].copy()
        a[name][0, 0, 1] += 1.0

    return mutate


def _cast(name, dtype):
    def mutate(a):
        a[name] = a[name].astype(dtype)

    return mutate


def _shorten(name):
    def mutate(a):
        a[name] = a[name][:-1]

    return mutate


POISSON_CASES = [
    (_drop("undetected_density"), "missing field 'undetected_density'"),
    (_set("undetected_density", 0, -1.0), "'undetected_density' has negative"),
    (_set("undetected_density", 0, np.nan), "non-finite"),
    (_cast("poisson_w", np.int64), "'poisson_w' has dtype"),
]
PMB_CASES = [
    (_drop("x"), "missing field 'x'"),
    (_drop("existence"), "missing field 'existence'"),
    (_set("existence", 0, 1.5), r"'existence' has values outside \(0, 1\]"),
    (_set("existence", 0, -0.1), r"'existence' has values outside \(0, 1\]"),
    (_set("existence", 0, 0.0), r"'existence' has values outside \(0, 1\]"),
    (_set("x", (0, 0), np.nan), "non-finite"),
    (_non_spd("P"), "'P' holds a covariance"),
    (_asym("P"), "'P' holds a covariance"),
    (_cast("ids", float), "'ids' has dtype"),
    (lambda a: a.update(ids=np.r_[a["ids"][:1], a["ids"][:1], a["ids"][2:]]), "distinct"),
    (_set("ids", 0, 0), "distinct positive"),
    (_shorten("P"), "'P' has shape"),
]
PMBM_CASES = [
    (_drop("hyp"), "missing field 'hyp'"),
    (_drop("sth_P"), "missing field 'sth_P'"),
    (_set("sth_r", 0, 1.5), r"'sth_r' has values outside \(0, 1\]"),
    (_set("sth_r", 0, 0.0), r"'sth_r' has values outside \(0, 1\]"),
    (_set("hyp", (0, 0), 10**6), "'hyp' names a single-target hypothesis that does not exist"),
    (_set("hyp", (0, 0), -2), "'hyp' names a single-target hypothesis that does not exist"),
    (_set("sth_track", 0, 10**6), "'sth_track' names a track that does not exist"),
    (_non_spd("sth_P"), "'sth_P' holds a covariance"),
    (_asym("sth_P"), "'sth_P' holds a covariance"),
    (_set("hyp_logw", 0, -1.0), "'hyp_logw' is not normalised"),
    (_set("hyp_logw", 0, np.inf), "non-finite"),
    (_shorten("hyp_logw"), "'hyp_logw' has shape"),
    (_shorten("sth_track"), "'sth_track' has shape"),
    (lambda a: a.update(hyp=a["hyp"][:0], hyp_logw=a["hyp_logw"][:0]), "no global hypothesis"),
    (_set("track_ids", 0, -5), "positive track ids"),
    (_cast("hyp", float), "'hyp' has dtype"),
]


@pytest.mark.parametrize("kind, mutate, match",
                         [(k, m, s) for k in KINDS for m, s in POISSON_CASES]
                         + [(PMBTracker, m, s) for m, s in PMB_CASES]
                         + [(PMBMTracker, m, s) for m, s in PMBM_CASES])  # fmt: skip
def test_invalid_values_are_refused(kind, mutate, match, tmp_path):
    trk, _ = _warm(kind, 30)
    path = trk.save(tmp_path / "good.npz")
    bad = _rewrite(path, tmp_path / "bad.npz", mutate_arrays=mutate)
    with pytest.raises(StateFileError, match=match) as info:
        kind.load(bad)
    assert "bad.npz" in str(info.value)


def test_hypothesis_under_another_track_is_refused(tmp_path):
    """A global hypothesis may only name STHs of the track whose column it is."""
    trk, _ = _warm(PMBMTracker, 30)
    path = trk.save(tmp_path / "good.npz")
    arrays, *_ = read_state(path)
    assert arrays["hyp"].shape[1] >= 2

    def swap(a):
        h = a["hyp"].copy()
        s = a["sth_track"]
        col = int(np.flatnonzero(h[0] >= 0)[0])
        other = int(np.flatnonzero(s != col)[0])  # an STH of another track
        h[0, col] = other
        a["hyp"] = h

    bad = _rewrite(path, tmp_path / "bad.npz", mutate_arrays=swap)
    with pytest.raises(StateFileError, match="under another track"):
        PMBMTracker.load(bad)


@pytest.mark.parametrize(
    "mutate, match",
    [
        (lambda h: h["config"].update(p_d=7.0), "invalid tracker configuration"),
        (lambda h: h["config"].update(bogus=1), "invalid tracker configuration"),
        (lambda h: h["config"].pop("r_estimate"), "invalid tracker configuration"),
        (lambda h: h["scalars"].update(next_id=-3), "next_id"),
        (lambda h: h["scalars"].update(next_id=1), "next_id"),  # not above every id
        (lambda h: h["scalars"].update(time="yesterday"), "time"),
        (lambda h: h["scalars"].update(time_origin="noon"), "time_origin"),
        (lambda h: h["rng"].update(state="x"), "random-generator state"),
        (lambda h: h["scalars"].update(tracker="kalman"), "'kalman' tracker"),
    ],
)
def test_invalid_header_values_are_refused(good_state, tmp_path, mutate, match):
    trk, path = good_state
    bad = _rewrite(path, tmp_path / "bad.npz", mutate_header=mutate)
    with pytest.raises(StateFileError, match=match):
        type(trk).load(bad)


def test_edited_payload_fails_the_checksum(good_state, tmp_path):
    trk, path = good_state
    with np.load(path) as npz:
        arrays = {k: npz[k] for k in npz.files}
    arrays["poisson_w"] = arrays["poisson_w"] + 1.0  # keep the old header (and its digest)
    arrays["undetected_density"] = arrays["undetected_density"] * 2.0
    bad = tmp_path / "edited.npz"
    np.savez(bad, **arrays)
    with pytest.raises(StateFileError, match="checksum"):
        type(trk).load(bad)


def test_foreign_and_missing_files(good_state, tmp_path):
    trk, _ = good_state
    np.savez(tmp_path / "other.npz", a=np.arange(3))
    with pytest.raises(StateFileError, match="other.npz"):
        type(trk).load(tmp_path / "other.npz")
    (tmp_path / "text.npz").write_bytes(b"not a state")
    with pytest.raises(StateFileError, match="text.npz"):
        type(trk).load(tmp_path / "text.npz")
    with pytest.raises(StateFileError, match="missing.npz"):
        type(trk).load(tmp_path / "missing.npz")


def test_a_state_of_another_kind_is_refused_clearly(tmp_path):
    sc = _scenario()
    jpda = JPDATracker(TrackerConfig(clutter_density=sc.clutter_density))
    jpda.step(0.0, sc.detections[0])
    files = {
        "jpda": jpda.save(tmp_path / "jpda.npz"),
        "pmb": _warm(PMBTracker, 3)[0].save(tmp_path / "pmb.npz"),
        "pmbm": _warm(PMBMTracker, 3)[0].save(tmp_path / "pmbm.npz"),
    }
    owner = {"jpda": JPDATracker, "pmb": PMBTracker, "pmbm": PMBMTracker}
    for kind, path in files.items():
        owner[kind].load(path)  # its own class loads it
        for other in owner.values():
            if other is owner[kind]:
                continue
            with pytest.raises(StateFileError) as info:
                other.load(path)
            msg = str(info.value)
            assert path.name in msg and f"{kind!r} tracker" in msg
            assert f"load it with {owner[kind].__name__}.load" in msg


# ---------------------------------------------------------------- kill and resume

_RUNNER = """
import sys, numpy as np
from pathlib import Path
from jointtrack.scenarios import crossing
from jointtrack.trackers.pmbm import PMBMConfig, PMBMTracker
state, out = Path(sys.argv[1]), Path(sys.argv[2])
sc = crossing(seed=3)
cfg = PMBMConfig(process_noise=0.05, measurement_noise=float(sc.R[0, 0]), p_d=sc.p_d,
                 clutter_density=sc.clutter_density, max_speed=15.0, birth_density=1e-6)
trk = PMBMTracker.load(state) if state.exists() else PMBMTracker(cfg)
print("ready", flush=True)
for k in range(trk.n_scans, len(sc.times)):
    r = trk.step(sc.times[k], sc.detections[k])
    # the estimates before the state that counts them: a kill between the last save and
    # a final write would leave a finished state and no estimates (a resume then has no
    # scan left to step)
    np.savez(out, ids=r.ids, x=r.x, P=r.P, existence=r.existence)
    trk.save(state)
print("done", flush=True)
"""


def _run(args, **kw):
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in sys.path if p)
    return subprocess.Popen([sys.executable, "-c", _RUNNER, *map(str, args)], env=env,
                            stdout=subprocess.PIPE, text=True, **kw)  # fmt: skip


def test_killed_pmbm_run_resumes_to_the_uninterrupted_estimates(tmp_path):
    """SIGKILL at random moments of a run that saves every scan; resume; same finish."""
    full = _run([tmp_path / "ref-state.npz", tmp_path / "ref.npz"])
    t0 = time.monotonic()
    assert full.stdout.readline().strip() == "ready"
    t_ready = time.monotonic()
    full.wait(timeout=300)
    run_seconds = time.monotonic() - t_ready
    assert full.returncode == 0, f"reference run failed after {time.monotonic() - t0:.1f} s"
    ref = np.load(tmp_path / "ref.npz")
    assert len(ref["ids"]) >= 2
    rng = np.random.default_rng(int.from_bytes(os.urandom(4), "little"))
    state, out = tmp_path / "state.npz", tmp_path / "out.npz"
    kills = 0
    for _ in range(3):  # up to three kills of the same run, each at a random moment
        proc = _run([state, out])
        assert proc.stdout.readline().strip() == "ready"
        time.sleep(rng.uniform(0.0, 0.6 * run_seconds))
        if proc.poll() is None:
            proc.send_signal(signal.SIGKILL)
            kills += 1
        proc.wait(timeout=300)
        assert proc.returncode in (0, -signal.SIGKILL)
        if proc.returncode == 0:
            break
    if proc.returncode != 0:
        resumed = _run([state, out])
        resumed.wait(timeout=300)
        assert resumed.returncode == 0
    got = np.load(out)
    for name in ("ids", "x", "P", "existence"):
        np.testing.assert_array_equal(got[name], ref[name], err_msg=name)
    assert kills >= 1, "no kill landed (the run finished before every delay)"
