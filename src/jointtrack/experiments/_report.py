"""Cell formatting and table shape shared by the reproductions' printed reports."""

from __future__ import annotations

import math

__all__ = ["fmt", "seconds", "table"]


def fmt(v, spec) -> str:
    """``v`` formatted with ``spec``; "–" for missing or non-finite values."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    return format(v, spec)


def seconds(v) -> str:
    """A duration with the unit that keeps three significant digits readable."""
    if v is None:
        return "–"
    if v >= 0.1:
        return f"{v:.3g} s"
    if v >= 1e-4:
        return f"{1e3 * v:.3g} ms"
    return f"{1e6 * v:.3g} µs"


def table(title: str, headers):
    """A rich table with right-aligned columns in the reports' style."""
    from rich import box
    from rich.table import Table

    t = Table(title=title, title_justify="left", box=box.SIMPLE_HEAD, pad_edge=False)
    for h in headers:
        t.add_column(h, justify="right")
    return t
