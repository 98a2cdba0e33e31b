"""The main job, ``jointtrack run``: detections in, tracks out, scored and plotted.

:func:`run_scenario` runs the JPDA tracker on a built-in scenario (which has a
truth, so the tracks are scored); :func:`run_detections` runs it on detections
read from a file, scored when a truth file is given (``--truth``; otherwise
tracks and timing only). Both write into ``out_dir``:

* ``tracks.csv`` (or ``tracks.parquet``): one row per confirmed track per scan,
  columns ``time, track_id, x, y[, z], vx, vy[, vz], existence`` and the
  position covariance ``P_x_x, P_x_y, P_y_y`` (3-D: also ``P_x_z, P_y_z,
  P_z_z``) — the format of :func:`jointtrack.io.read_tracks`. Written as
  committed parts that survive a kill at any instant and are assembled into
  the file at the end (see :mod:`~jointtrack.experiments.writers`); Parquet
  row groups hold 50 scans each.
* ``metrics.json``: ``scoring`` (which times are scored and where the truth
  is taken there: :data:`SCORING_SCAN_TIMES`, :data:`SCORING_INTERPOLATED`),
  GOSPA (α = 2, p = 2, mean per scan and its localisation /
  missed / false parts, identity switches), OSPA mean, the track statistics of
  :func:`jointtrack.metrics.track_statistics`, and timing: per cluster size
  (number of tracks in a multi-track cluster) the count, mean and maximum
  association seconds, plus the run's wall time and scans per second; the
  clusters the approximation solved instead of the configured method
  (``association.fallbacks``), every multi-track cluster by kind of track
  (confirmed or tentative), method and reason with its count and size range
  (``association.clusters``: the summary's closing ``association:`` sentence)
  and, for ISO-8601 detection times, the
  ``time_origin``. Without a truth there is no GOSPA/OSPA and the track counts
  are the numbers of confirmed tracks.
* ``scene.png``: truth trajectories, detections (grey; clutter lighter),
  confirmed tracks as coloured lines labelled with their ids. Range–bearing
  detections are drawn at their Cartesian positions ``s + r (cos θ, sin θ)``,
  with the sensor ``s`` marked.
* ``gospa.png``: GOSPA per scan and its decomposition (only with a truth).

Tracker settings for a built-in scenario are derived from the scenario
(:func:`scenario_tracker_settings`): P_D, R = σ² I, the known clutter density
λ, the truth's process noise q, P_G of the scenario (0.99) and ``max_speed`` =
1.5 × the fastest true speed. For ``bojilov`` the five tracks are started from
the true states at the first scan with the steady-state covariance of the NCV
Kalman filter (:func:`steady_state_covariance`), as in Bojilov et al.'s
experiment, which studies track maintenance and association, not initiation;
the other scenarios start with no tracks. ``start_from = "nothing"`` (``jointtrack
run --start-from nothing``) starts Bojilov's scenario with no tracks too, so
the tracker's own initiation (two-point or one-point, then JIPDA existence or
M-of-N confirmation) must find the targets; ``"truth"`` starts any scenario from
its truth. A detections file has no true states, so it always starts from
nothing. ``metrics.json`` says which start was used: ``start`` (``"truth"`` or
``"nothing"``; ``start_from_truth`` is the same as a boolean); a run from nothing
adds ``confirmation`` (with a truth: scans to confirm per target) and
``start_evidence`` (the expected evidence per scan and scans to confirm of a lone
target's track, :func:`~jointtrack.experiments.summary.start_evidence`). GOSPA and OSPA
use ``[metrics]`` ``c`` and ``p`` when set, else the scenario's own
(:func:`scenario_metric_settings`: ``coalescence`` is scored with c = 10, p = 2
as in its paper), else c = 5σ and p = 2.

Config file (``--config FILE``, TOML)
-------------------------------------
::

    [tracker]              # any TrackerConfig field; overrides the derived value
    p_d = 0.9
    association = "exact"  # or enumerate, pda, lbp, mcmc, kbest
    clutter_density = "estimate"   # a number (per unit area), or "estimate" =
                                   # Bojilov's heuristic (8)
    exact_max_tracks = 12          # confirmed-track clusters above it: the approximation
    exact_max_bits_tentative = 12  # tentative-track clusters: exact up to 2^12 DP states
    # range–bearing detections (columns time, range, bearing) need:
    # sensor = "range-bearing"
    # sensor_position = [2000.0, 0.0]
    # range_noise = 100.0          # σ_r², m²
    # bearing_noise = 2.5e-5       # σ_θ², rad²; clutter_density is then per
    #                              # unit range × radian

    [scenario]             # built-in scenario (ignored with --detections)
    name = "crossing"      # bojilov | crossing | many | abreast | coalescence
    seed = 3
    start_from = "nothing" # or "truth" (default: truth for bojilov, nothing for the
                           # others); start_from_truth = true|false is the older
                           # spelling, still read (both: they must agree)
    n_scans = 20           # any keyword of the scenario function, e.g.
    clutter_per_scan = 5   # bojilov: clutter_density (β), n_scans, speeds, …

    [pmbm]                 # --tracker pmb|pmbm only: PMBMConfig fields that are not
    r_estimate = 0.4       # [tracker] fields (birth_model, birth_density, prior_density,
    max_hypotheses = 200   # birth_weights/means/covs, prior_weight, pruning, …)

    [metrics]
    c = 50.0               # GOSPA/OSPA cut-off (default 5σ; coalescence: 10, its paper's)
    switch_penalty = 0.0   # GOSPA identity-switch penalty
    switch_convention = "partner"  # or "stonesoup" (half a switch for assigned↔unassigned)

Unknown tables or keys, wrong types and bad values raise :class:`RunConfigError`
with a one-line message naming the file and the key; so does a sensor that does
not match the detections (range–bearing detections without ``sensor =
"range-bearing"``, or positions with it). ``tracks.csv`` holds Cartesian states
for either sensor. ``--scenario``, ``--seed`` and ``--start-from`` on the command
line override ``name``, ``seed`` and ``start_from``.

Tracker kinds (``--tracker``, or ``[tracker] kind``)
--------------------------------------------------
``jipda`` (the default): :class:`~jointtrack.trackers.JPDATracker` with JIPDA
existence (``existence = true``); ``jpda``: the same tracker with M-of-N
confirmation (``existence = false``; setting ``existence`` against the kind is an
error); ``pmb`` / ``pmbm``: :class:`~jointtrack.trackers.pmbm.PMBTracker` /
:class:`~jointtrack.trackers.pmbm.PMBMTracker`; ``particle``: below.
``metrics.json`` ``tracker.kind`` and the summary's ``tracker`` row name it.

The PMB/PMBM settings (:func:`~jointtrack.experiments.config.make_pmbm_config`)
share the derived JPDA settings above (motion, R, P_D, P_S, association,
``max_speed`` …) except P_G, which is PMBMConfig's 0.9999 unless ``[tracker]``
sets ``p_g`` (the scenes' 0.99 is a JPDA gate whose miss weight carries
1 − P_D P_G; the Poisson weights have no gate factor). Birth model: coalescence's
own Gaussian birth and prior (``scenario.info``, with its P_S); ``many``: uniform
births at its birth rate over its region; the other scenes and detection files:
uniform births of 0.01 per scan over the scene's region (the detections' bounding
box), with a prior of one undetected target over the region at the first scan.
Without a clutter density (a detections file without ``clutter_density``, or
``"estimate"``) λ is estimated as (mean detections per scan) / (bounding-box area
of the detections, in measurement coordinates) — an upper bound, since every
detection counts as clutter; a note in ``metrics.json`` and the summary says so,
and these notes are kept in the checkpoint. ``[tracker]`` keys of the JPDA track
logic (``existence``, ``r_confirm``, ``confirm_m``, …) are refused with ``pmb``
and ``pmbm``, a ``[pmbm]`` table with the JPDA kinds. They start from nothing
(``--start-from truth`` is refused). Checkpoints hold the tracker's kind;
``--resume`` rebuilds that kind and refuses a ``--tracker`` (or ``kind``) that
differs.

Particle tracker (``--tracker particle``)
-----------------------------------------
``jointtrack run --tracker particle [--weights exact|saddle|saddle-corrected]
[--particles N]`` (or ``[tracker] kind = "particle"``, ``weights``,
``particles``) runs :class:`~jointtrack.trackers.particle.ParticleJPDATracker`
instead: N particles per target (default 1000), weights by Streit's mixed
derivative — exact (default) or the saddle-point approximation — and
systematic resampling every scan. It follows a known, fixed set of targets, so
it runs on a built-in scenario whose targets all exist from the first scan to
the last (``bojilov``, ``crossing``; not ``many``, which has births and deaths,
nor ``--detections``), started from the truth at the first scan (particles
drawn around the true states with the steady-state covariance above; ``--start-from
nothing`` is refused). It uses the derived settings ``dim``, ``motion``,
``process_noise``, ``measurement_noise``, ``p_d``, ``p_g`` (each particle's
likelihood is truncated to its gate of probability P_G; 1 = no gate),
``clutter_density`` (a number) and ``seed`` (of its random generator); any
other ``[tracker]`` key is refused. The outputs are the same files; the
existence column is 1, ``metrics.json`` has a ``particle`` section (weights
method, particles, seconds in coefficients and derivatives, effective sample
sizes) instead of ``association``.
Checkpoints are not supported for it: ``--checkpoint``, ``--checkpoint-every``
and ``--resume`` are refused (the checkpoint format holds Kalman tracks).

Checkpoints: with ``checkpoint=FILE`` the rows since the last checkpoint are
committed as a part and then the tracker state is saved, every
``checkpoint_every`` scans and at the end (:meth:`JPDATracker.save`, with the
run's bookkeeping — inputs, output directory and format, committed parts,
cluster timings — in the same checksummed file). ``resume=FILE`` checks that
the checkpoint belongs to this run, drops whatever was written after it and
continues with the next scan, so a run killed at any instant and resumed writes
exactly the tracks and metrics of an uninterrupted one. ``jointtrack run
--resume FILE`` needs no other flag: the inputs come from the checkpoint.
After the last scan the outputs are written in a finishing phase that resumes
too: each output once, in its final form, atomically, recorded in the
checkpoint (:mod:`~jointtrack.experiments.writers`); a resume there writes the
outputs not yet recorded. Resumed, the outputs equal an uninterrupted run's but
for the wall-clock fields of ``timing`` and, after a kill while tracking,
``n_scans_this_run`` (the scans of the last process that tracked any).
The committed parts (``OUT/.tracks-parts/``) stay only while the checkpoint
can continue the run (stopped early by ``max_scans``, killed, or failed after a
checkpoint); a run that has processed every scan and written every output, and
a run without a checkpoint that fails, removes them. Resuming a run that has
written every output raises :class:`~jointtrack.experiments.writers.RunAlreadyComplete`
(``jointtrack run --resume``: "already complete, nothing to do", exit 0); one
whose outputs were removed afterwards is an error naming them.

Hints where the settings are surely wrong (a warning on the console and a note in
``metrics.json``): a clutter density that expects more than
:data:`CLUTTER_HINT_FACTOR` times as many false returns per scan, over the
detections' bounding box, as the scans hold returns (:func:`clutter_hint`; not
for an estimated density, nor per-sensor or per-second densities), and sensors
of the detections without a ``[sensors.ID]`` table (they take the ``[tracker]``
sensor; the warning says which settings). ``jointtrack run --checkpoint FILE``
without ``--resume`` refuses a FILE that can still continue a run (saying how to
resume it) or that is not a checkpoint.

The pieces: :mod:`~jointtrack.experiments.config` (config file, scenarios,
tracker settings), :mod:`~jointtrack.experiments.writers` (tracks file,
checkpoint bookkeeping), :mod:`~jointtrack.experiments.summary` (metrics dict,
summary tables); this module holds the run loop. Their names are re-exported
here.
"""

from __future__ import annotations

import json
import logging
import math
import os
import time
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from jointtrack.association.budget import reason_kind
from jointtrack.errors import CoincidentReturnsWarning
from jointtrack.experiments.config import (  # noqa: F401 - re-exported
    _METRIC_KEYS,
    _TABLES,
    JPDA_KINDS,
    POISSON_KINDS,
    SCENARIOS,
    STARTS,
    TRACKER_KINDS,
    TRACKER_OPTION_KEYS,
    TRUTH_START_NOTE,
    RunConfig,
    RunConfigError,
    _check_tracker_keys,
    _describe,
    _is_int,
    _one_line,
    check_kind_keys,
    check_sensor,
    default_start,
    detections_extent,
    from_nothing_overrides,
    jpda_kind_overrides,
    kind_of_config,
    load_config,
    make_pmbm_config,
    make_scenario,
    make_sensors,
    make_tracker_config,
    particle_options,
    scenario_metric_settings,
    scenario_tracker_settings,
    sensor_label,
    sensor_tables_for,
    sensor_tables_from_run,
    sensor_tables_to_run,
    start_setting,
    start_truth_particles,
    start_truth_tracks,
    steady_state_covariance,
    tracker_kind,
)
from jointtrack.experiments.summary import (  # noqa: F401 - re-exported
    _cluster_timing,
    _fmt,
    _ospa_mean,
    _run_metrics,
    _version,
    cluster_rows,
    count_cluster,
    particle_metrics,
    print_summary,
    start_description,
    summary_tables,
)
from jointtrack.experiments.writers import (  # noqa: F401 - re-exported
    FORMATS,
    PARQUET_ROW_GROUP_SCANS,
    ExtraOutputs,
    RunAlreadyComplete,
    _save_checkpoint,
    _track_columns,
    _TrackWriter,
    atomic_output,
    check_run_phase,
    fault,
    mode_names_of,
)
from jointtrack.io import Detections, to_jsonable, write_metrics
from jointtrack.io._files import file_sha256
from jointtrack.scenarios import run_name
from jointtrack.trackers import JPDATracker, TrackerConfig
from jointtrack.trackers.pmbm_config import PMBMConfig
from jointtrack.trackers.state_io import StateFileError, read_run, read_state

__all__ = [
    "SCENARIOS",
    "RunConfig",
    "RunConfigError",
    "check_sensor",
    "load_config",
    "load_tracker",
    "make_scenario",
    "make_tracker_config",
    "particle_options",
    "print_summary",
    "run_detections",
    "run_scenario",
    "scenario_metric_settings",
    "scenario_tracker_settings",
    "start_truth_tracks",
    "steady_state_covariance",
    "tracker_kind_of",
]


#: metrics.json ``scoring`` of a built-in scenario: its truth has a row at every scan time
SCORING_SCAN_TIMES = {
    "rule": "scan-times",
    "description": "tracks and truth compared at every scan time (the scenario's truth has "
    "a row for each target at each scan time)",
}
#: metrics.json ``scoring`` of a detections run with a truth (:func:`_truth_at_scans`)
SCORING_INTERPOLATED = {
    "rule": "scan-times-interpolated-truth",
    "description": "tracks scored at every scan time; a target is present from its first "
    "truth row's time to its last, at its truth row there or linearly interpolated between "
    "its rows before and after (e.g. a second sensor's scans between the truth's times)",
}


@dataclass
class _Source:
    """What is being tracked: scans, plus the truth when simulated."""

    identity: dict
    times: np.ndarray
    scans: tuple
    dim: int
    truth: tuple | None = None  # (times, ids, positions)
    truth_states: tuple | None = None  # per scan, for plots
    truth_ids: tuple | None = None
    origins: tuple | None = None
    region: np.ndarray | None = None
    x0: np.ndarray | None = None  # start tracks from these states at the first scan
    sigma: float = 10.0
    # the scenario's own GOSPA/OSPA "c" and "p" (scenario_metric_settings): used where
    # [metrics] does not set them; kept apart from metrics_opts so that a checkpoint
    # holds only what the user set and --resume --config compares like with like
    metric_defaults: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    # how the PMB/PMBM settings were chosen (birth model, clutter estimate): saved in the
    # checkpoint, since a resumed run takes the checkpoint's settings as they are
    tracker_notes: list = field(default_factory=list)
    kind: str = "position"  # of the scans: "position" or "range-bearing" ([r, θ] rows)
    sensor_ids: tuple | None = None  # per scan, the sensor id of each detection
    # metrics.json "scoring" (with a truth): how truth and tracks are compared
    scoring: dict | None = field(default_factory=lambda: dict(SCORING_SCAN_TIMES))


def _cartesian(scans, sensor_position) -> list:
    """Range–bearing scans ``[r, θ]`` as Cartesian positions ``s + r (cos θ, sin θ)``."""
    s = np.asarray(sensor_position, dtype=float)
    out = []
    for z in scans:
        z = np.asarray(z, dtype=float).reshape(-1, 2)
        out.append(s + np.column_stack([z[:, 0] * np.cos(z[:, 1]), z[:, 0] * np.sin(z[:, 1])]))
    return out


def _register_sensors(trk, src, tables: dict, warn) -> None:
    """A tracker sensor per id of the detections' sensor column ([sensors] table or default).

    With a file's detections (``src.detections``, set by :func:`run_detections`)
    each sensor's type must match the kind of its rows (position rows: a
    position sensor; range–bearing rows: a range–bearing one), else a
    :class:`RunConfigError` naming the sensor; the sensors are kept in
    ``src.tracker_sensors`` (id → Sensor; ``None``: the configuration's) for
    :func:`_step_scan` to move a moving sensor to each scan's position.
    """
    det = getattr(src, "detections", None)
    src.tracker_sensors = {None: trk.default_sensor}
    if src.sensor_ids is None:
        if tables:
            warn("the [sensors] tables are ignored: the detections have no sensor column")
        return
    present = sorted({i for ids in src.sensor_ids for i in ids.tolist()})
    made = make_sensors(tables, trk.config, trk.state_dim)
    for sid in sorted(set(made) - set(present)):
        warn(f"[sensors] sensor {sid} does not occur in the detections")
    untabled = [sid for sid in present if sid not in made]
    if untabled:
        warn(_untabled_sensors_note(untabled, bool(made), trk.config))
    kinds = det.sensor_kinds() if det is not None else {}
    for sid in present:
        sensor = made.get(sid, trk.default_sensor)
        want = kinds.get(sid)
        if want is not None and sensor.kind != want:
            where = (
                f"its [sensors] table has type = {sensor.kind!r}"
                if sid in made
                else f"it has no [sensors] table and the [tracker] sensor is {sensor.kind!r}"
            )
            raise RunConfigError(
                f"sensor {sid}: the detections give it {want} rows but {where}; "
                f'set type = "{want}" in its [sensors] table (id = {sid})'
            )
        trk.add_sensor(sid, sensor)
        src.tracker_sensors[sid] = sensor


def _untabled_sensors_note(ids: list, any_tables: bool, cfg) -> str:
    """The warning for sensors of the detections without a ``[sensors.ID]`` table:
    which they are and the ``[tracker]`` sensor settings they take instead."""
    names = ", ".join(str(i) for i in ids)
    if cfg.sensor == "range-bearing":
        model = (
            f"range-bearing at {list(cfg.sensor_position)}, range_noise {cfg.range_noise:g}, "
            f"bearing_noise {cfg.bearing_noise:g}"
        )
    else:
        model = f"position, measurement_noise {cfg.measurement_noise}"
    lam = "estimated" if cfg.clutter_density is None else f"{cfg.clutter_density:g}"
    which = (
        f"sensor(s) {names} of the detections have no [sensors.ID] table (the config has "
        "tables for other sensors)"
        if any_tables
        else f"the detections name sensor(s) {names} but the config has no [sensors.ID] tables"
    )
    return (
        f"{which}: they take the [tracker] sensor ({model}, p_d {cfg.p_d:g}, "
        f"clutter_density {lam}); give a sensor that differs its own table, e.g. "
        f"[sensors.{ids[0]}]"
    )


#: a configured clutter density that expects more than this many times the returns the
#: scans hold per scan is surely in another unit (issue 25: 1000× off gave no track)
CLUTTER_HINT_FACTOR = 10.0


def clutter_hint(scans, kind: str, clutter_density) -> str | None:
    """A warning when ``clutter_density`` expects far more false returns than there are
    returns at all, else None.

    The expected count per scan is λ times the volume of the detections' bounding
    box in measurement coordinates (area for 2-D positions, range × bearing for
    range–bearing rows); more than :data:`CLUTTER_HINT_FACTOR` times the mean
    number of detections per scan cannot be right (every return would be taken for
    clutter: no track confirms). A density well below the data's is not flagged:
    clean data (few false returns) is legitimate. None for an estimated density.
    """
    if clutter_density is None or not len(scans):
        return None
    dims = [np.shape(z)[-1] for z in scans if len(z)]
    if not dims:
        return None
    extent, per_scan = detections_extent(scans, dims[0])
    if extent is None:
        return None
    expected = float(clutter_density) * float(np.prod(extent))
    if not expected > CLUTTER_HINT_FACTOR * per_scan:
        return None
    if kind == "range-bearing":
        unit = "unit range × radian"
        box = f"range {extent[0]:,.4g} × bearing {extent[1]:.3g} rad"
    else:
        unit = "unit area" if len(extent) == 2 else "unit volume"
        box = " × ".join(f"{axis} {e:,.4g}" for axis, e in zip("xyz", extent, strict=False))
    return (
        f"clutter_density {clutter_density:g} per {unit} expects {expected:,.0f} false "
        f"returns per scan over the detections' extent ({box}), but the scans hold "
        f"{per_scan:,.3g} detections on average: check its units (false returns per scan "
        f"per {unit} of the detections' coordinates, e.g. per m² for positions in m, not "
        "per km² or per scan); with so much clutter expected every return looks like "
        "clutter: tracks are lost and new ones do not confirm"
    )


def _clutter_note(src, cfg, sensor_tables: dict) -> str | None:
    """:func:`clutter_hint` for a run, where one density applies to every scan."""
    det = getattr(src, "detections", None)
    if (
        getattr(cfg, "reporting", "scan") != "scan"  # per second, not per scan
        or getattr(cfg, "measure_velocity", False)  # per unit area × velocity area
        or (det is not None and det.kind == "mixed")  # no one measurement space
        or any("clutter_density" in t for t in sensor_tables.values())  # per sensor
    ):
        return None
    return clutter_hint(src.scans, src.kind, getattr(cfg, "clutter_density", None))


_MOVING = ("moving sensor",)  # the tracker's key of an id-less moving sensor


def _step_scan(trk, t: float, src, k: int) -> list:
    """The scan(s) at time index k: one per sensor in id order (sequential-update JPDA).

    A file's detections (``src.detections``) are stepped as they are — each
    (time, sensor) scan with its own kind of rows (mixed files), a moving
    sensor's scan with its sensor placed at that scan's position (p_d and
    clutter density kept); ``src.scans`` may then hold their plotting form.
    """
    det = getattr(src, "detections", None)
    if det is not None:
        out = []
        for sid, _kind, z, pos in det.sensor_scans(k):
            if pos is None:
                extra = _report_fields(trk, src, det, k, sid)
                out.append(
                    trk.step(t, z, **extra) if sid is None else trk.step(t, z, sensor=sid, **extra)
                )
                continue
            # id None is the configuration's own sensor, which cannot be replaced; a
            # tuple key cannot clash with a sensor id (an int or a str)
            key = _MOVING if sid is None else sid
            try:
                trk.add_sensor(key, src.tracker_sensors[sid].at(pos))
            except ValueError as exc:
                raise RunConfigError(f"sensor {sid}: {_one_line(exc)}") from None
            out.append(trk.step(t, z, sensor=key))
        return out
    z = src.scans[k]
    if src.sensor_ids is None or not len(src.sensor_ids[k]):
        return [trk.step(t, z)]
    ids = src.sensor_ids[k]
    return [trk.step(t, z[ids == sid], sensor=sid) for sid in np.unique(ids).tolist()]


def _last_in_window(times, k: int, interval: float) -> bool:
    """Whether scan k is the last one of its window ((j − 1)·interval, j·interval].

    The windows end *at* the multiples, as the self-report scoring's (which takes
    each track's latest estimate in (t − window, t] at t = j·window): a scan exactly
    on a multiple belongs to the window ending there. Windows [.., j·interval)
    would write, for reports on whole multiples (OpenSky states every 10 s), the
    tracks one scan before each scoring instant — 2.3 km behind an airliner.
    """
    if k + 1 >= len(times):
        return True
    return math.ceil(times[k + 1] / interval) > math.ceil(times[k] / interval)


def _report_fields(trk, src, det, k: int, sid) -> dict:
    """The ``labels`` / ``velocities`` of scan k's rows of sensor ``sid`` for ``trk.step``.

    Given only to trackers that take them (``REPORT_FIELDS``): labels when the
    run associates by label (:func:`jointtrack.experiments.realdata.run_reports`),
    velocities (reported, e.g. AIS speed and course) always.
    """
    fields = getattr(trk, "REPORT_FIELDS", ())
    rows = slice(None) if sid is None else det.sensors[k] == sid
    extra = {}
    if "labels" in fields and det.labels is not None and getattr(src, "labels_to_tracker", False):
        extra["labels"] = det.labels[k][rows]
    if "velocities" in fields and det.velocities is not None:
        extra["velocities"] = det.velocities[k][rows]
    return extra


def _tracker_class(kind: str):
    """The tracker class of a kind (:data:`~jointtrack.experiments.config.TRACKER_KINDS`)."""
    if kind in POISSON_KINDS:
        from jointtrack.trackers.pmbm import PMBMTracker, PMBTracker

        return PMBMTracker if kind == "pmbm" else PMBTracker
    return JPDATracker


def tracker_kind_of(trk) -> str:
    """The kind a tracker runs: ``pmb``/``pmbm``, or ``jpda``/``jipda`` by its ``existence``."""
    return trk.KIND if trk.KIND in POISSON_KINDS else kind_of_config(trk.config)


def load_tracker(path):
    """The tracker saved in a state file, of the kind the file names (``jpda`` when it
    names none: files of the JPDA tracker have no kind); errors as ``load``."""
    _, _, scalars, _ = read_state(path)
    kind = scalars.get("tracker", "jpda")
    if kind not in ("jpda", *POISSON_KINDS):
        raise StateFileError(f"{path}: holds the state of an unknown tracker kind {kind!r}")
    return _tracker_class(kind).load(path)


def _check_writable(path: Path, flag: str) -> None:
    """Fail before the first scan if ``path`` cannot be written (not after ten scans)."""
    parent = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise RunConfigError(f"{flag} {path} is a directory; give a file name")
    if not parent.is_dir():
        raise RunConfigError(f"{flag} {path}: the directory {parent} does not exist")
    if not os.access(parent, os.W_OK):
        raise RunConfigError(f"{flag} {path}: the directory {parent} is not writable")


def _run_inputs(inputs):
    """A checkpoint's recorded inputs with the scenario's run name (checkpoints written
    before runs recorded it hold the generator's name, e.g. ``many_targets``)."""
    if isinstance(inputs, dict) and isinstance(inputs.get("scenario"), str):
        return {**inputs, "scenario": run_name(inputs["scenario"])}
    return inputs


def _check_resume(resume: Path, info, trk, src, identity, out_dir: Path, fmt: str) -> None:
    """The checkpoint belongs to this run: same inputs, output directory and format."""
    if not isinstance(info, dict) or "parts" not in info:
        raise RunConfigError(
            f"{resume}: a tracker state without the bookkeeping of a jointtrack run "
            "(saved by JPDATracker.save?); it cannot resume `jointtrack run`"
        )
    saved = _run_inputs(info.get("inputs"))
    if (
        isinstance(saved, dict)
        and saved != identity
        and {k: v for k, v in saved.items() if k != "fit"}
        == {k: v for k, v in identity.items() if k != "fit"}
    ):

        def fit_text(entry) -> str:
            fitted = entry.get("fitted") if isinstance(entry, dict) else None
            if fitted is None:
                return "without the fitted model (--no-fit)" if entry else "without a fit"
            if not fitted:  # the fit ran and every key fell back to its default
                return "with a fit that set no value (every key at its default)"
            return "with the fitted " + ", ".join(f"{k} = {v}" for k, v in fitted.items())

        raise RunConfigError(
            f"{resume}: the checkpoint's run was made {fit_text(saved.get('fit'))}; this run "
            f"{fit_text(identity.get('fit'))} (the fit is part of the run: resume with the "
            "same --no-fit choice and [tracker] keys)"
        )
    if saved != identity:
        raise RunConfigError(
            f"{resume}: the checkpoint was made for {_describe(info.get('inputs'))}, "
            f"not {_describe(identity)}"
        )
    if Path(info["out_dir"]) != out_dir.resolve():
        raise RunConfigError(
            f"{resume}: the run writes to {info['out_dir']}; resuming into {out_dir} would "
            f"score only the scans after the checkpoint — omit --out or use --out "
            f"{info['out_dir']}"
        )
    if info.get("format") != fmt:
        raise RunConfigError(
            f"{resume}: the run writes {info.get('format')} tracks; --format {fmt} conflicts"
        )
    if trk.config.dim != src.dim:
        raise RunConfigError(
            f"{resume}: the checkpoint tracks {trk.config.dim}-D data, these scans are {src.dim}-D"
        )
    if (trk.config.sensor == "range-bearing") != (src.kind == "range-bearing"):
        raise RunConfigError(
            f"{resume}: the checkpoint's tracker reads {trk.config.sensor} measurements, "
            f"these scans are {src.kind} detections"
        )


def _warm_up(cfg: TrackerConfig, particle=None) -> None:
    """Load / compile the association kernels before anything is timed.

    numba loads each compiled kernel on its first call (≈ 0.1 s), which would
    otherwise be charged to the first cluster of that kind. ``particle``: the
    particle tracker's config; its weights method is run on small scans instead.
    """
    if particle is not None:
        from jointtrack.trackers.particle import jpda_particle_log_weights

        rng = np.random.default_rng(12345)
        for n, m in ((2, 3), (3, 6)):
            log_lik = np.log(rng.random((n, 8, m)))
            jpda_particle_log_weights(np.zeros(m), np.full((n, 8), 0.9), log_lik, particle.weights)
        return
    from jointtrack.association import marginals

    rng = np.random.default_rng(12345)
    if isinstance(cfg, PMBMConfig):  # the PMBM tracker ranks events by Murty on the LSAP
        from jointtrack.association.kbest import kbest_hypotheses

        kbest_hypotheses(rng.random((3, 4)) + np.eye(3, 4), np.full(3, 0.1), k=4)
    methods = {cfg.association, cfg.approximation}
    for n, m in ((2, 2), (3, 5), (5, 9), (8, 14)):
        L = rng.random((n, m)) * (rng.random((n, m)) < 0.6) + np.eye(n, m)
        miss = np.full(n, 0.1)
        for method in methods:
            opts = {"rng": np.random.default_rng(0)} if method == "mcmc" else {}
            try:
                marginals(L, miss, method=method, **opts)
            except ValueError:
                pass


def _check_particle_run(src: _Source, checkpoint, resume, sensors) -> None:
    """The particle tracker runs a known, fixed set of targets started from the truth."""
    if checkpoint is not None or resume is not None:
        flag = "--resume" if resume is not None else "--checkpoint"
        raise RunConfigError(
            f"{flag}: the particle tracker has no checkpoints (the checkpoint format holds "
            "Kalman tracks, not particle sets and their generator); run it without "
            "--checkpoint, --checkpoint-every and --resume"
        )
    if sensors:
        raise RunConfigError("the particle tracker takes no [sensors] tables")
    if getattr(src, "detections", None) is not None or src.truth_ids is None:
        raise RunConfigError(
            "the particle tracker runs on a built-in scenario: it starts every target from "
            "the true state at the first scan, which a detections file does not have"
        )
    if src.x0 is None or not len(src.x0):
        raise RunConfigError(
            "the particle tracker follows a known, fixed set of targets started from the "
            "truth at the first scan; it does not initiate tracks (--start-from nothing "
            "is for the Kalman JPDA tracker)"
        )
    first = np.sort(np.asarray(src.truth_ids[0]))
    for k, ids in enumerate(src.truth_ids):
        if not np.array_equal(np.sort(np.asarray(ids)), first):
            raise RunConfigError(
                f"the particle tracker follows a known, fixed set of targets, but in "
                f"{_describe(src.identity)} targets are born or die (the targets at scan {k} "
                f"are not the {len(first)} of the first scan); use the Kalman JPDA tracker"
            )


_POISSON_TRUTH_START = (
    "--start-from truth: the PMB/PMBM trackers start from their Poisson prior intensity "
    "of undetected targets, not from given tracks; use --start-from nothing (their default)"
)


def _run(
    src: _Source,
    cfg: TrackerConfig,
    out_dir,
    *,
    fmt: str = "csv",
    progress: bool = False,
    checkpoint=None,
    checkpoint_every: int = 10,
    resume=None,
    max_scans: int | None = None,
    metrics_opts: Mapping | None = None,
    console=None,
    plots: bool = True,
    sensors: Mapping | None = None,
    particle=None,
    kind: str | None = None,
    extra: ExtraOutputs | None = None,
    output_interval: float | None = None,
) -> dict:
    """The run loop and its finishing phase (see the module docstring and
    :mod:`~jointtrack.experiments.writers`); ``extra``: outputs a caller adds
    (:class:`~jointtrack.experiments.writers.ExtraOutputs`: a report run's lat/lon
    columns, metrics and map); ``output_interval`` (seconds): write the tracks only
    at the last scan at or before each multiple of it (one scan per report makes
    thousands of scans a minute); ``particle``: a
    :class:`~jointtrack.trackers.particle.ParticleConfig` to run the particle
    tracker instead of the Kalman JPDA tracker ``cfg``. ``kind``: ``"pmb"`` or
    ``"pmbm"`` with a :class:`PMBMConfig` ``cfg``; for a :class:`TrackerConfig`
    ``jpda``/``jipda`` (None: by its ``existence``). On resume the kind comes from
    the checkpoint; a ``kind`` that differs is an error. A resume of a run that has
    written every output raises :class:`~jointtrack.experiments.writers.RunAlreadyComplete`.
    """
    from rich.console import Console

    wall0 = time.perf_counter()
    console = console or Console(quiet=True)
    notes = list(src.notes) + list(src.tracker_notes)
    extra = extra or ExtraOutputs()

    def warn(msg: str) -> None:
        notes.append(msg)
        console.print(
            f"warning: {msg}", style="yellow", markup=False, highlight=False, soft_wrap=True
        )

    if fmt not in FORMATS:
        raise RunConfigError(f"unknown format {fmt!r}; choose csv or parquet")
    if particle is not None:
        _check_particle_run(src, checkpoint, resume, sensors)
    if checkpoint_every < 1:
        raise RunConfigError(f"--checkpoint-every must be ≥ 1, got {checkpoint_every}")
    if max_scans is not None and max_scans < 1:
        raise RunConfigError(f"--max-scans must be ≥ 1, got {max_scans}")
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise RunConfigError(f"--out {out_dir} is a file, not a directory")
    out_dir.mkdir(parents=True, exist_ok=True)
    checkpoint = Path(checkpoint) if checkpoint is not None else None
    if checkpoint is not None:
        _check_writable(checkpoint, "--checkpoint")
    identity = to_jsonable(src.identity, fallback="text")
    metrics_opts = dict(metrics_opts or {})

    clusters: list = []  # [n_tracks, n_measurements, seconds] of multi-track confirmed clusters
    fallbacks: dict = {}  # reason → clusters solved by the approximation instead
    tiers: dict = {}  # method (approximation, lbp-sparse, pda) → those clusters
    solved: dict = {}  # every multi-track cluster by kind, method, reason (count_cluster)
    tally_complete = True  # solved covers every scan of the run
    coincident = [0]  # returns dropped as exact repeats of another of their scan
    continued = [0]  # new tracks that took a deleted track's id (id_continuation)
    elapsed_before = 0.0
    start = 0
    K = len(src.times)
    stop = K if max_scans is None else min(K, int(max_scans))
    # the outputs of the finishing phase, in the order they are written (metrics.json,
    # which names the others, last) and those already written in their final form
    outputs = _output_names(fmt, plots, src.truth is not None, extra)
    done: list = []
    # scans tracked by the last process that tracked any (metrics n_scans_this_run): a
    # resume that only finishes reports the count of the process that tracked
    tracked_before = 0
    writer = None

    def new_writer(directory, config):
        """The tracks writer of this run into ``directory`` (IMM mode columns of ``config``)."""
        return _TrackWriter(
            directory,
            src.dim,
            fmt,
            scan_times=src.times,
            frame=extra.frame,
            mode_names=mode_names_of(config),
        )

    # whether a checkpoint file refers to the parts (a resumed run's, or one saved below):
    # a failed run removes them otherwise, as they cannot be needed
    checkpointed = [resume is not None]
    try:
        if resume is not None:
            resume = Path(resume)
            trk = load_tracker(resume)
            saved_kind = tracker_kind_of(trk)
            if kind is not None and kind != saved_kind:
                raise RunConfigError(
                    f"{resume}: the checkpoint holds the state of a {saved_kind} tracker, but "
                    f"this run asks for the {kind} tracker; resume without --tracker (the "
                    "kind comes from the checkpoint) or start a new run"
                )
            kind = saved_kind
            info = read_run(resume)
            if not src.tracker_notes and isinstance(info, dict):
                src.tracker_notes = [str(n) for n in info.get("tracker_notes") or []]
                notes[len(src.notes) :] = src.tracker_notes + notes[len(src.notes) :]
            _check_resume(resume, info, trk, src, identity, out_dir, fmt)
            check_run_phase(resume, info)
            given = info.get("out_dir_given")
            if isinstance(given, str) and Path(given).resolve() == out_dir.resolve():
                # the directory as the run was first given it (--resume passes the
                # checkpoint's absolute one): metrics.json names the files as before
                out_dir = Path(given)
            writer = new_writer(out_dir, trk.config)
            clusters = list(info.get("clusters", []))
            fallbacks.update(info.get("fallbacks", {}))
            tiers.update(info.get("fallback_tiers", {}))
            # absent in older checkpoints: a tally of the resumed scans alone would
            # undercount, so such a run reports no association.clusters
            tally_complete = "cluster_tally" in info
            solved.update(info.get("cluster_tally", {}))
            coincident[0] = int(info.get("coincident_returns", 0))
            continued[0] = int(info.get("continued_ids", 0))
            elapsed_before = float(info.get("elapsed_seconds", 0.0))
            tracked_before = int(info.get("n_scans_this_run", 0))
            if type(trk.config) is not type(cfg):
                warn(f"{resume}: continuing with the checkpoint's {kind} tracker settings")
            elif trk.config != cfg:
                diff = sorted(k for k, v in cfg.to_dict().items() if trk.config.to_dict()[k] != v)
                warn(
                    f"{resume}: continuing with the checkpoint's tracker settings "
                    f"(differ in: {', '.join(diff)})"
                )
            cfg = trk.config
            if trk.time is not None:
                start = int(np.searchsorted(src.times, trk.time, side="right"))
            if start > stop:
                raise RunConfigError(
                    f"{resume}: the checkpoint has processed {start} scans, more than "
                    f"--max-scans {max_scans}; resume without --max-scans or with one of at "
                    f"least {start}"
                )
            done = _outputs_already_written(resume, info, writer, outputs, start, stop, K)
            writer.resume(int(info["parts"]), keep=done)
            if checkpoint is None:
                checkpoint = resume  # keep checkpointing where the run was checkpointed
        else:
            writer = new_writer(out_dir, cfg)
            writer.start_fresh()
            dt = float(np.median(np.diff(src.times))) if len(src.times) > 1 else 1.0
            if particle is not None:
                from jointtrack.trackers.particle import ParticleJPDATracker

                trk = ParticleJPDATracker(particle)
                start_truth_particles(trk, src.x0, dt)
            elif isinstance(cfg, PMBMConfig):
                if kind not in POISSON_KINDS:
                    raise RunConfigError(
                        f'a PMBMConfig runs the "pmb" or "pmbm" tracker, not kind {kind!r}'
                    )
                if src.x0 is not None:
                    raise RunConfigError(_POISSON_TRUTH_START)
                trk = _tracker_class(kind)(cfg)
            else:
                if kind is not None and kind != kind_of_config(cfg):
                    raise RunConfigError(
                        f"kind {kind!r} does not match the tracker settings (existence = "
                        f"{str(cfg.existence).lower()} is {kind_of_config(cfg)!r})"
                    )
                kind = kind_of_config(cfg)
                trk = JPDATracker(cfg)
                if src.x0 is not None and len(src.x0):
                    start_truth_tracks(trk, src.x0, dt)

        if hasattr(trk, "keep_history"):
            # the writer records the tracks (on disk): the tracker's own history would
            # only grow the memory of a long run
            trk.keep_history = False
        sensor_tables = {k: dict(v) for k, v in (sensors or {}).items()}
        if particle is None:
            _register_sensors(trk, src, sensor_tables, warn)
        hint = _clutter_note(src, trk.config if particle is None else cfg, sensor_tables)
        if hint:
            warn(hint)
        scan_weights: list = []  # particle tracker: per scan [coefficient s, derivative s, …]

        def run_info(n_parts: int, seconds: float, tracked: int, phase: str) -> dict:
            return {
                "inputs": identity,
                "out_dir": str(out_dir.resolve()),
                "out_dir_given": str(out_dir),
                "format": fmt,
                "checkpoint_every": int(checkpoint_every),
                "max_scans": None if max_scans is None else int(max_scans),
                "metrics_opts": to_jsonable(metrics_opts, fallback="text"),
                "parts": int(n_parts),
                "n_scans": int(trk.n_scans),
                "n_scans_this_run": int(tracked),
                "clusters": clusters,
                "fallbacks": dict(fallbacks),
                "fallback_tiers": dict(tiers),
                "cluster_tally": solved,
                "coincident_returns": coincident[0],
                "continued_ids": continued[0],
                "sensors": sensor_tables_to_run(sensor_tables),
                "tracker_notes": list(src.tracker_notes),
                "elapsed_seconds": seconds,
                # the finishing phase (writers): how far the outputs are
                "phase": phase,
                "stop": int(stop),
                "n_scans_total": int(K),
                "outputs": list(outputs),
                "outputs_done": list(done),
            }

        from jointtrack._console import progress_bar

        if start >= stop:
            pass  # nothing to track (a resume that only finishes): no kernels to load
        elif console.is_terminal or progress:
            with console.status(
                # measured first runs (empty numba cache): 47 s (issue 25's busy machine),
                # 342 s on 2 cores shared at load 10 (the same run compiled: 32 s)
                "loading the compiled kernels (the first run after install compiles them: "
                "a minute or more, several minutes on a busy machine)…"
            ):
                _warm_up(cfg, particle)
        else:
            _warm_up(cfg, particle)
        # one line per approximated cluster would flood the terminal: they are counted
        # per reason in metrics.json and the summary instead
        tracker_log = logging.getLogger("jointtrack.tracker")
        saved_level = tracker_log.level
        tracker_log.setLevel(logging.ERROR)
        loop0 = time.perf_counter()
        n_done = 0
        # likewise a warning per scan with exactly repeated returns (real data repeats
        # reports): counted in coincident_returns, one note after the run
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", CoincidentReturnsWarning)
            try:
                with progress_bar(console, unit="scans", enabled=progress, remaining=True) as bar:
                    task = bar.add_task("tracking", total=stop, completed=start)
                    for k in range(start, stop):
                        t = float(src.times[k])
                        for res in _step_scan(trk, t, src, k):
                            if particle is not None:
                                scan_weights.append(
                                    [
                                        res.coefficient_seconds,
                                        res.derivative_seconds,
                                        float(res.ess.mean()),
                                        float(res.ess.min()),
                                        max((c[1] for c in res.components), default=0),
                                    ]
                                )
                                continue
                            for (n_tr, n_me), sec, conf in zip(
                                res.cluster_sizes,
                                res.cluster_seconds,
                                res.cluster_confirmed,
                                strict=True,
                            ):
                                if conf:
                                    clusters.append([int(n_tr), int(n_me), float(sec)])
                            for (n_tr, n_me), reason, method, conf in zip(
                                res.cluster_sizes,
                                res.cluster_fallbacks,
                                res.cluster_methods,
                                res.cluster_confirmed,
                                strict=True,
                            ):
                                count_cluster(solved, conf, method, reason, n_tr, n_me)
                                if reason:
                                    # the reason's kind (exact_max_tracks, refused, dense_budget)
                                    # and the tier that solved the cluster
                                    key = reason_kind(reason)
                                    # tentative-track clusters (clutter-born, in heavy clutter)
                                    # apart from the confirmed ones the experiment is about
                                    key += "" if conf else ", tentative tracks"
                                    fallbacks[key] = fallbacks.get(key, 0) + 1
                                    tier = method + ("" if conf else ", tentative tracks")
                                    tiers[tier] = tiers.get(tier, 0) + 1
                            coincident[0] += res.n_coincident
                            continued[0] += res.n_continued
                        if output_interval is None or _last_in_window(
                            src.times, k, output_interval
                        ):
                            writer.write_scan(t, res)  # the tracks after the time's last sensor
                        fault("scan", k)
                        n_done += 1
                        if checkpoint is not None and trk.n_scans % checkpoint_every == 0:
                            # part first, then the checkpoint that counts it (see writers)
                            n_parts = writer.commit()
                            fault("part", k)
                            seconds = elapsed_before + time.perf_counter() - loop0
                            _save_checkpoint(
                                trk, checkpoint, run_info(n_parts, seconds, n_done, "tracking")
                            )
                            checkpointed[0] = True
                            fault("checkpoint", k)
                        bar.update(task, advance=1)
                # a resume that only finishes adds no time (the metrics keep the loop's)
                loop_seconds = time.perf_counter() - loop0 if n_done else 0.0
                tracked = n_done if n_done else tracked_before
                total_loop = elapsed_before + loop_seconds
                if checkpoint is None:
                    # nothing can resume from the parts: the rows are in memory
                    writer.discard_parts()
                elif n_done or resume is not None:
                    # every scan is committed: from here on the outputs are written, each
                    # recorded in the checkpoint once it is in place (see writers)
                    n_parts = writer.commit_pending()
                    _save_checkpoint(
                        trk, checkpoint, run_info(n_parts, total_loop, tracked, "finishing")
                    )
                    checkpointed[0] = True
                    fault("finishing", 0)
            except KeyboardInterrupt:
                writer.snapshot()
                raise
            finally:
                writer.close()
                tracker_log.setLevel(saved_level)
    except BaseException:
        if writer is not None and not checkpointed[0]:
            writer.discard_parts()
        raise

    if coincident[0]:
        notes.append(
            f"{coincident[0]} return(s) repeated another return of their scan exactly "
            "(identical measurement vectors) and were treated as one"
        )
    if continued[0]:
        notes.append(
            f"{continued[0]} new track(s) took the id of a track deleted at most "
            f"{getattr(cfg, 'id_continuation', 0.0):g} s before or losing its target "
            "(id_continuation: a target's track that died and was born again keeps its id)"
        )

    # ------------------------------------------------------------ metrics
    tracks = writer.table()
    scan_times = src.times[:stop]
    output_times = None  # the scans whose tracks are written, when not all of them
    if output_interval is not None:
        output_times = [
            float(src.times[k])
            for k in range(stop)
            if _last_in_window(src.times, k, output_interval)
        ]
    metrics, series, truth = _run_metrics(
        src,
        cfg,
        identity,
        tracks,
        writer.path,
        stop,
        tracked,
        clusters,
        total_loop,
        metrics_opts,
        notes,
        output_times=output_times,
    )

    if particle is not None:
        particle_metrics(metrics, particle, scan_weights)
    else:
        metrics["tracker"] = {"kind": kind, **metrics["tracker"]}
        metrics["association"] = {
            "method": cfg.association,
            "approximation": cfg.approximation,
            "fallbacks": dict(sorted(fallbacks.items())),
            "fallback_tiers": dict(sorted(tiers.items())),
            "exact_max_tracks": getattr(cfg, "exact_max_tracks", None),
            "exact_max_bits_tentative": getattr(cfg, "exact_max_bits_tentative", None),
            "max_ranking_work": getattr(cfg, "max_ranking_work", None),
            **({"clusters": cluster_rows(solved)} if tally_complete else {}),
            "coincident_returns": coincident[0],
            "continued_ids": continued[0],
            "fallbacks_note": "clusters solved by the approximation instead of the configured "
            "method, by reason (exact_max_tracks, exact_max_bits_tentative, refused by the exact "
            "engine's own limits, or "
            "dense_budget: too large for an N × M matrix; PMBM: ranking_truncated / "
            "ranking_merged past max_ranking_work), and in fallback_tiers by the "
            "method that solved them (the approximation, else lbp-sparse, else per-track "
            "pda); ', tentative tracks' marks clusters of tentative tracks. "
            "clusters: every multi-track cluster by kind of track, method and reason "
            "(empty when the configured method solved it), with its count and the range "
            "of its numbers of tracks and measurements. "
            "coincident_returns: returns dropped as exact repeats of another return of "
            "their scan. continued_ids: new tracks that took the id of a track deleted "
            "within id_continuation seconds or losing its target (JPDA/JIPDA)",
        }
    if extra.metrics is not None:
        extra.metrics(metrics, tracks)

    # ------------------------------------------------------------ outputs
    def draw_scene(path: Path) -> None:
        from jointtrack.experiments import plots as _plots

        scans, sensor = src.scans[:stop], None
        if src.kind == "range-bearing":
            sensor = cfg.sensor_position
            scans = _cartesian(scans, sensor)
        _plots.plot_scene(
            path,
            times=scan_times,
            scans=scans,
            origins=src.origins[:stop] if src.origins is not None else None,
            truth=truth,
            tracks=tracks,
            region=src.region,
            title=_describe(identity),
            sensor=sensor,
        )

    def draw_gospa(path: Path) -> None:
        from jointtrack.experiments import plots as _plots

        _plots.plot_gospa(path, series, title=_describe(identity))

    def write_metrics_file(path: Path) -> None:
        metrics["timing"]["total_seconds"] = time.perf_counter() - wall0
        write_metrics(metrics, path)

    # file name → (metrics.json "files" key, write(temporary path)), in `outputs` order
    steps = {
        writer.path.name: ("tracks", None),
        "scene.png": ("scene", draw_scene),
        "gospa.png": ("gospa", draw_gospa),
        **{name: (key, lambda p, d=draw: d(p, tracks)) for name, key, draw in extra.figures},
        "metrics.json": ("metrics", write_metrics_file),
    }
    files = {"tracks": str(writer.path), "metrics": str(out_dir / "metrics.json")}
    files.update((steps[n][0], str(out_dir / n)) for n in outputs[1:-1])
    metrics["files"] = files
    for i, name in enumerate(outputs):
        if name in done:
            continue  # written by the run this one resumes
        if name == writer.path.name:
            writer.write_tracks_file(stage=("write", i))
        else:
            with atomic_output(out_dir / name, ("write", i)) as tmp:
                steps[name][1](tmp)
        fault("output", i)
        done.append(name)
        if checkpoint is not None:
            _save_checkpoint(
                trk, checkpoint, run_info(writer.n_parts, total_loop, tracked, "finishing")
            )
            fault("recorded", i)
    if checkpoint is not None:
        _save_checkpoint(trk, checkpoint, run_info(writer.n_parts, total_loop, tracked, "done"))
        fault("done", 0)
    # the parts are kept only while a resume can extend the run (--max-scans)
    if checkpoint is not None and stop >= K:
        writer.remove_parts()
    return metrics


def _output_names(fmt: str, plots: bool, scored: bool, extra: ExtraOutputs) -> list[str]:
    """The files a run's finishing phase writes, in order: the tracks file first (the
    figures and metrics are computed from its rows), metrics.json (which names the
    others) last. ``scored``: the run has a truth (``gospa.png``)."""
    names = [f"tracks.{'csv' if fmt == 'csv' else 'parquet'}"]
    if plots:
        names.append("scene.png")
        if scored:
            names.append("gospa.png")
        names += [name for name, _, _ in extra.figures]
    return [*names, "metrics.json"]


def _outputs_already_written(resume, info, writer, outputs, start, stop, K) -> list[str]:
    """The outputs a resume keeps: those the checkpoint records as written in their final
    form and that are still there, when it resumes the finishing phase of the same
    scans (else none: the run tracks further and writes them all).

    Raises :class:`RunAlreadyComplete` when every output is there, and
    :class:`RunConfigError` naming the missing ones when they cannot be written again
    (a complete run removed its committed tracks).
    """
    phase = info.get("phase")
    recorded = info.get("outputs_done", [])
    saved_stop = info.get("stop")
    if phase is None and start >= K and not writer.parts_dir.is_dir():
        # a completed run of a jointtrack that did not record the phase
        phase, recorded, saved_stop = "done", list(outputs), K
    if start < stop or phase not in ("finishing", "done") or saved_stop != stop:
        return []
    done = [n for n in recorded if n in outputs and (writer.out_dir / n).is_file()]
    missing = [n for n in outputs if n not in done]
    scans = f"all {K} scans" if stop >= K else f"scans 1-{stop} of {K} (--max-scans {stop})"
    if not missing and phase == "done":
        if stop >= K:
            writer.remove_parts()  # what a removal killed half-way left behind
        path = writer.out_dir / "metrics.json"
        try:
            metrics = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise RunConfigError(f"{path} cannot be read ({exc}); start the run again") from None
        more = "" if stop >= K else "; resume without --max-scans to continue it"
        raise RunAlreadyComplete(
            f"{resume}: the run is complete ({scans}; its outputs are in "
            f"{writer.out_dir}): there is nothing to resume{more}",
            metrics,
        )
    if missing and not writer.parts_complete(int(info["parts"])):
        names = ", ".join(str(writer.out_dir / n) for n in missing)
        raise RunConfigError(
            f"{resume}: the run is complete ({scans}), but {names} "
            f"{'is' if len(missing) == 1 else 'are'} missing (removed after the run?); its "
            "committed tracks were removed when it completed, so the checkpoint cannot "
            "write them again: start the run again (without --resume)"
        )
    return done


def run_scenario(
    scenario="bojilov",
    config: TrackerConfig | Mapping | None = None,
    out_dir="jointtrack-out",
    fmt: str = "csv",
    progress: bool = False,
    *,
    seed: int = 0,
    scenario_kwargs: Mapping | None = None,
    start_from: str | None = None,
    start_from_truth: bool | None = None,
    checkpoint=None,
    checkpoint_every: int = 10,
    resume=None,
    max_scans: int | None = None,
    metrics_opts: Mapping | None = None,
    console=None,
    plots: bool = True,
    particle=None,
    tracker: str | None = None,
    pmbm: Mapping | None = None,
) -> dict:
    """Run the tracker on a built-in scenario, write the outputs, return the metrics dict.

    Parameters
    ----------
    scenario : a :class:`~jointtrack.scenarios.Scenario`, or a name
        (``bojilov | crossing | many | abreast | coalescence``) built with ``seed``
        and ``scenario_kwargs``.
    config : a :class:`TrackerConfig` (used as is) or a mapping of overrides on
        the settings derived from the scenario (:func:`scenario_tracker_settings`);
        ``None`` = the derived settings.
    out_dir : output directory (created).
    fmt : ``"csv"`` or ``"parquet"`` (tracks file).
    progress : show a rich progress bar over scans.
    start_from : ``"truth"`` (start confirmed tracks at the true states of the
        first scan) or ``"nothing"`` (the tracker initiates every track from the
        detections); default :func:`default_start` — truth for ``bojilov``
        (Bojilov et al.'s experiment), nothing otherwise.
    start_from_truth : the older spelling of ``start_from`` (True = ``"truth"``);
        when both are given they must agree.
    checkpoint, checkpoint_every, resume : see the module docstring.
    max_scans : process only the first ``max_scans`` scans (counted from the
        first scan of the scenario, also when resuming).
    metrics_opts : ``c`` (GOSPA/OSPA cut-off; default the scenario's own, see
        :func:`scenario_metric_settings`, else 5σ), ``p`` (2), ``switch_penalty`` (0).
    console : rich console for the progress bar and warnings.
    plots : write ``scene.png`` and ``gospa.png``.
    particle : run the particle JPDA tracker instead of the Kalman one: a
        :class:`~jointtrack.trackers.particle.ParticleConfig` (used as is), or
        a mapping of its ``weights`` and ``particles`` (the other settings come
        from ``config``, see :func:`particle_options` and the module
        docstring). Its start defaults to ``"truth"`` (the only one it takes).
    tracker : the kind of tracker: ``"jipda"`` (JPDA with JIPDA existence),
        ``"jpda"`` (JPDA with M-of-N confirmation), ``"pmb"`` or ``"pmbm"``; None = the
        JPDA tracker as ``config`` says (``existence``, default true). For ``pmb`` and
        ``pmbm`` ``config`` may also be a
        :class:`~jointtrack.trackers.pmbm_config.PMBMConfig` (used as is); else their
        settings are :func:`make_pmbm_config` of the derived JPDA settings, ``config``
        and ``pmbm`` (the ``[pmbm]`` table). They start from nothing.
    """
    kwargs = dict(scenario_kwargs or {})
    if isinstance(scenario, str):
        name = scenario
        scenario = make_scenario(name, seed, kwargs)
        identity = {"scenario": name, "seed": seed, "kwargs": kwargs}
    else:
        # the run name (many, not the generator's many_targets): --resume rebuilds it by name
        identity = {"scenario": run_name(scenario.name), "seed": scenario.seed, "kwargs": kwargs}
    start = start_setting(start_from, start_from_truth, "run_scenario:", noun="argument")
    kind = _check_kind(tracker, config, pmbm, particle)
    built = isinstance(config, TrackerConfig | PMBMConfig)
    start, over = start_settings(
        start, scenario.name, kind, {} if built else dict(config or {}), particle
    )
    if kind in POISSON_KINDS and start == "truth":
        raise RunConfigError(_POISSON_TRUTH_START)
    start_from_truth = start == "truth"
    notes = []
    if built:
        cfg = config
    else:
        cfg = make_tracker_config(scenario_tracker_settings(scenario), over)
    if kind in POISSON_KINDS and not isinstance(cfg, PMBMConfig):
        cfg, notes = make_pmbm_config(
            cfg,
            {} if isinstance(config, TrackerConfig) else dict(config or {}),
            pmbm,
            scenario=scenario,
            region=scenario.region,
            scans=scenario.detections,
        )
    if cfg.dim != scenario.dim:
        raise RunConfigError(
            f"[tracker] dim = {cfg.dim} but scenario {identity['scenario']} is {scenario.dim}-D"
        )
    check_sensor(cfg, "position", f"scenario {identity['scenario']}")
    if particle is not None:
        particle = _particle_config(particle, cfg)
    # the identity keeps the boolean spelling so that older checkpoints still resume
    identity["start_from_truth"] = start_from_truth
    sigma = float(math.sqrt(np.mean(np.diag(scenario.R))))
    src = _Source(
        identity=identity,
        times=scenario.times,
        scans=scenario.detections,
        dim=scenario.dim,
        truth=scenario.truth_table(),
        truth_states=scenario.truth_states,
        truth_ids=scenario.truth_ids,
        origins=scenario.origins,
        region=scenario.region,
        x0=scenario.truth_states[0] if start_from_truth else None,
        sigma=sigma,
        metric_defaults=scenario_metric_settings(scenario),
        tracker_notes=notes,
    )
    return _run(
        src,
        cfg,
        out_dir,
        fmt=fmt,
        progress=progress,
        checkpoint=checkpoint,
        checkpoint_every=checkpoint_every,
        resume=resume,
        max_scans=max_scans,
        metrics_opts=metrics_opts,
        console=console,
        plots=plots,
        particle=particle,
        kind=kind,
    )


def start_settings(
    start: str | None, scenario_name: str, kind: str | None, tracker: Mapping, particle=None
) -> tuple[str, dict]:
    """The start of a run on a built-in scenario and its ``[tracker]`` overrides.

    The start is :func:`resolved_start`; the overrides are ``tracker`` with the
    kind's ``existence`` (:func:`~jointtrack.experiments.config.jpda_kind_overrides`)
    and, when the run starts from nothing (not the particle tracker), the
    from-nothing settings for the keys ``tracker`` does not set
    (:func:`~jointtrack.experiments.config.from_nothing_overrides`). The one
    resolution :func:`run_scenario` and ``jointtrack run`` share: the CLI builds
    the TrackerConfig itself and hands it over, so the two must not each decide.
    """
    start = resolved_start(start, scenario_name, kind, particle)
    over = jpda_kind_overrides(kind, tracker)
    if start == "nothing" and particle is None:
        over = from_nothing_overrides(kind, over)
    return start, over


def resolved_start(start: str | None, scenario_name: str, kind: str | None, particle=None) -> str:
    """The start of a run on a built-in scenario: ``start`` when given, else the
    particle tracker's ``"truth"`` (it follows the targets it is started with), the
    Poisson trackers' ``"nothing"``, or :func:`default_start` of the scenario."""
    if start is not None:
        return start
    if particle is not None:
        return "truth"
    if kind in POISSON_KINDS:
        return "nothing"
    return default_start(scenario_name)


def _check_kind(tracker, config, pmbm, particle=None) -> str | None:
    """The tracker kind of a run from ``tracker`` and the config's type (module docstring).

    None for the particle tracker and for a JPDA run that names no kind (its
    ``existence`` decides); ``[pmbm]`` settings, JPDA-only keys with a Poisson kind
    and a PMBMConfig without one raise :class:`RunConfigError`.
    """
    if particle is not None:
        if tracker not in (None, "particle"):
            raise RunConfigError(f"tracker {tracker!r} and particle options: choose one")
        return None
    if tracker is not None and tracker not in (*JPDA_KINDS, *POISSON_KINDS):
        raise RunConfigError(
            f"tracker must be one of {', '.join((*JPDA_KINDS, *POISSON_KINDS))}, got {tracker!r}"
        )
    if isinstance(config, PMBMConfig):
        if tracker not in POISSON_KINDS:
            raise RunConfigError('a PMBMConfig needs tracker = "pmb" or "pmbm"')
        if pmbm:
            raise RunConfigError("pmbm settings with a PMBMConfig: put them in the PMBMConfig")
        return tracker
    table = {} if isinstance(config, TrackerConfig) or config is None else dict(config)
    check_kind_keys(tracker, table, dict(pmbm or {}), None)
    if isinstance(config, TrackerConfig) and tracker in JPDA_KINDS:
        if kind_of_config(config) != tracker:
            raise RunConfigError(
                f"tracker {tracker!r} but the TrackerConfig has existence = "
                f"{str(config.existence).lower()} ({kind_of_config(config)!r})"
            )
    return tracker


def _particle_config(particle, cfg: TrackerConfig):
    """A ParticleConfig from a ParticleConfig or a mapping of weights / particles on ``cfg``."""
    from jointtrack.trackers.particle import ParticleConfig

    if isinstance(particle, ParticleConfig):
        return particle
    if not isinstance(particle, Mapping):
        raise RunConfigError(
            f"particle must be a ParticleConfig or a mapping, got {type(particle).__name__}"
        )
    opts = dict(particle)
    unknown = sorted(set(opts) - {"weights", "particles"})
    if unknown:
        raise RunConfigError(
            f"particle: unknown option(s) {', '.join(unknown)} (known: weights, particles)"
        )
    if cfg.clutter_density is None:
        raise RunConfigError(
            "the particle tracker needs a known clutter density (its clutter terms "
            'a_m = Λ p_Λ(y_m)); clutter_density = "estimate" is for the Kalman tracker'
        )
    try:
        return ParticleConfig.from_tracker_config(cfg, **opts)
    except (TypeError, ValueError) as exc:
        raise RunConfigError(f"particle tracker: {_one_line(exc)}") from None


@dataclass
class _FileSource(_Source):
    """A :class:`_Source` of detections from a file, with their clock."""

    time_origin: str | None = None  # ISO-8601 timestamp of t = 0, or None (numeric times)


def _describe_time(t: float, time_origin: str | None) -> str:
    """``t = 12.5`` or, with a time origin, ``2026-11-23T10:00:12.5Z (t = 12.5 s)``."""
    if time_origin is None:
        return f"t = {t:g}"
    from jointtrack.io.times import format_timestamp, parse_origin

    _, ns0, aware = parse_origin(time_origin)
    return f"{format_timestamp(ns0 + round(t * 1e9), aware)} (t = {t:g} s)"


def _load_truth(truth, detections: Detections) -> tuple[tuple, dict, str]:
    """The truth of a detections run: ``(table, identity entries, name)``.

    ``truth``: a truth file (read with the detections' time origin) or a table
    ``(times, ids, positions)`` on the detections' clock.
    """
    from jointtrack.io import read_truth

    if isinstance(truth, (str, os.PathLike)):
        table = read_truth(truth, time_origin=detections.time_origin)
        path = Path(truth).resolve()
        # the file's content, so that a resume notices a changed file
        return table, {"truth": str(path), "truth_sha256": file_sha256(path)}, str(truth)
    try:
        tt, ti, tp = truth
    except (TypeError, ValueError):
        raise RunConfigError(
            "truth must be a truth file or a (times, ids, positions) table"
        ) from None
    tt = np.asarray(tt, dtype=np.float64).reshape(-1)
    ti = np.asarray(ti)
    tp = np.asarray(tp, dtype=np.float64)
    if tp.ndim != 2 or not (tt.size == ti.size == tp.shape[0]):
        raise RunConfigError(
            f"truth table: {tt.size} times, {ti.size} ids and positions of shape {tp.shape} "
            "do not form (times (R,), ids (R,), positions (R, dim))"
        )
    if not (np.all(np.isfinite(tt)) and np.all(np.isfinite(tp))):
        raise RunConfigError("truth table: times and positions must be finite")
    return (tt, ti.astype(np.int64), tp), {"truth": "<memory>"}, "the truth"


def _truth_at_scans(truth: tuple, times: np.ndarray, name: str, time_origin, dim: int):
    """The truth at the scan times, the number of its rows interpolated, and a note
    about the truth rows at times with no scan (or None).

    Tracks are scored at every scan time (:data:`SCORING_INTERPOLATED`). A
    target is there from its first row's time to its last; at a scan time in
    that span its position is its row at that time, else the linear
    interpolation between its rows just before and after (a scan of a second
    sensor between the truth's times: its tracks are compared with where the
    targets were, not with no target at all). Rows at a time with no scan are
    used only so; they are counted in the note. No row at any scan time is an
    error (a different clock or unit).
    """
    tt, ti, tp = truth
    if tp.shape[1] != dim:
        raise RunConfigError(
            f"{name} holds {tp.shape[1]}-D positions but the detections are {dim}-D"
        )
    times = np.asarray(times, dtype=np.float64)
    at_scan = np.isin(tt, times)
    if tt.size and not at_scan.any():
        raise RunConfigError(
            f"{name}: no truth row is at a scan time (truth from "
            f"{_describe_time(float(tt.min()), time_origin)} to "
            f"{_describe_time(float(tt.max()), time_origin)}, scans from "
            f"{_describe_time(float(times[0]), time_origin)} to "
            f"{_describe_time(float(times[-1]), time_origin)}); truth and tracks must be on "
            "one clock, so the truth needs rows at the detections' times (same unit and clock)"
        )
    note = None
    if not at_scan.all():
        off = tt[~at_scan]
        note = (
            f"{name}: {off.size} truth row(s) at {np.unique(off).size} time(s) with no scan "
            f"(first at {_describe_time(float(off[0]), time_origin)}) are not scored at their "
            "own times: tracks are scored at the scan times, where a target's position is its "
            "row or is interpolated between its rows"
        )
    out_t, out_i, out_p = [], [], []
    n_interpolated = 0
    order = np.lexsort((tt, ti))
    ids, first = np.unique(ti[order], return_index=True)
    bounds = [*first.tolist(), order.size]
    for j, tid in enumerate(ids.tolist()):
        rows = order[bounds[j] : bounds[j + 1]]
        t_id, p_id = tt[rows], tp[rows]
        same = np.flatnonzero(np.diff(t_id) == 0)
        if same.size:
            raise RunConfigError(
                f"{name}: target {tid} has two rows at "
                f"{_describe_time(float(t_id[same[0]]), time_origin)}"
            )
        inside = times[(times >= t_id[0]) & (times <= t_id[-1])]
        k = np.clip(np.searchsorted(t_id, inside, side="right") - 1, 0, t_id.size - 1)
        exact = t_id[k] == inside
        pos = p_id[k].copy()
        between = np.flatnonzero(~exact)
        if between.size:
            k0 = k[between]
            t0, t1 = t_id[k0], t_id[k0 + 1]
            # halves: no overflow of the differences for times near the float range
            w = ((inside[between] / 2 - t0 / 2) / (t1 / 2 - t0 / 2))[:, None]
            # a convex combination: no overflow for positions near the float range either
            pos[between] = p_id[k0] * (1.0 - w) + p_id[k0 + 1] * w
            n_interpolated += int(between.size)
        out_t.append(inside)
        out_i.append(np.full(inside.size, tid, dtype=np.int64))
        out_p.append(pos)
    if not out_t:
        return (tt[:0], ti[:0].astype(np.int64), tp[:0]), 0, note
    t_all, i_all, p_all = np.concatenate(out_t), np.concatenate(out_i), np.concatenate(out_p)
    o = np.lexsort((i_all, t_all))  # time order, then id
    return (t_all[o], i_all[o], p_all[o]), n_interpolated, note


def _check_resume_files(resume, identity: dict) -> None:
    """A clear error when an input file changed since the checkpoint, or the truth
    differs (checked before :func:`_check_resume`, whose message cannot tell)."""
    try:
        info = read_run(Path(resume))
    except Exception:  # noqa: BLE001 - the run loop reports an unreadable checkpoint
        return
    inputs = info.get("inputs") if isinstance(info, dict) else None
    if not isinstance(inputs, dict) or inputs.get("detections") != identity.get("detections"):
        return
    for key, sha in (("detections", "sha256"), ("truth", "truth_sha256")):
        if (
            inputs.get(key) == identity.get(key)
            and sha in inputs
            and sha in identity
            and inputs[sha] != identity[sha]
        ):
            raise RunConfigError(
                f"{resume}: the {key} file {identity[key]} changed since the checkpoint "
                "(its SHA-256 differs); start a new run instead of resuming"
            )
    was, now = inputs.get("truth"), identity.get("truth")
    if was != now:
        raise RunConfigError(
            f"{resume}: the checkpoint was made "
            + (f"with the truth {was}" if was else "without a truth")
            + ", this run has "
            + (f"the truth {now}" if now else "none")
            + " (--truth)"
        )


#: :func:`reporting_from_data`: a file is report-like when its times hold at most this
#: many returns on average ... (Solent AIS as time, lat, lon: 1.17; a scanning sensor
#: holds a return per target per scan)
REPORT_LIKE_RETURNS = 1.5
#: ... and the gaps between its times vary by at least this coefficient of variation
#: (std / mean; Poisson reporters' exponential gaps: 1; Solent AIS: 0.77; a scanning
#: sensor's fixed period: ≈ 0)
REPORT_LIKE_GAP_CV = 0.5
#: ... over at least this many times (fewer say nothing about a pattern)
REPORT_LIKE_MIN_TIMES = 20
#: what a report-like file runs with unless its [tracker] table sets the key: the
#: asynchronous reporting model and what it needs (TrackerConfig: p_survive_per
#: "second", a clutter density per m² per second; one false report per 10 km² per
#: ~3 hours, and a 0.9999 per second survival, a mean life of ~2.8 h, as the AIS
#: settings of jointtrack.experiments.realdata); report_interval stays the
#: TrackerConfig default (60 s: without identities one target's reports are unknown)
REPORT_LIKE_SETTINGS = {
    "reporting": "async",
    "p_survive_per": "second",
    "p_survive": 0.9999,
    "clutter_density": 1e-11,
}


def reporting_from_data(detections: Detections, table: Mapping, kind: str | None = None):
    """The ``[tracker]`` table with the asynchronous reporting model when the detections
    are report-like and the table does not set ``reporting``, and a note saying so.

    Report-like: position detections over at least :data:`REPORT_LIKE_MIN_TIMES`
    times holding at most :data:`REPORT_LIKE_RETURNS` returns per time on average,
    at gaps whose coefficient of variation is at least :data:`REPORT_LIKE_GAP_CV` —
    targets that report one at a time (AIS, ADS-B) rather than a sensor that scans
    them all. Such a file then runs with :data:`REPORT_LIKE_SETTINGS` (each key
    the table does not set). Returns ``(table, note)``; ``note`` is None and the
    table unchanged when the rule does not apply (the M-of-N ``kind`` "jpda", the
    table setting ``reporting`` or ``existence = false``, not report-like). The PMB
    and PMBM kinds get it as JIPDA does (their Bernoullis are detected as its tracks).
    """
    table = dict(table)
    scanning = kind not in (None, "jipda", *POISSON_KINDS) or table.get("existence") is False
    if scanning or "reporting" in table:
        return table, None
    times = detections.times
    if detections.kind != "position" or times.size < REPORT_LIKE_MIN_TIMES:
        return table, None
    per_time = detections.n_detections / times.size
    gaps = np.diff(times)
    cv = float(np.std(gaps) / np.mean(gaps))
    if per_time > REPORT_LIKE_RETURNS or cv < REPORT_LIKE_GAP_CV:
        return table, None
    set_here = {k: v for k, v in REPORT_LIKE_SETTINGS.items() if k not in table}
    table.update(set_here)
    text = ", ".join(f"{k} = {v!r}" for k, v in set_here.items())
    return table, (
        f"{text} from the data: irregular times (gap std/mean {cv:.2f} ≥ "
        f"{REPORT_LIKE_GAP_CV:g}), {per_time:.2f} returns per time (≤ {REPORT_LIKE_RETURNS:g}): "
        "targets reporting one at a time; report_interval "
        f"{table.get('report_interval', 60.0):g} s (default unless set); set reporting in "
        "[tracker] to choose"
    )


def settings_from_data(detections: Detections, table: Mapping, kind: str | None, fit: bool = True):
    """The ``[tracker]`` table a detections run uses: ``(table, notes, fit_identity)``.

    With ``fit`` (default) the model fitted to the data
    (:func:`jointtrack.experiments.fit.fit_tracker_settings`: every key the table
    does not set, each named in a note with its source); without it the table and
    :func:`reporting_from_data`'s asynchronous model for report-like files, as
    before the fit. ``fit_identity`` — the fitted values (None without the fit)
    and the notes — is part of the run's identity: a resume checks the values are
    the same, and a resume from the checkpoint alone takes both from it
    (:func:`saved_fit`), since its settings are the checkpoint's.
    """
    if not fit:
        out, note = reporting_from_data(detections, dict(table), kind)
        notes = [note] if note else []
        return out, notes, {"fitted": None, "notes": notes}
    from jointtrack.experiments.fit import fit_tracker_settings

    model = fit_tracker_settings(detections, dict(table), kind)
    notes = model.notes()
    ident = {"fitted": to_jsonable(model.identity(), fallback="text"), "notes": notes}
    return dict(model.table), notes, ident


def saved_fit(resume) -> tuple[dict | None, list]:
    """The fit identity and notes a checkpoint's run was made with (``(None, [])`` for
    a checkpoint without them)."""
    try:
        info = read_run(Path(resume))
    except Exception:  # noqa: BLE001 - the run loop reports an unreadable checkpoint
        return None, []
    inputs = info.get("inputs") if isinstance(info, dict) else None
    ident = inputs.get("fit") if isinstance(inputs, dict) else None
    if not isinstance(ident, dict):
        return None, []
    return ident, list(ident.get("notes") or [])


def run_detections(
    detections: Detections,
    config: TrackerConfig | Mapping | None = None,
    out_dir="jointtrack-out",
    fmt: str = "csv",
    progress: bool = False,
    *,
    truth=None,
    tracker: str | None = None,
    pmbm: Mapping | None = None,
    labels_to_tracker: bool = True,
    run_identity: Mapping | None = None,
    notes: list | None = None,
    fit: bool = True,
    **options,
) -> dict:
    """Run the tracker on detections (e.g. from :func:`jointtrack.io.read_detections`).

    Detections with ``labels`` give them to the tracker (association given the
    label) unless ``labels_to_tracker=False``; ``velocities`` seed new tracks.
    ``run_identity``: more JSON-able entries of the run's identity (how the
    detections were made), checked on resume. ``notes``: sentences for the
    metrics' notes and the summary (how the settings were chosen).

    Report-like detections (irregular times, about one return per time) run with
    the asynchronous reporting model unless ``config`` sets ``reporting``
    (:func:`reporting_from_data`, named in the notes).

    ``fit``: a ``config`` mapping's missing keys are fitted to the detections
    (:func:`settings_from_data`, each value's source in the notes; the fitted
    values are part of the run's identity); ``fit=False``: the defaults. A
    :class:`TrackerConfig` is used as given.

    ``config``: a :class:`TrackerConfig` or a mapping of overrides on the
    defaults (``dim`` is taken from the detections). Range–bearing detections
    (``detections.kind == "range-bearing"``) need ``sensor="range-bearing"``
    with ``sensor_position``, ``range_noise`` and ``bearing_noise``; position
    detections need the position sensor (else :class:`RunConfigError`); the
    tracks are Cartesian states either way. Other options as
    :func:`run_scenario` (``checkpoint``, ``checkpoint_every``, ``resume``,
    ``max_scans``, ``metrics_opts``, ``console``, ``plots``).

    ``truth``: ``None`` (the metrics hold track counts and timing only), a
    truth file (:func:`jointtrack.io.read_truth`, read with the detections'
    ``time_origin``) or a table ``(times, ids, positions)`` on the detections'
    clock. With a truth the run is scored as a built-in scenario is — GOSPA,
    OSPA, track statistics, ``gospa.png``, the truth in ``scene.png`` — at
    every scan time, where a target (present from its first truth row's time
    to its last) is at its truth row or at the linear interpolation between
    its rows before and after: a second sensor's scans between the truth's
    times are scored against where the targets were. ``metrics.json`` names
    this rule (``scoring``, with the number of interpolated positions). Truth
    rows at a time with no scan (e.g. a scan without detections, which a
    detections file cannot hold) are not scored at their own time and are
    counted in a note of ``metrics.json`` and the summary; a truth with no
    row at any scan time is an error (a different clock or unit). The truth file's path
    and SHA-256 are part of the run's identity, so a checkpoint resumes only
    with the same truth.

    With ISO-8601 detection times (``detections.time_origin``), metrics.json
    holds ``time_origin`` and all times (tracks file, plots) are seconds since it.

    ``tracker``, ``pmbm``: the kind of tracker and the ``[pmbm]`` table, as in
    :func:`run_scenario`. The PMB/PMBM birth model is uniform at
    :data:`~jointtrack.experiments.config.DEFAULT_BIRTHS_PER_SCAN` births per scan
    over the detections' bounding box; without a clutter density the clutter is
    estimated as (mean detections per scan) / (bounding-box area) — an upper bound,
    named in the notes of metrics.json and the summary.
    """
    if detections.dim not in (2, 3):
        raise RunConfigError(f"the tracker handles 2-D or 3-D detections, got {detections.dim}-D")
    tkind = _check_kind(tracker, config, pmbm)
    user = {} if isinstance(config, TrackerConfig | PMBMConfig) else dict(config or {})
    notes_in = list(notes or [])
    if not isinstance(config, TrackerConfig | PMBMConfig):
        config, fit_notes, fit_id = settings_from_data(detections, dict(config or {}), tkind, fit)
        notes_in += fit_notes
        run_identity = {"fit": fit_id, **dict(run_identity or {})}
    if isinstance(config, TrackerConfig | PMBMConfig):
        cfg = config
    else:
        over = jpda_kind_overrides(tkind, dict(config or {}))
        if "dim" in over and over["dim"] != detections.dim:
            raise RunConfigError(
                f"[tracker] dim = {over['dim']} but the detections are {detections.dim}-D"
            )
        cfg = make_tracker_config({"dim": detections.dim}, over)
    kind = detections.kind
    # "mixed" passes here: each sensor's type is checked against its rows (_register_sensors)
    check_sensor(cfg, kind, detections.source or "the detections")
    if cfg.dim != detections.dim:
        raise RunConfigError(f"tracker dim = {cfg.dim} but the detections are {detections.dim}-D")
    scans = detections.scans
    sigma = math.sqrt(float(np.max(np.diag(cfg.measurement_covariance()))))
    # range-bearing sensors' fixed positions: their [sensors] tables, else [tracker]
    string_ids = detections.sensors is not None and any(
        s.dtype.kind == "U" for s in detections.sensors
    )
    # ids are labels: [sensors.1] names the detections' id "1" when their ids are strings
    tables = sensor_tables_for(
        {sensor_label(i, "[sensors]"): dict(v) for i, v in (options.get("sensors") or {}).items()},
        string_ids,
    )
    options = {**options, "sensors": tables}
    state_dim = (2 if cfg.motion == "cv" else 3) * cfg.dim
    fixed = {None: tuple(cfg.sensor_position)}
    for sid, sensor in make_sensors(tables, cfg, state_dim).items():
        if sensor.kind == "range-bearing":
            fixed[sid] = tuple(float(v) for v in sensor.model.sensor_position)
    seen = set(detections.sensor_kinds()) if detections.sensors is not None else set()
    stations = [p for sid, p in fixed.items() if sid is None or sid in seen]
    # per-sensor positions (mixed files, moving or differently placed sensors): the
    # scans are drawn from Cartesian positions, each row converted with its sensor's position
    own = kind == "mixed" or detections.sensor_positions is not None
    own = own or (kind == "range-bearing" and len(set(stations)) > 1)
    has_rb = kind == "range-bearing" or any(
        v == "range-bearing" for v in detections.sensor_kinds().values()
    )
    if has_rb:
        sigma = (
            max(sigma, math.sqrt(cfg.range_noise))
            if kind == "mixed"
            else math.sqrt(cfg.range_noise)
        )
    if own:
        scans = detections.cartesian(fixed)
        if detections.sensor_positions is not None:
            moving = np.concatenate([p for p in detections.sensor_positions if len(p)] or [[]])
            stations += [tuple(p) for p in moving.reshape(-1, 2) if np.isfinite(p).all()]
    elif kind == "range-bearing":
        scans = _cartesian(scans, cfg.sensor_position)
    pts = [z for z in scans if len(z)]
    region = None
    if pts:
        allz = np.concatenate(pts)
        if has_rb:  # keep the sensor(s) in view
            allz = np.vstack([allz, *(np.reshape(p, (1, 2)) for p in stations)])
        region = np.stack([allz.min(axis=0), allz.max(axis=0)], axis=1)
    plot_scans, plot_kind = detections.scans, kind
    if own:
        # _run draws src.scans, converting range-bearing ones with [tracker]
        # sensor_position, and a resume checks src.kind against the tracker's sensor:
        # give it the Cartesian positions, re-expressed as [r, θ] about that position
        # when the tracker's sensor is range-bearing (the tracker steps detections)
        plot_scans, plot_kind = scans, "position"
        if cfg.sensor == "range-bearing":
            plot_kind = "range-bearing"
            s0 = np.asarray(cfg.sensor_position, dtype=float)
            plot_scans = tuple(
                np.column_stack([np.hypot(*(p - s0).T), np.arctan2(*(p - s0).T[::-1])])
                for p in scans
            )
    identity = {"detections": "<memory>"}
    if detections.source:
        path = Path(detections.source).resolve()
        # the file's content, so that a resume notices a changed file
        identity = {"detections": str(path), "sha256": file_sha256(path)}
    identity.update(run_identity or {})
    table, truth_ids, notes, scoring = None, None, notes_in, None
    if truth is not None:
        table, entries, name = _load_truth(truth, detections)
        identity.update(entries)
        table, n_interpolated, note = _truth_at_scans(
            table, detections.times, name, detections.time_origin, cfg.dim
        )
        scoring = {**SCORING_INTERPOLATED, "n_interpolated_rows": n_interpolated}
        if note:
            notes.append(note)
        truth_ids = tuple(table[1][table[0] == t] for t in detections.times)
        if region is not None and len(table[0]):  # keep the truth in view
            lo = np.minimum(region[:, 0], table[2].min(axis=0))
            hi = np.maximum(region[:, 1], table[2].max(axis=0))
            region = np.stack([lo, hi], axis=1)
    if tkind in POISSON_KINDS and not isinstance(cfg, PMBMConfig):
        # the bounding box of the detections in measurement coordinates (range × bearing
        # for a range-bearing file); a mixed file has no one such space
        cfg, pmbm_notes = make_pmbm_config(
            cfg,
            user,
            pmbm,
            region=region,
            scans=detections.scans if kind != "mixed" else None,
        )
    else:
        pmbm_notes = []
    if options.get("resume") is not None:
        _check_resume_files(options["resume"], to_jsonable(identity, fallback="text"))
    src = _FileSource(
        identity=identity,
        truth=table,
        truth_ids=truth_ids,  # truth_states stay None: a truth file has no velocities
        notes=notes,
        time_origin=detections.time_origin,
        times=detections.times,
        scans=plot_scans,
        sensor_ids=detections.sensors,
        dim=detections.dim,
        region=region,
        sigma=sigma,
        kind=plot_kind,
        scoring=scoring,
        tracker_notes=pmbm_notes,
    )
    src.detections = detections  # stepped by _step_scan, sensors checked by _register_sensors
    src.labels_to_tracker = bool(labels_to_tracker)
    if detections.geo_reference is not None:
        # every geodetic input the same: lat/lon tracks, geo_reference, map.png
        from jointtrack.experiments.realdata import geodetic_outputs

        options["extra"] = geodetic_outputs(detections, options.get("extra"))
    return _run(src, cfg, out_dir, fmt=fmt, progress=progress, kind=tkind, **options)
