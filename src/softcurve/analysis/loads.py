"""Constant loads on a robot and their symbolic forms, shared by the static and
linear analyses (:mod:`softcurve.analysis.statics`, :mod:`softcurve.analysis.linear`).

The loads are constant generalized forces ``tau``, constant actuator inputs ``u``
through an :class:`~softcurve.description.actuator.Actuator` (``H(q) u``), and a
constant world-frame tip wrench; the
gravity vector may be overridden without recompiling (it is a run-time parameter).
The CasADi Functions built from them are cached per model, actuator and which tip loads
they carry; the static balance of the equilibria is compiled to C once its evaluations
would have paid for the compile (:class:`StaticBalance`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from softcurve.base.docs import shared_parameters
from softcurve.base.validation import ParameterError, real_array
from softcurve.compiled import compile_function, load_function
from softcurve.description.actuator import Actuator
from softcurve.symbolic.contact import contact_statics
from softcurve.symbolic.kinematics import kinematic_chain, segment_frames


# -- loads ------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class StaticLoad:
    """Constant loads on the robot, validated against a model.

    Parameters
    ----------
    model : Model
        The model the loads act on.
    tau : array_like, shape (n,), optional
        Constant generalized forces.
    actuator : Actuator, optional
        The actuator; needed with ``inputs``.
    inputs : array_like, shape (m,), optional
        Constant actuator inputs [the actuator's ``input_unit``, e.g. Pa], within its
        bounds.
    tip_force : array_like, shape (3,), optional
        Constant world-frame force on the tip [N].
    tip_moment : array_like, shape (3,), optional
        Constant world-frame moment on the tip [N m] (not conservative, see module doc).
    gravity : array_like, shape (3,), optional
        Gravity [m/s^2] in the world frame; default the robot's own.
    """

    model: object
    tau: np.ndarray | None = None
    actuator: Actuator | None = None
    inputs: np.ndarray | None = None
    tip_force: np.ndarray | None = None
    tip_moment: np.ndarray | None = None
    gravity: np.ndarray | None = None
    parameters: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        n = self.model.n
        set_ = object.__setattr__  # frozen dataclass: normalize fields once here
        set_(self, "tau", real_array("tau", np.zeros(n) if self.tau is None else self.tau, (n,)))
        if (self.actuator is None) != (self.inputs is None):
            raise ParameterError("inputs and actuator must be given together")
        if self.actuator is not None:
            if not isinstance(self.actuator, Actuator):
                raise ParameterError(
                    f"actuator must be an Actuator, got {type(self.actuator).__name__}"
                )
            self.actuator.check_robot(self.model.robot)
            set_(self, "inputs", self.actuator.check_inputs(self.inputs))
        for name in ("tip_force", "tip_moment"):
            value = getattr(self, name)
            set_(self, name, real_array(name, np.zeros(3) if value is None else value, (3,)))
        gravity = self.model.robot.gravity if self.gravity is None else self.gravity
        set_(self, "gravity", real_array("gravity", gravity, (3,)))
        parameters = self.model.parameters.copy()
        parameters[self.model.robot.layout.slice("gravity")] = self.gravity
        set_(self, "parameters", parameters)

    @property
    def conservative(self) -> bool:
        """False when a tip moment is applied or the actuator is not conservative
        (e.g. tendons with friction)."""
        actuator_conservative = self.actuator is None or self.actuator.conservative
        return actuator_conservative and not np.any(self.tip_moment)

    def arguments(self) -> list:
        """The load inputs of the cached CasADi Functions, after ``q`` or ``x``."""
        inputs = np.zeros(0) if self.inputs is None else self.inputs
        return [self.parameters, self.tau, inputs, self.tip_force, self.tip_moment]


def _load_symbols(model, actuator, tip_force: bool = True, tip_moment: bool = True):
    """Symbols of the loads and the expressions built from them (see StaticLoad); without
    ``tip_force`` or ``tip_moment`` their terms are left out (their symbols stay inputs)."""
    e = model.expressions
    q, n = e.q, model.n
    m_inputs = 0 if actuator is None else actuator.n_inputs
    tau, u = ca.SX.sym("tau", n), ca.SX.sym("u", m_inputs)
    force, moment = ca.SX.sym("f", 3), ca.SX.sym("m", 3)
    elements = kinematic_chain(e.structure, e.p)
    (tip,) = segment_frames(
        q, elements, e.base_rotation, [(e.n_segments - 1, 1.0)], e.base_position
    )
    tip_work = ca.dot(force, tip.position) if tip_force else ca.SX(0)
    potential = e.gravity_energy + e.elastic_energy - ca.dot(tau, q) - tip_work
    # the tip force's term apart: the statics take it from its work (tip_work)
    terms = {"force": ca.jacobian(tip.position, q).T @ force} if tip_force else {}
    if tip_moment:
        terms["moment"] = (tip.rotation @ tip.angular_jacobian).T @ moment
    if actuator is not None:
        terms["actuator"] = actuator.input_matrix_symbolic(q) @ u
        potential -= actuator.input_work_symbolic(q, u)
    load, other = tau, tau
    for name, term in terms.items():
        load = load + term
        other = other if name == "force" else other + term
    contact = contact_statics(e)  # the penalty force and energy, with an environment
    if contact is not None:
        potential += contact[1]
    return {
        "inputs": [e.p, tau, u, force, moment],
        "names": ["p", "tau", "u", "f", "m"],
        "load": load,
        "other": other,
        "tip_work": tip_work,
        "potential": potential,
        "tip": tip.position,
        "contact": None if contact is None else contact[0],
    }


def _static_residual(e, sym):
    """``N(q) - loads``, minus the conservative contact force with an environment."""
    residual = e.gravity_force + e.elastic_force - sym["load"]
    return residual if sym["contact"] is None else residual - sym["contact"]


def _load_function(model, actuator, name: str, build, tip: tuple[bool, bool] = (True, True)):
    """The function ``build(expressions, load symbols)`` makes, cached in ``model`` under
    ``name``, the actuator and which tip loads ``tip`` (force, moment) it carries."""
    return model.cached(
        ("loads", name, actuator, *tip),
        lambda: build(model.expressions, _load_symbols(model, actuator, *tip)),
    )


@shared_parameters
def static_function(
    model, actuator: Actuator | None, tip_force: bool = True, tip_moment: bool = True
) -> ca.Function:
    """``F(q, p, tau, u, f, m) -> (r, K, W, tip)``: the residual ``r = N - loads``,
    ``K = dr/dq``, the conservative potential ``W`` [J] and the tip position [m].

    ``K`` takes the gravity's and the tip force's part as the Hessian of their potential
    (symmetric: about two thirds of the operations of the Jacobian of their force).

    Parameters
    ----------
    %(model)s
    %(actuator)s
    tip_force, tip_moment : bool
        Whether the function carries the tip force's and the tip moment's terms; without
        them it takes ``f`` and ``m`` but leaves them out, a smaller function: at twenty
        segments the moment's part of ``K`` is 1.4 of 2.1 million instructions.
    """

    def build(e, sym):
        hessian, gradient = ca.hessian(e.gravity_energy - sym["tip_work"], e.q)
        rest = e.elastic_force - sym["other"]
        if sym["contact"] is not None:
            rest = rest - sym["contact"]
        return ca.Function(
            "static_balance",  # not "static": the C generated from it is named so
            [e.q, *sym["inputs"]],
            [gradient + rest, hessian + ca.jacobian(rest, e.q), sym["potential"], sym["tip"]],
            ["q", *sym["names"]],
            ["r", "K", "W", "tip"],
        )

    return _load_function(model, actuator, "static", build, (tip_force, tip_moment))


COMPILE_AFTER = 2000
"""Evaluations of a structure's static balance in CasADi's virtual machine after which
it is compiled (:class:`StaticBalance`): about what a compile costs. Measured with
``python benchmarks/bench_statics_chain.py --virtual-machine`` and without (2-core
x86_64), an equilibrium of the upright robot evaluates the balance 22 times at four
segments, 35 at ten and 44 at twenty, an evaluation in the virtual machine takes 1.7 ms,
8.6 ms and 32 ms, the compile 4.2 s, 14 s and 94 s: 2,500, 1,600 and 3,000
evaluations' worth. Compiling once the
evaluations made would have paid for it (the ski-rental rule) keeps the total within
about twice the better of the two choices made in hindsight, whether a user solves one
equilibrium (44 evaluations at twenty segments) or thousands; a library already in the
cache is loaded at once."""


class StaticBalance:
    """The static balance of one structure, called as its CasADi function: in CasADi's
    virtual machine until it has been evaluated :data:`COMPILE_AFTER` times, then
    compiled to C and cached on disk as the model's library is
    (:func:`~softcurve.compiled.compile_function`, keyed by the function: the robot's
    structure, the actuator and which tip loads, not their values); compiled at once
    when its library is in the cache already. A model built with ``compile=False``
    keeps it in the virtual machine, as does a machine without a C compiler.

    Parameters
    ----------
    function : casadi.Function
        :func:`static_function`'s.
    compilable : bool
        Whether it may be compiled (the model is).
    """

    def __init__(self, function: ca.Function, compilable: bool):
        self.function = function
        self.evaluations = 0
        self.compilable = compilable
        # a library in the cache already: loaded now (serialized for its key once)
        self.compiled = (
            compile_function(function, load=load_function, build_new=False) if compilable else None
        )

    @property
    def in_c(self) -> bool:
        """Whether it is evaluated in compiled C."""
        return self.compiled is not None and not isinstance(self.compiled, ca.Function)

    def _compile(self) -> None:
        self.compilable = False  # tried once, whatever happens
        self.compiled = compile_function(self.function, load=load_function)

    def __call__(self, *args):
        """``(r, K, W, tip)`` at ``args``, as :func:`static_function`'s."""
        if self.compiled is None:
            self.evaluations += 1
            if self.compilable and self.evaluations > COMPILE_AFTER:
                self._compile()
        return (self.compiled or self.function)(*args)


def static_balance(load: StaticLoad) -> StaticBalance:
    """The static balance of ``load``'s structure, :func:`static_function` without the tip
    terms ``load`` does not have, kept with the model, compiled once its evaluations
    would have paid for it (:class:`StaticBalance`).

    Parameters
    ----------
    load : StaticLoad
        The loads and their model.

    Returns
    -------
    StaticBalance
        ``F(q, *load.arguments()) -> (r, K, W, tip)`` as :func:`static_function`'s,
        as NumPy arrays or CasADi matrices.
    """
    model = load.model
    tip = (bool(np.any(load.tip_force)), bool(np.any(load.tip_moment)))
    return model.cached(
        ("loads", "static balance", load.actuator, *tip),
        lambda: StaticBalance(
            static_function(model, load.actuator, *tip), model.compiled_library is not None
        ),
    )


@shared_parameters
def linear_function(model, actuator: Actuator | None) -> ca.Function:
    """``F(x, p, tau, u, f, m) -> (A, B, D, K)`` of the closed-form loaded dynamics
    ``xdot = f(x, tau + H(q) u + J^T w)``; ``B = df/dtau``.

    Parameters
    ----------
    %(model)s
    %(actuator)s
    """

    def build(e, sym):
        x = ca.vertcat(e.q, e.qd, e.lam)
        qdd = ca.substitute(e.forward_dynamics, e.tau, sym["load"])
        xdot = ca.vertcat(e.qd, qdd, e.creep_rate)
        residual = _static_residual(e, sym)
        tau = sym["inputs"][1]
        return ca.Function(
            "linear",
            [x, *sym["inputs"]],
            [
                ca.jacobian(xdot, x),
                ca.jacobian(xdot, tau),
                e.mass_matrix,
                ca.jacobian(residual, e.q),
            ],
            ["x", *sym["names"]],
            ["A", "B", "D", "K"],
        )

    return _load_function(model, actuator, "linear", build)


def elastic_stiffness_function(model) -> ca.Function:
    """``K_e(q, p) = d(elastic force)/dq``, the elastic part of the tangent stiffness.

    Parameters
    ----------
    model : Model
        The compiled model.
    """
    e = model.expressions
    return model.cached(
        ("loads", "elastic_stiffness"),
        lambda: ca.Function("k", [e.q, e.p], [ca.jacobian(e.elastic_force, e.q)]),
    )


def coordinate_scale(robot) -> np.ndarray:
    """``S``, the robot's
    :meth:`~softcurve.description.robot.Robot.coordinate_scale` (``(l0, 1/l0, 1/l0)`` per
    constant-curvature segment, ``1/L0`` per curvature and 1 per strain of a
    constant-strain one): ``q / S`` is dimensionless (a bending of one radian is 1) and
    ``S * force`` is an energy [J].

    Parameters
    ----------
    robot : Robot
        The robot.
    """
    return robot.coordinate_scale()


def rest_configuration(robot) -> np.ndarray:
    """The configuration at rest: ``(l0, 0, 0)`` per constant-curvature segment, the rest
    strains of a constant-strain one (:meth:`Robot.rest_configuration
    <softcurve.description.robot.Robot.rest_configuration>`).

    Parameters
    ----------
    robot : Robot
        The robot.
    """
    return robot.rest_configuration()


def residual_reference(model) -> np.ndarray:
    """``diag(S K_e S)`` at rest [J]: the elastic stiffness of each scaled coordinate,
    positive for every admissible stiffness law; the unit of the scaled residuals.

    Parameters
    ----------
    model : Model
        The compiled model.
    """
    stiffness = np.array(
        elastic_stiffness_function(model)(rest_configuration(model.robot), model.parameters)
    )
    return np.abs(np.diag(stiffness)) * coordinate_scale(model.robot) ** 2
