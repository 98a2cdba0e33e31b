"""The run summary says how a run from nothing started (issue 33, item 5).

Per-target scans to confirm with truth (omitted without), and the slow-start
note from the expected existence evidence per scan (``start_evidence``), which
is checked against a direct simulation of lone IPDA tracks.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from jointtrack.bench.from_nothing import jipda_config, oracle_confirmation
from jointtrack.experiments import summary as summod
from jointtrack.experiments.run import run_detections, run_scenario
from jointtrack.experiments.summary import (
    SLOW_START_SCANS,
    confirmation_scans,
    start_evidence,
    summary_tables,
)
from jointtrack.metrics import track_statistics
from jointtrack.scenarios import bojilov, crossing, simulate_scenario


def _rows(metrics) -> dict:
    """The summary's main table as {what: [values]}."""
    table = summary_tables(metrics)[0]
    what = [str(c) for c in table.columns[0]._cells]
    value = [str(c) for c in table.columns[1]._cells]
    out: dict = {}
    for w, v in zip(what, value, strict=True):
        out.setdefault(w, []).append(v)
    return out


def _lone_target(seed, n_scans=30, clutter_density=60 / 360000, p_d=0.7):
    """One target at 5 m/s, σ = 10, in clutter on a box just around its path."""
    traj = np.array([[5.0 * k, 0.0, 5.0, 0.0] for k in range(n_scans)])
    region = np.array([[-60.0, 5.0 * n_scans + 60], [-80.0, 80.0]])
    area = float(np.prod(region[:, 1] - region[:, 0]))
    return simulate_scenario(
        "lone",
        np.arange(float(n_scans)),
        [np.array([0])] * n_scans,
        [traj[k : k + 1] for k in range(n_scans)],
        region=region,
        p_d=p_d,
        clutter_rate=clutter_density * area,
        R=100.0 * np.eye(2),
        process_noise=1e-4,
        rng=seed,
    )


def test_expected_scans_match_lone_ipda_simulation():
    """start_evidence's expected scans (Wald: mean drift, no overshoot, the Kalman
    covariance) against lone IPDA tracks run by the tracker itself (the oracle, never
    deleted) on 24 seeds: the mean confirmation scan within 25 % of the formula's
    (measured: 8.4 ± 0.8 against 8; the scans' spread is ≈ 4)."""
    scenes = [_lone_target(s, n_scans=20, clutter_density=60 / 360000, p_d=0.9) for s in range(24)]
    cfg = jipda_config(scenes[0])
    expected = start_evidence(cfg, 1.0)["expected_scans"]
    assert 6 <= expected <= 12  # not a trivial case: the test says something about the drift
    sim = [oracle_confirmation(sc, restart=False)[0]["scans"] for sc in scenes]
    done = [v for v in sim if v is not None]
    assert len(done) >= 20
    assert abs(np.mean(done) - expected) <= 0.25 * expected, (sim, expected)


def test_evidence_grows_with_the_detection_rate_and_falls_with_clutter():
    cfg = jipda_config(_lone_target(0))
    base = start_evidence(cfg, 1.0)
    sharper = start_evidence(dataclasses.replace(cfg, p_d=0.95), 1.0)
    cluttered = start_evidence(
        dataclasses.replace(cfg, clutter_density=cfg.clutter_density * 8), 1.0
    )
    assert sharper["gain_last_scan"] > base["gain_last_scan"] > cluttered["gain_last_scan"]
    assert sharper["expected_scans"] < base["expected_scans"] < cluttered["expected_scans"]
    assert base["threshold_nats"] == pytest.approx(
        math.log(0.9 / 0.1) - math.log(0.02 / 0.98), rel=1e-12
    )


def test_evidence_from_subnormal_to_huge_clutter_density():
    """No NaN, no overflow, and slower starts as the clutter grows, at any magnitude."""
    cfg = jipda_config(_lone_target(0))
    scans = []
    for lam in (5e-324, 1e-300, 1e-6, 1e-3, 1e-2, 1.0, 1e300):
        ev = start_evidence(dataclasses.replace(cfg, clutter_density=lam), 1.0)
        assert all(math.isfinite(ev[k]) for k in ("gain_first_scan", "gain_last_scan"))
        scans.append(math.inf if ev["expected_scans"] is None else ev["expected_scans"])
    assert scans[0] == scans[1] == 1  # a return is all the evidence needed
    assert scans == sorted(scans) and scans[-1] == math.inf


def test_evidence_is_not_claimed_where_it_does_not_apply():
    cfg = jipda_config(_lone_target(0))
    assert start_evidence(dataclasses.replace(cfg, existence=False), 1.0) is None
    assert start_evidence(dataclasses.replace(cfg, clutter_density=None), 1.0) is None
    for dt in (0.0, -1.0, math.nan, math.inf, True, "1", 1j):
        with pytest.raises(ValueError, match="dt must be"):
            start_evidence(cfg, dt)


def test_slow_start_note_on_the_headline_scene_not_on_an_easy_one(tmp_path):
    m = run_scenario(
        "bojilov", start_from="nothing", max_scans=3, plots=False, out_dir=tmp_path / "b"
    )
    ev = m["start_evidence"]
    assert ev["slow"] and ev["expected_scans"] > SLOW_START_SCANS
    assert 0.3 <= ev["gain_last_scan"] <= 0.8  # the 0.4–0.7 nats per scan
    notes = [n for n in _rows(m)["note"] if n.startswith("slow start")]
    assert len(notes) == 1 and f"about {ev['expected_scans']} scans" in notes[0]
    m = run_scenario(
        "crossing", start_from="nothing", max_scans=3, plots=False, out_dir=tmp_path / "c"
    )
    assert not m["start_evidence"]["slow"]
    assert not any(n.startswith("slow start") for n in m["notes"])
    m = run_scenario(
        "bojilov", start_from="truth", max_scans=3, plots=False, out_dir=tmp_path / "t"
    )
    assert "start_evidence" not in m and "confirmation" not in m  # not a start from nothing


def test_scans_to_confirm_with_truth_and_omitted_without(tmp_path):
    sc = crossing(seed=2, n_scans=60, angle_deg=90.0)
    m = run_scenario(sc, start_from="nothing", plots=False, out_dir=tmp_path / "w", max_scans=14)
    c = m["gospa"]["c"]
    # brute force: the targets are > 2c apart in the first 14 scans (crossing at t = 29.5),
    # so a target's GOSPA partner within c is any track within c of it
    tracks = np.loadtxt(m["files"]["tracks"], delimiter=",", skiprows=1, ndmin=2)
    want = {}
    for tid in (0, 1):
        want[str(tid)] = None
        for k, t in enumerate(sc.times[:14]):
            pos = sc.truth_states[k][sc.truth_ids[k] == tid][0, :2]
            at = tracks[tracks[:, 0] == t]
            if len(at) and np.min(np.hypot(*(at[:, 2:4] - pos).T)) < c:
                want[str(tid)] = k + 1
                break
    got = m["confirmation"]
    assert got["scans_per_target"] == want
    row = _rows(m)["scans to confirm"][0]
    assert all(f"{t}: {'never' if v is None else v}" in row for t, v in want.items())
    # many targets: the spread, not a list (metrics.json keeps each)
    many = {str(i): (None if i % 5 == 0 else i) for i in range(40)}
    m["confirmation"] = {**got, "scans_per_target": many, "never": 8, "median": 22.5}
    row = _rows(m)["scans to confirm"][0]
    assert row.startswith("40 targets, quartiles 10.5–29.5, 8 never; median 22.5"), row
    # without truth: no per-target line, nothing guessed
    m = run_detections(
        sc.as_detections(), sc.tracker_config(), out_dir=tmp_path / "d", max_scans=14, plots=False
    )
    assert "confirmation" not in m and "scans to confirm" not in _rows(m)


@settings(max_examples=30, deadline=None)
@given(
    first=st.lists(st.integers(0, 6), min_size=1, max_size=3),
    hit=st.lists(st.one_of(st.none(), st.integers(0, 9)), min_size=3, max_size=3),
)
def test_confirmation_scans_against_brute_force(first, hit):
    """Targets born at scan first_j, a track on target j from scan hit_j (None: never):
    scans = hit_j − first_j + 1 counted from the birth (tracks before the birth are false)."""
    times = np.arange(10.0) * 2.5
    rows_t, rows_i, rows_p = [], [], []
    trk_t, trk_i, trk_p = [], [], []
    for j, f in enumerate(first):
        for k in range(f, 10):
            p = np.array([1000.0 * j, 7.0 * k])
            rows_t.append(times[k]), rows_i.append(j), rows_p.append(p)
            if hit[j] is not None and k >= hit[j]:
                trk_t.append(times[k]), trk_i.append(50 + j), trk_p.append(p + 0.5)
    truth = (np.array(rows_t), np.array(rows_i), np.array(rows_p))
    tracks = (np.array(trk_t), np.array(trk_i, dtype=np.int64), np.array(trk_p).reshape(-1, 2))
    stats = track_statistics(*truth, *tracks, gate=20.0)
    got = confirmation_scans(times, truth, stats)
    want = {j: (None if hit[j] is None else max(hit[j], f) - f + 1) for j, f in enumerate(first)}
    assert got == want


def test_confirmation_median_counts_never_as_late(tmp_path):
    """Two of five targets never confirmed in 12 scans of the headline scene: the
    median is the third-latest confirmed target's, or none when most never confirm."""
    m = run_scenario(
        bojilov(seed=0, n_scans=12), start_from="nothing", plots=False, out_dir=tmp_path / "b"
    )
    conf = m["confirmation"]
    vals = [math.inf if v is None else v for v in conf["scans_per_target"].values()]
    med = float(np.median(vals))
    assert conf["median"] == (med if math.isfinite(med) else None)
    assert conf["never"] == sum(v is None for v in conf["scans_per_target"].values())


def _magnitudes(sign):
    """0 and ±(subnormal … 1e300), as the project's numeric tests draw them."""
    mags = st.one_of(
        st.just(0.0),
        st.just(5e-324),
        st.floats(min_value=5e-324, max_value=1e300, allow_subnormal=True),
    )
    return mags.map(lambda m: sign * m) if sign else st.one_of(mags, mags.map(lambda m: -m))


@settings(max_examples=50, deadline=None)
@given(ell=_magnitudes(0), log_ps=_magnitudes(-1))
@example(ell=800.0, log_ps=0.0)  # r rounds to 1, no death: logit(r) = 800, not inf
@example(ell=1e300, log_ps=-5e-324)
@example(ell=-1e300, log_ps=-1e300)
def test_log_odds_survived_is_the_survival_step_exactly(ell, log_ps):
    """logit(p_s · expit(ell)) — the tracker's step existence · p_s — against 60-digit
    arithmetic: within 1e-12 relative (1e-12 absolute near 0), finite, never NaN."""
    import mpmath

    got = summod._log_odds_survived(ell, log_ps)
    with mpmath.workdps(60):
        e = mpmath.mpf(ell)
        r = 1 / (1 + mpmath.exp(-e))
        one_minus_r = 1 / (1 + mpmath.exp(e))
        one_minus_ps = -mpmath.expm1(mpmath.mpf(log_ps))  # 1 − p_s below 60 digits too
        # logit(p_s r) = log p_s + log r − log(1 − p_s r), 1 − p_s r = (1 − r) + r (1 − p_s)
        want = log_ps - mpmath.log1p(mpmath.exp(-e)) - mpmath.log(one_minus_r + r * one_minus_ps)
    assert math.isfinite(got)
    assert abs(got - float(want)) <= 1e-12 * max(1.0, abs(float(want)))


def test_start_evidence_is_computed_once_per_settings(monkeypatch):
    """The Monte Carlo runs once per settings in a process; every call gets an equal, own
    copy (the summary adds "slow" to it), equal to a fresh computation."""
    cfg = jipda_config(bojilov(seed=0))
    summod._start_evidence.cache_clear()
    fresh = start_evidence(cfg, 1.0)
    calls = []
    real = summod._expected_log_gain
    monkeypatch.setattr(summod, "_expected_log_gain", lambda *a: calls.append(a) or real(*a))
    again = start_evidence(cfg, 1.0)
    assert again == fresh and calls == []
    again["slow"] = True
    assert "slow" not in start_evidence(cfg, 1.0)
    other = start_evidence(dataclasses.replace(cfg, p_d=0.95), 1.0)
    assert calls and other != fresh  # other settings: computed
    summod._start_evidence.cache_clear()
    assert start_evidence(cfg, 1.0) == fresh


def test_start_evidence_survives_per_second_as_the_tracker():
    """p_survive per second over dt = 2 s is the tracker's p_s² per scan: the same evidence
    as p_s² per scan."""
    cfg = dataclasses.replace(jipda_config(bojilov(seed=0)), p_survive=0.99, p_survive_per="second")
    per_scan = dataclasses.replace(cfg, p_survive=0.99**2, p_survive_per="scan")
    a, b = start_evidence(cfg, 2.0), start_evidence(per_scan, 2.0)
    assert a["expected_scans"] == b["expected_scans"]
    assert a["gain_first_scan"] == b["gain_first_scan"]


def test_start_line_of_a_detections_run_says_it_keeps_the_joint_association():
    from jointtrack.experiments.summary import start_description

    tr = {"kind": "jipda", "existence": True, "initiation": "one-point", "r_confirm": 0.9}
    det = {"start": "nothing", "source": {"detections": "a.csv"}, "tracker": tr}
    assert "keeps the joint association" in start_description(det)
    alt = det | {"tracker": tr | {"tentative_association": "alternatives"}}
    assert "keeps the joint" not in start_description(alt)
    scene = det | {"source": {"scenario": "crossing"}}
    assert "keeps the joint" not in start_description(scene)
    split = det | {
        "tracker": tr | {"tentative_association": "splitting", "tentative_components": 6}
    }
    text = start_description(split)
    assert "keeps the joint" not in text
    assert "integrated track splitting" in text and "≤ 6 Gaussian histories" in text
    assert "alternatives" not in text


def test_an_old_state_file_gets_the_settings_defaults_for_splitting(tmp_path):
    """A state written before tentative_components existed loads with TrackerConfig's
    own default (one copy of each default, read from the dataclass)."""
    from jointtrack.trackers import JPDATracker, TrackerConfig
    from state_checks import load_state_without

    default = TrackerConfig().tentative_components
    trk = JPDATracker(TrackerConfig(existence=True, tentative_components=default + 3))
    trk.step(0.0, np.array([[0.0, 0.0], [50.0, 50.0]]))
    old = load_state_without(trk, "tentative_components", tmp_path)
    assert old.config.tentative_components == default
    assert old.config.tentative_confirm_state == TrackerConfig().tentative_confirm_state
