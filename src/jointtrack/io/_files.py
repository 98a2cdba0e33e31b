"""The column layer shared by detections and tracks: CSV/Parquet in, columns out.

Private: :mod:`jointtrack.io.detections` and :mod:`jointtrack.io.tracks` build on it.
"""

from __future__ import annotations

import csv
import gzip
import io as _io
import itertools
import os
import re
from collections import Counter
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from jointtrack._atomic import atomic_file
from jointtrack.io.errors import DataFileError

CSV_SUFFIXES = (".csv", ".csv.gz")
PARQUET_SUFFIXES = (".parquet", ".pq")


def file_kind(path: Path, err) -> str:
    name = path.name.lower()
    if name.endswith(CSV_SUFFIXES):
        return "csv"
    if name.endswith(PARQUET_SUFFIXES):
        return "parquet"
    raise err(
        path,
        "unknown file extension; use .csv, .csv.gz, .parquet or .pq",
    )


def open_input(path: Path, err, opener):
    """``opener()`` (a file handle of ``path``), with the usual failures as ``err(path, why)``."""
    try:
        return opener()
    except FileNotFoundError:
        raise err(path, "file not found") from None
    except IsADirectoryError:
        raise err(path, "is a directory, not a file") from None
    except OSError as exc:
        raise err(path, f"cannot open file: {exc.strerror or exc}") from None


def read_csv(path: Path, err) -> tuple[list[str], list[list[str]], np.ndarray]:
    if path.name.lower().endswith(".gz"):
        fh = open_input(path, err, lambda: gzip.open(path, "rt", newline="", encoding="utf-8-sig"))
    else:
        fh = open_input(path, err, lambda: open(path, newline="", encoding="utf-8-sig"))
    header = None
    rows: list[list[str]] = []
    lines: list[int] = []
    try:
        with fh:
            records = CsvRecords(fh)
            for rec in records:
                if header is None:
                    header = [f.strip() for f in rec]
                    header_line = records.line
                    continue
                if len(rec) != len(header):
                    raise err(
                        path,
                        f"has {len(rec)} fields but the header (line {header_line}) "
                        f"has {len(header)}",
                        row=len(rows) + 1,
                        line=records.line,
                    )
                rows.append(rec)
                lines.append(records.line)
    except UnicodeDecodeError:
        raise err(path, "is not a UTF-8 text (CSV) file") from None
    except csv.Error as exc:
        raise err(path, f"malformed CSV: {exc}", line=records.line) from None
    except (OSError, EOFError) as exc:  # e.g. a corrupt .gz
        raise err(path, f"cannot read file: {exc}") from None
    if header is None:
        raise err(path, "is empty (no header line)")
    dup = _duplicates(header)
    if dup:
        raise err(path, f"duplicate column(s) in the header: {', '.join(dup)}")
    return header, rows, np.asarray(lines, dtype=np.int64)


class CsvRecords:
    """The records of a CSV text stream (opened with ``newline=""``) that hold
    something, each with the physical line it ends on (:attr:`line`, 1-based, as
    ``csv.reader.line_num`` counted it).

    Records whose fields are all blank are skipped, as before; but a run of blank
    lines between records is skipped in bulk, with ``str`` methods over the block of
    text that holds it (:class:`_CsvLines`), not one ``csv.reader`` record per line:
    a 1 MB ``.csv.gz`` that inflates to a billion newlines took 238 s record by
    record. Only lines between records are skipped: a blank line inside a quoted
    field (a label, say) reaches the parser. Blocks without blank lines go to the
    parser as a list of lines. :attr:`lines_parsed` counts the lines given to the
    parser.
    """

    def __init__(self, fh, block: int = 1 << 20):
        self._lines = _CsvLines(fh, block)
        self._reader = csv.reader(itertools.chain.from_iterable(self._lines.blocks()))

    @property
    def line(self) -> int:
        """The physical line the last record read ends on (or the parser is on)."""
        return self._reader.line_num + self._lines.skipped

    @property
    def lines_parsed(self) -> int:
        """How many lines went through ``csv.reader`` (blank runs skipped in bulk do not)."""
        return self._reader.line_num

    def __iter__(self):
        reader, lines = self._reader, self._lines
        for rec in reader:
            if "".join(rec).strip():  # some field holds more than whitespace
                yield rec
            if lines.text is not None:  # between records: blank lines are no record
                lines.skip_blank()


class _CsvLines:
    """The lines of a text stream opened with ``newline=""`` — ended by ``\\n``,
    ``\\r\\n`` or a lone ``\\r``, as the stream's own iterator splits them — in
    blocks of whole lines. A block with blank lines is given line by line, and
    :meth:`skip_blank` jumps over a run of them."""

    #: one line with its end (or the last line of the stream, without one)
    _LINE = re.compile(r"[^\r\n]*(?:\r\n|\r|\n)|[^\r\n]+\Z")
    #: a line of spaces or tabs (other whitespace-only lines are parsed one by one)
    _SPACES_LINE = re.compile(r"(?:\A|[\r\n])[ \t]+[\r\n]")

    def __init__(self, fh, block: int):
        self._fh, self._block = fh, block
        self.text: str | None = None  # the block being given line by line, if any
        self._pos = 0  # where its next line starts
        self.skipped = 0  # blank lines skipped in bulk

    def blocks(self):
        """Lists of lines (blocks without blank lines) or generators of lines."""
        while True:
            text = self._fh.read(self._block)
            if not text:
                return
            # up to the end of the line: a block holds whole lines (a \r\n is not cut)
            text += self._fh.readline()
            if self._has_blank_line(text):
                yield self._one_by_one(text)
            else:
                yield self._LINE.findall(text)

    def _has_blank_line(self, text: str) -> bool:
        # empty lines by substring search (fast); lines of spaces or tabs by a regular
        # expression, tried only where a space or tab ends a line
        if text[0] in "\r\n" or "\n\n" in text or "\r\r" in text or "\n\r" in text:
            return True
        if any(s in text for s in (" \n", " \r", "\t\n", "\t\r")) or text[0] in " \t":
            return self._SPACES_LINE.search(text) is not None
        return False

    def _one_by_one(self, text: str):
        self.text, self._pos = text, 0
        unix = "\r" not in text  # lines end at \n only: str.find, faster than a match
        try:
            while (pos := self._pos) < len(text):
                if unix:
                    end = text.find("\n", pos) + 1 or len(text)
                else:  # (a block ends with a line end, or the stream does)
                    end = self._LINE.match(text, pos).end()
                self._pos = end
                yield text[pos:end]
        finally:
            self.text = None

    def skip_blank(self) -> None:
        """Skip the whole blank lines that follow in the current block (call between
        records): up to the last line end before the next character that is not
        whitespace, found by ``str.lstrip`` over a window that grows fourfold."""
        text, pos = self.text, self._pos
        if text is None or pos >= len(text) or not text[pos].isspace():
            return
        for end in ("\n", "\r\n"):  # one empty line, then a record: the common case
            if (
                text.startswith(end, pos)
                and not text[pos + len(end) : pos + len(end) + 1].isspace()
            ):
                self.skipped += 1
                self._pos = pos + len(end)
                return
        width = 256
        while True:
            window = text[pos : pos + width]
            blank = len(window) - len(window.lstrip())
            if blank < len(window) or pos + width >= len(text):
                break
            width *= 4
        stop = pos + blank
        last = max(text.rfind("\n", pos, stop), text.rfind("\r", pos, stop))
        if last < pos:
            return
        end = last + 1
        self.skipped += text.count("\n", pos, end) + text.count("\r", pos, end)
        self.skipped -= text.count("\r\n", pos, end)
        self._pos = end


def _duplicates(names: Sequence[str]) -> list[str]:
    """Column names (lower case, non-empty) that occur more than once, sorted.

    One counting pass: a header of 100 000 columns takes milliseconds (counting
    each name in the list, as before, took seconds for 10 000 and hung for more).
    """
    counts = Counter(n.lower() for n in names)
    return sorted(n for n, k in counts.items() if k > 1 and n)


def row_error(err, path, reason: str, i: int, lines, column: str) -> DataFileError:
    """``err`` for data row ``i`` (0-based) of ``column``; ``lines``: CSV line numbers or None."""
    return err(
        path, reason, row=i + 1, line=None if lines is None else int(lines[i]), column=column
    )


def bad_cell(s: str) -> str:
    """Why the text ``s`` of a cell is not a number."""
    return "empty value" if not s.strip() else f"non-numeric value {s.strip()!r}"


def strings_to_floats(path, err, cells: Sequence[str], lines, name: str) -> np.ndarray:
    """float64 values of text cells; ``err`` at the first cell that is not a number."""
    try:
        return np.array(cells, dtype=np.float64)
    except (ValueError, TypeError):
        pass
    out = np.empty(len(cells), dtype=np.float64)
    for i, s in enumerate(cells):
        try:
            out[i] = float(s)
        except (ValueError, TypeError):
            raise row_error(err, path, bad_cell(str(s)), i, lines, name) from None
    return out  # pragma: no cover - numpy and float() agree


def strings_to_floats_nullable(path, err, cells: Sequence[str], lines, name: str) -> np.ndarray:
    """Like :func:`strings_to_floats`, but an empty cell (or ``None``) is NaN."""
    out = np.empty(len(cells), dtype=np.float64)
    for i, s in enumerate(cells):
        if s is None or not str(s).strip():
            out[i] = np.nan
            continue
        try:
            out[i] = float(s)
        except (ValueError, TypeError):
            raise row_error(err, path, bad_cell(str(s)), i, lines, name) from None
    return out


def parquet_table(path: Path, err):
    """``(column names, number of rows, read)`` of a Parquet file: only the schema is
    parsed here; ``read(indices)`` reads those columns (a pyarrow Table)."""
    try:
        import pyarrow.parquet as pq
    except ImportError:  # pragma: no cover - pyarrow is a dependency
        raise err(path, "reading Parquet needs pyarrow (pip install pyarrow)") from None
    if not path.exists():
        raise err(path, "file not found")
    if path.is_dir():
        raise err(path, "is a directory, not a file")
    try:
        pf = pq.ParquetFile(path)
        raw = list(pf.schema_arrow.names)
    except Exception as exc:  # pyarrow raises several types for a non-Parquet file
        raise err(path, f"cannot read Parquet file: {_first_line(exc)}") from None
    names = [str(n).strip() for n in raw]
    dup = _duplicates(names)
    if dup:
        raise err(path, f"duplicate column(s): {', '.join(dup)}")

    def read(indices: Sequence[int]):
        """The columns at ``indices`` (only these are read: a file may have many others)."""
        try:
            return pf.read(columns=[raw[j] for j in indices])
        except Exception as exc:  # a corrupt column chunk
            raise err(path, f"cannot read Parquet file: {_first_line(exc)}") from None

    return names, pf.metadata.num_rows, read


def _first_line(exc) -> str:
    return str(exc).splitlines()[0] if str(exc) else type(exc).__name__


def parquet_nulls(path, err, col, name: str) -> None:
    """``err`` at the first null of a pyarrow column."""
    if col.null_count:
        mask = np.asarray(col.is_null().to_numpy(zero_copy_only=False), dtype=bool)
        i = int(np.flatnonzero(mask)[0])
        raise row_error(err, path, "missing (null) value", i, None, name)


def parquet_is_numeric(t) -> bool:
    import pyarrow as pa

    return pa.types.is_integer(t) or pa.types.is_floating(t) or pa.types.is_decimal(t)


def parquet_is_string(t) -> bool:
    import pyarrow as pa

    return pa.types.is_string(t) or pa.types.is_large_string(t)


def parquet_column(path, err, col, name: str) -> np.ndarray:
    parquet_nulls(path, err, col, name)
    t = col.type
    if parquet_is_numeric(t):
        return np.asarray(col.to_numpy(zero_copy_only=False), dtype=np.float64)
    if parquet_is_string(t):
        return strings_to_floats(path, err, col.to_pylist(), None, name)
    raise err(path, f"has type {t}, expected a numeric column", column=name)


def parquet_column_nullable(path, err, col, name: str) -> np.ndarray:
    """A numeric (or numeric-text) pyarrow column with nulls (and empty text) as NaN."""
    import pyarrow as pa

    t = col.type
    if parquet_is_numeric(t) or pa.types.is_null(t):
        import pyarrow.compute as pc

        filled = pc.fill_null(col.cast(pa.float64()), float("nan"))
        return np.asarray(filled.to_numpy(zero_copy_only=False), dtype=np.float64)
    if parquet_is_string(t):
        return strings_to_floats_nullable(path, err, col.to_pylist(), None, name)
    raise err(path, f"has type {t}, expected a numeric column", column=name)


def load_columns(
    path,
    err,
    required: Sequence[str],
    optional: Sequence[str],
    parse_extras: bool,
    pick=None,
    raw: Sequence[str] = (),
):
    """Read the named columns of a CSV/Parquet file as float64 arrays.

    Required and optional columns must be finite; other columns are ignored
    unless ``parse_extras`` (then they must be numeric, NaN allowed).
    ``pick(path, names)``, if given, chooses ``(required, optional, hint)`` —
    or ``(required, optional, hint, nullable)`` — from the file's column names
    instead (``hint`` is appended to a missing-column message; it may raise
    ``err``); ``nullable`` columns may hold empty cells / nulls, read as NaN,
    and are not checked for finiteness. Columns named in ``raw`` are returned
    unparsed: a list of cell strings (CSV) or the pyarrow column (Parquet).
    Returns ``(path, columns dict, extra column names in file order, lines or
    None, number of data rows)``.
    """
    path = Path(os.fspath(path))
    kind = file_kind(path, err)
    if kind == "csv":
        header, rows, lines = read_csv(path, err)
        names = header
        n_rows = len(rows)

        def get(j, name):
            col = [r[j] for r in rows]
            if name in raw:
                return col
            if name in nullable:
                return strings_to_floats_nullable(path, err, col, lines, name)
            return strings_to_floats(path, err, col, lines, name)

    else:
        names, n_rows, read_parquet = parquet_table(path, err)
        lines = None
        table = {}  # file column index → pyarrow column, read once ``todo`` is known

        def get(j, name):
            col = table[j]
            if name in raw:
                return col
            if name in nullable:
                return parquet_column_nullable(path, err, col, name)
            return parquet_column(path, err, col, name)

    low = [n.lower() for n in names]
    hint = ""
    nullable: Sequence[str] = ()
    if pick is not None:
        picked = pick(path, names)
        required, optional, hint = picked[:3]
        if len(picked) > 3:
            nullable = picked[3]
    missing = [c for c in required if c not in low]
    if missing:
        raise err(
            path,
            f"missing required column(s): {', '.join(missing)} "
            f"(found: {', '.join(n for n in names if n) or 'none'}){hint}",
        )
    cols = {}
    wanted = list(required) + [c for c in optional if c in low]
    # extra columns keep their own spelling
    extras = [(j, n) for j, n in enumerate(names) if n and low[j] not in wanted]
    todo = [(low.index(c), c) for c in wanted] + (extras if parse_extras else [])
    if kind == "parquet":
        got = read_parquet([j for j, _ in todo])
        table.update((j, got.column(i)) for i, (j, _) in enumerate(todo))
    for j, name in todo:
        v = get(j, name)
        if name in wanted and name not in raw and name not in nullable:
            bad = ~np.isfinite(v)
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise row_error(err, path, f"non-finite value {v[i]}", i, lines, name)
        cols[name] = v
    extras = [n for _, n in extras]
    return path, cols, extras, lines, n_rows


def check_integer(
    path, err, v: np.ndarray, name: str, lines, *, advice: str = "renumber the ids"
) -> np.ndarray:
    """int64 ids of a numeric column: integral, and within ±2^53.

    The column was parsed as float64, which holds every integer only up to 2^53;
    beyond, distinct ids would merge silently (and past 2^63 not fit int64), so
    they are refused naming the row, with ``advice``.
    """
    bad = ~np.isfinite(v) | (v != np.round(v))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise row_error(err, path, f"value {float(v[i])!r} is not an integer", i, lines, name)
    big = np.abs(v) > 2.0**53
    if big.any():
        i = int(np.flatnonzero(big)[0])
        raise row_error(
            err,
            path,
            f"value {float(v[i])!r} is beyond ±2^53, where distinct integer ids would merge "
            f"as numbers; {advice}",
            i,
            lines,
            name,
        )
    return v.astype(np.int64)


# ----------------------------------------------------------------------------- writing


def out_path(path, kind_err=ValueError) -> tuple[Path, str]:
    path = Path(os.fspath(path))
    name = path.name.lower()
    if name.endswith(CSV_SUFFIXES):
        kind = "csv"
    elif name.endswith(PARQUET_SUFFIXES):
        kind = "parquet"
    else:
        raise kind_err(f"{path}: unknown file extension; use .csv, .csv.gz, .parquet or .pq")
    path.parent.mkdir(parents=True, exist_ok=True)
    return path, kind


def as_columns(table, what: str) -> dict[str, np.ndarray]:
    if isinstance(table, np.ndarray) and table.dtype.names:
        cols = {n: table[n] for n in table.dtype.names}
    elif isinstance(table, Mapping):
        cols = dict(table)
    else:
        raise ValueError(
            f"{what} must be a mapping of column name → 1-D array, or a numpy "
            f"structured array; got {type(table).__name__}"
        )
    out = {}
    n = None
    for k, v in cols.items():
        if not isinstance(k, str) or not k:
            raise ValueError(f"{what}: column names must be non-empty strings, got {k!r}")
        a = np.asarray(v)
        if a.ndim != 1:
            raise ValueError(f"{what}: column '{k}' must be 1-D, got shape {a.shape}")
        if a.size and not (np.issubdtype(a.dtype, np.number) or a.dtype == np.bool_):
            raise ValueError(f"{what}: column '{k}' must be numeric, got dtype {a.dtype}")
        if n is None:
            n = a.shape[0]
        elif a.shape[0] != n:
            raise ValueError(f"{what}: column '{k}' has {a.shape[0]} rows but the others have {n}")
        out[k] = a
    return out


def write_columns(
    path: Path, kind: str, cols: dict, int_cols, text_cols: Mapping | None = None
) -> None:
    """Write columns to CSV/Parquet, atomically (a kill leaves the old file or the new
    one). ``text_cols``: name → ``(strings, pyarrow array)`` for columns written as
    given (CSV text / Parquet array) instead of as numbers."""
    text_cols = dict(text_cols or {})
    names = list(cols)
    if kind == "parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq

        arrays = [
            text_cols[n][1]
            if n in text_cols
            else pa.array(cols[n].astype(np.int64 if n in int_cols else np.float64))
            for n in names
        ]
        with atomic_file(path) as tmp:
            pq.write_table(pa.Table.from_arrays(arrays, names=names), tmp)
        return
    n = len(next(iter(cols.values()))) if cols else 0
    txt = []
    for name in names:
        a = cols[name]
        if name in text_cols:
            txt.append(list(text_cols[name][0]))
        elif name in int_cols:
            txt.append([str(int(v)) for v in a.astype(np.int64).tolist()])
        else:
            txt.append([repr(float(v)) for v in a.astype(np.float64).tolist()])
    buf = _io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(names)
    w.writerows(zip(*txt, strict=True) if n else [])
    data = buf.getvalue().encode("utf-8")
    with atomic_file(path) as tmp, open(tmp, "wb") as fh:
        if path.name.lower().endswith(".gz"):
            # the gzip header names the file being written, not its temporary name
            with gzip.GzipFile(filename=path.name[:-3], mode="wb", fileobj=fh) as gz:
                gz.write(data)
        else:
            fh.write(data)


#: why a label or identity with a NUL character is refused
NUL_REASON = (
    "holds a NUL character (U+0000), which labels cannot keep: they are numpy strings, "
    'which drop trailing NULs, so "A" and "A\\x00" would become one label'
)


def nul_index(texts: Sequence[str]) -> int | None:
    """The index of the first text holding a NUL character, else None (:data:`NUL_REASON`)."""
    if "\x00" not in "".join(texts):  # one pass in C for the usual clean column
        return None
    return next(i for i, t in enumerate(texts) if "\x00" in t)


def text_array(path, err, texts: list[str], lines, name: str) -> np.ndarray:
    """A file column's text cells as a numpy string array; ``err`` naming the row of
    the first cell with a NUL character (:data:`NUL_REASON`)."""
    i = nul_index(texts)
    if i is not None:
        raise row_error(err, path, f"value {texts[i]!r} {NUL_REASON}", i, lines, name)
    return np.array(texts or [""], dtype=str)[: len(texts)]


def string_array(value, name: str, error=TypeError) -> np.ndarray:
    """``value`` as a numpy string (``U``) array; ``error`` naming ``name`` for
    anything but strings (an object array of str is converted; empty is fine); a
    ValueError for strings holding a NUL character (:data:`NUL_REASON`; a list is
    looked at before numpy drops its trailing NULs)."""
    if isinstance(value, np.ndarray):
        a = value
    else:
        try:
            a = np.array(value, dtype=object)
        except ValueError:  # ragged nesting
            raise error(f"{name} must be a flat sequence of strings") from None
    if a.size == 0:
        return np.zeros(a.shape, dtype=str)
    if a.dtype.kind == "O":
        vals = a.reshape(-1).tolist()
        bad = next((v for v in vals if not isinstance(v, str)), None)
        if bad is not None:
            raise error(f"{name} must hold strings, got {bad!r}")
        i = nul_index(vals)
        if i is not None:
            raise ValueError(f"{name}: {vals[i]!r} {NUL_REASON}")
        a = np.array(vals, dtype=str).reshape(a.shape)
    if a.dtype.kind != "U":
        raise error(f"{name} must hold strings, got dtype {a.dtype}")
    return a


def file_sha256(path) -> str:
    """SHA-256 (hex) of a file's bytes, read in 1 MiB blocks."""
    import hashlib

    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
