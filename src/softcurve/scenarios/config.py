"""Scenario files (TOML): a robot and a simulation, read into a :class:`Scenario`.

The schema is in ``docs/configuration.md`` and examples are in ``examples/``. Every key
is checked: unknown keys, wrong types and values out of range raise :class:`ConfigError`
whose message is ``"<file>: <key path>: <reason>"``. The simulation's settings are
checked by :class:`~softcurve.simulation.SimulationSettings`, the rest by
:class:`Scenario` itself, so a scenario built or changed in Python is checked alike.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from softcurve.analysis.loads import rest_configuration
from softcurve.base.validation import ParameterError
from softcurve.description import presets
from softcurve.description.actuator import Actuator
from softcurve.description.domain import state_problem
from softcurve.description.elements import GROUPS, STRAINS, RigidBody, StrainSegment
from softcurve.description.environment import Environment
from softcurve.description.materials import Creep, LinearStiffness, TanhStiffness
from softcurve.description.robot import Robot, Segment
from softcurve.description.sections import Material, Section
from softcurve.scenarios.actuation import from_mapping
from softcurve.scenarios.environment import environment_from_mapping
from softcurve.scenarios.tables import ConfigError, Reader, read_toml, toml_parameters
from softcurve.simulation import SettingsError, SimulationSettings
from softcurve.symbolic.gaps import start_problem


def _entries(field: str, value, size: int) -> tuple | None:
    """``value`` as a tuple of ``size`` finite floats (None stays None)."""
    if value is None:
        return None
    try:
        entries = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise SettingsError(field, f"must be {size} numbers, got {value!r}") from None
    if entries.shape != (size,) or not np.all(np.isfinite(entries)):
        raise SettingsError(field, f"must have {size} entries, all finite, got {value!r}")
    return tuple(float(v) for v in entries)


@dataclass(frozen=True)
class Scenario:
    """A robot and what to simulate with it (see :func:`softcurve.simulate`); validated on
    construction, also by ``dataclasses.replace``.

    Parameters
    ----------
    robot : Robot
        The robot.
    settings : SimulationSettings
        End time, output interval, integrator and tolerances (default: the paper's case,
        10 s with an output every 1 ms).
    q0 : tuple of float, shape (n,), optional
        Initial coordinates [m, 1/m, 1/m] (default: straight at rest length).
    qd0 : tuple of float, shape (n,), optional
        Initial rates [m/s, 1/(m s), 1/(m s)] (default zero).
    lam0 : tuple of float, shape (n_creep,), optional
        Initial creep states (default zero).
    tau : tuple of float, shape (n,), optional
        Constant input forces [N, N m^2, N m^2] (default zero).
    inputs : tuple of float, shape (m,), optional
        Constant inputs of the actuator of ``actuation`` (pressures [Pa], tensions [N],
        named by the actuator's ``input_name`` in messages), instead of ``tau``.
    source : str
        Where the scenario comes from (a file name), for messages.
    actuation : dict, optional
        The raw ``[actuation]`` table, read by
        :func:`softcurve.scenarios.actuation.from_mapping`.
    environment : Environment or dict, optional
        Obstacles and contact law, or the raw ``[environment]`` table (read by
        :func:`softcurve.scenarios.environment.environment_from_mapping`); stored as an
        :class:`Environment`. ``q0`` (or the straight default) must not start the robot
        inside an obstacle.
    """

    robot: Robot
    settings: SimulationSettings = SimulationSettings()
    q0: tuple | None = None
    qd0: tuple | None = None
    lam0: tuple | None = None
    tau: tuple | None = None
    inputs: tuple | None = None
    source: str = "built-in"
    actuation: dict | None = None
    environment: Environment | dict | None = None

    def __post_init__(self):
        if not isinstance(self.robot, Robot):
            raise SettingsError("robot", f"must be a softcurve.Robot, got {self.robot!r}")
        if not isinstance(self.settings, SimulationSettings):
            raise SettingsError("settings", f"must be a SimulationSettings, got {self.settings!r}")
        n, set_ = self.robot.n, object.__setattr__
        for field, size in (("q0", n), ("qd0", n), ("lam0", self.robot.n_creep), ("tau", n)):
            set_(self, field, _entries(field, getattr(self, field), size))
        actuator = None
        if self.actuation is not None:  # built and checked once, here
            where = f"{self.source}: actuation"
            try:
                actuator = from_mapping(
                    self.actuation, n_segments=self.robot.n_segments, where=where, robot=self.robot
                )
            except ParameterError as exc:
                raise ConfigError(str(exc)) from None
            try:
                actuator.check_robot(self.robot)  # its routing inside the body
            except ParameterError as exc:
                raise ConfigError(f"{where}: {exc}") from None
        # the one check of a state's domain, the robot's and the actuator's
        problem = (
            None if self.q0 is None else state_problem(self.robot, self.q0, actuator, entry="q0")
        )
        if problem is not None:
            raise SettingsError("q0", problem)
        set_(self, "_actuator", actuator)
        self._check_environment()
        if self.inputs is not None:
            self._check_inputs()

    def _check_environment(self) -> None:
        environment = self.environment
        if environment is None:
            return
        try:
            if isinstance(environment, Mapping):
                environment = environment_from_mapping(
                    environment, where=f"{self.source}: environment"
                )
            elif not isinstance(environment, Environment):
                raise ParameterError(
                    f"{self.source}: environment must be a softcurve.Environment or a table, "
                    f"got {type(environment).__name__}"
                )
        except ParameterError as exc:
            raise ConfigError(str(exc)) from None
        try:
            environment.check_robot(self.robot)
        except ParameterError as exc:
            raise ConfigError(f"{self.source}: environment: {exc}") from None
        object.__setattr__(self, "environment", environment)
        problem = start_problem(environment, self.robot, self.initial_state()[0])
        if problem is not None:
            raise SettingsError("q0", problem)

    def _check_inputs(self) -> None:
        if self.actuation is None:
            raise SettingsError("inputs", "needs an [actuation] table (the actuator they drive)")
        if self.tau is not None:
            raise SettingsError("inputs", "give tau or inputs, not both")
        actuator = self.actuator()
        try:
            inputs = actuator.check_inputs(self.inputs, "inputs")
        except ParameterError as exc:  # named as in the file, and what they are
            what = f"the {actuator.input_name} of [actuation]"
            raise SettingsError("inputs", f"{exc} (inputs are {what})") from None
        object.__setattr__(self, "inputs", tuple(float(u) for u in inputs))

    def initial_state(self):
        """``(q0, qd0, lam0)`` as arrays, with the defaults filled in."""
        n, n_creep = self.robot.n, self.robot.n_creep
        rest = rest_configuration(self.robot)
        q0 = rest if self.q0 is None else np.array(self.q0, dtype=float)
        qd0 = np.zeros(n) if self.qd0 is None else np.array(self.qd0, dtype=float)
        lam0 = np.zeros(n_creep) if self.lam0 is None else np.array(self.lam0, dtype=float)
        return q0, qd0, lam0

    def actuator(self) -> Actuator | None:
        """The actuator of the ``[actuation]`` table, or None without one."""
        return self._actuator


def paper_scenario() -> Scenario:
    """The paper's section 4.2 case: preset ifac2020, q0 = (0.064, 25, 0),
    qd0 = (0, 0, 1500), lam0 = 0, 10 s, output every 1 ms (the default settings)."""
    return Scenario(
        robot=presets.ifac2020(),
        q0=(0.064, 25.0, 0.0),
        qd0=(0.0, 0.0, 1500.0),
        source="built-in paper case",
    )


@toml_parameters
def load_config(path) -> Scenario:
    """Read a scenario from a TOML file; raises :class:`ConfigError` on any problem.

    Parameters
    ----------
    %(path)s
    """
    return scenario_from_dict(*read_toml(path))


@toml_parameters
def scenario_from_dict(data: dict, file: str = "<config>") -> Scenario:
    """Build a :class:`Scenario` from the parsed TOML ``data`` (see :func:`load_config`).

    Parameters
    ----------
    %(data)s
    %(file)s
    """
    top = Reader(file, "", data)
    if not top.has("robot"):
        top.fail("robot", "is required (a [robot] table with preset = ... or [[robot.segments]])")
    robot = _robot(top.sub("robot"))
    sim = top.sub("simulation") if top.has("simulation") else Reader(file, "simulation", {})
    actuation = top.get("actuation", "table")
    environment = top.get("environment", "table")
    top.done()
    settings = {
        "t_final": sim.positive("t_final"),
        "dt": sim.positive("dt"),
        "method": sim.get("method", "string"),
        "jacobian": sim.get("jacobian", "string"),
        "rtol": sim.positive("rtol"),
        "max_steps": sim.get("max_steps", "integer"),
        "max_outputs": sim.get("max_outputs", "integer"),
    }
    if sim.has("atol"):
        atol = sim.table["atol"]
        settings["atol"] = (
            sim.positive("atol")
            if not isinstance(atol, list)
            else sim.vector("atol", 2 * robot.n + robot.n_creep)
        )
    values = {
        "q0": sim.vector("q0", robot.n),
        "qd0": sim.vector("qd0", robot.n),
        "lam0": sim.vector("lam0", robot.n_creep),
        "tau": sim.vector("tau", robot.n),
        "inputs": sim.vector("inputs"),
    }
    sim.done()
    try:
        chosen = SimulationSettings(**{k: v for k, v in settings.items() if v is not None})
        return Scenario(
            robot, chosen, source=file, actuation=actuation, environment=environment, **values
        )
    except SettingsError as exc:
        sim.fail(exc.field, exc.reason)


def _robot(r: Reader) -> Robot:
    extra = {}
    if r.has("gravity"):
        extra["gravity"] = r.vector("gravity", 3)
    if r.has("base_rotation"):
        extra["base_rotation"] = _matrix(r, "base_rotation")
    if r.has("base_position"):
        extra["base_position"] = r.vector("base_position", 3)
    if r.has("spans"):
        extra["spans"] = r.vector("spans")
    try:
        if r.has("preset"):
            name = r.get("preset", "string")
            if name != "ifac2020":
                r.fail("preset", f"unknown preset {name!r} (available: ifac2020)")
            creep, damping = r.get("creep", "bool", True), r.get("damping", "bool", True)
            r.done()
            robot = presets.ifac2020(creep=creep, damping=damping)
            return robot.replace(**extra) if extra else robot
        segments = [
            _element(Reader(r.file, f"{r.key('segments')}[{i}]", table))
            for i, table in enumerate(r.get("segments", "tables", required=True))
        ]
        r.done()
        return Robot(segments=tuple(segments), **extra)
    except ConfigError:
        raise
    except ParameterError as exc:
        r.fail("", str(exc))


def _matrix(r: Reader, name: str):
    """A 3 x 3 array of rows."""
    rows = r.get(name, "vector")
    if np.shape(rows) != (3, 3):
        r.fail(name, "must be a 3 x 3 array of rows")
    return rows


def _element(r: Reader):
    """An element of ``[[robot.segments]]`` by its ``kind`` (default: the paper's
    constant-curvature segment)."""
    kind = r.get("kind", "string", Segment.kind)
    readers = {
        Segment.kind: _segment,
        StrainSegment.kind: _strain_segment,
        RigidBody.kind: _rigid_body,
    }
    if kind not in readers:
        r.fail("kind", f"must be one of {sorted(readers)}, got {kind!r}")
    return readers[kind](r)


def _strain_segment(r: Reader) -> StrainSegment:
    """A constant-strain segment: its mass, radius and laws, or its ``material`` and
    ``section`` (:meth:`StrainSegment.from_material`)."""
    strains = r.get("strains", "strings", STRAINS)
    for name in strains:
        if name not in STRAINS:
            r.fail("strains", f"unknown strain {name!r} (allowed: {', '.join(STRAINS)})")
    rest_length = r.positive("rest_length", required=True)
    common = {}
    if r.has("rest_strain"):
        common["rest_strain"] = r.vector("rest_strain", 6)
    if r.has("damping"):
        common["damping"] = r.get("damping", "vector")
    if r.has("creep"):
        r.get("creep", "table")
        common["creep"] = _creep(r.sub("creep"), len(strains))
    if r.has("material") or r.has("section"):
        derived = ("mass", "radius", "slice_inertia", *GROUPS)
        given = [name for name in derived if r.has(name)]
        if given:
            r.fail(given[0], "comes from material and section: give one or the other")
        material = _material(r)
        section = _section(r, material)
        r.done()
        try:
            return StrainSegment.from_material(
                material, section, rest_length, tuple(strains), **common
            )
        except ParameterError as exc:
            r.fail("", str(exc))
    values = {name: r.positive(name, required=True) for name in ("mass", "radius")}
    for law, indices in GROUPS.items():
        chosen = [STRAINS[k] for k in indices if STRAINS[k] in strains]
        if chosen:
            r.get(law, "table", required=True)
            values[law] = _stiffness(r.sub(law))
            continue
        if r.has(law):
            r.fail(law, f"the segment chooses none of {', '.join(STRAINS[k] for k in indices)}")
    if r.has("slice_inertia"):
        values["slice_inertia"] = r.vector("slice_inertia", 3)
    r.done()
    try:
        return StrainSegment(rest_length=rest_length, strains=tuple(strains), **values, **common)
    except ParameterError as exc:
        r.fail("", str(exc))


def _material(r: Reader) -> Material:
    """``material = { youngs_modulus, density, shear_modulus or poisson_ratio }``."""
    r.get("material", "table", required=True)
    m = r.sub("material")
    values = {name: m.positive(name, required=True) for name in ("youngs_modulus", "density")}
    for name in ("shear_modulus", "poisson_ratio"):
        if m.has(name):
            values[name] = m.get(name, "number")
    m.done()
    try:
        return Material(**values)
    except ParameterError as exc:
        m.fail("", str(exc))


def _section(r: Reader, material: Material) -> Section:
    """``section = { radius }`` (a circle), ``{ outer_radius, inner_radius }`` (a tube),
    both of the material's Poisson ratio, or the constants ``{ area, second_moment,
    polar_moment, shear_coefficient, radius (optional) }``."""
    r.get("section", "table", required=True)
    s = r.sub("section")
    nu = material.poisson_ratio
    try:
        if s.has("outer_radius"):
            outer = s.positive("outer_radius")
            inner = s.get("inner_radius", "number", required=True)
            s.done()
            return Section.tube(outer, inner, poisson_ratio=nu)
        if s.has("area"):
            names = ("area", "second_moment", "polar_moment", "shear_coefficient")
            values = {name: s.positive(name, required=True) for name in names}
            values["radius"] = s.positive("radius")
            s.done()
            return Section(**values)
        radius = s.positive("radius", required=True)
        s.done()
        return Section.circle(radius, poisson_ratio=nu)
    except ParameterError as exc:
        if isinstance(exc, ConfigError):
            raise
        s.fail("", str(exc))


def _rigid_body(r: Reader) -> RigidBody:
    mass = r.get("mass", "number", required=True)
    values = {"mass": mass, "tip_position": r.vector("tip_position", 3)}
    if values["tip_position"] is None:
        r.fail("tip_position", "is required (where the next element's base lies [m])")
    if r.has("tip_rotation"):
        values["tip_rotation"] = _matrix(r, "tip_rotation")
    if r.has("centre_of_mass"):
        values["centre_of_mass"] = r.vector("centre_of_mass", 3)
    if r.has("inertia"):
        inertia = r.get("inertia", "vector")
        if np.shape(inertia) not in ((3,), (3, 3)):
            r.fail("inertia", "must be 3 numbers (a diagonal) or a 3 x 3 array of rows")
        values["inertia"] = inertia
    if r.has("radius"):
        values["radius"] = r.positive("radius")
    r.done()
    try:
        return RigidBody(**values)
    except ParameterError as exc:
        r.fail("", str(exc))


def _segment(r: Reader) -> Segment:
    values = {name: r.positive(name, required=True) for name in ("rest_length", "mass", "radius")}
    for mode in ("elongation_stiffness", "bending_stiffness"):
        r.get(mode, "table", required=True)
        values[mode] = _stiffness(r.sub(mode))
    values["damping"] = r.get("damping", "vector", (0.0, 0.0, 0.0))
    if r.has("creep"):
        r.get("creep", "table")
        values["creep"] = _creep(r.sub("creep"))
    r.done()
    try:
        return Segment(**values)
    except ParameterError as exc:
        r.fail("", str(exc))


def _stiffness(r: Reader):
    law = r.get("law", "string", required=True)
    try:
        if law == "tanh":
            a = [r.get(k, "number", required=True) for k in ("a1", "a2", "a3")]
            r.done()
            return TanhStiffness(*a)
        if law == "linear":
            k0 = r.get("k0", "number", required=True)
            r.done()
            return LinearStiffness(k0)
    except ParameterError as exc:
        if isinstance(exc, ConfigError):
            raise
        r.fail("", str(exc))
    r.fail("law", f"must be 'tanh' or 'linear', got {law!r}")


def _creep(r: Reader, size: int = 3) -> Creep:
    """Creep of ``size`` states: ``rate``, ``gain`` and ``compliance`` of that size, or (a
    constant-curvature segment) ``gamma``."""
    compliance = r.get("compliance", "vector", required=True)
    try:
        if r.has("gamma") and size == 3:
            gamma = r.vector("gamma", 6)
            r.done()
            return Creep.from_gamma(gamma, compliance)
        rate, gain = r.vector("rate", size), r.vector("gain", size)
        if rate is None or gain is None:
            gamma = "gamma = [6 numbers] or " if size == 3 else ""
            r.fail("", f"needs {gamma}both rate = [{size}] and gain = [{size}]")
        r.done()
        return Creep(rate=rate, gain=gain, compliance=compliance)
    except ConfigError:
        raise
    except ParameterError as exc:
        r.fail("", str(exc))
