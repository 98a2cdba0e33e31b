"""CV JIPDA against the IMM JIPDA (``motion = "imm"``) on targets in 5°/s turns (issue 32).

The workload: ``--targets`` targets at 30 m/s on a 20 km square, each flying
straight for a random 5–15 s and then a coordinated turn at ±5°/s (random
direction) to the end of the run; P_D 0.9, σ = 10 m, ``--clutter`` returns per
scan uniformly over the square, one scan per second. Each tracker kind — CV,
IMM ``("cv", "ct")``, IMM ``("cv", "ct", "ca")`` — runs the same scans,
interleaved over ``--repeats`` rounds (CPU time of the ``step`` calls, median).

Printed per kind: milliseconds per scan (and the ratio to CV), track ids per
target (each confirmed estimate is assigned to the nearest target within 100 m;
1.0 = every target held by one id from its first confirmation to the end),
the fraction of (target, scan) pairs with an estimate within 100 m, and the
position RMSE of those estimates.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from jointtrack.trackers import JPDATracker, TrackerConfig

SPEED, TURN_DEG, SIGMA, HALF = 30.0, 5.0, 10.0, 10_000.0


def scenario(n_targets: int, n_scans: int, clutter: float, seed: int):
    """(truth (T, K, 2), scans [(t, z)])."""
    rng = np.random.default_rng(seed)
    start = rng.uniform(-0.6 * HALF, 0.6 * HALF, (n_targets, 2))
    heading = rng.uniform(0, 2 * np.pi, n_targets)
    straight = rng.uniform(5, 15, n_targets)
    w = np.deg2rad(TURN_DEG) * rng.choice([-1.0, 1.0], n_targets)
    truth = np.zeros((n_scans, n_targets, 2))
    for k in range(n_scans):
        t = float(k)
        s = np.minimum(t, straight)
        u = np.maximum(t - straight, 0.0)
        d = np.stack([np.cos(heading), np.sin(heading)], -1)
        p = start + SPEED * s[:, None] * d
        # a turn of rate w from heading h: displacement (sin(h+wu) − sin h, cos h − cos(h+wu)) v/w
        h1 = heading + w * u
        p = p + (SPEED / w)[:, None] * np.stack(
            [np.sin(h1) - np.sin(heading), np.cos(heading) - np.cos(h1)], -1
        )
        truth[k] = p
    scans = []
    for k in range(n_scans):
        seen = rng.random(n_targets) < 0.9
        z = truth[k][seen] + rng.normal(size=(int(seen.sum()), 2)) * SIGMA
        junk = rng.uniform(-HALF, HALF, (rng.poisson(clutter), 2))
        scans.append((float(k), np.vstack([z, junk])))
    return truth, scans


def run(kind: str, scans, clutter: float):
    modes = {"cv": None, "imm2": ("cv", "ct"), "imm3": ("cv", "ct", "ca")}[kind]
    kw = {} if modes is None else {"motion": "imm", "imm_modes": modes}
    cfg = TrackerConfig(
        measurement_noise=SIGMA**2,
        process_noise=0.5,
        clutter_density=clutter / (2 * HALF) ** 2,
        **kw,
    )
    trk = JPDATracker(cfg)
    cpu = 0.0
    for t, z in scans:
        t0 = time.process_time()
        trk.step(t, z)
        cpu += time.process_time() - t0
    return cpu / len(scans), trk.history()


def quality(truth, hist, radius=100.0):
    """(ids per target, coverage, RMSE) of a history against the truth."""
    n_scans, n_targets, _ = truth.shape
    ids = [set() for _ in range(n_targets)]
    covered = np.zeros((n_scans, n_targets), bool)
    err2 = []
    for k in range(n_scans):
        rows = np.flatnonzero(hist.time == float(k))
        if not len(rows):
            continue
        d = np.linalg.norm(hist.x[rows, None, :2] - truth[k][None], axis=-1)
        j = d.argmin(axis=1)
        for r, jj, dd in zip(rows, j, d[np.arange(len(rows)), j], strict=True):
            if dd < radius:
                ids[jj].add(int(hist.track_id[r]))
                if not covered[k, jj]:
                    covered[k, jj] = True
                    err2.append(dd**2)
    held = [len(s) for s in ids if s]
    return (
        float(np.mean(held)) if held else float("nan"),
        covered.mean(),
        float(np.sqrt(np.mean(err2))) if err2 else float("nan"),
    )


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--targets", type=int, default=10)
    ap.add_argument("--scans", type=int, default=60)
    ap.add_argument("--clutter", type=float, default=20.0)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    truth, scans = scenario(args.targets, args.scans, args.clutter, args.seed)
    kinds = ("cv", "imm2", "imm3")
    times = {k: [] for k in kinds}
    hists = {}
    for _ in range(args.repeats):
        for k in kinds:  # interleaved: the machine's load falls on every kind alike
            per_scan, hists[k] = run(k, scans, args.clutter)
            times[k].append(per_scan)
    base = statistics.median(times["cv"])
    print(
        f"{args.targets} targets in 5°/s turns, {args.scans} scans, {args.clutter:g} clutter/scan, "
        f"median of {args.repeats} interleaved rounds (CPU)"
    )
    print(f"{'kind':6} {'ms/scan':>8} {'× CV':>6} {'ids/target':>10} {'coverage':>8} {'RMSE m':>7}")
    for k in kinds:
        med = statistics.median(times[k])
        ids, cov, rmse = quality(truth, hists[k])
        print(f"{k:6} {1e3 * med:8.2f} {med / base:6.2f} {ids:10.2f} {cov:8.3f} {rmse:7.1f}")


if __name__ == "__main__":
    main()
