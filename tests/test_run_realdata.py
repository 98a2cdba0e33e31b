"""``jointtrack run --detections`` on self-report files (issue 24): AIS, OpenSky, traffic.

The files are the test's own: ships and aircraft on straight lines, written in
the three public layouts (Stone Soup's AIS CSV, OpenSky states CSV, traffic's
gzip JSON records) with positions from pymap3d. Checked end to end through the
CLI: the outputs, lat/lon that invert the local x, y, the frame's reference,
scoring against the reports, each identity one track; one-line errors for bad
flags and files; and a run killed (SIGKILL) at several random instants, resumed
from its checkpoint alone, equal to the uninterrupted run.
"""

from __future__ import annotations

import csv
import gzip
import json
import math
import signal
from dataclasses import dataclass
from datetime import datetime, timedelta

import matplotlib.image
import numpy as np
import pymap3d
import pytest
from typer.testing import CliRunner

from cli_checks import one_line_error
from jointtrack.cli import app
from test_run_durable import _cli, _rows

runner = CliRunner()

KNOT = 1852.0 / 3600.0
FOOT = 0.3048
SPAN = 1200.0  # seconds of reports in the AIS file (20 min)
AIS_T0 = datetime(2016, 1, 12, 13, 2, 11, 218000)  # as Stone Soup's Solent file
AIS_HEADER = "Time,MMSI,Latitude_degrees,Longitude_degrees,COG_degrees,SOG_knots"
OPENSKY_HEADER = (
    "time,icao24,lat,lon,velocity,heading,vertrate,callsign,onground,alert,spi,squawk,"
    "baroaltitude,geoaltitude,lastposupdate,lastcontact"
)


@dataclass(frozen=True)
class Mover:
    """A target on a straight line: east/north metres at t = 0 about (lat0, lon0),
    speed (m/s) along a course (degrees from north), one report every ``interval`` s
    (times jittered by ±30 %)."""

    ident: str
    east: float
    north: float
    speed: float
    course: float
    interval: float

    def geodetic(self, t, lat0, lon0):
        t = np.asarray(t, dtype=float)
        c = math.radians(self.course)
        e = self.east + self.speed * math.sin(c) * t
        n = self.north + self.speed * math.cos(c) * t
        lat, lon, _ = pymap3d.enu2geodetic(e, n, np.zeros_like(e), lat0, lon0, 0.0)
        return np.asarray(lat, float), np.asarray(lon, float)

    def report_times(self, rng, span):
        times, t = [], float(rng.uniform(0.0, self.interval))
        while t < span:
            times.append(t)
            t += self.interval * float(rng.uniform(0.7, 1.3))
        return np.array(times)


# six ships near the Solent reporting every 5 s to every 3 min, one of them moored
# (SOG 0, COG 360 = "not available"); none comes within 1 km of another
SHIPS = (
    (50.7, -1.1),
    [
        Mover("235000001", -4000.0, -2000.0, 8.0 * KNOT, 60.0, 5.0),
        Mover("235000002", 3000.0, 2500.0, 12.0 * KNOT, 200.0, 12.0),
        Mover("235000003", -2500.0, 3000.0, 0.0, 360.0, 180.0),
        Mover("235000004", 0.0, -3500.0, 5.0 * KNOT, 300.0, 30.0),
        Mover("235000005", 4500.0, -1000.0, 15.0 * KNOT, 350.0, 60.0),
        Mover("235000006", -6000.0, 5000.0, 10.0 * KNOT, 100.0, 90.0),
    ],
)
# aircraft near Heathrow (OpenSky, states every 10 s) and Paris (traffic, every 2-8 s)
PLANES_OPENSKY = (
    (51.47, -0.45),
    [
        Mover("3c4591", -30000.0, 0.0, 230.0, 90.0, 10.0),
        Mover("407a19", 20000.0, 15000.0, 200.0, 250.0, 10.0),
        Mover("452057", 40000.0, -25000.0, 180.0, 10.0, 10.0),
    ],
)
PLANES_TRAFFIC = (
    (48.48, 3.83),
    [
        Mover("0101de", 0.0, 0.0, 167.0, 311.0, 5.0),
        Mover("3944ef", 30000.0, -20000.0, 220.0, 45.0, 5.0),
        Mover("4ca7b3", -20000.0, 25000.0, 150.0, 170.0, 5.0),
    ],
)


def _min_separation(movers, lat0, lon0, span) -> float:
    """The closest approach (m) of any two movers over [0, span]."""
    t = np.linspace(0.0, span, 601)
    pos = [np.column_stack(m.geodetic(t, lat0, lon0)) for m in movers]
    best = math.inf
    for i in range(len(pos)):
        for j in range(i + 1, len(pos)):
            e, n, _ = pymap3d.geodetic2enu(
                pos[i][:, 0], pos[i][:, 1], 0.0, pos[j][:, 0], pos[j][:, 1], 0.0
            )
            best = min(best, float(np.hypot(e, n).min()))
    return best


def write_ais(path, seed=0, bad_latitude=None):
    """The ships' reports as Stone Soup's AIS CSV; ``bad_latitude = (row, text)``
    replaces that data row's (1-based) latitude cell. Returns the rows written."""
    (lat0, lon0), ships = SHIPS
    rng = np.random.default_rng(seed)
    rows = []
    for ship in ships:
        times = np.round(ship.report_times(rng, SPAN), 3)  # the file has milliseconds
        lat, lon = ship.geodetic(times, lat0, lon0)
        cog = "360" if ship.speed == 0 else f"{ship.course:g}"
        for t, la, lo in zip(times, lat, lon, strict=True):
            rows.append([t, ship.ident, repr(float(la)), repr(float(lo)), cog, ship.speed / KNOT])
    rows.sort(key=lambda r: (r[0], r[1]))
    if bad_latitude is not None:
        rows[bad_latitude[0] - 1][2] = bad_latitude[1]
    with open(path, "w", newline="") as fh:
        fh.write(AIS_HEADER + "\n")
        for t, mmsi, la, lo, cog, sog in rows:
            stamp = (AIS_T0 + timedelta(seconds=t)).strftime("%Y-%m-%d %H:%M:%S.%f")[:-3]
            fh.write(f"{stamp},{mmsi},{la},{lo},{cog},{sog:.1f}\n")
    return rows


def write_opensky(path, span=480.0):
    """OpenSky state vectors every 10 s (Unix seconds), one state without a position.
    Returns the positions written ``(lat, lon)``."""
    (lat0, lon0), planes = PLANES_OPENSKY
    t0 = 1626098400
    lines = [OPENSKY_HEADER]
    written = []
    for k in range(int(span // 10)):
        t = 10.0 * k
        for p in planes:
            lat, lon = p.geodetic([t], lat0, lon0)
            written.append((float(lat[0]), float(lon[0])))
            lines.append(
                f"{t0 + int(t)},{p.ident},{float(lat[0])!r},{float(lon[0])!r},{p.speed},"
                f"{p.course},0.0,"
                f"BOX{p.ident[:3]}  ,False,False,False,1174.0,10668.0,10843.26,"
                f"{t0 + t - 0.5},{t0 + t}"
            )
    lines.append(f"{t0 + 20},3c4591,,,,,,BOX3c4  ,False,False,False,,,,,")  # no position
    path.write_text("\n".join(lines) + "\n")
    return written


def write_traffic(path, seed=3, span=420.0):
    """traffic's records (gzip JSON list; ms timestamps, feet, knots), one without a
    position. Returns the positions written ``(lat, lon)``."""
    (lat0, lon0), planes = PLANES_TRAFFIC
    rng = np.random.default_rng(seed)
    t0_ms = 1633608773000
    records = []
    for p in planes:
        times = np.round(p.report_times(rng, span), 3)
        lat, lon = p.geodetic(times, lat0, lon0)
        for t, la, lo in zip(times, lat, lon, strict=True):
            records.append(
                {
                    "altitude": 34975.0,
                    "callsign": f"CS{p.ident[:4]}",
                    "groundspeed": p.speed / KNOT,
                    "icao24": p.ident,
                    "latitude": float(la),
                    "longitude": float(lo),
                    "onground": False,
                    "timestamp": t0_ms + int(round(t * 1000)),
                    "track": p.course,
                    "vertical_rate": 0.0,
                }
            )
    records.sort(key=lambda r: r["timestamp"])
    records.insert(5, {**records[4], "latitude": None, "longitude": None})
    path.write_bytes(gzip.compress(json.dumps(records).encode()))
    return [(r["latitude"], r["longitude"]) for r in records if r["latitude"] is not None]


def _run(*args):
    """``jointtrack run`` in this process (the kernels stay loaded between calls)."""
    return runner.invoke(app, ["run", "--no-progress", *map(str, args)])


def _tracks(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return {name: np.array([float(r[i]) for r in rows[1:]]) for i, name in enumerate(rows[0])}


def _comparable(metrics: dict) -> dict:
    """metrics.json without what legitimately differs between an interrupted and an
    uninterrupted run: the timing and the scans of the last process."""
    return {k: v for k, v in metrics.items() if k not in ("timing", "n_scans_this_run")}


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    base = tmp_path_factory.mktemp("reports")
    rows = write_ais(base / "ais.csv")
    geo = {"states.csv": write_opensky(base / "states.csv")}
    geo["flights.json.gz"] = write_traffic(base / "flights.json.gz")
    (base / "det.csv").write_text("time,x,y\n0,1.0,2.0\n1,1.5,2.5\n")
    return base, rows, geo


@pytest.fixture(scope="module")
def full_ais(data):
    """The uninterrupted AIS run (default reference, labels associate)."""
    base, _, _ = data
    r = _run("--detections", base / "ais.csv", "--out", base / "full")
    assert r.exit_code == 0, r.output
    return base / "full"


def test_the_movers_are_apart():
    # the identity checks below assume no two targets are ever close
    assert _min_separation(SHIPS[1], *SHIPS[0], SPAN) > 1000.0
    assert _min_separation(PLANES_OPENSKY[1], *PLANES_OPENSKY[0], 480.0) > 4000.0
    assert _min_separation(PLANES_TRAFFIC[1], *PLANES_TRAFFIC[0], 420.0) > 4000.0


# ----------------------------------------------------------------------------- outputs


def _check_geodetic_columns(tracks, ref):
    """lat, lon of every row are the point whose local east/north about ``ref`` is x, y."""
    lat0, lon0, alt0 = ref
    assert len(tracks["x"]) > 0
    e, n, _ = pymap3d.geodetic2enu(tracks["lat"], tracks["lon"], alt0, lat0, lon0, alt0)
    np.testing.assert_allclose(e, tracks["x"], rtol=0, atol=1e-6)
    np.testing.assert_allclose(n, tracks["y"], rtol=0, atol=1e-6)


def _one_track_per_identity(tracks, movers, lat0, lon0, tol, shift):
    """Each row of the tracks lies within ``tol`` m of one mover; each track id follows
    one mover and each mover has one track id. ``shift``: the movers' time (s) at the
    tracks' t = 0 (the file's first report). Returns {identity: track id}."""
    names = [m.ident for m in movers]
    dist = []
    for m in movers:
        lat, lon = m.geodetic(tracks["time"] + shift, lat0, lon0)
        e, n, _ = pymap3d.geodetic2enu(tracks["lat"], tracks["lon"], 0.0, lat, lon, 0.0)
        dist.append(np.hypot(e, n))
    dist = np.array(dist)
    nearest = dist.argmin(axis=0)
    assert dist.min(axis=0).max() < tol, dist.min(axis=0).max()
    owner: dict = {}
    for tid, who in zip(tracks["track_id"].astype(int), nearest, strict=True):
        owner.setdefault(tid, set()).add(names[who])
    assert all(len(v) == 1 for v in owner.values()), owner
    by_identity: dict = {}
    for tid, who in owner.items():
        by_identity.setdefault(next(iter(who)), []).append(tid)
    assert sorted(by_identity) == sorted(names), by_identity
    assert all(len(v) == 1 for v in by_identity.values()), by_identity
    return {k: v[0] for k, v in by_identity.items()}


def _expected_centre(lat, lon):
    """The frame's default origin as documented (Reports.centre, geodetic.data_centre):
    the centre of the latitude/longitude bounding box of the reports that are not
    outliers — here all of them (the ships are a few km apart)."""
    lat, lon = np.asarray(lat, float), np.asarray(lon, float)
    return 0.5 * (lat.min() + lat.max()), 0.5 * (lon.min() + lon.max())


def test_ais_run_writes_lat_lon_tracks_scored_against_the_reports(data, full_ais):
    base, rows, _ = data
    out = full_ais
    for name in ("tracks.csv", "metrics.json", "map.png", "scene.png"):
        assert (out / name).is_file(), name
    assert (out / "map.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    image = matplotlib.image.imread(out / "map.png")
    assert image.ndim == 3 and min(image.shape[:2]) > 200 and image.std() > 0
    m = json.loads((out / "metrics.json").read_text())
    lat = [float(r[2]) for r in rows]
    lon = [float(r[3]) for r in rows]
    geo = m["geo_reference"]
    assert (geo["lat"], geo["lon"], geo["alt"]) == pytest.approx(
        (*_expected_centre(lat, lon), 0.0), abs=1e-12
    )
    assert geo["outliers_excluded"] == 0
    tracks = _tracks(out / "tracks.csv")
    assert list(tracks)[:6] == ["time", "track_id", "x", "y", "lat", "lon"]
    _check_geodetic_columns(tracks, (geo["lat"], geo["lon"], geo["alt"]))

    s = m["self_reports"]
    assert s["labels"] == "associate" and s["n_identities"] == len(SHIPS[1])
    assert s["coverage"] >= 0.99 and s["purity"] >= 0.99, s
    assert s["tracks_per_identity"] == 1.0 and s["n_id_switches"] == 0
    assert all(v["tracks"] == 1 for v in s["per_identity"].values())
    assert s["n_false_tracks"] == 0 and m["tracks"]["n_tracks"] == len(SHIPS[1])
    # counted at the scans whose tracks are written: the six ships are held throughout
    assert m["tracks"]["max_confirmed_per_scan"] == len(SHIPS[1])
    assert m["tracks"]["mean_confirmed_per_scan"] > 0.8 * len(SHIPS[1])
    # independently of the scoring: every track row is on one ship, one id per MMSI
    _one_track_per_identity(tracks, SHIPS[1], *SHIPS[0], tol=60.0, shift=rows[0][0])
    # one scan per report time; tracks written once per 60 s scoring window
    assert m["n_scans"] == len({r[0] for r in rows})
    assert len(np.unique(tracks["time"])) <= math.ceil(SPAN / 60.0) + 1


def test_given_reference_and_labels_only_scored(data):
    base, rows, _ = data
    out = base / "score"
    ref = (50.71, -1.12, 5.0)
    r = _run(
        "--detections", base / "ais.csv", "--out", out, "--labels", "score",
        "--reference", ",".join(map(str, ref)),
    )  # fmt: skip
    assert r.exit_code == 0, r.output
    m = json.loads((out / "metrics.json").read_text())
    geo = m["geo_reference"]
    assert (geo["lat"], geo["lon"], geo["alt"]) == ref
    assert m["source"]["reports"]["labels"] == "score"
    tracks = _tracks(out / "tracks.csv")
    _check_geodetic_columns(tracks, ref)
    s = m["self_reports"]
    assert s["labels"] == "score"
    for key in ("coverage", "purity", "gospa_mean", "tracks_per_identity"):
        assert isinstance(s[key], float) and math.isfinite(s[key]), key
    assert 0.0 <= s["coverage"] <= 1.0 and 0.0 <= s["purity"] <= 1.0
    assert (out / "map.png").read_bytes()[:4] == b"\x89PNG"


def test_labels_ignored_and_a_window(data):
    base, rows, _ = data
    r = _run("--detections", base / "ais.csv", "--out", base / "ign", "--labels", "ignore")
    assert r.exit_code == 0, r.output
    m = json.loads((base / "ign" / "metrics.json").read_text())
    assert "self_reports" not in m and "geo_reference" in m
    assert (base / "ign" / "map.png").read_bytes()[:4] == b"\x89PNG"

    r = _run("--detections", base / "ais.csv", "--out", base / "win", "--window", "60")
    assert r.exit_code == 0, r.output
    m = json.loads((base / "win" / "metrics.json").read_text())
    # Stone Soup's TimeSyncFeeder windows: the first report's instant, then (t0+(k-1)w, t0+kw]
    t = np.array(sorted(r[0] for r in rows)) - rows[0][0]
    assert m["n_scans"] == int(np.ceil(np.round(t[-1], 6) / 60.0)) + 1
    assert m["source"]["reports"]["window"] == 60.0
    assert m["self_reports"]["window_seconds"] == 60.0
    assert m["self_reports"]["coverage"] >= 0.9
    tracks = _tracks(base / "win" / "tracks.csv")
    g = m["geo_reference"]
    _check_geodetic_columns(tracks, (g["lat"], g["lon"], g["alt"]))
    assert set(np.round(tracks["time"], 6)) <= {60.0 * k for k in range(int(SPAN // 60) + 2)}
    # a later run of a detections file into that directory leaves no stale map
    r = _run("--detections", base / "det.csv", "--out", base / "win")
    assert r.exit_code == 0, r.output
    assert not (base / "win" / "map.png").exists()


@pytest.mark.parametrize(
    "name, movers, shift",
    [("states.csv", PLANES_OPENSKY, 0.0), ("flights.json.gz", PLANES_TRAFFIC, None)],
)
def test_adsb_files_give_one_track_per_aircraft(data, name, movers, shift):
    base, _, geo = data
    out = base / f"out-{name.split('.')[0]}"
    r = _run("--detections", base / name, "--out", out)
    assert r.exit_code == 0, r.output
    m = json.loads((out / "metrics.json").read_text())
    g = m["geo_reference"]
    tracks = _tracks(out / "tracks.csv")
    _check_geodetic_columns(tracks, (g["lat"], g["lon"], g["alt"]))
    (lat0, lon0), planes = movers
    lat, lon = np.array(geo[name]).T  # the rows without a position are left out
    assert (g["lat"], g["lon"], g["alt"]) == pytest.approx(
        (*_expected_centre(lat, lon), 0.0), abs=1e-12
    )
    if shift is None:  # the tracks' t = 0 is the file's first record
        recs = json.loads(gzip.decompress((base / name).read_bytes()))
        shift = (min(r["timestamp"] for r in recs) - 1633608773000) / 1000.0
    _one_track_per_identity(tracks, planes, lat0, lon0, tol=300.0, shift=shift)
    s = m["self_reports"]
    assert s["n_identities"] == len(planes) and s["tracks_per_identity"] == 1.0
    assert s["coverage"] >= 0.99 and s["purity"] >= 0.99 and s["n_false_tracks"] == 0
    if name == "states.csv":
        # states on whole 10 s: the tracks are written at the scoring instants themselves
        # (the last scan of each window (t - 60, t]), not one scan (2.3 km) before them
        times = np.unique(tracks["time"])
        assert set(times[:-1].tolist()) <= {60.0 * k for k in range(9)}, times
    assert (out / "map.png").read_bytes()[:4] == b"\x89PNG"


# ----------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    "extra, needles",
    [
        (["--window", "0"], ["--window", "0"]),
        (["--window", "-1"], ["--window", "-1"]),
        (["--window", "nan"], ["--window", "nan"]),
        (["--window", "inf"], ["--window", "inf"]),
        (["--window", "1e-6"], ["window", "1e-06", "scans", "longer window"]),
        (["--labels", "foo"], ["--labels", "foo", "associate"]),
        (["--reference", "abc"], ["--reference", "abc"]),
        (["--reference", "95,0"], ["--reference", "95"]),
        (["--reference", "50,nan"], ["--reference", "nan"]),
        (["--reference", "50,-1,0,7"], ["--reference"]),
        (["--tracker", "jpda"], ["--tracker jpda", "report", "M-of-N"]),
        (["--truth", "ais.csv"], ["--truth"]),
    ],
)
def test_bad_flags_on_a_report_file_are_one_line(data, monkeypatch, extra, needles):
    base, _, _ = data
    monkeypatch.chdir(base)
    r = _run("--detections", "ais.csv", "--out", "bad", *extra)
    one_line_error(r, *needles)
    assert not (base / "bad" / "tracks.csv").exists()


@pytest.mark.parametrize("flag, value", [("--window", "60"), ("--labels", "score")])
def test_report_flags_on_a_plain_detections_file_are_refused(data, flag, value):
    base, _, _ = data
    r = _run("--detections", base / "det.csv", "--out", base / "plain", flag, value)
    one_line_error(r, flag, "det.csv", "report files")


@pytest.mark.parametrize("cell, reason", [("abc", "'abc'"), ("95.5", "95.5")])
def test_a_bad_latitude_cell_is_named_by_row_and_column(tmp_path, cell, reason):
    write_ais(tmp_path / "bad.csv", bad_latitude=(17, cell))
    r = _run("--detections", tmp_path / "bad.csv", "--out", tmp_path / "o")
    line = one_line_error(r, "bad.csv", "data row 17", "line 18", reason)
    assert "latitude_degrees" in line.lower()


def test_a_missing_file_is_named(tmp_path):
    r = _run("--detections", tmp_path / "nowhere.csv", "--out", tmp_path / "o")
    one_line_error(r, "nowhere.csv", "not found")


# ----------------------------------------------------------------------------- checkpoints


def test_killed_at_random_instants_the_resumed_run_equals_the_uninterrupted_one(
    data, full_ais, tmp_path
):
    base, rows, _ = data
    n_scans = len({r[0] for r in rows})
    every = 25
    # three kills in one run, each at a random scan and stage (seeded): after the
    # scan's rows, after a part was committed, after the checkpoint
    rng = np.random.default_rng(24)
    cuts = np.sort(rng.choice(np.arange(1, n_scans // every), size=3, replace=False)) * every
    faults = []
    for cut in cuts:
        stage = str(rng.choice(["scan", "part", "checkpoint"]))
        # part / checkpoint happen at the last scan of every `every`; "scan" anywhere
        # between two of them, so the kills come in scan order and each one is reached
        k = int(cut) - 1 if stage != "scan" else int(cut) + int(rng.integers(0, every - 1))
        faults.append(f"{stage}:{k}")
    args = ["--detections", base / "ais.csv", "--checkpoint-every", every]
    _kill_resume_and_compare(tmp_path, args, faults, full_ais, "csv")


def test_a_killed_windowed_parquet_run_resumes_with_its_own_settings(data, tmp_path):
    # a bare --resume takes the window, frame and label use from the checkpoint
    base, _, _ = data
    args = ["--detections", base / "ais.csv", "--window", "30", "--labels", "score"]
    args += ["--reference", "50.72,-1.08", "--format", "parquet"]
    full = _run(*args, "--out", tmp_path / "full")
    assert full.exit_code == 0, full.output
    k = int(np.random.default_rng(5).integers(6, 36))
    _kill_resume_and_compare(
        tmp_path, [*args, "--checkpoint-every", 4], [f"scan:{k}"], tmp_path / "full", "parquet"
    )


def _kill_resume_and_compare(cwd, args, faults, full, fmt):
    """Run ``jointtrack run ARGS --out part --checkpoint ck.npz`` in subprocesses killed
    by each fault in turn (each a ``--resume ck.npz`` once the checkpoint exists), then
    resume with ``--resume ck.npz`` alone: the tracks and metrics (but the timing) are
    those of the uninterrupted run in ``full``."""
    first = ["run", "--no-progress", *args, "--out", "part", "--checkpoint", "ck.npz"]
    for fault in faults:
        again = ["run", "--resume", "ck.npz"] if (cwd / "ck.npz").exists() else first
        killed = _cli(again, cwd, fault)
        assert killed.returncode == -signal.SIGKILL, (fault, killed.stderr)
    resumed = _run("--resume", cwd / "ck.npz")  # no other flag
    assert resumed.exit_code == 0, resumed.output
    part = cwd / "part"
    assert _rows(part, fmt) == _rows(full, fmt)
    got = _comparable(json.loads((part / "metrics.json").read_text()))
    want = _comparable(json.loads((full / "metrics.json").read_text()))
    for key in ("files", "tracks_file"):  # the two runs' output directories
        got[key] = json.loads(json.dumps(got[key]).replace(str(part), "OUT"))
        want[key] = json.loads(json.dumps(want[key]).replace(str(full), "OUT"))
    assert got == want
    assert (part / "map.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize(
    "extra, flag",
    [
        (["--window", "30"], "--window"),
        (["--labels", "score"], "--labels"),
        (["--reference", "50.6,-1.0"], "--reference"),
    ],
)
def test_resume_refuses_other_report_settings(data, tmp_path, extra, flag):
    base, _, _ = data
    r = _run(
        "--detections", base / "ais.csv", "--out", tmp_path / "o", "--window", "60",
        "--checkpoint", tmp_path / "ck.npz", "--max-scans", "5",
    )  # fmt: skip
    assert r.exit_code == 0, r.output
    one_line_error(_run("--resume", tmp_path / "ck.npz", *extra), flag)
    # the same settings are accepted
    same = _run("--resume", tmp_path / "ck.npz", "--window", "60", "--labels", "associate")
    assert same.exit_code == 0, same.output
