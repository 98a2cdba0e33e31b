"""Where a result was measured: one description of the machine for every JSON report."""

from __future__ import annotations

import platform

__all__ = ["machine_info"]


def machine_info() -> dict:
    """Platform, Python version and processor of this machine."""
    return {
        "platform": platform.platform(),
        "python": platform.python_version(),
        "processor": platform.processor() or platform.machine(),
    }
