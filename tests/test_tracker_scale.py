"""The JPDA tracker at scale: memory on a huge scan, work per track at constant density.

No timing here (see ``jointtrack bench tracker`` for that): a 20,000-detection
scan must complete in a fresh process under a 2 GiB address-space limit (before
the linear-scaling rewrite it tried to allocate 11.9 GiB), and the number of
gating candidate pairs examined per track — ``PairGating.n_candidates``, read
by wrapping the tracker's ``gate_pairs`` — must not grow with the number of
targets at constant density (likewise the two-point initiation candidates per
new return).
"""

from __future__ import annotations

import json
import logging
import math
import subprocess
import sys

import numpy as np
import pytest

import jointtrack.trackers.base as tracker_base
import jointtrack.trackers.initiation as initiation
from jointtrack.scenarios import many_targets
from jointtrack.trackers import JPDATracker, TrackerConfig

_CHILD = """
import json, resource, sys
limit = 2 * 2**30
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
import numpy as np
from jointtrack.trackers import JPDATracker, TrackerConfig
rng = np.random.default_rng(0)
trk = JPDATracker(TrackerConfig(clutter_density=1e-6, initiation="two-point"))
tracks = []
for k in range(3):  # consecutive scans: two-point initiation pairs some returns
    trk.step(float(k), rng.uniform(0.0, 1e5, (20_000, 2)))
    tracks.append(len(trk.ids))
print(json.dumps({"tracks": tracks,
                  "rss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024}))
"""


def test_20000_detection_scan_completes_under_2gib_address_space():
    proc = subprocess.run(
        [sys.executable, "-c", _CHILD], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["tracks"][0] == 0 and out["tracks"][1] > 0  # scan 2 paired with scan 1
    assert out["rss"] < 2 * 2**30


def _constant_density_counts(n, n_scans=12, skip=5):
    """Gating candidates per track and initiation candidates per new return, scans ≥ skip."""
    side = 10_000.0 * math.sqrt(n / 100.0)
    sc = many_targets(n, 0.5 * n, seed=0, n_scans=n_scans, region=((0, side), (0, side)))
    speeds = [np.hypot(*s[:, 2:4].T).max() for s in sc.truth_states if len(s)]
    cfg = TrackerConfig(
        process_noise=max(sc.process_noise, 0.05),
        measurement_noise=float(sc.R[0, 0]),
        p_d=sc.p_d,
        clutter_density=sc.clutter_density,
        max_speed=1.5 * max(speeds),
        initiation="two-point",  # the candidate pairing measured below
    )
    gate_log, init_log = [], []
    scan = [0]
    real_gate, real_cand = tracker_base.gate_pairs, initiation._candidates

    def gate(*args, **kw):
        g = real_gate(*args, **kw)
        gate_log.append((scan[0], g.n_tracks, g.n_candidates, len(g.rows)))
        return g

    def cand(pos, *args, **kw):
        out = real_cand(pos, *args, **kw)
        init_log.append((scan[0], len(pos), len(out[0])))
        return out

    trk = JPDATracker(cfg)
    logging.disable(logging.WARNING)
    try:
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(tracker_base, "gate_pairs", gate)
            mp.setattr(initiation, "_candidates", cand)
            for k, (t, z) in enumerate(zip(sc.times, sc.detections, strict=True)):
                scan[0] = k
                trk.step(t, z)
    finally:
        logging.disable(logging.NOTSET)
    g = np.array([row for row in gate_log if row[0] >= skip])
    i = np.array([row for row in init_log if row[0] >= skip])
    return dict(
        tracks=int(g[:, 1].sum()),
        candidates_per_track=g[:, 2].sum() / g[:, 1].sum(),
        gated_per_track=g[:, 3].sum() / g[:, 1].sum(),
        init_candidates_per_return=i[:, 2].sum() / max(i[:, 1].sum(), 1),
    )


@pytest.fixture(scope="module")
def counts_300_3000():
    return _constant_density_counts(300), _constant_density_counts(3000)


@pytest.mark.parametrize(
    "key", ["candidates_per_track", "gated_per_track", "init_candidates_per_return"]
)
def test_work_per_track_does_not_grow_with_n_at_constant_density(key, counts_300_3000):
    small, large = counts_300_3000
    assert large["tracks"] > 5 * small["tracks"]  # the big scene really has ~10× the tracks
    assert small[key] > 0
    ratio = large[key] / small[key]
    assert 1 / 3 <= ratio <= 3, (key, small, large)
