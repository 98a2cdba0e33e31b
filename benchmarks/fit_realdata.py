"""Issue 32.1: the bare command on the switzerland ADS-B scene — the fitted model.

For each degradation seed, writes the ``adsb`` scene's detections
(:func:`jointtrack.bench.realdata.adsb_scene`: real flights, a synthetic 10 s
scanning sensor with P_D 0.9, 20 false returns per scan, 50 m noise, identities
stripped) as a plain ``time, lat, lon`` CSV, runs the bare command

    jointtrack run --no-progress --detections FILE --out DIR

(a subprocess, wall and CPU timed; no config: every model value is fitted), and
scores its tracks as ``bench realdata`` does
(:func:`jointtrack.metrics.selfreport.score_self_reports`: truth = the undegraded
reports interpolated to the scan times, c = 500 m, window 10 s), in the scene's
frame (the tracks' lat/lon columns). ``--hand`` also runs the hand-set
``ADSB_TRACKER`` (:func:`jointtrack.bench.jointtrack_realdata.run_jointtrack`) on
the same scene in the same process, for the ratio.

    python benchmarks/fit_realdata.py --seeds 1 2 --out DIR [--max-scans N] [--hand] [--config TOML]

``--config`` passes a ``[tracker]`` TOML to the run (ablations: the keys it sets are
not fitted).
"""

from __future__ import annotations

import argparse
import csv
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from jointtrack.bench.realdata import MAX_GAP, adsb_scene
from jointtrack.bench.realdata_data import fetch_realdata
from jointtrack.io.times import format_timestamp, parse_origin
from jointtrack.metrics.selfreport import score_self_reports

KEYS = (
    "coverage",
    "purity",
    "tracks_per_identity",
    "false_tracks_per_hour",
    "gospa_mean",
    "tracks_per_identity_held",
    "lost_straight",
    "lost_manoeuvre",
    "lost_close_pair",
)


def _num(v) -> str:
    """A score for the printout; None (undefined, e.g. no close pairs) as '-'."""
    return "-" if v is None else f"{v:.4g}"


def write_plain(scene, path: Path) -> None:
    """The scene's detections as ``time, lat, lon`` rows (ISO-8601 UTC, ms)."""
    lat, lon = scene.frame.to_geodetic(scene.positions)
    _, ns0, _ = parse_origin(scene.time_origin)
    ns = np.rint(scene.times * 1e9).astype(np.int64)
    with open(path, "w", newline="") as fh:
        fh.write("time,lat,lon\n")
        for k in range(len(ns)):
            stamp = format_timestamp(ns0 + int(ns[k]), True)
            fh.write(f"{stamp},{float(lat[k])!r},{float(lon[k])!r}\n")


#: where the straight-flight truth points a run lost are (:func:`lost_by_kind`)
LOST_KINDS = ("start", "end", "off", "unreported", "id_change")


def lost_by_kind(score) -> dict:
    """Where a run loses straight flight, and what its id changes are (issue 32).

    Each straight truth point not associated (the scorer's ``class_of`` 0) is, along its
    aircraft's flight (its instants up to an absence, below): ``start`` — before the
    flight's first associated instant (confirmation latency); ``end`` — after its last;
    between two associated instants of one track id, ``off`` — that track is reported at
    the instant but more than c away, or ``unreported`` — it is not reported then;
    between two different ids, ``id_change``. Shares of all straight truth points (they add up to
    ``lost_straight``). Each id change along an aircraft's associations is a
    ``new_flight`` when the aircraft is absent at some instant between the two (its
    reports stop for more than the scorer's ``max_gap``: it landed or left and came back
    — no tracker without identities can keep the id), else a ``rebirth`` when the old
    id is never reported after the new id's first report (a track died and another was
    born on the aircraft), else an ``overlap`` (both ids reported at once: a swap or a
    duplicate). ``flights_per_identity``: the mean number of such flights (runs of
    instants without an absence) of the aircraft ``tracks_per_identity`` is averaged
    over (those with a track) — the fewest ids per aircraft any tracker without
    identities can have.
    """
    t, ident, _ = score.truth_sampled
    st = score.statistics
    instants = score.instants
    K = max(len(instants), 1)
    ids_u = np.unique(ident)
    key = np.searchsorted(ids_u, ident) * K + np.searchsorted(instants, t)
    assoc_key = np.searchsorted(ids_u, st.assoc_truth_ids) * K + np.searchsorted(
        instants, st.assoc_times
    )
    track_of = np.full(len(t), -1, np.int64)
    order = np.argsort(key)
    track_of[order[np.searchsorted(key[order], assoc_key)]] = st.assoc_track_ids
    tt, ti, _ = score.tracks_sampled
    reported = set(zip(np.searchsorted(instants, tt).tolist(), ti.tolist(), strict=True))
    first_seen, last_seen = {}, {}
    for k in np.unique(ti):
        when = tt[ti == k]
        first_seen[int(k)], last_seen[int(k)] = float(when.min()), float(when.max())
    counts = dict.fromkeys(LOST_KINDS, 0)
    changes = {"new_flight": 0, "rebirth": 0, "overlap": 0}
    flights = []
    straight = score.class_of == 0
    for rows in np.split(
        np.argsort(key, kind="stable"),
        np.cumsum(np.bincount(np.searchsorted(ids_u, ident), minlength=len(ids_u)))[:-1],
    ):
        trk = track_of[rows]
        held = np.flatnonzero(trk >= 0)
        # an absence: consecutive instants of the aircraft more than one instant apart
        step = np.searchsorted(instants, t[rows])
        away = np.r_[False, np.diff(step) > 1]
        if len(held):
            flights.append(1 + int(away.sum()))
        for a, b in zip(held[:-1], held[1:], strict=True):
            old, new = int(trk[a]), int(trk[b])
            if old != new:
                if away[a + 1 : b + 1].any():
                    changes["new_flight"] += 1
                elif last_seen[old] > first_seen[new]:
                    changes["overlap"] += 1
                else:
                    changes["rebirth"] += 1
        # the lost points of each flight, in that flight alone
        flight = np.cumsum(away)
        for j in np.flatnonzero((trk < 0) & straight[rows]):
            mine = held[flight[held] == flight[j]]
            if not len(mine) or j < mine[0]:
                kind = "start"
            elif j > mine[-1]:
                kind = "end"
            else:
                before = int(trk[mine[mine < j][-1]])
                after = int(trk[mine[mine > j][0]])
                if before != after:
                    kind = "id_change"
                elif (int(np.searchsorted(instants, t[rows[j]])), before) in reported:
                    kind = "off"
                else:
                    kind = "unreported"
            counts[kind] += 1
    n = max(int(straight.sum()), 1)
    return (
        {f"lost_straight_{k}": v / n for k, v in counts.items()}
        | {f"id_changes_{k}": v for k, v in changes.items()}
        | {"flights_per_identity": float(np.mean(flights)) if flights else None}
    )


def score_tracks(scene, run_dir: Path, n_scans: int) -> dict:
    """Self-report scores of ``run_dir/tracks.csv`` in the scene's frame and clock."""
    m = json.loads((run_dir / "metrics.json").read_text())
    _, ns_run, _ = parse_origin(m["time_origin"])
    _, ns_scene, _ = parse_origin(scene.time_origin)
    shift = (ns_run - ns_scene) / 1e9
    with open(run_dir / "tracks.csv") as fh:
        rows = list(csv.DictReader(fh))
    tt = np.array([float(r["time"]) for r in rows]) + shift
    ti = np.array([int(r["track_id"]) for r in rows])
    lat = np.array([float(r["lat"]) for r in rows])
    lon = np.array([float(r["lon"]) for r in rows])
    tp = np.asarray(scene.frame.to_local(lat, lon), dtype=float).reshape(-1, 2)
    t, ids, xy = scene.truth()
    end = float(scene.scan_times[min(n_scans, len(scene.scan_times)) - 1])
    keep = t <= end
    score = score_self_reports(
        t[keep],
        ids[keep],
        xy[keep],
        tt,
        ti,
        tp,
        window=scene.window,
        c=scene.cutoff,
        max_gap=MAX_GAP,
        duration=max(end - float(scene.scan_times[0]), scene.window),
        t0=float(scene.scan_times[0]),
    )
    scores = score.as_dict()
    return (
        {k: scores[k] for k in KEYS}
        | lost_by_kind(score)
        | {"tracker": m["tracker"], "notes": m.get("notes", [])}
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--out", required=True, help="working folder")
    parser.add_argument(
        "--data", default="switzerland", help="switzerland or quickstart (fetch_realdata keys)"
    )
    parser.add_argument("--max-scans", type=int, default=None)
    parser.add_argument("--hand", action="store_true", help="also the hand-set ADSB_TRACKER")
    parser.add_argument(
        "--config",
        default=None,
        help="a TOML passed to the run (ablations: the values it sets are not fitted)",
    )
    args = parser.parse_args()
    work = Path(args.out)
    work.mkdir(parents=True, exist_ok=True)
    path = fetch_realdata(progress=None)[args.data]
    results = []
    for seed in args.seeds:
        scene = adsb_scene(path, seed=seed)
        n_scans = len(scene.scan_times) if args.max_scans is None else args.max_scans
        plain = work / f"adsb-seed{seed}.csv"
        write_plain(scene, plain)
        out = work / f"run-seed{seed}"
        code = "import sys; from jointtrack.cli import main; sys.argv[0] = 'jointtrack'; main()"
        argv = [sys.executable, "-c", code, "run", "--no-progress", "--detections", str(plain)]
        argv += ["--out", str(out)]
        if args.max_scans is not None:
            argv += ["--max-scans", str(args.max_scans)]
        if args.config is not None:
            argv += ["--config", str(Path(args.config).resolve())]
        c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        w0 = time.perf_counter()
        done = subprocess.run(argv, capture_output=True, text=True)
        wall = time.perf_counter() - w0
        c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (c1.ru_utime - c0.ru_utime) + (c1.ru_stime - c0.ru_stime)
        if done.returncode:
            sys.exit(f"jointtrack run failed ({done.returncode}):\n{done.stderr}")
        row = {"seed": seed, "scans": n_scans, "wall_s": wall, "cpu_s": cpu}
        row["data_hours"] = float(scene.scan_times[n_scans - 1] - scene.scan_times[0]) / 3600.0
        row["bare"] = score_tracks(scene, out, n_scans)
        if args.hand:
            from jointtrack.bench.jointtrack_realdata import run_jointtrack
            from jointtrack.bench.realdata import score_run

            sub = scene
            if args.max_scans is not None:
                keep = scene.scan_index < args.max_scans
                from dataclasses import replace

                sub = replace(
                    scene,
                    times=scene.times[keep],
                    positions=scene.positions[keep],
                    scan_index=scene.scan_index[keep],
                    scan_times=scene.scan_times[: args.max_scans],
                    labels=None if scene.labels is None else scene.labels[keep],
                )
            res = score_run(sub, run_jointtrack(sub, wall_cap=1e9))
            row["hand"] = {k: res.score[k] for k in KEYS} if res.score else res.score_error
        results.append(row)
        print(json.dumps({k: v for k, v in row.items() if k != "bare"}, indent=1))
        print(
            f"seed {seed}: bare "
            + ", ".join(f"{k} {_num(row['bare'][k])}" for k in KEYS)
            + "; straight lost by kind (% of straight points): "
            + ", ".join(f"{k} {100 * row['bare'][f'lost_straight_{k}']:.2f}" for k in LOST_KINDS)
            + "; id changes: "
            + ", ".join(
                f"{k} {row['bare'][f'id_changes_{k}']}"
                for k in ("new_flight", "rebirth", "overlap")
            )
            + f" (flights per aircraft {_num(row['bare']['flights_per_identity'])}: the fewest "
            "ids any tracker without identities can have)"
            + f"; CPU {cpu:.0f} s for {row['data_hours']:.1f} h of data "
            f"({row['data_hours'] * 3600 / max(cpu, 1e-9):.0f}× real time)"
        )
        print(
            "fitted:",
            json.dumps(
                {
                    k: row["bare"]["tracker"].get(k)
                    for k in (
                        "measurement_noise",
                        "process_noise",
                        "max_speed",
                        "p_d",
                        "p_g",
                        "clutter_density",
                    )
                }
            ),
        )
    (work / "fit_realdata.json").write_text(json.dumps(results, indent=1))
    for key in KEYS:
        vals = [r["bare"][key] for r in results]
        known = [v for v in vals if v is not None]
        spread = f"{max(known) - min(known):.3g}" if known else "-"
        print(f"{key}: {' '.join(_num(v) for v in vals)} (spread {spread})")


if __name__ == "__main__":
    main()
