"""Issue 31 (readers, geodetic frame): two measurements behind choices in jointtrack.io.

1. ``plane``: the 2-D round trip ``LocalFrame.to_geodetic(to_local(lat, lon))``
   against the angle θ between the point's vertical and the reference's (≈ distance /
   6,371 km), for the 8 fixed Newton steps of the old ``to_geodetic`` (re-implemented
   here as the baseline) and for the current one, iterated to convergence: the largest
   ground error (m, ECEF distance) over points on 64 azimuths from 4 references.
   Beyond 60° (``PLANE_MAX_ANGLE``) the current frame refuses the points; the table
   goes on with the Newton iteration alone to show the 1 / cos θ growth.
2. ``csv``: CPU seconds to read the records of a CSV with the old loop (``csv.reader``
   over the file, every blank line a record) and with ``CsvRecords`` (blank runs between
   records skipped in bulk), interleaved in this process, best of ``--repeats``: a
   plain 1,000,000-row file (the common case: the price of the new reader), a
   ``.csv.gz`` of two rows and 10,000,000 blank lines, and a file with a blank line
   after every row (the worst case for the block-by-block path).

Usage: ``PYTHONPATH=src python benchmarks/io_issue31.py [plane|csv|all] [--repeats 3]``.
"""

from __future__ import annotations

import argparse
import csv
import gzip
import tempfile
import time
from pathlib import Path

import numpy as np


def _at_angle(lat0, lon0, angle, azimuth):
    """(lat, lon) arrays of points whose vertical is ``angle`` degrees from (lat0, lon0)'s."""
    p0, l0 = np.deg2rad(lat0), np.deg2rad(lon0)
    up = np.array([np.cos(p0) * np.cos(l0), np.cos(p0) * np.sin(l0), np.sin(p0)])
    east = np.array([-np.sin(l0), np.cos(l0), 0.0])
    north = np.cross(up, east)
    a, z = np.deg2rad(angle), np.deg2rad(azimuth)[:, None]
    n = np.cos(a) * up + np.sin(a) * (np.cos(z) * north + np.sin(z) * east)
    return np.rad2deg(np.arcsin(np.clip(n[:, 2], -1, 1))), np.rad2deg(np.arctan2(n[:, 1], n[:, 0]))


def _eight_steps(frame, xy):
    """The old to_geodetic: u ← u − (h − alt0), 8 times at most (no convergence check)."""
    import pymap3d

    ref = frame.reference
    u = np.zeros(len(xy))
    for _ in range(8):
        _, _, h = pymap3d.enu2geodetic(xy[:, 0], xy[:, 1], u, *ref)
        step = np.asarray(h) - ref[2]
        u = u - step
        if np.all(np.abs(step) < 1e-10):
            break
    lat, lon, _ = pymap3d.enu2geodetic(xy[:, 0], xy[:, 1], u, *ref)
    return np.asarray(lat), np.asarray(lon)


def _newton(frame, xy):
    """The current iteration without the 60° refusal (to show the error past it)."""
    import pymap3d

    ref = frame.reference
    u = np.zeros(len(xy))
    for _ in range(60):
        lat, lon, h = pymap3d.enu2geodetic(xy[:, 0], xy[:, 1], u, *ref)
        cos = np.cos(np.deg2rad(frame.plane_angle(lat, np.mod(lon + 180, 360) - 180)))
        step = (np.asarray(h) - ref[2]) / cos
        u = u - step
        if np.all(np.abs(step) <= 1e-7):
            break
    lat, lon, _ = pymap3d.enu2geodetic(xy[:, 0], xy[:, 1], u, *ref)
    return np.asarray(lat), np.asarray(lon)


def plane() -> None:
    import pymap3d

    from jointtrack.io.geodetic import PLANE_MAX_ANGLE, LocalFrame

    az = np.linspace(0.0, 360.0, 64, endpoint=False)
    refs = [(50.0, -1.0), (0.0, 100.0), (85.0, 10.0), (-33.9, 151.2)]
    print("θ (deg)  ~km     8 fixed steps (m)  current (m)")
    for angle in (1, 9, 20, 30, 45, 59.99, 70, 80, 89, 89.9):
        worst = {"old": 0.0, "new": 0.0}
        for lat0, lon0 in refs:
            f = LocalFrame(lat0, lon0)
            lat, lon = _at_angle(lat0, lon0, angle, az)
            e, n, _ = pymap3d.geodetic2enu(lat, lon, 0.0 * lat, lat0, lon0, 0.0)
            xy = np.column_stack([e, n])
            p = np.column_stack(pymap3d.geodetic2ecef(lat, lon, 0.0 * lat))
            current = f.to_geodetic(xy) if angle <= PLANE_MAX_ANGLE else _newton(f, xy)
            for key, (la, lo) in (("old", _eight_steps(f, xy)), ("new", current)):
                q = np.column_stack(pymap3d.geodetic2ecef(la, lo, 0.0 * la))
                worst[key] = max(worst[key], float(np.max(np.linalg.norm(p - q, axis=1))))
        note = "" if angle <= PLANE_MAX_ANGLE else "  (refused by the frame)"
        km = np.deg2rad(angle) * 6371.0088
        print(f"{angle:7g}  {km:6,.0f}  {worst['old']:17.3g}  {worst['new']:11.3g}{note}")


def _plain_records(fh):
    """The old read_csv loop: every csv.reader record, blank ones skipped one by one."""
    reader = csv.reader(fh)
    n = 0
    for rec in reader:
        if not rec or all(not f.strip() for f in rec):
            continue
        n += 1
        _ = reader.line_num
    return n


def _bulk_records(fh):
    from jointtrack.io._files import CsvRecords

    records = CsvRecords(fh)
    n = 0
    for _ in records:
        n += 1
        _ = records.line
    return n


def _open(path: Path):
    if path.name.endswith(".gz"):
        return gzip.open(path, "rt", newline="", encoding="utf-8-sig")
    return open(path, newline="", encoding="utf-8-sig")  # noqa: SIM115


def csv_speed(repeats: int) -> None:
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as tmp:
        files = {}
        rows = "".join(
            f"{k // 10},{x!r},{y!r}\n"
            for k, (x, y) in enumerate(rng.normal(0, 1e4, (1_000_000, 2)).tolist())
        )
        files["1,000,000 rows"] = Path(tmp) / "rows.csv"
        files["1,000,000 rows"].write_text("time,x,y\n" + rows)
        files["2 rows + 10M blank lines (.gz)"] = Path(tmp) / "blank.csv.gz"
        with gzip.open(files["2 rows + 10M blank lines (.gz)"], "wb", compresslevel=9) as fh:
            fh.write(b"time,x,y\n0,1,2\n")
            for _ in range(10):
                fh.write(b"\n" * 1_000_000)
            fh.write(b"1,2,3\n")
        files["200,000 rows, a blank line after each"] = Path(tmp) / "alt.csv"
        files["200,000 rows, a blank line after each"].write_text(
            "time,x,y\n" + "".join(f"{k},1.5,2.5\n\n" for k in range(200_000))
        )
        print("file                                      old loop (s)  CsvRecords (s)  ratio")
        for name, path in files.items():
            best = {"old": float("inf"), "new": float("inf")}
            counts = set()
            for _ in range(repeats):
                for key, fn in (("old", _plain_records), ("new", _bulk_records)):
                    with _open(path) as fh:
                        t = time.process_time()
                        counts.add(fn(fh))
                        best[key] = min(best[key], time.process_time() - t)
            assert len(counts) == 1, counts  # both read the same records
            ratio = best["new"] / best["old"]
            print(f"{name:40s}  {best['old']:12.3f}  {best['new']:14.3f}  {ratio:5.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", nargs="?", default="all", choices=["plane", "csv", "all"])
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    if args.what in ("plane", "all"):
        plane()
    if args.what in ("csv", "all"):
        csv_speed(args.repeats)


if __name__ == "__main__":
    main()
