"""The rich console every command prints to."""

from __future__ import annotations

from rich.console import Console


def make_console(**kwargs) -> Console:
    """A console; when output goes to a file or pipe (logs, CI), wide enough for the tables
    instead of rich's 80-column default."""
    console = Console(**kwargs)
    if not console.is_terminal:
        console = Console(width=160, **kwargs)
    return console


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
