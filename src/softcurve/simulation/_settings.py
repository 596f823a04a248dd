"""The settings of a simulation, validated once: :class:`SimulationSettings`.

One frozen object carries the end time, the output interval, the integrator, its
tolerances and its step budget; :func:`~softcurve.simulation.simulate`,
:func:`~softcurve.simulation.batch.simulate_batch`, scenario files, sweeps and the
command line all take it, and each default is written here alone.
"""

from __future__ import annotations

import ctypes
import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from softcurve.base.validation import ParameterError, beyond_float, real_scalar

METHODS = ("cvodes", "auto", "adams", "bdf", "radau", "rk45")
"""Integrators: ``"cvodes"`` chooses Adams or BDF per problem, ``"auto"`` chooses Radau IIA
or ``"cvodes"``'s choice by the initial linearization and the changes of the input
(``softcurve.simulation.solvers.auto_method``), ``"adams"`` and ``"bdf"`` force CVODES's
family, ``"radau"`` is the C driver's L-stable Radau IIA of order 5, ``"rk45"`` is
SciPy's explicit Runge-Kutta 4(5)."""

JACOBIANS = ("differences", "exact")
"""The Jacobians of the C driver's Newton matrix (``SimulationSettings.jacobian``)."""

EPSILON = float(np.finfo(np.float64).eps)
"""The float64 epsilon, 2^-52: the spacing of floats relative to their size."""

RTOL_MIN = 100 * EPSILON
"""Smallest relative tolerance (about 2.2e-14): tighter ones ask for fewer than 100 units
in the last place over a whole run, which float64 arithmetic cannot deliver, and CVODES
stops with CV_TOO_MUCH_ACC after the work is done; they are refused up front instead."""

MAX_STEPS = 2 ** (8 * ctypes.sizeof(ctypes.c_long) - 1) - 1
"""Largest step budget (2^63 - 1 where a C ``long`` has 64 bits): CVODES takes it as a C
``long`` (``CVodeSetMaxNumSteps``, and the C driver's ``sc_options.max_steps``); a
larger one wraps around there (2^64 + 1 became 1)."""

MIN_TIME = math.sqrt(float(np.finfo(np.float64).tiny))
"""Shortest output interval, and so end time [s] (about 1.5e-154 s): CVODES squares
step sizes (its first step's estimate weighs ``h^2`` times the second derivative), and
below the square root of the smallest normal float64 that square is subnormal or zero
(measured: from 1e-155 s CVODES needs four times the steps, below 1e-160 s it stops with
CV_ILL_INPUT)."""

MAX_OUTPUTS = 10_000_000
"""Default limit of output times: 1000 times the paper's 10 s at 1 ms; the state of a
one-segment robot (13 columns with time and tip) then takes about 1 GB of memory and
3 GB of CSV text, more than a typical laptop should be asked for by accident."""

BYTES_PER_VALUE = 8
"""Bytes of one output value in memory (float64)."""

CSV_BYTES_PER_VALUE = 24
"""Bytes of one output value in a CSV file: up to 17 significant digits, sign, point,
exponent and the separator (measured: 23 on average for a paper trajectory)."""


class SettingsError(ParameterError):
    """A simulation setting is out of its range; ``field`` names it, ``reason`` says why."""

    def __init__(self, field: str, reason: str):
        super().__init__(f"{field} {reason}")
        self.field, self.reason = field, reason


def checked_jacobian(jacobian: str) -> str:
    """``jacobian`` where it names one of :data:`JACOBIANS`: forward differences of the
    state derivative or the model's exact Jacobian, for the driver's Newton matrix
    (``SimulationSettings.jacobian``) and a Rosenbrock method's (the stepper's, the
    environments'); else :class:`SettingsError`, naming the field.

    Parameters
    ----------
    jacobian : str
        The name asked for.
    """
    if jacobian not in JACOBIANS:
        raise SettingsError("jacobian", f"must be one of {', '.join(JACOBIANS)}, got {jacobian!r}")
    return jacobian


def checked_rtol(rtol) -> float:
    """``rtol`` as a float where it is a real number in ``[RTOL_MIN, 1)``: a relative
    tolerance of integration (``SimulationSettings.rtol``, the gradients' ``rtol``); else
    :class:`SettingsError`, naming the field.

    Parameters
    ----------
    rtol : float
        The relative tolerance asked for, dimensionless.
    """
    value = _number("rtol", rtol, unit="")
    if not RTOL_MIN <= value < 1:
        raise SettingsError("rtol", f"must be in [{RTOL_MIN:g}, 1), got {value!r}")
    return value


def _number(field: str, value, *, unit: str) -> float:
    """``value`` as a finite float > 0, or :class:`SettingsError`."""
    # plain floats and ints (the usual case) skip NumPy's checks, a few microseconds each
    plain = type(value) is float or type(value) is int
    if not plain and (
        isinstance(value, bool | str | bytes) or not np.isscalar(value) or not np.isrealobj(value)
    ):
        raise SettingsError(field, f"must be a real number > 0{unit}, got {value!r}")
    try:
        x = float(value)
    except OverflowError:
        raise SettingsError(field, beyond_float(value)) from None
    if not (math.isfinite(x) and x > 0):
        raise SettingsError(field, f"must be a finite number > 0{unit}, got {x!r}")
    return x


def format_bytes(size: float) -> str:
    """A byte count in MB, GB or TB, for messages.

    Parameters
    ----------
    size : float
        Bytes [B].
    """
    for unit, scale in (("TB", 1e12), ("GB", 1e9)):
        if size >= scale:
            return f"{size / scale:.3g} {unit}"
    return f"{size / 1e6:.3g} MB"


@dataclass(frozen=True)
class SimulationSettings:
    """What to integrate and how: end time, output interval, integrator, tolerances.

    Every field is checked on construction and by :meth:`replace`; a bad one raises
    :class:`~softcurve.ParameterError` naming the field, its value and its range.

    Parameters
    ----------
    t_final : float
        End time [s], ``>= MIN_TIME`` (default 10 s, the paper's case).
    dt : float
        Output interval [s], ``MIN_TIME <= dt <= t_final`` (default 1 ms; :data:`MIN_TIME`
        is about 1.5e-154 s) and at least ``t_final`` times the float64 epsilon (so that
        every ``t + dt`` is a new time). The integrator chooses its own steps by error
        control, independently of ``dt``.
    method : {"cvodes", "auto", "adams", "bdf", "radau", "rk45"}
        The integrator (default ``"cvodes"``: CVODES, Adams or BDF chosen per problem;
        ``"radau"``: Radau IIA of order 5, L-stable, in the C driver; ``"auto"``: Radau
        IIA where an input on the output grid changes often against the robot's fastest
        mode, else ``"cvodes"``; a batch's members hold one input each: ``"cvodes"``).
    rtol : float
        Relative tolerance, ``0 < rtol < 1`` (default 1e-6).
    atol : None, float or sequence of float, shape (n_state,)
        Absolute tolerance per state (> 0); None (default) means ``rtol`` times each
        state's natural scale (:func:`~softcurve.simulation.solvers.nominal_scale`).
    max_steps : int
        Internal steps allowed between two output times, in ``[1, MAX_STEPS]`` (default
        50 000; :data:`MAX_STEPS` is a C ``long``'s largest value, 2^63 - 1 on 64-bit
        Linux and macOS).
    max_outputs : int
        Output times allowed, >= 2 (default :data:`MAX_OUTPUTS`): ``t_final / dt + 1``
        above it is refused before anything is allocated, with the size the outputs
        would take; raise it for longer records.
    jacobian : {"differences", "exact"}
        The Jacobian of the Newton matrices in the C driver's routes of one member per
        system (CVODES's and Radau IIA's: ``simulate``, and batches not grouped over
        lanes): forward differences
        of the state derivative (default; ``n_state + 1`` evaluations each), or the
        model's exact one (:meth:`~softcurve.Model.rhs_jacobian`, compiled on first use
        into a library of its own and cached: at 2 segments and more it is cheaper, see
        docs/performance.md). The other routes take their own; the route's reason says
        which the driver took.

    Examples
    --------
    >>> from softcurve.simulation import SimulationSettings
    >>> settings = SimulationSettings(t_final=2.0, dt=0.01)
    >>> settings.replace(rtol=1e-8).rtol
    1e-08
    """

    t_final: float = 10.0
    dt: float = 1e-3
    method: str = "cvodes"
    rtol: float = 1e-6
    atol: float | tuple[float, ...] | None = None
    max_steps: int = 50_000
    max_outputs: int = MAX_OUTPUTS
    jacobian: str = "differences"

    def __post_init__(self):
        t_final = _number("t_final", self.t_final, unit=" [s]")
        dt = _number("dt", self.dt, unit=" [s]")
        if t_final < MIN_TIME:
            raise SettingsError(
                "t_final",
                f"must be >= {MIN_TIME:.3g} s (the shortest time whose square CVODES's step "
                f"sizes need as a normal float64), got {t_final!r}",
            )
        if dt > t_final:
            raise SettingsError("dt", f"must be <= t_final = {t_final!r} [s], got {dt!r}")
        if self.method not in METHODS:
            raise SettingsError(
                "method", f"must be one of {', '.join(METHODS)}, got {self.method!r}"
            )
        checked_jacobian(self.jacobian)
        rtol = checked_rtol(self.rtol)
        max_steps = self.max_steps
        integer = isinstance(max_steps, int | np.integer) and not isinstance(max_steps, bool)
        if not integer or not 1 <= max_steps <= MAX_STEPS:
            raise SettingsError(
                "max_steps",
                f"must be an integer in [1, {MAX_STEPS}] (CVODES counts steps in a C long), "
                f"got {max_steps!r}",
            )
        limit = self.max_outputs
        integer = isinstance(limit, int | np.integer) and not isinstance(limit, bool)
        if not integer or limit < 2:
            raise SettingsError("max_outputs", f"must be an integer >= 2, got {limit!r}")
        outputs = output_count(t_final, dt)
        if outputs > limit:
            raise SettingsError(
                "t_final",
                f"{t_final:g} s with dt {dt:g} s asks for {outputs:.4g} output times "
                f"({format_bytes(outputs * BYTES_PER_VALUE)} in memory and "
                f"{format_bytes(outputs * CSV_BYTES_PER_VALUE)} of CSV for each recorded value, "
                f"13 of them for one segment with creep), more than max_outputs "
                f"{int(limit)}: shorten t_final, raise dt, or raise max_outputs",
            )
        shortest = max(MIN_TIME, t_final * EPSILON)
        if dt < shortest:
            raise SettingsError(
                "dt",
                f"must be in [{shortest:.3g}, {t_final!r}] [s] (at least {MIN_TIME:.2g} s, "
                "whose square CVODES's step sizes need as a normal float64, and t_final "
                f"times the float64 epsilon, so that each output time differs from the one "
                f"before), got {dt!r}",
            )
        set_ = object.__setattr__
        set_(self, "max_outputs", int(limit))
        set_(self, "t_final", t_final)
        set_(self, "dt", dt)
        set_(self, "rtol", rtol)
        set_(self, "max_steps", int(max_steps))
        set_(self, "atol", _atol(self.atol))

    def replace(self, **changes) -> SimulationSettings:
        """A copy with ``changes`` (fields of this class), validated again.

        Parameters
        ----------
        **changes : dict
            New values of fields, e.g. ``t_final=2.0``.
        """
        unknown = sorted(set(changes) - _FIELDS)
        if unknown:
            raise ParameterError(
                f"unknown simulation setting {unknown[0]!r} (the settings are "
                f"{', '.join(f.name for f in dataclasses.fields(self))})"
            )
        return dataclasses.replace(self, **changes)

    def output_times(self) -> np.ndarray:
        """Times ``0, dt, 2 dt, ...`` [s]; the last one is ``t_final`` also where it is not
        a multiple of ``dt`` (a shorter last interval)."""
        count = self.t_final / self.dt
        steps = round(count)
        if abs(count - steps) > 1e-9 * max(count, 1.0):  # not a multiple: a shorter last step
            steps = math.ceil(count)
        # float indices times dt, in place: the values of int indices times dt, one array
        grid = np.arange(steps + 1, dtype=np.float64)
        grid *= self.dt
        grid[-1] = self.t_final
        return grid

    def output_size(self, columns: int) -> tuple[float, float]:
        """``(memory, csv)``: bytes the outputs take with ``columns`` values per output
        time, in memory (float64) and as CSV text (estimated, see
        :data:`CSV_BYTES_PER_VALUE`).

        Parameters
        ----------
        columns : int
            Values per output time (e.g. time, states, tip).
        """
        values = output_count(self.t_final, self.dt) * columns
        return values * BYTES_PER_VALUE, values * CSV_BYTES_PER_VALUE

    def atol_vector(self, nominal: np.ndarray) -> np.ndarray:
        """The absolute tolerance of every state, shape of ``nominal`` (n_state,): ``atol``,
        or ``rtol * nominal`` by default.

        Parameters
        ----------
        nominal : ndarray, shape (n_state,)
            Each state's scale (> 0), :func:`~softcurve.simulation.solvers.nominal_scale`.
        """
        if self.atol is None:
            return self.rtol * nominal
        if isinstance(self.atol, float):
            return np.full(nominal.shape, self.atol)
        if len(self.atol) != nominal.size:
            raise SettingsError(
                "atol", f"must have {nominal.size} entries (one per state), got {len(self.atol)}"
            )
        return np.array(self.atol)


def output_count(t_final: float, dt: float) -> float:
    """Number of output times of ``t_final`` [s] at ``dt`` [s] (a float: it may be
    astronomically large, or inf; computed without allocating anything).

    Parameters
    ----------
    t_final : float
        End time [s], > 0.
    dt : float
        Output interval [s], > 0.
    """
    ratio = t_final / dt
    if not ratio < 2.0**52:  # beyond exact integers, or inf: the ratio itself
        return ratio + 1.0
    return math.ceil(ratio * (1 - 1e-12)) + 1.0


def sample_time(name: str, value, settings: SimulationSettings | None = None) -> float:
    """``value`` as the time between a controller's samples [s]: a finite number >=
    :data:`MIN_TIME` (the shortest time CVODES steps over, as ``dt``), and with
    ``settings`` at most ``max_outputs`` samples up to ``t_final`` (the samples are
    times of the run, as the outputs are); :class:`~softcurve.ParameterError` otherwise.

    Parameters
    ----------
    name : str
        The field's name, for the message (e.g. ``"controller.sample_time"``).
    value : float
        The sample time [s].
    settings : SimulationSettings, optional
        The run's settings.
    """
    x = real_scalar(name, value, positive=True)
    shortest = MIN_TIME
    if settings is not None:
        shortest = max(shortest, settings.t_final / settings.max_outputs)
    if x < shortest:
        bound = "" if settings is None else (
            f", and t_final {settings.t_final:g} s over at most max_outputs "
            f"{settings.max_outputs} samples"
        )  # fmt: skip
        raise SettingsError(
            name,
            f"must be >= {shortest:.3g} s (at least {MIN_TIME:.2g} s, the shortest time "
            f"CVODES steps over{bound}), got {x!r}",
        )
    return x


def _atol(value):
    """None, a float > 0, or a tuple of floats > 0."""
    if value is None:
        return None
    if np.ndim(value) == 0:
        return _number("atol", value, unit="")
    try:
        entries = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise SettingsError("atol", f"must be None, a number or a vector, got {value!r}") from None
    if entries.ndim != 1 or entries.size == 0 or not np.all(np.isfinite(entries) & (entries > 0)):
        raise SettingsError("atol", f"must be finite and > 0 in every entry, got {value!r}")
    return tuple(float(a) for a in entries)


_FIELDS = frozenset(f.name for f in dataclasses.fields(SimulationSettings))

_DEFAULT = SimulationSettings()
"""The default settings, validated once (frozen, so one instance serves every call)."""


def settings_with(settings: SimulationSettings | None, options: dict, caller: str):
    """``settings`` (default :class:`SimulationSettings`) with the keyword ``options`` of
    ``caller`` (fields of the settings) applied.

    Parameters
    ----------
    settings : SimulationSettings or None
        The base settings.
    options : dict
        Fields to override.
    caller : str
        The function's name, for messages.
    """
    if settings is None:
        settings = _DEFAULT
    elif not isinstance(settings, SimulationSettings):
        raise ParameterError(
            f"settings must be a SimulationSettings, got {type(settings).__name__}"
        )
    unknown = sorted(set(options) - _FIELDS)
    if unknown:
        raise TypeError(
            f"{caller}() got an unexpected keyword argument {unknown[0]!r} (its settings are "
            f"{', '.join(sorted(_FIELDS))})"
        )
    return settings.replace(**options) if options else settings
