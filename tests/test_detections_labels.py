"""Detections' labels, velocities, geodetic reference and empty scans: in memory and on disk."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from jointtrack.io import DetectionFileError, Detections, read_detections, write_detections
from jointtrack.io.geodetic import KNOT, LocalFrame, velocity_en

SETTINGS = settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
coords = st.floats(-1e6, 1e6, allow_nan=False)
# labels with CSV's quirks: separators, quotes, newlines, spaces, non-ASCII
labels = st.text(alphabet="abcXYZ019 ,;\"'é中-_\n", max_size=6) | st.sampled_from(
    ["", "235070762", "3c4591"]
)


@st.composite
def detections(draw):
    dim = draw(st.sampled_from([2, 3]))
    k = draw(st.integers(1, 5))
    times = np.cumsum(draw(st.lists(st.floats(0.001, 100), min_size=k, max_size=k)))
    sizes = draw(st.lists(st.integers(0, 3), min_size=k, max_size=k))
    scans = [
        np.array(draw(st.lists(st.tuples(*[coords] * dim), min_size=m, max_size=m))).reshape(m, dim)
        for m in sizes
    ]
    lab = None
    if draw(st.booleans()):
        lab = [np.array(draw(st.lists(labels, min_size=m, max_size=m)), dtype=str) for m in sizes]
    vel = None
    if draw(st.booleans()):
        v = st.floats(-300, 300) | st.just(float("nan"))
        vel = [
            np.array(draw(st.lists(st.tuples(*[v] * dim), min_size=m, max_size=m))).reshape(m, dim)
            for m in sizes
        ]
    sensors = None
    if draw(st.booleans()):
        ids = st.integers(-5, 5)
        sensors = [
            np.array(draw(st.lists(ids, min_size=m, max_size=m)), dtype=np.int64) for m in sizes
        ]
    geo = None
    if draw(st.booleans()):
        geo = (draw(st.floats(-80, 80)), draw(st.floats(-180, 360)), draw(st.floats(-100, 100)))
        # positions of a geodetic frame: within a few hundred km of the reference
        scans = [z / 10 for z in scans]
    origin = draw(st.sampled_from([None, "2016-01-12T13:02:11.218Z"]))
    if origin is not None:  # timestamps hold whole nanoseconds, from t = 0 at the origin
        times = np.round(times - times[0], 3)
        times = np.unique(times)
        scans, k = scans[: times.size], times.size
        sizes = sizes[:k]
        lab = None if lab is None else lab[:k]
        vel = None if vel is None else vel[:k]
        sensors = None if sensors is None else sensors[:k]
    return Detections(
        times=times,
        scans=scans,
        dim=dim,
        labels=lab,
        velocities=vel,
        sensors=sensors,
        geo_reference=geo,
        time_origin=origin,
    )


def _same(a: Detections, b: Detections):
    assert np.array_equal(a.times, b.times) and a.time_origin == b.time_origin
    assert a.dim == b.dim and len(a) == len(b)
    for k in range(len(a)):
        assert np.array_equal(a.scans[k], b.scans[k])
    for name in ("labels", "sensors"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None)
        if x is not None:
            assert all(p.tolist() == q.tolist() for p, q in zip(x, y, strict=True))
    assert (a.velocities is None) == (b.velocities is None)
    if a.velocities is not None:
        for p, q in zip(a.velocities, b.velocities, strict=True):
            assert np.array_equal(p, q, equal_nan=True)
    assert a.geo_reference == b.geo_reference


@SETTINGS
@given(d=detections(), suffix=st.sampled_from([".csv", ".parquet", ".csv.gz"]))
def test_round_trip_is_exact(tmp_path, d, suffix):
    p = write_detections(d, tmp_path / f"d{suffix}")
    _same(d, read_detections(p, allow_empty=True))


def test_empty_scans_are_rows_with_only_a_time(tmp_path):
    d = Detections(
        times=[0.0, 1.0, 2.0, 3.5],
        scans=[np.zeros((0, 2)), [[1.0, 2.0]], np.zeros((0, 2)), np.zeros((0, 2))],
        sensors=[[], ["radar_a"], [], []],
    )
    p = write_detections(d, tmp_path / "e.csv")
    assert p.read_text() == "time,x,y,sensor\n0.0,,,\n1.0,1.0,2.0,radar_a\n2.0,,,\n3.5,,,\n"
    _same(d, read_detections(p))
    # by hand, and with a column the reader ignores
    q = tmp_path / "hand.csv"
    q.write_text("time,x,y,snr\n0,,,5\n1,3,4,2\n")
    e = read_detections(q)
    assert e.times.tolist() == [0.0, 1.0] and [z.shape[0] for z in e.scans] == [0, 1]


@pytest.mark.parametrize(
    ("text", "row", "column", "words"),
    [
        ("time,x,y\n0,,\n0,1,2\n", 1, "time", "empty scan"),
        ("time,x,y\n0,1,2\n0,,\n", 2, "time", "empty scan"),
        ("time,x,y\n0,1,\n", 1, "y", "empty"),
        ("time,x,y,sensor\n0,,,3\n", 1, "x", "empty"),
        ("time,x,y,label\n0,,,a\n", 1, "x", "empty"),
        ("time,x,y,vx\n0,1,2,3\n", None, None, "vy"),
        ("time,x,y,vx,vy,speed_knots,course_deg\n0,1,2,3,4,,\n", None, None, "one velocity"),
        ("time,x,y,speed_knots,course_deg\n0,1,2,-3,4\n", 1, "speed_knots", "negative"),
        ("time,x,y,vx,vy\n0,1,2,inf,4\n", 1, "vx", "non-finite"),
        ("time,x,y,vx,vy,vz\n0,1,2,3,4,5\n", None, None, "vz"),
        ("time,lat,lon\n0,91,2\n", 1, "lat", "outside"),
        ("time,lat,lon\n0,1,2\n1,1,-200\n", 2, "lon", "outside"),
        ("time,lat,lon\n0,1,abc\n", 1, "lon", "'abc'"),
        ("time,x,y,ref_lat,ref_lon\n0,1,2,50,1\n1,1,2,51,1\n", 2, "ref_lat", "differs"),
        ("time,x,y,ref_lat,ref_lon\n0,1,2,95,1\n", 1, "ref_lat", "lat0"),
        ("time,x,y,lat,lon,ref_lat,ref_lon\n0,0,0,50.001,1,50,1\n", 1, "lat", "from its x, y"),
    ],
)
def test_bad_files_name_the_row_and_column(tmp_path, text, row, column, words):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(DetectionFileError) as info:
        read_detections(p)
    e = info.value
    assert (e.row, e.column) == (row, column), str(e)
    assert words in str(e) and str(p) in str(e)


def test_errors_after_an_empty_scan_row_name_the_files_row(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("time,x,y,sensor\n0,,,\n1,1,2,1\n2,1,2,1.5\n")
    with pytest.raises(DetectionFileError) as info:
        read_detections(p)
    assert (info.value.row, info.value.line, info.value.column) == (3, 4, "sensor")


@SETTINGS
@given(
    pts=st.lists(
        st.tuples(st.floats(50.0, 51.0), st.floats(-2.0, 0.0), st.floats(0, 40), st.floats(0, 359)),
        min_size=1,
        max_size=8,
    ),
    given_ref=st.booleans(),
    with_alt=st.booleans(),
)
def test_geodetic_files_are_projected(tmp_path, pts, given_ref, with_alt):
    lat = np.array([p[0] for p in pts])
    lon = np.array([p[1] for p in pts])
    sog = np.array([p[2] for p in pts])
    cog = np.array([p[3] for p in pts])
    alt = np.arange(len(pts)) * 10.0
    head = "time,lat,lon" + (",alt" if with_alt else "") + ",speed_knots,course_deg,label\n"
    body = "".join(
        f"{i // 2},{float(lat[i])!r},{float(lon[i])!r}"
        + (f",{float(alt[i])!r}" if with_alt else "")
        + f",{float(sog[i])!r},{float(cog[i])!r},L{i}\n"
        for i in range(len(pts))
    )  # fmt: skip
    p = tmp_path / "geo.csv"
    p.write_text(head + body)
    ref = (50.5, -1.0, 5.0) if given_ref else None
    d = read_detections(p, reference=ref)
    frame = LocalFrame(*ref) if ref else LocalFrame.centre(lat, lon)
    assert d.geo_reference == frame.reference
    want = frame.to_local(lat, lon, alt if with_alt else None)
    assert np.array_equal(np.concatenate(d.scans), want) and d.dim == (3 if with_alt else 2)
    v = np.concatenate(d.velocities)
    assert np.array_equal(v[:, :2], velocity_en(sog * KNOT, cog))
    assert with_alt == (v.shape[1] == 3) and np.isnan(v[:, 2:]).all()
    assert np.concatenate(d.labels).tolist() == [f"L{i}" for i in range(len(pts))]
    # written back: x, y and lat, lon, the frame in ref_*; read back the same
    q = write_detections(d, tmp_path / "back.csv")
    _same(d, read_detections(q))
    _same(d, read_detections(q, reference=d.geo_reference))
    with pytest.raises(DetectionFileError, match="not the reference"):
        read_detections(q, reference=(0.0, 0.0))


def test_reference_argument_is_checked_first(tmp_path):
    p = tmp_path / "missing.csv"
    with pytest.raises(TypeError, match="reference"):
        read_detections(p, reference=(True, 0.0))
    with pytest.raises(ValueError, match="reference"):
        read_detections(p, reference=(0.0,))
    with pytest.raises(ValueError, match="reference"):
        read_detections(p, reference=(0.0, 400.0))
    q = tmp_path / "xy.csv"
    q.write_text("time,x,y\n0,1,2\n")
    with pytest.raises(DetectionFileError, match="without a reference"):
        read_detections(q, reference=(0.0, 0.0))


@pytest.mark.parametrize(
    ("kw", "exc", "words"),
    [
        (dict(labels=[[1]]), ValueError, "labels"),
        (dict(labels=[np.array(["a", "b"])]), ValueError, "labels\\[0\\]"),
        (dict(labels=["a"]), ValueError, "labels"),
        (dict(labels=[["a"], ["b"]]), ValueError, "labels"),
        (dict(velocities=[[[1.0, 2.0, 3.0]]]), ValueError, "velocities\\[0\\]"),
        (dict(velocities=[[[True, False]]]), ValueError, "velocities"),
        (dict(velocities=[[[1j, 0.0]]]), ValueError, "velocities"),
        (dict(velocities=[[[np.inf, 0.0]]]), ValueError, "velocities"),
        (dict(geo_reference=(True, 0.0)), TypeError, "geo_reference"),
        (dict(geo_reference=(0.0, 1j)), TypeError, "geo_reference"),
        (dict(geo_reference=(91.0, 0.0)), ValueError, "geo_reference"),
        (dict(geo_reference=(0.0, np.nan)), ValueError, "geo_reference"),
        (dict(geo_reference=(0.0,)), ValueError, "geo_reference"),
        (dict(geo_reference="50,1"), ValueError, "geo_reference"),
    ],
)
def test_detections_refuse_bad_fields(kw, exc, words):
    with pytest.raises(exc, match=words):
        Detections(times=[0.0], scans=[[[1.0, 2.0]]], **kw)


def test_fields_for_position_detections_only():
    rb = dict(times=[0.0], scans=[[[1.0, 0.5]]], kind="range-bearing")
    with pytest.raises(ValueError, match="velocities"):
        Detections(**rb, velocities=[[[1.0, 2.0]]])
    with pytest.raises(ValueError, match="geo_reference"):
        Detections(**rb, geo_reference=(0.0, 0.0))
    d = Detections(**rb, labels=[["a"]])  # a label fits any measurement
    assert d.labels[0].tolist() == ["a"] and d.to_table()["label"].tolist() == ["a"]


def test_to_table_columns():
    d = Detections(
        times=[0.0, 1.0],
        scans=[[[0.0, 0.0]], np.zeros((0, 2))],
        labels=[["m"], []],
        velocities=[[[1.0, np.nan]], np.zeros((0, 2))],
        geo_reference=(50.0, -1.0),
    )
    t = d.to_table()
    assert list(t) == ["time", "x", "y", "label", "vx", "vy", "lat", "lon"]
    # the reference itself, through pymap3d's inverse (not bit-exact)
    assert abs(t["lat"][0] - 50.0) < 1e-12 and abs(t["lon"][0] + 1.0) < 1e-12
    assert d.geo_frame() == LocalFrame(50.0, -1.0)


# ----------------------------------------------------------------------------- issue 31


# a label holding a NUL (U+0000) somewhere, e.g. "A\x00": numpy's fixed-width strings
# drop trailing NULs, so "A" and "A\x00" became one label and the tracker dropped the
# second report of "A" in a scan (50 km away) as a repeat
nul_labels = st.tuples(st.text(max_size=3), st.text(max_size=3)).map(lambda p: p[0] + "\x00" + p[1])


@settings(max_examples=60, deadline=None)
@given(bad=nul_labels, row=st.integers(0, 2))
def test_labels_with_a_nul_are_refused_everywhere(bad, row):
    from jointtrack.io.reports import Reports
    from jointtrack.trackers import JPDATracker, TrackerConfig

    labels = ["A", "B", "C"]
    labels[row] = bad
    z = np.array([[0.0, 0.0], [5e4, 0.0], [0.0, 5e4]])
    with pytest.raises(ValueError, match="NUL") as info:
        Detections(times=[0.0], scans=[z], labels=[labels])
    assert "labels[0]" in str(info.value)
    with pytest.raises(ValueError, match="NUL"):
        Detections(times=[0.0], scans=[z], sensors=[labels])
    with pytest.raises(ValueError, match="NUL") as info:
        Reports(times=[0.0, 1.0, 2.0], time_origin="2016-01-12T13:02:11Z", lat=[50.0] * 3,
                lon=[-1.0] * 3, identity=labels)  # fmt: skip
    assert "identity" in str(info.value)
    trk = JPDATracker(TrackerConfig(clutter_density=1e-6, measurement_noise=100.0))
    with pytest.raises(ValueError, match="NUL") as info:
        trk.step(0.0, z, labels=labels)
    assert f"labels[{row}]" in str(info.value) and len(trk.ids) == 0


@settings(
    max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(bad=nul_labels, row=st.integers(1, 3), suffix=st.sampled_from([".csv", ".parquet"]))
def test_label_and_sensor_cells_with_a_nul_are_named(tmp_path, bad, row, suffix):
    import pyarrow as pa
    import pyarrow.parquet as pq

    for column in ("label", "sensor"):
        cells = ["A", "B", "C"]
        cells[row - 1] = bad
        p = tmp_path / f"d{suffix}"
        table = {"time": [0.0, 1.0, 2.0], "x": [0.0, 1.0, 2.0], "y": [0.0, 1.0, 2.0], column: cells}
        if suffix == ".csv":
            import csv

            with open(p, "w", newline="", encoding="utf-8") as fh:
                w = csv.writer(fh)
                w.writerow(list(table))
                w.writerows(zip(*table.values(), strict=True))
        else:
            pq.write_table(pa.table(table), p)
        with pytest.raises(DetectionFileError, match="NUL") as info:
            read_detections(p)
        assert (info.value.row, info.value.column) == (row, column)


def test_report_identities_with_a_nul_are_named(tmp_path):
    import gzip
    import json

    from jointtrack.io.reports import read_ais_csv, read_traffic_records

    p = tmp_path / "ais.csv"
    p.write_text(
        "Time,MMSI,Latitude_degrees,Longitude_degrees\n2016-01-12 13:02:11,235,50.0,-1.0\n"
        "2016-01-12 13:02:12,235\x00,50.45,-1.0\n"
    )
    with pytest.raises(DetectionFileError, match="NUL") as info:
        read_ais_csv(p)
    assert (info.value.row, info.value.column) == (2, "mmsi")
    rec = {"timestamp": 1533101250000, "latitude": 48.0, "longitude": 3.0}
    q = tmp_path / "t.json.gz"
    recs = [{**rec, "icao24": "3c4591"}, {**rec, "icao24": "3c4591\x00"}]
    q.write_bytes(gzip.compress(json.dumps(recs).encode()))
    with pytest.raises(DetectionFileError, match="NUL") as info:
        read_traffic_records(q)
    assert (info.value.row, info.value.column) == (2, "icao24")


def test_geodetic_files_beyond_the_plane_or_the_altitude_range_are_named(tmp_path):
    # issue 31.5 / 31.14: a point on the far side of the Earth from the reference, and
    # alt = 1e300 (reported as "column 'x'" once projected)
    p = tmp_path / "far.csv"
    p.write_text("time,lat,lon\n0,50.0,-1.0\n1,-50.8,178.7\n")
    with pytest.raises(DetectionFileError, match="60°") as info:
        read_detections(p, reference=(50.0, -1.0))
    assert (info.value.row, info.value.column) == (2, "lat") and "--reference" in str(info.value)
    with pytest.raises(DetectionFileError, match="centre of the data"):
        read_detections(p)
    q = tmp_path / "alt.csv"
    q.write_text("time,lat,lon,alt\n0,50.0,-1.0,100\n1,50.01,-1.0,1e300\n")
    with pytest.raises(DetectionFileError, match="outside") as info:
        read_detections(q)
    assert (info.value.row, info.value.column) == (2, "alt")
    # east, north, up holds the far side exactly: with an alt column it is read
    r = tmp_path / "far3d.csv"
    r.write_text("time,lat,lon,alt\n0,50.0,-1.0,0\n1,-50.8,178.7,0\n")
    d = read_detections(r, reference=(50.0, -1.0))
    lat, lon, _ = LocalFrame(50.0, -1.0).to_geodetic(np.concatenate(d.scans))
    assert np.allclose(lat, [50.0, -50.8], atol=1e-9) and np.allclose(lon, [-1.0, 178.7], atol=1e-9)
