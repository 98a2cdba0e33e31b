"""Every ```python block of the README runs as written (in a scratch directory), and
prints what it says it prints.

A ``print(...)`` line with a trailing comment states its output: the comment up to
the first ``": "`` (or all of it) must be exactly what that line printed, e.g.
``print(spec.n_cells, spec.n_runs)  # 2 4`` or ``print(first)  # 3: prose``.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCKS = re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), flags=re.S)


def test_readme_has_python_examples():
    assert len(BLOCKS) >= 3


def _stated_outputs(block: str) -> dict[int, str]:
    """Line number (1-based) → the output a ``print(...)  # OUTPUT[: prose]`` line states."""
    stated = {}
    for number, line in enumerate(block.splitlines(), start=1):
        code, sep, comment = line.partition("  # ")
        if sep and code.lstrip().startswith("print("):
            stated[number] = comment.split(": ", 1)[0].strip()
    return stated


def test_stated_outputs_are_read_from_print_comments():
    block = "x = 1  # 9\nprint(x, 2)  # 1 2: prose\nprint(x)\nprint([1])  # [1]\n"
    assert _stated_outputs(block) == {2: "1 2", 4: "[1]"}


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_readme_example_runs(index, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    name = f"README.md[python block {index}]"
    printed: dict[int, list[str]] = {}

    def recording_print(*args, sep=" ", end="\n", **kwargs):
        # the README line that called print: its stated output is checked below
        frame = sys._getframe(1)
        if frame.f_code.co_filename == name:
            printed.setdefault(frame.f_lineno, []).append(sep.join(map(str, args)))
        print(*args, sep=sep, end=end, **kwargs)

    exec(compile(BLOCKS[index], name, "exec"), {"print": recording_print})
    for line, stated in _stated_outputs(BLOCKS[index]).items():
        assert printed.get(line) == [stated], (
            f"{name} line {line} says it prints {stated!r}, printed {printed.get(line)!r}"
        )


def _real_data_commands() -> list[str]:
    section = README.read_text(encoding="utf-8").split("## Real data", 1)[1]
    block = re.search(r"```bash\n(.*?)```", section, flags=re.S).group(1)
    return [line.strip() for line in block.splitlines() if line.strip()]


def test_readme_real_data_commands(tmp_path, monkeypatch):
    """The real-data section's second command runs as written on a file in the fetched
    file's place and format (the first needs the network: `jointtrack data fetch` is
    tested with a fake pip in test_bench_realdata)."""
    import datetime as dt
    import shlex

    from typer.testing import CliRunner

    from jointtrack.cli import app

    fetch, run = _real_data_commands()
    assert fetch.startswith("pip install -e . && jointtrack data fetch --cache data")
    args = shlex.split(run)
    assert args[0] == "jointtrack"
    monkeypatch.chdir(tmp_path)
    path = Path(args[args.index("--detections") + 1])
    path.parent.mkdir(parents=True)
    t0 = dt.datetime(2016, 1, 12, 13, 2, 11)
    rows = ["Time,MMSI,Latitude_degrees,Longitude_degrees,COG_degrees,SOG_knots"]
    for k in range(40):  # two vessels, one moored, one under way at 10 kn east
        t = t0 + dt.timedelta(seconds=15 * k)
        rows.append(f"{t:%Y-%m-%d %H:%M:%S}.000,235000001,50.80,-1.10,0.0,0.0")
        lon = -1.05 + 10 * 1852 / 3600 * 15 * k / (111320 * 0.633)
        rows.append(f"{t:%Y-%m-%d %H:%M:%S}.500,235000002,50.75,{lon:.7f},90.0,10.0")
    path.write_text("\n".join(rows) + "\n")
    result = CliRunner().invoke(app, args[1:])
    assert result.exit_code == 0, result.output
    out = Path(args[args.index("--out") + 1])
    for name in ("map.png", "tracks.csv", "metrics.json"):
        assert (out / name).is_file()
    import json

    score = json.loads((out / "metrics.json").read_text())["self_reports"]
    # 18 of the 19 instants: at the first (t = 0, the first report) no track is written yet
    assert score["coverage"] >= 0.94 and score["purity"] >= 0.99
