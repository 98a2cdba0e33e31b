"""Run configuration: the ``--config`` TOML file, scenarios and tracker settings.

:func:`load_config` reads and checks the TOML file (its format is documented in
:mod:`jointtrack.experiments.run`); :func:`make_scenario` builds a built-in
scenario and :func:`make_tracker_config` the tracker configuration;
:func:`scenario_tracker_settings` derives tracker settings from a scenario,
:func:`scenario_metric_settings` the GOSPA/OSPA parameters its paper scores with, and
:func:`start_truth_tracks` starts tracks at the true states with the
steady-state covariance (:func:`steady_state_covariance`); :func:`start_setting`
and :func:`default_start` say how a run's tracks start (``"truth"`` or
``"nothing"``); :func:`particle_options` resolves which tracker runs (the
Kalman JPDA tracker, or the particle JPDA tracker with its weights method and
particle count) from the flags and the ``[tracker]`` table. Bad settings raise
:class:`RunConfigError` with a one-line message.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from jointtrack.scenarios import GENERATORS
from jointtrack.trackers import JPDATracker, TrackerConfig
from jointtrack.trackers.config import check_field

__all__ = [
    "DEFAULT_BIRTHS_PER_SCAN",
    "DEFAULT_PRIOR_TARGETS",
    "JPDA_KINDS",
    "POISSON_KINDS",
    "SCENARIOS",
    "STARTS",
    "TRACKER_KINDS",
    "TRACKER_OPTION_KEYS",
    "TRUTH_START_NOTE",
    "RunConfig",
    "RunConfigError",
    "bounding_box_clutter",
    "detections_extent",
    "check_kind_keys",
    "check_pmbm_keys",
    "check_sensor",
    "default_start",
    "load_config",
    "make_scenario",
    "make_pmbm_config",
    "make_tracker_config",
    "particle_options",
    "scenario_metric_settings",
    "scenario_tracker_settings",
    "start_setting",
    "start_truth_particles",
    "start_truth_tracks",
    "steady_state_covariance",
    "tracker_kind",
]

SCENARIOS = tuple(GENERATORS)  # bojilov, crossing, many, abreast, coalescence
# How a run's tracks start: confirmed at the true states of the first scan, or
# initiated from the detections by the tracker's own logic.
STARTS = ("truth", "nothing")
TRUTH_START_NOTE = (
    "tracks started from the truth at the first scan: Bojilov's experiment studies "
    "track maintenance and association, not initiation"
)


class RunConfigError(ValueError):
    """A bad run configuration (config file, scenario or option); one-line message."""


@dataclass(frozen=True)
class RunConfig:
    """A parsed ``--config`` file: the three optional tables, as plain dicts."""

    tracker: dict = field(default_factory=dict)
    scenario: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)
    source: str | None = None
    sensors: dict = field(default_factory=dict)  # sensor id (int or str) → [sensors.NAME] table
    # which tracker: [tracker] keys kind / weights / particles (see particle_options)
    tracker_options: dict = field(default_factory=dict)
    # [pmbm]: PMB/PMBM-only settings (PMBM_KEYS), for kind = "pmb" or "pmbm"
    pmbm: dict = field(default_factory=dict)


_TABLES = ("tracker", "scenario", "metrics", "sensors", "pmbm")
_SENSOR_KEYS = (
    "id",
    "type",
    "measurement_noise",
    "range_noise",
    "bearing_noise",
    "sensor_position",
    "p_d",
    "clutter_density",
)
_METRIC_KEYS = {
    "c": "number > 0",
    "p": "number ≥ 1",
    "switch_penalty": "number ≥ 0",
    "switch_convention": "'partner' or 'stonesoup'",
}


def metric_value_ok(key: str, value) -> bool:
    """Whether ``value`` is allowed for the ``[metrics]`` key ``key`` (of :data:`_METRIC_KEYS`)."""
    if key == "switch_convention":
        return value in ("partner", "stonesoup")
    if not isinstance(value, int | float) or isinstance(value, bool) or not math.isfinite(value):
        return False
    return {"c": value > 0, "p": value >= 1, "switch_penalty": value >= 0}[key]


def read_toml(path: Path, what: str, error: type[ValueError] = ValueError) -> dict:
    """The parsed TOML file at ``path``; ``error`` with a one-line message naming the
    file when it is missing, unreadable or not TOML (``what``: "config", "sweep spec")."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise error(f"{path}: no such {what} file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise error(f"{path}: cannot read the {what} file ({exc})") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{path}: not valid TOML: {_one_line(exc)}") from None


def load_config(path) -> RunConfig:
    """Read a TOML run configuration (format: :mod:`jointtrack.experiments.run`).

    Checks the table names, the ``[tracker]`` keys and value types and the
    ``[metrics]`` values here; ``[scenario]`` keywords are checked against the
    scenario function when the scenario is made (:func:`make_scenario`).
    """
    path = Path(path)
    data = read_toml(path, "config", RunConfigError)
    for key, value in data.items():
        if key not in _TABLES:
            raise RunConfigError(
                f"{path}: unknown key '{key}' (known tables: {', '.join(_TABLES)})"
            )
        if not isinstance(value, dict):
            raise RunConfigError(f"{path}: '{key}' must be a table ([{key}])")
    tracker = dict(data.get("tracker", {}))
    options = {k: tracker.pop(k) for k in TRACKER_OPTION_KEYS if k in tracker}
    _check_tracker_options(options, str(path))
    _check_tracker_keys(tracker, str(path))
    metrics = dict(data.get("metrics", {}))
    for key, value in metrics.items():
        if key not in _METRIC_KEYS:
            raise RunConfigError(
                f"{path}: unknown key '{key}' in [metrics] (known: {', '.join(_METRIC_KEYS)})"
            )
        if not metric_value_ok(key, value):
            raise RunConfigError(
                f"{path}: [metrics] key '{key}' must be a {_METRIC_KEYS[key]}, got {value!r}"
            )
    scenario = dict(data.get("scenario", {}))
    if "name" in scenario and scenario["name"] not in SCENARIOS:
        raise RunConfigError(
            f"{path}: [scenario] key 'name' must be one of {', '.join(SCENARIOS)}, "
            f"got {scenario['name']!r}"
        )
    if "seed" in scenario and not _is_int(scenario["seed"]):
        raise RunConfigError(f"{path}: [scenario] key 'seed' must be an integer")
    start_setting(
        scenario.get("start_from"), scenario.get("start_from_truth"), f"{path}: [scenario]"
    )
    sensors = _sensor_tables(data.get("sensors", {}), str(path))
    pmbm = dict(data.get("pmbm", {}))
    # which keys fit which kind is checked once the kind is known (--tracker wins over kind)
    check_pmbm_keys(pmbm, str(path))
    return RunConfig(
        tracker=tracker,
        scenario=scenario,
        metrics=metrics,
        source=str(path),
        sensors=sensors,
        tracker_options=options,
        pmbm=pmbm,
    )


def sensor_label(value, where: str):
    """A sensor id as a label: a Python ``int`` (int64, exactly) or a ``str``.

    Integers, and strings that are integers (``"7"``, a TOML table name
    ``[sensors.7]``), give ``int`` ids, as the integer cells of a detections
    file do; other strings are string ids (``radar_a``). Booleans, floats and
    integers beyond 64 bits raise :class:`RunConfigError` naming ``where``.
    """
    if isinstance(value, str):
        text = value.strip()
        if not text:
            raise RunConfigError(f"{where}: a sensor id cannot be empty")
        if not re.fullmatch(r"[+-]?[0-9]+", text):
            return text
        value = int(text)
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise RunConfigError(
            f"{where}: the sensor id (key 'id', or the table name) must be an integer or a "
            f"string as in the detections' sensor column, got {value!r}"
        )
    if not -(2**63) <= int(value) < 2**63:
        raise RunConfigError(f"{where}: sensor id {value} is beyond 64-bit integers")
    return int(value)


def sensor_tables_for(tables: Mapping, string_ids: bool) -> dict:
    """``[sensors]`` tables keyed like the detections' ids: as they are for integer
    ids; as strings (``1`` → ``"1"``) when the detections' ids are strings."""
    out: dict = {}
    for sid, table in tables.items():
        key = str(sid) if string_ids else sid
        if key in out:
            raise RunConfigError(f"[sensors]: sensor id {key!r} is configured twice")
        out[key] = table
    return out


def sensor_tables_to_run(tables: Mapping) -> list:
    """The ``[sensors]`` tables as ``[[id, table], …]`` for a checkpoint (JSON keys are
    strings: pairs keep int ids ints, exactly)."""
    return [[sid, dict(t)] for sid, t in tables.items()]


def sensor_tables_from_run(saved) -> dict:
    """The ``[sensors]`` tables of :func:`sensor_tables_to_run` (or, from older
    checkpoints, ``{str(id): table}``) by id."""
    if isinstance(saved, Mapping):
        return {sensor_label(k, "checkpoint"): dict(v) for k, v in saved.items()}
    return {sensor_label(k, "checkpoint"): dict(v) for k, v in (saved or [])}


def _sensor_tables(tables: dict, source: str) -> dict:
    """``[sensors.NAME]`` tables by sensor id (the ``id`` key, or NAME;
    :func:`sensor_label`)."""
    out: dict = {}
    for name, table in tables.items():
        where = f"{source}: [sensors.{name}]"
        if not isinstance(table, dict):
            raise RunConfigError(f"{where} must be a table")
        unknown = sorted(set(table) - set(_SENSOR_KEYS))
        if unknown:
            raise RunConfigError(
                f"{where}: unknown key(s) {', '.join(unknown)} (known: {', '.join(_SENSOR_KEYS)})"
            )
        sid = sensor_label(table.get("id", name), where)
        if sid in out:
            raise RunConfigError(f"{where}: sensor id {sid!r} is configured twice")
        kind = table.get("type", None)
        if kind is not None and kind not in ("position", "range-bearing"):
            raise RunConfigError(f"{where}: 'type' must be 'position' or 'range-bearing'")
        out[sid] = dict(table)
    return out


def make_sensors(tables: dict, cfg, state_dim: int) -> dict:
    """``{id: Sensor}`` from ``[sensors.NAME]`` tables; unset values come from ``cfg``."""
    from jointtrack.models import LinearPosition, RangeBearing
    from jointtrack.trackers.sensors import Sensor

    out = {}
    for sid, t in tables.items():
        kind = t.get("type", cfg.sensor)
        try:
            if kind == "position":
                noise = t.get("measurement_noise", cfg.measurement_noise)
                model = LinearPosition(cfg.dim, noise, state_dim=state_dim)
            else:
                model = RangeBearing(
                    [
                        t.get("range_noise", cfg.range_noise),
                        t.get("bearing_noise", cfg.bearing_noise),
                    ],
                    sensor_position=tuple(t.get("sensor_position", cfg.sensor_position)),
                    state_dim=state_dim,
                )
            out[sid] = Sensor(model, t.get("p_d"), t.get("clutter_density"))
        except (TypeError, ValueError) as exc:
            raise RunConfigError(f"[sensors] sensor {sid}: {_one_line(exc)}") from None
    return out


def _one_line(exc) -> str:
    return " ".join(str(exc).split())


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _check_tracker_keys(d: Mapping, where: str) -> None:
    """Known keys and value types / ranges of a ``[tracker]`` table, each on its own.

    Every value is checked by :func:`jointtrack.trackers.config.check_field`
    (a string, bool or list where a number is expected, NaN, a float where an
    integer is expected, out of range, …); the message names the key. Rules
    between keys are checked when the :class:`TrackerConfig` is built
    (:func:`make_tracker_config`).
    """
    known = {f.name for f in dataclasses.fields(TrackerConfig)}
    for key, value in d.items():
        if key not in known:
            names = ", ".join(sorted(known | set(TRACKER_OPTION_KEYS)))
            raise RunConfigError(f"{where}: unknown key '{key}' in [tracker] (known: {names})")
        if key == "clutter_density" and value == "estimate":
            continue
        try:
            check_field(key, value)
        except ValueError as exc:
            msg = _one_line(exc)
            for prefix in ("TrackerConfig: ", f"{key} "):
                msg = msg.removeprefix(prefix)
            raise RunConfigError(f"{where}: [tracker] key '{key}' {msg}") from None


# ----------------------------------------------------------------------------- which tracker

#: ``jointtrack run --tracker``: the Kalman JPDA tracker with M-of-N confirmation ("jpda")
#: or JIPDA existence ("jipda"; the default, ``existence = true``), the PMB and PMBM
#: trackers, or the particle JPDA tracker
TRACKER_KINDS = ("jpda", "jipda", "pmb", "pmbm", "particle")
#: kinds run by :class:`~jointtrack.trackers.JPDATracker` / by the Poisson trackers
JPDA_KINDS = ("jpda", "jipda")
POISSON_KINDS = ("pmb", "pmbm")
#: ``[tracker]`` keys that choose the tracker rather than set a TrackerConfig field
TRACKER_OPTION_KEYS = ("kind", "weights", "particles")


def particle_options(
    kind=None,
    weights=None,
    particles=None,
    table: Mapping | None = None,
    tracker: Mapping | None = None,
    *,
    source: str | None = None,
) -> dict | None:
    """Which tracker a run uses: ``None`` (Kalman JPDA) or the particle tracker's options.

    ``kind``, ``weights``, ``particles``: the ``--tracker``, ``--weights`` and
    ``--particles`` flags (None when not given), which win over ``table`` (the
    ``[tracker]`` keys ``kind``, ``weights``, ``particles``). ``tracker``: the
    other ``[tracker]`` keys; with the particle tracker only the
    :class:`~jointtrack.trackers.TrackerConfig` fields it uses are allowed
    (:attr:`~jointtrack.trackers.particle.ParticleConfig.FROM_TRACKER`), and
    ``clutter_density`` must be a number. Returns ``{"weights": …,
    "particles": …}`` for the particle tracker. Options that make no sense
    together (``--weights`` or ``--particles`` with the Kalman tracker, an
    unavailable weights method, a particle count < 1, …) raise
    :class:`RunConfigError` with a one-line message.
    """
    from jointtrack.trackers.particle import ParticleConfig, available_weight_methods

    table = dict(table or {})
    where = f"{source}: [tracker]" if source else "[tracker]"

    def pick(flag, value, key):
        # the flag wins over the table, like --scenario over [scenario] name
        if value is not None:
            return value, flag
        if key in table:
            return table[key], f"{where} key '{key}'"
        return None, None

    kind, kind_from = pick("--tracker", kind, "kind")
    weights, weights_from = pick("--weights", weights, "weights")
    particles, particles_from = pick("--particles", particles, "particles")
    _check_option_values(kind, kind_from, weights, weights_from, particles, particles_from)
    if kind != "particle":
        extra = weights_from or particles_from
        if extra is not None:
            what = "--tracker jpda" if kind_from == "--tracker" else "the Kalman JPDA tracker"
            raise RunConfigError(
                f"{extra} applies to the particle tracker only, but this run uses {what}; "
                'add --tracker particle (or kind = "particle" in [tracker])'
            )
        return None
    if weights is not None and weights not in available_weight_methods():
        raise RunConfigError(
            f"{weights_from} = {weights!r} needs the method {weights!r} of jointtrack.saddle, "
            f"which this installation does not provide (it has: "
            f"{', '.join(available_weight_methods())})"
        )
    unused = sorted(set(tracker or {}) - set(ParticleConfig.FROM_TRACKER))
    if unused:
        raise RunConfigError(
            f"{where} key(s) {', '.join(unused)} set the Kalman JPDA tracker, not the particle "
            f"tracker (it uses {', '.join(ParticleConfig.FROM_TRACKER)}); remove them, or run "
            "the Kalman JPDA tracker"
        )
    if (tracker or {}).get("clutter_density") == "estimate":
        raise RunConfigError(
            f'{where} clutter_density = "estimate" is not available to the particle tracker: '
            "its clutter terms a_m = Λ p_Λ(y_m) need a known clutter density (a number)"
        )
    out = {}
    if weights is not None:
        out["weights"] = weights
    if particles is not None:
        out["particles"] = int(particles)
    return out


def _check_option_values(kind, kind_from, weights, weights_from, particles, particles_from):
    from jointtrack.trackers.particle import WEIGHT_METHODS

    if kind is not None and kind not in TRACKER_KINDS:
        raise RunConfigError(f"{kind_from} must be {' or '.join(TRACKER_KINDS)}, got {kind!r}")
    if weights is not None and weights not in WEIGHT_METHODS:
        raise RunConfigError(
            f"{weights_from} must be one of {', '.join(WEIGHT_METHODS)}, got {weights!r}"
        )
    if particles is not None and (not _is_int(particles) or particles < 1):
        raise RunConfigError(f"{particles_from} must be an integer ≥ 1, got {particles!r}")


def _check_tracker_options(table: Mapping, where: str) -> None:
    """The ``[tracker]`` keys kind / weights / particles, each on its own (values, types)."""
    args = []
    for key in TRACKER_OPTION_KEYS:
        value = table.get(key)
        args += [value, f"{where}: [tracker] key '{key}'" if value is not None else None]
    _check_option_values(*args)


def make_tracker_config(
    base: Mapping | None = None, overrides: Mapping | None = None, *, source: str | None = None
) -> TrackerConfig:
    """``TrackerConfig`` from derived settings ``base`` updated by ``overrides``.

    ``clutter_density = "estimate"`` in the overrides means ``None`` (Bojilov's
    heuristic (8)). Errors name ``source`` (the config file) when given.
    """
    where = source or "tracker settings"
    overrides = dict(overrides or {})
    _check_tracker_keys(overrides, where)
    if overrides.get("clutter_density") == "estimate":
        overrides["clutter_density"] = None
    d = {**TrackerConfig().to_dict(), **dict(base or {}), **overrides}
    try:
        return TrackerConfig.from_dict(d)
    except (ValueError, TypeError) as exc:
        raise RunConfigError(f"{where}: [tracker] {_one_line(exc)}") from None


# ----------------------------------------------------------------------------- PMB / PMBM

#: ``[tracker]`` keys the PMB / PMBM trackers do not have (JPDA/JIPDA track logic)
JPDA_ONLY_KEYS = (
    "initiation",
    "confirm_m",
    "confirm_n",
    "delete_misses",
    "max_position_std",
    "existence",
    "coalescence_avoidance",
    "id_continuation",
    "r_init",
    "r_confirm",
    "r_delete",
    "r_report",
    "merge_threshold",
    "tentative_association",
    "tentative_process_noise",
    "tentative_components",
    "tentative_confirm_state",
    "miss_model",
    "exact_max_bits_tentative",
    # not in the Poisson trackers (yet): they seed new Bernoullis with reported
    # velocities but do not measure them, and delete by existence, not by time
    "measure_velocity",
    "max_coast",
)
#: expected births per scan over the surveillance region when a scene states no birth
#: model (every scene but ``many`` and ``coalescence``, and detection files)
DEFAULT_BIRTHS_PER_SCAN = 0.01
#: expected undetected targets over the region at the first scan (uniform birth model):
#: runs start from nothing while the scenes' targets are there from the first scan, and
#: the steady state of a small birth rate (PMBMConfig's default prior) would make the
#: first detections of those targets look like clutter for many scans
DEFAULT_PRIOR_TARGETS = 1.0


def _pmbm_only_keys() -> tuple:
    """The :class:`~jointtrack.trackers.pmbm_config.PMBMConfig` fields that are not
    ``TrackerConfig`` fields: the keys of a ``[pmbm]`` table."""
    from jointtrack.trackers.pmbm_config import PMBMConfig

    shared = {f.name for f in dataclasses.fields(TrackerConfig)}
    return tuple(f.name for f in dataclasses.fields(PMBMConfig) if f.name not in shared)


def check_pmbm_keys(table: Mapping, where: str) -> None:
    """Known keys of a ``[pmbm]`` table (values are checked when the config is built)."""
    known = _pmbm_only_keys()
    for key, value in table.items():
        if key not in known:
            raise RunConfigError(
                f"{where}: unknown key '{key}' in [pmbm] (known: {', '.join(known)})"
            )
        if isinstance(value, Mapping):
            raise RunConfigError(f"{where}: [pmbm] key '{key}' must be a value, not a table")


def check_kind_keys(kind, tracker: Mapping, pmbm: Mapping, where: str | None) -> None:
    """Settings that do not belong to the tracker ``kind`` (None: JPDA/JIPDA by ``existence``).

    The PMB/PMBM trackers have no JPDA track logic (:data:`JPDA_ONLY_KEYS` in
    ``[tracker]``); the JPDA trackers take no ``[pmbm]`` table; ``kind = "jpda"``
    (M-of-N) with ``existence = true``, or ``"jipda"`` with ``existence = false``,
    contradict each other. Raises :class:`RunConfigError` naming the keys.
    """
    at = f"{where}: " if where else ""
    if kind in POISSON_KINDS:
        bad = sorted(k for k in tracker if k in JPDA_ONLY_KEYS)
        if bad:
            raise RunConfigError(
                f"{at}[tracker] key(s) {', '.join(bad)} set the JPDA track logic, which the "
                f"{kind} tracker does not have; remove them (its own settings go in [pmbm]: "
                f"{', '.join(_pmbm_only_keys())})"
            )
        return
    if pmbm and kind != "particle":
        what = f'kind = "{kind}"' if kind else "the JPDA tracker (no kind set)"
        raise RunConfigError(
            f'{at}[pmbm] applies to kind = "pmb" or "pmbm" only, but this run uses {what}; '
            "remove [pmbm] or choose --tracker pmb|pmbm"
        )
    if pmbm:
        raise RunConfigError(f"{at}[pmbm] does not apply to the particle tracker")
    existence = tracker.get("existence")
    if kind == "jpda" and existence is True:
        raise RunConfigError(
            f'{at}kind "jpda" is JPDA with M-of-N confirmation, but [tracker] existence = true '
            'asks for JIPDA existence: use kind "jipda" (or remove existence)'
        )
    if kind == "jipda" and existence is False:
        raise RunConfigError(
            f'{at}kind "jipda" is JPDA with JIPDA existence, but [tracker] existence = false '
            'asks for M-of-N confirmation: use kind "jpda" (or remove existence)'
        )


def tracker_kind(flag=None, table: Mapping | None = None, tracker: Mapping | None = None) -> str:
    """The kind of tracker a run uses: ``--tracker`` (``flag``), else ``[tracker] kind``,
    else the JPDA tracker named by ``existence`` (``"jipda"`` by default, ``"jpda"`` with
    ``existence = false``)."""
    kind = flag if flag is not None else (table or {}).get("kind")
    if kind is not None:
        return kind
    return "jpda" if (tracker or {}).get("existence") is False else "jipda"


def jpda_kind_overrides(kind: str, tracker: Mapping) -> dict:
    """``[tracker]`` overrides with ``existence`` set by a JPDA kind (``jpda``: M-of-N)."""
    out = dict(tracker)
    if kind == "jpda":
        out["existence"] = False
    elif kind == "jipda":
        out["existence"] = True
    return out


#: The JIPDA settings of a run from nothing, unless ``[tracker]`` sets them (issue 33):
#: tentative tracks scored as alternatives (each a lone IPDA, so a target's evidence is
#: not split between the tracks born on its returns; :mod:`jointtrack.trackers.existence`,
#: point 5) and, because every clutter-born track is then a test of its own, a stricter
#: confirmation — Wald's bound odds(r_init)/odds(r_confirm) per test is what keeps the
#: false confirmed tracks at ≈ 0.1 per scan on the Bojilov scene (0.9: 0.26, 0.97: 0.10,
#: 0.99: 0.05). Measured on seeds 0–9 of the five built-in scenes against the joint
#: association: ``benchmarks/RESULTS.md``, "JIPDA from nothing: the default". Runs of
#: detection files (``--detections``, :func:`~jointtrack.experiments.run.run_detections`)
#: do not take it: on the held-out ADS-B flights (quickstart) it lost coverage 0.967 →
#: 0.954, purity 0.856 → 0.842 and GOSPA 604 → 627 (close pairs lost 5.7 → 12.2 %), and
#: the switzerland slice only traded 0.2 points of coverage for fewer ids
#: (``benchmarks/RESULTS.md``, "Issue 33: the matched floor …").
FROM_NOTHING_JIPDA = {"tentative_association": "alternatives", "r_confirm": 0.97}


def from_nothing_overrides(kind: str | None, tracker: Mapping) -> dict:
    """``[tracker]`` overrides with :data:`FROM_NOTHING_JIPDA` for the keys they do not
    set, when the run is JIPDA (``kind`` ``"jipda"``, or None with ``existence`` not
    false); other kinds' overrides unchanged. For runs that start from nothing."""
    out = dict(tracker)
    if kind in (None, "jipda") and out.get("existence", True) is True:
        for key, value in FROM_NOTHING_JIPDA.items():
            out.setdefault(key, value)
    return out


def kind_of_config(cfg) -> str:
    """The kind a tracker configuration runs: ``jpda``/``jipda`` (TrackerConfig, by
    ``existence``); a PMBMConfig does not say whether it is PMB or PMBM (None)."""
    if isinstance(cfg, TrackerConfig):
        return "jipda" if cfg.existence else "jpda"
    return None


def detections_extent(scans, dim: int) -> tuple[np.ndarray | None, float]:
    """The side lengths of the bounding box of every (finite) detection of ``scans``
    in measurement coordinates (None without any), and the mean detections per scan."""
    pts = [np.asarray(z, dtype=float).reshape(-1, dim) for z in scans]
    allz = np.concatenate(pts) if pts else np.zeros((0, dim))
    per_scan = len(allz) / max(len(pts), 1)
    allz = allz[np.all(np.isfinite(allz), axis=1)]
    side = allz.max(axis=0) - allz.min(axis=0) if len(allz) else None
    return side, per_scan


def bounding_box_clutter(scans, dim: int) -> tuple[float, str]:
    """An upper bound on the clutter density from detections alone: ``(λ, note)``.

    λ = (mean detections per scan) / (volume of the detections' bounding box): every
    detection is counted as clutter and the box is the smallest that holds them, so
    the true clutter density is below it (targets' returns are counted too). The
    detections are taken in measurement coordinates (a range–bearing sensor's λ is
    per unit range × radian). Raises :class:`RunConfigError` when the box has no
    volume (fewer than two distinct detections along some axis).
    """
    side, per_scan = detections_extent(scans, dim)
    volume = float(np.prod(side)) if side is not None else 0.0
    if not (np.isfinite(volume) and volume > 0):
        raise RunConfigError(
            "the PMB/PMBM trackers need a clutter density, and the detections' bounding box "
            "has no volume to estimate one from; set clutter_density = <number> in [tracker]"
        )
    lam = per_scan / volume
    note = (
        f"clutter density not given: estimated as {lam:.4g} = mean detections per scan "
        f"({per_scan:.4g}) / bounding-box {'area' if dim == 2 else 'volume'} "
        f"of the detections in measurement coordinates ({volume:.4g}) — an upper bound (every "
        "detection counted as clutter)"
    )
    return lam, note


def make_pmbm_config(
    base: TrackerConfig,
    user_tracker: Mapping | None = None,
    pmbm: Mapping | None = None,
    *,
    scenario=None,
    region=None,
    scans=None,
    source: str | None = None,
) -> tuple:
    """The :class:`~jointtrack.trackers.pmbm_config.PMBMConfig` of a run and notes on it.

    ``base``: the JPDA settings the run would use (derived from the scenario or the
    detections, ``[tracker]`` applied); its motion, sensor, P_D, P_S, association and
    ``max_speed`` are shared. ``user_tracker``: the ``[tracker]`` keys set by the
    user (``p_g`` is taken from ``base`` only when set there: the scenes' P_G = 0.99
    is a JPDA gate, whose miss weight carries 1 − P_D P_G; the Poisson trackers' weights
    have no gate factor and use PMBMConfig's 0.9999). ``pmbm``: the ``[pmbm]`` table,
    applied last. The birth model, unless ``[pmbm]`` sets one:

    * a scenario whose ``info`` holds a Gaussian ``birth`` / ``prior`` model
      (``coalescence``): that model (``birth_model = "gaussian"``), and its P_S;
    * a scenario with a known ``birth_rate`` (``many``): uniform births of
      birth_rate / |region| per unit area per scan;
    * otherwise (other scenarios, detection files): uniform births of
      :data:`DEFAULT_BIRTHS_PER_SCAN` (0.01) per scan over ``region`` (the scenario's
      region or the detections' bounding box) — a small rate, so that clutter rarely
      starts a track; the prior density at the first scan is then the steady state
      of that rate (PMBMConfig's default).

    The clutter density is ``base.clutter_density``; when it is unknown (None, e.g.
    a detections file without ``clutter_density``) it is estimated from ``scans``
    by :func:`bounding_box_clutter`, an upper bound, and a note says so. Returns
    ``(PMBMConfig, notes)``; bad values raise :class:`RunConfigError`.
    """
    from jointtrack.trackers.pmbm_config import PMBMConfig

    where = f"{source}: " if source else ""
    user_tracker = dict(user_tracker or {})
    pmbm = dict(pmbm or {})
    notes = []
    over: dict = {}
    if "p_g" not in user_tracker:
        over["p_g"] = PMBMConfig.p_g
    info = getattr(scenario, "info", None)
    info = info if isinstance(info, Mapping) else {}
    birth = info.get("birth")
    if "birth_model" not in pmbm and isinstance(birth, Mapping) and "mean" in birth:
        prior = info.get("prior") if isinstance(info.get("prior"), Mapping) else {}
        over.update(
            birth_model="gaussian",
            birth_weights=[float(birth["weight"])],
            birth_means=[list(birth["mean"])],
            birth_covs=[[list(r) for r in birth["cov"]]],
            prior_weight=float(prior.get("lambda", 0.0)),
        )
        if "p_s" in info and "p_survive" not in user_tracker:
            over["p_survive"] = float(info["p_s"])
        notes.append(
            f"PMB/PMBM birth model: the scenario's Gaussian birth intensity (weight "
            f"{float(birth['weight']):g}) and prior (λ₀ = {over['prior_weight']:g})"
        )
    elif pmbm.get("birth_model", "uniform") == "uniform" and "birth_density" not in pmbm:
        box = None if region is None else np.asarray(region, dtype=float)
        area = float(np.prod(box[:, 1] - box[:, 0])) if box is not None else 0.0
        rate = info.get("birth_rate")
        # reporting targets: rates per second, a "scan" being one report_interval
        per = "scan" if base.reporting == "scan" else "second"
        if area > 0 and isinstance(rate, int | float) and rate > 0:
            over["birth_density"] = float(rate) / area
            why = f"the scenario's birth rate {float(rate):g} per scan"
        elif area > 0 and per == "second":
            over["birth_density"] = DEFAULT_BIRTHS_PER_SCAN / base.report_interval / area
            why = (
                f"the default {DEFAULT_BIRTHS_PER_SCAN:g} births per report_interval "
                f"({base.report_interval:g} s; no birth model known)"
            )
        elif area > 0:
            over["birth_density"] = DEFAULT_BIRTHS_PER_SCAN / area
            why = f"the default {DEFAULT_BIRTHS_PER_SCAN:g} births per scan (no birth model known)"
        else:
            why = None
        if why:
            unit = "area" if base.dim == 2 else "volume"
            text = (
                f"PMB/PMBM birth model: uniform, {over['birth_density']:.4g} per unit {unit} "
                f"per {per} = {why} over the region ({area:.4g})"
            )
            if "prior_density" not in pmbm:
                p_s = float(user_tracker.get("p_survive", base.p_survive))
                if per == "second":  # births against deaths and first reports, per second
                    loss = -math.log(p_s) + base.p_d / base.report_interval
                else:
                    loss = 1.0 - p_s * (1.0 - base.p_d)
                steady = over["birth_density"] / loss
                over["prior_density"] = max(steady, DEFAULT_PRIOR_TARGETS / area)
                text += (
                    f"; prior {over['prior_density']:.4g} per unit {unit} at the first scan "
                    f"(max of {DEFAULT_PRIOR_TARGETS:g} target over the region and the birth "
                    "steady state)"
                )
            notes.append(text)
    if base.clutter_density is None and "clutter_density" not in pmbm:
        if scans is None:
            raise RunConfigError(
                f"{where}the PMB/PMBM trackers need a known clutter density: set "
                "clutter_density = <number> in [tracker]"
            )
        lam, note = bounding_box_clutter(scans, base.dim)
        over["clutter_density"] = lam
        notes.append(note)
    over.update(pmbm)
    try:
        cfg = PMBMConfig.from_tracker_config(base, **over)
    except (TypeError, ValueError) as exc:
        raise RunConfigError(f"{where}[pmbm] {_one_line(exc)}") from None
    return cfg, notes


_RB_SETTINGS = (
    'sensor = "range-bearing", sensor_position = [x, y], range_noise = σ_r² and '
    "bearing_noise = σ_θ² (rad²)"
)


def check_sensor(cfg: TrackerConfig, kind: str, data: str, source: str | None = None) -> None:
    """A :class:`RunConfigError` unless the tracker's sensor reads detections of ``kind``.

    ``kind``: :attr:`jointtrack.io.Detections.kind` (``"position"`` or
    ``"range-bearing"``); ``data``: what holds the detections (for the
    message); ``source``: the config file, if any.
    """
    if kind == "range-bearing" and cfg.sensor != "range-bearing":
        where = f"the [tracker] table of {source}" if source else "[tracker] of a --config file"
        raise RunConfigError(
            f"{data} holds range-bearing detections (range, bearing) but the tracker's sensor "
            f'is "{cfg.sensor}": set {_RB_SETTINGS} in {where}'
        )
    if kind == "position" and cfg.sensor != "position":
        where = f"{source}: [tracker]" if source else "[tracker]"
        raise RunConfigError(
            f'{where} sensor = "{cfg.sensor}" but {data} holds position detections '
            '(x, y): remove that key or set sensor = "position"'
        )


def make_scenario(
    name: str = "bojilov",
    seed: int = 0,
    kwargs: Mapping | None = None,
    *,
    source: str | None = None,
):
    """Build a built-in scenario by name (``bojilov | crossing | many | abreast | coalescence``).

    ``kwargs`` are passed to the scenario function (:mod:`jointtrack.scenarios`);
    unknown keywords and bad values raise :class:`RunConfigError` naming them.
    """

    # the file's table when the scenario comes from a config; the message then goes on
    # "scenario NAME: …" (not "scenario scenario NAME", issue 25)
    where = f"{source}: [scenario] " if source else ""
    if name not in SCENARIOS:
        raise RunConfigError(
            f"{where}unknown scenario {name!r}; choose one of {', '.join(SCENARIOS)}"
        )
    fn = GENERATORS[name]
    params = [p for p in inspect.signature(fn).parameters if p != "seed"]
    kwargs = dict(kwargs or {})
    for key in kwargs:
        if key not in params:
            raise RunConfigError(
                f"{where}unknown key '{key}' for scenario {name} (known: name, seed, "
                f"start_from, {', '.join(params)})"
            )
    try:
        return fn(seed=seed, **kwargs)
    except (ValueError, TypeError) as exc:
        which = f'name = "{name}"' if source else f"scenario {name}"
        raise RunConfigError(f"{where}{which}: {_one_line(exc)}") from None


def default_start(scenario_name: str) -> str:
    """How a built-in scenario's tracks start unless told otherwise.

    ``"truth"`` for ``bojilov``: Bojilov et al.'s experiment starts the five
    tracks at the true states (it studies maintenance and association, not
    initiation), and the default run is that experiment. ``"nothing"`` for the
    others, which have births and so need initiation anyway.
    """
    return "truth" if scenario_name == "bojilov" else "nothing"


def start_setting(
    start_from=None, start_from_truth=None, where: str = "[scenario]", *, noun: str = "key"
) -> str | None:
    """The start (``"truth"`` or ``"nothing"``) set by ``start_from`` or its alias.

    ``start_from = "truth" | "nothing"`` is the setting; ``start_from_truth =
    true | false`` is its older spelling, still read so that existing config
    files and checkpoints keep working. Either may be given, or both when they
    agree; ``None`` when neither is (the scenario's :func:`default_start`
    applies). A bad value or a disagreement raises :class:`RunConfigError`
    naming ``where`` (e.g. ``"run.toml: [scenario]"``) and the setting, called
    a ``noun`` (``"key"`` in a TOML table, ``"argument"`` of a function).
    """
    start = None
    if start_from is not None:
        if start_from not in STARTS:
            raise RunConfigError(
                f'{where} {noun} \'start_from\' must be "truth" or "nothing", got {start_from!r}'
            )
        start = start_from
    if start_from_truth is not None:
        if not isinstance(start_from_truth, bool):
            raise RunConfigError(
                f"{where} {noun} 'start_from_truth' must be true or false, got {start_from_truth!r}"
            )
        alias = "truth" if start_from_truth else "nothing"
        if start is not None and start != alias:
            raise RunConfigError(
                f"{where} 'start_from' = \"{start}\" and 'start_from_truth' = "
                f"{str(start_from_truth).lower()} disagree; keep 'start_from' "
                "('start_from_truth' is its older spelling)"
            )
        start = alias
    return start


def scenario_tracker_settings(scenario) -> dict:
    """Tracker settings derived from a scenario's parameters.

    See :mod:`jointtrack.experiments.run` for how they are derived.
    """
    speeds = [np.linalg.norm(s[:, scenario.dim :], axis=1) for s in scenario.truth_states if len(s)]
    vmax = float(max((v.max() for v in speeds), default=0.0))
    d = {
        "dim": scenario.dim,
        "motion": "cv",
        "process_noise": max(float(scenario.process_noise), 1e-9),
        "measurement_noise": _noise_setting(scenario.R),
        "p_d": float(scenario.p_d),
        "p_g": float(scenario.info.get("p_g", 0.99)),
        "clutter_density": float(scenario.clutter_density)
        if scenario.clutter_density > 0
        else None,
        "max_speed": 1.5 * vmax if vmax > 0 else 1.0,
    }
    return d


def scenario_metric_settings(scenario) -> dict:
    """The GOSPA/OSPA ``c`` and ``p`` a scenario is scored with unless ``[metrics]`` sets them.

    A scenario whose paper fixes them says so in ``info["gospa"]`` (coalescence:
    c = 10, p = 2, as García-Fernández et al. score it); the others have none
    (``{}``) and a run uses c = 5σ, p = 2. Only ``c`` and ``p`` are taken: a
    run's GOSPA always has α = 2.
    """
    own = scenario.info.get("gospa") if isinstance(scenario.info, Mapping) else None
    if not isinstance(own, Mapping):
        return {}
    return {k: float(own[k]) for k in ("c", "p") if k in own}


def _noise_setting(R) -> float | tuple:
    """``measurement_noise`` for a scenario's R: σ² when R = σ² I, the per-axis
    σ² when R is diagonal, else the full matrix (as tuples)."""
    R = np.atleast_2d(np.asarray(R, dtype=float))
    d = np.diag(R)
    if np.count_nonzero(R - np.diag(d)) == 0:
        if np.all(d == d[0]):
            return float(d[0])
        return tuple(float(v) for v in d)
    return tuple(tuple(float(v) for v in row) for row in R)


def steady_state_covariance(dt: float, q: float, r, dim: int = 2) -> np.ndarray:
    """Steady-state updated covariance of the NCV Kalman filter, layout [pos…, vel…].

    Per axis: the discrete Riccati equation for F = [[1, T], [0, 1]],
    Q = q [[T³/3, T²/2], [T²/2, T]], H = [1 0], R = r gives the predicted P⁻;
    the updated P = P⁻ − P⁻Hᵀ S⁻¹ H P⁻ with S = P⁻ₓₓ + r. ``r``: σ² (all
    axes), per-axis σ² (length ``dim``) or a ``dim × dim`` covariance (its
    diagonal is used per axis — the axes are solved independently).
    """
    from scipy import linalg

    from jointtrack.scenarios import ncv_matrices

    ra = np.asarray(r, dtype=float)
    rs = np.diag(ra) if ra.ndim == 2 else np.broadcast_to(ra, (dim,))
    F, Q = ncv_matrices(dt, max(q, 1e-12), 1)
    H = np.array([[1.0, 0.0]])
    P = np.zeros((2 * dim, 2 * dim))
    for a in range(dim):
        ri = float(rs[a])
        Pp = linalg.solve_discrete_are(F.T, H.T, Q, np.array([[ri]]))
        S = Pp[0, 0] + ri
        Pu = Pp - np.outer(Pp[:, 0], Pp[0, :]) / S
        Pu = 0.5 * (Pu + Pu.T)
        idx = [a, dim + a]
        P[np.ix_(idx, idx)] = Pu
    return P


def start_truth_tracks(trk: JPDATracker, states, dt: float) -> np.ndarray:
    """Start confirmed tracks at the true NCV ``states`` (K, 2·dim) of the first scan.

    Covariance: :func:`steady_state_covariance` of the tracker's own q and σ²
    (what a track that has been followed for long has), so the first gates are
    the nominal steady-state gates; a constant-acceleration tracker gets zero
    acceleration with unit variance. Returns the track ids.
    """
    c = trk.config
    n = trk._motion.state_dim
    d = c.dim
    states = np.atleast_2d(np.asarray(states, dtype=float))
    x0 = np.zeros((len(states), n))
    x0[:, : 2 * d] = states[:, : 2 * d]
    P0 = np.eye(n)
    P0[: 2 * d, : 2 * d] = steady_state_covariance(dt, c.process_noise, c.measurement_noise, d)
    return trk.start_tracks(x0, P0)


def start_truth_particles(trk, states, dt: float) -> np.ndarray:
    """Start a particle tracker's targets at the true NCV ``states`` (N, 2·dim) of the first scan.

    Each target's particles are drawn from N(state, P0) with P0 the
    :func:`steady_state_covariance` of the tracker's own q and R, as
    :func:`start_truth_tracks` starts the Kalman tracks (a constant-acceleration
    model gets zero acceleration with unit variance). Returns the target ids 1…N.
    """
    c = trk.config
    n = trk.state_dim
    d = c.dim
    states = np.atleast_2d(np.asarray(states, dtype=float))
    x0 = np.zeros((len(states), n))
    x0[:, : 2 * d] = states[:, : 2 * d]
    P0 = np.eye(n)
    P0[: 2 * d, : 2 * d] = steady_state_covariance(dt, c.process_noise, c.measurement_noise, d)
    return trk.start(x0, P0)


def _describe(identity) -> str:
    """One-line description of a run's source (scenario and seed, or detections file)."""
    if not isinstance(identity, Mapping):
        return "an unknown run"
    if "detections" in identity:
        return f"detections {identity['detections']}"
    kw = identity.get("kwargs") or {}
    extra = "".join(f", {k}={v}" for k, v in kw.items())
    return f"scenario {identity.get('scenario')} (seed {identity.get('seed')}{extra})"
