"""bench.from_nothing: phases, scores, the floor, the oracle, the bad input (issue 33)."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from benchmark_scripts import load_benchmark
from jointtrack.bench import from_nothing as fn
from jointtrack.experiments.run import run_scenario
from jointtrack.scenarios import crossing, simulate_scenario


def _reference_phases(sc, start_scans=20, end_scans=10, close_sigmas=3.0):
    """The module docstring's phase definition, scan by scan."""
    sigma = math.sqrt(np.mean(np.diag(sc.R)))
    K = sc.n_scans
    close = []
    for k in range(K):
        p = sc.truth_positions[k]
        d = min(
            (
                float(np.linalg.norm(p[i] - p[j]))
                for i in range(len(p))
                for j in range(i + 1, len(p))
            ),
            default=math.inf,
        )
        close.append(d < close_sigmas * sigma)
    first_close = next((k for k in range(K) if close[k]), K)
    k_s = min(start_scans, first_close, K)
    late = [k for k in range(K) if close[k] and k >= k_s]
    names = []
    for k in range(K):
        if k < k_s:
            names.append("start")
        elif late and late[0] <= k <= late[-1]:
            names.append("close")
        elif k >= K - end_scans and not (late and k < late[0]):
            # the end follows the close phase (scan order), never precedes it
            names.append("end")
        elif late and k > late[-1]:
            names.append("separating")
        else:
            names.append("approach")
    return [fn.PHASES.index(n) for n in names]


@settings(max_examples=25, deadline=None)
@given(
    n_scans=st.integers(2, 70),
    angle=st.floats(1.0, 170.0),
    speed=st.floats(0.5, 30.0),
    start=st.integers(0, 30),
    end=st.integers(0, 15),
    sigmas=st.floats(0.5, 6.0),
)
def test_phases_follow_the_definition(n_scans, angle, speed, start, end, sigmas):
    sc = crossing(seed=1, n_scans=n_scans, angle_deg=angle, speed=speed, clutter_per_scan=0.0)
    got = fn.phases(sc, start_scans=start, end_scans=end, close_sigmas=sigmas)
    assert got.tolist() == _reference_phases(sc, start, end, sigmas)
    assert np.all(np.diff(got) >= 0)  # in scan order


def test_phases_of_the_scenes():
    """Bojilov's lanes are close around t_meet = 40, crossing's targets around t_c = 30."""
    ph = fn.phases(fn.make_scene("bojilov", 0)).tolist()
    close = [k for k, p in enumerate(ph) if p == fn.PHASES.index("close")]
    assert 25 <= close[0] <= 32 and 48 <= close[-1] <= 62  # the lanes drift (q): 57 on seed 0
    ph = fn.phases(fn.make_scene("crossing", 0)).tolist()
    close = [k for k, p in enumerate(ph) if p == fn.PHASES.index("close")]
    assert 25 <= close[0] <= 31 and 31 <= close[-1] <= 38  # 29–36 on seed 0 (q = 0.01)


def _two_targets(n_scans=12):
    return crossing(seed=3, n_scans=n_scans, clutter_per_scan=0.0)


@settings(max_examples=12, deadline=None)
@given(
    starts=st.lists(st.one_of(st.none(), st.integers(0, 11)), min_size=2, max_size=2),
    false_scans=st.lists(st.integers(0, 11), max_size=5, unique=True),
)
def test_scores_of_exact_tracks(starts, false_scans):
    """Tracks on the truth from scan s_j: GOSPA per scan is √(missed·c²/2) exactly,
    confirmation s_j + 1, no switch; a far track is one false track at its scans."""
    sc = _two_targets()
    tt, ti, tp = sc.truth_table()
    keep = np.zeros(tt.size, bool)
    for j, s in enumerate(starts):
        if s is not None:
            keep |= (ti == j) & (tt >= sc.times[s])
    far = np.array([[1e6, 1e6]] * len(false_scans)).reshape(-1, 2)
    t = np.concatenate([tt[keep], sc.times[false_scans]])
    ids = np.concatenate([ti[keep] + 100, np.full(len(false_scans), 7)])
    pos = np.concatenate([tp[keep], far])
    s = fn.score_tracks(sc, (t, ids, pos))
    c, p = s["c"], s["p"]
    assert (c, p) == (50.0, 2.0)  # 5σ, σ = 10
    for k in range(sc.n_scans):
        missed = sum(1 for st_ in starts if st_ is None or st_ > k)
        false = int(k in false_scans)
        want = math.sqrt((missed + false) * c**2 / 2)
        assert s["gospa_series"][k] == pytest.approx(want, rel=1e-12, abs=1e-12)
    assert s["confirm_scans"] == {j: (None if v is None else v + 1) for j, v in enumerate(starts)}
    assert s["switches"] == 0
    assert s["false_per_scan"] == pytest.approx(len(false_scans) / sc.n_scans, rel=1e-12)


def test_floor_keeps_each_truth_track_from_its_oracle_scan():
    sc = _two_targets()
    tt, ti, tp = sc.truth_table()
    late = tt >= sc.times[4]
    run = (
        np.concatenate([tt, tt[late & (ti == 1)]]),
        np.concatenate([ti + 1, np.full(int((late & (ti == 1)).sum()), 99)]),
        np.concatenate([tp, tp[late & (ti == 1)] + 1.0]),
    )
    oracle = {0: {"confirm_scan": 6}, 1: {"confirm_scan": None}}
    t, ids, _pos = fn.floor_tracks(sc, run, oracle)
    scan = np.searchsorted(sc.times, t)
    assert set(scan[ids == 1].tolist()) == set(range(6, sc.n_scans))
    assert not (ids == 2).any()  # the oracle never confirmed target 1
    assert (ids == 99).sum() == (late & (ti == 1)).sum()  # started by the run: kept whole


def _lone_target(seed, n_scans=8, clutter=20.0):
    x0 = np.array([[0.0, 0.0, 5.0, 0.0]])
    traj = np.stack([x0[0] + k * np.array([5.0, 0.0, 0.0, 0.0]) for k in range(n_scans)])
    return simulate_scenario(
        "lone",
        np.arange(float(n_scans)),
        [np.array([0])] * n_scans,
        [traj[k : k + 1] for k in range(n_scans)],
        region=np.array([[-200.0, 240.0], [-200.0, 200.0]]),
        p_d=0.9,
        clutter_rate=clutter,
        R=25.0 * np.eye(2),
        process_noise=1e-4,
        rng=seed,
    )


def test_oracle_of_a_lone_target_sees_the_same_returns_either_way():
    for seed in range(3):
        sc = _lone_target(seed)
        a, b = fn.oracle_confirmation(sc), fn.oracle_confirmation(sc, returns="own")
        assert a == b
        assert a[0]["scans"] is not None and 1 <= a[0]["scans"] <= sc.n_scans


def test_bad_input_is_refused_by_name():
    sc = _two_targets()
    with pytest.raises(ValueError, match="scenario must be a jointtrack.scenarios.Scenario"):
        fn.check_scene(sc.as_detections())
    empty = dataclasses.replace(
        sc,
        truth_ids=tuple(np.zeros(0, np.int64) for _ in sc.times),
        truth_states=tuple(np.zeros((0, 4)) for _ in sc.times),
    )
    for call in (fn.check_scene, fn.oracle_confirmation, fn.phases):
        with pytest.raises(ValueError, match="has no truth"):
            call(empty)
    with pytest.raises(ValueError, match="scene must be one of"):
        fn.make_scene("many", 0)
    with pytest.raises(ValueError, match="seed must be"):
        fn.make_scene("bojilov", True)
    with pytest.raises(ValueError, match="tracker must be one of"):
        fn.tracker_tracks("crossing", 0, "kalman")
    with pytest.raises(ValueError, match="trackers must be a sequence"):
        fn.evaluate("crossing", 0, "jipda")
    with pytest.raises(ValueError, match="returns must be"):
        fn.oracle_confirmation(sc, returns="others")
    with pytest.raises(ValueError, match="restart must be"):
        fn.oracle_confirmation(sc, restart=1)
    with pytest.raises(ValueError, match="close_sigmas must be"):
        fn.phases(sc, close_sigmas=1j)
    with pytest.raises(ValueError, match="start_scans must be"):
        fn.phases(sc, start_scans=2.5)
    with pytest.raises(ValueError, match="runs must hold"):
        fn.aggregate([])


def _fake(seed, floor, jipda, switches, false, confirm, oracle):
    def score(g, sw, fa, conf):
        part = {"n_scans": 1, "gospa": g, "localisation": 0.0, "missed": 0.0, "false": 0.0}
        return {
            "gospa": g,
            "phases": dict.fromkeys(fn.PHASES, part),
            "confirm_scans": conf,
            "switches": sw,
            "false_per_scan": fa,
        }

    return {
        "scene": "bojilov",
        "seed": seed,
        "oracle": oracle,
        "floor": score(floor, 0, 0.0, oracle),
        "trackers": {"jipda": score(jipda, switches, false, confirm)},
    }


def test_aggregate_pass_lines():
    runs = [
        _fake(0, 20.0, 22.0, 1, 0.05, {0: 18, 1: None}, {0: 16, 1: 17}),
        _fake(1, 25.0, 27.5, 0, 0.05, {0: 19, 1: 19}, {0: 17, 1: None}),
    ]
    agg = fn.aggregate(runs)
    row = agg["jipda"]
    assert row["ratio"]["mean"] == pytest.approx(1.1)
    assert agg["floor"]["ratio"] == {"mean": 1.0, "std": 0.0}
    assert agg["oracle_median"] == 17.0 and agg["oracle_never"] == 1
    assert row["confirm_median"] == 19.0 and row["confirm_never"] == 1  # 18, 19, 19, never
    assert row["behind_oracle_median"] == 2.0  # pairs (18−16), (19−17)
    assert all(row["checks"].values())
    worse = fn.aggregate([_fake(0, 20.0, 30.0, 3, 0.5, {0: 40}, {0: 16})])["jipda"]["checks"]
    assert not any(worse.values())


def test_evaluate_two_short_seeds(tmp_path):
    """A 2-seed, 8-scan crossing case end to end: the floor confirms each target exactly
    at its oracle scan, and a tracker is scored as its own run scores itself."""
    kw = {"n_scans": 8}
    runs = [fn.evaluate("crossing", s, ["jipda"], scenario_kwargs=kw) for s in (0, 1)]
    for r in runs:
        assert len(r["phases"]) == 8
        assert all(v is None or 1 <= v <= 8 for v in r["oracle"].values())
        assert r["floor"]["confirm_scans"] == r["oracle"]
    m = run_scenario(
        "crossing",
        seed=1,
        start_from="nothing",
        tracker="jipda",
        scenario_kwargs=kw,
        plots=False,
        out_dir=tmp_path,
    )
    assert runs[1]["trackers"]["jipda"]["gospa"] == pytest.approx(m["gospa"]["mean"], rel=1e-12)
    assert runs[1]["trackers"]["jipda"]["switches"] == m["tracks"]["n_id_switches"]
    agg = fn.aggregate(runs)
    assert agg["floor"]["ratio"] == {"mean": 1.0, "std": 0.0}
    want = np.mean([r["trackers"]["jipda"]["gospa"] / r["floor"]["gospa"] for r in runs])
    assert agg["jipda"]["ratio"]["mean"] == pytest.approx(want, rel=1e-12)
    assert set(agg["jipda"]["checks"]) == {
        "GOSPA ≤ 1.15 × floor",
        "switches ≤ 1/run",
        "median confirmation ≤ oracle + 2",
        "false ≤ 0.1/scan",
    }


# ----------------------------------------------------------------------------- the command line


@pytest.fixture(scope="module")
def script():
    return load_benchmark("from_nothing")


def _canned(scene, seed, trackers, **_kw):
    """A stand-in for evaluate: a 3-scan result whose numbers depend on the seed."""
    series = [10.0 + seed, 5.0, 5.0]
    ph = {p: {"n_scans": 0} for p in fn.PHASES}
    ph["start"] = {"n_scans": 3, "gospa": 6.0 + seed, "localisation": 1.0, "missed": 2.0,
                   "false": 0.0}  # fmt: skip
    score = {"gospa": 6.0 + seed, "gospa_series": series, "phases": ph,
             "confirm_scans": {0: 1}, "switches": 0, "false_per_scan": 0.0}  # fmt: skip
    return {"scene": scene, "seed": seed, "n_scans": 3, "oracle": {0: 1}, "phases": [0, 0, 0],
            "floor": score, "trackers": {k: dict(score) for k in trackers}}  # fmt: skip


def _rate():
    """A stand-in for false_track_rate's result."""
    return {"grid": [0.9, 0.99], "false_per_scan": [0.5, 0.05], "false_per_scan_se": [0.1, 0.01],
            "p_confirm": [1e-3, 1e-4], "reported_scans": [5.0, 4.0], "r_star": 0.99,
            "births": 10, "copies": 12, "seed": 0, "clutter_rate": 10.0}  # fmt: skip


def test_a_killed_benchmark_resumes_from_its_file(script, tmp_path, monkeypatch):
    """Seed 1 fails (fault injection): exit 1, seed 0 kept in --out; the same command again
    runs seed 1 only and writes what an uninterrupted run writes."""
    out = tmp_path / "r.json"
    argv = ["--seeds", "2", "--scenes", "crossing", "--trackers", "jipda", "--out", str(out)]
    calls = []

    def failing(scene, seed, trackers, **kw):
        calls.append(seed)
        if seed == 1:
            raise RuntimeError("killed")
        return _canned(scene, seed, trackers)

    monkeypatch.setattr(script.fn, "evaluate", failing)
    # r* (seconds of simulation): a stand-in that counts its calls — it is computed once per
    # scene and resumed from the file, not again
    rates = []
    monkeypatch.setattr(
        script.fn, "false_track_rate", lambda sc, **kw: rates.append(sc.name) or _rate()
    )
    # the figure is matplotlib's (seconds to import): a stand-in records that it was drawn
    monkeypatch.setattr(script, "plot", lambda path, aggs, runs: path.write_text(str(len(runs))))
    assert script.main(argv) == 1
    doc = json.loads(out.read_text())
    assert doc["partial"] and [r["seed"] for r in doc["runs"]["crossing"]] == [0]
    calls.clear()
    monkeypatch.setattr(script.fn, "evaluate", lambda *a, **k: calls.append(a[1]) or _canned(*a))
    assert script.main(argv) == 0
    assert calls == [1]
    assert rates == ["crossing"]  # the second run took r* from the file
    resumed = json.loads(out.read_text())
    assert resumed["rates"]["crossing"] == _rate()
    fresh = tmp_path / "f.json"
    assert script.main([*argv[:-1], str(fresh)]) == 0
    fresh_doc = json.loads(fresh.read_text())
    for key in ("scenes", "runs", "setup", "partial", "rates"):
        assert resumed[key] == fresh_doc[key]
    assert out.with_suffix(".png").exists()
    # another --trackers is refused by name, the file left as it was
    with pytest.raises(SystemExit, match="other settings"):
        script.main([*argv[:5], "pmb", *argv[6:]])
    assert json.loads(out.read_text()) == resumed


def test_the_command_refuses_unknown_names(script, capsys):
    for argv in (["--scenes", "many"], ["--trackers", "jipda,kalman"], ["--seeds", "0"]):
        with pytest.raises(SystemExit):
            script.main(argv)
        err = capsys.readouterr().err
        assert "many" in err or "kalman" in err or "--seeds" in err
