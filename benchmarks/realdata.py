"""Real AIS / ADS-B data, jointtrack beside Stone Soup; see jointtrack.bench.realdata.

Same as `jointtrack bench realdata` (the runners, jointtrack's and Stone Soup's, live in
jointtrack.bench.realdata): jointtrack-handset, jointtrack-bare[-jipda|-pmb|-pmbm],
stonesoup-demo/nn/gnn/jpda on Solent (labelled and not), switzerland (adsb) and the
held-out quickstart flights (adsb-quickstart), over --seeds degradation seeds.
"""

import argparse

from jointtrack.bench import realdata

if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--quick", action="store_true", help="Solent's first 30 scans; ADS-B's first 30 min"
    )
    parser.add_argument("--out", help="folder for realdata.json, track tables and plots")
    parser.add_argument(
        "--scene", action="append", choices=[*realdata.SCENE_NAMES, "all"], help="repeatable"
    )
    parser.add_argument("--runner", action="append", help="only these runners (repeatable)")
    parser.add_argument("--cache-dir", help="data cache (default $JOINTTRACK_DATA)")
    parser.add_argument("--cap", type=float, default=realdata.WALL_CAP, help="seconds per run")
    parser.add_argument("--seed", type=int, default=realdata.SEED)
    parser.add_argument("--seeds", type=int, default=1, help="ADS-B seeds SEED … SEED+N-1")
    parser.add_argument(
        "--bare-tracker", action="append", choices=realdata.BARE_TRACKERS, help="repeatable"
    )
    parser.add_argument("--stamp", choices=realdata.STAMPS, help="Stone Soup's detection times")
    args = parser.parse_args()
    scenes = realdata.SCENE_NAMES if not args.scene or "all" in args.scene else args.scene
    realdata.run(
        quick=args.quick,
        out=args.out,
        scenes=scenes,
        runners=args.runner,
        cache_dir=args.cache_dir,
        wall_cap=args.cap,
        seed=args.seed,
        seeds=args.seeds,
        bare_trackers=tuple(args.bare_tracker or ()),
        stamp=args.stamp,
    )
