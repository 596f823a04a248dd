"""What a learning environment simulates: the robot, its actuator, the obstacles, the
control period and the episode's start, from Python objects or a TOML scenario
(:mod:`softcurve.scenarios`), built and checked once.

Defaults (no robot given): the paper's robot (:func:`softcurve.presets.ifac2020`) with
three bellows 12 mm from the backbone, 2e-4 m^2 each, 0 to 6e4 Pa gauge, lagging their
command by 0.02 s (``examples/pneumatic.toml``), controlled every 0.02 s.
"""

from __future__ import annotations

import math
import pickle
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from softcurve.analysis.loads import rest_configuration
from softcurve.base.docs import parameters_from
from softcurve.base.validation import ParameterError, real_scalar, whole_count
from softcurve.compiled import Model
from softcurve.description import presets
from softcurve.description.actuator import Actuator
from softcurve.description.bellows import PneumaticActuator
from softcurve.description.robot import Robot
from softcurve.scenarios.config import Scenario, scenario_from_dict
from softcurve.scenarios.tables import read_toml
from softcurve.simulation import SimulationSettings
from softcurve.simulation.solvers import ActuatorInput
from softcurve.simulation.stepper import (
    METHODS,
    Stepper,
    check_explicit_step,
    checked_jacobian,
    default_substeps,
)

EXPLICIT_METHOD = "RK4"
"""The stepper's method when neither ``method`` nor ``substeps`` is given and the robot
allows it: within 0.58 mm of ``simulate`` where ROS34PW2 is within 0.95 mm, at about three
times the environment steps per second (docs/stepping.md, docs/envs.md)."""

DEFAULT_PERIOD = 0.02
"""Control period [s] without a scenario or ``period=``: 50 Hz, the rate of the
pressure controllers of soft pneumatic robots and ten times the pressure lag below."""

DEFAULT_BELLOWS = {
    "distance": 0.012,
    "area": 2.0e-4,
    "p_min": 0.0,
    "p_max": 6.0e4,
    "time_constant": 0.02,
}
"""The bellows of ``examples/pneumatic.toml`` (illustrative: the paper does not publish
its bellows' geometry)."""

ENV_PARAMETERS = {
    "robot": ("Robot, optional", "The robot (default: ``softcurve.presets.ifac2020()``)."),
    "actuator": (
        "Actuator, optional",
        "What the actions drive: bellows (pressures [Pa]) or tendons (tensions [N]); "
        "default: the three bellows of ``examples/pneumatic.toml``.",
    ),
    "scenario": (
        "Scenario or str or Path, optional",
        "A scenario (or its TOML file) giving the robot, the ``[actuation]``, the "
        "``[environment]``, the start ``q0``/``qd0``/``lam0``, and, where the file sets "
        "them, the control period (``[simulation] dt``), the episode's duration "
        "(``t_final``) and the stepper's Jacobian (``jacobian``); instead of "
        "``robot``/``actuator``.",
    ),
    "environment": (
        "Environment, optional",
        "Obstacles and contact law (default: the scenario's, or the task's own).",
    ),
    "period": ("float, optional", "Control period [s] (default: the scenario's dt or 0.02 s)."),
    "max_episode_steps": (
        "int, optional",
        "Number of control periods after which an episode is truncated (default: the "
        "task's duration, or the scenario's ``t_final``, over the period).",
    ),
    "tolerance": (
        "float, optional",
        "Success tolerance, in the task's unit (Reach, Track: [m]; Press: [N]; default "
        "a twentieth of the workspace or force range).",
    ),
    "substeps": ("int, optional", "Integrator steps per period (the stepper's default)."),
    "method": (
        "str, optional",
        "The stepper's method: ``'RK4'`` (explicit, about three times the throughput) or "
        "``'ROS34PW2'`` (L-stable, for any robot). Default: ``'RK4'`` where the robot "
        "allows it (no obstacles, its fastest mode within RK4's stability at its default "
        "step: checked at construction, docs/stepping.md), else ``'ROS34PW2'``; "
        "``'ROS34PW2'`` when ``substeps`` is given.",
    ),
    "jacobian": (
        "str, optional",
        "The Jacobian of the implicit method's Newton matrix: ``'differences'`` (default, "
        "or the scenario's ``[simulation] jacobian`` where its file sets it and no "
        "``method`` is given) or "
        "``'exact'``, the model's exact Jacobian (a longer first build, cheaper "
        "periods from about four segments on: docs/stepping.md). ``'exact'`` makes "
        "``'ROS34PW2'`` the default method, and is refused with ``'RK4'``.",
    ),
    "threads": ("int, optional", "Threads of the stepper (its default)."),
    "render_mode": ("str, optional", "Gymnasium's render mode; only None is supported."),
}
"""The constructor parameters every environment shares."""

env_parameters = parameters_from(ENV_PARAMETERS)
"""Decorator: substitute the shared entries of :data:`ENV_PARAMETERS` into docstrings."""


def default_actuator(n_segments: int = 1, *, robot: Robot | None = None) -> PneumaticActuator:
    """Three bellows per segment, as ``examples/pneumatic.toml`` (:data:`DEFAULT_BELLOWS`).

    Parameters
    ----------
    n_segments : int
        Number of segments of a robot of constant-curvature segments alone.
    robot : Robot, optional
        A robot of any elements instead: three bellows on each of its soft segments
        (its rigid bodies carry none).
    """
    if robot is None or robot.constant_curvature:
        count = n_segments if robot is None else robot.n_segments
        return PneumaticActuator.three_bellows(n_segments=count, **DEFAULT_BELLOWS)
    return PneumaticActuator.three_bellows(elements=robot, **DEFAULT_BELLOWS)


@dataclass(frozen=True)
class Setup:
    """A robot ready to be stepped: the stepper, the episode's start and length.

    Attributes
    ----------
    stepper : Stepper
        The compiled stepper (model, actuator, period).
    x0 : ndarray, shape (n_state,)
        The state every episode starts from.
    max_episode_steps : int
        Control periods per episode (truncation).
    source : str
        Where the robot came from (a file name or "built-in"), for messages.
    """

    stepper: Stepper
    x0: np.ndarray
    max_episode_steps: int
    source: str

    @property
    def period(self) -> float:
        """The control period [s]."""
        return self.stepper.period


_STEPPERS: dict[bytes, Stepper] = {}
"""Steppers by content (robot, obstacles, actuator, period, substeps, threads, method,
Jacobian): the
environments of one process share them, since building one (its compiled period
function, loaded from the on-disk cache) takes seconds; a stepper keeps no state between
calls."""


def _stepper(robot, environment, actuator, period, substeps, threads, method, jacobian):
    key = pickle.dumps((robot, environment, actuator, period, substeps, threads, method, jacobian))
    if key not in _STEPPERS:
        model = Model(robot, environment=environment)  # loaded from the on-disk cache
        method = stepper_method(model, actuator, period, substeps, method, jacobian)
        _STEPPERS[key] = Stepper(
            model, actuator, period=period, substeps=substeps, threads=threads, method=method,
            jacobian="differences" if jacobian is None else jacobian,
        )  # fmt: skip
    return _STEPPERS[key]


def stepper_method(model, actuator, period, substeps, method, jacobian=None) -> str | None:
    """The stepper's method of an environment: ``method`` when given; else
    :data:`EXPLICIT_METHOD` where its default step passes its check on this robot
    (:func:`~softcurve.simulation.stepper.check_explicit_step`) and neither
    ``substeps``, obstacles nor the exact Jacobian are asked; else None (the stepper's
    default).

    Parameters
    ----------
    model : Model
        The model (its environment, if any, holds the obstacles).
    actuator : Actuator
        The actuator the actions drive.
    period : float
        Control period [s].
    substeps : int or None
        Steps per period, if given.
    method : str or None
        The method asked for.
    jacobian : str or None
        The Jacobian asked for (``"exact"``: an implicit method).
    """
    asked = method is not None or substeps is not None or jacobian == "exact"
    if asked or model.environment is not None:
        return method
    explicit = METHODS[EXPLICIT_METHOD]
    steps = default_substeps(period, EXPLICIT_METHOD)
    try:
        check_explicit_step(model, ActuatorInput.of(actuator, model.n), period, steps, explicit)
    except ParameterError:  # stiff modes: the L-stable default
        return None
    return EXPLICIT_METHOD


SCENARIO_KEYS = ("dt", "t_final", "jacobian")
"""The ``[simulation]`` keys of a scenario that an environment takes where the file sets
them: the control period, the episode's duration and the stepper's Jacobian."""


def _scenario(value) -> tuple[Scenario, set[str]]:
    """The scenario and which ``[simulation]`` keys its file sets explicitly."""
    if isinstance(value, Scenario):
        default = SimulationSettings()
        given = {k for k in SCENARIO_KEYS if getattr(value.settings, k) != getattr(default, k)}
        return value, given
    if isinstance(value, str | Path):
        data, file = read_toml(value)
        simulation = data.get("simulation", {})
        given = {k for k in SCENARIO_KEYS if isinstance(simulation, dict) and k in simulation}
        return scenario_from_dict(data, file), given
    raise ParameterError(f"scenario must be a softcurve Scenario or a TOML path, got {value!r}")


def build_setup(
    *,
    robot=None,
    actuator=None,
    scenario=None,
    environment=None,
    period=None,
    duration: float,
    max_episode_steps=None,
    substeps=None,
    threads=None,
    method=None,
    jacobian=None,
) -> Setup:
    """The :class:`Setup` of an environment from Python objects or a scenario.

    Parameters
    ----------
    %(robot)s
    %(actuator)s
    %(scenario)s
    %(environment)s
    %(period)s
    duration : float
        The task's default episode duration [s].
    %(max_episode_steps)s
    %(substeps)s
    %(threads)s
    %(method)s
    %(jacobian)s
    """
    q0 = qd0 = lam0 = None
    source = "built-in"
    given: set[str] = set()
    if scenario is not None:
        if robot is not None or actuator is not None:
            raise ParameterError("give scenario= or robot=/actuator=, not both")
        scenario, given = _scenario(scenario)
        robot, actuator, source = scenario.robot, scenario.actuator(), scenario.source
        if actuator is None:
            raise ParameterError(
                f"{source}: a learning environment needs an [actuation] table (what the "
                "actions drive)"
            )
        q0, qd0, lam0 = scenario.initial_state()
        if environment is None:
            environment = scenario.environment
        if period is None and "dt" in given:
            period = scenario.settings.dt
        if max_episode_steps is None and "t_final" in given:
            duration = scenario.settings.t_final
        if jacobian is None and method is None and "jacobian" in given:
            jacobian = scenario.settings.jacobian  # a method asked for keeps its own
    robot = presets.ifac2020() if robot is None else robot
    if not isinstance(robot, Robot):
        raise ParameterError(f"robot must be a softcurve.Robot, got {robot!r}")
    if actuator is None:
        actuator = default_actuator(robot=robot)
    if not isinstance(actuator, Actuator) or actuator.n != robot.n:
        raise ParameterError(
            f"actuator must be a softcurve.Actuator acting on the robot's n = {robot.n} "
            f"coordinates, got {actuator!r}"
        )
    if jacobian is not None:  # before the model is built
        checked_jacobian(jacobian)
    period = real_scalar("period", DEFAULT_PERIOD if period is None else period, positive=True)
    if max_episode_steps is None:
        max_episode_steps = max(1, math.ceil(duration / period - 1e-9))
    whole_count("max_episode_steps", max_episode_steps)
    if environment is not None:
        environment.check_robot(robot)
    stepper = _stepper(robot, environment, actuator, period, substeps, threads, method, jacobian)
    if q0 is None:
        q0 = rest_configuration(robot)
    x0 = np.array(stepper.initial_state(q0, qd0), dtype=np.float64)
    if lam0 is not None and robot.n_creep:
        x0[2 * robot.n : 2 * robot.n + robot.n_creep] = lam0  # (q, qd, lam, inputs)
    x0.setflags(write=False)
    return Setup(stepper, x0, int(max_episode_steps), source)


build_setup = env_parameters(build_setup)
