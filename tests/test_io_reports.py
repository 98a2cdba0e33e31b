"""Self-reports (AIS, ADS-B): readers, degradation, Stone Soup's demo reduction, views."""

from __future__ import annotations

import datetime
import gzip
import json

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
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
            # 181 is AIS's "longitude not available": such rows are left out (tested below)
            st.floats(-180, 360).filter(lambda v: v != 181.0),
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
        ("2016-01-12 13:02:11.218,1,91.5,-1.0,1,1\n", 1, "latitude_degrees", "outside"),
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


# ----------------------------------------------------------------------------- issue 31


def _solent_like(tmp_path, n=20):
    """Ships near the Solent (50.8° N, 1.2° W): AIS rows (ms, mmsi, lat, lon, cog, sog)."""
    rows = [(1000 * k, str(235000000 + k % 3), 50.8 + 1e-3 * k, -1.2 + 1e-3 * k, 90.0, 5.0)
            for k in range(n)]  # fmt: skip
    return _ais_file(tmp_path, rows), rows


@pytest.mark.parametrize("reference", [(-50.8, 178.7), (-50.8, 178.7, 0.0), (0.0, 90.0)])
def test_a_reference_whose_plane_cannot_hold_the_reports_is_refused(tmp_path, reference):
    # issue 31.5: --reference -50.8,178.7 (the antipode) put every track on the other
    # side of the Earth and exited 0: the plane folds the far side onto the near side
    path, _ = _solent_like(tmp_path)
    r = read_ais_csv(path)
    for call in (
        lambda: r.frame(reference),
        lambda: r.detections(reference),
        lambda: r.truth(reference),
        lambda: r.detections(LocalFrame(*reference)),
    ):
        with pytest.raises(ValueError) as info:
            call()
        text = str(info.value)
        assert str(path) in text and "20 of 20 reports" in text and "--reference" in text
        assert "60°" in text and "given reference" in text
    ok = r.frame((50.0, 0.0))  # near the data: kept
    assert ok.reference == (50.0, 0.0, 0.0) and len(r.detections(ok).scans) == 20


def test_reports_spread_beyond_one_plane_are_refused_about_their_centre():
    r = _reports(4, lat=[0.0, 0.0, 0.0, 0.0], lon=[-100.0, -99.0, 99.0, 100.0])
    with pytest.raises(ValueError, match="centre of the reports"):
        r.detections()


# -- 31.7: raw exceptions from the readers, each now an error naming the file


@pytest.mark.parametrize("depth", [10_000, 200_000])
@pytest.mark.parametrize("brackets", ["[]", '{"a":}'])
def test_traffic_json_nested_past_the_parser_is_named(tmp_path, depth, brackets):
    p = tmp_path / "deep.json"
    if brackets == "[]":
        p.write_text("[" * depth + "]" * depth)
    else:
        p.write_text('{"a":' * depth + "1" + "}" * depth)
    with pytest.raises(DetectionFileError, match="too deeply") as info:
        read_traffic_records(p)
    assert str(p) in str(info.value)


_RECORD = {"timestamp": 1_533_101_250_000, "icao24": "3c4591", "latitude": 48.5,
           "longitude": 3.8, "altitude": 35000.0, "groundspeed": 400.0, "track": 90.0}  # fmt: skip


@SETTINGS
@given(
    digits=st.integers(310, 20_000),
    field=st.sampled_from(
        ["timestamp", "icao24", "latitude", "longitude", "altitude", "groundspeed", "track"]
    ),
    row=st.integers(0, 3),
    sign=st.sampled_from(["", "-"]),
)
def test_traffic_numbers_of_thousands_of_digits_are_named(tmp_path, digits, field, row, sign):
    # a 5,000-digit number raised "Exceeds the limit (4300 digits)", no file named
    recs = [dict(_RECORD, timestamp=_RECORD["timestamp"] + k) for k in range(4)]
    text = json.dumps(recs)
    big = sign + "7" * digits
    marker = f'"{field}": "BIG{row}"'
    recs[row][field] = f"BIG{row}"
    text = json.dumps(recs).replace(marker, f'"{field}": {big}')
    p = tmp_path / "big.json"
    p.write_text(text)
    with pytest.raises(DetectionFileError) as info:
        read_traffic_records(p)
    e = info.value
    assert (e.row, e.column) == (row + 1, field) and str(p) in str(e), str(e)
    assert f"{digits + len(sign):,} characters" in str(e)


@SETTINGS
@given(value=st.integers(2**43 + 1, 10**300) | st.integers(-(10**300), -(2**43) - 1))
def test_traffic_timestamps_beyond_the_unix_range_are_named(tmp_path, value):
    # "timestamp": 10**30 raised a TypeError from numpy
    p = _traffic([dict(_RECORD), dict(_RECORD, timestamp=value)], tmp_path / "t.json", False)
    with pytest.raises(DetectionFileError, match="outside the Unix times read") as info:
        read_traffic_records(p)
    assert (info.value.row, info.value.column) == (2, "timestamp")


def test_traffic_gzip_inflating_past_the_cap_is_refused_while_streaming(tmp_path, monkeypatch):
    # a 2 MB gzip inflating to 2 GiB raised MemoryError: gzip.decompress inflated it all.
    # Here a 64 MiB bomb against a 1 MiB cap: refused, naming the cap, and the reader
    # never holds much more than the cap (traced), whatever the file inflates to.
    import tracemalloc
    import zlib

    import jointtrack.io.reports as reports

    assert reports.MAX_JSON_BYTES == 256 * 2**20  # the stated cap
    monkeypatch.setattr(reports, "MAX_JSON_BYTES", 2**20)
    body = b"[" + b" " * (64 * 2**20) + b"]"
    z = zlib.compressobj(9, zlib.DEFLATED, 31)  # gzip container
    bomb = tmp_path / "bomb.json.gz"
    bomb.write_bytes(z.compress(body) + z.flush())
    del body
    assert bomb.stat().st_size < 2**20
    tracemalloc.start()
    try:
        with pytest.raises(DetectionFileError, match="inflates to more than 1,048,576") as info:
            read_traffic_records(bomb)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert "MAX_JSON_BYTES" in str(info.value) and str(bomb) in str(info.value)
    assert peak < 8 * 2**20, peak
    plain = tmp_path / "big.json"
    plain.write_bytes(b"[" + b" " * 2**20 + b"]")
    with pytest.raises(DetectionFileError, match="holds more than 1,048,576"):
        read_traffic_records(plain)
    # at the cap exactly: read
    ok = json.dumps([_RECORD]).encode()
    fits = tmp_path / "fits.json.gz"
    fits.write_bytes(gzip.compress(ok + b" " * (2**20 - len(ok))))
    assert len(read_traffic_records(fits)) == 1


_YEAR = st.integers(1, 1676) | st.integers(2263, 9999)


@SETTINGS
@given(year=_YEAR, row=st.integers(1, 3))
def test_ais_times_outside_int64_nanoseconds_are_named(tmp_path, year, row):
    # AIS times before 1678 or after 2261 raised OverflowError (int64 ns wrap)
    p = tmp_path / "old.csv"
    rows = [f"2016-01-12 13:02:1{k}.218,1,50.0,-1.0,1,1" for k in range(3)]
    rows[row - 1] = f"{year:04d}-01-12 13:02:11.218,1,50.0,-1.0,1,1"
    p.write_text(AIS_HEADER + "\n".join(rows) + "\n")
    with pytest.raises(DetectionFileError, match="outside the times that can be held") as info:
        read_ais_csv(p)
    e = info.value
    assert (e.row, e.line, e.column) == (row, row + 1, "time")
    assert "1677-09-21T00:12:43.145224192 to 2262-04-11T23:47:16.854775807" in str(e)


def test_times_spanning_more_than_int64_nanoseconds_are_refused(tmp_path):
    # each time fits int64 ns, their difference does not: it wrapped around silently
    p = tmp_path / "span.csv"
    p.write_text(
        AIS_HEADER + "1700-01-01 00:00:00,1,50.0,-1.0,1,1\n2250-01-01 00:00:00,1,50.0,-1.0,1,1\n"
    )
    with pytest.raises(DetectionFileError, match="span 550 years"):
        read_ais_csv(p)
    d = tmp_path / "det.csv"
    d.write_text("time,x,y\n1700-01-01T00:00:00,0,0\n2250-01-01T00:00:00,1,1\n")
    from jointtrack.io import read_detections

    with pytest.raises(DetectionFileError, match="span 550 years"):
        read_detections(d)


@pytest.mark.parametrize("unit", ["s", "ms", "us"])
def test_parquet_timestamps_outside_int64_nanoseconds_are_named(tmp_path, unit):
    import pyarrow as pa
    import pyarrow.parquet as pq

    from jointtrack.io import read_detections

    per_s = {"s": 1, "ms": 1000, "us": 10**6}[unit]
    far = 20_000_000_000 * per_s  # year 2603
    times = pa.array([0, far], type=pa.timestamp(unit, tz="UTC"))
    p = tmp_path / "t.parquet"
    pq.write_table(
        pa.table({"Time": times, "MMSI": ["1", "1"], "Latitude_degrees": [50.0, 50.0],
                  "Longitude_degrees": [-1.0, -1.0]}), p,
    )  # fmt: skip
    with pytest.raises(DetectionFileError, match="outside the times") as info:
        read_ais_csv(p)
    assert (info.value.row, info.value.column) == (2, "time")
    q = tmp_path / "d.parquet"
    pq.write_table(pa.table({"time": times, "x": [0.0, 1.0], "y": [0.0, 1.0]}), q)
    with pytest.raises(DetectionFileError, match="outside the times") as info:
        read_detections(q)
    assert info.value.row == 2


@SETTINGS
@given(
    window=st.floats(1.0001e9, 1e300) | st.sampled_from([1e12, float(2**63)]),
    n=st.integers(1, 5),
)
def test_windows_beyond_the_maximum_are_refused_by_name(window, n):
    # --window 1e12 raised OverflowError
    from jointtrack.io.reports import MAX_WINDOW

    assert MAX_WINDOW == 1e9
    with pytest.raises(ValueError, match="window must be at most 1e\\+09 seconds"):
        _reports(n).window_index(window)


@SETTINGS
@given(
    window=st.floats(1e-3, 1e9),
    offsets=st.lists(st.integers(0, 10**12), min_size=1, max_size=8),
    first=st.integers(-(9 * 10**18), 9 * 10**18),
)
@example(window=1e9, offsets=[0, 1], first=9 * 10**18)
@example(window=5e8, offsets=[0, 10**9], first=-(9 * 10**18))
# the overflow branch's ends were int / int there (one rounding), not float(int) / 1e9
# as in the int64 branch: 9286979779.000008 against 9286979779.000006
@example(window=286979779.0, offsets=[11, 13], first=8_999_999_999_999_995_705)
def test_window_ends_are_exact_up_to_the_maximum_window(window, offsets, first):
    # the ends t0 + k·w in whole nanoseconds, without int64 wrap-around: with t0 near
    # the end of int64 nanoseconds (2262) the next window's end wrapped to a negative
    # time; times beyond int64 nanoseconds are refused by name
    ns = np.sort(np.array([first + o * 1000 for o in offsets], dtype=np.int64))
    r = _reports(len(ns), times=ns / 1e9)
    if np.abs(r.times).max() * 1e9 >= 2.0**63:
        with pytest.raises(ValueError, match="times reach"):
            r.window_index(window)
        return
    k, ends = r.window_index(window)
    w_ns = round(window * 1e9)
    got_ns = [int(v) for v in np.rint(r.times * 1e9).astype(np.int64)]
    rel = [v - got_ns[0] for v in got_ns]
    assert k.tolist() == [-(-v // w_ns) for v in rel]
    assert ends.tolist() == [(got_ns[0] + j * w_ns) / 1e9 for j in range(int(k[-1]) + 1)]


# -- 31.8: values that were accepted silently


@SETTINGS
@given(
    value=st.integers(-(2**70), 2**70)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.booleans()
    | st.lists(st.text(max_size=3), max_size=2)
    | st.dictionaries(st.text(max_size=2), st.integers(), max_size=2),
    row=st.integers(0, 2),
)
def test_traffic_icao24_must_be_text(tmp_path, value, row):
    # an icao24 given as an object, list or number was stringified ("{'a': 1}", 404040
    # losing the leading zeros of "0404040"...)
    recs = [dict(_RECORD) for _ in range(3)]
    recs[row]["icao24"] = value
    p = _traffic(recs, tmp_path / "t.json", False)
    with pytest.raises(DetectionFileError, match="icao24 must be a string") as info:
        read_traffic_records(p)
    assert (info.value.row, info.value.column) == (row + 1, "icao24")


_NS_1990, _NS_2100 = 631_152_000 * 10**9, 4_102_444_800 * 10**9


@SETTINGS
@given(
    instants=st.lists(st.integers(_NS_1990, _NS_2100), min_size=1, max_size=6),
    unit=st.sampled_from(["s", "ms"]),
    as_float=st.booleans(),
    gz=st.booleans(),
)
def test_traffic_timestamps_in_seconds_or_milliseconds_are_told_apart(
    tmp_path, instants, unit, as_float, gz
):
    # 1.5e9 (seconds) was read as milliseconds: 1970-01-18. Each value is exact: whole
    # seconds or milliseconds (a float holds them exactly in this range)
    per = 10**9 if unit == "s" else 10**6
    whole = [v // per for v in instants]
    recs = [
        dict(_RECORD, timestamp=float(w) if as_float else w, icao24=f"a{i}")
        for i, w in enumerate(whole)
    ]
    r = read_traffic_records(_traffic(recs, tmp_path / ("t.json.gz" if gz else "t.json"), gz))
    ns = sorted(w * per for w in whole)
    from jointtrack.io.times import parse_timestamp

    assert parse_timestamp(r.time_origin)[0] == ns[0]
    assert r.times.tolist() == [(v - ns[0]) / 1e9 for v in ns]


@SETTINGS
@given(
    seconds=st.floats(-(2.0**33), 2.0**33),
    ms=st.floats(2.0**33, 2.0**43, exclude_min=True)
    | st.floats(-(2.0**43), -(2.0**33), exclude_max=True),
)
def test_traffic_timestamp_units_by_magnitude_exactly(tmp_path, seconds, ms):
    from fractions import Fraction

    from jointtrack.io.times import parse_timestamp

    recs = [dict(_RECORD, timestamp=seconds), dict(_RECORD, timestamp=ms)]
    want = sorted([round(Fraction(seconds) * 10**9), round(Fraction(ms) * 10**6)])
    if want[1] - want[0] >= 2**63:  # more than ~292 years apart: refused (tested above)
        return
    r = read_traffic_records(_traffic(recs, tmp_path / "t.json", False))
    assert parse_timestamp(r.time_origin)[0] == want[0]
    assert r.times.tolist() == [0.0, (want[1] - want[0]) / 1e9]


@SETTINGS
@given(
    codes=st.lists(
        st.sampled_from([None, (91.0, -1.0), (50.0, 181.0), (91.0, 181.0)]), min_size=1,
        max_size=12,
    ),
    gz=st.booleans(),
)  # fmt: skip
def test_ais_position_not_available_rows_are_skipped_and_counted(tmp_path, codes, gz):
    # lat 91 refused the whole file and lon 181 was read as -179°: ITU-R M.1371's
    # "position not available" codes; such rows are left out and counted
    rows = []
    for k, c in enumerate(codes):
        la, lo = (50.0 + 1e-3 * k, -1.0) if c is None else c
        rows.append((1000 * k, str(k), la, lo, 90.0, 5.0))
    path = _ais_file(tmp_path, rows, name="ais.csv.gz" if gz else "ais.csv")
    if gz:
        path.write_bytes(gzip.compress(path.read_bytes()))
    r = read_ais_csv(path)
    kept = [row for row, c in zip(rows, codes, strict=True) if c is None]
    assert r.skipped == len(rows) - len(kept)
    assert r.identity.tolist() == [row[1] for row in kept]
    assert r.lat.tolist() == [row[2] for row in kept]
    assert r.lon.tolist() == [row[3] for row in kept]
    assert (r.lat <= 90).all() and (r.lon != 181.0).all()


def test_a_gzip_csv_of_blank_lines_is_skipped_in_bulk(tmp_path, monkeypatch):
    # a 1 MB .csv.gz of blank lines took 238 s, one csv record per blank line; now the
    # blank runs between records are skipped a block of text at a time: the records the
    # csv parser makes are the file's own, however many blank lines there are (counted
    # here by wrapping csv.reader; tests/test_io_csv_records.py checks the records equal)
    import csv
    import zlib

    made = []
    plain_reader = csv.reader

    class CountingReader:
        def __init__(self, lines):
            self._reader = plain_reader(lines)
            made.append(0)

        def __iter__(self):
            return self

        def __next__(self):
            rec = next(self._reader)
            made[-1] += 1
            return rec

        @property
        def line_num(self):
            return self._reader.line_num

    monkeypatch.setattr(csv, "reader", CountingReader)
    blank = 1_000_000
    z = zlib.compressobj(9, zlib.DEFLATED, 31)
    head = (
        "\n" * 3 + AIS_HEADER + " \r\n\t\n" * 5 + "2016-01-12 13:02:11.218,1,50.0,-1.0,1,1\n"
    ).encode()
    data = z.compress(head) + z.compress(b"\n" * blank)
    data += z.compress(b"2016-01-12 13:02:12.218,2,50.0,-1.0,1,1\n" + b"\n" * 1000) + z.flush()
    p = tmp_path / "blank.csv.gz"
    p.write_bytes(data)
    assert p.stat().st_size < 5_000
    r = read_ais_csv(p)
    assert r.identity.tolist() == ["1", "2"] and r.times.tolist() == [0.0, 1.0]
    # the sniffing of the header (read_reports) and the reader: a few records each
    assert read_reports(p).identity.tolist() == ["1", "2"]
    assert made and max(made) <= 3 + 2 * (blank // 2**20 + 2), made
    bad = tmp_path / "bad.csv.gz"
    bad.write_bytes(gzip.compress(head + b"\n" * blank + b"2016-01-12 13:02:12.218,2,x,1,1,1\n"))
    with pytest.raises(DetectionFileError) as info:
        read_ais_csv(bad)
    assert (info.value.row, info.value.line, info.value.column) == (
        2, 16 + blank, "latitude_degrees"
    )  # fmt: skip


def test_altitudes_beyond_the_frame_range_are_named(tmp_path):
    # issue 31.14: alt = 1e300 was reported as "column 'x'" (detections) or kept
    recs = [dict(_RECORD), dict(_RECORD, altitude=1e300)]
    with pytest.raises(DetectionFileError, match="outside") as info:
        read_traffic_records(_traffic(recs, tmp_path / "t.json", False))
    assert (info.value.row, info.value.column) == (2, "altitude")
    p = _opensky_file(tmp_path, [(1626098400, "a", 50.0, 1.0, 3.0, 1.0, None, 1e300)])
    with pytest.raises(DetectionFileError, match="outside") as info:
        read_opensky_states(p)
    assert (info.value.row, info.value.column) == (1, "geoaltitude")
    with pytest.raises(ValueError, match="alt must be within"):
        _reports(5, alt=np.full(5, 1e300))
    assert np.isnan(_reports(5, alt=np.full(5, np.nan)).alt).all()
