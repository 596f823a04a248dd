"""A compiled, batched fixed-step stepper: many robots advanced by one control period in
one call into compiled code, for learning environments and other fixed-rate loops.

:class:`Stepper` advances ``N`` members (states ``x`` (N, n_state), inputs (N, m)) by
``period`` seconds with ``substeps`` fixed steps (``softcurve.simulation.stepper._scheme``),
the input held. The state is ``simulate``'s: ``(q, qd, lam)``, then the lagging inputs of
an actuator with a ``time_constant``. A member whose new state is non-finite or outside
the model's domain is flagged in :class:`StepResult` and keeps its state; no member's
failure stops the others. The error is fixed by ``method`` and ``substeps``
(docs/stepping.md); :func:`~softcurve.simulation.simulate` controls it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import casadi as ca
import numpy as np

from softcurve.base.status import Result, Status
from softcurve.base.validation import ParameterError, real_scalar, whole_count
from softcurve.compiled import Model
from softcurve.description.actuator import Actuator
from softcurve.figures import plot_member_tips
from softcurve.simulation.solvers import (
    ActuatorInput,
    BufferedCall,
    Route,
    choose_route,
    domain_reason,
    outside_domain,
)
from softcurve.simulation.solvers import (
    initial_state as checked_state,
)
from softcurve.simulation.stepper._lanes import LanesMembers, lanes_period
from softcurve.simulation.stepper._methods import DEFAULT_EXPLICIT_STEP as DEFAULT_EXPLICIT_STEP
from softcurve.simulation.stepper._methods import DEFAULT_METHOD as DEFAULT_METHOD
from softcurve.simulation.stepper._methods import DEFAULT_STEP as DEFAULT_STEP
from softcurve.simulation.stepper._methods import DEFAULT_SUBSTEPS as DEFAULT_SUBSTEPS
from softcurve.simulation.stepper._methods import METHODS, ExplicitTableau, default_substeps
from softcurve.simulation.stepper._scheme import (
    ThreadedMembers,
    checked_jacobian,
    observer,
    period_function,
)
from softcurve.simulation.stepper._stability import check_explicit_step

CONTACT_JACOBIAN_EVERY = 1
"""Steps between fresh Jacobians with an environment (default of ``jacobian_every``).
Measured (docs/stepping.md): the paper's robot stretching into a ceiling with friction
(``ContactLaw(1e7, damping=1, friction=0.5)``), 0.1 s at 20 ms periods with ROS34PW2 x
16: the curvature ends 0.004 1/m from ``simulate(rtol=1e-10)`` with a Jacobian at every
step, 0.45 with one every 4 steps and 0.59 with one per period (the friction force then
has the wrong sign): a Jacobian from before the body touched, or before it stuck, does
not see the contact's stiffness."""


@dataclass(frozen=True)
class StepResult(Result):
    """The members after one period.

    Parameters
    ----------
    x : ndarray, shape (N, n_state)
        States at the end of the period; a failed member keeps its state from before the
        step.
    tip : ndarray, shape (N, 3)
        Tip position [m] in the world frame at the end of the period (for a failed
        member, at its kept state).
    contact_force : ndarray, shape (N, 3)
        Total force [N] of the environment on the robot, world frame (zeros without an
        environment).
    ok : ndarray, shape (N,), bool
        Whether each member advanced.
    reasons : tuple of (str or None), length N
        None, or why the member failed (non-finite state, left the model's domain).
    """

    x: np.ndarray
    tip: np.ndarray
    contact_force: np.ndarray
    ok: np.ndarray
    reasons: tuple

    @property
    def status(self) -> Status:
        """``SUCCESS`` when every member advanced, ``LEFT_DOMAIN`` when none did, else
        ``PARTIAL``."""
        if self.ok.all():
            return Status.SUCCESS
        return Status.LEFT_DOMAIN if not self.ok.any() else Status.PARTIAL

    @property
    def message(self) -> str:
        """How many members advanced, and the first failure's reason."""
        failed = np.flatnonzero(~self.ok)
        text = f"{self.ok.size - failed.size} of {self.ok.size} members advanced"
        if failed.size:
            text += f"; member {failed[0]}: {self.reasons[failed[0]]}"
        return text

    def plot(self, ax=None):
        """The tip of every member at the end of the period, from the side (x-z) and from
        above (x-y), the members that failed crossed in red.

        Parameters
        ----------
        ax : None or sequence of matplotlib.axes.Axes, shape (2,)
            Panels for the side and the top view; None draws a new figure.

        Returns
        -------
        matplotlib.figure.Figure
            Write it with :func:`softcurve.figures.save_figure`.
        """
        return plot_member_tips(self, ax)


class Stepper:
    """Advance many robots by one control period in one compiled call.

    Parameters
    ----------
    model : Model
        The compiled model (with or without environment); its robot parameters are
        read at every step (one compiled function serves any values of the same
        structure).
    actuator : Actuator, optional
        The inputs are the actuator's (commands when it has a ``time_constant``); without
        one, the inputs are generalized forces [N, N m^2, N m^2].
    period : float
        Control period [s] > 0: the inputs are held over it.
    substeps : int, optional
        Steps per period, >= 1 (default:
        :func:`~softcurve.simulation.stepper.default_substeps`, 16 at a 20 ms
        period, 6 for RK4).
    threads : int, optional
        Threads of the batched call, >= 1 (default ``os.cpu_count()``).
    method : str, optional
        A key of :data:`~softcurve.simulation.stepper.METHODS` (default
        ``softcurve.simulation.stepper._methods.DEFAULT_METHOD``): a Rosenbrock-W
        method for any robot, or ``"RK4"``,
        explicit and about three times faster per period, for a robot without an
        environment whose fastest mode the step resolves (checked here, at rest:
        :func:`~softcurve.simulation.stepper.check_explicit_step`).
    compiled : bool
        Generate the whole period as C over vector lanes of four members and compile it
        (default; ``softcurve.simulation.stepper._lanes``; cached on disk, one
        library per robot structure, environment, actuator, method and ``substeps``), or
        evaluate it in CasADi's virtual machine on the model's right-hand side (no
        compile, slower). A model built with ``compile=False`` is never compiled.
    jacobian_every : int, optional
        Steps between fresh Jacobians, >= 1. Default: one per period for a free robot;
        every step with an environment, whose contact and friction switch on and off
        within a period (:data:`CONTACT_JACOBIAN_EVERY`).
    jacobian : {"differences", "exact"}, optional
        The Newton matrix's Jacobian (a Rosenbrock method's): forward differences of the
        state derivative (default, ``n_x + 1`` evaluations a Jacobian), or the model's
        exact Jacobian, the derivatives of the chain algorithms with the actuator's part,
        generated with the period (over lanes, or per member). A W-method keeps its order
        with either; docs/stepping.md gives what each costs.
    """

    def __init__(
        self,
        model,
        actuator=None,
        *,
        period,
        substeps=None,
        threads=None,
        method=None,
        compiled=True,
        jacobian_every=None,
        jacobian="differences",
    ):
        if not isinstance(model, Model):
            raise ParameterError(f"model must be a softcurve.Model, got {type(model).__name__}")
        if actuator is not None:
            if not isinstance(actuator, Actuator):
                raise ParameterError(
                    f"actuator must be a softcurve.Actuator or None, got {type(actuator).__name__}"
                )
            actuator.check_robot(model.robot)
        self._model, self._actuator = model, actuator
        self._period = real_scalar("period", period, positive=True)
        method = DEFAULT_METHOD if method is None else method
        if method not in METHODS:
            raise ParameterError(f"method must be one of {sorted(METHODS)}, got {method!r}")
        self._method, explicit = method, isinstance(METHODS[method], ExplicitTableau)
        if substeps is None:  # the measured step, whatever the period
            substeps = default_substeps(self._period, method)
        self._substeps = whole_count("substeps", substeps)
        self._threads = whole_count(
            "threads", (os.cpu_count() or 1) if threads is None else threads
        )
        self._input = None if actuator is None else ActuatorInput.of(actuator, model.n)
        extra = 0 if self._input is None else self._input.n_states
        self._n_state = model.n_state + extra
        if actuator is None:
            self._lower, self._upper = np.full(model.n, -np.inf), np.full(model.n, np.inf)
        else:
            self._lower, self._upper = actuator.lower.copy(), actuator.upper.copy()
        self._jacobian = checked_jacobian(jacobian)
        if explicit:
            if jacobian != "differences":
                raise ParameterError(
                    f"jacobian applies to the Rosenbrock methods; {method} takes no "
                    f"Jacobian, got jacobian={jacobian!r}"
                )
            if jacobian_every is not None:
                raise ParameterError(
                    f"jacobian_every applies to the Rosenbrock methods; {method} takes no "
                    f"Jacobian, got jacobian_every={jacobian_every!r}"
                )
            check_explicit_step(model, self._input, self._period, self._substeps, METHODS[method])
        compiled = bool(compiled) and model.compiled_library is not None
        if jacobian_every is None:
            free = model.environment is None
            jacobian_every = self._substeps if free else CONTACT_JACOBIAN_EVERY
        self._every = min(whole_count("jacobian_every", jacobian_every), self._substeps)
        scheme = (model, self._input, self._substeps, method)

        def lane_members():  # members in lock-step: vector lanes
            lanes = lanes_period(model, self._input, self._substeps, method, self._every, jacobian)
            return None if lanes is None else LanesMembers(lanes, self._threads)

        def threaded_members():
            native = period_function(
                *scheme, True, None, self._every, native=True, jacobian=jacobian
            )
            return None if native is None else ThreadedMembers(native, self._threads)

        builders = {"stepper-lanes": lane_members, "stepper-threads": threaded_members}
        self._route = choose_route(
            "stepper", builders=builders if compiled else {}, jacobian=jacobian
        )
        self._members = self._route.built
        # CasADi evaluates the period only where ctypes cannot (no compiled library)
        self._function = None
        if self._members is None:
            self._function = period_function(
                *scheme, compiled, None, self._every, jacobian=jacobian
            )
        inputs_key = None if self._input is None else self._input.key
        self._key = (self._substeps, method, compiled, self._every, inputs_key, jacobian)
        self._period_array = np.array([self._period])
        self._observer = observer(model, symbolic=False)
        self._calls: dict[int, BufferedCall] = {}

    # -- properties ---------------------------------------------------------------
    @property
    def route(self) -> Route:
        """The route that steps the members (``ROUTES`` of :mod:`softcurve.simulation.solvers`:
        "stepper-lanes", "stepper-threads" or "stepper-casadi"), with its reason."""
        return self._route

    @property
    def stats(self) -> dict:
        """``{"route": name, "route_reason": why, "method": method, "substeps": k,
        "jacobian": jacobian}``: the route, its reason and the method as the integrators'
        results record them, with the steps and :attr:`jacobian`."""
        return {"route": self._route.name, "route_reason": self._route.reason,
                "method": self._method, "substeps": self._substeps,
                "jacobian": self.jacobian}  # fmt: skip

    @property
    def model(self) -> Model:
        """The model."""
        return self._model

    @property
    def actuator(self) -> Actuator | None:
        """The actuator, or None (inputs are generalized forces)."""
        return self._actuator

    @property
    def period(self) -> float:
        """The control period [s]."""
        return self._period

    @property
    def substeps(self) -> int:
        """Steps per period."""
        return self._substeps

    @property
    def method(self) -> str:
        """The method's name."""
        return self._method

    @property
    def jacobian_every(self) -> int | None:
        """Steps between fresh Jacobians (None for an explicit method: it takes none)."""
        return None if isinstance(METHODS[self._method], ExplicitTableau) else self._every

    @property
    def jacobian(self) -> str | None:
        """The Newton matrix's Jacobian, "differences" or "exact" (None for an explicit
        method)."""
        return None if isinstance(METHODS[self._method], ExplicitTableau) else self._jacobian

    @property
    def n_state(self) -> int:
        """Length of the state: ``model.n_state`` plus the actuator's lag states."""
        return self._n_state

    @property
    def n_inputs(self) -> int:
        """Inputs per member: the actuator's, or ``model.n`` forces without one."""
        return self._lower.size

    @property
    def lower(self) -> np.ndarray:
        """Lower bounds of the inputs (m,); -inf for forces."""
        return self._lower.copy()

    @property
    def upper(self) -> np.ndarray:
        """Upper bounds of the inputs (m,); inf for forces."""
        return self._upper.copy()

    # -- states ---------------------------------------------------------------------
    def initial_state(self, q0, qd0=None, inputs=None) -> np.ndarray:
        """A state (n_state,): ``(q0, qd0)``, creep states zero, lag states ``inputs``.

        Parameters
        ----------
        q0 : array_like, shape (n,)
            Coordinates [m, 1/m, 1/m] in the model's domain, clear of the obstacles.
        qd0 : array_like, shape (n,), optional
            Rates [m/s, 1/(m s), 1/(m s)] (default zero).
        inputs : array_like, shape (m,), optional
            The actuator's inputs at the start (its lag states; clipped to the bounds),
            default zero clipped to the bounds as in ``simulate``; ignored without lag.
        """
        n = self._model.n
        x = checked_state(self._model, q0, np.zeros(n) if qd0 is None else qd0)
        extra = self._n_state - self._model.n_state
        if not extra:
            return x
        start = np.zeros(extra) if inputs is None else np.asarray(inputs, dtype=np.float64)
        if start.shape != (extra,) or not np.all(np.isfinite(start)):
            raise ParameterError(f"inputs must be finite with shape ({extra},), got {inputs!r}")
        return np.concatenate([x, np.clip(start, self._lower, self._upper)])

    def tip(self, x) -> np.ndarray:
        """Tip positions [m] (N, 3), world frame, at the states ``x`` (N, n_state).

        Parameters
        ----------
        x : array_like, shape (N, n_state)
            States.
        """
        return self._observe(self._states(x))[0]

    # -- the step -------------------------------------------------------------------
    def step(self, x, inputs) -> StepResult:
        """Advance every member by one period with its inputs held.

        Parameters
        ----------
        x : array_like, shape (N, n_state)
            States.
        inputs : array_like, shape (N, m)
            The actuator's inputs (commands with a ``time_constant``), or forces without
            an actuator; clipped to ``[lower, upper]``.

        Returns
        -------
        StepResult
            States, tips and contact forces at the end of the period, and which members
            failed and why.
        """
        x = self._states(x)
        count = x.shape[0]
        u = np.asarray(inputs, dtype=np.float64)
        if u.shape != (count, self.n_inputs):
            raise ParameterError(
                f"inputs must have shape ({count}, {self.n_inputs}), got {u.shape}"
            )
        u = np.ascontiguousarray(np.clip(u, self._lower, self._upper))
        out = np.empty((count, self._n_state + 6))
        failures = {}
        if self._members is not None:  # threads of compiled code, without the GIL
            out[:] = np.nan
            parameters = self._model.parameters
            failures = dict(self._members(x, u, parameters, self._period_array, out))
        else:
            shared = {2: self._model.parameters, 3: self._period_array}
            failure, _ = self._call(count)({0: x, 1: u, **shared}, out)
            if failure is not None:
                failures = dict.fromkeys(range(count), failure)
        x_next = out[:, : self._n_state]
        robot = self._model.robot
        bad_start = outside_domain(x, robot)
        bad = bad_start | outside_domain(x_next, robot)
        bad[list(failures)] = True
        reasons = [None] * count
        for i in np.flatnonzero(bad):
            if i in failures:
                reasons[i] = f"the compiled step failed: {failures[i]}"
            elif bad_start[i]:
                reasons[i] = domain_reason(x[i], robot, 0.0) + " (the state given to the step)"
            else:
                reasons[i] = domain_reason(x_next[i], robot, self._period) + (
                    " (t from the start of the step)"
                )
        tip = out[:, self._n_state : self._n_state + 3]
        force = out[:, self._n_state + 3 :]
        if bad.any():
            x_next[bad] = x[bad]
            tip[bad], force[bad] = self._observe(x[bad])
        return StepResult(
            x=x_next.copy(),
            tip=tip.copy(),
            contact_force=force.copy(),
            ok=~bad,
            reasons=tuple(reasons),
        )

    # -- helpers --------------------------------------------------------------------
    def _states(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != self._n_state or x.shape[0] < 1:
            raise ParameterError(
                f"x must have shape (N, {self._n_state}) with N >= 1, got {x.shape}"
            )
        return np.ascontiguousarray(x)

    def _call(self, count: int) -> BufferedCall:
        """The period function mapped over ``count`` members (threads), cached per count."""
        call = self._calls.get(count)
        if call is None:
            key = ("stepper-map", self._key, count, self._threads)

            def build():
                f = self._function
                mapped = f if count == 1 else f.map(count, "thread", self._threads)
                x = ca.MX.sym("x", f.size1_in(0), count)
                u = ca.MX.sym("u", f.size1_in(1), count)
                p = ca.MX.sym("p", f.size1_in(2))  # shared by the members
                period = ca.MX.sym("period")
                out = mapped(x, u, ca.repmat(p, 1, count), ca.repmat(period, 1, count))
                wrapper = ca.Function("softcurve_stepper_map", [x, u, p, period], [out])
                return BufferedCall(wrapper)

            call = self._calls[count] = self._model.cached(key, build)
        return call

    def _observe(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Tips and contact forces (each (N, 3)) at states ``x`` (N, n_state)."""
        states = x[:, : self._model.n_state].T
        out = np.array(self._observer.map(x.shape[0])(states, self._model.parameters)).T
        return out[:, :3].copy(), out[:, 3:].copy()
