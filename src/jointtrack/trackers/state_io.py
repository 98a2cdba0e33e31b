"""Tracker state files: versioned, checksummed, validated, never pickle.

A state file is a NumPy ``.npz`` archive (a zip of ``.npy`` arrays, read with
``allow_pickle=False``) holding the tracker's arrays and one more array,
``__header__``, with a UTF-8 JSON header::

    {"format": "jointtrack-tracker-state", "version": 5,
     "sha256": "<hex digest of the payload>", "config": {...},
     "scalars": {"time": ..., "next_id": ..., "n_scans": ...},
     "rng": {... numpy bit-generator state ...}}

The SHA-256 covers the header (without the digest) and every array's name,
dtype, shape and bytes, so any damaged byte is detected. Loading never runs
code: a pickle checkpoint of an older jointtrack is refused with a message that
says why. Every damaged, truncated, foreign or wrong-version file gives one
:class:`ValueError` naming the file and what is wrong, and the values are
checked (shapes, finiteness, symmetric positive-definite covariances,
probabilities in [0, 1], unique ids). Saving writes a temporary file beside the
target, flushes it to disk and renames it over the target (atomic on POSIX); a
save that fails removes the temporary file, leaves the target as it was and raises
:class:`StateFileError` naming the target.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import zipfile
from pathlib import Path

import numpy as np

from jointtrack._atomic import atomic_file
from jointtrack.trackers.config import TrackerConfig

__all__ = [
    "FORMAT",
    "VERSION",
    "StateFileError",
    "read_run",
    "read_state",
    "validate_component_arrays",
    "validate_counters",
    "validate_mode_arrays",
    "validate_retired_arrays",
    "validate_update_arrays",
    "write_state",
]

FORMAT = "jointtrack-tracker-state"
VERSION = 6
#: Older versions still read, each upgraded by :func:`_upgrade` to this one.
_READABLE = (3, 4, 5, 6)
#: JPDA settings of the interacting multiple model (version 5), and the values an
#: older state's run continues under (its motion is "cv" or "ca": they are unused)
_IMM_SETTINGS = {
    "imm_modes": ["cv", "ct"],
    "imm_switching": 0.95,
    "imm_initial": None,
    "turn_rate_std": 0.02,
    "max_turn_rate": 0.2,
}
_PICKLE_MAGIC = b"\x80"
_ZIP_MAGIC = b"PK\x03\x04"
#: Largest array member accepted (a tracker with a million tracks is ~100 MB).
_MAX_MEMBER_BYTES = 2**31
#: Largest next track id / scan count a state holds: ids live in int64 arrays, and a
#: tracker must be able to add tracks after it (headroom below 2**63).
MAX_ID = 2**62


class StateFileError(ValueError):
    """A tracker state file that cannot be read, used or written (the message names
    the file)."""


def _digest(header: dict, arrays: dict[str, np.ndarray]) -> str:
    h = hashlib.sha256()
    h.update(json.dumps(header, sort_keys=True, separators=(",", ":")).encode())
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def write_state(
    path, arrays: dict[str, np.ndarray], config: dict, scalars: dict, rng: dict, run=None
):
    """Write a state file atomically; returns the path.

    Raises :class:`StateFileError` naming ``path`` when it cannot be written (a
    directory, a missing or read-only directory, a full disk); the temporary file
    is removed and a state file already at ``path`` is left as it was, whatever
    fails (an interrupt too).

    ``run`` (optional, JSON-able) is stored in the same checksummed header — a
    caller's bookkeeping that must change together with the state (e.g. the
    run inputs and committed output parts of ``jointtrack run``).
    """
    path = Path(path)
    arrays = {k: np.ascontiguousarray(v) for k, v in arrays.items()}
    for k, v in arrays.items():
        if v.dtype.kind not in "biufU":
            raise TypeError(
                f"state array {k!r} has dtype {v.dtype}; only plain numbers and fixed-width "
                "text are saved"
            )
    header = {
        "format": FORMAT,
        "version": VERSION,
        "config": config,
        "scalars": scalars,
        "rng": rng,
        "run": run,
    }
    header["sha256"] = _digest(header, arrays)
    blob = np.frombuffer(json.dumps(header).encode("utf-8"), dtype=np.uint8)
    if path.is_dir():  # else the rename fails after the whole state was written
        raise StateFileError(f"{path}: cannot write the tracker state there: it is a directory")
    try:
        with atomic_file(path) as tmp, open(tmp, "wb") as fh:
            np.savez(fh, __header__=blob, **arrays)
    except OSError as exc:
        # whatever failed (a full disk, a read-only or missing directory), the temporary
        # file is gone and an existing state file at ``path`` is untouched (atomic_file)
        what = exc.strerror or str(exc)
        if not path.parent.is_dir():
            what = f"its directory {path.parent} does not exist"
        raise StateFileError(f"{path}: cannot write the tracker state ({what})") from None
    return path


def read_state(path) -> tuple[dict[str, np.ndarray], dict, dict, dict]:
    """Read and verify a state file: ``(arrays, config, scalars, rng)``; see :func:`read_run`.

    Raises :class:`StateFileError` (a ValueError) for anything but an intact
    file of this format and version. Value checks beyond the checksum are the
    tracker's (:func:`validate_tracker_arrays`).
    """
    header, arrays = _read_verified(path)
    return arrays, header["config"], header["scalars"], header["rng"]


def _read_verified(path):
    """(header, arrays) of an intact state file of this format and version."""
    path = Path(path)

    def bad(what: str) -> StateFileError:
        return StateFileError(f"{path}: {what}")

    try:
        with open(path, "rb") as fh:
            magic = fh.read(4)
    except FileNotFoundError:
        raise bad("no such tracker state file") from None
    except OSError as exc:
        raise bad(f"cannot be read ({exc.strerror or exc})") from None
    if magic[:1] == _PICKLE_MAGIC:
        raise bad(
            "is a pickle checkpoint of an older jointtrack; pickle files can run arbitrary "
            "code when loaded, so they are refused — start the run again to write a "
            f"{FORMAT} file"
        )
    if magic != _ZIP_MAGIC:
        raise bad(f"not a jointtrack tracker state file (no {FORMAT} archive)")
    try:
        with zipfile.ZipFile(path) as zf:
            for info in zf.infolist():
                if info.file_size > _MAX_MEMBER_BYTES:
                    raise bad(f"member {info.filename} claims {info.file_size} bytes: damaged")
        with np.load(path, allow_pickle=False) as npz:
            names = list(npz.files)
            if "__header__" not in names:
                raise bad(f"not a {FORMAT} file (no header)")
            arrays = {k: npz[k] for k in names}
    except StateFileError:
        raise
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, KeyError, MemoryError) as exc:
        raise bad(f"damaged or truncated state file ({type(exc).__name__}: {exc})") from None
    except Exception as exc:  # zlib.error and friends: never a raw traceback
        raise bad(f"damaged state file ({type(exc).__name__}: {exc})") from None
    blob = arrays.pop("__header__")
    if blob.dtype != np.uint8 or blob.ndim != 1:
        raise bad("damaged header")
    try:
        header = json.loads(blob.tobytes().decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise bad(f"damaged header ({exc})") from None
    except RecursionError:  # JSON nested deeper than the parser's recursion limit
        raise bad("damaged header (JSON nested too deeply)") from None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise bad(f"not a {FORMAT} file")
    version = header.get("version")
    if type(version) is not int or version not in _READABLE:
        raise bad(
            f"state format version {version!r} is not supported (this jointtrack writes "
            f"version {VERSION} and reads versions {', '.join(map(str, _READABLE))})"
        )
    digest = header.pop("sha256", None)
    if not isinstance(digest, str) or digest != _digest(header, arrays):
        raise bad("checksum mismatch: the file is damaged or was edited")
    for key in ("config", "scalars", "rng"):
        if not isinstance(header.get(key), dict):
            raise bad(f"header has no {key}")
    if version < VERSION:
        _upgrade(header, arrays)
        _upgrade_poisson(header, arrays)
    _fill_added_settings(header, arrays)
    return header, arrays


def _fill_added_settings(header: dict, arrays: dict) -> None:
    """Fill the JPDA settings (and their arrays) added after a state file was written,
    in place.

    ``exact_max_bits_tentative`` (issue 25) gets None: tentative clusters budgeted
    by ``exact_max_tracks`` like confirmed ones, as every earlier jointtrack did, so
    the continued run is identical (not the new default, which would change it).
    ``coalescence_avoidance`` gets False (plain JPDA β), what every earlier state ran.
    """
    if header["scalars"].get("tracker", "jpda") != "jpda":
        return
    header["config"].setdefault("exact_max_bits_tentative", None)
    # coalescence_avoidance (JPDA*, issue 32) came after version 5: plain JPDA, as written
    header["config"].setdefault("coalescence_avoidance", False)
    # id_continuation (issue 32) came after version 6: off, as every earlier state ran,
    # and nothing remembered (a state written with the key must hold the arrays)
    if "id_continuation" not in header["config"]:
        header["config"]["id_continuation"] = 0.0
        for name, shape in _RETIRED_EMPTY.items():
            arrays.setdefault(name, np.zeros(shape, np.int64 if name == "retired_ids" else float))
    # the IMM's switching per second and per-mode q (issue 32) came after version 6:
    # per scan and one q, as every earlier state ran
    header["config"].setdefault("imm_switching_per", "scan")
    header["config"].setdefault("imm_process_noise", None)
    # tentative_association (issue 33) came after version 6: one joint association, as
    # every earlier state ran
    header["config"].setdefault("tentative_association", "joint")
    # tentative_process_noise (issue 33) came after version 6: none, as every earlier state ran
    header["config"].setdefault("tentative_process_noise", 0.0)
    # the track components of tentative_association = "splitting" (issue 33) came after
    # version 6: no earlier state holds a splitting track, so none (a state written with
    # the settings must hold the arrays)
    if "tentative_components" not in header["config"] and "ids" in arrays:
        # the settings' own defaults (one copy of each: TrackerConfig's fields)
        defaults = {f.name: f.default for f in dataclasses.fields(TrackerConfig)}
        header["config"]["tentative_components"] = defaults["tentative_components"]
        header["config"].setdefault("tentative_confirm_state", defaults["tentative_confirm_state"])
        n, w = len(arrays["ids"]), arrays["x"].shape[-1] if "x" in arrays else 0
        arrays.setdefault("comp_x", np.zeros((n, 0, w)))
        arrays.setdefault("comp_P", np.zeros((n, 0, w, w)))
        arrays.setdefault("comp_log_w", np.zeros((n, 0)))
        arrays.setdefault("comp_n", np.zeros(n, np.int64))
    if header["version"] < 5:  # the IMM settings (issue 32) did not exist
        for key, value in _IMM_SETTINGS.items():
            header["config"].setdefault(key, value)
    # each track's last update (issue 32, reporting targets predicted from it) came
    # after version 6: the saved state at the saved time, where an earlier run predicted
    # from (absent fields the validation names stay absent)
    if "updated_time" not in arrays and "ids" in arrays:
        t = header["scalars"].get("time")
        ok = isinstance(t, int | float) and not isinstance(t, bool)
        t = float(t) if ok and abs(t) < 1e300 else 0.0  # a bad time is refused later
        arrays["updated_time"] = np.full(len(arrays["ids"]), t)
        for name in ("x", "P", "mode_x", "mode_P", "mode_log_prob"):
            if name in arrays:
                arrays.setdefault("updated_" + name, np.array(arrays[name], copy=True))


#: the id-continuation fields of a JPDA state (empty: nothing remembered), by shape
#: with 0 for the state's 2·dim (an empty array's width is not checked)
_RETIRED_EMPTY = {
    "retired_ids": (0,),
    "retired_x": (0, 0),
    "retired_P": (0, 0, 0),
    "retired_time": (0,),
}


def check_array_fields(path, arrays: dict, spec: dict) -> None:
    """Each field of ``spec`` {name: (dtype kind, ndim)} present in ``arrays`` with that
    kind and number of dimensions, and finite where it is float; StateFileError naming
    the field (the shapes' agreement is the caller's)."""
    for name, (kind, ndim) in spec.items():
        if name not in arrays:
            raise StateFileError(f"{path}: missing field {name!r}")
        a = arrays[name]
        if a.dtype.kind != kind or a.ndim != ndim:
            raise StateFileError(
                f"{path}: field {name!r} has dtype {a.dtype} and {a.ndim} dimension(s)"
            )
        if kind == "f" and not np.isfinite(a).all():
            raise StateFileError(f"{path}: field {name!r} has non-finite values")


def validate_retired_arrays(path, arrays: dict, scalars: dict, width: int) -> None:
    """Check a JPDA state's id-continuation fields (``retired_ids``, ``retired_x``
    (k, width), ``retired_P`` (k, width, width), ``retired_time`` (k,)):
    StateFileError naming the field."""

    def bad(what: str) -> StateFileError:
        return StateFileError(f"{path}: {what}")

    check_array_fields(
        path,
        arrays,
        {
            "retired_ids": ("i", 1),
            "retired_x": ("f", 2),
            "retired_P": ("f", 3),
            "retired_time": ("f", 1),
        },
    )
    k = len(arrays["retired_ids"])
    if k == 0:
        for name in ("retired_x", "retired_P", "retired_time"):
            if arrays[name].shape[0] != 0:
                raise bad("fields 'retired_*' have inconsistent shapes")
        arrays["retired_x"] = np.zeros((0, width))
        arrays["retired_P"] = np.zeros((0, width, width))
        return
    if (
        arrays["retired_x"].shape != (k, width)
        or arrays["retired_P"].shape != (k, width, width)
        or arrays["retired_time"].shape != (k,)
    ):
        raise bad("fields 'retired_*' have inconsistent shapes")
    problem = covariance_problem(arrays["retired_P"])
    if problem:
        raise bad(f"field 'retired_P' holds a covariance that {problem}")
    ids = arrays["retired_ids"]
    if len(np.unique(ids)) != k or ((ids < 1) | (ids >= scalars["next_id"])).any():
        raise bad("field 'retired_ids' holds repeated ids or ids the tracker never issued")
    if np.isin(ids, arrays["ids"]).any():
        raise bad("field 'retired_ids' holds the id of a live track")


def validate_update_arrays(path, arrays: dict, scalars: dict, state_dim: int, modes) -> None:
    """Check a JPDA state's last-update fields (``updated_time`` (N,), ``updated_x``
    (N, n), ``updated_P`` (N, n, n) and the IMM's ``updated_mode_*``): finite, no
    update after the state's time, valid covariances; StateFileError naming the field."""

    def bad(what: str) -> StateFileError:
        return StateFileError(f"{path}: {what}")

    check_array_fields(
        path, arrays, {"updated_time": ("f", 1), "updated_x": ("f", 2), "updated_P": ("f", 3)}
    )
    N = len(arrays["ids"])
    for name, shape in (
        ("updated_time", (N,)),
        ("updated_x", (N, state_dim)),
        ("updated_P", (N, state_dim, state_dim)),
    ):
        if arrays[name].shape != shape:
            raise bad(f"field {name!r} has shape {arrays[name].shape}, expected {shape}")
    problem = covariance_problem(arrays["updated_P"])
    if problem:
        raise bad(f"field 'updated_P' holds a covariance that {problem}")
    t = scalars.get("time")
    if N and isinstance(t, int | float) and (arrays["updated_time"] > t).any():
        raise bad("field 'updated_time' holds a time after the state's time")
    validate_mode_arrays(path, arrays, modes, prefix="updated_")


def validate_component_arrays(path, arrays: dict, state_dim: int, slots: int) -> None:
    """Check a JPDA state's track components (``tentative_association = "splitting"``,
    :mod:`jointtrack.trackers.track_splitting`): ``comp_x`` (N, K, n), ``comp_P``
    (N, K, n, n), ``comp_log_w`` (N, K), ``comp_n`` (N,) with K = ``slots``. Each
    tentative track holds 1 … K components, a confirmed one none; the slots in use hold
    valid covariances and log weights that sum to one (to 1e-9), the rest zeros.
    Raises :class:`StateFileError` naming the field."""

    def bad(what: str) -> StateFileError:
        return StateFileError(f"{path}: {what}")

    check_array_fields(
        path,
        arrays,
        {"comp_x": ("f", 3), "comp_P": ("f", 4), "comp_log_w": ("f", 2), "comp_n": ("i", 1)},
    )
    N, n, K = len(arrays["ids"]), state_dim, slots
    for name, shape in (
        ("comp_x", (N, K, n)),
        ("comp_P", (N, K, n, n)),
        ("comp_log_w", (N, K)),
        ("comp_n", (N,)),
    ):
        if arrays[name].shape != shape:
            raise bad(f"field {name!r} has shape {arrays[name].shape}, expected {shape}")
    counts = arrays["comp_n"]
    confirmed = arrays["confirmed"]
    low = np.where(confirmed, 0, min(K, 1))
    high = np.where(confirmed, 0, K)
    if ((counts < low) | (counts > high)).any():
        i = int(np.argmax((counts < low) | (counts > high)))
        raise bad(
            f"field 'comp_n' gives track {i} {counts[i]} components (a tentative track "
            f"holds 1 to {K}, a confirmed one none)"
        )
    used = np.arange(K)[None, :] < counts[:, None]
    if (
        arrays["comp_x"][~used].any()
        or arrays["comp_P"][~used].any()
        or arrays["comp_log_w"][~used].any()
    ):
        raise bad("fields 'comp_*' hold values in slots no component uses")
    problem = covariance_problem(arrays["comp_P"][used])
    if problem:
        raise bad(f"field 'comp_P' holds a covariance that {problem}")
    lw = np.where(used, arrays["comp_log_w"], -np.inf)
    top = lw.max(axis=1, initial=-np.inf)
    has = counts > 0
    tot = np.log(np.exp(lw[has] - top[has, None]).sum(axis=1)) + top[has]
    if (np.abs(tot) > 1e-9).any():
        raise bad("field 'comp_log_w': a track's component weights do not sum to 1")


def _upgrade(header: dict, arrays: dict) -> None:
    """Bring an intact version-3 or 4 JPDA state to version 5, in place.

    Version 5 added the per-track modes of ``motion = "imm"`` (``mode_x``,
    ``mode_P``, ``mode_log_prob``; zero modes for the CV/CA trackers every
    earlier state holds) and the IMM settings (:data:`_IMM_SETTINGS`, unused by
    those trackers).

    Version 4 added the settings and track arrays of reporting targets
    (``reporting``, ``report_interval``, ``p_survive_per``, ``max_coast``,
    ``velocity_std``, ``measure_velocity``, ``r_labelled``; ``last_hit``, ``born``,
    ``report_count``, ``labels``). A version-3 run used none of them, so they are filled with the
    values under which version 4 behaves exactly as version 3 did (a scanning
    sensor, survival per scan, no time-based deletion, no labels) — not
    guessed defaults: the continued run is identical.
    """
    if header["scalars"].get("tracker", "jpda") != "jpda" or "ids" not in arrays:
        return
    config = header["config"]
    for key, value in (
        ("reporting", "scan"),
        ("report_interval", 60.0),
        ("p_survive_per", "scan"),
        ("max_coast", math.inf),
        ("velocity_std", 1.0),
        ("measure_velocity", False),
        ("r_labelled", 0.999),
    ):
        config.setdefault(key, value)
    n = len(arrays["ids"])
    clock = header["scalars"].get("time")
    clock = float(clock) if isinstance(clock, int | float) else 0.0
    arrays.setdefault("last_hit", np.full(n, clock))
    arrays.setdefault("born", np.full(n, clock))
    arrays.setdefault("report_count", np.zeros(n))
    arrays.setdefault("labels", np.full(n, "", dtype="U1"))
    arrays.setdefault("label_names", np.zeros(0, dtype="U1"))
    arrays.setdefault("label_ids", np.zeros(0, np.int64))
    arrays.setdefault("mode_x", np.zeros((n, 0, 0)))
    arrays.setdefault("mode_P", np.zeros((n, 0, 0, 0)))
    arrays.setdefault("mode_log_prob", np.zeros((n, 0)))


def _upgrade_poisson(header: dict, arrays: dict) -> None:
    """Bring an intact PMB/PMBM state of version 5 or before to version 6, in place.

    Version 6 (issue 32) gave the PMB/PMBM trackers reporting targets: each
    Bernoulli's (PMBM: single-target hypothesis') birth time and reports
    (``born``/``report_count``, ``sth_born``/``sth_reports``) and the labelled
    Bernoullis with the label table (``labelled_*``, ``label_names``,
    ``label_ids``). An older run used none of them (a scanning sensor, no labels:
    its settings get ``reporting = "scan"`` from
    :data:`~jointtrack.trackers.pmbm_config._ADDED_SETTINGS`), so they are filled
    with values that continue it exactly: birth at the state's clock, no reports,
    no labelled Bernoulli.
    """
    kind = header["scalars"].get("tracker", "jpda")
    if kind not in ("pmb", "pmbm"):
        return
    clock = header["scalars"].get("time")
    clock = float(clock) if isinstance(clock, int | float) else 0.0
    count = "existence" if kind == "pmb" else "sth_r"
    n = len(arrays[count]) if count in arrays else 0
    born, reports = ("born", "report_count") if kind == "pmb" else ("sth_born", "sth_reports")
    arrays.setdefault(born, np.full(n, clock))
    arrays.setdefault(reports, np.zeros(n))
    width = arrays["poisson_m"].shape[1] if arrays.get("poisson_m", np.zeros(0)).ndim == 2 else 0
    arrays.setdefault("labelled_r", np.zeros(0))
    arrays.setdefault("labelled_x", np.zeros((0, width)))
    arrays.setdefault("labelled_P", np.zeros((0, width, width)))
    arrays.setdefault("labelled_ids", np.zeros(0, np.int64))
    arrays.setdefault("labelled_labels", np.zeros(0, dtype="U1"))
    arrays.setdefault("labelled_born", np.zeros(0))
    arrays.setdefault("labelled_reports", np.zeros(0))
    arrays.setdefault("label_names", np.zeros(0, dtype="U1"))
    arrays.setdefault("label_ids", np.zeros(0, np.int64))
    # zero IMM modes: the CV/CA trackers every older state holds
    modes = "mode_" if kind == "pmb" else "sth_mode_"
    for prefix, k in ((modes, n), ("labelled_mode_", 0)):
        arrays.setdefault(prefix + "x", np.zeros((k, 0, 0)))
        arrays.setdefault(prefix + "P", np.zeros((k, 0, 0, 0)))
        arrays.setdefault(prefix + "log_prob", np.zeros((k, 0)))


def read_run(path):
    """The ``run`` bookkeeping stored with a state file (None if there is none); verified."""
    header, _ = _read_verified(path)
    return header.get("run")


def validate_tracker_arrays(path, arrays: dict, scalars: dict, state_dim: int, dim: int) -> None:
    """Check shapes, dtypes and values of a tracker's arrays; StateFileError naming the field."""

    def bad(what: str) -> StateFileError:
        return StateFileError(f"{path}: {what}")

    spec = {
        "x": ("f", 2),
        "P": ("f", 3),
        "ids": ("i", 1),
        "confirmed": ("b", 1),
        "history": ("i", 1),
        "age": ("i", 1),
        "misses": ("i", 1),
        "existence": ("f", 1),
        "seeds": ("f", 2),
        "seed_covs": ("f", 3),
        "seed_times": ("f", 1),
        "last_hit": ("f", 1),
        "born": ("f", 1),
        "report_count": ("f", 1),
        "labels": ("U", 1),
        "label_names": ("U", 1),
        "label_ids": ("i", 1),
    }
    check_array_fields(path, arrays, spec)
    N = arrays["x"].shape[0]
    if arrays["x"].shape != (N, state_dim):
        raise bad(f"field 'x' has shape {arrays['x'].shape}, expected (N, {state_dim})")
    if arrays["P"].shape != (N, state_dim, state_dim):
        raise bad(
            f"field 'P' has shape {arrays['P'].shape}, expected ({N}, {state_dim}, {state_dim})"
        )
    per_track = ("ids", "confirmed", "history", "age", "misses", "existence")
    for name in (*per_track, "last_hit", "born", "report_count", "labels"):
        if arrays[name].shape != (N,):
            raise bad(f"field {name!r} has shape {arrays[name].shape}, expected ({N},)")
    k = arrays["seeds"].shape[0]
    if (
        arrays["seeds"].shape != (k, dim)
        or arrays["seed_covs"].shape != (k, dim, dim)
        or arrays["seed_times"].shape != (k,)
    ):
        raise bad("fields 'seeds'/'seed_covs'/'seed_times' have inconsistent shapes")
    for name in ("P", "seed_covs"):
        problem = covariance_problem(arrays[name])
        if problem:
            raise bad(f"field {name!r} holds a covariance that {problem}")
    ex = arrays["existence"]
    if ((ex < 0) | (ex > 1)).any():
        raise bad("field 'existence' has values outside [0, 1]")
    for name in ("history", "age", "misses", "report_count"):
        if (arrays[name] < 0).any():
            raise bad(f"field {name!r} has negative values")
    named = arrays["labels"][arrays["labels"] != ""]
    if len(np.unique(named)) != len(named):
        # the label → track lookup of JPDATracker needs one track per label
        raise bad("field 'labels' names one target on two tracks")
    validate_counters(path, arrays["ids"], scalars)
    names, numbers = arrays["label_names"], arrays["label_ids"]
    if names.shape != numbers.shape or (len(names) and not (names[1:] > names[:-1]).all()):
        raise bad("fields 'label_names'/'label_ids' are not one sorted list of distinct labels")
    if len(numbers) and ((numbers < 1) | (numbers >= scalars["next_id"])).any():
        raise bad("field 'label_ids' holds ids the tracker never issued")


def validate_mode_arrays(path, arrays: dict, modes, prefix: str = "", count=None) -> None:
    """Check the IMM fields ``mode_x``, ``mode_P``, ``mode_log_prob`` of a state.

    ``prefix``: of the field names (the PMB/PMBM trackers' ``labelled_``, ``sth_``);
    ``count``: how many tracks they hold (default: the length of ``ids``).

    ``modes``: the tracker's :class:`~jointtrack.filters.imm.IMMModes`, or None
    (then every track has zero modes). Each mode's state must be finite and zero
    outside the mode's own components, its covariance there symmetric positive
    definite and zero elsewhere, and each track's log mode probabilities finite
    and normalised (to 1e-9). Raises :class:`StateFileError` naming the field.
    """

    def bad(what: str) -> StateFileError:
        return StateFileError(f"{path}: {what}")

    N = len(arrays["ids"]) if count is None else count
    r, n = (modes.n_modes, modes.state_dim) if modes is not None else (0, 0)
    x_name, P_name, lp_name = (prefix + k for k in ("mode_x", "mode_P", "mode_log_prob"))
    for name, shape in (
        (x_name, (N, r, n)),
        (P_name, (N, r, n, n)),
        (lp_name, (N, r)),
    ):
        if name not in arrays:
            raise bad(f"missing field {name!r}")
        a = arrays[name]
        if a.dtype.kind != "f" or a.shape != shape:
            raise bad(
                f"field {name!r} has dtype {a.dtype} and shape {a.shape}, expected float "
                f"{shape} ({r} modes of the configuration's motion)"
            )
        if not np.isfinite(a).all():
            raise bad(f"field {name!r} has non-finite values")
    if modes is None or N == 0:
        return
    mx, mP, lp = arrays[x_name], arrays[P_name], arrays[lp_name]
    for j, idx in enumerate(modes.mode_indices):
        other = np.setdiff1d(np.arange(n), idx)
        outside = mP[:, j][:, other].any() or mP[:, j][:, :, other].any()
        if outside or mx[:, j, other].any():
            raise bad(f"field '{x_name}'/'{P_name}': mode {j} has components outside its model")
        problem = covariance_problem(mP[:, j][:, idx[:, None], idx[None, :]])
        if problem:
            raise bad(f"field '{P_name}' holds a covariance of mode {j} that {problem}")
    top = lp.max(axis=1, keepdims=True)
    tot = np.log(np.exp(lp - top).sum(axis=1)) + top[:, 0]
    if (np.abs(tot) > 1e-9).any():
        i = int(np.argmax(np.abs(tot) > 1e-9))
        raise bad(f"field '{lp_name}': the mode probabilities of track {i} do not sum to 1")


def validate_counters(path, ids: np.ndarray, scalars: dict, field: str = "ids") -> None:
    """Check a state's track ids, ``next_id``, ``n_scans`` and ``time`` (every tracker kind).

    ``ids``: the distinct positive track ids the state holds (the array
    ``field``); ``next_id`` must be above all of them. Raises
    :class:`StateFileError` naming the field.
    """

    def bad(what: str) -> StateFileError:
        return StateFileError(f"{path}: {what}")

    if (ids < 1).any() or len(np.unique(ids)) != len(ids):
        raise bad(f"field {field!r} must hold distinct positive track ids")
    for name in ("next_id", "n_scans"):
        v = scalars.get(name)
        if not isinstance(v, int) or isinstance(v, bool) or not 0 <= v <= MAX_ID:
            shown = v if not isinstance(v, int) or abs(v) < 10**30 else f"{len(str(v))}-digit int"
            raise bad(f"scalar {name!r} must be an integer in [0, 2**62], got {shown!r}")
    if len(ids) and scalars["next_id"] <= int(ids.max()):
        raise bad("scalar 'next_id' is not above every track id")
    t = scalars.get("time")
    if t is not None:
        try:  # a Python int beyond the float range overflows float() (and math.isfinite)
            ok = isinstance(t, int | float) and not isinstance(t, bool) and math.isfinite(float(t))
        except OverflowError:
            ok = False
        if not ok:
            shown = t if not isinstance(t, int) or abs(t) < 10**30 else f"{len(str(t))}-digit int"
            raise bad(f"scalar 'time' must be a finite number or null, got {shown!r}")


def covariance_problem(cov: np.ndarray) -> str | None:
    """What keeps a stack (K, d, d) of covariances out of a tracker state, or None.

    The one test both :func:`validate_tracker_arrays` (on load) and
    ``JPDATracker.start_tracks`` (on the way in) apply, so that every state the
    API accepts can be saved and loaded again: finite, symmetric to 1e-9 relative
    and positive definite (Cholesky). Returns e.g. ``"is not symmetric (track 3)"``.
    """
    if not len(cov):
        return None
    finite = np.isfinite(cov).reshape(len(cov), -1).all(axis=1)
    if not finite.all():
        return f"has non-finite entries (track {int(np.argmin(finite))})"
    asym = np.abs(cov - cov.transpose(0, 2, 1)).reshape(len(cov), -1).max(axis=1)
    scale = np.abs(cov).reshape(len(cov), -1).max(axis=1)
    bad = asym > 1e-9 * np.maximum(scale, 1e-300)
    if bad.any():
        return f"is not symmetric (track {int(np.argmax(bad))})"
    try:
        np.linalg.cholesky(cov)
        return None
    except np.linalg.LinAlgError:
        pass
    for i in range(len(cov)):
        try:
            np.linalg.cholesky(cov[i])
        except np.linalg.LinAlgError:
            return f"is not positive definite (track {i})"
    return "is not positive definite"  # pragma: no cover
