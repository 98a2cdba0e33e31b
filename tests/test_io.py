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
    d = read_detections(_csv(tmp_path, "time,x,y\n"))
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
    e = _err(_csv(tmp_path, "time,lat,lon\n0,1,2\n"))
    msg = str(e)
    assert "missing required column(s): x, y (found: time, lat, lon)" in msg
    assert "range, bearing" in msg
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
