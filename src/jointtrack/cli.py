"""The ``jointtrack`` command line."""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Annotated

import typer
from typer.core import TyperCommand, TyperGroup

from jointtrack import __version__


def _plain_flags(params: list) -> list:
    """``params`` with their flags shown bare in --help (``--quick``, not ``--quick <bool>``).

    Newer typer prints a flag's type as if the flag took a value, yet ``--quick true``
    is refused; an empty metavar leaves the type column of a flag blank.
    """
    for param in params:
        if getattr(param, "is_flag", False) and param.metavar is None:
            param.metavar = ""
    return params


class _Command(TyperCommand):
    """A command whose --help shows its flags as flags (:func:`_plain_flags`)."""

    def get_params(self, ctx):
        return _plain_flags(super().get_params(ctx))


class _Group(TyperGroup):
    """A command group whose --help shows its flags as flags (:func:`_plain_flags`)."""

    def get_params(self, ctx):
        return _plain_flags(super().get_params(ctx))


app = typer.Typer(
    name="jointtrack",
    cls=_Group,
    help="Exact, fast and honest multi-target association.",
    no_args_is_help=True,
    add_completion=False,
)
bench_app = typer.Typer(
    cls=_Group, help="Benchmarks against the peer libraries, timed in the same run."
)
app.add_typer(bench_app, name="bench")
data_app = typer.Typer(cls=_Group, help="Public real data (AIS, ADS-B) for runs and benchmarks.")
app.add_typer(data_app, name="data")


def _version(value: bool) -> None:
    if value:
        typer.echo(f"jointtrack {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(
        False, "--version", callback=_version, is_eager=True, help="Print the version and exit."
    ),
) -> None:
    """jointtrack: JPDA, permanents, identity and superpositional-sensor filters."""


def _run_bench(name: str, quick: bool, out) -> None:
    module = importlib.import_module(f"jointtrack.bench.{name}")
    module.run(quick=quick, out=out)


@bench_app.command("permanent", cls=_Command)
def bench_permanent(
    quick: bool = typer.Option(False, "--quick", help="Smaller sizes; finishes in seconds."),
    out: str = typer.Option(None, "--out", help="Also write the results as JSON to this file."),
) -> None:
    """Permanent engine vs thewalrus: uniform, badly scaled, banded and identity workloads."""
    _run_bench("permanent", quick, out)


@bench_app.command("tracker", cls=_Command)
def bench_tracker(
    quick: bool = typer.Option(False, "--quick", help="Fewer scans and seeds, for a quick check."),
    out: str = typer.Option(None, "--out", help="Also write the results as JSON to this file."),
    part: Annotated[
        list[str] | None,
        typer.Option(
            "--part",
            metavar="PART",
            help="Run only this part (repeatable): many, bojilov, scaling, memory, large.",
        ),
    ] = None,
) -> None:
    """Trackers end to end: many-target scan rate, Bojilov cluster cost vs his Table 3,
    JIPDA/PMB/PMBM scans/s against targets at constant density, memory against scans."""
    from jointtrack.bench.tracker import PARTS, run

    unknown = sorted(set(part or ()) - set(PARTS))
    if unknown:
        raise typer.BadParameter(
            f"unknown part(s) {', '.join(unknown)}; the parts: {', '.join(PARTS)}",
            param_hint="--part",
        )
    run(quick=quick, out=out, parts=part or None)


@bench_app.command("association", cls=_Command)
def bench_association(
    quick: bool = typer.Option(False, "--quick", help="Smaller sizes; finishes in seconds."),
    out: str = typer.Option(None, "--out", help="Also write the results as JSON to this file."),
) -> None:
    """JPDA association engine vs Stone Soup and pyehm on the canonical clusters."""
    _run_bench("association", quick, out)


@bench_app.command("quality", cls=_Command)
def bench_quality(
    quick: bool = typer.Option(False, "--quick", help="Fewer seeds and scans; about a minute."),
    out: str = typer.Option(None, "--out", help="Also write the results as JSON to this file."),
) -> None:
    """Tracking quality from nothing — JIPDA, JPDA, PMB and PMBM beside Stone Soup's tutorial
    JPDA tracker on the same detections: time to confirm, targets held, false tracks, GOSPA
    and its parts per scan (PNG with --out)."""
    _run_bench("quality", quick, out)


@data_app.command("fetch", cls=_Command)
def data_fetch(
    cache: str = typer.Option(
        None,
        "--cache",
        help="Folder for the data (default $JOINTTRACK_DATA or ~/.cache/jointtrack).",
    ),
) -> None:
    """Download (pip download, ~50 MB) and check the public samples: Solent AIS and OpenSky
    states from Stone Soup 1.9.1's source, quickstart and switzerland ADS-B from traffic 2.13;
    prints each file's path (CACHE/extracted/…)."""
    from jointtrack.bench.realdata_data import RealDataError, fetch_realdata

    try:
        paths = fetch_realdata(cache, progress=lambda line: typer.echo(line, err=True))
    except RealDataError as exc:
        _fail(exc, code=1)
    for name, path in paths.items():
        typer.echo(f"{name}: {path}")


@bench_app.command("realdata", cls=_Command)
def bench_realdata(
    quick: bool = typer.Option(
        False, "--quick", help="Solent's first 30 scans; the ADS-B scenes' first 30 minutes."
    ),
    out: str = typer.Option(
        None, "--out", help="Folder for realdata.json, the track tables and the RSS plots."
    ),
    scene: Annotated[
        list[str] | None,
        typer.Option(
            "--scene",
            help="solent-labels, solent, adsb, adsb-quickstart or all (repeatable; default all).",
        ),
    ] = None,
    runner: Annotated[
        list[str] | None,
        typer.Option("--runner", help="Only these runners, e.g. stonesoup-nn (repeatable)."),
    ] = None,
    cache_dir: str = typer.Option(
        None, "--cache-dir", help="Data cache (default $JOINTTRACK_DATA or ~/.cache/jointtrack)."
    ),
    cap: float = typer.Option(600.0, "--cap", help="Wall-time cap of each run, seconds."),
    seed: int = typer.Option(0, "--seed", help="Seed of the ADS-B degradation and noise."),
    seeds: int = typer.Option(
        1, "--seeds", help="ADS-B degradation seeds SEED … SEED+N-1 (table: mean, min–max)."
    ),
    bare_tracker: Annotated[
        list[str] | None,
        typer.Option(
            "--bare-tracker",
            help="Also the bare run with tracker= jipda, pmb or pmbm (repeatable).",
        ),
    ] = None,
    stamp: str = typer.Option(
        None,
        "--stamp",
        help="Stone Soup's detection times: report (own; Solent's default) or scan (ADS-B's).",
    ),
) -> None:
    """Real AIS (Solent) and ADS-B data: jointtrack beside Stone Soup's own demo trackers on
    identical reports — wall, CPU, peak RSS and the scores against the self-reports. Downloads
    the public data with pip on first use."""
    from jointtrack.bench import realdata
    from jointtrack.bench.realdata_data import RealDataError

    scenes = list(realdata.SCENE_NAMES) if not scene or "all" in scene else scene
    bad = [s for s in scenes if s not in realdata.SCENE_NAMES]
    if bad:
        _fail(f"--scene must be among {', '.join(realdata.SCENE_NAMES)} or all, got {bad}")
    if not cap > 0:
        _fail(f"--cap must be > 0 seconds, got {cap}")
    if stamp is not None and stamp not in realdata.STAMPS:
        _fail(f"--stamp must be one of {', '.join(realdata.STAMPS)}, got {stamp!r}")
    if seeds < 1:
        _fail(f"--seeds must be ≥ 1, got {seeds}")
    bad = [k for k in bare_tracker or () if k not in realdata.BARE_TRACKERS]
    if bad:
        _fail(f"--bare-tracker must be among {', '.join(realdata.BARE_TRACKERS)}, got {bad}")
    try:
        realdata.run(
            quick=quick,
            out=out,
            scenes=scenes,
            runners=runner or None,
            cache_dir=cache_dir,
            wall_cap=cap,
            seed=seed,
            seeds=seeds,
            bare_trackers=tuple(bare_tracker or ()),
            stamp=stamp,
        )
    except RealDataError as exc:
        _fail(exc, code=1)


reproduce_app = typer.Typer(
    cls=_Group,
    help="Reproduce a paper's tables beside the paper's own numbers.",
    no_args_is_help=True,
)
app.add_typer(reproduce_app, name="reproduce")


def _fail(message, code: int = 2):
    """One red line on stderr and exit ``code`` (never a traceback)."""
    from rich.console import Console

    text = " ".join(str(message).split())
    Console(stderr=True).print(
        f"error: {text}", style="bold red", markup=False, highlight=False, soft_wrap=True
    )
    raise typer.Exit(code)


#: ``jointtrack run --scenario`` names: the detection scenarios (the keys of
#: jointtrack.scenarios.GENERATORS, in its order) and the superpositional ``acoustic``
#: (run by its own filter). Spelled out so that --help does not import the scenarios
#: (seconds); test_newcomer checks that the two lists agree.
RUN_SCENARIOS = ("bojilov", "crossing", "many", "abreast", "coalescence", "acoustic")

#: options shared by the commands
ReproduceOut = Annotated[Path, typer.Option("--out", help="Output directory.")]
ProgressFlag = Annotated[
    bool | None,
    typer.Option("--progress/--no-progress", help="Progress bar (default: on a terminal)."),
]


@app.command("run", cls=_Command)
def run_command(
    detections: Annotated[
        Path | None,
        typer.Option(
            "--detections",
            help="Detections file (CSV or Parquet: time, x, y[, z][, sensor], or time, "
            'range, bearing[, sensor] with sensor = "range-bearing" in the config).',
        ),
    ] = None,
    truth: Annotated[
        Path | None,
        typer.Option(
            "--truth",
            help="Ground truth for --detections (CSV or Parquet: time, id, x, y[, z]; times "
            "as in the detections file): scores the tracks (GOSPA, OSPA, track statistics, "
            "gospa.png). Truth rows at times with no scan are not scored (a note says so).",
        ),
    ] = None,
    config: Annotated[
        Path | None,
        typer.Option("--config", help="TOML file with tracker, scenario and metrics tables."),
    ] = None,
    scenario: Annotated[
        str | None,
        typer.Option(
            "--scenario",
            metavar=f"[{'|'.join(RUN_SCENARIOS)}]",
            help=f"Built-in scenario: {', '.join(RUN_SCENARIOS[:-1])} or {RUN_SCENARIOS[-1]} "
            "(superpositional sensors, see --filter); default bojilov.",
        ),
    ] = None,
    out: Annotated[
        Path | None, typer.Option("--out", help="Output directory (default jointtrack-out).")
    ] = None,
    seed: Annotated[int | None, typer.Option("--seed", help="Scenario seed (default 0).")] = None,
    fmt: Annotated[
        str | None, typer.Option("--format", help="Tracks file format: csv (default) | parquet.")
    ] = None,
    checkpoint: Annotated[
        Path | None,
        typer.Option(
            "--checkpoint",
            help="Save the tracker state to this file as the run goes. A file that can "
            "still continue a run (or is not a checkpoint) is not overwritten: continue "
            "with --resume FILE, or delete it to start over.",
        ),
    ] = None,
    checkpoint_every: Annotated[
        int | None, typer.Option("--checkpoint-every", help="Scans between checkpoints (10).")
    ] = None,
    resume: Annotated[
        Path | None,
        typer.Option(
            "--resume",
            help="Continue the run saved in this checkpoint (its inputs, settings and output "
            "directory come from the checkpoint; other flags only if they agree).",
        ),
    ] = None,
    max_scans: Annotated[
        int | None,
        typer.Option("--max-scans", help="Stop after this many scans (counted from the first)."),
    ] = None,
    progress: ProgressFlag = None,
    start_from: Annotated[
        str | None,
        typer.Option(
            "--start-from",
            metavar="[truth|nothing]",
            help="truth: start confirmed tracks at the true states of the first scan (the "
            "default for bojilov, the paper's experiment); nothing: the tracker initiates "
            "every track from the detections (the default for the other scenarios and "
            "--detections). Overrides start_from in \\[scenario].",
        ),
    ] = None,
    tracker: Annotated[
        str | None,
        typer.Option(
            "--tracker",
            metavar="[jipda|jpda|pmb|pmbm|particle]",
            help="jipda (default): Kalman JPDA with JIPDA existence; jpda: Kalman JPDA with "
            "M-of-N confirmation; pmb / pmbm: Poisson multi-Bernoulli (mixture), settings in "
            "\\[pmbm]; particle: particle JPDA of the scenario's known targets, started from "
            "the truth (bojilov, crossing; no checkpoints). Overrides kind in \\[tracker].",
        ),
    ] = None,
    weights: Annotated[
        str | None,
        typer.Option(
            "--weights",
            metavar="[exact|saddle|saddle-corrected]",
            help="Particle weights (--tracker particle): Streit's mixed derivative, exact "
            "(default) or by the saddle point.",
        ),
    ] = None,
    particles: Annotated[
        int | None,
        typer.Option(
            "--particles",
            help="Particles per target (--tracker particle; 1000). --scenario acoustic: "
            "particles of the filter (4000; sps-mb: per component, 1000).",
        ),
    ] = None,
    filter_name: Annotated[
        str | None,
        typer.Option(
            "--filter",
            metavar="[sps-cphd|sps-phd|sps-mb]",
            help="--scenario acoustic: the superpositional-sensor filter (default sps-cphd).",
        ),
    ] = None,
    likelihood: Annotated[
        str | None,
        typer.Option(
            "--likelihood",
            metavar="[gaussian|saddlepoint|hybrid]",
            help="--scenario acoustic: the filter's likelihood method (default gaussian).",
        ),
    ] = None,
    window: Annotated[
        float | None,
        typer.Option(
            "--window",
            help="Report files (AIS, OpenSky, traffic): scans of this many seconds instead "
            "of one scan per report time.",
        ),
    ] = None,
    reference: Annotated[
        str | None,
        typer.Option(
            "--reference",
            metavar="LAT,LON",
            help="Geodetic data: origin of the local east-north frame in degrees (default: "
            "the centre of the data).",
        ),
    ] = None,
    no_fit: Annotated[
        bool,
        typer.Option(
            "--no-fit",
            help="--detections: keep the defaults for the [tracker] keys the config does not "
            "set, instead of fitting them to the data (jointtrack fit).",
        ),
    ] = False,
    labels: Annotated[
        str | None,
        typer.Option(
            "--labels",
            metavar="[associate|score|ignore]",
            help="Report files: the identities (MMSI, icao24) associate reports to tracks "
            "and score them (associate, default), only score them, or are ignored.",
        ),
    ] = None,
) -> None:
    """Track: detections in, tracks out (default: Bojilov's five targets, beta = 1, seed 0).

    Writes tracks.csv (or .parquet), metrics.json, scene.png and gospa.png to
    --out and prints a summary.
    """
    from jointtrack._console import make_console
    from jointtrack.experiments.writers import RunAlreadyComplete
    from jointtrack.io import DataFileError

    console = make_console()
    show = console.is_terminal if progress is None else progress
    if seed is not None and seed < 0:
        _fail(f"--seed must be a non-negative integer (the scenario's random seed), got {seed}")
    if scenario == "acoustic" or filter_name is not None or likelihood is not None:
        _run_acoustic(locals(), console, show)
        return
    try:
        from jointtrack.experiments import run as runmod

        if start_from is not None and start_from not in runmod.STARTS:
            raise runmod.RunConfigError(
                f"--start-from must be truth or nothing, got {start_from!r}"
            )
        if resume is not None and runmod.particle_options(tracker, weights, particles) is not None:
            raise runmod.RunConfigError(
                "--resume continues a checkpointed Kalman JPDA run; the particle tracker "
                "(--tracker particle) has no checkpoints"
            )
        if resume is not None and config is not None:
            opts = runmod.load_config(config).tracker_options
            if runmod.particle_options(table=opts, source=str(config)) is not None:
                raise runmod.RunConfigError(
                    f'--config {config} sets kind = "particle" in [tracker], but --resume '
                    "continues a checkpointed Kalman JPDA run; the particle tracker has no "
                    "checkpoints"
                )
        given = runmod.load_config(config) if config is not None else runmod.RunConfig()
        asked_kind = tracker if tracker is not None else given.tracker_options.get("kind")
        saved_cfg = None
        if resume is not None:
            saved_kind, saved_cfg = _checkpoint_tracker(resume)
            if asked_kind is not None and asked_kind != saved_kind:
                flag = "--tracker" if tracker is not None else f"--config {config} kind"
                raise runmod.RunConfigError(
                    f"{flag} {asked_kind} conflicts with the checkpoint {resume}, which holds "
                    f"the state of a {saved_kind} tracker; omit it (--resume continues with "
                    "the checkpoint's tracker)"
                )
            tracker = saved_kind
            detections, config, scenario, seed, out, fmt, checkpoint_every, restored = (
                _from_checkpoint(
                    resume,
                    detections,
                    config,
                    scenario,
                    seed,
                    out,
                    fmt,
                    checkpoint_every,
                    start_from,
                )
            )
            truth = _truth_from_checkpoint(resume, truth)
        else:
            restored = None
            if checkpoint is not None:
                _existing_checkpoint(checkpoint, console)
        out = Path("jointtrack-out") if out is None else out
        fmt = "csv" if fmt is None else fmt
        every_given = checkpoint_every
        if fmt not in runmod.FORMATS:
            raise runmod.RunConfigError(f"--format must be csv or parquet, got {fmt!r}")
        checkpoint_every = 10 if checkpoint_every is None else checkpoint_every
        if scenario is not None and scenario not in runmod.SCENARIOS:
            # acoustic runs on its own path (_run_acoustic), so is not among runmod's
            names = ", ".join(RUN_SCENARIOS)
            raise runmod.RunConfigError(f"--scenario must be one of {names}, got {scenario!r}")
        cfg = runmod.load_config(config) if config is not None else runmod.RunConfig()
        if restored is not None:
            cfg = restored
        particle = runmod.particle_options(
            tracker, weights, particles, cfg.tracker_options, cfg.tracker, source=cfg.source
        )
        kind = None
        if particle is None:
            kind = runmod.tracker_kind(tracker, cfg.tracker_options, cfg.tracker)
            runmod.check_kind_keys(kind, cfg.tracker, cfg.pmbm, cfg.source)
        jpda_table = cfg.tracker
        if kind in runmod.JPDA_KINDS:
            jpda_table = runmod.jpda_kind_overrides(kind, cfg.tracker)
        kind_opts = {} if particle is not None else {"tracker": kind, "pmbm": cfg.pmbm}
        if particle is not None:
            if detections is not None:
                raise runmod.RunConfigError(
                    "--tracker particle runs on a built-in scenario (it starts every target "
                    f"from its true state at the first scan); --detections {detections} has none"
                )
            for flag, value in (
                ("--checkpoint", checkpoint),
                ("--checkpoint-every", every_given),
            ):
                if value is not None:
                    raise runmod.RunConfigError(
                        f"{flag}: the particle tracker has no checkpoints (the checkpoint "
                        "format holds Kalman tracks); run it without checkpoint options"
                    )
            if start_from == "nothing":
                raise runmod.RunConfigError(
                    "--start-from nothing: the particle tracker follows a known, fixed set of "
                    "targets started from the truth at the first scan; it does not initiate "
                    "tracks"
                )
        common = dict(
            out_dir=out,
            fmt=fmt,
            progress=show,
            checkpoint=checkpoint,
            checkpoint_every=checkpoint_every,
            resume=resume,
            max_scans=max_scans,
            metrics_opts=cfg.metrics,
            console=console,
        )
        if truth is not None and detections is None:
            raise runmod.RunConfigError(
                "--truth needs --detections (a built-in scenario is scored with its own truth)"
            )
        if detections is not None:
            if scenario is not None or seed is not None:
                raise runmod.RunConfigError(
                    "--detections cannot be combined with --scenario or --seed"
                )
            if start_from == "truth":
                # a truth file holds positions only: no velocities to start a track at
                raise runmod.RunConfigError(
                    "--start-from truth needs a built-in scenario's true states; "
                    f"--detections {detections} has none (a --truth file holds positions "
                    "only): use --start-from nothing, which is what a detections run does"
                )
            from jointtrack.io import read_detections
            from jointtrack.io.reports import report_format

            rfmt = report_format(detections)
            if rfmt is not None and truth is not None:
                raise runmod.RunConfigError(
                    f"--truth: {detections} is a report file, scored against the targets' "
                    "own reports (self_reports in metrics.json); a truth file is not used"
                )
            if rfmt is not None:
                metrics = _run_report_file(
                    detections, rfmt, kind, jpda_table, resume, window, reference, labels, common,
                    pmbm=cfg.pmbm,
                )  # fmt: skip
                runmod.print_summary(metrics, console)
                console.print(f"outputs in {out}/", markup=False, highlight=False)
                return
            for flag, value in (("--window", window), ("--labels", labels)):
                if value is not None:
                    raise runmod.RunConfigError(
                        f"{flag} is for report files (AIS, OpenSky, traffic); {detections} is a "
                        "detections file"
                    )
            dets = read_detections(detections, reference=_reference(reference))
            # report-like files (irregular times, ~1 return per time) get the async
            # model unless [tracker] sets reporting; a resume decides the same again
            # the model fitted to the data for every key [tracker] does not set (or, with
            # --no-fit, report-like files' async model); a resume fits the same again and
            # the fitted values are part of the run's identity
            if restored is not None:
                # the checkpoint's settings (the fit is in them): its fit and notes
                fit_id, data_notes = runmod.saved_fit(resume)
            else:
                jpda_table, data_notes, fit_id = runmod.settings_from_data(
                    dets, jpda_table, kind, fit=not no_fit
                )
            tracker_cfg = runmod.make_tracker_config(
                {"dim": dets.dim}, jpda_table, source=cfg.source
            )
            runmod.check_sensor(tracker_cfg, dets.kind, str(detections), cfg.source)
            if tracker_cfg.dim != dets.dim:
                raise runmod.RunConfigError(
                    f"{cfg.source}: [tracker] key 'dim' = {tracker_cfg.dim} but {detections} "
                    f"holds {dets.dim}-D detections"
                )
            if cfg.scenario:
                console.print(
                    "warning: the [scenario] table of the config is ignored with --detections",
                    style="yellow",
                    markup=False,
                    highlight=False,
                    soft_wrap=True,
                )
            if kind in runmod.POISSON_KINDS:
                # the [tracker] keys as the user set them (p_g: see make_pmbm_config)
                # and the settings chosen from the data above (reporting model, fit)
                tracker_cfg = saved_cfg if saved_cfg is not None else dict(jpda_table)
            metrics = runmod.run_detections(
                dets,
                tracker_cfg,
                truth=truth,
                sensors=cfg.sensors,
                notes=data_notes,
                fit=False,  # fitted above
                run_identity={} if fit_id is None else {"fit": fit_id},
                **kind_opts,
                **common,
            )
        else:
            sc_table = dict(cfg.scenario)
            name = scenario or sc_table.pop("name", "bojilov")
            sc_table.pop("name", None)
            sd = seed if seed is not None else sc_table.pop("seed", 0)
            sc_table.pop("seed", None)
            where = f"{cfg.source}: [scenario]" if cfg.source else "[scenario]"
            table_start = runmod.start_setting(
                sc_table.pop("start_from", None), sc_table.pop("start_from_truth", None), where
            )
            # like --scenario and --seed, the flag wins over the config's table
            start = start_from if start_from is not None else table_start
            sc = runmod.make_scenario(name, sd, sc_table, source=cfg.source)
            # this path hands run_scenario a built TrackerConfig: the start's settings come
            # from the resolution run_scenario uses for a mapping (run.start_settings)
            _start, jpda_table = runmod.start_settings(start, sc.name, kind, jpda_table, particle)
            tracker_cfg = runmod.make_tracker_config(
                runmod.scenario_tracker_settings(sc), jpda_table, source=cfg.source
            )
            if tracker_cfg.dim != sc.dim:
                raise runmod.RunConfigError(
                    f"{cfg.source}: [tracker] key 'dim' = {tracker_cfg.dim} but scenario "
                    f"{name} is {sc.dim}-D"
                )
            runmod.check_sensor(tracker_cfg, "position", f"scenario {name}", cfg.source)
            if kind in runmod.POISSON_KINDS:
                tracker_cfg = saved_cfg if saved_cfg is not None else dict(cfg.tracker)
            metrics = runmod.run_scenario(
                sc,
                tracker_cfg,
                scenario_kwargs=sc_table,
                start_from=start,
                particle=particle,
                **kind_opts,
                **common,
            )
    except KeyboardInterrupt:
        _fail(
            f"interrupted; the tracks so far are in {out}"
            # a resumed run keeps checkpointing to the file it resumed
            + (f"; continue with --resume {checkpoint or resume}" if checkpoint or resume else ""),
            code=130,
        )
    except RunAlreadyComplete as exc:
        # e.g. killed in its last instant: every output is there, nothing is wrong
        console.print(
            f"already complete, nothing to do: {exc}", markup=False, highlight=False, soft_wrap=True
        )
        metrics = exc.metrics
    except (DataFileError, ValueError, OSError) as exc:
        _fail(exc)
    runmod.print_summary(metrics, console)
    console.print(f"outputs in {out}/", markup=False, highlight=False)


def _run_acoustic(flags: dict, console, show: bool) -> None:
    """``jointtrack run --scenario acoustic``: a superpositional-sensor filter (no detections)."""
    if flags["scenario"] != "acoustic":
        _fail("--filter and --likelihood apply to --scenario acoustic only")
    refused = {
        "detections": "--detections",
        "truth": "--truth",
        "config": "--config",
        "checkpoint": "--checkpoint",
        "checkpoint_every": "--checkpoint-every",
        "resume": "--resume",
        "weights": "--weights",
        "start_from": "--start-from",
    }
    for key, flag in refused.items():
        if flags[key] is not None:
            _fail(
                f"{flag} does not apply to --scenario acoustic (a superpositional sensor "
                "network read by a particle SPS filter)"
            )
    if flags["tracker"] is not None:
        _fail("--tracker does not apply to --scenario acoustic; choose the filter with --filter")
    if flags["fmt"] not in (None, "csv"):
        _fail("--format: --scenario acoustic writes tracks.csv only")
    from jointtrack.experiments.acoustic_run import print_acoustic_summary, run_acoustic

    out = Path("jointtrack-out") if flags["out"] is None else flags["out"]
    try:
        metrics = run_acoustic(
            out,
            filter_name=flags["filter_name"] or "sps-cphd",
            likelihood=flags["likelihood"] or "gaussian",
            seed=0 if flags["seed"] is None else flags["seed"],
            max_scans=flags["max_scans"],
            particles=flags["particles"],
            progress=show,
            console=console,
        )
    except KeyboardInterrupt:
        _fail("interrupted", code=130)
    except (ValueError, OSError, NotImplementedError) as exc:
        _fail(exc)
    print_acoustic_summary(metrics, console)
    console.print(f"outputs in {out}/", markup=False, highlight=False)


def _reference(text):
    """``--reference LAT,LON[,ALT]`` as a tuple of floats (None when not given)."""
    if text is None:
        return None
    from jointtrack.experiments.run import RunConfigError
    from jointtrack.io.geodetic import LocalFrame

    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) not in (2, 3):
        raise RunConfigError(f"--reference must be LAT,LON[,ALT] in degrees, got {text!r}")
    try:
        # the frame checks the ranges (latitude within ±90°, finite values); checked
        # here so the error names the flag, not the frame's lat0/lon0 arguments
        LocalFrame(*values)
    except ValueError as exc:
        raise RunConfigError(f"--reference {text}: {exc}") from None
    return values


def _run_report_file(path, rfmt, kind, table, resume, window, reference, labels, common, pmbm=None):
    """``jointtrack run --detections`` on a report file: :func:`run_reports`.

    On ``--resume`` the window, frame and label use come from the checkpoint
    (the run's identity); flags that differ are an error. ``kind``: JIPDA (None or
    ``"jipda"``), ``"pmb"`` or ``"pmbm"`` (``pmbm``: the ``[pmbm]`` table).
    """
    import math

    from jointtrack.experiments.realdata import LABEL_MODES, run_reports
    from jointtrack.experiments.run import RunConfigError, read_run
    from jointtrack.io.reports import MAX_WINDOW

    if kind not in (None, "jipda", "pmb", "pmbm"):
        raise RunConfigError(
            f"report files run the JIPDA, PMB or PMBM tracker with the asynchronous "
            f"reporting model; --tracker {kind} (M-of-N confirmation) is not available for them"
        )
    # checked here, not only by run_reports, so that the message names the flag
    if window is not None and not (math.isfinite(window) and window > 0):
        raise RunConfigError(f"--window must be a positive number of seconds, got {window:g}")
    if window is not None and window > MAX_WINDOW:
        raise RunConfigError(
            f"--window must be at most {MAX_WINDOW:g} seconds (~31.7 years; windows are "
            f"counted in 64-bit nanoseconds), got {window:g}"
        )
    if labels is not None and labels not in LABEL_MODES:
        raise RunConfigError(f"--labels must be one of {', '.join(LABEL_MODES)}, got {labels!r}")
    ref = _reference(reference)
    if resume is not None:
        saved = ((read_run(resume) or {}).get("inputs") or {}).get("reports") or {}
        # the checkpoint records the frame's origin with its altitude (0 when not given)
        given_ref = None if ref is None else [*ref, 0.0][:3]
        for flag, given, key, text in (
            ("--window", window, "window", window),
            ("--labels", labels, "labels", labels),
            ("--reference", given_ref, "reference", reference),
        ):
            if given is not None and given != saved.get(key):
                raise RunConfigError(
                    f"{flag} {text} differs from the checkpoint's ({saved.get(key)}); omit it"
                )
        window, labels, ref = saved.get("window"), saved.get("labels"), saved.get("reference")
    return run_reports(
        path,
        {k: v for k, v in table.items() if k != "kind"},
        report_format=rfmt,
        window=window,
        reference=ref,
        labels=labels or "associate",
        tracker=kind,
        pmbm=pmbm,
        **common,
    )


def _from_checkpoint(
    resume, detections, config, scenario, seed, out, fmt, checkpoint_every, start_from=None
):
    """Fill the run's inputs from a checkpoint; a flag that disagrees is an error naming it."""
    from jointtrack.experiments import run as runmod
    from jointtrack.trackers.state_io import read_run

    info = read_run(resume)
    if not isinstance(info, dict) or "inputs" not in info:
        raise runmod.RunConfigError(
            f"{resume}: a tracker state without the bookkeeping of a jointtrack run; it "
            "cannot resume `jointtrack run`"
        )
    inputs = runmod._run_inputs(info["inputs"])
    what = runmod._describe(inputs)

    def conflict(flag, value):
        return runmod.RunConfigError(
            f"{flag} {value} conflicts with the checkpoint {resume}, which continues "
            f"{what} into {info['out_dir']}; omit {flag}"
        )

    if out is not None and Path(out).resolve() != Path(info["out_dir"]):
        raise conflict("--out", out)
    if fmt is not None and fmt != info["format"]:
        raise conflict("--format", fmt)
    if "detections" in inputs:
        if scenario is not None:
            raise conflict("--scenario", scenario)
        if seed is not None:
            raise conflict("--seed", seed)
        if detections is not None and Path(detections).resolve() != Path(inputs["detections"]):
            raise conflict("--detections", detections)
        detections = Path(inputs["detections"])
    else:
        if detections is not None:
            raise conflict("--detections", detections)
        if scenario is not None and scenario != inputs.get("scenario"):
            raise conflict("--scenario", scenario)
        if seed is not None and seed != inputs.get("seed"):
            raise conflict("--seed", seed)
        scenario, seed = inputs.get("scenario"), inputs.get("seed")
    # a detections run always starts from nothing; a scenario run records its start
    if "detections" in inputs:
        saved_start = "nothing"
    elif "start_from_truth" in inputs:
        saved_start = "truth" if inputs["start_from_truth"] else "nothing"
    else:
        saved_start = runmod.default_start(str(inputs.get("scenario")))
    saved_words = "the truth" if saved_start == "truth" else "nothing"
    if start_from is not None and start_from != saved_start:
        raise runmod.RunConfigError(
            f"--start-from {start_from} conflicts with the checkpoint {resume}, whose "
            f"tracks started from {saved_words} ({what} into {info['out_dir']}); omit "
            "--start-from"
        )
    # the tracker settings are in the checkpoint; the scenario and metrics tables here
    table = {} if "detections" in inputs else dict(inputs.get("kwargs") or {})
    if "start_from_truth" in inputs:
        table["start_from_truth"] = inputs["start_from_truth"]
    trk = runmod.load_tracker(resume)
    tracker = {}  # a PMB/PMBM run continues with the checkpoint's PMBMConfig as it is
    if runmod.tracker_kind_of(trk) in runmod.JPDA_KINDS:
        tracker = trk.config.to_dict()  # exactly the checkpoint's settings
        tracker = {k: list(v) if isinstance(v, tuple) else v for k, v in tracker.items()}
    restored = runmod.RunConfig(
        tracker=tracker,
        scenario=table,
        metrics=dict(info.get("metrics_opts") or {}),
        sensors=runmod.sensor_tables_from_run(info.get("sensors")),
    )
    if config is not None:
        given = runmod.load_config(config)
        own = ("name", "seed", "start_from", "start_from_truth")  # compared on their own
        if given.metrics != restored.metrics or (
            "detections" not in inputs
            and {k: v for k, v in given.scenario.items() if k not in own}
            != {k: v for k, v in restored.scenario.items() if k not in own}
        ):
            raise conflict("--config", config)
        given_start = runmod.start_setting(
            given.scenario.get("start_from"), given.scenario.get("start_from_truth")
        )
        # --start-from (already checked) overrides the config's start, as in a fresh run
        if (
            "detections" not in inputs
            and start_from is None
            and given_start not in (None, saved_start)
        ):
            raise runmod.RunConfigError(
                f'--config {config} sets [scenario] start_from = "{given_start}" but the '
                f"checkpoint {resume} continues a run whose tracks started from "
                f"{saved_words}; omit --config"
            )
    return (
        detections,
        None,
        scenario,
        seed,
        Path(info["out_dir"]),
        info["format"],
        checkpoint_every if checkpoint_every is not None else info.get("checkpoint_every"),
        restored,
    )


def _existing_checkpoint(checkpoint, console) -> None:
    """Refuse a new run whose ``--checkpoint`` file would overwrite one that can still
    continue a run (a killed or ``--max-scans`` run: say how to resume it) or a file
    that is not a checkpoint at all; a completed run's checkpoint is replaced with a
    notice (nothing is lost: its tracks are complete)."""
    from jointtrack.experiments import run as runmod
    from jointtrack.experiments.writers import PARTS_DIR, run_is_complete
    from jointtrack.trackers.state_io import read_run

    path = Path(checkpoint)
    if not path.is_file():
        return  # a new file (a directory is refused with the other output checks)
    try:
        info = read_run(path)
    except Exception:  # noqa: BLE001 - any unreadable file is "not a checkpoint" here
        info = None
    if not isinstance(info, dict) or "inputs" not in info or "out_dir" not in info:
        raise runmod.RunConfigError(
            f"--checkpoint {path} exists and is not the checkpoint of a jointtrack run; "
            "the run would overwrite it: give another file name, or delete the file"
        )
    what = runmod._describe(runmod._run_inputs(info["inputs"]))
    if not run_is_complete(info, Path(info["out_dir"]) / PARTS_DIR):
        raise runmod.RunConfigError(
            f"--checkpoint {path} holds an unfinished run ({what} into {info['out_dir']}, "
            f"{info.get('n_scans', '?')} scans done"
            + (", writing its outputs" if info.get("phase") == "finishing" else "")
            + "); continue it with `jointtrack run "
            f"--resume {path}`, or delete {path} to start over"
        )
    console.print(
        f"note: --checkpoint {path} held the checkpoint of a completed run ({what}); "
        "this run replaces it",
        markup=False,
        highlight=False,
        soft_wrap=True,
    )


def _checkpoint_tracker(resume):
    """``(kind, config)`` of the tracker a checkpoint holds (config None for JPDA kinds,
    whose settings are rebuilt from the checkpoint's table by :func:`_from_checkpoint`)."""
    from jointtrack.experiments import run as runmod

    trk = runmod.load_tracker(resume)
    kind = runmod.tracker_kind_of(trk)
    return kind, (trk.config if kind in runmod.POISSON_KINDS else None)


def _truth_from_checkpoint(resume, truth):
    """The truth file of the run a checkpoint continues (``--truth`` must agree)."""
    from jointtrack.experiments import run as runmod
    from jointtrack.trackers.state_io import read_run

    info = read_run(resume)
    inputs = info["inputs"]
    saved = inputs.get("truth") if "detections" in inputs else None
    if truth is not None and (saved is None or Path(truth).resolve() != Path(saved)):
        raise runmod.RunConfigError(
            f"--truth {truth} conflicts with the checkpoint {resume}, which continues "
            f"{runmod._describe(inputs)} "
            + (f"with the truth {saved}" if saved else "without a truth")
            + f" into {info['out_dir']}; omit --truth"
        )
    return Path(saved) if saved is not None else None


def _reproduce(progress, run):
    """Run a reproduction: console, progress default, and one-line errors.

    ``run(console, show_progress)`` returns the result; ``(result, console)``
    is returned for the report.
    """
    from jointtrack._console import make_console

    console = make_console()
    show = console.is_terminal if progress is None else progress
    try:
        return run(console, show), console
    except KeyboardInterrupt:
        _fail("interrupted", code=130)
    except (ValueError, OSError) as exc:
        _fail(exc)


@reproduce_app.command("bojilov", cls=_Command)
def reproduce_bojilov(
    runs: Annotated[
        int | None, typer.Option("--runs", help="Runs per clutter density (default 10).")
    ] = None,
    quick: Annotated[
        bool, typer.Option("--quick", help="2 runs per clutter density (--runs wins).")
    ] = False,
    out: ReproduceOut = Path("jointtrack-out"),
    progress: ProgressFlag = None,
) -> None:
    """Bojilov et al. Tables 2-3 (hypotheses, multiplications, seconds per cluster) vs ours."""
    n = runs if runs is not None else (2 if quick else 10)
    if n < 1:
        _fail(f"--runs must be >= 1, got {n}")
    from jointtrack.experiments import bojilov as boj

    result, console = _reproduce(
        progress,
        lambda console, show: boj.reproduce(runs=n, out_dir=out, progress=show, console=console),
    )
    boj.print_report(result, console)


@reproduce_app.command("schaub", cls=_Command)
def reproduce_schaub(
    quick: Annotated[
        bool,
        typer.Option(
            "--quick",
            help="40 steps, 10 seeds (full: 100), curves of one seed, reference every 5th.",
        ),
    ] = False,
    seeds: Annotated[
        int | None,
        typer.Option(
            "--seeds", help="Seeds 0..N-1 of the max-weight statistics (default 100; quick 10)."
        ),
    ] = None,
    steps: Annotated[
        int | None, typer.Option("--steps", help="Time steps per example (default 400/100/400).")
    ] = None,
    process_noise_reading: Annotated[
        str,
        typer.Option(
            "--process-noise-reading",
            help="variance (default: Table III's c read literally, Σ_P = c I) | std "
            "(c a standard deviation, Σ_P = c² I). The max-weight statistics show both.",
        ),
    ] = "variance",
    out: ReproduceOut = Path("jointtrack-out"),
    progress: ProgressFlag = None,
) -> None:
    """Schaub §4 examples 1-3: max KL vs step per method (Figures 5-7), ms per step.

    Exits 1 only if a self-check fails; the paper's figures are measured differences.
    """
    if seeds is not None and seeds < 1:
        _fail(f"--seeds must be >= 1, got {seeds}")
    if steps is not None and steps < 1:
        _fail(f"--steps must be >= 1, got {steps}")
    from jointtrack.experiments import schaub

    if process_noise_reading not in schaub.READINGS:
        _fail(
            f"--process-noise-reading must be one of {', '.join(schaub.READINGS)}, "
            f"got {process_noise_reading!r}"
        )
    result, console = _reproduce(
        progress,
        lambda console, show: schaub.reproduce(
            quick,
            out_dir=out,
            seeds=None if seeds is None else range(seeds),
            steps=steps,
            process_noise_reading=process_noise_reading,
            progress=show,
            console=console,
        ),
    )
    if schaub.print_report(result, console):
        raise typer.Exit(1)


@reproduce_app.command("streit", cls=_Command)
def reproduce_streit(
    quick: Annotated[
        bool, typer.Option("--quick", help="100 trials per cell and a small cost grid.")
    ] = False,
    out: ReproduceOut = Path("jointtrack-out"),
    progress: ProgressFlag = None,
) -> None:
    """Streit Table 1 (saddle-point ratios), Figures 1, 3, 4 and the exact-vs-saddle cost table."""
    from jointtrack.experiments import streit

    result, console = _reproduce(
        progress,
        lambda console, show: streit.reproduce(quick, out_dir=out, progress=show, console=console),
    )
    streit.print_report(result, console)


@reproduce_app.command("nannuru", cls=_Command)
def reproduce_nannuru(
    quick: Annotated[
        bool, typer.Option("--quick", help="5 trials per row, 10 x 50 ratio states (< 60 s).")
    ] = False,
    out: ReproduceOut = Path("jointtrack-out"),
    progress: ProgressFlag = None,
) -> None:
    """Nannuru & Coates Tables I-IV, Example 1, Figures 1-5: Gaussian vs exact superposition."""
    from jointtrack.experiments import nannuru

    result, console = _reproduce(
        progress,
        lambda console, show: nannuru.reproduce(quick, out_dir=out, progress=show, console=console),
    )
    nannuru.print_report(result, console)


@app.command("fit", cls=_Command)
def fit_command(
    detections: Annotated[
        Path,
        typer.Argument(help="Detections file (CSV or Parquet, as jointtrack run --detections)."),
    ],
    out: Annotated[
        Path | None,
        typer.Option("--out", help="Write the fitted [tracker] TOML here (atomically)."),
    ] = None,
    tracker: Annotated[
        str | None,
        typer.Option(
            "--tracker", metavar="[jipda|jpda|pmb|pmbm]", help="The tracker the model is for."
        ),
    ] = None,
    config: Annotated[
        Path | None,
        typer.Option("--config", help="TOML config: its [tracker] keys are kept, not fitted."),
    ] = None,
    reference: Annotated[
        str | None,
        typer.Option(
            "--reference",
            metavar="LAT,LON",
            help="Geodetic data: origin of the local east-north frame in degrees.",
        ),
    ] = None,
) -> None:
    """Fit the tracker's model (noise, process noise, speed, P_D, clutter, gate) to a
    detections file and print (or write) it as a commented [tracker] TOML table.

    Exits 1 when nothing could be fitted (every value is then a stated default).
    """
    from jointtrack._atomic import atomic_file
    from jointtrack._console import make_console
    from jointtrack.io import DataFileError

    console = make_console()
    try:
        from jointtrack.experiments import run as runmod
        from jointtrack.experiments.fit import fit_tracker_settings
        from jointtrack.io import read_detections
        from jointtrack.io.reports import report_format

        if tracker is not None and tracker not in ("jipda", "jpda", "pmb", "pmbm"):
            raise runmod.RunConfigError(
                f"--tracker must be jipda, jpda, pmb or pmbm, got {tracker!r}"
            )
        cfg = runmod.load_config(config) if config is not None else runmod.RunConfig()
        kind = runmod.tracker_kind(tracker, cfg.tracker_options, cfg.tracker)
        if kind not in ("jipda", "jpda", "pmb", "pmbm"):
            raise runmod.RunConfigError(f"jointtrack fit has no model for --tracker {kind}")
        if report_format(detections) is not None:
            raise runmod.RunConfigError(
                f"{detections} is a report file (AIS, OpenSky, traffic), which runs with its "
                "own settings; jointtrack fit reads detections files (time, x, y or time, lat, lon)"
            )
        table = dict(cfg.tracker)
        if kind in runmod.JPDA_KINDS:
            table = runmod.jpda_kind_overrides(kind, table)
        dets = read_detections(detections, reference=_reference(reference))
        model = fit_tracker_settings(dets, table, kind)
        text = model.to_toml()
        runmod.make_tracker_config({"dim": dets.dim}, model.table, source=str(detections))
        if out is not None:
            with atomic_file(out) as tmp:
                Path(tmp).write_text(text)
    except (ValueError, OSError, DataFileError) as exc:
        _fail(exc)
    console.print(text, markup=False, highlight=False, soft_wrap=True)
    if out is not None:
        console.print(f"written to {out}", markup=False, highlight=False)
    if not model.fitted:
        _fail(
            "nothing could be fitted: "
            + "; ".join(sorted(set(model.fallbacks.values())) or ["every key is set in [tracker]"]),
            code=1,
        )


@app.command("sweep", cls=_Command)
def sweep_command(
    spec: Annotated[
        Path,
        typer.Argument(
            # rich markup would take [sweep] etc. for style tags and drop them: escaped
            help="Sweep spec (TOML): \\[sweep] axes and seeds over the \\[tracker], "
            "\\[scenario], \\[metrics] (and \\[filter]) base tables; see jointtrack.sweep.spec."
        ),
    ],
    workers: Annotated[
        int | None,
        typer.Option("--workers", help="Worker processes of the local Dask cluster (cores)."),
    ] = None,
    scheduler: Annotated[
        str | None,
        typer.Option("--scheduler", help="Run on an existing Dask scheduler (tcp://host:port)."),
    ] = None,
    out: Annotated[
        Path, typer.Option("--out", help="Output directory: results/ (Parquet), summary, plots.")
    ] = Path("jointtrack-sweep"),
    dry_run: Annotated[
        bool,
        typer.Option(
            "--dry-run", help="Print the grid size, runs already done and the estimated cost."
        ),
    ] = False,
    fail_fast: Annotated[
        bool, typer.Option("--fail-fast", help="Stop at the first failed run.")
    ] = False,
    progress: Annotated[
        bool | None,
        typer.Option("--progress/--no-progress", help="Progress bar (default: on a terminal)."),
    ] = None,
) -> None:
    """Monte Carlo sweep on Dask: every cell x seed of SPEC, one Parquet row per run.

    Finished runs are skipped when the same sweep is started again (resume);
    exits non-zero if any run failed or is missing at the end.
    """
    from jointtrack._console import make_console
    from jointtrack.sweep import engine, report
    from jointtrack.sweep.spec import load_spec

    if not engine.dask_available():
        _fail(engine.DASK_MISSING)
    if workers is not None and workers < 1:
        _fail(f"--workers must be >= 1, got {workers}")
    if workers is not None and scheduler is not None:
        _fail("--workers and --scheduler: an existing scheduler brings its own workers")
    console = make_console()
    show = console.is_terminal if progress is None else progress
    try:
        parsed = load_spec(spec)
        if dry_run:
            _print_plan(engine.plan(parsed, out, workers=workers), console)
            return
        outcome = engine.run_sweep(
            parsed,
            out,
            workers=workers,
            scheduler=scheduler,
            fail_fast=fail_fast,
            progress=show,
            console=console,
        )
        written = report.write_report(
            engine.ResultStore(outcome.results).read_rows(), parsed.axes, out
        )
    except KeyboardInterrupt:
        _fail(f"interrupted; finished runs are in {out}/results (run again to resume)", 130)
    except (ValueError, OSError, ImportError) as exc:
        _fail(exc)
    report.print_summary(written["cells"], parsed.axes, console)
    console.print(
        f"{outcome.total} runs: {outcome.ok} ok, {outcome.failed} failed, "
        f"{len(outcome.missing)} missing ({outcome.skipped} done before, {outcome.ran} run "
        f"now on {outcome.workers} workers in {outcome.wall_seconds:.1f} s); results in "
        f"{outcome.results}/, summary {written['summary']}, {len(written['plots'])} plots",
        markup=False,
        highlight=False,
    )
    if not outcome.complete:
        _fail(
            f"{outcome.failed} run(s) failed and {len(outcome.missing)} missing; their errors "
            f"are in the rows with status = 'failed'; run the sweep again to retry them",
            1,
        )


def _print_plan(p: dict, console) -> None:
    """The dry run's report: grid, resume state and the estimate with its basis."""
    lines = [
        f"grid: {p['cells']} cells x {p['seeds']} seeds = {p['runs']} runs",
        f"done already: {p['done']} (failed before, to rerun: {p['failed_before']}); "
        f"to run: {p['pending']}",
    ]
    for scenario, method, seconds, status in p.get("pilots", []):
        lines.append(f"pilot {scenario} {method}: {seconds:.2f} s ({status})")
    if p["pending"]:
        lines.append(
            f"estimate: {p['cpu_seconds']:.0f} CPU-s, about {p['wall_seconds']:.0f} s on "
            f"{p['workers']} workers (basis: one pilot run per scenario and method, run here, "
            "times the runs of its group; Dask overhead not counted)"
        )
    for line in lines:
        console.print(line, markup=False, highlight=False)


def main() -> None:
    app()


if __name__ == "__main__":
    main()
