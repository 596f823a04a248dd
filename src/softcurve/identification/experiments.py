"""Measured experiments: loading, checking, resampling and trimming.

An :class:`Experiment` is a time grid with named measured signals (outputs of the
robot, e.g. a tip bending angle or curvatures) and named inputs (e.g. bellow
pressures), each with a unit. Files are read by :func:`load_mat` (MATLAB files via
SciPy) and :func:`load_csv`; every check happens once, when the experiment is
built, and a bad file raises :class:`ExperimentError` naming the file and column.
Nothing here knows about the robot model.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.io

from softcurve.base.docs import parameters_from
from softcurve.base.validation import ParameterError


class ExperimentError(ParameterError):
    """An experiment file or array is malformed (missing column, bad time, NaN...)."""


def _column(name: str, value, length: int | None, source: str) -> np.ndarray:
    a = np.asarray(value, dtype=np.float64)
    if a.ndim == 2 and 1 in a.shape:  # MATLAB stores vectors as 1xN or Nx1
        a = a.ravel()
    if a.ndim != 1:
        raise ExperimentError(f"{source}: {name!r} must be a vector, got shape {a.shape}")
    if length is not None and a.shape[0] != length:
        raise ExperimentError(
            f"{source}: {name!r} has {a.shape[0]} samples but the time vector has {length}"
        )
    bad = ~np.isfinite(a)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise ExperimentError(
            f"{source}: {name!r} has {int(bad.sum())} non-finite values (NaN or inf), "
            f"the first at sample {first}"
        )
    return a


_columns = parameters_from(
    {
        "names": (
            "list of str, optional",
            "Names of the signals or inputs, in column order (default: all, in the "
            "experiment's order).",
        )
    }
)


@dataclass(frozen=True, eq=False)
class Experiment:
    """One recorded experiment on a common time grid.

    Parameters
    ----------
    t : array_like, shape (T,)
        Sample times [s], strictly increasing, T >= 2.
    signals : dict of str to array_like, shape (T,)
        Measured outputs by name.
    inputs : dict of str to array_like, shape (T,)
        Applied inputs by name (may be empty for free motion), in the order they
        map onto the actuators.
    units : dict of str to str
        Unit of each signal and input (e.g. ``"deg"``, ``"1/m"``, ``"Pa"``);
        missing entries are ``""``.
    name : str
        A label for reports and figures.
    """

    t: np.ndarray
    signals: dict[str, np.ndarray]
    inputs: dict[str, np.ndarray] = field(default_factory=dict)
    units: dict[str, str] = field(default_factory=dict)
    name: str = "experiment"

    def __post_init__(self):
        source = f"experiment {self.name!r}"
        t = _column("t", self.t, None, source)
        if t.shape[0] < 2:
            raise ExperimentError(f"{source}: needs at least 2 samples, got {t.shape[0]}")
        steps = np.diff(t)
        if not np.all(steps > 0):
            k = int(np.flatnonzero(steps <= 0)[0])
            raise ExperimentError(
                f"{source}: time must be strictly increasing, but t[{k + 1}] = {t[k + 1]!r} "
                f"<= t[{k}] = {t[k]!r}"
            )
        if not self.signals:
            raise ExperimentError(f"{source}: needs at least one measured signal")
        signals = {str(k): _column(k, v, t.size, source) for k, v in self.signals.items()}
        inputs = {str(k): _column(k, v, t.size, source) for k, v in self.inputs.items()}
        clash = set(signals) & set(inputs)
        if clash:
            raise ExperimentError(f"{source}: names used both as signal and input: {sorted(clash)}")
        units = {k: str(self.units.get(k, "")) for k in (*signals, *inputs)}
        for name, value in (("t", t), ("signals", signals), ("inputs", inputs), ("units", units)):
            object.__setattr__(self, name, value)
        t.setflags(write=False)
        for a in (*signals.values(), *inputs.values()):
            a.setflags(write=False)

    @property
    def duration(self) -> float:
        """``t[-1] - t[0]`` [s]."""
        return float(self.t[-1] - self.t[0])

    @_columns
    def signal_matrix(self, names=None) -> np.ndarray:
        """Signals stacked as columns, shape (T, len(names)).

        Parameters
        ----------
        %(names)s
        """
        return self._stack(self.signals, names, "signal")

    @_columns
    def input_matrix(self, names=None) -> np.ndarray:
        """Inputs stacked as columns, shape (T, len(names)).

        Parameters
        ----------
        %(names)s
        """
        return self._stack(self.inputs, names, "input")

    def _stack(self, table, names, kind) -> np.ndarray:
        names = list(table) if names is None else list(names)
        missing = [n for n in names if n not in table]
        if missing:
            raise ExperimentError(
                f"experiment {self.name!r} has no {kind} {missing}; it has {sorted(table)}"
            )
        if not names:
            return np.zeros((self.t.size, 0))
        return np.column_stack([table[n] for n in names])

    def _with(self, t, rows) -> Experiment:
        """A new experiment on grid ``t`` whose columns are ``rows(column)``."""
        return Experiment(
            t=t,
            signals={k: rows(v) for k, v in self.signals.items()},
            inputs={k: rows(v) for k, v in self.inputs.items()},
            units=self.units,
            name=self.name,
        )

    def trim(self, start: float | None = None, stop: float | None = None, *, rezero=False):
        """The samples with ``start <= t <= stop``, as a new experiment.

        Parameters
        ----------
        start : float, optional
            First time kept [s] (default: the first sample).
        stop : float, optional
            Last time kept [s] (default: the last sample).
        rezero : bool
            Shift the time so that the trimmed experiment starts at 0.
        """
        lo = self.t[0] if start is None else float(start)
        hi = self.t[-1] if stop is None else float(stop)
        keep = (self.t >= lo) & (self.t <= hi)
        if keep.sum() < 2:
            raise ExperimentError(
                f"experiment {self.name!r}: trimming to [{lo}, {hi}] s leaves "
                f"{int(keep.sum())} samples (its time runs from {self.t[0]} to {self.t[-1]} s)"
            )
        t = self.t[keep] - (self.t[keep][0] if rezero else 0.0)
        return self._with(t, lambda v: v[keep])

    def resample(self, dt: float) -> Experiment:
        """Linear interpolation onto a uniform grid from ``t[0]``, as a new experiment.

        Parameters
        ----------
        dt : float
            Step of the new grid [s]; at most the experiment's duration.
        """
        dt = float(dt)
        if not (np.isfinite(dt) and dt > 0):
            raise ExperimentError(f"dt must be a positive number of seconds, got {dt!r}")
        count = int(np.floor(self.duration / dt * (1 + 1e-12))) + 1
        if count < 2:
            raise ExperimentError(f"dt = {dt} s is longer than the experiment ({self.duration} s)")
        t = self.t[0] + dt * np.arange(count)
        return self._with(t, lambda v: np.interp(t, self.t, v))

    def with_signals(self, **signals) -> Experiment:
        """A copy with signals replaced or added (e.g. offsets removed).

        Parameters
        ----------
        **signals : array_like, shape (T,)
            New signal columns by name, on the experiment's time grid.
        """
        return Experiment(self.t, {**self.signals, **signals}, self.inputs, self.units, self.name)


def _time(source, table, time, sample_rate, length) -> np.ndarray:
    if (time is None) == (sample_rate is None):
        raise ExperimentError(f"{source}: give exactly one of time (a column) or sample_rate")
    if time is not None:
        return _lookup(source, table, time)
    rate = float(sample_rate)
    if not (np.isfinite(rate) and rate > 0):
        raise ExperimentError(f"sample_rate must be a positive number in Hz, got {sample_rate!r}")
    return np.arange(length) / rate


def _lookup(source: str, table: dict, key: str):
    """``table[key]``, where a key ``"name:j"`` selects column ``j`` of a matrix."""
    base, _, column = key.partition(":")
    if base not in table:
        raise ExperimentError(
            f"{source}: no variable or column {base!r}; available: {sorted(table)}"
        )
    value = np.asarray(table[base])
    if not column:
        return value
    if value.ndim != 2:
        raise ExperimentError(f"{source}: {base!r} is not a matrix, cannot take column {column}")
    j = int(column)
    if not 0 <= j < value.shape[1]:
        raise ExperimentError(
            f"{source}: {base!r} has {value.shape[1]} columns, column {j} does not exist"
        )
    return value[:, j]


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


def load_mat(
    path,
    *,
    signals: dict[str, str],
    time: str | None = None,
    sample_rate: float | None = None,
    inputs: dict[str, str] | None = None,
    units: dict[str, str] | None = None,
    name: str | None = None,
) -> Experiment:
    """Read an experiment from a MATLAB ``.mat`` file (``scipy.io.loadmat``).

    Parameters
    ----------
    path : str or Path
        The file.
    signals, inputs : dict of str to str
        Experiment name -> variable in the file; ``"U_:1"`` takes column 1 of matrix
        ``U_``. Row and column vectors are both accepted.
    time : str, optional
        Variable holding the sample times [s].
    sample_rate : float, optional
        Sampling rate [Hz] when the file has no time variable (``t = k / rate``).
    units : dict of str to str, optional
        Unit of each signal and input.
    name : str, optional
        Label (default: the file name without suffix).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"experiment file {str(path)!r} does not exist")
    try:
        table = scipy.io.loadmat(path)
    except (ValueError, TypeError, OSError, IndexError, EOFError, KeyError) as exc:
        raise ExperimentError(f"{path}: not a readable MATLAB file ({exc})") from None
    table = {k: v for k, v in table.items() if not k.startswith("__")}
    return _build(str(path), table, time, sample_rate, signals, inputs, units, name or path.stem)


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

    Empty or non-numeric cells are errors.

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
        Unit of each signal and input.
    name : str, optional
        Label (default: the file name without suffix).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"experiment file {str(path)!r} does not exist")
    try:
        with path.open(newline="", encoding="utf-8") as handle:
            rows = list(csv.reader(handle))
    except UnicodeDecodeError as exc:
        raise ExperimentError(
            f"{path}: not a UTF-8 text file (byte {exc.start}); save it as UTF-8 CSV"
        ) from None
    if len(rows) < 2:
        raise ExperimentError(f"{path}: needs a header row and at least one data row")
    header = [h.strip() for h in rows[0]]
    table: dict[str, list[float]] = {h: [] for h in header}
    for number, row in enumerate(rows[1:], start=2):
        if not row:
            continue
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
    as_dict = dict if isinstance(signals, dict) else (lambda names: {n: n for n in names})
    return _build(
        str(path),
        {k: np.array(v) for k, v in table.items()},
        time,
        sample_rate,
        as_dict(signals),
        as_dict(inputs or {}),
        units,
        name or path.stem,
    )
