"""Values a reproduction figure can draw, and the note that says which it could not.

Matplotlib warns from inside site-packages (``overflow encountered in exp`` in
``matplotlib/scale.py``) when a log axis meets a value near 1e300, and a
histogram or a Gaussian overlay over such a range is meaningless anyway. The
reproductions' figures therefore pass their data through :func:`plottable`
first: a value that is non-finite, larger in magnitude than :data:`OFF_SCALE`
or (on a log axis) not positive is not drawn, and the figure says how many
were left out (:func:`off_scale_note`) instead of leaking a warning.
"""

from __future__ import annotations

import numpy as np

__all__ = ["OFF_SCALE", "REPRO_DPI", "UNITS", "off_scale_note", "plottable"]

#: magnitudes beyond this are not drawn: no measured time, count, ratio or
#: divergence of the reproductions comes near it, and 10**(log10(v) + margin)
#: stays far from float overflow on a log axis
OFF_SCALE = 1e100

#: the unit suffixes the reproductions' axis labels end with (a count or a ratio
#: says so, so that no axis is left without one)
UNITS = ("(s)", "(ms)", "(m)", "(1/m)", "(m²)", "(nats)", "(rad)", "(count)", "(dimensionless)")


def plottable(values, *, log: bool = False) -> tuple[np.ndarray, int]:
    """``values`` as floats with NaN where a value cannot be drawn, and how many those are.

    Parameters
    ----------
    values : array_like
        Numbers; ``None`` counts as missing (not as off scale).
    log : bool
        The axis is logarithmic: values ≤ 1/OFF_SCALE are off scale too.

    Returns
    -------
    y : numpy.ndarray
        Float copy of ``values``, NaN (a gap in a line) where not drawable.
    n_off : int
        Values present but off scale (non-finite, ``|v| > OFF_SCALE``, or
        too small for the log axis); missing ``None`` entries are not counted.
    """
    if isinstance(values, np.ndarray) and values.dtype.kind in "iuf":
        y = values.astype(float).ravel()  # a copy: the caller's array is not touched
        missing = np.zeros(y.shape, dtype=bool)
    else:
        raw = list(values)
        missing = np.array([v is None for v in raw], dtype=bool)
        y = np.array([np.nan if v is None else v for v in raw], dtype=float)
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(y) | (np.abs(y) > OFF_SCALE)
        if log:
            bad |= ~(y >= 1.0 / OFF_SCALE)
    bad &= ~missing
    return np.where(bad | missing, np.nan, y), int(bad.sum())


def off_scale_note(n_off: int, what: str, log: bool = False) -> str:
    """A sentence for the figure: ``n_off`` ``what`` not drawn and why ("" if none)."""
    if n_off == 0:
        return ""
    why = "non-finite, beyond 1e100" + (" or ≤ 1e-100 on the log axis" if log else "")
    return f"{n_off} {what} not drawn ({why})"


#: resolution of the reproductions' PNGs (≈ 100 dpi keeps each under 300 KB)
REPRO_DPI = 100


def legend_below(fig, axes, ncols: int) -> None:
    """One legend for all ``axes`` below the panels (each label once), off the data.

    Needs a figure with constrained layout (``"outside"`` locations).
    """
    handles: dict = {}
    for ax in axes:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(label, handle)
    fig.legend(
        handles.values(),
        handles.keys(),
        loc="outside lower center",
        ncols=ncols,
        fontsize=8,
        frameon=False,
    )
