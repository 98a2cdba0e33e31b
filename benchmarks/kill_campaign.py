"""Kill campaign: `jointtrack run` killed (SIGKILL) at random wall-clock instants over
whole runs, resumed with `--resume CHECKPOINT` alone, compared with the uninterrupted run.

Cases: built-in scenarios (JIPDA, PMBM; CSV and Parquet), detection files (JIPDA,
PMBM), an AIS report file (the synthetic one of tests/test_run_realdata.py, and the
real Solent file with ``--solent PATH``; CSV and Parquet). For each case the
uninterrupted run is timed first (its second run: the first may compile kernels), in this
same campaign (on this machine at this load):
T, the seconds from its first write (its output directory prepared, after loading the
modules and reading the inputs, which write nothing) to its end. Each kill then starts
the run with ``--checkpoint`` in a fresh directory, sends SIGKILL a delay drawn
uniformly from [0, 1.05 T] (seeded) after its first write — anywhere in the kernel
loading, the tracking, the finishing phase, or past the end — and resumes it
(``--resume`` alone; a run killed before its first checkpoint is started again). Every
resume must end with every output of the uninterrupted run: the tracks file and the
PNGs byte for byte, metrics.json equal but for its wall-clock fields
(``tests/test_run_finish.py`` WALL_CLOCK) and, after a kill while tracking,
``n_scans_this_run``; nothing else in the output directory (no parts, no temporary
files). Prints one line per kill (where it landed: before the first checkpoint,
tracking, finishing — with the outputs done —, done, or after the run ended), a line
per case and the count; exits 1 if any resume differs.

    PYTHONPATH=src python benchmarks/kill_campaign.py --kills 6 [--solent SolentAIS.csv]

The Solent file: ``pip download --no-deps --no-binary :all: stonesoup==1.9.1`` holds it
in ``docs/demos/`` (not committed here).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from jointtrack.trackers.state_io import read_run  # noqa: E402
from test_run_finish import _files, _without_wall_clock, _write_detections, supervise  # noqa: E402
from test_run_realdata import write_ais  # noqa: E402

SCENARIO = '[scenario]\nname = "{name}"\nseed = {seed}\n{extra}'


def cases(data: Path, solent: Path | None) -> dict:
    """name → (CLI arguments without --out/--checkpoint, scans between checkpoints)."""
    (data / "crossing.toml").write_text(
        SCENARIO.format(name="crossing", seed=4, extra="n_scans = 60\nclutter_per_scan = 6.0\n")
    )
    # tentative tracks as track-splitting mixtures: their components are state arrays too
    (data / "splitting.toml").write_text(
        SCENARIO.format(name="bojilov", seed=3, extra='start_from = "nothing"\nn_scans = 50\n')
        + '[tracker]\ntentative_association = "splitting"\n'
    )
    (data / "coalescence.toml").write_text(SCENARIO.format(name="coalescence", seed=2, extra=""))
    _write_detections(data / "det.csv")
    write_ais(data / "ais.csv")
    out = {
        "crossing jipda csv": (["--config", data / "crossing.toml"], 7),
        "crossing jipda parquet": (["--config", data / "crossing.toml", "--format", "parquet"], 7),
        "bojilov jipda splitting csv": (["--config", data / "splitting.toml"], 3),
        "coalescence pmbm csv": (
            [
                "--scenario",
                "coalescence",
                "--config",
                data / "coalescence.toml",
                "--tracker",
                "pmbm",
            ],
            5,
        ),
        "detections pmbm parquet": (
            ["--detections", data / "det.csv", "--tracker", "pmbm", "--format", "parquet"],
            3,
        ),
        "detections jipda csv": (["--detections", data / "det.csv"], 3),
        "AIS (synthetic) csv": (["--detections", data / "ais.csv"], 40),
        "AIS (synthetic) parquet": (["--detections", data / "ais.csv", "--format", "parquet"], 40),
    }
    if solent is not None:
        shutil.copy(solent, data / solent.name)
        out["AIS Solent csv"] = (["--detections", data / solent.name], 500)
    return out


def landing(cwd: Path, killed: bool) -> str:
    """Where a kill fell, from what it left."""
    if not killed:
        return "after the end"
    ck = cwd / "ck.npz"
    if not ck.exists():
        return "before the first checkpoint"
    info = read_run(ck)
    phase = info.get("phase", "tracking")
    if phase == "finishing":
        return f"finishing ({len(info['outputs_done'])}/{len(info['outputs'])} outputs)"
    if phase == "tracking":
        return f"tracking (checkpoint at scan {info['n_scans']})"
    return phase


def same_outputs(out: Path, want: dict, tracking_killed: bool) -> str | None:
    """None when ``out`` holds the uninterrupted run's outputs, else what differs."""
    got = _files(out)
    if sorted(got) != sorted(want):
        return f"files {sorted(got)} instead of {sorted(want)}"
    for name, data in want.items():
        if name == "metrics.json":
            a = _without_wall_clock(json.loads(got[name]), tracking_killed)
            b = _without_wall_clock(json.loads(data), tracking_killed)
            if a != b:
                return "metrics.json: " + ", ".join(k for k in b if a.get(k) != b[k])
        elif got[name] != data:
            return f"{name} differs"
    return None


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--kills", type=int, default=8, help="kills per case (8)")
    parser.add_argument("--seed", type=int, default=31)
    parser.add_argument("--solent", type=Path, help="Stone Soup's SolentAIS_20160112_130211.csv")
    parser.add_argument("--case", action="append", help="only cases whose name holds this")
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    work = Path(tempfile.mkdtemp(prefix="kill-campaign-"))
    data = work / "data"
    data.mkdir()
    total = failed = 0
    by_landing: dict = {}
    try:
        for name, (case_args, every) in cases(data, args.solent).items():
            if args.case and not any(c in name for c in args.case):
                continue
            slug = "".join(c if c.isalnum() else "-" for c in name)
            ref = work / f"{slug}-ref"
            ref.mkdir()
            base = ["run", "--no-progress", *case_args, "--out", "out"]
            # timed on its second run: a first run after a change compiles its kernels
            # (minutes), and delays drawn from that time would all fall past the end
            supervise(base, ref)
            shutil.rmtree(ref / "out")
            started, ended, _ = supervise(base, ref)
            seconds = ended - started
            want = _files(ref / "out")
            print(
                f"{name}: uninterrupted {ended:.1f} s, {seconds:.1f} s from its first write; "
                f"outputs {', '.join(sorted(want))}"
            )
            ok = 0
            for k in range(args.kills):
                cwd = work / f"{slug}-{k}"
                cwd.mkdir()
                first = [*base, "--checkpoint", "ck.npz", "--checkpoint-every", every]
                delay = float(rng.uniform(0.0, 1.05 * seconds))
                _, _, killed = supervise(
                    first, cwd, lambda t, s, d=delay: s is not None and t >= s + d
                )
                where = landing(cwd, killed)
                ck = cwd / "ck.npz"
                tracking = not ck.exists() or read_run(ck).get("phase", "tracking") == "tracking"
                again = ["run", "--resume", "ck.npz"] if ck.exists() else first
                try:
                    _, resumed, _ = supervise(again, cwd)
                    problem = same_outputs(cwd / "out", want, tracking)
                except AssertionError as exc:  # the resume failed: its error line
                    lines = [ln for ln in str(exc).splitlines() if "error" in ln] or [str(exc)]
                    resumed, problem = float("nan"), "resume failed: " + lines[0].strip()
                total += 1
                by_landing[where.split(" (")[0]] = by_landing.get(where.split(" (")[0], 0) + 1
                if problem is None:
                    ok += 1
                else:
                    failed += 1
                print(
                    f"  kill {k + 1}: {delay:6.2f} s after its first write, {where}; "
                    f"resumed in {resumed:.1f} s: "
                    + ("identical" if problem is None else f"DIFFERS: {problem}"),
                    flush=True,
                )
                shutil.rmtree(cwd)
            print(f"{name}: {ok}/{args.kills} resumes identical to the uninterrupted run")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print(f"kills by where they fell: {by_landing}")
    print(f"total: {total - failed}/{total} killed runs resumed to the uninterrupted outputs")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
