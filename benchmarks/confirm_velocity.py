"""Issue 33: the velocity error JIPDA tracks confirm with, from nothing on the headline scene.

For each configuration (a ``[tracker]`` table as JSON) and seed,
``run_scenario("bojilov", start_from="nothing", tracker="jipda", config=...)`` runs;
each track's first reported row (its confirmation) is compared with the nearest true
target at that scan (within 50 m): |Δv|, the norm of the velocity difference. Prints
per configuration the number of such tracks, the median and mean |Δv| and the share
above 2 m/s (the lanes' speed difference).

    PYTHONPATH=src python benchmarks/confirm_velocity.py \\
        '[{"tentative_association": "alternatives"}, {"tentative_association": "splitting"}]' \\
        0,1,2,3,4,5,6,7,8,9

Results: ``benchmarks/RESULTS.md``, issue 33 (track splitting).
"""

from __future__ import annotations

import csv
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from jointtrack.bench.from_nothing import make_scene
from jointtrack.experiments.run import run_scenario

#: a first report farther than this from every target is a false track (not counted)
NEAR = 50.0


def confirmation_velocity_errors(config: dict, seed: int) -> list[float]:
    """|Δv| of every track's first report that lies within NEAR of a target."""
    sc = make_scene("bojilov", seed)
    truth = np.asarray(sc.truth_states)  # (scans, targets, 4), NaN where absent
    with tempfile.TemporaryDirectory() as out:
        run_scenario(
            "bojilov",
            config=config,
            out_dir=out,
            seed=seed,
            start_from="nothing",
            plots=False,
            tracker="jipda",
        )
        first: dict[str, dict] = {}
        with open(Path(out) / "tracks.csv") as f:
            for row in csv.DictReader(f):
                first.setdefault(row["track_id"], row)
    errors = []
    for row in first.values():
        k = int(np.argmin(np.abs(sc.times - float(row["time"]))))
        pos = np.array([float(row["x"]), float(row["y"])])
        vel = np.array([float(row["vx"]), float(row["vy"])])
        d = np.linalg.norm(truth[k][:, :2] - pos, axis=1)
        if np.isnan(d).all():
            continue
        j = int(np.nanargmin(d))
        if d[j] < NEAR:
            errors.append(float(np.linalg.norm(truth[k][j, 2:4] - vel)))
    return errors


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    configs = json.loads(argv[0])
    seeds = [int(s) for s in argv[1].split(",")]
    for config in configs:
        e = np.array([v for s in seeds for v in confirmation_velocity_errors(config, s)])
        print(
            json.dumps(config),
            seeds,
            f"tracks {len(e)}",
            f"|dv| median {np.median(e):.2f} mean {e.mean():.2f}",
            f"share > 2 m/s {(e > 2).mean():.2f}",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
