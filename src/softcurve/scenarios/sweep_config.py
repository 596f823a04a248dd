"""Sweep files: a design over named parameters and initial conditions, read and checked
into a :class:`SweepConfig` before any simulation runs (schema: ``docs/sweeps.md``)."""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from dataclasses import dataclass

import numpy as np

from softcurve._version import __version__
from softcurve.scenarios.config import Scenario, scenario_from_dict
from softcurve.scenarios.sweep_variables import (
    ACTUATED,
    Variable,
    check_design_box,
    read_variable,
    variable_target,
)
from softcurve.scenarios.tables import ConfigError, Reader, read_toml, toml_parameters
from softcurve.simulation import SimulationSettings
from softcurve.symbolic.dynamics import DEFAULT_QUADRATURE_NODES

DESIGNS = ("grid", "random", "sobol")
OUTPUTS = ("final_state", "tip_range", "settling_time", "peak_energy")
MAX_DESIGN_SIZE = 10_000_000


@dataclass(frozen=True)
class SweepConfig:
    """A validated sweep: the scenario, the variables and how to run and summarize.

    Parameters
    ----------
    scenario : Scenario
        The robot and the simulation every design point starts from.
    variables : tuple of Variable
        The swept quantities.
    design : {"grid", "random", "sobol"}
        How the points are chosen.
    samples : int or None
        Points of a random or Sobol design.
    seed : int
        Seed of a random or Sobol design.
    chunk_size : int
        Simulations per chunk (one file per chunk).
    output_dt : float
        Output interval of the simulations [s].
    outputs : tuple of str
        Summaries per simulation, from ``OUTPUTS``.
    settling_fraction : float
        Band of the settling time, a fraction of the largest tip excursion.
    fingerprint : str
        Hash of the configuration and the softcurve version.
    quadrature_nodes : int
        Quadrature nodes of the model.
    source : str
        The file read.
    """

    scenario: Scenario
    variables: tuple[Variable, ...]
    design: str
    samples: int | None
    seed: int
    chunk_size: int
    output_dt: float
    outputs: tuple[str, ...]
    settling_fraction: float
    fingerprint: str
    quadrature_nodes: int = DEFAULT_QUADRATURE_NODES
    source: str = "<config>"

    def design_points(self) -> np.ndarray:
        """The design, shape (size, len(variables)), one row per simulation."""
        d = len(self.variables)
        if self.design == "grid":
            axes = [np.linspace(0.0, 1.0, v.points) for v in self.variables]
            unit = np.array(list(itertools.product(*axes)), dtype=np.float64).reshape(-1, d)
        elif self.design == "random":
            unit = np.random.default_rng(self.seed).random((self.samples, d))
        else:
            from scipy.stats import qmc

            sobol = qmc.Sobol(d, scramble=True, seed=self.seed)
            unit = sobol.random_base2(int(math.log2(self.samples)))
        return np.column_stack([v.values(unit[:, j]) for j, v in enumerate(self.variables)])

    @property
    def settings(self) -> SimulationSettings:
        """The scenario's settings with the sweep's output interval."""
        return self.scenario.settings.replace(dt=self.output_dt)

    @property
    def actuated(self) -> bool:
        """Whether the actuator drives the members: the scenario gives its ``inputs`` or
        a variable is one of them or an actuator parameter."""
        swept = (variable_target(self.scenario, v.name)[0] for v in self.variables)
        return self.scenario.inputs is not None or any(kind in ACTUATED for kind in swept)

    def batch_arguments(self, design: np.ndarray) -> dict:
        """The arguments of :func:`~softcurve.simulation.batch.simulate_batch` for the
        design rows ``design`` (rows, len(variables)): ``q0``, ``qd0``, ``lam0``,
        ``parameters`` and either ``tau`` or ``actuator``, ``inputs`` and
        ``actuator_parameters``, one row per design point.

        Parameters
        ----------
        design : ndarray, shape (rows, len(variables))
            Design points.
        """
        scenario = self.scenario
        q0, qd0, lam0 = scenario.initial_state()
        rows = {"q0": q0, "qd0": qd0, "lam0": lam0, "parameters": scenario.robot.parameter_vector()}
        actuator = scenario.actuator() if self.actuated else None
        if actuator is None:
            rows["tau"] = np.zeros(scenario.robot.n) if scenario.tau is None else scenario.tau
        else:
            given = scenario.inputs
            rows["inputs"] = actuator.rest_inputs() if given is None else given
            rows["actuator_parameters"] = actuator.parameter_vector()
        size = design.shape[0]
        rows = {k: np.repeat(np.asarray(v, float)[None, :], size, axis=0) for k, v in rows.items()}
        for j, v in enumerate(self.variables):
            kind, indices = variable_target(scenario, v.name)
            rows[kind][:, indices] = design[:, j : j + 1]
        return {**rows, "actuator": actuator} if actuator is not None else rows

    @property
    def size(self) -> int:
        """Number of design points."""
        if self.design == "grid":
            return math.prod(v.points for v in self.variables)
        return self.samples


# -- reading and checking ------------------------------------------------------------------
@toml_parameters
def load_sweep(path) -> SweepConfig:
    """Read and check a sweep file; raises :class:`ConfigError` naming the key.

    Parameters
    ----------
    %(path)s
    """
    return sweep_from_dict(*read_toml(path))


@toml_parameters
def sweep_from_dict(data: dict, file: str = "<config>") -> SweepConfig:
    """Build a :class:`SweepConfig` from parsed TOML; every check happens here.

    Parameters
    ----------
    %(data)s
    %(file)s
    """
    if not isinstance(data, dict) or "sweep" not in data:
        raise ConfigError(f"{file}: sweep: is required (a [sweep] table, see docs/sweeps.md)")
    rest = {k: v for k, v in data.items() if k != "sweep"}
    scenario = scenario_from_dict(rest, file)
    if scenario.settings.method == "rk45":
        raise ConfigError(
            f"{file}: simulation.method: sweeps run cvodes, auto, adams, bdf or radau, got 'rk45'"
        )
    r = Reader(file, "sweep", data["sweep"])
    design = r.get("design", "string", required=True)
    if design not in DESIGNS:
        r.fail("design", f"must be one of {', '.join(DESIGNS)}, got {design!r}")
    samples = r.get("samples", "integer")
    if design == "grid" and samples is not None:
        r.fail("samples", "is for random and sobol designs; a grid takes points per variable")
    if design != "grid":
        if samples is None or samples < 1:
            r.fail("samples", f"is required for a {design} design: an integer >= 1")
        if design == "sobol" and samples & (samples - 1):
            r.fail("samples", f"must be a power of 2 for a sobol design (balance), got {samples}")
    seed = r.get("seed", "integer", 0)
    if seed < 0:
        r.fail("seed", f"must be >= 0, got {seed}")
    chunk_size = r.get("chunk_size", "integer", 64)
    if chunk_size < 1:
        r.fail("chunk_size", f"must be >= 1, got {chunk_size}")
    t_final = scenario.settings.t_final
    output_dt = r.positive("output_dt", min(0.01, t_final))
    if output_dt > t_final:
        r.fail("output_dt", f"must be <= simulation.t_final = {t_final}, got {output_dt}")
    outputs = _strings(r, "outputs")
    nodes = r.get("quadrature_nodes", "integer", DEFAULT_QUADRATURE_NODES)
    if not 1 <= nodes <= 64:
        r.fail("quadrature_nodes", f"must be in [1, 64], got {nodes}")
    fraction = r.positive("settling_fraction", 0.02)
    if not fraction < 1:
        r.fail("settling_fraction", f"must be in (0, 1), got {fraction}")
    tables = r.get("variables", "tables", required=True)
    variables = tuple(
        read_variable(Reader(file, f"sweep.variables[{i}]", t), design, scenario)
        for i, t in enumerate(tables)
    )
    r.done()
    names = [v.name for v in variables]
    for name in names:
        if names.count(name) > 1:
            r.fail("variables", f"{name!r} appears more than once")
    config = SweepConfig(
        scenario=scenario,
        variables=variables,
        design=design,
        samples=samples,
        seed=seed,
        chunk_size=chunk_size,
        output_dt=output_dt,
        outputs=outputs,
        settling_fraction=fraction,
        fingerprint=_fingerprint(data),
        source=file,
        quadrature_nodes=nodes,
    )
    if config.actuated and scenario.tau is not None:
        raise ConfigError(
            f"{file}: simulation.tau: the actuator drives this sweep (simulation.inputs or an "
            "actuator variable): give simulation.inputs, not tau"
        )
    if config.size > MAX_DESIGN_SIZE:
        r.fail("variables", f"the design has {config.size} points, more than {MAX_DESIGN_SIZE}")
    check_design_box(config, r)
    return config


def _strings(r: Reader, name: str) -> tuple[str, ...]:
    r.used.add(name)
    value = r.table.get(name, list(OUTPUTS))
    if not (isinstance(value, list) and value and all(isinstance(v, str) for v in value)):
        r.fail(name, f"must be a non-empty array of names from {', '.join(OUTPUTS)}")
    for v in value:
        if v not in OUTPUTS:
            r.fail(name, f"unknown output {v!r} (allowed: {', '.join(OUTPUTS)})")
    return tuple(dict.fromkeys(value))


def _fingerprint(data: dict) -> str:
    text = json.dumps({"config": data, "softcurve": __version__}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]
