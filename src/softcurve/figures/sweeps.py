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
    ("final tip position [mm]", ("final_tip_x", "final_tip_y", "final_tip_z"), MM_PER_M),
    ("tip range [mm]", ("tip_range_x", "tip_range_y", "tip_range_z"), MM_PER_M),
    ("settling time [s]", ("settling_time",), 1.0),
    ("peak energy [J]", ("peak_energy",), 1.0),
)
"""The rows of the figure: ``(axis label, columns drawn in it, factor to the label's unit)``;
a row whose columns are all absent from the table is left out."""


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


def plot_sweep(table, ax=None, *, variables=None):
    """Each summary output of a sweep against each swept variable, one point per
    simulation.

    One column of panels per variable; one row per output: the final tip position and
    the tip's range per axis (x, y, z in one panel) [mm], the settling time [s] and the
    peak energy [J] (rows whose outputs the sweep did not compute are left out). With
    several variables, the points above one value of a variable are the simulations
    that differ in the others. Failed simulations (NaN outputs) are not drawn; their
    count is in the title.

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
    rows = [(label, [c for c in names if c in columns], f) for label, names, f in PANELS]
    rows = [row for row in rows if row[1]]
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
        figsize=(3.6 * len(variables) + 0.8, 2.3 * len(rows) + 0.6),
    )
    for r, (label, names, factor) in enumerate(rows):
        for v, variable in enumerate(variables):
            axis = axes[r * len(variables) + v]
            x = columns[variable].astype(np.float64)
            for name in names:
                series = name.rsplit("_", 1)[-1] if len(names) > 1 else None
                axis.plot(x, factor * columns[name].astype(np.float64), ".", label=series)
            if len(names) > 1 and v == 0:
                axis.legend(fontsize="small")
            if r == len(rows) - 1:
                axis.set_xlabel(variable)
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
