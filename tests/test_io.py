"""Detections / tracks / metrics files (jointtrack.io)."""

from __future__ import annotations

import gzip
import json
import math

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from jointtrack.io import (
    DataFileError,
    DetectionFileError,
    Detections,
    TrackFileError,
    read_detections,
    read_tracks,
    write_detections,
    write_metrics,
    write_tracks,
)
from jointtrack.metrics import gospa
from jointtrack.scenarios import bojilov


def _csv(tmp_path, text, name="det.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def _parquet(tmp_path, cols: dict, name="det.parquet"):
    p = tmp_path / name
    pq.write_table(pa.table(cols), p)
    return p


def _err(path, exc=DetectionFileError, reader=read_detections):
    with pytest.raises(exc) as info:
        reader(path)
    msg = str(info.value)
    assert isinstance(info.value, ValueError)
    assert "\n" not in msg
    assert str(path) in msg
    return info.value


# ----------------------------------------------------------------------------- reading: good files


def test_read_csv_groups_scans_and_tolerates_layout(tmp_path):
    p = _csv(
        tmp_path,
        " Time , X,Y , snr\n\n0,1.5,2,30\n0, 3 ,4,31\n1,5,6,29\n\n2.5,7,8e1,1\n",
    )
    d = read_detections(p)
    assert isinstance(d, Detections)
    assert d.times.tolist() == [0.0, 1.0, 2.5]
    assert [z.shape for z in d.scans] == [(2, 2), (1, 2), (1, 2)]
    assert d.scans[0].tolist() == [[1.5, 2.0], [3.0, 4.0]]
    assert d.scans[2].tolist() == [[7.0, 80.0]]
    assert d.sensors is None and d.dim == 2 and d.n_detections == 4
    assert d.source == str(p)
    t, z = d[1]
    assert t == 1.0 and z.tolist() == [[5.0, 6.0]]
    assert [t for t, _ in d] == [0.0, 1.0, 2.5]


def test_read_csv_3d_with_sensor(tmp_path):
    p = _csv(tmp_path, "time,x,y,z,sensor\n0,1,2,3,1\n0,4,5,6,2\n1,7,8,9,1\n")
    d = read_detections(p)
    assert d.dim == 3
    assert d.scans[0].tolist() == [[1, 2, 3], [4, 5, 6]]
    assert [s.tolist() for s in d.sensors] == [[1, 2], [1]]
    assert d.sensors[0].dtype == np.int64


def test_header_only_gives_no_scans(tmp_path):
    # a header-only file is an error by default (see test_header_only_is_an_error)
    d = read_detections(_csv(tmp_path, "time,x,y\n"), allow_empty=True)
    assert len(d) == 0 and d.n_detections == 0


@pytest.mark.parametrize("suffix", [".csv", ".csv.gz", ".parquet"])
def test_round_trip_of_a_scenario(tmp_path, suffix):
    sc = bojilov(1.0, seed=3, n_scans=12)
    det = sc.as_detections()
    p = write_detections(det, tmp_path / f"sub/dir/det{suffix}")
    back = read_detections(p)
    assert np.array_equal(back.times, det.times)
    for a, b in zip(back.scans, det.scans, strict=True):
        assert np.array_equal(a, b)  # bit-exact, also through CSV


def test_parquet_round_trip_with_sensor_and_int_time(tmp_path):
    p = _parquet(
        tmp_path,
        {
            "time": pa.array([0, 0, 2], pa.int32()),
            "x": [1.0, 2.0, 3.0],
            "y": pa.array(["4", "5.5", "6"]),  # numbers held as strings are accepted
            "sensor": pa.array([3, 4, 3], pa.int8()),
            "label": pa.array(["a", "b", "c"]),  # ignored
        },
    )
    d = read_detections(p)
    assert d.times.tolist() == [0.0, 2.0]
    assert d.scans[0].tolist() == [[1, 4], [2, 5.5]]
    assert [s.tolist() for s in d.sensors] == [[3, 4], [3]]
    q = write_detections(d, tmp_path / "again.pq")
    d2 = read_detections(q)
    assert [s.tolist() for s in d2.sensors] == [[3, 4], [3]]


def test_detections_validation():
    with pytest.raises(ValueError, match="strictly increasing"):
        Detections(times=[1.0, 1.0], scans=[np.zeros((0, 2))] * 2)
    with pytest.raises(ValueError, match="shape"):
        Detections(times=[1.0], scans=[np.zeros((2, 3))], dim=2)
    with pytest.raises(ValueError, match="scans"):
        Detections(times=[1.0, 2.0], scans=[np.zeros((0, 2))])


# ----------------------------------------------------------------------------- reading: bad files


def test_missing_file_and_directory(tmp_path):
    e = _err(tmp_path / "nope.csv")
    assert "not found" in str(e)
    e = _err(tmp_path / "nope.parquet")
    assert "not found" in str(e)
    (tmp_path / "dir.csv").mkdir()
    assert "directory" in str(_err(tmp_path / "dir.csv"))


def test_unknown_extension_and_empty_file(tmp_path):
    assert "extension" in str(_err(_csv(tmp_path, "time,x,y\n", name="det.txt")))
    assert "empty" in str(_err(_csv(tmp_path, "\n\n")))


def test_missing_columns_are_all_listed(tmp_path):
    e = _err(_csv(tmp_path, "time,lat\n0,1\n"))
    assert "missing required column(s): x, y" in str(e)
    e = _err(_parquet(tmp_path, {"x": [1.0], "y": [2.0]}))
    assert "missing required column(s): time" in str(e)


def test_non_numeric_value_names_line_row_and_column(tmp_path):
    p = _csv(tmp_path, "time,x,y\n0,1,2\n\n1,abc,3\n")
    e = _err(p)
    assert (e.row, e.line, e.column) == (2, 4, "x")
    assert "line 4 (data row 2)" in str(e) and "'x'" in str(e) and "'abc'" in str(e)


def test_empty_value(tmp_path):
    e = _err(_csv(tmp_path, "time,x,y\n0,1,2\n1,2,\n"))
    assert (e.row, e.column) == (2, "y") and "empty" in str(e)


@pytest.mark.parametrize("bad", ["nan", "inf", "-inf", "NaN"])
def test_non_finite_value(tmp_path, bad):
    e = _err(_csv(tmp_path, f"time,x,y\n0,1,2\n0,3,4\n1,{bad},5\n"))
    assert (e.row, e.line, e.column) == (3, 4, "x") and "non-finite" in str(e)


def test_non_monotone_time(tmp_path):
    e = _err(_csv(tmp_path, "time,x,y\n0,1,2\n2,1,2\n2,1,2\n1.5,1,2\n"))
    assert (e.row, e.line, e.column) == (4, 5, "time")
    assert "earlier" in str(e)


def test_wrong_number_of_fields(tmp_path):
    e = _err(_csv(tmp_path, "time,x,y\n0,1,2\n1,2\n"))
    assert e.row == 2 and e.line == 3 and "fields" in str(e)


def test_non_integer_sensor(tmp_path):
    e = _err(_csv(tmp_path, "time,x,y,sensor\n0,1,2,1\n1,1,2,1.5\n"))
    assert (e.row, e.column) == (2, "sensor") and "integer" in str(e)


def test_duplicate_header(tmp_path):
    assert "duplicate" in str(_err(_csv(tmp_path, "time,x,x,y\n0,1,2,3\n")))


def test_corrupt_gzip(tmp_path):
    p = tmp_path / "d.csv.gz"
    p.write_bytes(b"not gzip at all")
    assert "cannot read" in str(_err(p))


def test_binary_file_as_csv(tmp_path):
    p = tmp_path / "d.csv"
    p.write_bytes(b"\xff\xfe\x00\x81garbage")
    _err(p)


def test_parquet_bad_cases(tmp_path):
    p = tmp_path / "junk.parquet"
    p.write_bytes(b"this is not parquet")
    assert "cannot read Parquet" in str(_err(p))
    e = _err(_parquet(tmp_path, {"time": [0.0, 1.0], "x": [1.0, None], "y": [1.0, 2.0]}))
    assert (e.row, e.column, e.line) == (2, "x", None) and "null" in str(e)
    e = _err(_parquet(tmp_path, {"time": [0.0, 1.0], "x": ["1", "b"], "y": [1.0, 2.0]}))
    assert (e.row, e.column) == (2, "x") and "'b'" in str(e)
    e = _err(_parquet(tmp_path, {"time": [0.0, 1.0], "x": [1.0, np.nan], "y": [1.0, 2.0]}))
    assert (e.row, e.column) == (2, "x") and "non-finite" in str(e)
    e = _err(_parquet(tmp_path, {"time": [3.0, 1.0], "x": [1.0, 2.0], "y": [1.0, 2.0]}))
    assert (e.row, e.column) == (2, "time")
    e = _err(_parquet(tmp_path, {"time": [0.0], "x": [[1.0, 2.0]], "y": [1.0]}))
    assert e.column == "x" and "numeric" in str(e)


def test_error_hierarchy():
    assert issubclass(DetectionFileError, DataFileError)
    assert issubclass(TrackFileError, DataFileError)
    assert issubclass(DataFileError, ValueError)


# ----------------------------------------------------------------------------- range–bearing


def test_read_range_bearing_csv(tmp_path):
    p = _csv(
        tmp_path,
        " Time , Range,BEARING,sensor, snr\n0,1250.5,0.785,1,30\n0,980,-3.1,2,12\n2,0,3.14,1,9\n",
    )
    d = read_detections(p)
    assert d.kind == "range-bearing" and d.dim == 2
    assert d.times.tolist() == [0.0, 2.0]
    assert d.scans[0].tolist() == [[1250.5, 0.785], [980.0, -3.1]]  # [r, θ] rows
    assert d.scans[1].tolist() == [[0.0, 3.14]]  # zero range is allowed
    assert [s.tolist() for s in d.sensors] == [[1, 2], [1]]
    assert d.to_table().keys() == {"time", "range", "bearing", "sensor"}


def test_position_files_are_of_kind_position(tmp_path):
    assert read_detections(_csv(tmp_path, "time,x,y\n0,1,2\n")).kind == "position"
    assert Detections(times=[0.0], scans=[np.zeros((1, 3))], dim=3).kind == "position"


def _range_bearing_detections(seed=0, sensors=False):
    rng = np.random.default_rng(seed)
    scans = [
        np.column_stack([rng.uniform(0, 3000, m), rng.uniform(-np.pi, np.pi, m)])
        for m in (3, 1, 4, 2)
    ]
    sens = [rng.integers(0, 3, len(z)) for z in scans] if sensors else None
    return Detections(times=[0.0, 0.5, 1.5, 2.0], scans=scans, sensors=sens, kind="range-bearing")


@pytest.mark.parametrize("suffix", [".csv", ".csv.gz", ".parquet"])
@pytest.mark.parametrize("sensors", [False, True])
def test_range_bearing_round_trip(tmp_path, suffix, sensors):
    det = _range_bearing_detections(sensors=sensors)
    p = write_detections(det, tmp_path / f"rb{suffix}")
    back = read_detections(p)
    assert back.kind == "range-bearing" and back.dim == 2
    assert np.array_equal(back.times, det.times)
    for a, b in zip(back.scans, det.scans, strict=True):
        assert np.array_equal(a, b)  # bit-exact, also through CSV
    if sensors:
        for a, b in zip(back.sensors, det.sensors, strict=True):
            assert np.array_equal(a, b)
    else:
        assert back.sensors is None
    if suffix == ".csv":
        header = "time,range,bearing" + (",sensor" if sensors else "")
        assert p.read_text().splitlines()[0] == header


def test_range_bearing_parquet_with_int_and_string_columns(tmp_path):
    p = _parquet(
        tmp_path,
        {
            "time": pa.array([0, 0, 1], pa.int32()),
            "range": pa.array([100, 200, 300], pa.int16()),
            "bearing": pa.array(["0.5", "-1", "3"]),
        },
    )
    d = read_detections(p)
    assert d.kind == "range-bearing"
    assert d.scans[0].tolist() == [[100.0, 0.5], [200.0, -1.0]]


@pytest.mark.parametrize(
    "header",
    ["time,x,y,range,bearing", "time,range,bearing,z", "time,X,Bearing", "time,range,y"],
)
def test_position_and_range_bearing_columns_together(tmp_path, header):
    n = header.count(",")
    p = _csv(tmp_path, header + "\n" + ",".join(["1"] * (n + 1)) + "\n")
    e = _err(p)
    msg = str(e)
    assert "both position column(s)" in msg and "range-bearing column(s)" in msg
    for name in header.split(",")[1:]:  # every offending column is named as spelled
        assert name in msg


def test_neither_position_nor_range_bearing_columns(tmp_path):
    # (time, lat, lon is a geodetic file since issue 24: tests/test_detections_labels.py)
    e = _err(_csv(tmp_path, "time,east,north\n0,1,2\n"))
    msg = str(e)
    assert "missing required column(s): x, y (found: time, east, north)" in msg
    assert "range, bearing" in msg and "lat, lon" in msg
    # a range–bearing file missing one of its columns names that one
    e = _err(_csv(tmp_path, "time,range\n0,1\n"))
    assert "missing required column(s): bearing (found: time, range)" in str(e)
    e = _err(_parquet(tmp_path, {"bearing": [1.0], "range": [2.0]}))
    assert "missing required column(s): time" in str(e)


def test_negative_range_names_the_row(tmp_path):
    p = _csv(tmp_path, "time,range,bearing\n0,10,0.1\n\n0,-0.5,0.2\n")
    e = _err(p)
    assert (e.row, e.line, e.column) == (2, 4, "range")
    assert "line 4 (data row 2)" in str(e) and "negative range -0.5" in str(e)
    e = _err(_parquet(tmp_path, {"time": [0.0, 1.0], "range": [1.0, -2.0], "bearing": [0.0, 0]}))
    assert (e.row, e.line, e.column) == (2, None, "range") and "negative" in str(e)


def test_bearing_in_degrees_is_rejected(tmp_path):
    e = _err(_csv(tmp_path, "time,range,bearing\n0,10,6.28\n1,10,45\n"))
    assert (e.row, e.column) == (2, "bearing") and "radians" in str(e)


def test_range_bearing_cells_are_checked_like_positions(tmp_path):
    e = _err(_csv(tmp_path, "time,range,bearing\n0,10,abc\n"))
    assert (e.row, e.column) == (1, "bearing") and "'abc'" in str(e)
    e = _err(_csv(tmp_path, "time,range,bearing\n0,inf,0\n"))
    assert (e.row, e.column) == (1, "range") and "non-finite" in str(e)
    e = _err(_csv(tmp_path, "time,range,bearing\n1,10,0\n0,10,0\n"))
    assert (e.row, e.column) == (2, "time") and "earlier" in str(e)


def test_range_bearing_detections_validation():
    with pytest.raises(ValueError, match="kind"):
        Detections(times=[0.0], scans=[np.zeros((1, 2))], kind="polar")
    with pytest.raises(ValueError, match="dim 2"):
        Detections(times=[0.0], scans=[np.zeros((1, 3))], dim=3, kind="range-bearing")
    with pytest.raises(ValueError, match="negative range"):
        Detections(times=[0.0], scans=[[[-1.0, 0.0]]], kind="range-bearing")
    with pytest.raises(ValueError, match="radians"):
        Detections(times=[0.0], scans=[[[1.0, 90.0]]], kind="range-bearing")
    # positions may be negative and large, as before
    Detections(times=[0.0], scans=[[[-1.0, 90.0]]])


# ----------------------------------------------------------------------------- tracks


def _tracks(n=7, dim=2, seed=0):
    rng = np.random.default_rng(seed)
    t = {"time": np.repeat(np.arange(n // 2 + 1.0), 2)[:n], "track_id": np.arange(n) % 3}
    for c in ["x", "y", "z"][:dim]:
        t[c] = rng.normal(0, 1e3, n)
    for c in ["vx", "vy", "vz"][:dim]:
        t[c] = rng.normal(0, 10, n)
    return t


@pytest.mark.parametrize("suffix", [".csv", ".parquet", ".csv.gz"])
@pytest.mark.parametrize("dim", [2, 3])
def test_tracks_round_trip_exact(tmp_path, suffix, dim):
    t = _tracks(dim=dim)
    t["existence"] = np.linspace(0, 1, 7)
    t["P_x_x"] = np.full(7, np.nan)  # extras may be NaN
    # give the columns in a scrambled order: the file has the canonical order
    scrambled = {k: t[k] for k in reversed(list(t))}
    p = write_tracks(scrambled, tmp_path / f"out/tracks{suffix}")
    back = read_tracks(p)
    canon = ["time", "track_id", "x", "y"] + (["z"] if dim == 3 else []) + ["vx", "vy"]
    canon += ["vz"] if dim == 3 else []
    assert list(back)[: len(canon)] == canon
    assert set(back) == set(t)
    assert back["track_id"].dtype == np.int64
    for k in t:
        np.testing.assert_array_equal(back[k], t[k])


def test_tracks_header_of_csv(tmp_path):
    p = write_tracks(_tracks(), tmp_path / "t.csv")
    assert p.read_text().splitlines()[0] == "time,track_id,x,y,vx,vy"


def test_write_tracks_from_structured_array(tmp_path):
    arr = np.zeros(3, dtype=[("time", float), ("track_id", int), ("x", float), ("y", float),
                             ("vx", float), ("vy", float)])  # fmt: skip
    arr["track_id"] = [5, 6, 7]
    back = read_tracks(write_tracks(arr, tmp_path / "t.parquet"))
    assert back["track_id"].tolist() == [5, 6, 7]


def test_write_tracks_errors(tmp_path):
    t = _tracks()
    with pytest.raises(ValueError, match="missing required column"):
        write_tracks({k: v for k, v in t.items() if k != "vy"}, tmp_path / "t.csv")
    with pytest.raises(ValueError, match="together"):
        write_tracks({**t, "z": t["x"]}, tmp_path / "t.csv")
    with pytest.raises(ValueError, match="integer"):
        write_tracks({**t, "track_id": t["track_id"] + 0.5}, tmp_path / "t.csv")
    with pytest.raises(ValueError, match="not finite"):
        write_tracks({**t, "x": np.full(7, np.inf)}, tmp_path / "t.csv")
    with pytest.raises(ValueError, match="rows"):
        write_tracks({**t, "x": t["x"][:3]}, tmp_path / "t.csv")
    with pytest.raises(ValueError, match="extension"):
        write_tracks(t, tmp_path / "t.xlsx")
    with pytest.raises(ValueError, match="mapping"):
        write_tracks([1, 2, 3], tmp_path / "t.csv")


def test_read_tracks_errors(tmp_path):
    p = _csv(tmp_path, "time,track_id,x,y,vx,vy\n0,1.5,0,0,0,0\n", name="t.csv")
    e = _err(p, TrackFileError, read_tracks)
    assert (e.row, e.column) == (1, "track_id")
    p = _csv(tmp_path, "time,track_id,x,y\n0,1,0,0\n", name="t2.csv")
    assert "vx, vy" in str(_err(p, TrackFileError, read_tracks))


# ----------------------------------------------------------------------------- metrics


def test_write_metrics_converts_numpy_and_dataclasses(tmp_path):
    g = gospa([[0, 0]], [[0, 3], [50, 50]], c=10)
    m = {
        "gospa": g,
        "rmse": np.float32(1.5),
        "count": np.int64(3),
        "ok": np.bool_(True),
        "series": np.arange(3.0),
        "nan": float("nan"),
        "inf": np.inf,
        "nested": {"t": (1, 2), np.int64(4): "four"},
        "path": tmp_path,
    }
    p = write_metrics(m, tmp_path / "m/metrics.json")
    back = json.loads(p.read_text())
    assert back["rmse"] == 1.5 and back["count"] == 3 and back["ok"] is True
    assert back["series"] == [0.0, 1.0, 2.0]
    assert back["nan"] is None and back["inf"] is None
    assert back["nested"] == {"t": [1, 2], "4": "four"}
    assert back["gospa"]["total"] == pytest.approx(g.total)
    assert back["gospa"]["assignment"] == [[0, 0]]
    assert back["path"] == str(tmp_path)
    assert math.isclose(back["gospa"]["localisation"], 9.0)


def test_write_metrics_rejects_unknown_objects(tmp_path):
    with pytest.raises(ValueError, match="object"):
        write_metrics({"a": object()}, tmp_path / "m.json")
    with pytest.raises(ValueError, match="mapping"):
        write_metrics([1, 2], tmp_path / "m.json")


def test_gzip_csv_is_readable_by_gzip(tmp_path):
    p = write_tracks(_tracks(), tmp_path / "t.csv.gz")
    with gzip.open(p, "rt") as fh:
        assert fh.readline().strip() == "time,track_id,x,y,vx,vy"


# ----------------------------------------------------------------------------- layout


def test_io_is_a_package_split_by_concern():
    import jointtrack.io as jio
    from jointtrack.io import detections, errors, jsonify, metrics, tracks

    assert hasattr(jio, "__path__")  # a package, not a module
    assert detections.Detections is Detections and detections.read_detections is read_detections
    assert tracks.read_tracks is read_tracks and tracks.write_tracks is write_tracks
    assert metrics.write_metrics is write_metrics
    assert errors.DataFileError is DataFileError and errors.TrackFileError is TrackFileError
    for name in jio.__all__:
        assert getattr(jio, name) is not None
    assert jsonify.to_jsonable is jio.to_jsonable


def test_one_json_helper_in_the_package():
    """No private numpy-aware JSON copies left: every user imports jointtrack.io's."""
    import pathlib
    import re

    import jointtrack

    root = pathlib.Path(jointtrack.__file__).parent
    copies = []
    for f in root.rglob("*.py"):
        text = f.read_text(encoding="utf-8")
        if f.parent.name == "io" and f.name == "jsonify.py":
            continue
        if re.search(r"def _json(able|ify)\b", text) or re.search(
            r"json\.dumps?\(.*default=", text
        ):
            copies.append(str(f.relative_to(root)))
    assert copies == []


def test_to_jsonable_options():
    from jointtrack.io import to_jsonable

    data = {"a": np.float64("nan"), "b": [np.inf], "e": ValueError("bad")}
    assert to_jsonable(data, nonfinite="string", fallback="text") == {
        "a": "nan",
        "b": ["inf"],
        "e": "ValueError: bad",
    }
    assert to_jsonable({"x": np.int64(3), "y": np.arange(2)}, fallback=float) == {
        "x": 3,
        "y": [0, 1],
    }
    with pytest.raises(ValueError, match="ValueError"):
        to_jsonable(data)


# ----------------------------------------------------------------------------- ISO-8601 times


def test_iso_times_become_seconds_since_the_first_scan(tmp_path):
    p = _csv(
        tmp_path,
        "time,x,y\n"
        "2026-11-23T10:00:00Z,1,2\n"
        "2026-11-23T10:00:00Z,3,4\n"
        "2026-11-23T10:00:00.5Z,5,6\n"
        "2026-11-23T11:00:01.25+01:00,7,8\n",  # = 10:00:01.25Z
    )
    d = read_detections(p)
    assert d.times.tolist() == [0.0, 0.5, 1.25]
    assert d.time_origin == "2026-11-23T10:00:00Z"
    assert [z.shape[0] for z in d.scans] == [2, 1, 1]
    assert d.timestamps() == [
        "2026-11-23T10:00:00Z",
        "2026-11-23T10:00:00.5Z",
        "2026-11-23T10:00:01.25Z",
    ]


def test_iso_times_without_offset_or_fraction(tmp_path):
    p = _csv(tmp_path, "time,x,y\n2026-11-23 23:59:59,1,2\n2026-11-24T00:00:01,3,4\n")
    d = read_detections(p)
    assert d.times.tolist() == [0.0, 2.0]
    assert d.time_origin == "2026-11-23T23:59:59"  # naive in, naive out


def test_numeric_times_have_no_origin(tmp_path):
    d = read_detections(_csv(tmp_path, "time,x,y\n0.5,1,2\n1.5,3,4\n"))
    assert d.times.tolist() == [0.5, 1.5] and d.time_origin is None


@pytest.mark.parametrize("suffix", [".csv", ".csv.gz", ".parquet"])
def test_iso_times_round_trip(tmp_path, suffix):
    p = _csv(
        tmp_path,
        "time,x,y\n2026-11-23T10:00:00.123456789Z,1,2\n2026-11-23T10:00:07.5Z,3,4\n",
    )
    d = read_detections(p)
    back = read_detections(write_detections(d, tmp_path / f"again{suffix}"))
    assert np.array_equal(back.times, d.times)
    assert back.time_origin == d.time_origin == "2026-11-23T10:00:00.123456789Z"


def test_parquet_timestamp_column(tmp_path):
    import datetime as dt

    utc = dt.UTC
    t0 = dt.datetime(2026, 11, 23, 10, 0, 0, tzinfo=utc)
    times = [t0, t0, t0 + dt.timedelta(seconds=0.25), t0 + dt.timedelta(seconds=2)]
    p = _parquet(
        tmp_path,
        {"time": pa.array(times, pa.timestamp("us", tz="UTC")), "x": [1.0] * 4, "y": [2.0] * 4},
    )
    d = read_detections(p)
    assert d.times.tolist() == [0.0, 0.25, 2.0]
    assert d.time_origin == "2026-11-23T10:00:00Z"
    naive = _parquet(
        tmp_path,
        {
            "time": pa.array([t.replace(tzinfo=None) for t in times], pa.timestamp("ms")),
            "x": [1.0] * 4,
            "y": [2.0] * 4,
        },  # fmt: skip
        name="naive.parquet",
    )
    assert read_detections(naive).time_origin == "2026-11-23T10:00:00"


@pytest.mark.parametrize(
    "cell",
    ["ten o'clock", "2026-11-23T10:00:00.5Q", "23/11/2026 10:00", "2026-13-01T00:00:00Z"],
)
def test_time_neither_number_nor_iso(tmp_path, cell):
    p = _csv(tmp_path, f"time,x,y\n2026-11-23T10:00:00Z,1,2\n{cell},3,4\n")
    e = _err(p)
    assert (e.row, e.line, e.column) == (2, 3, "time")
    msg = str(e)
    assert "2026-13-01" in msg or cell in msg  # the bad cell is shown
    assert "number" in msg and "ISO-8601" in msg and "2026-11-23T10:00:00.5Z" in msg
    # the same when the column starts with a number, and in Parquet
    e = _err(_csv(tmp_path, f"time,x,y\n0.0,1,2\n{cell},3,4\n", name="n.csv"))
    assert e.row == 2 and "ISO-8601" in str(e)
    q = _parquet(tmp_path, {"time": ["x0", "1"], "x": [1.0, 2.0], "y": [1.0, 2.0]})
    e = _err(q)
    assert e.row == 1 and "'x0'" in str(e) and "ISO-8601" in str(e)


def test_time_kinds_may_not_be_mixed(tmp_path):
    e = _err(_csv(tmp_path, "time,x,y\n0.0,1,2\n2026-11-23T10:00:00Z,3,4\n"))
    assert e.row == 2 and "column of numbers" in str(e)
    e = _err(_csv(tmp_path, "time,x,y\n2026-11-23T10:00:00Z,1,2\n5,3,4\n", name="b.csv"))
    assert e.row == 2 and "column of timestamps" in str(e)
    e = _err(
        _csv(tmp_path, "time,x,y\n2026-11-23T10:00:00Z,1,2\n2026-11-23T10:00:01,3,4\n", "c.csv")
    )
    assert e.row == 2 and "UTC offset" in str(e)


def test_iso_times_out_of_order_name_the_timestamps(tmp_path):
    p = _csv(tmp_path, "time,x,y\n2026-11-23T10:00:01Z,1,2\n2026-11-23T10:00:00Z,3,4\n")
    e = _err(p)
    assert e.row == 2 and "2026-11-23T10:00:00Z" in str(e) and "earlier" in str(e)


def test_detections_time_origin_validation():
    d = Detections(times=[0.0], scans=[np.zeros((1, 2))], time_origin="2026-11-23T11:00:00+01:00")
    assert d.time_origin == "2026-11-23T10:00:00Z"
    with pytest.raises(ValueError, match="time_origin"):
        Detections(times=[0.0], scans=[np.zeros((1, 2))], time_origin="yesterday")
    with pytest.raises(ValueError, match="time_origin"):
        Detections(times=[0.0], scans=[np.zeros((1, 2))], time_origin=0.0)


# ----------------------------------------------------------------------------- header only


@pytest.mark.parametrize("kind", ["csv", "csv.gz", "parquet", "range-bearing"])
def test_header_only_is_an_error(tmp_path, kind):
    if kind == "parquet":
        p = _parquet(tmp_path, {"time": pa.array([], pa.float64()), "x": pa.array([], pa.float64()),
                                "y": pa.array([], pa.float64())})  # fmt: skip
    elif kind == "csv.gz":
        p = tmp_path / "det.csv.gz"
        with gzip.open(p, "wt") as fh:
            fh.write("time,x,y\n\n")
    else:
        header = "time,range,bearing" if kind == "range-bearing" else "time,x,y"
        p = _csv(tmp_path, header + "\n\n")
    e = _err(p)
    assert "has no detections" in str(e)
    assert str(e).startswith(f"{p}: has no detections")


def test_header_only_with_missing_columns_names_the_columns(tmp_path):
    assert "missing required column" in str(_err(_csv(tmp_path, "time,x\n")))


def test_cli_run_on_header_only_file_fails(tmp_path):
    from typer.testing import CliRunner

    from jointtrack.cli import app

    p = _csv(tmp_path, "time,x,y\n")
    res = CliRunner().invoke(app, ["run", "--no-progress", "--detections", str(p),
                                   "--out", str(tmp_path / "out")])  # fmt: skip
    assert res.exit_code != 0
    assert "has no detections" in res.output
    assert not (tmp_path / "out" / "tracks.csv").exists()
