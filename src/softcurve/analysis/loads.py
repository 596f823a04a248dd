"""Constant loads on a robot and their symbolic forms, shared by the static and
linear analyses (:mod:`softcurve.analysis.statics`, :mod:`softcurve.analysis.linear`).

The loads are constant generalized forces ``tau``, constant actuator inputs ``u``
through an :class:`~softcurve.description.actuator.Actuator` (``H(q) u``), and a
constant world-frame tip wrench; the
gravity vector may be overridden without recompiling (it is a run-time parameter).
The CasADi Functions built from them are cached per model, actuator and which tip loads
they carry; the static balance of the equilibria is compiled to C from
:data:`COMPILED_SEGMENTS` segments (:func:`static_balance`).
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
from softcurve.symbolic.kinematics import segment_frames


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
    (tip,) = segment_frames(q, e.n_segments, e.base_rotation, [(e.n_segments - 1, 1.0)])
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


COMPILED_SEGMENTS = 4
"""Robots of this many segments or more solve their statics on the static balance
compiled with the model (:func:`static_balance`), fewer in CasADi's virtual machine.
An equilibrium of the upright robot from rest (``python
benchmarks/bench_statics_chain.py``, and with ``--virtual-machine``) takes in the
virtual machine 0.004 s at one segment, 0.013 s at two, 0.040 s at four, 0.30 s at ten
and 1.4 s at twenty; compiled 0.003 s at four, 0.020 s at ten and 0.09 s at twenty,
after a compile of 4.7 s, 14 s and 114 s once per structure and cache. From four
segments a search of :func:`~softcurve.analysis.statics.equilibria` (48 starts) takes
seconds in the virtual machine and a few searches repay the compile; below, the compile
would be most of what a first equilibrium waits for, and hundreds of equilibria would
repay it."""


def static_balance(load: StaticLoad):
    """The static balance of ``load``'s structure, :func:`static_function` without the tip
    terms ``load`` does not have, compiled to C and cached on disk as the model's library
    is (:func:`~softcurve.compiled.compile_function`, keyed by the function: the robot's
    structure, the actuator and which tip loads, not their values) and kept with the
    model; in CasADi's virtual machine for a model that is not compiled, below
    :data:`COMPILED_SEGMENTS` segments, or without a C compiler.

    Parameters
    ----------
    load : StaticLoad
        The loads and their model.

    Returns
    -------
    callable
        ``F(q, *load.arguments()) -> (r, K, W, tip)`` as :func:`static_function`'s,
        as NumPy arrays or CasADi matrices.
    """
    model = load.model
    tip = (bool(np.any(load.tip_force)), bool(np.any(load.tip_moment)))
    compiled = model.compiled_library is not None and model.robot.n_segments >= COMPILED_SEGMENTS

    def build():
        function = static_function(model, load.actuator, *tip)
        return compile_function(function, load=load_function) if compiled else function

    return model.cached(("loads", "static balance", load.actuator, *tip), build)


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
    """``S = (l0, 1/l0, 1/l0)`` per segment: ``q / S`` is dimensionless (a bending of one
    radian is 1) and ``S * force`` is an energy [J].

    Parameters
    ----------
    robot : Robot
        Supplies the rest lengths ``l0`` [m].
    """
    return np.array(
        [v for s in robot.segments for v in (s.rest_length, 1 / s.rest_length, 1 / s.rest_length)]
    )


def rest_configuration(robot) -> np.ndarray:
    """The straight, unstretched configuration ``(l0, 0, 0)`` per segment.

    Parameters
    ----------
    robot : Robot
        Supplies the rest lengths ``l0`` [m].
    """
    return np.array([v for s in robot.segments for v in (s.rest_length, 0.0, 0.0)])


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
