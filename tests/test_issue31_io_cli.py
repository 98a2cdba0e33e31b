"""Issue 31 through ``jointtrack run`` on report files: a reference whose plane cannot
hold the data (31.5), --window / --reference values named by flag (31.7, 31.14), and
AIS "position not available" rows counted in the run's metrics (31.8)."""

from __future__ import annotations

import json

import pytest

from cli_checks import one_line_error
from test_run_realdata import _run, write_ais


@pytest.fixture(scope="module")
def ais(tmp_path_factory):
    base = tmp_path_factory.mktemp("issue31")
    write_ais(base / "ais.csv")
    return base


@pytest.mark.parametrize(
    "extra, needles",
    [
        # the antipode of the ships: every track's lat/lon came out on the far side
        (["--reference", "-50.7,178.9"], ["ais.csv", "--reference", "60°", "reports lie"]),
        (["--reference", "0,90"], ["--reference", "60°"]),
        # OverflowError from the window's nanoseconds
        (["--window", "1e12"], ["--window", "1e+12", "at most 1e+09"]),
        (["--window", "1e300"], ["--window", "at most 1e+09"]),
        # refused later, without naming the flag
        (["--reference", "50.7,-1.1,1e308"], ["--reference 50.7,-1.1,1e308", "alt0"]),
        (["--reference", "50.7,-1.1,-2e6"], ["--reference", "alt0"]),
    ],
)
def test_flags_the_run_cannot_honour_are_named(ais, extra, needles):
    r = _run("--detections", ais / "ais.csv", "--out", ais / "bad", *extra)
    one_line_error(r, *needles)
    assert not (ais / "bad" / "tracks.csv").exists()


def test_a_geodetic_detections_file_with_a_wild_altitude_names_alt(tmp_path):
    p = tmp_path / "geo.csv"
    p.write_text("time,lat,lon,alt\n0,50.0,-1.0,100\n1,50.01,-1.0,1e300\n")
    r = _run("--detections", p, "--out", tmp_path / "o")
    one_line_error(r, "geo.csv", "data row 2", "column 'alt'", "1e+300")


def test_position_not_available_rows_are_counted_in_the_metrics(ais, tmp_path):
    # AIS lat 91 / lon 181 (ITU-R M.1371 "not available"): left out, counted and said
    lines = (ais / "ais.csv").read_text().splitlines()
    head, rows = lines[0], lines[1:]
    cells = rows[10].split(",")
    rows.insert(11, ",".join([cells[0], cells[1], "91", cells[3], *cells[4:]]))
    rows.insert(30, ",".join([*rows[29].split(",")[:3], "181", *rows[29].split(",")[4:]]))
    p = tmp_path / "na.csv"
    p.write_text("\n".join([head, *rows]) + "\n")
    r = _run("--detections", p, "--out", tmp_path / "o")
    assert r.exit_code == 0, r.output
    metrics = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert metrics["reports_skipped"] == 2
    assert any("2 report rows without a position left out" in n for n in metrics["notes"])
    assert "2 report rows without a position" in r.output
