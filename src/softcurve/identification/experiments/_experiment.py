"""The :class:`Experiment`: a time grid with named signals and inputs, in SI units.

Built directly from arrays or by the loaders of
:mod:`softcurve.identification.experiments`; every check and the unit conversion
(``softcurve.identification.experiments._units``) happen once, when it is built.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from softcurve.base.docs import parameters_from
from softcurve.base.validation import whole_count
from softcurve.identification.experiments._errors import ExperimentError, UnitError
from softcurve.identification.experiments._units import to_si


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
        Unit each signal and input is recorded in (e.g. ``"psi"``, ``"mm"``, ``"deg"``;
        known units: ``softcurve.identification.experiments._units.UNITS``); missing entries are
        ``""`` (unspecified). The values are converted once to SI, and ``units`` then
        holds the SI unit (angles stay in deg or rad).
    name : str
        A label for reports and figures.
    source_units : dict of str to str
        The unit each column was recorded in, before the conversion (filled in when
        built; given only when copying an experiment whose values are already SI).
    """

    t: np.ndarray
    signals: dict[str, np.ndarray]
    inputs: dict[str, np.ndarray] = field(default_factory=dict)
    units: dict[str, str] = field(default_factory=dict)
    name: str = "experiment"
    source_units: dict[str, str] = field(default_factory=dict)

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
        unknown = sorted(set(self.units) - set(signals) - set(inputs))
        if unknown:
            raise ExperimentError(
                f"{source}: units given for {unknown}, which are neither signals nor inputs"
            )
        units, recorded = {}, {}
        for table in (signals, inputs):
            for k, column in table.items():
                unit = str(self.units.get(k, "")).strip()
                try:
                    units[k], factor = to_si(k, unit, source)
                except UnitError as exc:
                    raise ExperimentError(str(exc)) from None
                recorded[k] = str(self.source_units.get(k, unit))
                if factor != 1.0:
                    table[k] = column * factor
        fields = {"t": t, "signals": signals, "inputs": inputs, "units": units}
        for name, value in {**fields, "source_units": recorded}.items():
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
            source_units=self.source_units,
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

    def _blocks(self, count, what: str) -> int:
        count = whole_count(what, count)
        if self.t.size // count < 2:
            raise ExperimentError(
                f"experiment {self.name!r}: {what}={count} leaves fewer than 2 of its "
                f"{self.t.size} samples"
            )
        return count

    def thin(self, every: int) -> Experiment:
        """Every ``every``-th sample, from the first, as a new experiment.

        A fit on it costs about ``1 / every`` as much per evaluation where the cost is
        per sample (a quasi-static fit solves one equilibrium per sample); its estimate
        uses ``every`` times fewer samples of the same noise, so with independent noise
        its standard errors and intervals grow by about ``sqrt(every)``. Thinning a
        dense record, whose neighbouring residuals are correlated, loses less (their
        intervals were too narrow: docs/identify.md).

        Parameters
        ----------
        every : int
            Keep sample 0, ``every``, ``2 every``, ...; at least 1.
        """
        every = self._blocks(every, "every")
        return self._with(self.t[::every], lambda v: v[::every])

    def bin(self, count: int) -> Experiment:
        """Means of consecutive blocks of ``count`` samples (time, signals and inputs), as
        a new experiment; a last, incomplete block is dropped.

        As :meth:`thin`, ``count`` times fewer samples; but each mean has ``1 / count``
        of the noise variance of independent noise, so the intervals stay about as wide
        as on the whole record, and the residuals' RMS falls by ``sqrt(count)``. The
        means smooth the record over ``count`` samples: keep ``count * dt`` well under
        the fastest time the fit should resolve (for a quasi-static fit, the inputs'
        changes).

        Parameters
        ----------
        count : int
            Samples per block; at least 1.
        """
        count = self._blocks(count, "count")
        blocks = self.t.size // count

        def means(v):
            return v[: blocks * count].reshape(blocks, count).mean(axis=1)

        return self._with(means(self.t), means)

    def with_signals(self, **signals) -> Experiment:
        """A copy with signals replaced or added (e.g. offsets removed).

        Parameters
        ----------
        **signals : array_like, shape (T,)
            New signal columns by name, on the experiment's time grid, in the unit
            stored (``units``; a new signal has none).
        """
        return Experiment(
            self.t,
            {**self.signals, **signals},
            self.inputs,
            self.units,
            self.name,
            self.source_units,
        )
