"""The figure of a sweep's table: each summary output against each swept variable."""

from __future__ import annotations

import numpy as np

from softcurve.base.validation import ParameterError
from softcurve.figures.drawing import panels

BOOKKEEPING = ("index", "status", "message")
"""Columns of a sweep table that are neither swept variables nor outputs."""
OUTPUT_PREFIXES = ("final_", "tip_range_")
OUTPUT_NAMES = ("settling_time", "peak_energy")
MM_PER_M = 1e3
PANELS = (
    *((f"final tip {k} [mm]", f"final_tip_{k}", MM_PER_M) for k in "xyz"),
    *((f"tip range {k} [mm]", f"tip_range_{k}", MM_PER_M) for k in "xyz"),
    ("settling time [s]", "settling_time", 1.0),
    ("peak energy [J]", "peak_energy", 1.0),
)
"""The rows of the figure: ``(axis label, column, factor to the label's unit)``, one
output per row so that each has its own scale (a millimetre of z beside 40 mm of x is
invisible on a shared axis); a row whose column the table lacks is left out."""
TIP_COLUMNS = ("final_tip_x", "final_tip_y", "final_tip_z")
ROUND_OFF = 1e-4
"""Relative spread below which an output is drawn as a constant: a spread below
``ROUND_OFF`` of the output's scale (for the tip's positions and ranges, the largest
final tip distance; otherwise the largest value) is the integrator's error, not the
swept variable's effect. CVODES at the default rtol 1e-6 leaves a settled tip about 2e-6
of its reach off (examples/sweep_grid.toml: final tip x spread over 1.3e-4 mm around an
exact 0 at a 65 mm reach); 1e-4 keeps a 50x margin above that."""


def sweep_columns(table) -> dict[str, np.ndarray]:
    """The columns of a sweep table as NumPy arrays, whatever holds them.

    Parameters
    ----------
    table : pyarrow.Table, pandas.DataFrame or mapping of str to array_like, shape (rows,)
        The table of ``softcurve sweep`` (``results.parquet``, ``SweepResult.table``),
        read with pyarrow or pandas, or a dict of columns.

    Returns
    -------
    dict of str to ndarray, shape (rows,)
    """
    names = getattr(table, "column_names", None)
    if names is None:
        names = getattr(table, "columns", None)
    if names is None and hasattr(table, "keys"):
        names = table.keys()
    if names is None:
        raise ParameterError(
            "table must be a sweep table (pyarrow.Table, pandas.DataFrame or a dict of "
            f"columns), got {type(table).__name__}"
        )
    return {str(name): np.asarray(table[name]) for name in names}


def is_output(name: str) -> bool:
    """Whether the column ``name`` of a sweep table is a summary output.

    Parameters
    ----------
    name : str
        A column name.

    Returns
    -------
    bool
    """
    return name in OUTPUT_NAMES or name.startswith(OUTPUT_PREFIXES)


def constant_value(values, scale: float) -> float | None:
    """The constant an output's values are within round-off, or None when they vary.

    Parameters
    ----------
    values : array_like, shape (rows,)
        The output over the simulations [any unit]; NaN (failed simulations) ignored.
    scale : float
        The output's scale [its unit]: a spread below ``ROUND_OFF`` of it is round-off.

    Returns
    -------
    float or None
        Their mean (0 where it is itself round-off of ``scale``) when the finite values
        spread less than ``ROUND_OFF * scale``, exactly equal values included; None when
        they spread more or none is finite.
    """
    values = np.asarray(values, dtype=np.float64)
    values = values[np.isfinite(values)]
    if not values.size:
        return None
    tolerance = ROUND_OFF * abs(scale)
    if np.ptp(values) > tolerance:
        return None
    mean = float(values.mean())
    return 0.0 if abs(mean) <= tolerance else mean


def _scales(columns: dict, rows) -> dict[str, float]:
    """Each row's scale (see ``ROUND_OFF``) in the row's unit: the tip's reach, the
    largest final tip distance, for the tip's rows (at least their own largest value),
    the largest value for the others."""
    tip = [columns[c].astype(np.float64) for c in TIP_COLUMNS if c in columns]
    reach = np.linalg.norm(np.array(tip), axis=0) if tip else np.zeros(0)
    reach = float(reach[np.isfinite(reach)].max(initial=0.0))
    scales = {}
    for _, name, factor in rows:
        values = np.abs(factor * columns[name].astype(np.float64))
        own = float(values[np.isfinite(values)].max(initial=0.0))
        scales[name] = (
            max(own, factor * reach) if name.startswith(("final_tip_", "tip_range_")) else own
        )
    return scales


def _draw_constant(axis, x, value: float, scale: float, label: str) -> None:
    """One output that is constant within round-off: its points on one level, a band of
    the scale's 5 % around it (no offset label of noise) and the value written."""
    axis.plot(x, np.full(x.shape, value), ".", ms=4)
    half = 0.05 * (scale if scale > 0 else 1.0)
    axis.set_ylim(value - half, value + half)
    unit = f" {label[label.rfind('[') + 1 : -1]}" if label.endswith("]") else ""
    spread = f"spread < {100 * ROUND_OFF:g} % of {scale:.3g}{unit}"
    axis.text(
        0.5,
        0.8,
        f"constant: {value:.6g}{unit} ({spread})",
        transform=axis.transAxes,
        ha="center",
        fontsize="small",
    )


def plot_sweep(table, ax=None, *, variables=None, labels=None):
    """Each summary output of a sweep against each swept variable, one point per
    simulation.

    One column of panels per variable; one row per output, each on its own scale: the
    final tip position and the tip's range along x, y and z [mm], the settling time [s]
    and the peak energy [J] (rows whose outputs the sweep did not compute are left out). With
    several variables, the points above one value of a variable are the simulations
    that differ in the others. Failed simulations (NaN outputs) are not drawn; their
    count is in the title. An output whose values spread less than ``ROUND_OFF`` (1e-4)
    of its scale (the tip's reach for the tip's rows) is the integrator's round-off of one
    value: drawn on one level and written as a constant, never as noise under an offset.

    Parameters
    ----------
    table : pyarrow.Table, pandas.DataFrame or mapping of str to array_like, shape (rows,)
        The table of ``softcurve sweep`` (``results.parquet`` or ``SweepResult.table``):
        an ``index`` column, one column per swept variable, the outputs, ``status``.
    ax : None or sequence of matplotlib.axes.Axes, shape (outputs, variables)
        The panels, row by row; None draws a new figure.
    variables : sequence of str, optional
        The swept variables to draw against, by column name (default: every column that
        is neither an output nor ``index``, ``status``, ``message``).
    labels : mapping of str to str, optional
        The x axis label of each variable, with its unit (``SweepResult.plot`` passes
        the sweep's: ``"segment 0: elongation stiffness a1 [N/m]"``); default: the
        column's name.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import numpy as np
    >>> from softcurve.figures import plot_sweep
    >>> table = {"index": np.arange(3), "q0[1]": [0.0, 10.0, 20.0],
    ...          "settling_time": [0.1, 0.2, 0.4], "status": ["success"] * 3}
    >>> figure = plot_sweep(table)
    >>> [a.get_xlabel() for a in figure.axes], [a.get_ylabel() for a in figure.axes]
    (['q0[1]'], ['settling time [s]'])
    >>> import matplotlib.pyplot as plt
    >>> plt.close(figure)
    """
    columns = sweep_columns(table)
    if variables is None:
        variables = [n for n in columns if n not in BOOKKEEPING and not is_output(n)]
    variables = [variables] if isinstance(variables, str) else list(variables)
    for name in variables:
        if name not in columns or name in BOOKKEEPING or is_output(name):
            raise ParameterError(
                f"variables: {name!r} is not a swept variable of the table; its columns "
                f"are {sorted(columns)}"
            )
    labels = dict(labels or {})
    rows = [row for row in PANELS if row[1] in columns]
    if not variables or not rows:
        raise ParameterError(
            "the sweep figure needs at least one swept variable and one output column "
            f"(final_tip_*, tip_range_*, settling_time, peak_energy); got {sorted(columns)}"
        )
    figure, axes = panels(
        ax,
        len(rows) * len(variables),
        "the sweep figure",
        rows=len(rows),
        sharex="col",
        figsize=(3.6 * len(variables) + 0.8, 1.7 * len(rows) + 0.9),
    )
    scales = _scales(columns, rows)
    for r, (label, name, factor) in enumerate(rows):
        values = factor * columns[name].astype(np.float64)
        constant = constant_value(values, scales[name])
        for v, variable in enumerate(variables):
            axis = axes[r * len(variables) + v]
            x = columns[variable].astype(np.float64)
            if constant is None:
                axis.plot(x, values, ".", ms=4)
            else:
                _draw_constant(axis, x[np.isfinite(values)], constant, scales[name], label)
            axis.grid(True, alpha=0.3)
            # an output the same to many digits reads as its values, not as "1e-6 + 63.96"
            axis.ticklabel_format(axis="y", useOffset=False)
            if r == len(rows) - 1:
                axis.set_xlabel(labels.get(variable, variable))
            if v == 0:
                axis.set_ylabel(label)
    status = columns.get("status")
    failed = 0 if status is None else int(np.sum(status.astype(str) != "success"))
    if ax is None:  # the caller's figure keeps its own title
        size = len(columns[variables[0]])
        figure.suptitle(
            f"sweep of {size} simulations" + (f", {failed} failed (not drawn)" if failed else "")
        )
    return figure
