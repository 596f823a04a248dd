"""The integrators of the one engine: CVODES on the model's compiled right-hand side here,
and SciPy's RK45 stepped from Python (``softcurve.simulation.solvers._rk45``).

Both answer one question: starting from state ``x`` at time ``t0``, integrate over
``[t0, t0 + h]`` with a piecewise-constant input ``u`` (one value per output interval)
and return the state at the output times ``t0 + h * tout`` (``0 < tout <= 1``). The input
is the generalized force ``tau`` or, with an :class:`ActuatorInput`, the actuator's inputs,
whose force ``H(q) u`` is evaluated inside the integrator.

CVODES runs in compiled code and never returns to Python during an integration: through
softcurve's C driver (``softcurve.simulation.solvers._driver``; Jacobian by forward
differences, kept while CVODES allows) where it builds, else inside CasADi's
``integrator`` on :func:`scaled_dae`. Measurements of both in ``docs/performance.md``.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import numpy as np

from softcurve.simulation.solvers import _driver as c_driver
from softcurve.simulation.solvers._actuated import actuated_derivative
from softcurve.simulation.solvers._policy import (
    IntegrationFailure,
    cvodes_reason,
)


@dataclass(frozen=True)
class ActuatorInput:
    """An actuator's inputs as the integrator's input: the force is ``H(q) u``.

    Without a ``time_constant`` the integrator's input is the actuator's input ``u``
    itself (e.g. the chamber pressures). With one, it is the command, and the actuator's
    inputs are ``m`` extra states after ``(q, qd, lam)``:
    ``u' = (clip(command, lower, upper) - u) / time_constant``.

    Parameters
    ----------
    force : casadi.Function
        ``(q (n,), u (m,)) -> H(q) u (n,)``.
    lower, upper : ndarray, shape (m,)
        Bounds of the inputs (in the actuator's unit, e.g. [Pa]).
    time_constant : float or None
        First-order lag of the inputs behind their command [s].
    """

    force: ca.Function
    lower: np.ndarray
    upper: np.ndarray
    time_constant: float | None = None

    @classmethod
    def of(cls, actuator, n: int) -> ActuatorInput:
        """The input of ``actuator`` (a :class:`~softcurve.Actuator`) on a robot with
        ``n`` coordinates."""
        q, u = ca.SX.sym("q", n), ca.SX.sym("u", actuator.n_inputs)
        force = ca.Function("H_u", [q, u], [ca.mtimes(actuator.input_matrix_symbolic(q), u)])
        return cls(force, actuator.lower.copy(), actuator.upper.copy(), actuator.time_constant)

    @property
    def n_inputs(self) -> int:
        """Number of inputs ``m``."""
        return self.lower.size

    @property
    def n_states(self) -> int:
        """Extra states: the inputs when they lag their command."""
        return 0 if self.time_constant is None else self.n_inputs

    @cached_property
    def key(self) -> tuple:
        """What the compiled integrators built on it depend on (computed once)."""
        return (self.force.serialize(), self.lower.tobytes(), self.upper.tobytes(),
                self.time_constant)  # fmt: skip

    def state_derivative(self, model, y: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The derivative of ``(x, u)`` (or of ``x`` without lag) in NumPy, for SciPy."""
        x = y[: model.n_state]
        inputs = u if self.time_constant is None else y[model.n_state :]
        force = np.array(self.force(x[: model.n], inputs)).ravel()
        xdot = model.state_derivative(x, force)
        if self.time_constant is None:
            return xdot
        rate = (np.clip(u, self.lower, self.upper) - inputs) / self.time_constant
        return np.concatenate([xdot, rate])

    def forces(self, q: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        """``H(q_k) u_k`` at every row of ``q`` (T, n) and ``inputs`` (T, m): (T, n)."""
        return np.array(self.force.map(q.shape[0])(q.T, inputs.T)).T


def _key(inputs: ActuatorInput | None):
    return None if inputs is None else inputs.key


def scaled_dae(model, inputs: ActuatorInput | None = None) -> ca.Function:
    """``dxs/ds = h f(nominal * xs, tau, p) / nominal`` on normalized time ``s`` in [0, 1].

    Integrator parameter ``(robot parameters (n_p,), h, nominal (n_state [+ m],))``; input
    ``u`` is the input force ``tau`` or, with ``inputs``, the actuator's inputs (or their
    commands, see :class:`ActuatorInput`). The scale is a parameter so that one integrator serves
    every initial state and every member of a batch. The right-hand side is the model's
    compiled ``rhs`` (an ``external``, Jacobian by forward differences) or, without a
    compiled library, its symbolic form.

    Parameters
    ----------
    model : Model
        The compiled model.
    inputs : ActuatorInput, optional
        The actuator's input, or None for forces.
    """

    def build():
        rhs = model.function("rhs", {"enable_fd": True, "fd_method": "forward"})
        xdot_of = actuated_derivative(model, inputs, rhs)
        n_par = model.parameters.size
        size = xdot_of.size1_in(0)
        xs = ca.MX.sym("x", size)
        p = ca.MX.sym("p", n_par + 1 + size)
        u = ca.MX.sym("u", xdot_of.size1_in(1))
        scale = p[n_par + 1 :]
        xdot = xdot_of(scale * xs, u, p[:n_par])
        ode = p[n_par] * xdot / scale
        empty = ca.MX(0, 1)
        return ca.Function(
            "softcurve_dae",
            [ca.MX.sym("t"), xs, ca.MX.sym("z", 0), p, u],
            [ode, empty, empty, empty],
            ca.dyn_in(),
            ca.dyn_out(),
        )

    return model.cached(("dae", _key(inputs)), build)


def cvodes_integrator(
    model, tout: np.ndarray, options: dict, inputs: ActuatorInput | None = None
) -> ca.Function:
    """CVODES on :func:`scaled_dae` with outputs at normalized times ``tout``, cached.

    Parameters
    ----------
    model : Model
        The compiled model.
    tout : ndarray, shape (k,)
        Normalized output times in (0, 1], dimensionless.
    options : dict
        CasADi's CVODES options (:func:`~softcurve.simulation.solvers.cvodes_options`).
    inputs : ActuatorInput, optional
        The actuator's input, or None for forces.
    """
    key = ("cvodes", tout.tobytes(), tuple(sorted(options.items())), _key(inputs))

    def build():
        dae = scaled_dae(model, inputs)
        return ca.integrator("softcurve_cvodes", "cvodes", dae, 0.0, tout, options)

    return model.cached(key, build)


class BufferedCall:
    """A CasADi function evaluated on NumPy memory through its buffer interface (no
    conversions); a lock keeps one caller at a time on the buffer.

    Inputs and the first output are C-contiguous float64 arrays laid out as CasADi's
    column-major matrices (one column after another).
    """

    def __init__(self, function: ca.Function):
        self.lock = threading.Lock()
        self.buffer, self.evaluate = function.buffer()

    def __call__(self, inputs: dict[int, np.ndarray], output: np.ndarray) -> tuple:
        """``(failure, stats)``: None or CasADi's message, and the function's statistics."""
        with self.lock:
            for i, a in inputs.items():
                self.buffer.set_arg(i, memoryview(a))
            self.buffer.set_res(0, memoryview(output))
            try:
                self.evaluate()
                status = self.buffer.ret()
                failure = None if status == 0 else f"status {status}"
            except RuntimeError as exc:
                failure = str(exc)
            return failure, self.buffer.stats()


class PiecewiseSolver:
    """The ``advance`` of every :class:`~softcurve.simulation.solvers.Solver`, written
    once: split the input into runs where it is constant, because an
    error-controlled integrator must not step across a jump of the input."""

    def advance(self, x, h, tout, taus) -> np.ndarray:
        """States (len(tout), n_state) at ``t0 + h * tout`` from ``x`` at ``t0``, with
        ``taus[k]`` applied on ``(tout[k-1], tout[k]]``."""
        taus = np.asarray(taus)
        out = np.empty((tout.size, x.size))
        changes = np.flatnonzero(np.any(taus[1:] != taus[:-1], axis=1)) + 1
        start = 0.0
        for k, stop in zip(np.r_[0, changes], np.r_[changes, tout.size], strict=True):
            j = stop - 1
            length = tout[j] - start
            try:
                out[k:stop] = self._constant(
                    x, h * length, (tout[k:stop] - start) / length, taus[k]
                )
            except IntegrationFailure as failure:
                done = failure.states.shape[0]
                out[k : k + done] = failure.states
                raise IntegrationFailure(failure.reason, out[: k + done].copy()) from None
            x, start = out[j], tout[j]
        return out


class CvodesEngine(PiecewiseSolver):
    """SUNDIALS CVODES (variable order, variable step) with ``multistep`` = "adams" or "bdf".

    Parameters
    ----------
    problem : Problem
        The integration (:class:`~softcurve.simulation.solvers.Problem`): model, actuator
        input, state scale, tolerances (CVODES takes one absolute tolerance for the scaled
        state, ``Problem.scaled_atol``), step budget.
    multistep : {"adams", "bdf"}
        The family at the start.
    native : DriverProblem, optional
        The driver's problem of the route "driver"
        (:func:`~softcurve.simulation.solvers.choose_route`); None: CasADi's integrator.

    Notes
    -----
    Integrates with softcurve's C driver of CVODES
    (:func:`~softcurve.simulation.solvers.driver_integrate`) on the route "driver", else
    with CasADi's CVODES integrator on :func:`scaled_dae`.
    """

    name = "cvodes"

    def __init__(self, problem, multistep="adams", native=None):
        self.problem = problem
        self.model = problem.model
        self.nominal = problem.nominal
        self.inputs = problem.inputs
        self.families = [multistep]
        self.use(multistep)
        self.native = native
        self.route = "casadi-cvodes" if native is None else "driver"
        self.counts = dict.fromkeys(c_driver.STATISTICS, 0)

    def use(self, multistep: str) -> None:
        """Integrate from here on with ``multistep`` ("adams" or "bdf")."""
        self.multistep = multistep
        if multistep not in self.families:
            self.families.append(multistep)

    @property
    def options(self) -> dict:
        """CasADi's CVODES options of the family in use (the route without the C driver)."""
        return self.problem.cvodes_options(self.multistep)

    @property
    def method(self) -> str:
        """ "cvodes-adams", "cvodes-bdf", or "cvodes-adams+bdf" when both were used."""
        return "cvodes-" + "+".join(self.families)

    def _integrator(self, tout: np.ndarray) -> BufferedCall:
        """The integrator with outputs at ``tout``, cached with the model."""
        key = ("buffer", tout.tobytes(), tuple(sorted(self.options.items())), _key(self.inputs))

        def build():
            return BufferedCall(cvodes_integrator(self.model, tout, self.options, self.inputs))

        return self.model.cached(key, build)

    def _count(self, stats: dict) -> None:
        c = self.counts
        c["steps"] += int(stats.get("nsteps", 0))
        c["rhs_evaluations"] += int(stats.get("nfevals", 0))
        # one Jacobian per linear-solver setup (CasADi's call counters accumulate over calls)
        c["jacobian_evaluations"] += int(stats.get("nlinsetups", 0))
        c["linear_solver_setups"] += int(stats.get("nlinsetups", 0))
        c["error_test_failures"] += int(stats.get("netfails", 0))
        c["newton_failures"] += int(stats.get("nncfails", 0))

    def _constant(self, x, h, tout, tau) -> np.ndarray:
        if self.native is not None:
            return self._native(x, h, tout, tau)
        x0 = np.ascontiguousarray(x / self.nominal)
        p = np.concatenate([self.model.parameters, [h], self.nominal])
        u = np.tile(np.asarray(tau, dtype=np.float64), tout.size)  # column-major (n, k)
        out = np.zeros(x.size * tout.size)  # column-major (n_state, k)
        failure, stats = self._integrator(tout)({0: x0, 2: p, 3: u}, out)
        self._count(stats)
        if failure is not None:
            raise IntegrationFailure(cvodes_reason(failure), np.empty((0, x.size)))
        return out.reshape(tout.size, x.size) * self.nominal

    def _native(self, x, h, tout, tau) -> np.ndarray:
        """:meth:`_constant` with the C driver; a failure keeps the outputs reached."""
        out, reached, flags = self.run_native(
            x[None], np.atleast_2d(tau)[:, None, :], np.r_[0.0, h * tout], [tout.size], [False]
        )
        if flags[0]:
            reason = self.failure_reason(flags[0])
            raise IntegrationFailure(reason, out[0, 1 : reached[0]].copy())
        return out[0, 1:]

    @staticmethod
    def failure_reason(flag: int) -> str:
        """The driver's failure ``flag`` in a sentence
        (:func:`~softcurve.simulation.solvers.cvodes_reason`).

        Parameters
        ----------
        flag : int
            A negative flag of CVODES, or -100 (the driver could not set it up).
        """
        return cvodes_reason(c_driver.reason(flag))

    def run_native(
        self, x0, u, times, ends, restart, fastest=None, check_domain=False, out=None
    ) -> tuple:
        """:func:`softcurve.simulation.solvers.driver_integrate` of this run (one member: ``x0``
        (1, N), ``u`` (1, S, k); ``fastest`` [1/s], ``check_domain``: stop at the first output
        outside the model's domain) with this engine's family, counted: ``(states (1, T, N),
        reached, flags)``.

        Parameters
        ----------
        x0, u, times, ends, restart, fastest, check_domain, out
            As :func:`softcurve.simulation.solvers.driver_integrate` takes them, for one member.
        """
        family = c_driver.FAMILIES[self.multistep]
        settings = self.problem.driver_options()
        out, reached, flags, counts, used_bdf = c_driver.integrate(
            self.native, [family], x0, u, self.model.parameters[None], self.nominal[None],
            times, (ends, restart), settings,
            fastest=None if fastest is None else np.array([fastest]),
            check_domain=check_domain, out=out,
        )  # fmt: skip
        for name, value in zip(c_driver.STATISTICS, counts[0].tolist(), strict=True):
            self.counts[name] += value
        if used_bdf[0] and "bdf" not in self.families:
            self.families.append("bdf")
        return out, reached, flags
