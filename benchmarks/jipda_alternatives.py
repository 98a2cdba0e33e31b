"""Issue 33: JIPDA from nothing with tentative tracks jointly associated or as alternatives.

For each seed, ``run_scenario(scene, start_from="nothing", tracker="jipda",
config=...)`` scores the run with its own metrics (GOSPA mean, identity switches,
false tracks, coverage); the same tracker is then stepped directly over the same
scans to count, per target, the scans from its first scan to the first at which a
reported track is its GOSPA partner (Hungarian assignment within the run's c), and
the reported tracks without a partner per scan (false confirmed tracks per scan).
Prints one JSON line per scene and seed set: GOSPA mean ± std (ddof 1), per seed,
switches, false tracks, false per scan, coverage, the median confirmation (a target
never confirmed counts as infinitely late) and every target's confirmation.

    PYTHONPATH=src python benchmarks/jipda_alternatives.py bojilov 0,1,2,3,4 \\
        '{"tentative_association": "alternatives"}'

(the third argument is the ``[tracker]`` table as JSON; ``'{}'`` gives the default
of a run from nothing, ``experiments.config.FROM_NOTHING_JIPDA``, in both passes,
through ``run.start_settings``; ``'{"tentative_association": "joint",
"r_confirm": 0.9}'`` the joint association.) Results: ``benchmarks/RESULTS.md``, issue 33 (jipda).
"""

from __future__ import annotations

import json
import sys
import tempfile

import numpy as np
from scipy.optimize import linear_sum_assignment

from jointtrack.bench.perfect_start import perfect_start_config
from jointtrack.experiments.config import make_scenario
from jointtrack.experiments.run import run_scenario
from jointtrack.trackers import JPDATracker


def confirmation_and_false(scene: str, seed: int, config: dict, c: float):
    """Per-target scans to the first GOSPA partner, and unpartnered reported tracks per scan."""
    sc = make_scenario(scene, seed, {})
    # the settings run_scenario gives a JIPDA run from nothing (the from-nothing
    # defaults for the keys config does not set), so this pass replays that run
    trk = JPDATracker(perfect_start_config(sc, config))
    first, first_truth, false = {}, {}, []
    for k, (t, z) in enumerate(zip(sc.times, sc.detections, strict=True)):
        res = trk.step(t, z)
        X, ids = sc.truth_states[k], sc.truth_ids[k]
        for i in ids:
            first_truth.setdefault(int(i), k)
        if len(X) and len(res.ids):
            D = np.linalg.norm(res.x[:, None, : sc.dim] - X[None, :, : sc.dim], axis=2)
            a, b = linear_sum_assignment(np.minimum(D, c))
            ok = D[a, b] < c
            for j in b[ok]:
                first.setdefault(int(ids[j]), k)
            false.append(len(res.ids) - int(ok.sum()))
        else:
            false.append(len(res.ids))
    conf = [first[i] - first_truth[i] + 1 if i in first else None for i in first_truth]
    return conf, float(np.mean(false))


def main(argv):
    if len(argv) not in (2, 3):
        sys.exit(__doc__)
    scene, seeds = argv[0], [int(s) for s in argv[1].split(",")]
    config = json.loads(argv[2]) if len(argv) == 3 else {}
    rows = []
    for seed in seeds:
        with tempfile.TemporaryDirectory() as out:
            m = run_scenario(
                scene,
                config=config,
                out_dir=out,
                seed=seed,
                start_from="nothing",
                plots=False,
                tracker="jipda",
            )
        conf, false_per_scan = confirmation_and_false(scene, seed, config, m["gospa"]["c"])
        tr = m["tracks"]
        rows.append((m["gospa"]["mean"], tr, conf, false_per_scan))
    g = np.array([r[0] for r in rows])
    every = [np.inf if v is None else v for r in rows for v in r[2]]
    print(
        json.dumps(
            {
                "scene": scene,
                "seeds": seeds,
                "config": config,
                "gospa_mean": round(float(g.mean()), 2),
                "gospa_std": round(float(g.std(ddof=1)), 2) if len(g) > 1 else 0.0,
                "per_seed": [round(float(v), 1) for v in g],
                "switches": [r[1]["n_id_switches"] for r in rows],
                "false_tracks": [r[1]["n_false_tracks"] for r in rows],
                "false_per_scan": round(float(np.mean([r[3] for r in rows])), 3),
                "coverage": [round(float(r[1].get("coverage") or 0.0), 3) for r in rows],
                "confirm_median": float(np.median(every)),
                "confirm": [r[2] for r in rows],
            }
        ),
        flush=True,
    )


if __name__ == "__main__":
    main(sys.argv[1:])
