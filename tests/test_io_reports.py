"""Self-reports (AIS, ADS-B): readers, degradation, Stone Soup's demo reduction, views."""

from __future__ import annotations

import datetime
import gzip
import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from jointtrack.io import DetectionFileError
from jointtrack.io.geodetic import FOOT, KNOT, LocalFrame, velocity_en
from jointtrack.io.reports import (
    Reports,
    read_ais_csv,
    read_opensky_states,
    read_reports,
    read_traffic_records,
)

T0 = datetime.datetime(2016, 1, 12, 13, 2, 11, 218000)
AIS_HEADER = "Time,MMSI,Latitude_degrees,Longitude_degrees,COG_degrees,SOG_knots\n"
OPENSKY_HEADER = (
    "time,icao24,lat,lon,velocity,heading,vertrate,callsign,onground,alert,spi,squawk,"
    "baroaltitude,geoaltitude,lastposupdate,lastcontact\n"
)
SETTINGS = settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)

lats = st.floats(50.0, 51.0, allow_nan=False)
lons = st.floats(-1.5, -0.5, allow_nan=False)


def _stamp(ms: int) -> str:
    return (T0 + datetime.timedelta(milliseconds=ms)).strftime("%Y-%m-%d %H:%M:%S.%f")[:-3]


def _ais_file(tmp_path, rows, name="ais.csv"):
    """rows: (ms since T0, mmsi, lat, lon, cog or None, sog or None)."""
    p = tmp_path / name
    body = "".join(
        f"{_stamp(ms)},{m},{la!r},{lo!r},{'' if c is None else repr(c)},"
        f"{'' if s is None else repr(s)}\n"
        for ms, m, la, lo, c, s in rows
    )
    p.write_text(AIS_HEADER + body)
    return p


@st.composite
def ais_rows(draw, max_size=30):
    """Time-ordered AIS rows, at most one report per (time, MMSI) (Stone Soup keeps
    an arbitrary one of such ties)."""
    n = draw(st.integers(1, max_size))
    ms, seen, rows = 0, set(), []
    for _ in range(n):
        ms += draw(st.integers(0, 40_000))
        m = draw(st.sampled_from(["235070762", "235013375", "244630", "1", "99"]))
        if (ms, m) in seen:
            continue
        seen.add((ms, m))
        rows.append((ms, m, draw(lats), draw(lons), 12.5, 3.0))
    return rows


# ----------------------------------------------------------------------------- readers


@SETTINGS
@given(
    rows=st.lists(
        st.tuples(
            st.integers(0, 10**7),
            st.sampled_from(["235070762", "7", "abc"]),
            st.floats(-90, 90),
            st.floats(-180, 360),
            st.none() | st.floats(0, 359.9),
            st.none() | st.floats(0, 102.2),
        ),
        min_size=1,
        max_size=20,
    )
)
def test_ais_values_are_read_exactly_and_sorted_by_time(tmp_path, rows):
    r = read_ais_csv(_ais_file(tmp_path, rows))
    order = sorted(range(len(rows)), key=lambda i: rows[i][0])  # stable, like the reader
    first = rows[order[0]][0]
    want = (T0 + datetime.timedelta(milliseconds=first)).replace(tzinfo=datetime.UTC)
    assert r.time_origin.endswith("Z")
    assert datetime.datetime.fromisoformat(r.time_origin) == want
    for j, i in enumerate(order):
        ms, m, la, lo, c, s = rows[i]
        assert r.times[j] == (ms - first) / 1000
        assert (r.identity[j], r.lat[j], r.lon[j]) == (m, la, lo)
        assert np.isnan(r.course[j]) if c is None else r.course[j] == c
        assert np.isnan(r.speed[j]) if s is None else r.speed[j] == s * KNOT
    assert not r.is_clutter.any() and np.isnan(r.alt).all() and r.skipped == 0


def test_ais_not_available_codes_are_unknown(tmp_path):
    r = read_ais_csv(_ais_file(tmp_path, [(0, "1", 50.0, -1.0, 360.0, 102.3)]))
    assert np.isnan(r.course[0]) and np.isnan(r.speed[0])
    d = read_ais_csv(_ais_file(tmp_path, [(0, "1", 50.0, -1.0, 360.0, 0.0)])).detections()
    assert d.velocities[0].tolist() == [[0.0, 0.0]]  # at rest, whatever the course


@pytest.mark.parametrize(
    ("body", "row", "column", "words"),
    [
        ("2016-01-12 13:02:11.218,1,abc,-1.0,1,1\n", 1, "latitude_degrees", "'abc'"),
        ("2016-01-12 13:02:11.218,1,91,-1.0,1,1\n", 1, "latitude_degrees", "outside"),
        ("2016-01-12 13:02:11.218,1,50,400,1,1\n", 1, "longitude_degrees", "outside"),
        ("2016-01-12 13:02:11.218,1,50,1,1,-1\n", 1, "sog_knots", "negative"),
        ("2016-01-12 13:02:11.218,1,50,1,1,1\nyesterday,1,50,1,1,1\n", 2, "time", "timestamp"),
        ("2016-13-12 13:02:11.218,1,50,1,1,1\n", 1, "time", "valid"),
        ("2016-01-12 13:02:11.218,1,50,,1,1\n", 1, "longitude_degrees", "empty"),
        ("2016-01-12 13:02:11.218,1,50,1,inf,1\n", 1, "cog_degrees", "non-finite"),
    ],
)
def test_ais_bad_cells_name_file_row_column(tmp_path, body, row, column, words):
    p = tmp_path / "bad.csv"
    p.write_text(AIS_HEADER + body)
    with pytest.raises(DetectionFileError) as info:
        read_ais_csv(p)
    e = info.value
    assert (e.row, e.line, e.column) == (row, row + 1, column), str(e)
    assert str(p) in str(e) and words in str(e)


def test_ais_missing_columns_are_listed(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("Time,MMSI,Lat\n2016-01-12 13:02:11,1,50\n")
    with pytest.raises(DetectionFileError, match="latitude_degrees, longitude_degrees"):
        read_ais_csv(p)


def _opensky_file(tmp_path, rows):
    """rows: (unix s, icao24, lat, lon, velocity, heading, baro, geo); None = empty cell."""

    def cell(v):
        return "" if v is None else repr(v) if isinstance(v, float) else str(v)

    p = tmp_path / "states.csv"
    body = "".join(
        ",".join(
            [cell(t), ic, cell(la), cell(lo), cell(v), cell(h), "0.0", "BOX413  ", "False",
             "False", "False", "1174.0", cell(b), cell(g), "0", "0"]
        ) + "\n"
        for t, ic, la, lo, v, h, b, g in rows
    )  # fmt: skip
    p.write_text(OPENSKY_HEADER + body)
    return p


@SETTINGS
@given(
    rows=st.lists(
        st.tuples(
            st.integers(1_626_098_400, 1_626_099_600),
            st.sampled_from(["3c4591", "407a19"]),
            st.none() | st.floats(-90, 90),
            st.floats(-180, 180),
            st.none() | st.floats(0, 300),
            st.none() | st.floats(0, 360),
            st.none() | st.floats(-100, 12000),
            st.none() | st.floats(-100, 12000),
        ),
        min_size=1,
        max_size=15,
    )
)
def test_opensky_rows_without_position_are_skipped_and_counted(tmp_path, rows):
    r = read_opensky_states(_opensky_file(tmp_path, rows))
    kept = sorted((row for row in rows if row[2] is not None), key=lambda row: row[0])
    assert r.skipped == len(rows) - len(kept) and len(r) == len(kept)
    for j, (t, ic, la, lo, v, h, b, g) in enumerate(kept):
        assert r.times[j] == t - kept[0][0] and r.identity[j] == ic
        assert (r.lat[j], r.lon[j]) == (la, lo)
        want_alt = g if g is not None else b
        assert np.isnan(r.alt[j]) if want_alt is None else r.alt[j] == want_alt
        assert np.isnan(r.speed[j]) if v is None else r.speed[j] == v
        assert np.isnan(r.course[j]) if h is None else r.course[j] == h
    if kept:
        stamp = datetime.datetime.fromtimestamp(kept[0][0], datetime.UTC)
        assert r.time_origin == stamp.strftime("%Y-%m-%dT%H:%M:%SZ")


def test_opensky_bad_cells(tmp_path):
    p = _opensky_file(tmp_path, [(1626098400, "a", 50.0, 1.0, -3.0, 1.0, None, None)])
    with pytest.raises(DetectionFileError) as info:
        read_opensky_states(p)
    assert (info.value.row, info.value.column) == (1, "velocity")
    p = _opensky_file(tmp_path, [(1626098400, "a", 95.0, 1.0, 3.0, 1.0, None, None)])
    with pytest.raises(DetectionFileError, match="outside") as info:
        read_opensky_states(p)
    assert info.value.column == "lat"


def _traffic(records, path, gz):
    data = json.dumps(records).encode()
    path.write_bytes(gzip.compress(data) if gz else data)
    return path


@SETTINGS
@given(
    recs=st.lists(
        st.fixed_dictionaries(
            {
                "timestamp": st.integers(1_533_101_250_000, 1_533_101_950_000),
                "icao24": st.sampled_from(["3003ae", "4ca2bf"]),
                "latitude": st.none() | st.floats(-90, 90),
                "longitude": st.floats(-180, 180),
                "altitude": st.none() | st.floats(-1000, 45000),
                "groundspeed": st.none() | st.floats(0, 600),
                "track": st.none() | st.floats(0, 360),
                "callsign": st.just("AFR12"),
            }
        ),
        min_size=1,
        max_size=15,
    ),
    gz=st.booleans(),
    iso=st.booleans(),
)
def test_traffic_records_units_and_skips(tmp_path, recs, gz, iso):
    if iso:  # pandas' date_format="iso"
        for r in recs:
            stamp = datetime.datetime.fromtimestamp(r["timestamp"] / 1000, datetime.UTC)
            r["timestamp"] = stamp.strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z"
    r = read_traffic_records(_traffic(recs, tmp_path / ("t.json.gz" if gz else "t.json"), gz))
    assert read_reports(tmp_path / ("t.json.gz" if gz else "t.json")).times.tolist() == (
        r.times.tolist()
    )
    kept = [x for x in recs if x["latitude"] is not None]
    assert r.skipped == len(recs) - len(kept) and len(r) == len(kept)
    ms = np.array(
        [
            x["timestamp"]
            if not iso
            else round(datetime.datetime.fromisoformat(x["timestamp"]).timestamp() * 1000)
            for x in kept
        ]
    )
    order = np.argsort(ms, kind="stable")
    for j, i in enumerate(order.tolist()):
        x = kept[i]
        assert r.times[j] == (ms[i] - ms[order[0]]) / 1000
        assert (r.lat[j], r.lon[j], r.identity[j]) == (x["latitude"], x["longitude"], x["icao24"])
        for got, key, unit in ((r.alt, "altitude", FOOT), (r.speed, "groundspeed", KNOT)):
            assert np.isnan(got[j]) if x[key] is None else got[j] == x[key] * unit
        assert np.isnan(r.course[j]) if x["track"] is None else r.course[j] == x["track"]


@pytest.mark.parametrize(
    ("records", "row", "column", "words"),
    [
        ({"a": 1}, None, None, "list of records"),
        ([1], 1, None, "not an object"),
        ([{"timestamp": 0, "latitude": 1.0, "longitude": 1.0}], 1, "icao24", "missing"),
        ([{"timestamp": "x", "icao24": "a", "latitude": 1.0, "longitude": 1.0}], 1, "timestamp",
         "neither"),
        ([{"timestamp": 0, "icao24": "a", "latitude": True, "longitude": 1.0}], 1, "latitude",
         "not a number"),
        ([{"timestamp": 0, "icao24": "a", "latitude": 1.0, "longitude": 1.0, "track": 1j}], None,
         None, "JSON"),
    ],
)  # fmt: skip
def test_traffic_bad_records(tmp_path, records, row, column, words):
    p = tmp_path / "t.json"
    if isinstance(records, list) and records and isinstance(records[0], dict):
        text = json.dumps(records, default=str).replace('"1j"', "1j")
    else:
        text = json.dumps(records)
    p.write_text(text)
    with pytest.raises(DetectionFileError) as info:
        read_traffic_records(p)
    assert (info.value.row, info.value.column) == (row, column), str(info.value)
    assert words in str(info.value) and str(p) in str(info.value)


def test_read_reports_sniffs_the_format(tmp_path):
    a = _ais_file(tmp_path, [(0, "1", 50.0, -1.0, 1.0, 1.0)])
    o = _opensky_file(tmp_path, [(1626098400, "a", 50.0, 1.0, 3.0, 1.0, None, None)])
    assert read_reports(a).identity.tolist() == ["1"]
    assert read_reports(o).identity.tolist() == ["a"]
    assert read_reports(o, format="opensky").identity.tolist() == ["a"]
    other = tmp_path / "other.csv"
    other.write_text("time,x,y\n0,1,2\n")
    with pytest.raises(DetectionFileError, match="not a known report format"):
        read_reports(other)
    with pytest.raises(ValueError, match="format"):
        read_reports(a, format="nmea")
    with pytest.raises(DetectionFileError, match="MMSI|mmsi"):
        read_reports(o, format="ais")


# ----------------------------------------------------------------------------- Reports


def _reports(n=5, **kw):
    base = dict(
        times=np.arange(n, dtype=float),
        time_origin="2016-01-12T13:02:11.218Z",
        lat=np.linspace(50, 51, n),
        lon=np.linspace(-1, 0, n),
    )
    base.update(kw)
    return Reports(**base)


@pytest.mark.parametrize(
    ("kw", "exc", "words"),
    [
        (dict(lat=[True] * 5), TypeError, "lat"),
        (dict(lon=np.zeros(5) + 1j), TypeError, "lon"),
        (dict(lat=np.full(5, 91.0)), ValueError, "lat"),
        (dict(lon=np.full(5, np.nan)), ValueError, "lon"),
        (dict(times=[0, 2, 1, 3, 4.0]), ValueError, "non-decreasing"),
        (dict(identity=[1, 2, 3, 4, 5]), TypeError, "identity"),
        (dict(speed=-np.ones(5)), ValueError, "speed"),
        (dict(time_origin="noon"), ValueError, "time_origin"),
        (dict(lat=np.zeros(4)), ValueError, "shape"),
        (dict(is_clutter=np.zeros(5)), TypeError, "is_clutter"),
        (dict(lat=None), ValueError, "lat"),
        (dict(times=[0.0, 1.0, 2.0, 3.0, True]), TypeError, "times"),
    ],
)
def test_reports_refuse_bad_fields(kw, exc, words):
    with pytest.raises(exc, match=words):
        _reports(**kw)


@pytest.mark.parametrize(
    ("kw", "exc", "words"),
    [
        (dict(p_d=True), TypeError, "p_d"),
        (dict(p_d=1.5), ValueError, "p_d"),
        (dict(p_d=0.5j), TypeError, "p_d"),
        (dict(clutter_rate=float("inf")), ValueError, "clutter_rate"),
        (dict(clutter_rate=-1.0), ValueError, "clutter_rate"),
        (dict(seed=-1), TypeError, "seed"),
        (dict(seed=1.5), TypeError, "seed"),
        (dict(strip_identities=1), TypeError, "strip_identities"),
    ],
)
def test_degrade_refuses_bad_arguments(kw, exc, words):
    with pytest.raises(exc, match=words):
        _reports().degrade(**kw)


def test_degrade_statistics_and_determinism():
    n, span = 20_000, 1000.0
    rng = np.random.default_rng(7)
    r = Reports(
        times=np.sort(rng.uniform(0, span, n)),
        time_origin="2021-07-12T14:00:00Z",
        lat=rng.uniform(51.0, 52.0, n),
        lon=rng.uniform(-2.0, 0.5, n),
        identity=np.array([f"id{i % 50}" for i in range(n)]),
    )
    t_lo, t_hi = float(r.times.min()), float(r.times.max())
    p_d, rate = 0.9, 0.5
    for seed in range(3):
        d = r.degrade(p_d=p_d, clutter_rate=rate, seed=seed)
        real, fake = ~d.is_clutter, d.is_clutter
        # kept reports: Binomial(n, p_d), within 5 standard deviations
        sd = np.sqrt(n * p_d * (1 - p_d))
        assert abs(real.sum() - n * p_d) < 5 * sd
        # clutter count: Poisson(rate × span), within 5 standard deviations
        mean = rate * (t_hi - t_lo)
        assert abs(fake.sum() - mean) < 5 * np.sqrt(mean)
        assert (d.identity[fake] == "").all() and (d.identity[real] != "").all()
        assert np.isnan(d.speed[fake]).all()
        assert (d.lat[fake] >= 51.0).all() and (d.lat[fake] <= 52.0).all()
        assert (d.lon[fake] >= r.lon.min()).all() and (d.lon[fake] <= r.lon.max()).all()
        assert (d.times[fake] >= t_lo).all() and (d.times[fake] <= t_hi).all()
        assert np.all(np.diff(d.times) >= 0)
        # the kept real reports are a subsequence of the originals
        assert np.isin(d.times[real], r.times).all()
        again = r.degrade(p_d=p_d, clutter_rate=rate, seed=seed)
        for f in ("times", "lat", "lon", "identity", "is_clutter"):
            assert np.array_equal(getattr(d, f), getattr(again, f))
    assert len(r.degrade(p_d=p_d, seed=1)) != len(r.degrade(p_d=p_d, seed=2))
    assert (r.degrade(strip_identities=True).identity == "").all()
    assert len(r.degrade()) == n  # p_d = 1, no clutter: the same reports
    g = np.random.default_rng(3)
    assert len(r.degrade(p_d=0.5, seed=g)) != len(r.degrade(p_d=0.5, seed=g))  # state advances


def test_degrade_clutter_across_the_antimeridian():
    r = _reports(2, lat=[10.0, 11.0], lon=[179.0, -179.0], times=[0.0, 1000.0])
    d = r.degrade(clutter_rate=1.0, seed=0)
    lon = d.lon[d.is_clutter]
    assert lon.size > 800 and np.all((lon >= 179.0) | (lon <= -179.0))


# ----------------------------------------------------------------------------- Stone Soup


def _stonesoup_windows(path, window):
    from stonesoup.feeder.filter import MetadataReducer
    from stonesoup.feeder.time import TimeSyncFeeder
    from stonesoup.reader.generic import CSVDetectionReader

    reader = CSVDetectionReader(
        str(path), state_vector_fields=("Longitude_degrees", "Latitude_degrees"), time_field="Time"
    )
    feed = MetadataReducer(
        TimeSyncFeeder(reader, time_window=datetime.timedelta(seconds=window)), "MMSI"
    )
    out = []
    for time, dets in feed:
        rows = {
            ((d.timestamp - T0) // datetime.timedelta(milliseconds=1), d.metadata["MMSI"])
            for d in dets
        }
        out.append(((time - T0) // datetime.timedelta(milliseconds=1), rows))
    return out


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(rows=ais_rows(), window=st.sampled_from([0.5, 1.0, 7.5, 30.0, 60.0]))
def test_reduce_equals_stonesoup_time_sync_and_metadata_reducer(tmp_path, rows, window):
    pytest.importorskip("stonesoup")
    path = _ais_file(tmp_path, rows)
    want = _stonesoup_windows(path, window)
    r = read_ais_csv(path)
    first = rows[0][0]
    k, ends = r.window_index(window)
    red = r.reduce(window)
    k_red, ends_red = red.window_index(window)
    assert np.array_equal(ends_red, ends)
    ms = np.rint(red.times * 1000).astype(int) + first
    got = [
        (
            round(end * 1000) + first,
            set(zip(ms[k_red == j].tolist(), red.identity[k_red == j], strict=True)),
        )
        for j, end in enumerate(ends.tolist())
    ]
    assert got == want
    d = red.detections(scan=window, labels=True)
    assert d.times.tolist() == ends.tolist()
    assert [z.shape[0] for z in d.scans] == [len(rows_j) for _, rows_j in want]
    assert [sorted(lab.tolist()) for lab in d.labels] == [
        sorted(m for _, m in rows_j) for _, rows_j in want
    ]


def test_reduce_keeps_every_row_without_identity():
    r = _reports(
        4, times=[0.0, 1.0, 1.0, 2.0], identity=np.array(["a", "", "", "a"]), lat=[50.0] * 4
    )
    red = r.reduce(10.0)
    assert red.identity.tolist() == ["a", "", "", "a"]  # window 0 = the instant t0 alone
    red = r.reduce(0.5).reduce(10.0)
    assert red.identity.tolist() == ["a", "", "", "a"]
    r = _reports(4, times=[0.0, 1.0, 1.5, 2.0], identity=np.array(["b", "a", "", "a"]))
    assert r.reduce(10.0).times.tolist() == [0.0, 1.5, 2.0]


# ----------------------------------------------------------------------------- views


def test_truth_and_detections_views():
    r = _reports(
        6,
        times=[0.0, 0.0, 1.0, 2.5, 2.5, 4.0],
        identity=np.array(["b", "a", "", "a", "b", "c"]),
        speed=[1.0, 0.0, np.nan, 2.0, 3.0, 4.0],
        course=[90.0, np.nan, 0.0, 180.0, 45.0, np.nan],
        is_clutter=[False, False, True, False, False, False],
    )
    frame = LocalFrame(50.5, -0.5)
    times, ids, pos, names = r.truth(frame)
    assert names == {"a": 0, "b": 1, "c": 2}
    assert times.tolist() == [0.0, 0.0, 2.5, 2.5, 4.0] and ids.tolist() == [1, 0, 0, 1, 2]
    keep = [0, 1, 3, 4, 5]
    assert np.array_equal(pos, frame.to_local(r.lat[keep], r.lon[keep]))
    d = r.detections(frame, labels=True)
    assert d.times.tolist() == [0.0, 1.0, 2.5, 4.0]
    assert [z.shape[0] for z in d.scans] == [2, 1, 2, 1]
    assert np.array_equal(np.concatenate(d.scans), frame.to_local(r.lat, r.lon))
    assert [lab.tolist() for lab in d.labels] == [["b", "a"], [""], ["a", "b"], ["c"]]
    v = np.concatenate(d.velocities)
    want = velocity_en(r.speed, r.course)
    want[1] = 0.0  # at rest: a zero velocity whatever the course
    assert np.array_equal(np.isnan(v), np.isnan(want)) and np.allclose(v, want, equal_nan=True)
    assert d.geo_reference == frame.reference and d.time_origin == r.time_origin
    w = r.detections(frame, scan=2.0, velocities=False)
    assert w.times.tolist() == [0.0, 2.0, 4.0] and w.velocities is None and w.labels is None
    assert [z.shape[0] for z in w.scans] == [2, 1, 3]
    e = r.detections(frame, scan=1.0)  # an empty window between reports stays
    assert e.times.tolist() == [0.0, 1.0, 2.0, 3.0, 4.0]
    assert [z.shape[0] for z in e.scans] == [2, 1, 0, 2, 1]
    with pytest.raises(ValueError, match="scan"):
        r.detections(frame, scan="minute")
    with pytest.raises(ValueError, match="window"):
        r.detections(frame, scan=0.0)
    assert r.frame() == LocalFrame.centre(r.lat, r.lon)
    assert r.frame((50.0, 1.0)) == LocalFrame(50.0, 1.0)


def test_subset():
    r = _reports(5, identity=np.array(list("abcde")))
    assert r.subset(r.lat > 50.4).identity.tolist() == ["c", "d", "e"]
    assert r.subset([4, 0]).identity.tolist() == ["a", "e"]  # time order kept
    assert len(r.subset([])) == 0
    with pytest.raises(ValueError, match="rows"):
        r.subset(np.ones(3, bool))
    with pytest.raises(ValueError, match="rows"):
        r.subset([7])
    with pytest.raises(TypeError, match="rows"):
        r.subset([0.5])
