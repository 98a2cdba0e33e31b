"""Issue 32.5: the Solent AIS file as a plain ``time, lat, lon`` detection file, no config.

Writes the reports of Stone Soup's Solent AIS demo CSV (18,623 reports, 91 vessels)
as ``time, lat, lon`` only — no MMSI, speed or course — runs ``jointtrack run
--detections plain.csv --out OUT`` on it with no config (a subprocess, timed), and
scores the tracks with the project's self-report scorer
(:func:`jointtrack.metrics.selfreport.score_self_reports`: truth = each vessel's own
reports, identities from the original file, in the run's own frame from
``metrics.json`` ``geo_reference``; window 60 s, GOSPA cut-off 500 m, as the
report-file runs of ``jointtrack run``).

    python benchmarks/plain_geodetic.py --ais SolentAIS_20160112_130211.csv --out DIR

``--minutes A B`` keeps the reports from minute A to minute B after the first one
(e.g. ``0 42`` and ``42 85``: the file's first and second halves, one to choose
settings on and one held out).

Besides the scorer's figures, ``vessel_classes`` says where coverage is lost: the
scorer's own coverage summed over classes of vessel from the original file's speeds
and times — under way (median reported speed above :data:`AT_REST` m/s), at rest
reporting < 60 s apart, at rest reporting ≥ 60 s apart (AIS class A at anchor: every
3 minutes), and at rest with one report in the slice.
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from jointtrack.io.geodetic import LocalFrame
from jointtrack.io.reports import read_ais_csv
from jointtrack.io.times import format_timestamp, parse_origin
from jointtrack.metrics.selfreport import score_self_reports

#: the scoring of jointtrack run's report-file runs (realdata._SCORE_C["ais"], 60 s)
WINDOW, C = 60.0, 500.0
#: a vessel whose median reported speed is at most this (m/s) is at rest
AT_REST = 0.25


def write_plain(reports, path: Path) -> None:
    """``time, lat, lon`` rows: ISO-8601 UTC timestamps (ms), degrees as read."""
    _, ns0, _ = parse_origin(reports.time_origin)
    ns = np.rint(reports.times * 1e9).astype(np.int64)
    with open(path, "w", newline="") as fh:
        fh.write("time,lat,lon\n")
        for k in range(len(reports)):
            stamp = format_timestamp(ns0 + int(ns[k]), True)
            fh.write(f"{stamp},{float(reports.lat[k])!r},{float(reports.lon[k])!r}\n")


def vessel_classes(rep, identity_of: dict, score) -> dict:
    """The scorer's coverage split by class of vessel (module docstring): per class, its
    vessels, their instants and the fraction of those associated with a track
    (``score.identity_associated`` / ``identity_instants`` summed over the class, so
    the classes' instants and associations add up to the scorer's coverage).
    ``identity_of``: identity → truth id, as :meth:`Reports.truth` returns it."""
    t = np.asarray(rep.times, float)
    ids = np.asarray(rep.identity)
    speed = np.asarray(rep.speed, float)
    row = {int(i): k for k, i in enumerate(np.asarray(score.identity_ids).tolist())}
    out: dict = {}
    for vessel, truth_id in identity_of.items():
        mine = ids == vessel
        gaps = np.diff(t[mine])
        moving = np.isfinite(speed[mine]).any() and np.nanmedian(speed[mine]) > AT_REST
        if moving:
            cls = "under way"
        elif not gaps.size:
            cls = "at rest, one report"
        elif np.median(gaps) >= 60.0:
            cls = "at rest, reports >= 60 s apart"
        else:
            cls = "at rest, reports < 60 s apart"
        c = out.setdefault(cls, {"vessels": 0, "instants": 0, "associated": 0})
        c["vessels"] += 1
        k = row.get(int(truth_id))
        if k is not None:
            c["instants"] += int(score.identity_instants[k])
            c["associated"] += int(score.identity_associated[k])
    for c in out.values():
        c["coverage"] = c["associated"] / c["instants"] if c["instants"] else float("nan")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--ais", required=True, help="Stone Soup's SolentAIS_*.csv")
    parser.add_argument("--out", required=True, help="working folder")
    parser.add_argument(
        "--minutes",
        nargs=2,
        type=float,
        metavar=("FROM", "TO"),
        help="only the reports from minute FROM to minute TO after the first report",
    )
    parser.add_argument(
        "--config", help="a TOML passed to jointtrack run (ablations; the benchmark has none)"
    )
    args = parser.parse_args()
    work = Path(args.out)
    work.mkdir(parents=True, exist_ok=True)
    rep = read_ais_csv(args.ais)
    if args.minutes:
        since = (rep.times - rep.times[0]) / 60.0
        rep = rep.subset((since >= args.minutes[0]) & (since < args.minutes[1]))
    plain = work / "plain.csv"
    write_plain(rep, plain)
    out = work / "run"
    code = "import sys; from jointtrack.cli import main; sys.argv[0] = 'jointtrack'; main()"
    argv = [sys.executable, "-c", code, "run", "--no-progress", "--detections", str(plain)]
    if args.config:
        argv += ["--config", args.config]
    t0 = time.perf_counter()
    done = subprocess.run([*argv, "--out", str(out)], capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    print(done.stdout)
    if done.returncode:
        sys.exit(f"jointtrack run failed ({done.returncode}):\n{done.stderr}")
    m = json.loads((out / "metrics.json").read_text())
    geo = m["geo_reference"]
    frame = LocalFrame(geo["lat"], geo["lon"], geo["alt"])
    # the vessels' own reports, in the run's frame (the run left out its outliers:
    # score against the same reports, so that a corrupt position is no one's truth)
    keep = np.ones(len(rep), dtype=bool)
    if geo["outliers_excluded"]:
        keep = rep.centre().outliers == False  # noqa: E712 - a mask, elementwise
    truth = rep.subset(keep).truth(frame)
    with open(out / "tracks.csv") as fh:
        rows = list(csv.DictReader(fh))
    tt = np.array([float(r["time"]) for r in rows])
    ti = np.array([int(r["track_id"]) for r in rows])
    tp = np.array([[float(r["x"]), float(r["y"])] for r in rows]).reshape(-1, 2)
    score = score_self_reports(
        truth[0], truth[1], truth[2], tt, ti, tp, window=WINDOW, c=C, t0=float(rep.times[0])
    )
    classes = vessel_classes(rep.subset(keep), truth[3], score)
    result = {
        "minutes": args.minutes,
        "reports": len(rep),
        "vessels": len(truth[3]),
        "run_seconds": seconds,
        "confirmed_tracks": m["tracks"]["n_tracks"],
        "outliers_excluded": geo["outliers_excluded"],
        "geo_reference": [geo["lat"], geo["lon"]],
        "tracker": {k: m["tracker"].get(k) for k in ("reporting", "report_interval")},
        "notes": m.get("notes", []),
        "self_reports": score.as_dict(),
        "vessel_classes": classes,
    }
    (work / "plain_geodetic.json").write_text(json.dumps(result, indent=1))
    print(json.dumps({k: v for k, v in result.items() if k != "notes"}, indent=1))
    print("self-reports:", score.summary())
    for name, c in classes.items():
        share = f"{c['vessels']} vessels, {c['instants']} instants"
        print(f"{name}: {share}, coverage {c['coverage']:.3f}")


if __name__ == "__main__":
    main()
