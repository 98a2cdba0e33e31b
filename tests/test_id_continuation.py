"""Id continuation (``TrackerConfig.id_continuation``, issue 32): a track that died
and whose target's returns start a new track keeps its id — when, and only when, the
new track confirms within the window inside the gate of the deleted track's coasted
prediction (position and velocity)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from jointtrack.experiments import fit as fitmod
from jointtrack.experiments.fit import fit_tracker_settings
from jointtrack.io import Detections
from jointtrack.trackers.jpda import CONTINUATION_GATE, JPDATracker, TrackerConfig
from jointtrack.trackers.state_io import StateFileError, read_state, write_state
from test_fit import report_like_detections

SPEED = 100.0  # m/s along x
DT = 10.0  # s between scans


def _tracker(window: float, **kw) -> JPDATracker:
    cfg = dict(
        clutter_density=1e-9,
        measurement_noise=20.0**2,
        process_noise=1.0,
        max_speed=300.0,
        p_d=0.9,
        p_g=0.9999,
        id_continuation=window,
    )
    return JPDATracker(TrackerConfig(**(cfg | kw)))


def _scan(k: int, gap: range, back: bool = False) -> np.ndarray:
    """The target's return at scan k (none during ``gap``). ``back``: after the gap
    the returns come from a target flying the other way through the same place."""
    if k in gap:
        return np.zeros((0, 2))
    if back and k > gap.stop - 1:
        # at the coasted prediction's position at the gap's end, flying −x
        x = SPEED * DT * (gap.stop - 1) - SPEED * DT * (k - gap.stop + 1)
        return np.array([[x, 0.0]])
    return np.array([[SPEED * DT * k, 0.0]])


def _run(trk: JPDATracker, scans, gap=range(10, 15), back=False):
    ids, continued = set(), 0
    for k in scans:
        res = trk.step(DT * k, _scan(k, gap, back))
        ids |= set(res.ids.tolist())
        continued += res.n_continued
    return ids, continued


def test_a_track_born_again_on_its_target_keeps_its_id():
    ids, continued = _run(_tracker(0.0), range(30))
    assert len(ids) == 2 and continued == 0  # off: the gap deletes it, a new id follows
    ids, continued = _run(_tracker(12 * DT), range(30))
    assert ids == {1} and continued == 1


def test_a_new_track_flying_the_other_way_does_not_take_the_id():
    ids, continued = _run(_tracker(12 * DT), range(30), back=True)
    assert len(ids) == 2 and continued == 0


def test_a_deleted_track_is_forgotten_after_the_window():
    # deletion to the new track's confirmation takes more than one scan interval here
    ids, continued = _run(_tracker(DT), range(30))
    assert len(ids) == 2 and continued == 0


def test_resume_inside_the_gap_continues_exactly(tmp_path):
    whole = _tracker(12 * DT)
    ids_whole, _ = _run(whole, range(30))
    first = _tracker(12 * DT)
    _run(first, range(15))
    assert len(first.retired_ids) == 1  # the deleted track is remembered
    path = first.save(tmp_path / "s.npz")
    loaded = JPDATracker.load(path)
    ids_rest, continued = _run(loaded, range(15, 30))
    assert ids_rest == ids_whole == {1} and continued == 1
    np.testing.assert_array_equal(loaded.x, whole.x)


def test_a_state_written_before_the_setting_existed_loads_with_it_off(tmp_path):
    trk = _tracker(0.0)
    _run(trk, range(14))
    arrays, config, scalars, rng = read_state(trk.save(tmp_path / "now.npz"))
    config.pop("id_continuation")
    for name in ("retired_ids", "retired_x", "retired_P", "retired_time"):
        arrays.pop(name)
    write_state(tmp_path / "before.npz", arrays, config, scalars, rng)
    loaded = JPDATracker.load(tmp_path / "before.npz")
    assert loaded.config.id_continuation == 0.0 and len(loaded.retired_ids) == 0
    assert _run(loaded, range(14, 30)) == _run(trk, range(14, 30))


def test_damaged_id_continuation_fields_are_refused_by_name(tmp_path):
    trk = _tracker(12 * DT)
    _run(trk, range(15))
    arrays, config, scalars, rng = read_state(trk.save(tmp_path / "now.npz"))
    missing = dict(arrays)
    missing.pop("retired_x")
    write_state(tmp_path / "missing.npz", missing, config, scalars, rng)
    with pytest.raises(StateFileError, match="retired_x"):
        JPDATracker.load(tmp_path / "missing.npz")
    never = dict(arrays, retired_ids=np.array([scalars["next_id"]]))
    write_state(tmp_path / "never.npz", never, config, scalars, rng)
    with pytest.raises(StateFileError, match="retired_ids"):
        JPDATracker.load(tmp_path / "never.npz")
    bad_p = dict(arrays, retired_P=-arrays["retired_P"])
    write_state(tmp_path / "bad_p.npz", bad_p, config, scalars, rng)
    with pytest.raises(StateFileError, match="retired_P"):
        JPDATracker.load(tmp_path / "bad_p.npz")


@pytest.mark.parametrize("value", [-1.0, math.nan, math.inf, True, 1j, "60", 10**400])
def test_bad_id_continuation_is_refused_by_name(value):
    with pytest.raises(ValueError, match="id_continuation"):
        TrackerConfig(id_continuation=value)


def _brute_force(new_x, new_P, old_x, old_P, limit):
    """Unambiguous pairs by an explicit inverse (reference): new track a takes old b
    when b is the only old state in a's gate and a the only new state in b's gate."""
    inside = np.array(
        [
            [
                float(
                    (new_x[a] - old_x[b])
                    @ np.linalg.inv(new_P[a] + old_P[b])
                    @ (new_x[a] - old_x[b])
                )
                <= limit
                for b in range(len(old_x))
            ]
            for a in range(len(new_x))
        ],
        dtype=bool,
    ).reshape(len(new_x), len(old_x))
    return {
        a: int(np.flatnonzero(inside[a])[0])
        for a in range(len(new_x))
        if inside[a].sum() == 1 and inside[:, np.flatnonzero(inside[a])[0]].sum() == 1
    }


@settings(max_examples=30, deadline=None)
@given(
    n_new=st.integers(1, 3),
    n_old=st.integers(1, 3),
    seed=st.integers(0, 2**31 - 1),
    spread=st.sampled_from([1.0, 30.0, 300.0, 3000.0]),
    coast=st.sampled_from([0.0, 30.0]),
)
def test_ids_go_to_the_unambiguous_consistent_pairs(n_new, n_old, seed, spread, coast):
    """The new tracks' ids equal the reference matching of their states to the deleted
    tracks' coasted predictions (states drawn around one point, so that some are
    ambiguous; ``coast`` 0: deleted at the same scan)."""
    rng = np.random.default_rng(seed)
    trk = _tracker(100.0)
    x_new = rng.normal(0, spread, (n_new, 4))
    trk.start_tracks(x_new, np.eye(4) * 100.0, confirmed=False, time=50.0)
    old_x = rng.normal(0, spread, (n_old, 4))
    old_P = np.broadcast_to(np.diag([400.0, 400.0, 25.0, 25.0]), (n_old, 4, 4)).copy()
    trk.retired_ids = np.arange(100, 100 + n_old)
    trk.retired_x, trk.retired_P = old_x.copy(), old_P.copy()
    trk.retired_time = np.full(n_old, 50.0 - coast)
    trk.confirmed[:] = True
    ids_before = trk.ids.copy()
    taken = trk._continue_ids(set(), 50.0)
    # reference: each deleted track coasted (CV, white acceleration q = 1)
    t = coast
    F = np.eye(4)
    F[0, 2] = F[1, 3] = t
    Q = np.zeros((4, 4))
    for i, v in ((0, 2), (1, 3)):
        Q[np.ix_([i, v], [i, v])] = [[t**3 / 3, t**2 / 2], [t**2 / 2, t]]
    coasted_x = old_x @ F.T
    coasted_P = F @ old_P @ F.T + Q
    want = _brute_force(trk.x, trk.P, coasted_x, coasted_P, stats.chi2.ppf(CONTINUATION_GATE, 4))
    assert taken == len(want)
    for a in range(n_new):
        expect = 100 + want[a] if a in want else ids_before[a]
        assert trk.ids[a] == expect
    assert sorted(trk.retired_ids.tolist()) == sorted(
        set(range(100, 100 + n_old)) - {100 + b for b in want.values()}
    )


def test_scan_files_fit_the_window_and_report_files_do_not():
    rng = np.random.default_rng(3)
    t = np.arange(60.0) * DT
    starts = rng.uniform(0, 50_000, (20, 2))
    vel = rng.normal(0, 100.0, (20, 2))
    scans = tuple(starts + vel * tk + rng.normal(0, 20.0, (20, 2)) for tk in t)
    f = fit_tracker_settings(Detections(times=t, scans=scans, dim=2))
    assert f.table["id_continuation"] == fitmod.CONTINUATION_SCANS * DT
    assert f.sources["id_continuation"].startswith("fitted")
    # targets reporting one at a time (exponential gaps): a report-like file, no window
    f = fit_tracker_settings(report_like_detections(rng))
    assert f.table["reporting"] == "async"
    assert "id_continuation" not in f.table and "id_continuation" not in f.sources


def test_a_run_counts_continued_ids_across_a_resume(tmp_path):
    from jointtrack.experiments.run import run_detections

    times = DT * np.arange(30.0)
    d = Detections(times=times, scans=tuple(_scan(k, range(10, 15)) for k in range(30)), dim=2)
    table = {
        "clutter_density": 1e-9,
        "measurement_noise": 400.0,
        "process_noise": 1.0,
        "max_speed": 300.0,
        "p_d": 0.9,
        "p_g": 0.9999,
        "id_continuation": 12 * DT,
    }
    full = run_detections(d, table, tmp_path / "full", plots=False, fit=False)
    assert full["association"]["continued_ids"] == 1
    assert any("took the id of a track deleted" in n for n in full["notes"])
    ck = tmp_path / "ck.npz"
    # stopped after the deletion (scan 14), before the new track confirms
    run_detections(
        d,
        table,
        tmp_path / "part",
        checkpoint=ck,
        checkpoint_every=1,
        max_scans=16,
        plots=False,
        fit=False,
    )
    part = run_detections(d, table, tmp_path / "part", resume=ck, plots=False, fit=False)
    assert part["association"]["continued_ids"] == 1
    assert (tmp_path / "part" / "tracks.csv").read_bytes() == (
        tmp_path / "full" / "tracks.csv"
    ).read_bytes()
    off = run_detections(
        d, table | {"id_continuation": 0.0}, tmp_path / "off", plots=False, fit=False
    )
    assert off["association"]["continued_ids"] == 0


@pytest.mark.parametrize(
    ("misses", "existence", "velocity", "hands_over"),
    [
        (1, 0.99, SPEED, True),
        (0, 0.5, SPEED, True),
        (0, 0.99, SPEED, False),
        (2, 0.5, -SPEED, False),
    ],
)
def test_a_new_track_on_a_losing_tracks_target_takes_its_id(
    misses, existence, velocity, hands_over
):
    """A confirmed track losing its target (it missed this scan, or its existence fell
    below r_confirm), with a track confirming in its gate: the new track takes its id
    and the losing one ends — only then, and only if the states agree (position and
    velocity)."""
    trk = _tracker(12 * DT)
    P_old = np.diag([300.0**2, 300.0**2, 30.0**2, 30.0**2])
    (old,) = trk.start_tracks([[0.0, 0.0, SPEED, 0.0]], P_old, time=0.0, existence=existence)
    (new,) = trk.start_tracks([[250.0, 100.0, velocity, 10.0]], np.eye(4) * 100.0, time=0.0)
    trk.misses[0] = misses
    taken = trk._continue_ids({int(old)}, 0.0)
    if hands_over:
        assert taken == 1 and trk.ids.tolist() == [old]
        np.testing.assert_array_equal(trk.x[0], [250.0, 100.0, velocity, 10.0])
    else:
        assert taken == 0 and trk.ids.tolist() == [old, new]


def _retired_and_new(since: float, new_x, window: float) -> JPDATracker:
    """A tracker at t = 100 s holding one confirmed track deleted ``since`` s before
    (state at deletion: 5 m/s along x, position σ 400 m, velocity σ 20 m/s) and one
    track confirming now at ``new_x``; process noise 24 m²/s³ (quickstart's fit)."""
    trk = _tracker(window, process_noise=24.0)
    (new,) = trk.start_tracks([new_x], np.diag([60.0**2] * 2 + [10.0**2] * 2), time=100.0)
    trk.retired_ids = np.array([new + 100])
    trk.retired_x = np.array([[0.0, 0.0, 5.0, 0.0]])
    trk.retired_P = np.diag([400.0**2] * 2 + [20.0**2] * 2)[None]
    trk.retired_time = np.array([100.0 - since])
    return trk


def test_the_fitted_window_refuses_a_new_aircraft_where_an_old_one_ended():
    """The fitted window (scan files: CONTINUATION_SCANS scan intervals) is what a
    rebirth takes — a one-point birth confirms two scans after its first return, plus
    one missed scan. A target that slowed and vanished (an aircraft landing) and a new
    track confirming 50 s later 3 km away at 70 m/s (one taking off): the deleted
    track's prediction coasted 50 s is so wide that the new track passes its χ²₄(0.99)
    gate — on quickstart eight such hand-overs mixed two aircraft each, all 50–80 s
    after the deletion. The same new track 20 s after the deletion still takes the id."""
    window = fitmod.CONTINUATION_SCANS * DT
    far = [3000.0 * math.cos(0.5), 3000.0 * math.sin(0.5), 70.0, 0.0]
    late = _retired_and_new(50.0, far, 12 * DT)  # the wide gate itself admits it
    assert late._continue_ids(set(), 100.0) == 1
    late = _retired_and_new(50.0, far, window)
    assert late._continue_ids(set(), 100.0) == 0 and late.ids.tolist() == [1]
    soon = _retired_and_new(20.0, [500.0, 50.0, 8.0, 1.0], window)
    assert soon._continue_ids(set(), 100.0) == 1 and soon.ids.tolist() == [101]
