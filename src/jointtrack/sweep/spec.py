"""Sweep specification: a TOML grid of cells × seeds, checked before anything runs.

A spec file has the run tables of ``jointtrack run --config`` as the base of
every cell (``[tracker]``, ``[scenario]``, ``[metrics]``; and ``[filter]`` for
the superpositional filters on ``scenario.name = "acoustic"``) and one
``[sweep]`` table of axes::

    [sweep]
    seeds = 10                       # seeds 0..9; or a list: [0, 4, 7]
    scenario.clutter_density = [0.5, 1.0, 2.0]
    tracker.association = ["exact", "lbp"]

    [scenario]
    name = "bojilov"                 # bojilov | crossing | many | abreast | coalescence | acoustic
    n_scans = 30

An axis is ``TABLE.KEY = [values]`` (a dotted key, or the same key quoted) with
``TABLE`` one of ``scenario``, ``tracker``, ``metrics``, ``filter``; the grid is
the Cartesian product of the axes, each cell run once per seed. The seed of a
run is the scenario's seed and, unless ``[tracker]`` sets ``seed``, the
tracker's. ``[filter]`` keys (acoustic only): ``name`` (sps-cphd | sps-phd |
sps-mb), ``likelihood``, ``particles``, ``n_scans``, ``max_scans``,
``burn_in``, ``link_gate``. The particle JPDA tracker is ``tracker.kind =
"particle"`` with ``tracker.weights`` and ``tracker.particles``, as in ``jointtrack
run``.

Every key and value type is checked here (:func:`parse_spec`); a bad one raises
``ValueError`` naming it. Values that only the run can judge (a scenario
keyword out of range, say) make that cell's runs fail, recorded with the error.
"""

from __future__ import annotations

import hashlib
import inspect
import itertools
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from jointtrack.scenarios import GENERATORS

__all__ = ["Run", "SweepSpec", "cell_id", "load_spec", "parse_spec", "run_id"]

#: Scenarios a cell can run: the detection scenarios of ``jointtrack run`` plus acoustic.
SCENARIO_NAMES = (*GENERATORS, "acoustic")
_TABLES = ("tracker", "scenario", "metrics", "filter")
#: ``[filter]`` keys of an acoustic cell and the type each must have.
FILTER_KEYS = {
    "name": "one of sps-cphd, sps-phd, sps-mb",
    "likelihood": "one of gaussian, saddlepoint, hybrid",
    "particles": "integer ≥ 1",
    "n_scans": "integer ≥ 10",
    "max_scans": "integer ≥ 1",
    "burn_in": "integer ≥ 0",
    "link_gate": "number > 0",
}
_MAX_SEEDS = 1_000_000


@dataclass(frozen=True)
class Run:
    """One run of the sweep: a cell's parameters and a seed, with its stable ids."""

    params: dict  # flat "table.key" -> value, every setting of the cell (base and axes)
    seed: int
    run_id: str
    cell_id: str


@dataclass(frozen=True)
class SweepSpec:
    """A parsed sweep: the base tables, the axes and the seeds.

    Attributes
    ----------
    base : flat ``"table.key" -> value`` settings shared by every cell.
    axes : ``"table.key" -> list of values``, in the file's order.
    seeds : the seeds each cell is run with.
    source : the file the spec was read from (for messages), if any.
    """

    base: dict
    axes: dict
    seeds: tuple
    source: str | None = None
    cells: list = field(default_factory=list, compare=False)

    @property
    def n_cells(self) -> int:
        """Number of parameter cells (the product of the axis lengths)."""
        return len(self.cells)

    @property
    def n_runs(self) -> int:
        """Number of runs: cells × seeds."""
        return len(self.cells) * len(self.seeds)

    def runs(self) -> list[Run]:
        """Every run of the grid, cell by cell, seeds in order."""
        out = []
        for params in self.cells:
            cid = cell_id(params)
            out.extend(Run(params, s, run_id(params, s), cid) for s in self.seeds)
        return out


def _canonical(obj) -> str:
    # sorted keys and no spaces: the same parameters always give the same text;
    # 1 and 1.0 differ on purpose (they are different TOML values)
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), allow_nan=False)


def cell_id(params: Mapping) -> str:
    """Stable id of a cell: a hash of its parameters (16 hex digits).

    >>> cell_id({"scenario.name": "bojilov"}) == cell_id({"scenario.name": "bojilov"})
    True
    """
    return hashlib.sha256(_canonical(dict(params)).encode()).hexdigest()[:16]


def run_id(params: Mapping, seed: int) -> str:
    """Stable id of a run: a hash of (cell parameters, seed) (20 hex digits).

    The same parameters and seed give the same id in any process, on any
    machine, so a restarted sweep recognises finished runs and a run's row is
    written under one name only.

    >>> run_id({"scenario.name": "bojilov"}, 1) != run_id({"scenario.name": "bojilov"}, 2)
    True
    """
    text = _canonical({"params": dict(params), "seed": int(seed)})
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def load_spec(path) -> SweepSpec:
    """Read and check a sweep spec TOML file (format: module docstring)."""
    from jointtrack.experiments.config import read_toml

    path = Path(path)
    return parse_spec(read_toml(path, "sweep spec"), source=str(path))


def parse_spec(data: Mapping, *, source: str | None = None) -> SweepSpec:
    """Check a sweep spec given as a mapping (the parsed TOML) and expand its grid.

    Parameters
    ----------
    data : the tables ``sweep`` (required), ``tracker``, ``scenario``,
        ``metrics``, ``filter``.
    source : name of the file, used in messages.

    Returns
    -------
    SweepSpec

    Raises
    ------
    ValueError
        Naming the table and key: unknown tables or keys, an empty or
        non-list axis, a value of the wrong type, a key set both in a base
        table and as an axis, ``seed`` anywhere but ``[sweep] seeds``.

    Examples
    --------
    >>> spec = parse_spec({"sweep": {"seeds": 3, "tracker": {"association": ["exact", "lbp"]}},
    ...                    "scenario": {"name": "crossing", "n_scans": 5}})
    >>> spec.n_cells, spec.n_runs
    (2, 6)
    """
    where = f"{source}: " if source else ""
    if not isinstance(data, Mapping):
        raise ValueError(f"{where}the sweep spec must be a table, got {type(data).__name__}")
    for key, value in data.items():
        if key != "sweep" and key not in _TABLES:
            raise ValueError(f"{where}unknown table '{key}' (known: sweep, {', '.join(_TABLES)})")
        if not isinstance(value, Mapping):
            raise ValueError(f"{where}'{key}' must be a table ([{key}])")
    if "sweep" not in data:
        raise ValueError(f"{where}no [sweep] table: give at least `seeds = N` in [sweep]")
    base = {}
    for table in _TABLES:
        for key, value in data.get(table, {}).items():
            if table == "scenario" and key == "seed":
                raise ValueError(
                    f"{where}[scenario] key 'seed': a sweep takes its seeds from "
                    "[sweep] seeds (an integer N for 0..N-1, or a list)"
                )
            if isinstance(value, Mapping):
                raise ValueError(f"{where}[{table}] key '{key}' must be a value, not a table")
            base[f"{table}.{key}"] = value
    sweep = dict(data["sweep"])
    seeds = _seeds(sweep.pop("seeds", None), where)
    axes = {}
    for key, value in _flatten(sweep, where).items():
        table, _, name = key.partition(".")
        if table not in _TABLES or not name:
            raise ValueError(
                f"{where}[sweep] unknown axis '{key}': an axis is TABLE.KEY = [values] with "
                f"TABLE one of {', '.join(_TABLES)} (or seeds = N)"
            )
        if key == "scenario.seed":
            raise ValueError(f"{where}[sweep] axis '{key}': seeds are given by [sweep] seeds")
        if not isinstance(value, list):
            raise ValueError(f"{where}[sweep] axis '{key}' must be a list of values, got {value!r}")
        if not value:
            raise ValueError(f"{where}[sweep] axis '{key}' is empty: give at least one value")
        if key in base:
            raise ValueError(
                f"{where}[sweep] axis '{key}' is also set in [{table}]; set it in one place"
            )
        for v in value:
            if isinstance(v, list | Mapping) and key not in _LIST_KEYS:
                raise ValueError(
                    f"{where}[sweep] axis '{key}': each value must be a number, string or "
                    f"boolean, got {v!r}"
                )
        if len({_canonical(v) for v in value}) != len(value):
            raise ValueError(f"{where}[sweep] axis '{key}' repeats a value: {value!r}")
        axes[key] = list(value)
    cells = []
    for combo in itertools.product(*axes.values()):
        params = {**base, **dict(zip(axes, combo, strict=True))}
        params.setdefault("scenario.name", "bojilov")
        cells.append(params)
    # each distinct cell is checked once: keys, types, and combinations of keys
    for params in cells:
        _check_cell(params, where, axes)
    return SweepSpec(base=base, axes=axes, seeds=seeds, source=source, cells=cells)


# [scenario] keys whose value is a list (a value of such an axis may be a list)
_LIST_KEYS = {"scenario.speeds", "scenario.region", "scenario.speed_range"}


def _flatten(d: Mapping, where: str, prefix: str = "") -> dict:
    out = {}
    for key, value in d.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            if prefix:
                raise ValueError(f"{where}[sweep] axis '{name}' nests too deep (TABLE.KEY)")
            out.update(_flatten(value, where, f"{name}."))
        else:
            out[name] = value
    return out


def _seeds(value, where: str) -> tuple:
    if value is None:
        raise ValueError(f"{where}[sweep] key 'seeds' is missing: give seeds = N or a list")
    if isinstance(value, bool) or not isinstance(value, int | list):
        raise ValueError(
            f"{where}[sweep] key 'seeds' must be an integer N ≥ 1 (seeds 0..N-1) or a list "
            f"of integers ≥ 0, got {value!r}"
        )
    if isinstance(value, int):
        if not 1 <= value <= _MAX_SEEDS:
            raise ValueError(f"{where}[sweep] key 'seeds' must be in 1..{_MAX_SEEDS}, got {value}")
        return tuple(range(value))
    if not value:
        raise ValueError(f"{where}[sweep] key 'seeds' is an empty list")
    for s in value:
        if isinstance(s, bool) or not isinstance(s, int) or s < 0:
            raise ValueError(f"{where}[sweep] key 'seeds' must hold integers ≥ 0, got {s!r}")
    if len(set(value)) != len(value):
        raise ValueError(f"{where}[sweep] key 'seeds' repeats a seed: {value!r}")
    return tuple(value)


def _origin(key: str, axes: Mapping) -> str:
    table, _, name = key.partition(".")
    return f"[sweep] axis '{key}'" if key in axes else f"[{table}] key '{name}'"


def _check_cell(params: Mapping, where: str, axes: Mapping) -> None:
    """Keys and value types of one cell (RunConfigError is a ValueError naming the key)."""
    from jointtrack.experiments.config import (
        _METRIC_KEYS,
        TRACKER_OPTION_KEYS,
        _check_tracker_keys,
        _check_tracker_options,
        metric_value_ok,
        particle_options,
        start_setting,
    )

    name = params["scenario.name"]
    if name not in SCENARIO_NAMES:
        raise ValueError(
            f"{where}{_origin('scenario.name', axes)} must be one of "
            f"{', '.join(SCENARIO_NAMES)}, got {name!r}"
        )
    tables = {t: {} for t in _TABLES}
    for key, value in params.items():
        table, _, k = key.partition(".")
        tables[table][k] = value
    scen = {k: v for k, v in tables["scenario"].items() if k != "name"}
    if name == "acoustic":
        for table in ("tracker", "metrics"):
            for k in tables[table]:
                raise ValueError(
                    f"{where}{_origin(f'{table}.{k}', axes)} does not apply to scenario "
                    "acoustic (a superpositional-sensor filter: set it in [filter])"
                )
        for k in scen:
            raise ValueError(
                f"{where}{_origin(f'scenario.{k}', axes)} does not apply to scenario acoustic "
                "(its settings are in [filter]: n_scans, …)"
            )
        _check_filter(tables["filter"], where, axes)
        return
    for k in tables["filter"]:
        raise ValueError(f"{where}{_origin(f'filter.{k}', axes)} applies to scenario acoustic only")

    fn = GENERATORS[name]
    known = [p for p in inspect.signature(fn).parameters if p != "seed"]
    for k in scen:
        if k in ("start_from", "start_from_truth"):
            continue
        if k not in known:
            raise ValueError(
                f"{where}{_origin(f'scenario.{k}', axes)}: unknown key for scenario {name} "
                f"(known: name, start_from, {', '.join(known)})"
            )
    start_setting(scen.get("start_from"), scen.get("start_from_truth"), f"{where}[scenario]")
    tracker = dict(tables["tracker"])
    options = {k: tracker.pop(k) for k in TRACKER_OPTION_KEYS if k in tracker}
    src = where.rstrip(": ") or "sweep spec"
    # key by key, so that a bad value of an axis is reported as that axis
    for k, v in {**options, **tracker}.items():
        try:
            if k in TRACKER_OPTION_KEYS:
                _check_tracker_options({k: v}, src)
            else:
                _check_tracker_keys({k: v}, src)
        except ValueError as exc:
            if f"tracker.{k}" not in axes:
                raise
            raise ValueError(
                f"{where}[sweep] axis 'tracker.{k}': {str(exc).removeprefix(f'{src}: ')}"
            ) from None
    particle_options(table=options, tracker=tracker, source=src)
    for k, value in tables["metrics"].items():
        if k not in _METRIC_KEYS:
            raise ValueError(
                f"{where}{_origin(f'metrics.{k}', axes)}: unknown key (known: "
                f"{', '.join(_METRIC_KEYS)})"
            )
        if not metric_value_ok(k, value):
            raise ValueError(
                f"{where}{_origin(f'metrics.{k}', axes)} must be a {_METRIC_KEYS[k]}, got {value!r}"
            )


def _check_filter(table: Mapping, where: str, axes: Mapping) -> None:
    from jointtrack.experiments.acoustic_run import FILTER_DEFAULTS, LIKELIHOODS

    for k, v in table.items():
        if k not in FILTER_KEYS:
            raise ValueError(
                f"{where}{_origin(f'filter.{k}', axes)}: unknown key (known: "
                f"{', '.join(FILTER_KEYS)})"
            )
        is_int = isinstance(v, int) and not isinstance(v, bool)
        ok = {
            "name": v in FILTER_DEFAULTS,
            "likelihood": v in LIKELIHOODS,
            "particles": is_int and v >= 1,
            "n_scans": is_int and v >= 10,
            "max_scans": is_int and v >= 1,
            "burn_in": is_int and v >= 0,
            "link_gate": isinstance(v, int | float)
            and not isinstance(v, bool)
            and math.isfinite(v)
            and v > 0,
        }[k]
        if not ok:
            raise ValueError(
                f"{where}{_origin(f'filter.{k}', axes)} must be a {FILTER_KEYS[k]}, got {v!r}"
            )
