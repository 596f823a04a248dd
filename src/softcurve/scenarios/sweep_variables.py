"""The variables of a sweep: what each swept name sets (the initial state, a robot
parameter, an actuator input or an actuator parameter), read and checked from the
``[[sweep.variables]]`` tables of a sweep file (schema: ``docs/sweeps.md``)."""

from __future__ import annotations

import itertools
import re
from dataclasses import dataclass

import numpy as np

from softcurve.base.validation import ParameterError
from softcurve.scenarios.config import Scenario
from softcurve.scenarios.tables import Reader

STATE = re.compile(r"^(q0|qd0|lam0|tau)\[(\d+)\]$")
INPUT = re.compile(r"^(\w+)\[(\d+)\]$")
ACTUATED = ("inputs", "actuator_parameters")
"""What a swept quantity may be besides the state and the robot: the actuator's."""


@dataclass(frozen=True)
class Variable:
    """One swept quantity, sampled in ``[low, high]``.

    Parameters
    ----------
    name : str
        A robot parameter entry (``robot.layout.names``), ``q0[i]``, ``qd0[i]``,
        ``lam0[i]``, ``tau[i]``, or an actuator input or parameter
        (:func:`variable_target`).
    low : float
        Lower end [unit of the quantity].
    high : float
        Upper end (> low) [unit of the quantity].
    scale : {"linear", "log"}
        Spacing of the samples.
    points : int, optional
        Points of a grid design.
    """

    name: str
    low: float
    high: float
    scale: str = "linear"
    points: int | None = None  # grid designs

    def values(self, unit: np.ndarray) -> np.ndarray:
        """Map ``unit`` in [0, 1] onto ``[low, high]`` (the ends exactly).

        Parameters
        ----------
        unit : ndarray
            Points in [0, 1].
        """
        if self.scale == "log":
            values = np.exp(np.log(self.low) + unit * (np.log(self.high) - np.log(self.low)))
        else:
            values = self.low * (1.0 - unit) + self.high * unit
        return np.where(unit == 0.0, self.low, np.where(unit == 1.0, self.high, values))


def variable_target(scenario: Scenario, name: str) -> tuple[str, list[int]] | None:
    """Where the swept quantity ``name`` goes: ``(argument of simulate_batch, indices)``,
    or None when it names nothing.

    ``q0[i]``, ``qd0[i]``, ``lam0[i]``, ``tau[i]``; a robot parameter
    (``robot.layout.names``, argument ``parameters``); with an ``[actuation]`` table an
    actuator input ``inputs[i]`` (also spelled by the actuator's ``input_name``:
    ``tensions[i]``, ``pressures[i]``), or an actuator parameter
    (``actuator.parameter_names()``, e.g. ``tendons[0].distance``), where ``[*]`` stands
    for every index (``tendons[*].distance``: all the tendons' distances at once).

    Parameters
    ----------
    scenario : Scenario
        The scenario swept.
    name : str
        The variable's name.
    """
    match = STATE.match(name)
    if match:
        return match.group(1), [int(match.group(2))]
    index = parameter_index(scenario.robot, name)
    if index is not None:
        return "parameters", [index]
    actuator = scenario.actuator()
    if actuator is None:
        return None
    match = INPUT.match(name)
    if match and match.group(1) in ("inputs", actuator.input_name):
        return "inputs", [int(match.group(2))]
    pattern = re.compile("^" + re.escape(name).replace(r"\[\*\]", r"\[\d+\]") + "$")
    found = [j for j, entry in enumerate(actuator.parameter_names()) if pattern.match(entry)]
    return ("actuator_parameters", found) if found else None


WORDS = {"l": "length l", "kx": "curvature kx", "ky": "curvature ky"}
"""A constant-curvature coordinate in words (a strain is named by itself, ``twist``)."""
RATE_UNITS = {"m": "m/s", "1/m": "1/(m s)", "": "1/s"}
"""The unit of a coordinate's rate, by the coordinate's unit."""


def variable_label(scenario: Scenario, name: str) -> str:
    """The swept quantity ``name`` in words with its unit, for the sweep figure's axes.

    Parameters
    ----------
    scenario : Scenario
        The scenario swept.
    name : str
        A valid variable name (:func:`variable_target` finds it).

    Returns
    -------
    str
        E.g. ``"initial curvature kx, segment 0 [1/m]"`` for ``q0[1]``, ``"segment 0:
        elongation stiffness a1 [N/m]"``, ``"tensions[0] [N]"``; an actuator parameter
        keeps its name (its unit is its actuator's).
    """
    kind, (index, *_) = variable_target(scenario, name)
    if kind in ("q0", "qd0"):
        robot = scenario.robot
        element = int(np.searchsorted(robot.offsets, index, side="right")) - 1
        name = robot.segments[element].coordinate_names[index - robot.offsets[element]]
        words, unit = WORDS.get(name, name), robot.coordinate_units()[index]
        segment, rate_unit = f", segment {element}", RATE_UNITS[unit]
        if kind == "q0":
            return f"initial {words}{segment} [{unit or '-'}]"
        return f"initial rate of {words}{segment} [{rate_unit}]"
    if kind == "parameters":
        return scenario.robot.layout.label(name)
    if kind == "inputs":
        actuator = scenario.actuator()
        unit = f" [{actuator.input_unit}]" if actuator.input_unit else ""
        return f"{actuator.input_name}[{index}]{unit}"
    return name


def parameter_index(robot, name: str) -> int | None:
    """Where the parameter entry ``name`` lies in ``robot``'s vector, None if it is none.

    Parameters
    ----------
    robot : Robot
        The robot.
    name : str
        An entry name, e.g. ``"gravity[2]"``.
    """
    try:
        return robot.layout.index(name)
    except ParameterError:
        return None


def read_variable(r: Reader, design: str, scenario) -> Variable:
    """One ``[[sweep.variables]]`` table, checked: the name, the range (within the
    actuator's bounds for an input), the scale and the grid points.

    Parameters
    ----------
    r : Reader
        The table.
    design : str
        The design, ``"grid"``, ``"random"`` or ``"sobol"``.
    scenario : Scenario
        The scenario swept.
    """
    robot, actuator = scenario.robot, scenario.actuator()
    name = r.get("name", "string", required=True)
    target = variable_target(scenario, name)
    if target is None:
        extra = ""
        if actuator is not None:
            extra = (f", an actuator input inputs[i] ({actuator.input_name}[i]) or an actuator "
                     f"parameter (e.g. {actuator.parameter_names()[1]!r}; "
                     "actuator.parameter_names() lists them)")  # fmt: skip
        r.fail(
            "name",
            f"{name!r} is neither q0[i], qd0[i], lam0[i], tau[i] nor a parameter "
            f"of the robot (e.g. {robot.layout.names[6]!r}; "
            f"softcurve.Robot.parameter_names() lists them){extra}",
        )
    kind, (index, *_) = target
    size = {"lam0": robot.n_creep, "inputs": actuator and actuator.n_inputs}.get(kind, robot.n)
    if kind in ("q0", "qd0", "lam0", "tau", "inputs") and index >= size:
        r.fail("name", f"{name!r}: index out of range, {kind} has {size} entries")
    if name.startswith("base_rotation"):
        r.fail("name", "base_rotation entries cannot be swept one by one (it must stay a rotation)")
    low, high = r.get("low", "number", required=True), r.get("high", "number", required=True)
    if not low < high:
        r.fail("high", f"must be > low = {low}, got {high}")
    if kind == "inputs":
        lower, upper, unit = actuator.lower[index], actuator.upper[index], actuator.input_unit
        if low < lower or high > upper:
            r.fail(
                "low" if low < lower else "high",
                f"the range [{low:g}, {high:g}] {unit} leaves the bounds [{lower:g}, "
                f"{upper:g}] {unit} of {actuator.input_name}[{index}]",
            )
    scale = r.get("scale", "string", "linear")
    if scale not in ("linear", "log"):
        r.fail("scale", f"must be 'linear' or 'log', got {scale!r}")
    if scale == "log" and not low > 0:
        r.fail("low", f"must be > 0 on a log scale, got {low}")
    points = r.get("points", "integer")
    if design == "grid" and (points is None or points < 2):
        r.fail("points", f"is required for a grid design: an integer >= 2, got {points!r}")
    if design != "grid" and points is not None:
        r.fail("points", f"is for grid designs; a {design} design takes sweep.samples")
    r.done()
    return Variable(name, low, high, scale, points)


def check_design_box(config, r: Reader) -> None:
    """Check every robot and every actuator of a design before any work.

    Every robot of the design is valid if every corner of the box of swept robot
    parameters is: the valid set (positive values, ``a1 > a2``, positive definite
    matrices, ...) is convex, and the box is the convex hull of its corners. Actuators
    alike (distances and areas > 0, friction >= 0, any azimuth), and the initial
    coordinates swept (each within the model's domain at the box's ends).

    Parameters
    ----------
    config : SweepConfig
        The sweep (:class:`~softcurve.scenarios.sweep_config.SweepConfig`).
    r : Reader
        The ``[sweep]`` table, for messages.
    """
    scenario = config.scenario
    for kind, what in (("parameters", "robot"), ("actuator_parameters", "actuator")):
        swept = [v for v in config.variables if variable_target(scenario, v.name)[0] == kind]
        if not swept:
            continue
        corners = itertools.product(*[(v.low, v.high) for v in swept]) if len(swept) <= 12 else ()
        if kind == "parameters":
            base, build = scenario.robot.parameter_vector(), scenario.robot.with_parameter_vector
        else:
            base = scenario.actuator().parameter_vector()
            build = scenario.actuator().with_parameter_vector
        for corner in corners:
            vector = base.copy()
            for v, value in zip(swept, corner, strict=True):
                vector[variable_target(scenario, v.name)[1]] = value
            try:
                build(vector)
            except ValueError as exc:
                where = ", ".join(f"{v.name} = {c:g}" for v, c in zip(swept, corner, strict=True))
                r.fail("variables", f"the {what} at the corner {where} of the design is invalid: "
                                    f"{exc}")  # fmt: skip
    robot = scenario.robot
    start = robot.rest_configuration() if scenario.q0 is None else np.array(scenario.q0)
    for v in config.variables:
        match = STATE.match(v.name)
        if not match or match.group(1) != "q0":
            continue
        for value in (v.low, v.high):  # each element's domain is an interval per coordinate
            q = start.copy()
            q[int(match.group(2))] = value
            problem = robot.domain_problem(q, entry="q0")
            if problem is not None:
                r.fail("variables", f"{v.name} = {value:g} is outside the model's domain "
                                    f"({problem})")  # fmt: skip
