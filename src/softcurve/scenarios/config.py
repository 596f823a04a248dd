"""Files: scenario configurations (TOML) and trajectories (CSV, NPZ).

A configuration describes a robot and a simulation; the schema is in
``docs/configuration.md`` and examples are in ``examples/``. Every key is checked:
unknown keys, wrong types and values out of range raise :class:`ConfigError` whose
message is ``"<file>: <key path>: <reason>"``.

Every file written here is written whole or not at all: to a temporary file in the
target directory, then renamed over the target (:func:`atomic_path`).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from softcurve.base.validation import ParameterError
from softcurve.description import presets
from softcurve.description.materials import Creep, LinearStiffness, TanhStiffness
from softcurve.description.robot import Robot, Segment

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


class ConfigError(ParameterError):
    """A configuration file is malformed; the message names the file and the key."""


@dataclass(frozen=True)
class Scenario:
    """A robot and what to simulate with it (see :func:`softcurve.simulate`)."""

    robot: Robot
    t_final: float = 10.0
    dt: float = 1e-3
    q0: tuple | None = None  # None: the straight rest configuration
    qd0: tuple | None = None
    lam0: tuple | None = None
    tau: tuple | None = None
    pressures: tuple | None = None  # [Pa], with the pressure map of [actuation]
    method: str = "cvodes"
    rtol: float = 1e-6
    atol: float | tuple | None = None
    max_steps: int = 50_000
    source: str = "built-in"
    actuation: dict | None = None  # the raw [actuation] table, read by the actuation model

    def initial_state(self):
        """``(q0, qd0, lam0)`` as arrays, with the defaults filled in."""
        n, n_creep = self.robot.n, self.robot.n_creep
        rest = np.concatenate([[s.rest_length, 0.0, 0.0] for s in self.robot.segments])
        q0 = rest if self.q0 is None else np.array(self.q0, dtype=float)
        qd0 = np.zeros(n) if self.qd0 is None else np.array(self.qd0, dtype=float)
        lam0 = np.zeros(n_creep) if self.lam0 is None else np.array(self.lam0, dtype=float)
        return q0, qd0, lam0

    def actuator(self):
        """The pressure map of the ``[actuation]`` table, or None without one."""
        if self.actuation is None:
            return None
        from softcurve.description.actuators import from_mapping

        where = f"{self.source}: actuation"
        return from_mapping(self.actuation, n_segments=self.robot.n_segments, where=where)


def paper_scenario() -> Scenario:
    """The paper's section 4.2 case: preset ifac2020, q0 = (0.064, 25, 0),
    qd0 = (0, 0, 1500), lam0 = 0, 10 s, output every 1 ms."""
    return Scenario(
        robot=presets.ifac2020(),
        t_final=10.0,
        dt=1e-3,
        q0=(0.064, 25.0, 0.0),
        qd0=(0.0, 0.0, 1500.0),
        source="built-in paper case",
    )


# -- reading configurations --------------------------------------------------------------
class _Reader:
    """Typed access to one TOML table, recording which keys were used."""

    def __init__(self, file: str, path: str, table):
        self.file, self.path = file, path
        if not isinstance(table, dict):
            self.fail("", f"must be a table, got {_kind(table)}")
        self.table = table
        self.used: set[str] = set()

    def key(self, name: str) -> str:
        return f"{self.path}.{name}" if self.path else name

    def fail(self, name: str, reason: str):
        where = self.key(name) if name else self.path or "(top level)"
        raise ConfigError(f"{self.file}: {where}: {reason}")

    def has(self, name: str) -> bool:
        return name in self.table

    def get(self, name, kind, default=None, *, required=False):
        self.used.add(name)
        if name not in self.table:
            if required:
                self.fail(name, "is required")
            return default
        value = self.table[name]
        checker = {
            "number": _number,
            "string": _string,
            "bool": _bool,
            "vector": _vector,
            "integer": _integer,
            "table": _table,
            "tables": _tables,
        }[kind]
        ok, result = checker(value)
        if not ok:
            self.fail(name, f"must be {result}, got {_kind(value)} {value!r}")
        return result

    def positive(self, name, default=None, *, required=False):
        value = self.get(name, "number", default, required=required)
        if value is not None and not value > 0:
            self.fail(name, f"must be > 0, got {value!r}")
        return value

    def vector(self, name, length=None, default=None):
        value = self.get(name, "vector", default)
        if value is not None and length is not None and len(value) not in _as_tuple(length):
            self.fail(
                name,
                f"must have {' or '.join(map(str, _as_tuple(length)))} entries, got {len(value)}",
            )
        return value

    def sub(self, name) -> _Reader:
        self.used.add(name)
        return _Reader(self.file, self.key(name), self.table[name])

    def done(self) -> None:
        unknown = sorted(set(self.table) - self.used)
        if unknown:
            known = ", ".join(sorted(self.used)) or "none"
            self.fail(unknown[0], f"unknown key (allowed here: {known})")


def _as_tuple(x):
    return x if isinstance(x, tuple) else (x,)


def _kind(value) -> str:
    return {
        bool: "a boolean",
        str: "a string",
        int: "an integer",
        float: "a number",
        list: "an array",
        dict: "a table",
    }.get(type(value), type(value).__name__)


def _number(v):
    if isinstance(v, int | float) and not isinstance(v, bool):
        if np.isfinite(v):
            return True, float(v)
    return False, "a finite number"


def _integer(v):
    return (True, v) if isinstance(v, int) and not isinstance(v, bool) else (False, "an integer")


def _string(v):
    return (True, v) if isinstance(v, str) else (False, "a string")


def _bool(v):
    return (True, v) if isinstance(v, bool) else (False, "true or false")


def _vector(v):
    if isinstance(v, list) and v and all(_number(x)[0] for x in v):
        return True, tuple(float(x) for x in v)
    if isinstance(v, list) and v and all(isinstance(r, list) for r in v):
        rows = [_vector(r) for r in v]
        if all(ok for ok, _ in rows) and len({len(r) for _, r in rows}) == 1:
            return True, tuple(r for _, r in rows)
    return False, "a non-empty array of finite numbers (or of equal rows)"


def _table(v):
    return (True, v) if isinstance(v, dict) else (False, "a table")


def _tables(v):
    ok = isinstance(v, list) and v and all(isinstance(x, dict) for x in v)
    return (True, v) if ok else (False, "an array of tables ([[...]])")


def load_config(path) -> Scenario:
    """Read a scenario from a TOML file; raises :class:`ConfigError` on any problem."""
    path = Path(path)
    file = str(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{file}: no such file") from None
    except (IsADirectoryError, PermissionError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{file}: cannot read: {exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{file}: not valid TOML: {exc}") from None
    return scenario_from_dict(data, file)


def scenario_from_dict(data: dict, file: str = "<config>") -> Scenario:
    """Build a :class:`Scenario` from the parsed TOML ``data`` (see :func:`load_config`)."""
    top = _Reader(file, "", data)
    if not top.has("robot"):
        top.fail("robot", "is required (a [robot] table with preset = ... or [[robot.segments]])")
    robot = _robot(top.sub("robot"))
    sim = top.sub("simulation") if top.has("simulation") else _Reader(file, "simulation", {})
    actuation = top.get("actuation", "table")
    top.done()
    values = {
        "t_final": sim.positive("t_final", 10.0),
        "dt": sim.positive("dt", 1e-3),
        "q0": sim.vector("q0", robot.n),
        "qd0": sim.vector("qd0", robot.n),
        "lam0": sim.vector("lam0", robot.n_creep) if robot.n_creep else sim.vector("lam0", 0),
        "tau": sim.vector("tau", robot.n),
        "pressures": sim.vector("pressures"),
        "method": sim.get("method", "string", "cvodes"),
        "rtol": sim.positive("rtol", 1e-6),
        "max_steps": sim.get("max_steps", "integer", 50_000),
    }
    if sim.has("atol"):
        atol = sim.table["atol"]
        values["atol"] = (
            sim.positive("atol")
            if not isinstance(atol, list)
            else sim.vector("atol", 2 * robot.n + robot.n_creep)
        )
        if isinstance(values["atol"], tuple) and min(values["atol"]) <= 0:
            sim.fail("atol", "must be > 0 in every entry")
    sim.done()
    from softcurve.simulation.simulate import METHODS

    if values["method"] not in METHODS:
        sim.fail("method", f"must be one of {', '.join(METHODS)}, got {values['method']!r}")
    if values["dt"] > values["t_final"]:
        sim.fail("dt", f"must be <= t_final = {values['t_final']}, got {values['dt']}")
    if not values["rtol"] < 1:
        sim.fail("rtol", f"must be < 1, got {values['rtol']}")
    if values["max_steps"] < 1:
        sim.fail("max_steps", f"must be >= 1, got {values['max_steps']}")
    q0 = values["q0"]
    if q0 is not None and any(q0[3 * i] <= 0 for i in range(robot.n_segments)):
        sim.fail("q0", "lengths l (entries 0, 3, ...) must be > 0")
    scenario = Scenario(robot=robot, source=file, actuation=actuation, **values)
    if scenario.pressures is not None:
        _check_pressures(sim, scenario)
    return scenario


def _check_pressures(sim: _Reader, scenario: Scenario) -> None:
    if scenario.actuation is None:
        sim.fail("pressures", "needs an [actuation] table (the map from pressures to forces)")
    if scenario.tau is not None:
        sim.fail("pressures", "give tau or pressures, not both")
    actuator = scenario.actuator()
    try:
        actuator.check_inputs(scenario.pressures)
    except ParameterError as exc:
        sim.fail("pressures", str(exc))


def _robot(r: _Reader) -> Robot:
    extra = {}
    if r.has("gravity"):
        extra["gravity"] = r.vector("gravity", 3)
    if r.has("base_rotation"):
        rotation = r.get("base_rotation", "vector")
        if np.shape(rotation) != (3, 3):
            r.fail("base_rotation", "must be a 3 x 3 array of rows")
        extra["base_rotation"] = rotation
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
            _segment(_Reader(r.file, f"{r.key('segments')}[{i}]", table))
            for i, table in enumerate(r.get("segments", "tables", required=True))
        ]
        r.done()
        return Robot(segments=tuple(segments), **extra)
    except ConfigError:
        raise
    except ParameterError as exc:
        r.fail("", str(exc))


def _segment(r: _Reader) -> Segment:
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


def _stiffness(r: _Reader):
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


def _creep(r: _Reader) -> Creep:
    compliance = r.get("compliance", "vector", required=True)
    try:
        if r.has("gamma"):
            gamma = r.vector("gamma", 6)
            r.done()
            return Creep.from_gamma(gamma, compliance)
        rate, gain = r.vector("rate", 3), r.vector("gain", 3)
        if rate is None or gain is None:
            r.fail("", "needs gamma = [6 numbers] or both rate = [3] and gain = [3]")
        r.done()
        return Creep(rate=rate, gain=gain, compliance=compliance)
    except ConfigError:
        raise
    except ParameterError as exc:
        r.fail("", str(exc))
