"""What an optimizer needs of a robot, as CasADi Functions with exact derivatives: the
actuated right-hand side, one step of Radau IIA over it, the collocation equations of
that step, the tip, the domain margins and the contact gaps (:class:`Transcription`).

Planning (:func:`~softcurve.control.optimize_trajectory`), the gradients of rollouts and
a user's own optimizer share these Functions. Every one takes the parameter vector ``p``
as an input, so a derivative along the robot's parameters is one more seed, as along the
initial state and the inputs.

The step is one step of the three-stage Radau IIA method (order 5, L-stable, stiffly
accurate: the last stage is the new state), with the inputs held over it. Its stages
solve the collocation equations ``Z_i = h sum_j a_ij f(x + Z_j, u, p)`` (the tableau of
:func:`softcurve.simulation.solvers.radau_tableau`, the C driver's own); the step solves
them by Newton's method (CasADi's ``rootfinder``), so its derivatives are the implicit
function's, exact to the Newton tolerance, and :attr:`Transcription.collocation` gives the
equations themselves to an optimizer that keeps the stages as unknowns (direct
collocation).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import numpy as np

from softcurve.base.validation import ParameterError
from softcurve.compiled import compile_function, exact_external
from softcurve.description.actuator import Actuator
from softcurve.simulation.solvers import (
    ActuatorInput,
    actuated_derivative,
    actuated_jacobian,
    actuator_exit,
    domain_reason,
    initial_state,
    outside_domain,
    radau_tableau,
)
from softcurve.symbolic.functions import domain_margins
from softcurve.symbolic.gaps import obstacle_distances

NEWTON_TOLERANCE = 1e-12
"""Residual norm at which :attr:`Transcription.step`'s Newton iteration stops, in the
units of the state: the stages' derivatives, by the implicit function theorem, are exact
to it."""

NEWTON_ITERATIONS = 30
"""Iterations :attr:`Transcription.step`'s Newton method may take before it fails."""

DERIVATIVE_FLAGS = ("-O1",)
"""The compiler's flags of :meth:`Transcription.compiled_rhs`: ``python
benchmarks/bench_gradient.py --flags`` compiles the paper robot's right-hand side with
its first derivatives under these and under the model's flags and times a gradient with
each: 7.2 s and a gradient of 1.41 s on 100 intervals, against 23.5 s and 1.17 s, so the
first result comes 16 s sooner and about seventy gradients cost what they would with the
model's flags. The second derivatives take the same flags, not measured apart."""

STAGE_JACOBIAN_ROUTES = ("passes", "expanded")
"""The routes of :meth:`Transcription.compiled_stage_jacobian`."""


@dataclass(frozen=True, eq=False)
class Transcription:
    """A robot's dynamics as CasADi Functions for optimizers.

    The state is ``simulate``'s: ``x = (q, qd, lam)`` then, where the actuator lags its
    commands, its inputs; ``u`` is the actuator's inputs (its commands where it lags), or
    the generalized forces ``tau`` without an actuator; ``p`` is the model's parameter
    vector (:attr:`parameters`, ``Model.parameters``).

    Parameters
    ----------
    model : Model
        The compiled model; its environment gives :attr:`gaps`.
    actuator : Actuator, optional
        The actuator whose inputs drive the robot; None: generalized forces.

    Examples
    --------
    >>> import numpy as np
    >>> import softcurve as sc
    >>> model = sc.Model(sc.presets.ifac2020())
    >>> plan = sc.Transcription(model)
    >>> x = np.array([0.064, 25.0, 0.0, 0, 0, 0, 0, 0, 0])
    >>> x1 = plan.step(x, np.zeros(3), plan.parameters, 0.01)
    >>> x1.shape
    (9, 1)
    """

    model: object
    actuator: Actuator | None = None

    def __post_init__(self):
        if self.actuator is not None:
            if not isinstance(self.actuator, Actuator):
                raise ParameterError(
                    f"actuator must be an Actuator or None, got {type(self.actuator).__name__}"
                )
            self.actuator.check_robot(self.model.robot)

    # -- sizes ------------------------------------------------------------------------
    @cached_property
    def inputs(self) -> ActuatorInput | None:
        """The actuator as the integrator's input (None without one)."""
        if self.actuator is None:
            return None
        return ActuatorInput.of(self.actuator, self.model.n)

    @property
    def n_x(self) -> int:
        """Entries of the state: the model's and the lagging inputs."""
        return self.model.n_state + (0 if self.inputs is None else self.inputs.n_states)

    @property
    def n_u(self) -> int:
        """Entries of the input: the actuator's inputs, else the coordinates' forces."""
        return self.model.n if self.inputs is None else self.inputs.n_inputs

    @cached_property
    def tableau(self):
        """Radau IIA's constants (:func:`softcurve.simulation.solvers.radau_tableau`)."""
        return radau_tableau()

    @property
    def stages(self) -> int:
        """Stages of a step (3): the columns of :attr:`collocation`'s ``z``."""
        return self.tableau.nodes.size

    @property
    def parameters(self) -> np.ndarray:
        """The model's parameter vector, shape (n_p,): the ``p`` of every Function."""
        return np.asarray(self.model.parameters, dtype=np.float64)

    @property
    def input_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """``(lower, upper)`` of ``u``, shape (n_u,) each: the actuator's bounds, else
        unbounded forces."""
        if self.inputs is None:
            return np.full(self.n_u, -np.inf), np.full(self.n_u, np.inf)
        return self.inputs.lower.copy(), self.inputs.upper.copy()

    def _symbols(self, kind=ca.SX) -> tuple:
        """``(x, u, p)``: symbols of ``kind`` (``casadi.SX`` or ``casadi.MX``) of the
        state, the input and the parameters."""
        return tuple(kind.sym(name, size) for name, size in
                     (("x", self.n_x), ("u", self.n_u), ("p", self.parameters.size)))  # fmt: skip

    # -- the Functions ----------------------------------------------------------------
    @cached_property
    def rhs(self) -> ca.Function:
        """``rhs(x, u, p) -> xdot``: the actuated state derivative (MX, calling the
        model's symbolic ``rhs``)."""
        return actuated_derivative(self.model, self.inputs, self.model.casadi_rhs())

    @cached_property
    def collocation(self) -> ca.Function:
        """``collocation(x, z, u, p, h) -> (residual, x_next)``: the equations of one Radau
        IIA step from ``x`` with stage increments ``z`` (n_x, 3), ``residual`` (n_x, 3)
        zero at the step's stages, ``x_next = x + z[:, 2]``; ``h`` the step [s]."""
        return self._collocation_on(self.rhs_sx, ca.SX)

    def _collocation_on(self, rhs: ca.Function, kind) -> ca.Function:
        """The collocation equations on the right-hand side ``rhs``, in symbols of
        ``kind`` (``casadi.SX`` or ``casadi.MX``)."""
        x, u, p = self._symbols(kind)
        z, h = kind.sym("z", self.n_x, self.stages), kind.sym("h")
        slopes = ca.horzcat(*[rhs(x + z[:, j], u, p) for j in range(self.stages)])
        return ca.Function(
            "collocation", [x, z, u, p, h], list(self.collocation_equations(x, z, slopes, h)),
            ["x", "z", "u", "p", "h"], ["residual", "x_next"],
        )  # fmt: skip

    def collocation_equations(self, x, z, slopes, h) -> tuple:
        """``(residual, x_next)`` of one Radau IIA step given the slopes at its stages:
        ``residual = z - h slopes A^T`` (``A`` the tableau's matrix), zero where
        ``slopes[:, j]`` is the right-hand side at the stage ``x + z[:, j]``, and
        ``x_next = x + z[:, -1]``. Linear in ``z`` and in ``h slopes``: the curvature of
        the equations is the right-hand side's alone (:attr:`stage_hessian`).

        Parameters
        ----------
        x : casadi.SX or casadi.MX, shape (n_x, 1)
            The state at the step's start.
        z : casadi.SX or casadi.MX, shape (n_x, 3)
            The stage increments.
        slopes : casadi.SX or casadi.MX, shape (n_x, 3)
            The state derivatives at the stages.
        h : casadi.SX or casadi.MX
            The step [s].
        """
        return z - h * ca.mtimes(slopes, ca.DM(self.tableau.matrix.T)), x + z[:, -1]

    @property
    def stage_jacobian(self) -> ca.Function:
        """``stage_jacobian(x, u, p) -> (xdot, J)``: :attr:`rhs` and its exact Jacobian
        along ``(x, u)`` (n_x, n_x + n_u), :meth:`compiled_stage_jacobian` by the route the
        robot's elements take."""
        return self.compiled_stage_jacobian()

    def compiled_stage_jacobian(self, route: str | None = None) -> ca.Function:
        """:attr:`stage_jacobian` by one route, generated as one C function and compiled
        with :data:`DERIVATIVE_FLAGS`, cached on disk with the model's libraries; no
        derivatives of it are compiled (and none by differences: asking for one is an
        error). Where the model is not compiled, the expression in CasADi's virtual
        machine.

        Parameters
        ----------
        route : {"passes", "expanded"}, optional
            ``"passes"``: the derivatives of the chain algorithms through the segments'
            calls (:func:`~softcurve.simulation.solvers.actuated_jacobian` on
            ``Model.jacobian_passes``, ``O(N^2)`` operations in N segments);
            ``"expanded"``: CasADi's Jacobian of the expanded right-hand side
            (:attr:`rhs_sx`). Default: the first where the model keeps its elements'
            calls, the second for a robot of one element, whose model inlines them
            (``Model.inlined``). Measured on 60 stages
            (``python benchmarks/bench_planning.py --stage-jacobians``): the ten-segment
            tendon robot's compiled in 20.2 s by passes and took 39.0 ms, against 62.8 s
            and 150.9 ms expanded; the paper's robot with bellows took 1.6 ms by passes
            and 1.0 ms expanded.
        """
        if route is None:
            route = "expanded" if self.model.inlined else "passes"
        if route not in STAGE_JACOBIAN_ROUTES:
            raise ParameterError(f"route must be one of {STAGE_JACOBIAN_ROUTES}, got {route!r}")
        key = ("stage_jacobian", route)
        if key in self._compiled:
            return self._compiled[key]
        if route == "expanded":
            x, u, p = self._symbols()
            xdot = self.rhs_sx(x, u, p)
            jacobian = ca.jacobian(xdot, ca.vertcat(x, u))
        else:
            passes = self.model.jacobian_passes()
            jacobian_of = actuated_jacobian(self.model, self.inputs, passes, along_inputs=True)
            x, u, p = self._symbols(ca.MX)
            xdot, jacobian = self.rhs(x, u, p), jacobian_of(x, u, p)
        function = ca.Function(
            f"softcurve_stage_jacobian_{route}", [x, u, p], [xdot, ca.densify(jacobian)],
            ["x", "u", "p"], ["xdot", "jacobian"],
        )  # fmt: skip
        if self.model.compiled_library is not None:
            function = compile_function(function, flags=DERIVATIVE_FLAGS, derivatives=0,
                                        load=exact_external)  # fmt: skip
        self._compiled[key] = function
        return function

    @cached_property
    def stage_hessian(self) -> ca.Function:
        """``stage_hessian(x, u, mu, p) -> H`` (n_x + n_u, n_x + n_u): the Hessian of
        ``mu . rhs(x, u, p)`` along ``(x, u)``, on :meth:`compiled_rhs` with its second
        derivatives (twelve directions on the paper's robot with bellows, where the
        Hessian of a whole plan's Lagrangian sweeps every stage in every direction it
        colours).
        """
        x, u, p = self._symbols(ca.MX)
        mu = ca.MX.sym("mu", self.n_x)
        hessian = ca.hessian(ca.dot(mu, self.compiled_rhs(2)(x, u, p)), ca.vertcat(x, u))[0]
        return ca.Function("stage_hessian", [x, u, mu, p], [ca.densify(hessian)],
                           ["x", "u", "mu", "p"], ["hessian"])  # fmt: skip

    def compiled_collocation(self, order: int = 2) -> ca.Function:
        """:attr:`collocation` on :meth:`compiled_rhs` (MX): the same equations, their
        derivatives evaluated in C, up to the second with ``order`` 2 (an exact Hessian of
        the Lagrangian), the first alone with 1 (an optimizer that approximates its
        Hessian). Where nothing compiles, the right-hand side runs in CasADi's virtual
        machine with every derivative.

        Parameters
        ----------
        order : {1, 2}
            The derivatives compiled (:meth:`compiled_rhs`).
        """
        key = ("collocation", order)
        if key not in self._compiled:
            self._compiled[key] = self._collocation_on(self.compiled_rhs(order), ca.MX)
        return self._compiled[key]

    def compiled_rhs(self, order: int = 1) -> ca.Function:
        """:attr:`rhs` generated as C and compiled with its derivatives, forward and
        reverse (:func:`softcurve.compiled.compile_function`'s ``derivatives``: 0 none,
        what the values alone need (CasADi differences any derivative asked of it); 1 the
        first, what an integrator's adjoint and a constraint Jacobian need; 2 also the
        second an exact Hessian needs; 3 also those of forward sensitivities), with
        :data:`DERIVATIVE_FLAGS`, cached on disk with the model's libraries. Where the
        model is not compiled (``compile=False``, or no C compiler), the symbolic
        right-hand side in CasADi's virtual machine, with every derivative.

        Parameters
        ----------
        order : {0, 1, 2, 3}
            The derivatives compiled.
        """
        if order not in (0, 1, 2, 3):
            raise ParameterError(f"order must be 0, 1, 2 or 3, got {order!r}")
        if order not in self._compiled:
            x, u, p = self._symbols()
            rhs = ca.Function("softcurve_actuated_rhs", [x, u, p], [self.rhs_sx(x, u, p)])
            if self.model.compiled_library is None:  # compile=False, or no compiler
                self._compiled[order] = rhs
            else:
                self._compiled[order] = compile_function(
                    rhs, flags=DERIVATIVE_FLAGS, derivatives=order
                )
        return self._compiled[order]

    @cached_property
    def _compiled(self) -> dict:
        return {}

    @cached_property
    def rhs_sx(self) -> ca.Function:
        """:attr:`rhs` expanded to SX: one expression graph, evaluated faster in CasADi's
        virtual machine and differentiated without calls (the collocation's)."""
        return self.rhs.expand()

    @cached_property
    def step(self) -> ca.Function:
        """``step(x, u, p, h) -> x_next``: one Radau IIA step of ``h`` [s] with ``u`` held,
        its stages solved by Newton's method from the explicit Euler guess
        (:data:`NEWTON_TOLERANCE`); derivatives by the implicit function theorem."""
        stages = self.stages
        x, u, p = self._symbols(ca.MX)
        h, z = ca.MX.sym("h"), ca.MX.sym("z", self.n_x * stages)
        residual = self.collocation(x, ca.reshape(z, self.n_x, stages), u, p, h)[0]
        equations = ca.Function("stages", [z, ca.vertcat(x, u, p, h)], [ca.vec(residual)])
        solver = ca.rootfinder(
            "radau_stages", "newton", equations,
            {"abstol": NEWTON_TOLERANCE, "max_iter": NEWTON_ITERATIONS, "error_on_fail": True},
        )  # fmt: skip
        guess = ca.vec(h * ca.mtimes(self.rhs(x, u, p), ca.DM(self.tableau.nodes).T))
        z_solved = ca.reshape(solver(guess, ca.vertcat(x, u, p, h)), self.n_x, stages)
        return ca.Function(
            "step", [x, u, p, h], [x + z_solved[:, -1]], ["x", "u", "p", "h"], ["x_next"]
        )

    def rollout(self, steps: int) -> ca.Function:
        """``rollout(x0, U, p, h) -> X``: ``steps`` steps of :attr:`step` from ``x0``,
        ``U`` (n_u, steps) held one per step, ``X`` (n_x, steps) the state after each.

        Parameters
        ----------
        steps : int
            Steps, >= 1.
        """
        if not (isinstance(steps, int | np.integer) and steps >= 1):
            raise ParameterError(f"steps must be an integer >= 1, got {steps!r}")
        x, u, p = self._symbols(ca.MX)
        h = ca.MX.sym("h")
        one = ca.Function("one", [x, ca.vertcat(u, p, h)], [self.step(x, u, p, h)])
        x0, U = ca.MX.sym("x0", self.n_x), ca.MX.sym("U", self.n_u, int(steps))
        rest = ca.repmat(ca.vertcat(p, h), 1, int(steps))
        states = one.mapaccum("steps", int(steps))(x0, ca.vertcat(U, rest))
        return ca.Function("rollout", [x0, U, p, h], [states], ["x0", "U", "p", "h"], ["X"])

    @cached_property
    def tip(self) -> ca.Function:
        """``tip(x, p) -> position``: the tip's position (3,) [m] in the world frame."""
        x, _, p = self._symbols()
        position = self.model.symbolic["pose"](x[: self.model.n], 1.0, p)[1]
        return ca.Function("tip", [x, p], [position], ["x", "p"], ["position"])

    @cached_property
    def domain(self) -> ca.Function:
        """``domain(x, p) -> margins``: every element's domain margins (length, bend,
        twist, shear, in the chain's order) and the actuator's (each fiber's length per
        segment: tendons, chambers), inside the domain where all are >= 0 (the strict
        ones > 0) [each margin's unit]."""
        x, _, p = self._symbols()
        q = x[: self.model.n]
        values = [m.value for m in domain_margins(self.model.robot.structure(), q, p)]
        if self.actuator is not None:
            for part in self.actuator.segment_lengths_symbolic(q):
                values.extend(part)
        margins = ca.vertcat(*values) if values else ca.SX(0, 1)
        return ca.Function("domain", [x, p], [margins], ["x", "p"], ["margins"])

    @cached_property
    def gaps(self) -> ca.Function | None:
        """``gaps(x, p) -> distances``: the signed distance [m] of each contact point (the
        base first) from each obstacle, vectorized point by point, positive outside; None
        where the model has no environment."""
        environment = self.model.environment
        if environment is None:
            return None
        distances, _ = obstacle_distances(environment, self.model.robot.structure())
        x, _, p = self._symbols()
        values = ca.vec(distances(x[: self.model.n], p).T)
        return ca.Function("gaps", [x, p], [values], ["x", "p"], ["distances"])

    def domain_exit(self, x: np.ndarray, t: np.ndarray, robot=None) -> str | None:
        """Why the states ``x`` first leave the model's or the actuator's domain, by the
        checks ``simulate`` runs at its outputs (every kind's own, strict margins), or
        None where every state lies inside.

        Parameters
        ----------
        x : ndarray, shape (T, n_x)
            States at the times ``t`` (:attr:`n_x` entries each).
        t : ndarray, shape (T,)
            Their times [s].
        robot : Robot, optional
            The robot of another parameter vector than the model's (its rest lengths and
            bounds), default the model's.
        """
        robot = self.model.robot if robot is None else robot
        states = x[:, : self.model.n_state]
        outside = np.flatnonzero(outside_domain(states, robot))
        first = [(k, domain_reason(states[k], robot, float(t[k]))) for k in outside[:1]]
        exit_ = actuator_exit(self.actuator, t, states[:, : robot.n])
        first += [exit_] if exit_ is not None else []
        return min(first, key=lambda entry: entry[0])[1] if first else None

    def start(self, q0, qd0=None, lam0=None, actuator_state=None) -> np.ndarray:
        """The state ``x`` of a start, as ``simulate`` builds it, checked.

        Parameters
        ----------
        q0 : array_like, shape (n,)
            Coordinates, in the model's domain.
        qd0 : array_like, shape (n,), optional
            Rates (default zero).
        lam0 : array_like, shape (n_creep,), optional
            Creep states (default zero).
        actuator_state : array_like, shape (m,), optional
            The lagging inputs' start (default the actuator's rest inputs).
        """
        model = self.model
        x0 = initial_state(model, q0, np.zeros(model.n) if qd0 is None else qd0, lam0)
        if self.actuator is None:
            if actuator_state is not None:
                raise ParameterError("actuator_state needs an actuator with a time_constant")
            return x0
        lagging = self.actuator.lag_start(actuator_state)  # refused without a lag
        problem = self.actuator.domain_problem(x0[: model.n])
        if problem is not None:
            raise ParameterError(f"q0 is outside the actuator's domain: {problem}")
        parts = [x0, lagging] if self.inputs.n_states else [x0]
        return np.concatenate(parts)
