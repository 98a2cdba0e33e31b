"""The rich console every command prints to.

On a terminal, rich's tables, colours and progress bars. Anywhere else (a pipe,
a log file, CI) plain text (:class:`PlainConsole`): tables as aligned columns
without box-drawing characters, no colour, no wrapping and nothing cut short,
so that a log holds whole lines of valid UTF-8 that ``grep`` and ``cut`` can read.
"""

from __future__ import annotations

from rich.console import Console
from rich.table import Table
from rich.text import Text


def make_console(**kwargs) -> Console:
    """A console for the command's output: rich on a terminal, :class:`PlainConsole`
    when output goes to a file or pipe (logs, CI)."""
    console = Console(**kwargs)
    if not console.is_terminal:
        console = PlainConsole(**kwargs)
    return console


class PlainConsole(Console):
    """A console for output that is not a terminal: plain text, one line per row.

    Tables printed to it become :func:`plain_table` text; every line is printed
    whole (``soft_wrap``: no wrapping at the console width), without colour.
    Other renderables print as rich prints them.
    """

    def __init__(self, **kwargs) -> None:
        kwargs.setdefault("no_color", True)
        kwargs.setdefault("soft_wrap", True)
        # wide enough that the renderables rich still lays out (panels, rules) need
        # not wrap; text and tables do not wrap at all
        kwargs.setdefault("width", 160)
        super().__init__(**kwargs)

    def print(self, *objects, **kwargs) -> None:  # noqa: A003 - rich's name
        objects = tuple(
            plain_table(obj, self) if isinstance(obj, Table) else obj for obj in objects
        )
        super().print(*objects, **kwargs)


def _cell_text(cell, console: Console) -> str | None:
    """A table cell's text as the table would show it (markup read), or None when the
    cell is another renderable (then the table is left to rich)."""
    if isinstance(cell, Text):
        return cell.plain
    if isinstance(cell, str):
        return console.render_str(cell).plain
    return None


def plain_table(table: Table, console: Console):
    """``table`` as plain :class:`~rich.text.Text`: its title, the header row (if
    shown) and the rows, columns padded to their widest cell and two spaces apart,
    numbers right-aligned where the column is; the table itself when a cell is not
    text (rich renders that)."""
    columns = []
    for column in table.columns:
        cells = [_cell_text(c, console) for c in column.cells]
        header = _cell_text(column.header, console) if table.show_header else ""
        if header is None or any(c is None for c in cells):
            return table
        columns.append((column, header, cells))
    n_rows = max((len(cells) for _, _, cells in columns), default=0)
    rows = []
    if table.show_header:
        rows.append([header for _, header, _ in columns])
    for r in range(n_rows):
        rows.append([cells[r] if r < len(cells) else "" for _, _, cells in columns])
    # a multi-line cell takes as many lines as it has; the other cells stay on its first
    lines = []
    for row in rows:
        split = [cell.splitlines() or [""] for cell in row]
        for k in range(max(len(s) for s in split)):
            lines.append([s[k] if k < len(s) else "" for s in split])
    widths = [max((len(line[j]) for line in lines), default=0) for j in range(len(columns))]
    out = []
    title = _cell_text(table.title, console) if table.title else None
    if title:
        out.append(title)
    for line in lines:
        parts = [
            cell.rjust(w) if column.justify == "right" else cell.ljust(w)
            for cell, w, (column, _, _) in zip(line, widths, columns, strict=True)
        ]
        out.append("  ".join(parts).rstrip())
    if table.show_header and lines:
        # a dashed rule under the header, of plain ASCII
        out.insert(2 if title else 1, "  ".join("-" * w for w in widths))
    caption = _cell_text(table.caption, console) if table.caption else None
    if caption:
        out.append(caption)
    return Text("\n".join(out), no_wrap=True, overflow="ignore")


def progress_bar(
    console: Console,
    *,
    unit: str | None = None,
    enabled: bool = True,
    remaining: bool = False,
    transient: bool = False,
):
    """The progress bar of every long command: description, bar, done/total [unit], elapsed
    [, ETA remaining]; ``enabled=False`` draws nothing (the work runs the same).

    ``unit`` is a rich ``TextColumn`` template, so it may name task fields
    (the sweep's ``"failed {task.fields[failed]}"``).
    """
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    columns = [TextColumn("[progress.description]{task.description}"), BarColumn()]
    columns.append(MofNCompleteColumn())
    if unit:
        columns.append(TextColumn(unit))
    columns.append(TimeElapsedColumn())
    if remaining:
        columns += [TextColumn("ETA"), TimeRemainingColumn()]
    return Progress(*columns, console=console, disable=not enabled, transient=transient)
