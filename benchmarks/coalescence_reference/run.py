"""Reference PMBM / PMB (García-Fernández et al.'s MATLAB code) on jointtrack's detections.

Benchmark harness for issue 23: the authors' public PMBM filter and its PMB
variant (GitHub ``Agarciafernandez/MTT``, folder "PMBM filter") run under GNU
Octave on detections *we* write, and their estimates are scored by *our*
GOSPA (:func:`jointtrack.metrics.gospa`, c = 10, p = 2, α = 2) on the same
detections as jointtrack's trackers. The third-party code is never imported
by jointtrack: it lives outside the repository (``setup.sh`` extracts and
builds it) and is only run here, in a subprocess.

References
----------
Á. F. García-Fernández, J. L. Williams, K. Granström and L. Svensson,
"Poisson multi-Bernoulli mixture filter: direct derivation and
implementation", IEEE Trans. Aerospace and Electronic Systems 54(4),
1883–1901, 2018 (the PMBM filter and the coalescence scenario, Section VI).
A. S. Rahmathullah, Á. F. García-Fernández and L. Svensson, "Generalized
optimal sub-pattern assignment metric", 20th Int. Conf. on Information
Fusion, 2017 (GOSPA).

Subcommands (paths of the third-party code come from ``--mtt-dir`` /
``--mex-dir`` or the environment variables ``JT_MTT_DIR`` / ``JT_KBEST_MEX_DIR``
that ``setup.sh`` prints)::

    # detections of jointtrack.scenarios.coalescence(seed) for seeds 0..99
    python run.py detections --seeds 0-99 --data WORK/ours
    # their filters on them (Octave; --jobs parallel processes)
    python run.py reference --data WORK/ours --out WORK/ours_out --filters pmbm,pmb --runs 0-99
    # score with jointtrack's GOSPA; summary JSON (+ full per-run JSON)
    python run.py score --data WORK/ours --out WORK/ours_out --filters pmbm,pmb --runs 0-99 \
        --json results.json --full-json WORK/ours_full.json

File formats: ``run_NNNN.csv`` (``step,x,y``, steps 1..K), truth in
``truth_NNNN.csv`` or one shared ``truth.csv`` (``step,id,x,y,vx,vy``),
estimates ``<filter>_run_NNNN.csv`` (``step,x,y,vx,vy``) and CPU times
``<filter>_run_NNNN_cpu.csv`` (``step,cpu_seconds``).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import math
import os
import shlex
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
FILTERS = ("pmbm", "pmb")
C_GOSPA, P_GOSPA, ALPHA_GOSPA = 10.0, 2.0, 2.0


def parse_runs(text: str) -> list[int]:
    """``"0-99"``, ``"1,3,5-7"`` → sorted list of distinct non-negative ints."""
    runs: set[int] = set()
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        try:
            if "-" in part:
                lo, hi = (int(v) for v in part.split("-", 1))
                if hi < lo:
                    raise ValueError
                runs.update(range(lo, hi + 1))
            else:
                runs.add(int(part))
        except ValueError:
            raise ValueError(
                f"runs: bad range {part!r} in {text!r} (use e.g. 0-99 or 1,3,5-7)"
            ) from None
    if not runs or min(runs) < 0:
        raise ValueError(f"runs: {text!r} gives no non-negative run numbers")
    return sorted(runs)


def _read_csv(path: Path, header: str, ncol: int) -> np.ndarray:
    with open(path) as fh:
        first = fh.readline().strip()
        if first != header:
            raise ValueError(f"{path}: header {first!r}, expected {header!r}")
        rows = [line for line in fh if line.strip()]
    if not rows:
        return np.zeros((0, ncol))
    arr = np.loadtxt(rows, delimiter=",", ndmin=2)
    if arr.shape[1] != ncol:
        raise ValueError(f"{path}: {arr.shape[1]} columns, expected {ncol}")
    return arr


def _write_csv(path: Path, header: str, rows: np.ndarray, fmt: str) -> None:
    with open(path, "w") as fh:
        fh.write(header + "\n")
        for r in rows:
            fh.write(fmt % tuple(r) + "\n")


# --------------------------------------------------------------------------- detections
def cmd_detections(args) -> None:
    """Write jointtrack.scenarios.coalescence(seed) detections and truth as CSV."""
    from jointtrack.scenarios import coalescence

    data = Path(args.data)
    data.mkdir(parents=True, exist_ok=True)
    n_steps = None
    for seed in parse_runs(args.seeds):
        sc = coalescence(seed=seed)
        if n_steps is None:
            n_steps = sc.n_scans
        elif sc.n_scans != n_steps:
            raise ValueError(f"seed {seed}: {sc.n_scans} scans, other seeds have {n_steps}")
        det = [
            (k + 1, float(z[0]), float(z[1]))
            for k, Z in enumerate(sc.detections)
            for z in np.asarray(Z, dtype=float).reshape(-1, 2)
        ]
        _write_csv(data / f"run_{seed:04d}.csv", "step,x,y", det, "%d,%.17g,%.17g")
        truth = [
            (k + 1, int(i), *(float(v) for v in s[:4]))
            for k, (ids, S) in enumerate(zip(sc.truth_ids, sc.truth_states, strict=True))
            for i, s in zip(ids, np.asarray(S, dtype=float).reshape(len(ids), -1), strict=True)
        ]
        _write_csv(
            data / f"truth_{seed:04d}.csv",
            "step,id,x,y,vx,vy",
            truth,
            "%d,%d,%.17g,%.17g,%.17g,%.17g",
        )
    (data / "n_steps.txt").write_text(f"{n_steps}\n")
    print(f"wrote {len(parse_runs(args.seeds))} runs ({n_steps} scans) to {data}")


# --------------------------------------------------------------------------- reference
def _third_party_dirs(args) -> tuple[str, str]:
    mtt = args.mtt_dir or os.environ.get("JT_MTT_DIR")
    mex = args.mex_dir or os.environ.get("JT_KBEST_MEX_DIR")
    if not mtt or not (Path(mtt) / "PMBM filter").is_dir():
        raise SystemExit(
            f"--mtt-dir / JT_MTT_DIR: {mtt!r} has no 'PMBM filter' folder (run setup.sh)"
        )
    if not mex or not list(Path(mex).glob("kBest2DAssign.mex*")):
        raise SystemExit(
            f"--mex-dir / JT_KBEST_MEX_DIR: {mex!r} has no kBest2DAssign.mex (run setup.sh)"
        )
    return mtt, mex


def _n_steps(data: Path, given: int | None) -> int:
    if given is not None:
        return given
    f = data / "n_steps.txt"
    if not f.exists():
        raise SystemExit(f"--steps not given and {f} missing")
    return int(f.read_text())


def _octave_str(s: str) -> str:
    return "'" + str(s).replace("'", "''") + "'"


def cmd_reference(args) -> None:
    """Run run_reference.m over the runs, split into --jobs Octave processes."""
    mtt, mex = _third_party_dirs(args)
    data, out = Path(args.data), Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    n_steps = _n_steps(data, args.steps)
    runs = parse_runs(args.runs)
    filters = [f.strip() for f in args.filters.split(",")]
    for f in filters:
        if f not in FILTERS:
            raise SystemExit(f"--filters: unknown filter {f!r} (choose from {FILTERS})")
    todo = [
        (f, r)
        for f in filters
        for r in runs
        if args.force or not (out / f"{f}_run_{r:04d}_cpu.csv").exists()
    ]

    def one(job):
        f, r = job
        call = (
            f"run_reference({_octave_str(mtt)}, {_octave_str(mex)}, {_octave_str(data)}, "
            f"{_octave_str(out)}, {_octave_str(f)}, {r}, {n_steps})"
        )
        cmd = ["octave-cli", "--no-window-system", "--eval", call]
        proc = subprocess.run(cmd, cwd=HERE, capture_output=True, text=True)
        ok = (out / f"{f}_run_{r:04d}_cpu.csv").exists()
        msg = proc.stdout.strip().splitlines()[-1:] if ok else proc.stderr.strip().splitlines()[:5]
        status = "ok" if ok else "FAILED"
        print(f"[{time.strftime('%H:%M:%S')}] {f} run {r}: {status} {' | '.join(msg)}", flush=True)
        return ok

    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        results = list(pool.map(one, todo))
    if not all(results):
        raise SystemExit(f"{results.count(False)} reference runs failed")


# --------------------------------------------------------------------------- score
def _by_step(arr: np.ndarray, n_steps: int, cols: slice) -> list[np.ndarray]:
    steps = arr[:, 0].astype(int) if arr.size else np.zeros(0, dtype=int)
    if steps.size and (steps.min() < 1 or steps.max() > n_steps):
        raise ValueError(f"steps outside 1..{n_steps}")
    return [arr[steps == k, cols] for k in range(1, n_steps + 1)]


def score_run(data: Path, out: Path, filt: str, run: int, n_steps: int) -> dict:
    """Per-step GOSPA (jointtrack.metrics.gospa) of one reference run, with its parts and CPU."""
    from jointtrack.metrics import gospa

    truth_file = data / f"truth_{run:04d}.csv"
    if not truth_file.exists():
        truth_file = data / "truth.csv"
    truth = _by_step(_read_csv(truth_file, "step,id,x,y,vx,vy", 6), n_steps, slice(2, 4))
    est_rows = _read_csv(out / f"{filt}_run_{run:04d}.csv", "step,x,y,vx,vy", 5)
    est = _by_step(est_rows, n_steps, slice(1, 3))
    cpu = _read_csv(out / f"{filt}_run_{run:04d}_cpu.csv", "step,cpu_seconds", 2)
    if cpu.shape[0] != n_steps or not np.array_equal(cpu[:, 0], np.arange(1, n_steps + 1)):
        raise ValueError(f"{filt} run {run}: CPU file does not list steps 1..{n_steps}")
    res = {k: [] for k in ("gospa", "localisation", "missed", "false", "n_truth", "n_est")}
    for X, Y in zip(truth, est, strict=True):
        g = gospa(X, Y, c=C_GOSPA, p=P_GOSPA, alpha=ALPHA_GOSPA)
        res["gospa"].append(float(g.total))
        res["localisation"].append(float(g.localisation))
        res["missed"].append(float(g.missed))
        res["false"].append(float(g.false))
        res["n_truth"].append(int(X.shape[0]))
        res["n_est"].append(int(Y.shape[0]))
    res["cpu_seconds"] = [float(v) for v in cpu[:, 1]]
    return res


def _mean_se(v) -> tuple[float, float]:
    v = np.asarray(v, dtype=float)
    se = float(v.std(ddof=1) / math.sqrt(v.size)) if v.size > 1 else float("nan")
    return float(v.mean()), se


def summarise(per_run: dict[int, dict]) -> dict:
    """Monte Carlo summary of one filter's runs."""
    runs = sorted(per_run)
    G = np.array([per_run[r]["gospa"] for r in runs])  # (n_runs, K)
    parts = {
        p: np.array([per_run[r][p] for r in runs]) for p in ("localisation", "missed", "false")
    }
    cpu = np.array([per_run[r]["cpu_seconds"] for r in runs])
    mean, se = _mean_se(G.mean(axis=1))
    out = {
        "n_runs": len(runs),
        "runs": runs,
        "mean_gospa": mean,
        "mean_gospa_se": se,
        # Their demo scripts print this: sqrt of the mean squared GOSPA over runs and steps.
        "rms_gospa": float(math.sqrt((G**2).mean())),
        "parts_mean_squared": {p: float(a.mean()) for p, a in parts.items()},
        "parts_rms": {p: float(math.sqrt(a.mean())) for p, a in parts.items()},
        "mean_n_est_minus_n_truth": float(
            np.mean([np.subtract(per_run[r]["n_est"], per_run[r]["n_truth"]).mean() for r in runs])
        ),
        "per_step_mean_gospa": [round(float(v), 6) for v in G.mean(axis=0)],
        "per_step_rms_gospa": [round(float(v), 6) for v in np.sqrt((G**2).mean(axis=0))],
        "per_step_mean_parts": {
            p: [round(float(v), 6) for v in a.mean(axis=0)] for p, a in parts.items()
        },
        "cpu_seconds_per_step_mean": float(cpu.mean()),
        "cpu_seconds_per_run_mean": float(cpu.sum(axis=1).mean()),
        "per_step_mean_cpu_seconds": [round(float(v), 6) for v in cpu.mean(axis=0)],
    }
    return out


def cmd_score(args) -> None:
    data, out = Path(args.data), Path(args.out)
    n_steps = _n_steps(data, args.steps)
    runs = parse_runs(args.runs)
    filters = [f.strip() for f in args.filters.split(",")]
    full, summary = {}, {}
    for f in filters:
        done = [r for r in runs if (out / f"{f}_run_{r:04d}_cpu.csv").exists()]
        if not done:
            print(f"{f}: no finished runs in {out}", file=sys.stderr)
            continue
        per_run = {r: score_run(data, out, f, r, n_steps) for r in done}
        full[f] = {str(r): v for r, v in per_run.items()}
        summary[f] = summarise(per_run)
        s = summary[f]
        sq = s["parts_mean_squared"]
        print(
            f"{f}: {s['n_runs']} runs  mean GOSPA {s['mean_gospa']:.4f} "
            f"± {s['mean_gospa_se']:.4f} (SE)  RMS GOSPA {s['rms_gospa']:.4f}  "
            f"parts (mean sq.) loc {sq['localisation']:.3f} missed {sq['missed']:.3f} "
            f"false {sq['false']:.3f}  CPU {s['cpu_seconds_per_run_mean']:.1f} s/run"
        )
    meta = {
        "command": " ".join(shlex.quote(a) for a in sys.argv),
        "date_utc": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "data": str(data),
        "source": args.source,
        "gospa": {
            "c": C_GOSPA,
            "p": P_GOSPA,
            "alpha": ALPHA_GOSPA,
            "implementation": "jointtrack.metrics.gospa",
        },
        "n_steps": n_steps,
        "notes": args.note or [],
    }
    if args.json:
        Path(args.json).write_text(json.dumps({**meta, "filters": summary}, indent=1) + "\n")
    if args.full_json:
        Path(args.full_json).write_text(json.dumps({**meta, "per_run": full}) + "\n")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)

    d = sub.add_parser("detections", help="write jointtrack coalescence detections/truth as CSV")
    d.add_argument("--seeds", default="0-99")
    d.add_argument("--data", required=True)
    d.set_defaults(fn=cmd_detections)

    r = sub.add_parser("reference", help="run their PMBM/PMB under Octave")
    r.add_argument("--data", required=True)
    r.add_argument("--out", required=True)
    r.add_argument("--filters", default="pmbm,pmb")
    r.add_argument("--runs", required=True)
    r.add_argument("--steps", type=int, default=None)
    r.add_argument("--jobs", type=int, default=1)
    r.add_argument("--force", action="store_true", help="rerun runs that already have output")
    r.add_argument("--mtt-dir", default=None)
    r.add_argument("--mex-dir", default=None)
    r.set_defaults(fn=cmd_reference)

    s = sub.add_parser("score", help="score reference estimates with jointtrack GOSPA")
    s.add_argument("--data", required=True)
    s.add_argument("--out", required=True)
    s.add_argument("--filters", default="pmbm,pmb")
    s.add_argument("--runs", required=True)
    s.add_argument("--steps", type=int, default=None)
    s.add_argument("--source", default="jointtrack.scenarios.coalescence")
    s.add_argument("--note", action="append")
    s.add_argument("--json", default=None)
    s.add_argument("--full-json", default=None)
    s.set_defaults(fn=cmd_score)

    args = ap.parse_args(argv)
    try:
        args.fn(args)
    except ValueError as exc:
        raise SystemExit(f"error: {exc}") from None


if __name__ == "__main__":
    main()
