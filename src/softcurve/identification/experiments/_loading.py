"""Measured experiments: loading, checking, units, resampling and trimming.

An :class:`Experiment` is a time grid with named measured signals (outputs of the
robot, e.g. a tip bending angle or curvatures) and named inputs (e.g. chamber
pressures), each with a unit. Units are converted once, when the experiment is built,
to SI (pressures to Pa, lengths to m, curvatures to 1/m; angles stay in deg or rad), the
unit recorded kept in ``source_units`` (the units :func:`check_units` knows). Files
are read by :func:`load_mat` (MATLAB files via SciPy, with struct arrays of trials),
:func:`load_mat_trials` and
:func:`load_csv`; every check happens once, when the experiment is built, and a bad
file raises :class:`ExperimentError` naming the file and the field. Nothing here knows
about the robot model.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from softcurve.base.docs import parameters_from
from softcurve.base.files import InputFileError, InputFileNotFound, input_file, read_input
from softcurve.identification.experiments._errors import ExperimentError, ExperimentFileNotFound
from softcurve.identification.experiments._experiment import Experiment
from softcurve.identification.experiments._mat import count_elements, numeric, read_mat, select

__all__ = [
    "Experiment",
    "ExperimentError",
    "ExperimentFileNotFound",
    "load_csv",
    "load_mat",
    "load_mat_trials",
]


def _time(source, table, time, sample_rate, length) -> np.ndarray:
    if (time is None) == (sample_rate is None):
        raise ExperimentError(f"{source}: give exactly one of time (a column) or sample_rate")
    if time is not None:
        return _lookup(source, table, time)
    try:
        rate = float(sample_rate)
    except (TypeError, ValueError):
        rate = np.nan
    if not (np.isfinite(rate) and rate > 0):
        raise ExperimentError(
            f"{source}: sample_rate must be a positive number in Hz, got {sample_rate!r}"
        )
    return np.arange(length) / rate


def _lookup(source: str, table: dict, key: str) -> np.ndarray:
    """The numbers a column name or selector names (``"U_:1"``, ``"train[0].y"``):
    a CSV header is matched verbatim first, then as a selector
    (``softcurve.identification.experiments._mat``)."""
    if not isinstance(key, str):
        raise ExperimentError(f"{source}: a column is named by a str, got {key!r}")
    value = table[key] if key in table else select(source, table, key)
    return numeric(source, key, value)


def _build(source, table, time, sample_rate, signals, inputs, units, name) -> Experiment:
    if not signals:
        raise ExperimentError(f"{source}: name at least one signal to read")
    columns = {k: _lookup(source, table, v) for k, v in signals.items()}
    input_columns = {k: _lookup(source, table, v) for k, v in (inputs or {}).items()}
    length = np.asarray(next(iter(columns.values()))).size
    t = _time(source, table, time, sample_rate, length)
    try:
        return Experiment(t, columns, input_columns, dict(units or {}), name)
    except ExperimentError as exc:
        raise ExperimentError(f"{source}: {exc}") from None


def _existing(path) -> Path:
    """``path``, checked by :func:`~softcurve.base.files.input_file`, its error an
    :class:`ExperimentError`."""
    try:
        return input_file(path, "experiment file")
    except InputFileNotFound as exc:
        raise ExperimentFileNotFound(str(exc)) from None
    except InputFileError as exc:
        raise ExperimentError(str(exc)) from None


_mat_options = parameters_from(
    {
        "signals": (
            "dict of str to str",
            'Experiment name -> selector in the file: a variable (``"y"``), a column of a '
            'matrix (``"U_:1"``), a field of a struct or of a trial of a struct array '
            '(``"train[0].y"``, ``"meta.rig.p:0"``); grammar in '
            "``softcurve.identification.experiments._mat``. Row and column vectors are both "
            "accepted.",
        ),
        "inputs": ("dict of str to str, optional", "Input selectors, as ``signals``."),
        "time": ("str, optional", "Selector of the sample times [s]."),
        "sample_rate": (
            "float, optional",
            "Sampling rate [Hz] when the file has no time variable (``t = k / rate``).",
        ),
        "units": (
            "dict of str to str, optional",
            "Unit each signal and input is recorded in (converted to SI, see :class:`Experiment`).",
        ),
        "root": (
            "str, optional",
            "Selector of a struct in which all the other selectors are looked up, e.g. "
            '``"train[0]"`` (equivalently ``"train:0"``): trial 0 of the struct array '
            "``train``.",
        ),
    }
)


@_mat_options
def load_mat(
    path,
    *,
    signals: dict[str, str],
    time: str | None = None,
    sample_rate: float | None = None,
    inputs: dict[str, str] | None = None,
    units: dict[str, str] | None = None,
    name: str | None = None,
    root: str | None = None,
) -> Experiment:
    """Read an experiment from a MATLAB ``.mat`` file (``scipy.io.loadmat``, v4 to v7).

    Parameters
    ----------
    path : str or Path
        The file.
    %(signals)s
    %(time)s
    %(sample_rate)s
    %(inputs)s
    %(units)s
    name : str, optional
        Label (default: the file name without suffix, with ``root`` if given).
    %(root)s

    Examples
    --------
    A file with a 1xK struct array ``train`` of trials with fields ``t``, ``y`` and a
    matrix of pressures ``p`` (one column per chamber, in psi)::

        load_mat(path, root="train[3]", time="t", signals={"x": "y"},
                 inputs={f"p{i}": f"p:{i}" for i in range(3)},
                 units={f"p{i}": "psi" for i in range(3)})
    """
    path = _existing(path)
    table, source = read_mat(path), str(path)
    label = name or path.stem
    if root is not None:
        inner = select(source, table, root)
        if not isinstance(inner, dict):
            raise ExperimentError(
                f"{source}: root {root!r} is not a struct (its fields would be the "
                f"variables); select one trial, e.g. {root + '[0]'!r}"
            )
        table, source = inner, f"{source}, {root}"
        label = name or f"{path.stem}:{root}"
    return _build(source, table, time, sample_rate, signals, inputs, units, label)


def load_mat_trials(path, root: str, **selectors) -> list[Experiment]:
    """Every trial of a struct array of trials, as experiments (one per element).

    Parameters
    ----------
    path : str or Path
        The file.
    root : str
        Selector of the struct array of trials (e.g. ``"train"``); trial ``k`` is read
        by :func:`load_mat` with ``root=f"{root}[{k}]"``.
    **selectors : dict
        The keyword arguments of :func:`load_mat` (``signals``, ``time`` or
        ``sample_rate``, ``inputs``, ``units``), the same for every trial.

    Returns
    -------
    list of Experiment
        Named ``"file:root[k]"``.
    """
    path = _existing(path)
    count = count_elements(str(path), read_mat(path), root)
    return [load_mat(path, root=f"{root}[{k}]", **selectors) for k in range(count)]


def _check_rows(path, columns: dict[str, np.ndarray], lines: list[int], time) -> None:
    """An :class:`ExperimentError` naming the line (``lines[k]`` holds row ``k``) and the
    column of the first NaN or infinite value in ``columns`` (those read), or the line
    where the ``time`` column does not increase."""
    if columns:
        names = list(columns)
        bad = np.argwhere(~np.isfinite(np.column_stack([columns[k] for k in names])))
        if bad.size:
            k, j = bad[0]
            raise ExperimentError(
                f"{path}, line {lines[k]}, column {names[j]!r}: non-finite value "
                f"{columns[names[j]][k]} (NaN or inf)"
            )
    if isinstance(time, str) and time in columns:
        t = columns[time]
        back = np.flatnonzero(np.diff(t) <= 0)
        if back.size:
            k = back[0] + 1
            raise ExperimentError(
                f"{path}, line {lines[k]}: time must be strictly increasing, but {time!r} is "
                f"{float(t[k])!r} s, not after {float(t[k - 1])!r} s on line {lines[k - 1]}"
            )


def load_csv(
    path,
    *,
    signals: dict[str, str] | list[str],
    time: str | None = "t",
    sample_rate: float | None = None,
    inputs: dict[str, str] | list[str] | None = None,
    units: dict[str, str] | None = None,
    name: str | None = None,
) -> Experiment:
    """Read an experiment from a CSV file with one header row of column names.

    Empty or non-numeric cells are errors, and so are NaN or infinite values in the
    columns read and times that do not increase (naming the line).

    Parameters
    ----------
    path : str or Path
        The file.
    signals : list of str or dict of str to str
        Column names, or experiment name -> column name.
    time : str or None
        Column holding the sample times [s]; None to use ``sample_rate`` instead.
    sample_rate : float, optional
        Sampling rate [Hz] when ``time`` is None (``t = k / rate``).
    inputs : list of str or dict of str to str, optional
        Input columns, in the same form as ``signals``.
    units : dict of str to str, optional
        Unit each signal and input is recorded in (converted to SI, see
        :class:`Experiment`).
    name : str, optional
        Label (default: the file name without suffix).
    """
    path = _existing(path)
    try:
        rows = list(csv.reader(io.StringIO(read_input(path, "experiment file"), newline="")))
    except InputFileError as exc:
        raise ExperimentError(str(exc)) from None
    if len(rows) < 2:
        raise ExperimentError(f"{path}: needs a header row and at least one data row")
    header = [h.strip() for h in rows[0]]
    table: dict[str, list[float]] = {h: [] for h in header}
    lines = []  # the line of each data row, for the messages
    for number, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        lines.append(number)
        if len(row) != len(header):
            raise ExperimentError(
                f"{path}, line {number}: {len(row)} fields, the header has {len(header)}"
            )
        for h, cell in zip(header, row, strict=True):
            try:
                table[h].append(float(cell))
            except ValueError:
                raise ExperimentError(
                    f"{path}, line {number}, column {h!r}: {cell!r} is not a number"
                ) from None

    def as_dict(names):
        return dict(names) if isinstance(names, dict) else {n: n for n in names}

    columns = {k: np.array(v) for k, v in table.items()}
    read = [*as_dict(signals).values(), *as_dict(inputs or {}).values(), time]
    _check_rows(
        path, {k: columns[k] for k in read if isinstance(k, str) and k in columns}, lines, time
    )
    return _build(
        str(path),
        columns,
        time,
        sample_rate,
        as_dict(signals),
        as_dict(inputs or {}),
        units,
        name or path.stem,
    )
