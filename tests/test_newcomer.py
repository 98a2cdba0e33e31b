"""Issue 25 (first items): what a newcomer reads first — help texts and the package map."""

from __future__ import annotations

import re

from typer.testing import CliRunner

import jointtrack
from jointtrack.cli import app


def test_sweep_help_keeps_the_table_names():
    out = CliRunner().invoke(app, ["sweep", "--help"], env={"COLUMNS": "200"}).output
    text = re.sub(r"[│\s]+", " ", out)
    for table in ("[sweep]", "[tracker]", "[scenario]", "[metrics]", "[filter]"):
        assert table in text, table
    assert ", , " not in text


def test_package_map_and_lazy_names():
    doc = jointtrack.__doc__
    assert "jointtrack.assignment` — the one assignment-sum core" in doc
    for sub in ("permanent", "association", "trackers", "io", "metrics", "interop"):
        assert f":mod:`jointtrack.{sub}`" in doc
    names = dir(jointtrack)
    assert "JPDATracker" in names and "TrackerConfig" in names
    import textwrap

    quick = doc.split("Quick start::", 1)[1].split("Map of the package", 1)[0]
    exec(textwrap.dedent(quick.strip("\n")), {})
