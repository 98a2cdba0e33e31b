"""Track history (JPDATracker.history / TrackHistory) and datetime scan times."""

from __future__ import annotations

import datetime as dt
import sys
import types

import numpy as np
import pytest

import jointtrack.trackers.jpda as jpda_module
from jointtrack.scenarios import crossing
from jointtrack.trackers import JPDATracker, StateFileError, TrackerConfig, TrackHistory
from jointtrack.trackers.history import iso_from_ns, ns_from_iso, scan_time_ns
from jointtrack.trackers.state_io import read_state, write_state

UTC = dt.UTC
T0 = dt.datetime(2024, 3, 1, 12, 0, 0)  # naive = UTC


def _config(**kw):
    sc = crossing(seed=3)
    base = dict(
        process_noise=max(sc.process_noise, 0.05),
        measurement_noise=float(sc.R[0, 0]),
        p_d=sc.p_d,
        clutter_density=sc.clutter_density,
        max_speed=15.0,
    )
    base.update(kw)
    return TrackerConfig(**base)


def _run(trk, n=40, times=None):
    sc = crossing(seed=3)
    times = sc.times if times is None else times
    return [trk.step(t, z) for t, z in list(zip(times, sc.detections, strict=False))[:n]]


def _stack(results):
    rows = [(r.time, r.ids, r.x, r.P, r.existence) for r in results if len(r.ids)]
    time = np.concatenate([np.full(len(r[1]), r[0]) for r in rows])
    return (time, *(np.concatenate(col) for col in list(zip(*rows, strict=True))[1:]))


# ------------------------------------------------------------------ history
@pytest.mark.parametrize("existence", [False, True])
def test_history_is_every_confirmed_estimate_of_every_scan(existence):
    trk = JPDATracker(_config(existence=existence))
    results = _run(trk)
    h = trk.history()
    assert isinstance(h, TrackHistory)
    time, ids, x, P, ex = _stack(results)
    assert len(h) == len(time) > 50
    np.testing.assert_array_equal(h.time, time)
    np.testing.assert_array_equal(h.track_id, ids)
    np.testing.assert_array_equal(h.x, x)
    np.testing.assert_array_equal(h.P, P)
    np.testing.assert_array_equal(h.existence, ex)
    assert h.x.shape == (len(h), 4) and h.P.shape == (len(h), 4, 4) and h.state_dim == 4
    assert h.time.dtype == float and h.track_id.dtype == np.int64
    if existence:
        assert (h.existence < 1).any()
    else:
        assert (h.existence == 1).all()
    # one row per (scan time, track id), in scan order
    pairs = set(zip(h.time.tolist(), h.track_id.tolist(), strict=True))
    assert len(pairs) == len(h)
    assert (np.diff(h.time) >= 0).all()
    assert h.time_origin is None


def test_history_rows_are_copies_and_read_only():
    trk = JPDATracker(_config())
    results = _run(trk, 20)
    before = trk.history().x.copy()
    for r in results:  # callers may change their ScanResults freely
        r.x[:] = -1.0
    trk.x[:] = 7.0  # and the tracker keeps running on its own arrays
    h = trk.history()
    np.testing.assert_array_equal(h.x, before)
    with pytest.raises(ValueError):
        h.x[0, 0] = 1.0
    # repeated calls (the rows are consolidated) give the same table
    np.testing.assert_array_equal(trk.history().P, h.P)


def test_track_and_iteration_group_rows_by_track():
    trk = JPDATracker(_config())
    _run(trk)
    h = trk.history()
    groups = list(h)
    ids = [tid for tid, _ in groups]
    assert ids == sorted(set(h.track_id.tolist())) == h.track_ids.tolist()
    assert len(ids) >= 2
    assert sum(len(rows) for _, rows in groups) == len(h)
    for tid, rows in groups:
        assert isinstance(tid, int)
        assert (rows.track_id == tid).all()
        assert (np.diff(rows.time) > 0).all()
        one = h.track(tid)
        np.testing.assert_array_equal(one.x, h.x[h.track_id == tid])
        np.testing.assert_array_equal(one.time, rows.time)
    assert set(dict(h)) == set(ids)
    with pytest.raises(KeyError, match="track 999"):
        h.track(999)
    assert "rows" in repr(h)


def test_columns_are_plain_1d_and_round_trip_through_csv(tmp_path):
    trk = JPDATracker(_config())
    _run(trk, 30)
    h = trk.history()
    cols = h.to_dict()
    names = h.columns()
    assert list(cols) == names
    assert names[:2] == ["time", "track_id"] and names[-1] == "existence"
    assert names[2:6] == ["x_0", "x_1", "x_2", "x_3"]
    p_names = [n for n in names if n.startswith("P_")]
    assert len(p_names) == 4 * 5 // 2 and "P_0_3" in p_names and "P_3_0" not in p_names
    for v in cols.values():
        assert v.ndim == 1 and len(v) == len(h)
    np.testing.assert_array_equal(cols["P_1_3"], h.P[:, 1, 3])
    np.testing.assert_array_equal(cols["x_2"], h.x[:, 2])
    # CSV and back
    path = tmp_path / "tracks.csv"
    np.savetxt(
        path,
        np.column_stack(list(cols.values())),
        delimiter=",",
        header=",".join(names),
        comments="",
        fmt="%.17g",
    )
    data = np.genfromtxt(path, delimiter=",", names=True)
    back = TrackHistory.from_dict({n: data[n] for n in data.dtype.names})
    np.testing.assert_array_equal(back.track_id, h.track_id)
    np.testing.assert_array_equal(back.x, h.x)
    np.testing.assert_allclose(back.P, 0.5 * (h.P + h.P.transpose(0, 2, 1)), rtol=0, atol=0)


def test_to_pandas_without_pandas_raises_a_clear_import_error(monkeypatch):
    trk = JPDATracker(_config())
    _run(trk, 10)
    monkeypatch.setitem(sys.modules, "pandas", None)  # import pandas → ImportError
    with pytest.raises(ImportError, match="needs pandas.*to_dict"):
        trk.history().to_pandas()


def test_to_pandas_builds_a_frame_of_the_columns(monkeypatch):
    fake = types.ModuleType("pandas")

    class DataFrame(dict):
        def __init__(self, data):
            super().__init__(data)
            self.attrs = {}

    fake.DataFrame = DataFrame
    monkeypatch.setitem(sys.modules, "pandas", fake)
    trk = JPDATracker(_config())
    _run(trk, 15, times=[T0 + dt.timedelta(seconds=k) for k in range(15)])
    h = trk.history()
    df = h.to_pandas()
    assert list(df) == h.columns()
    np.testing.assert_array_equal(df["x_0"], h.x[:, 0])
    assert df.attrs["time_origin"] == "2024-03-01T12:00:00+00:00"


def test_to_pandas_with_real_pandas():
    pytest.importorskip("pandas")
    trk = JPDATracker(_config())
    _run(trk, 15)
    h = trk.history()
    df = h.to_pandas()
    assert list(df.columns) == h.columns() and len(df) == len(h)


def test_keep_history_false_records_nothing_and_tracks_the_same():
    a = JPDATracker(_config(), keep_history=False)
    b = JPDATracker(_config())
    ra, rb = _run(a), _run(b)
    for x, y in zip(ra, rb, strict=True):
        np.testing.assert_array_equal(x.x, y.x)
    assert a._history_rows == []
    with pytest.raises(RuntimeError, match="keep_history=False"):
        a.history()
    assert len(b.history()) > 0
    b.clear_history()
    assert len(b.history()) == 0 and b.history().x.shape == (0, 4)


def test_a_failing_step_adds_no_rows_and_the_retry_adds_one_scan(monkeypatch):
    sc = crossing(seed=3)
    trk = JPDATracker(_config())
    _run(trk, 25)
    before = trk.history()

    def boom(*a, **k):
        raise RuntimeError("injected")

    monkeypatch.setattr(jpda_module, "pda_pairs_update", boom)
    with pytest.raises(RuntimeError, match="injected"):
        trk.step(sc.times[25], sc.detections[25])
    monkeypatch.undo()
    with pytest.raises(ValueError):  # bad input fails too, and adds nothing
        trk.step(sc.times[25], np.zeros((2, 3)))
    h = trk.history()
    assert len(h) == len(before)
    np.testing.assert_array_equal(h.x, before.x)
    r = trk.step(sc.times[25], sc.detections[25])
    h = trk.history()
    assert len(h) == len(before) + len(r.ids) and len(r.ids)
    np.testing.assert_array_equal(h.x[len(before) :], r.x)


def test_history_is_not_saved_load_starts_empty(tmp_path):
    sc = crossing(seed=3)
    trk = JPDATracker(_config())
    _run(trk, 20)
    assert len(trk.history()) > 0
    # the saved/restored state has no track-history rows
    assert set(trk.state_dict()) == {
        *JPDATracker._ARRAYS,
        *JPDATracker._SCALARS,
        "config",
        "rng",
    }
    path = trk.save(tmp_path / "s.npz")
    loaded = JPDATracker.load(path)
    assert len(loaded.history()) == 0
    r = loaded.step(sc.times[20], sc.detections[20])
    h = loaded.history()
    assert len(h) == len(r.ids) and (h.time == sc.times[20]).all()
    off = JPDATracker.load(path, keep_history=False)
    off.step(sc.times[20], sc.detections[20])
    with pytest.raises(RuntimeError):
        off.history()


def test_track_logic_bits_still_round_trip_under_their_state_name(tmp_path):
    trk = JPDATracker(_config())
    _run(trk, 20)
    assert callable(trk.history)
    np.testing.assert_array_equal(trk.state_dict()["history"], trk.hit_history)
    arrays, *_ = read_state(trk.save(tmp_path / "s.npz"))
    np.testing.assert_array_equal(arrays["history"], trk.hit_history)
    np.testing.assert_array_equal(JPDATracker.load(tmp_path / "s.npz").hit_history, trk.hit_history)


# ------------------------------------------------------------------ datetimes
def _datetimes(kind, n=40):
    secs = crossing(seed=3).times[:n]
    if kind == "naive":
        return [T0 + dt.timedelta(seconds=float(s)) for s in secs]
    if kind == "aware":  # the same instants, in UTC+05:30
        tz = dt.timezone(dt.timedelta(hours=5, minutes=30))
        return [
            (T0 + dt.timedelta(seconds=float(s))).replace(tzinfo=UTC).astimezone(tz) for s in secs
        ]
    if kind == "datetime64":
        return [
            np.datetime64("2024-03-01T12:00:00", "ns") + np.timedelta64(int(s), "s") for s in secs
        ]
    raise AssertionError(kind)


@pytest.mark.parametrize("kind", ["naive", "aware", "datetime64"])
def test_datetime_scans_track_exactly_like_seconds(kind):
    ref = JPDATracker(_config())
    trk = JPDATracker(_config())
    r_ref = _run(ref)
    r_dt = _run(trk, times=_datetimes(kind))
    for a, b in zip(r_ref, r_dt, strict=True):
        assert isinstance(b.time, float) and b.time == a.time
        np.testing.assert_array_equal(a.ids, b.ids)
        np.testing.assert_array_equal(a.x, b.x)
        np.testing.assert_array_equal(a.P, b.P)
    assert trk.time_origin == "2024-03-01T12:00:00+00:00"
    h = trk.history()
    assert h.time_origin == trk.time_origin
    np.testing.assert_array_equal(h.time, ref.history().time)
    expected = np.datetime64("2024-03-01T12:00:00", "ns") + (h.time * 1e9).astype("timedelta64[ns]")
    np.testing.assert_array_equal(h.datetimes(), expected)
    with pytest.raises(ValueError, match="no time_origin"):
        ref.history().datetimes()


def test_datetime64_keeps_nanoseconds_and_any_unit():
    trk = JPDATracker(_config())
    t0 = np.datetime64("2024-03-01T12:00:00.000000001", "ns")
    assert trk.step(t0, np.zeros((0, 2))).time == 0.0
    assert trk.time_origin == "2024-03-01T12:00:00.000000001+00:00"
    assert trk.step(t0 + np.timedelta64(1500, "ns"), np.zeros((0, 2))).time == 1.5e-6
    assert trk.step(np.datetime64("2024-03-01T12:00:02", "s"), np.zeros((0, 2))).time == 2.0 - 1e-9
    assert trk.step(np.datetime64("2024-03-02", "D"), np.zeros((0, 2))).time == 43200 - 1e-9
    # a 0-d datetime64 array counts as a datetime, too
    assert trk.step(
        np.array(np.datetime64("2024-03-03", "D")), np.zeros((0, 2))
    ).time == pytest.approx(129600.0)


def test_mixing_numbers_and_datetimes_is_refused_and_leaves_the_tracker_unchanged():
    sc = crossing(seed=3)
    num = JPDATracker(_config())
    num.step(0.0, sc.detections[0])
    snap = num.state_dict()
    with pytest.raises(ValueError, match="numbers.*datetimes.*not both"):
        num.step(T0, sc.detections[1])
    assert num.state_dict()["n_scans"] == snap["n_scans"] and num.time_origin is None

    dtr = JPDATracker(_config())
    dtr.step(T0, sc.detections[0])
    with pytest.raises(ValueError, match="is a number.*datetimes.*not both"):
        dtr.step(1.0, sc.detections[1])
    with pytest.raises(ValueError, match="is a number"):
        dtr.step(np.float64(1.0), sc.detections[1])
    assert dtr.n_scans == 1 and dtr.time_origin == "2024-03-01T12:00:00+00:00"
    dtr.step(T0 + dt.timedelta(seconds=1), sc.detections[1])
    assert dtr.n_scans == 2


def test_bad_datetime_scans():
    trk = JPDATracker(_config())
    with pytest.raises(ValueError, match="NaT"):
        trk.step(np.datetime64("NaT"), np.zeros((0, 2)))
    with pytest.raises(TypeError, match="datetime.datetime or a numpy.datetime64"):
        trk.step(dt.date(2024, 3, 1), np.zeros((0, 2)))
    # a first datetime scan that fails does not fix the origin
    with pytest.raises(ValueError, match="shape"):
        trk.step(T0, np.zeros((1, 3)))
    assert trk.time_origin is None and trk.time is None
    trk.step(T0 + dt.timedelta(seconds=5), np.zeros((0, 2)))
    assert trk.time_origin == "2024-03-01T12:00:05+00:00"
    with pytest.raises(ValueError, match="must increase"):
        trk.step(T0, np.zeros((0, 2)))


def test_time_origin_is_saved_and_a_datetime_run_continues_after_load(tmp_path):
    sc = crossing(seed=3)
    times = _datetimes("naive")
    ref = JPDATracker(_config())
    _run(ref, times=times)
    trk = JPDATracker(_config())
    _run(trk, 20, times=times)
    path = trk.save(tmp_path / "s.npz")
    loaded = JPDATracker.load(path)
    assert loaded.time_origin == "2024-03-01T12:00:00+00:00"
    for k in range(20, 40):
        r = loaded.step(times[k], sc.detections[k])
    np.testing.assert_array_equal(r.x, ref.x[ref.confirmed])
    assert loaded.history().time_origin == loaded.time_origin
    with pytest.raises(ValueError, match="not both"):
        JPDATracker.load(path).step(100.0, sc.detections[40])
    # a numeric run's file has no origin and keeps refusing datetimes
    num = JPDATracker(_config())
    _run(num, 5)
    back = JPDATracker.load(num.save(tmp_path / "n.npz"))
    assert back.time_origin is None
    with pytest.raises(ValueError, match="not both"):
        back.step(T0, sc.detections[5])


def test_damaged_time_origin_in_a_state_file_is_refused(tmp_path):
    trk = JPDATracker(_config())
    _run(trk, 5, times=_datetimes("naive"))
    path = trk.save(tmp_path / "s.npz")
    arrays, config, scalars, rng = read_state(path)
    scalars["time_origin"] = "yesterday"
    write_state(path, arrays, config, scalars, rng)
    with pytest.raises(StateFileError, match="time_origin"):
        JPDATracker.load(path)


@pytest.mark.parametrize(
    "ns",
    [0, 1, 999, 1_709_294_400_123_456_789, -1, -86_400 * 10**9 * 365 * 100 + 7],
)
def test_iso_origin_round_trips_to_the_nanosecond(ns):
    s = iso_from_ns(ns)
    assert s.endswith("+00:00")
    assert ns_from_iso(s) == ns
    assert ns_from_iso(s.replace("+00:00", "")) == ns  # naive = UTC


def test_scan_time_ns_agrees_across_types():
    aware = dt.datetime(2024, 3, 1, 7, 0, tzinfo=dt.timezone(dt.timedelta(hours=-5)))
    want = scan_time_ns(T0)
    assert scan_time_ns(aware) == want
    assert scan_time_ns(np.datetime64("2024-03-01T12:00")) == want
    assert scan_time_ns(np.datetime64(2500, "ps")) == 2  # sub-ns units: floor to ns
    assert scan_time_ns(np.datetime64("2024-03", "M")) == scan_time_ns(dt.datetime(2024, 3, 1))
    assert scan_time_ns(T0.replace(tzinfo=UTC)) == want == 1_709_294_400 * 10**9
