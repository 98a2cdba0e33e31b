"""CsvRecords (issue 31.8): the CSV records of a text stream with blank runs skipped in
bulk give exactly what ``csv.reader`` gives, record for record and line for line."""

from __future__ import annotations

import csv
import io

from hypothesis import example, given, settings
from hypothesis import strategies as st

from jointtrack.io._files import CsvRecords


def _reference(text: str):
    """What read_csv did before: every csv.reader record with a non-blank field, and
    the reader's line number after it; or the csv.Error and its line."""
    reader = csv.reader(io.StringIO(text, newline=""))
    out = []
    try:
        for rec in reader:
            if rec and any(f.strip() for f in rec):
                out.append((rec, reader.line_num))
    except csv.Error as exc:
        return out, (str(exc), reader.line_num)
    return out, None


def _bulk(text: str, block: int):
    records = CsvRecords(io.StringIO(text, newline=""), block=block)
    out = []
    try:
        for rec in records:
            out.append((rec, records.line))
    except csv.Error as exc:
        return out, (str(exc), records.line), records
    return out, None, records


# CSV's awkward characters: separators, quotes, every line end, whitespace, NUL
_PIECES = ["a", "é", ",", '"', " ", "\t", "\r", "\n", "\r\n", "\n\n\n", "\x0c", "\x00"]
_TEXT = st.lists(st.sampled_from(_PIECES), max_size=40).map("".join)


@settings(max_examples=1500, deadline=None)
@given(text=_TEXT, block=st.integers(1, 9))
@example(text='a\n"x\n\n\ny"\n\n\nb\n', block=1)  # blank lines inside a quoted field stay
@example(text="a\r\r\n\r\nb", block=1)  # a \r\n split across blocks is one line end
@example(text="a\n \n\t\n  ", block=2)  # whitespace-only lines, the last without an end
def test_bulk_records_equal_csv_reader_records(text, block):
    want, want_error = _reference(text)
    got, got_error, _ = _bulk(text, block)
    assert got == want
    assert got_error == want_error


@settings(max_examples=200, deadline=None)
@given(
    runs=st.lists(st.integers(0, 5000), min_size=1, max_size=6),
    ends=st.sampled_from(["\n", "\r\n", "\r", " \n", "\t\r\n"]),
)
def test_blank_runs_do_not_reach_the_parser(runs, ends):
    rows = [f"r{k},{k}" for k in range(len(runs))]
    text = "".join(ends * n + row + "\n" for n, row in zip(runs, rows, strict=True))
    got, error, records = _bulk(text, 1 << 10)
    assert error is None and got == _reference(text)[0]
    # one line per record, plus at most one partial blank line per block of text
    assert records.lines_parsed <= len(rows) + len(text) // (1 << 10) + 1
