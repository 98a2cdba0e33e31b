"""The public real data of the real-data benchmark, fetched through the package registry.

Two packages on PyPI carry recorded AIS and ADS-B data beside their code:

* ``stonesoup==1.9.1`` **source distribution** (the wheel lacks the demos):
  ``docs/demos/SolentAIS_20160112_130211.csv`` (18,623 AIS reports of the Solent,
  the data of Stone Soup's ``AIS_Solent_Tracker.py``) and
  ``docs/demos/OpenSky_Plane_States.csv`` (OpenSky ADS-B state vectors of
  ``OpenSky_Demo.py``);
* ``traffic==2.13`` **wheel**: ``traffic/data/samples/collections/quickstart.json.gz``
  (3 h, 213 aircraft) and ``switzerland.json.gz`` (about 17 h, 842 aircraft), gzip
  JSON lists of records.

:func:`fetch_realdata` downloads the two archives with ``pip download --no-deps``
into a cache folder when they are missing, extracts the four files and checks
them against the SHA-256 digests below (measured on the archives PyPI served in
2026, so a changed upload or a corrupt download is refused rather than silently
benchmarked). Neither the package nor its tests depend on this data.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tarfile
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

__all__ = ["DATA_FILES", "RealDataError", "default_cache_dir", "fetch_realdata"]


class RealDataError(RuntimeError):
    """The real data could not be fetched, extracted or verified (the message says what to do)."""


@dataclass(frozen=True)
class DataFile:
    """One file of the real data: where it sits in which archive, and its SHA-256."""

    archive: str  # the key of ARCHIVES
    member: str  # path inside the archive
    sha256: str


#: the two archives: (file name pip writes, pip requirement, extra pip arguments)
ARCHIVES = {
    "stonesoup": (
        "stonesoup-1.9.1.tar.gz",
        "stonesoup==1.9.1",
        # the sdist: only it carries docs/demos
        ("--no-binary", ":all:"),
    ),
    "traffic": ("traffic-2.13-py3-none-any.whl", "traffic==2.13", ()),
}

#: the four files, by the key :func:`fetch_realdata` returns them under
DATA_FILES = {
    "solent_ais": DataFile(
        "stonesoup",
        "stonesoup-1.9.1/docs/demos/SolentAIS_20160112_130211.csv",
        "53adaa090db13bd5b0867daf3459e3d96faf5c87ce429f3b4072c7444b5e88d1",
    ),
    "opensky_states": DataFile(
        "stonesoup",
        "stonesoup-1.9.1/docs/demos/OpenSky_Plane_States.csv",
        "4e5132735a1ccedf5c1dfd8108bf7f64a8e47483c4435c342eca202d4fa9e746",
    ),
    "quickstart": DataFile(
        "traffic",
        "traffic/data/samples/collections/quickstart.json.gz",
        "0ef1a97f6b96c31a58e2d9cf58af01a90016eb97472f37718dcba3913c682403",
    ),
    "switzerland": DataFile(
        "traffic",
        "traffic/data/samples/collections/switzerland.json.gz",
        "ff5be108224b2a96892a697faf2a7492bf530e64d145d9675eb927c4ed97d4c3",
    ),
}

EXTRACTED = "extracted"


def default_cache_dir() -> Path:
    """``$JOINTTRACK_DATA`` if set, else ``~/.cache/jointtrack/realdata``."""
    env = os.environ.get("JOINTTRACK_DATA")
    if env:
        return Path(env).expanduser()
    return Path.home() / ".cache" / "jointtrack" / "realdata"


def sha256_of(path: Path) -> str:
    """SHA-256 (hex) of a file (:func:`jointtrack.io._files.file_sha256`)."""
    from jointtrack.io._files import file_sha256

    return file_sha256(path)


def _by_hand(cache: Path) -> str:
    """What to run elsewhere when this machine cannot download."""
    lines = [
        f"python -m pip download --no-deps {' '.join(extra)} {req} -d {cache}"
        for _, req, extra in ARCHIVES.values()
    ]
    names = ", ".join(name for name, _, _ in ARCHIVES.values())
    return (
        f"download {names} by hand on a machine with network access ("
        + "; ".join(lines)
        + f") and copy them into {cache}"
    )


def _pip_download(key: str, cache: Path, runner) -> Path:
    """``pip download --no-deps`` one archive into ``cache``; the archive's path."""
    name, requirement, extra = ARCHIVES[key]
    command = [sys.executable, "-m", "pip", "download", "--no-deps", *extra, requirement]
    command += ["-d", str(cache)]
    try:
        done = runner(command, capture_output=True, text=True)
    except OSError as exc:  # no python/pip executable at all
        raise RealDataError(f"cannot run pip ({exc}); {_by_hand(cache)}") from exc
    path = cache / name
    if done.returncode != 0 or not path.is_file():
        tail = " ".join((done.stderr or done.stdout or "").split()[-40:])
        raise RealDataError(
            f"pip download {requirement} failed (exit {done.returncode}: {tail or 'no output'}); "
            + _by_hand(cache)
        )
    return path


def _extract(archive_key: str, archive: Path, members: list[tuple[str, Path]]) -> None:
    """Copy ``members`` (archive path, destination) out of an sdist (.tar.gz) or wheel (.zip)."""
    try:
        if archive.name.endswith(".tar.gz"):
            with tarfile.open(archive, "r:gz") as tar:
                for member, dest in members:
                    source = tar.extractfile(member)
                    if source is None:
                        raise KeyError(member)
                    with source, open(dest, "wb") as out:
                        shutil.copyfileobj(source, out)
        else:
            with zipfile.ZipFile(archive) as zf:
                for member, dest in members:
                    with zf.open(member) as source, open(dest, "wb") as out:
                        shutil.copyfileobj(source, out)
    except KeyError as exc:
        raise RealDataError(
            f"{archive} has no {exc.args[0]}: not the {ARCHIVES[archive_key][1]} archive; "
            "delete it and run again"
        ) from exc
    except (tarfile.TarError, zipfile.BadZipFile, EOFError, OSError) as exc:
        raise RealDataError(
            f"cannot extract {archive} ({exc}): a damaged download? delete it and run again"
        ) from exc


def fetch_realdata(
    cache_dir=None,
    progress: Callable[[str], None] | None = print,
    *,
    _run=subprocess.run,
) -> dict[str, Path]:
    """Download (if missing), extract and verify the real data; the four files' paths.

    Parameters
    ----------
    cache_dir : folder for the archives (created if missing); default
        :func:`default_cache_dir`. The files are extracted into
        ``cache_dir/extracted``.
    progress : called with one line per download or extraction; ``None`` is silent.
    _run : ``subprocess.run`` (replaced by the tests with a fake pip).

    Returns
    -------
    dict with keys ``solent_ais``, ``opensky_states``, ``quickstart``,
    ``switzerland`` (see :data:`DATA_FILES`).

    Raises
    ------
    RealDataError
        pip or the network is unavailable (the message says what to download by
        hand and where to put it), the cache folder is unusable, or a file's
        SHA-256 differs from the recorded one.
    """
    say = progress or (lambda _msg: None)
    cache = default_cache_dir() if cache_dir is None else Path(cache_dir).expanduser()
    if cache.exists() and not cache.is_dir():
        raise RealDataError(f"cache_dir {cache} exists and is not a folder")
    extracted = cache / EXTRACTED
    try:
        extracted.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RealDataError(f"cache_dir {cache}: cannot create {extracted} ({exc})") from exc
    if not os.access(extracted, os.W_OK):
        raise RealDataError(f"cache_dir {cache}: {extracted} is not writable")

    paths = {key: extracted / Path(f.member).name for key, f in DATA_FILES.items()}
    for archive_key in ARCHIVES:
        wanted = [
            (key, f)
            for key, f in DATA_FILES.items()
            if f.archive == archive_key
            and not (paths[key].is_file() and sha256_of(paths[key]) == f.sha256)
        ]
        if not wanted:
            continue
        archive = cache / ARCHIVES[archive_key][0]
        if not archive.is_file():
            say(f"downloading {ARCHIVES[archive_key][1]} into {cache} (pip download --no-deps)")
            archive = _pip_download(archive_key, cache, _run)
        say(f"extracting {', '.join(Path(f.member).name for _, f in wanted)} from {archive.name}")
        _extract(archive_key, archive, [(f.member, paths[key]) for key, f in wanted])
        for key, f in wanted:
            got = sha256_of(paths[key])
            if got != f.sha256:
                paths[key].unlink(missing_ok=True)
                raise RealDataError(
                    f"{Path(f.member).name} from {archive} has SHA-256 {got}, expected "
                    f"{f.sha256}: delete {archive} and run again, or download it by hand ("
                    + _by_hand(cache)
                    + ")"
                )
    return paths


if __name__ == "__main__":  # python -m jointtrack.bench.realdata_data [CACHE_DIR]
    try:
        for key, path in fetch_realdata(sys.argv[1] if len(sys.argv) > 1 else None).items():
            print(f"{key}: {path}")
    except RealDataError as exc:
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(1)
