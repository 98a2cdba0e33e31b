"""Issue 34 items 4–5: every speed figure quiet and beside busy processes, old code against new.

Figures (each measured in a child interpreter, so that the old and the new code
run the same way):

* ``snippet``: the README's Stone Soup JPDA snippet (20 scans, 2 crossing
  targets, seed 1991), milliseconds per ``associate`` call (wall and CPU of the
  whole process, i.e. every thread), median over repeats, for Stone Soup's
  ``PDAHypothesiser`` + ``JPDAwithEHM2`` (the peer), ``PDAHypothesiser`` +
  ``JPDAExact`` and ``FastPDAHypothesiser`` + ``JPDAExact``.
* ``coalescence``: PMBM and PMB steps/s on the coalescence scene (seed 0), built
  as ``jointtrack run --scenario coalescence --tracker pmbm|pmb`` builds them.
* ``many``: JIPDA and PMB scans/s on the ``many`` scene (100 targets, 50 clutter
  per scan, seed 0), built as ``jointtrack run --scenario many --tracker jipda|pmb``.

Every figure is run for the code at ``--old`` (a worktree of the base commit,
e.g. ``git worktree add /tmp/orig-load 831ecfa``) and the code of this checkout,
alternated (old, new, old, new, …; ``--rounds``), first on a quiet machine and
then beside ``--busy`` processes ``python -c "while True: pass"`` started here
and killed after. ``uptime`` is printed before and after each phase. Printed: the
median of each figure per code and phase, the ratios new/old and busy/quiet, and
the GOSPA of every tracker run (equal old and new: the change must not alter
results).

Run: ``python benchmarks/load.py --old /tmp/orig-load/src [--rounds 3] [--busy 3]``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
NEW_SRC = HERE.parent / "src"
SNIPPET_CONFIGS = ("pda+ehm2", "pda+exact", "fast+exact")


# ------------------------------------------------------------------- child side
def _snippet_setup():
    """The README snippet's scene (the same seed, the same draws) and its models."""
    from datetime import datetime, timedelta

    import numpy as np
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.transition.linear import (
        CombinedLinearGaussianTransitionModel,
        ConstantVelocity,
    )
    from stonesoup.types.detection import Clutter, TrueDetection
    from stonesoup.types.groundtruth import GroundTruthPath, GroundTruthState

    # the README's legacy global generator, so that the scene is the README's
    np.random.seed(1991)  # noqa: NPY002
    start_time = datetime(2025, 1, 1)
    transition_model = CombinedLinearGaussianTransitionModel([ConstantVelocity(0.005)] * 2)
    measurement_model = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.eye(2) * 0.75)
    truths = set()
    for y0, vy in ((0, 1), (20, -1)):
        truth = GroundTruthPath([GroundTruthState([0, 1, y0, vy], timestamp=start_time)])
        for k in range(1, 21):
            truth.append(
                GroundTruthState(
                    transition_model.function(
                        truth[k - 1], noise=True, time_interval=timedelta(seconds=1)
                    ),
                    timestamp=start_time + timedelta(seconds=k),
                )
            )
        truths.add(truth)
    scans = []
    for k in range(20):
        measurement_set = set()
        for truth in truths:
            if np.random.rand() <= 0.9:  # noqa: NPY002
                z = measurement_model.function(truth[k], noise=True)
                measurement_set.add(
                    TrueDetection(z, groundtruth_path=truth, timestamp=truth[k].timestamp)
                )
            x, y = truth[k].state_vector[0], truth[k].state_vector[2]
            for _ in range(np.random.randint(10)):  # noqa: NPY002
                x_c = np.random.uniform(x - 10, x + 10)  # noqa: NPY002
                y_c = np.random.uniform(y - 10, y + 10)  # noqa: NPY002
                clutter = np.array([[x_c], [y_c]])
                measurement_set.add(Clutter(clutter, timestamp=truth[k].timestamp))
        scans.append(measurement_set)
    return start_time, transition_model, measurement_model, scans


def _snippet_run(setup, config: str) -> tuple[float, float, list]:
    """One pass of the snippet: (wall s, CPU s) summed over the ``associate`` calls, and
    the final track means (to check that every configuration tracks alike)."""
    from datetime import timedelta

    import numpy as np
    from stonesoup.dataassociator.probability import JPDAwithEHM2
    from stonesoup.functions import gm_reduce_single
    from stonesoup.hypothesiser.probability import PDAHypothesiser
    from stonesoup.predictor.kalman import KalmanPredictor
    from stonesoup.types.array import StateVectors
    from stonesoup.types.state import GaussianState
    from stonesoup.types.track import Track
    from stonesoup.types.update import GaussianStateUpdate
    from stonesoup.updater.kalman import KalmanUpdater

    from jointtrack.interop.stonesoup import FastPDAHypothesiser, JPDAExact

    start_time, transition_model, measurement_model, scans = setup
    predictor = KalmanPredictor(transition_model)
    updater = KalmanUpdater(measurement_model)
    hyp_kind, assoc_kind = config.split("+")
    hyp_cls = FastPDAHypothesiser if hyp_kind == "fast" else PDAHypothesiser
    hypothesiser = hyp_cls(
        predictor=predictor, updater=updater, clutter_spatial_density=0.125, prob_detect=0.9
    )
    associator = (JPDAwithEHM2 if assoc_kind == "ehm2" else JPDAExact)(hypothesiser=hypothesiser)
    cov = np.diag([1.5, 0.5, 1.5, 0.5])
    tracks = [
        Track([GaussianState([[0], [1], [0], [1]], cov, timestamp=start_time)]),
        Track([GaussianState([[0], [1], [20], [-1]], cov, timestamp=start_time)]),
    ]
    wall = cpu = 0.0
    for n, measurements in enumerate(scans):
        t0, c0 = time.perf_counter(), time.process_time()
        hypotheses = associator.associate(
            set(tracks), measurements, start_time + timedelta(seconds=n)
        )
        wall += time.perf_counter() - t0
        cpu += time.process_time() - c0
        for track in tracks:
            track_hypotheses = hypotheses[track]
            states, weights = [], []
            for hypothesis in track_hypotheses:
                states.append(
                    hypothesis.prediction if not hypothesis else updater.update(hypothesis)
                )
                weights.append(hypothesis.probability)
            means = StateVectors([s.state_vector for s in states])
            covars = np.stack([s.covar for s in states], axis=2)
            mean, covar = gm_reduce_single(means, covars, np.asarray(weights))
            track.append(
                GaussianStateUpdate(
                    mean, covar, track_hypotheses, track_hypotheses[0].measurement.timestamp
                )
            )
    return wall, cpu, [np.ravel(t.state_vector).tolist() for t in tracks]


def child_snippet(repeats: int) -> dict:
    setup = _snippet_setup()
    for config in SNIPPET_CONFIGS:  # warm-up: imports, numba kernels, Stone Soup caches
        _snippet_run(setup, config)
    runs = {c: [] for c in SNIPPET_CONFIGS}
    finals = {}
    for _ in range(repeats):
        for config in SNIPPET_CONFIGS:  # interleaved, so a burst of load hits all alike
            wall, cpu, final = _snippet_run(setup, config)
            runs[config].append((wall, cpu))
            finals[config] = final
    calls = len(setup[3])
    out = {}
    for config, r in runs.items():
        out[f"snippet {config} ms/call"] = statistics.median(w for w, _ in r) / calls * 1e3
        out[f"snippet {config} CPU ms/call"] = statistics.median(c for _, c in r) / calls * 1e3
    out["snippet final means"] = finals
    return out


def _tracker(kind: str, sc):
    """The tracker ``jointtrack run --scenario <sc> --tracker <kind>`` builds (from nothing)."""
    from jointtrack.experiments.config import (
        make_pmbm_config,
        make_tracker_config,
        scenario_tracker_settings,
    )
    from jointtrack.experiments.run import start_settings
    from jointtrack.trackers import JPDATracker
    from jointtrack.trackers.pmbm import PMBMTracker, PMBTracker

    _, over = start_settings(None, sc.name, kind, {})
    cfg = make_tracker_config(scenario_tracker_settings(sc), over)
    if kind == "jipda":
        return JPDATracker(cfg, keep_history=False)
    cfg, _ = make_pmbm_config(cfg, {}, None, scenario=sc, region=sc.region, scans=sc.detections)
    return (PMBMTracker if kind == "pmbm" else PMBTracker)(cfg, keep_history=False)


def _timed_run(kind: str, sc, c: float, scans: int | None = None) -> tuple[float, float, float]:
    """(wall s, CPU s) of the ``step`` calls on the first ``scans`` scans (None: all) and
    the mean GOSPA (cut-off c, p = 2)."""
    import numpy as np

    from jointtrack.metrics import gospa

    trk = _tracker(kind, sc)
    wall = cpu = 0.0
    g = []
    scenes = list(zip(sc.times, sc.detections, sc.truth_states, strict=True))[:scans]
    for t, z, truth in scenes:
        t0, c0 = time.perf_counter(), time.process_time()
        res = trk.step(t, z)
        wall += time.perf_counter() - t0
        cpu += time.process_time() - c0
        g.append(gospa(truth[:, : sc.dim], res.x[:, : sc.dim], c=c, p=2, alpha=2).total)
    return wall, cpu, float(np.mean(g))


def child_trackers(scene: str, kinds: list[str], scans: int | None) -> dict:
    import logging

    from jointtrack.experiments.config import make_scenario

    logging.disable(logging.WARNING)
    sc = make_scenario(scene, 0, {})
    out = {}
    for kind in kinds:
        _timed_run(kind, make_scenario(scene, 1, {}), 10.0, 5)  # numba kernels, caches
        wall, cpu, g = _timed_run(kind, sc, 10.0, scans)
        steps = len(sc.times[:scans])
        out[f"{scene} {kind} steps/s"] = steps / wall
        out[f"{scene} {kind} CPU steps/s"] = steps / cpu
        out[f"{scene} {kind} GOSPA"] = g
    return out


def child(args) -> None:
    sys.path.insert(0, args.src)
    out: dict = {"src": args.src}
    if "snippet" in args.figures:
        out |= child_snippet(args.repeats)
    if "coalescence" in args.figures:
        out |= child_trackers("coalescence", ["pmbm", "pmb"], args.scans)
    if "many" in args.figures:
        out |= child_trackers("many", ["jipda", "pmb"], args.scans)
    print("RESULT " + json.dumps(out), flush=True)


# ------------------------------------------------------------------ parent side
def uptime() -> str:
    with open("/proc/loadavg") as fh:
        return "load average " + " ".join(fh.read().split()[:3])


def run_child(src: str, figures: list[str], repeats: int, scans: int | None) -> dict:
    cmd = [sys.executable, __file__, "--child", "--src", src, "--repeats", str(repeats)]
    cmd += ["--figures", *figures] + ([] if scans is None else ["--scans", str(scans)])
    env = dict(os.environ, PYTHONPATH=src)
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=3600)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    if proc.returncode != 0 or not lines:
        raise SystemExit(f"child on {src} failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    return json.loads(lines[-1][len("RESULT ") :])


def phase(label, srcs, figures, rounds, repeats, scans, busy) -> dict:
    procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(busy)]
    try:
        print(f"[{label}] {busy} busy processes; before: {uptime()}", flush=True)
        got = {name: [] for name in srcs}
        for r in range(rounds):
            for name, src in srcs.items():
                got[name].append(run_child(src, figures, repeats, scans))
                print(f"[{label}] round {r + 1} {name} done ({uptime()})", flush=True)
        print(f"[{label}] after: {uptime()}", flush=True)
    finally:
        for p in procs:
            p.kill()
            p.wait()
    return got


def summarise(results: dict) -> dict:
    """Median over rounds of every numeric figure, per phase and code."""
    table = {}
    for ph, by_code in results.items():
        for code, runs in by_code.items():
            for key, value in runs[0].items():
                if isinstance(value, int | float):
                    table.setdefault(key, {})[(ph, code)] = statistics.median(r[key] for r in runs)
    return table


def report(results: dict) -> None:
    table = summarise(results)
    phases = list(results)
    codes = list(next(iter(results.values())))
    head = f"{'figure':42s}" + "".join(f"{ph + ' ' + c:>16s}" for ph in phases for c in codes)
    head += "".join(f"{ph + ' new/old':>16s}" for ph in phases)
    head += "".join(f"{c + ' busy/quiet':>18s}" for c in codes) if len(phases) > 1 else ""
    print(head)
    for key, cells in table.items():
        line = f"{key:42s}" + "".join(f"{cells[(ph, c)]:16.3f}" for ph in phases for c in codes)
        if len(codes) == 2:
            line += "".join(
                f"{cells[(ph, codes[1])] / cells[(ph, codes[0])]:16.3f}" for ph in phases
            )
        if len(phases) == 2:
            line += "".join(f"{cells[(phases[1], c)] / cells[(phases[0], c)]:18.3f}" for c in codes)
        print(line)
    for ph in phases:
        for c in codes:
            cells = table
            peer = cells.get("snippet pda+ehm2 ms/call", {}).get((ph, c))
            ours = cells.get("snippet fast+exact ms/call", {}).get((ph, c))
            if peer and ours:
                print(
                    f"{ph} {c}: FastPDAHypothesiser + JPDAExact / PDAHypothesiser + "
                    f"JPDAwithEHM2 = {ours / peer:.2f}×"
                )
    for c in codes:
        for kind in ("coalescence pmbm", "coalescence pmb", "many pmb", "many jipda"):
            key = f"{kind} steps/s"
            if key in table and len(phases) == 2:
                q, b = table[key][(phases[0], c)], table[key][(phases[1], c)]
                print(f"{c}: {kind} keeps {b / q:.0%} of its quiet rate beside busy processes")
    gospas = {k: v for k, v in table.items() if k.endswith("GOSPA")}
    for key, cells in gospas.items():
        values = set(cells.values())
        print(f"{key}: {'equal in every run' if len(values) == 1 else sorted(values)}")


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--old", help="src directory of the old code (a worktree of the base commit)")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--repeats", type=int, default=5, help="snippet passes per child")
    p.add_argument("--busy", type=int, default=3)
    p.add_argument("--scans", type=int, default=None, help="limit the tracker scenes' scans")
    p.add_argument("--figures", nargs="+", default=["snippet", "coalescence", "many"])
    p.add_argument("--phases", nargs="+", default=["quiet", "busy"])
    p.add_argument("--out", help="write every child's figures as JSON here")
    p.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--src", default=str(NEW_SRC), help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        child(args)
        return
    srcs = {"old": args.old, "new": str(NEW_SRC)} if args.old else {"new": str(NEW_SRC)}
    results = {}
    for ph in args.phases:
        busy = args.busy if ph == "busy" else 0
        results[ph] = phase(ph, srcs, args.figures, args.rounds, args.repeats, args.scans, busy)
    report(results)
    if args.out:
        Path(args.out).write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
