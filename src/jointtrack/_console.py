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
