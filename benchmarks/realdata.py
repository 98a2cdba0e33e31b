"""Real AIS / ADS-B data, jointtrack beside Stone Soup; see jointtrack.bench.realdata.

Same as `jointtrack bench realdata`, plus jointtrack's own runners registered here.
"""

import argparse

from jointtrack.bench import realdata


def run_jointtrack(scene, *, tracker="jipda", wall_cap, workdir=None, progress=None):
    """jointtrack on ``scene`` → :class:`jointtrack.bench.realdata.RunResult`.

    COORDINATOR (issue 24): not written yet — it needs the merged asynchronous
    reporting mode (TrackerConfig.report_interval, p_survive_interval, max_coast;
    JPDATracker.step(t, z, labels=...)) and the PMBM equivalent. Once merged:
    build one scan per ``scene.scan_times[k]`` from the rows with
    ``scene.scan_index == k`` (``scene.labels`` as ``labels=`` when not None),
    configure from ``scene.measurement_noise``, ``scene.p_d``,
    ``scene.clutter_density`` and the reporting rate, run with history on (or
    collect confirmed tracks per scan) inside
    ``realdata.RssSampler()`` — preferably in a fresh process for an honest peak
    RSS — stop at ``wall_cap`` seconds, and return a RunResult whose track table
    holds every confirmed track's (time, id, x, y) per scan.
    """
    raise NotImplementedError(
        f"jointtrack-{tracker} on real data awaits the asynchronous-reporting tracker "
        "(issue 24 item 2); see benchmarks/realdata.py run_jointtrack"
    )


def _jointtrack(tracker):
    def runner(scene, *, wall_cap, workdir=None, progress=None):
        return run_jointtrack(
            scene, tracker=tracker, wall_cap=wall_cap, workdir=workdir, progress=progress
        )

    return runner


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="Solent 30 scans; ADS-B quickstart")
    parser.add_argument("--out", help="folder for realdata.json, track tables and plots")
    parser.add_argument(
        "--scene", action="append", choices=[*realdata.SCENE_NAMES, "all"], help="repeatable"
    )
    parser.add_argument("--runner", action="append", help="only these runners (repeatable)")
    parser.add_argument("--cache-dir", help="data cache (default $JOINTTRACK_DATA)")
    parser.add_argument("--cap", type=float, default=realdata.WALL_CAP, help="seconds per run")
    parser.add_argument("--seed", type=int, default=realdata.SEED)
    parser.add_argument("--stamp", choices=realdata.STAMPS, help="Stone Soup's detection times")
    args = parser.parse_args()
    for name in ("jipda", "pmbm"):
        realdata.register_runner(f"jointtrack-{name}", _jointtrack(name))
    scenes = realdata.SCENE_NAMES if not args.scene or "all" in args.scene else args.scene
    realdata.run(
        quick=args.quick,
        out=args.out,
        scenes=scenes,
        runners=args.runner,
        cache_dir=args.cache_dir,
        wall_cap=args.cap,
        seed=args.seed,
        stamp=args.stamp,
    )
