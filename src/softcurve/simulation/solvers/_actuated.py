"""The state derivative of a robot driven by forces or by an actuator, as a CasADi
function: the one definition behind CVODES's scaled DAE
(``softcurve.simulation.solvers._cvodes.scaled_dae``) and the fixed-step stepper
(``softcurve.simulation.stepper._scheme.state_derivative``).
"""

from __future__ import annotations

import casadi as ca

from softcurve.base.docs import parameters_from

actuated_parameters = parameters_from(
    {
        "model": ("Model", "The model (its sizes)."),
        "inputs": (
            "ActuatorInput or None",
            "The actuator's input, or None for generalized forces.",
        ),
    }
)
"""Substitutes the entries ``model`` and ``inputs`` shared by this module's functions."""


def _actuated(model, inputs) -> tuple:
    """``(x, u, p, tau, rates)`` (MX): the symbols of :func:`actuated_derivative`, the
    generalized force ``tau`` on the robot and the lagging inputs' rates (an empty list
    without a lag)."""
    n, n_state = model.n, model.n_state
    extra = 0 if inputs is None else inputs.n_states
    x = ca.MX.sym("x", n_state + extra)
    u = ca.MX.sym("u", n if inputs is None else inputs.n_inputs)
    p = ca.MX.sym("p", model.parameters.size)
    rates = []
    if inputs is None:
        tau = u
    elif inputs.time_constant is None:
        tau = inputs.force(x[:n], u)
    else:
        lagging = x[n_state:]
        tau = inputs.force(x[:n], lagging)
        command = ca.fmin(ca.fmax(u, ca.DM(inputs.lower)), ca.DM(inputs.upper))
        rates = [(command - lagging) / inputs.time_constant]
    return x, u, p, tau, rates


@actuated_parameters
def actuated_derivative(model, inputs, rhs: ca.Function) -> ca.Function:
    """``(x, u, p) -> xdot`` on the model's right-hand side ``rhs``: ``u`` is the force
    ``tau`` without ``inputs``; with them, the actuator's inputs, whose force is
    ``H(q) u``, or, when they lag, their commands: the inputs are then states after
    ``(q, qd, lam)`` with ``u' = (clip(command, lower, upper) - u) / time_constant``.

    Parameters
    ----------
    %(model)s
    %(inputs)s
    rhs : casadi.Function
        ``(x, tau, p) -> xdot`` of the model (compiled or symbolic).
    """
    x, u, p, tau, rates = _actuated(model, inputs)
    xdot = ca.vertcat(rhs(x[: model.n_state], tau, p), *rates)
    return ca.Function("softcurve_xdot", [x, u, p], [xdot], ["x", "u", "p"], ["xdot"])


@actuated_parameters
def actuated_jacobian(model, inputs, passes, along_inputs: bool = False) -> ca.Function:
    """``(x, u, p) -> J``: the exact Jacobian of :func:`actuated_derivative` by the state
    (n_x, n_x), or by the state and the input (n_x, n_x + n_u). Its passes are
    :func:`actuated_passes`' (the robot's ``dF/dx`` with the actuator's force moving
    with the coordinates and the lagging inputs, and the rows of the creep rates and of
    the lag, ``-1 / time_constant`` on their diagonal); the accelerations' rows are
    ``D^-1 (G - dID/dx)`` (``passes.accelerations``), the inputs' columns having no
    inertial term: ``D^-1 dF/du``.

    Parameters
    ----------
    %(model)s
    %(inputs)s
    passes : JacobianPasses
        The model's (``Model.jacobian_passes``).
    along_inputs : bool
        Append the columns of the input ``u`` (the planners' stage Jacobian).
    """
    n = model.n
    at_state = actuated_passes(model, inputs, passes.at_state, along_inputs)
    x, u, p = (ca.MX.sym(name, at_state.sparsity_in(k)) for k, name in enumerate("xup"))
    *values, g, rows = at_state(x, u, p)
    n_x = x.shape[0]
    columns = n_x + (u.shape[0] if along_inputs else 0)
    accelerations, _ = passes.accelerations(values, ca.reshape(g, n, columns))
    j = ca.vertcat(
        ca.horzcat(ca.MX(n, n), ca.MX.eye(n), ca.MX(n, columns - 2 * n)),
        accelerations,
        ca.reshape(rows, n_x - 2 * n, columns),
    )
    return ca.Function("softcurve_xdot_jacobian", [x, u, p], [j], ["x", "u", "p"], ["J"])


@actuated_parameters
def actuated_passes(
    model, inputs, at_state: ca.Function, along_inputs: bool = False
) -> ca.Function:
    """``(x, u, p) -> (*values, G, R)``: the passes at the state of the exact Jacobian of
    :func:`actuated_derivative`, for code that runs the tangents and the solve by itself
    (the stepper's lanes). The accelerations' rows of ``J`` are
    ``D^-1 (G - dID/dx)``, with ``dID/dx`` and ``D`` the tangent passes at ``values``.

    Parameters
    ----------
    %(model)s
    %(inputs)s
    at_state : casadi.Function
        ``(x, tau, p) -> (*values, dF/dx, d creep rate/dx)`` of the model
        (``softcurve.symbolic.derivatives.JacobianPasses.at_state``).
    along_inputs : bool
        Append the columns of the input ``u`` to ``G`` and ``R``.

    Returns
    -------
    casadi.Function
        ``values``: the passes' dense columns; ``G``: ``vec`` of ``dF/dx`` (n, n_x) with
        the actuator's force's derivative; ``R``: ``vec`` of the rows after the
        accelerations' (creep rates, then lagging inputs), (n_x - 2 n, n_x); with
        ``along_inputs``, each with ``n_u`` columns more.
    """
    n, n_state = model.n, model.n_state
    x, u, p, tau, rates = _actuated(model, inputs)
    *values, force_x, creep_x = at_state(x[:n_state], tau, p)
    along = ca.vertcat(x, u) if along_inputs else x
    # the model's generalized force takes tau with the identity
    g = ca.horzcat(force_x, ca.MX(n, along.shape[0] - n_state)) + ca.jacobian(tau, along)
    rows = ca.vertcat(  # the creep rates do not take tau: zero beyond the model's state
        ca.horzcat(creep_x, ca.MX(n_state - 2 * n, along.shape[0] - n_state)),
        *(ca.jacobian(r, along) for r in rates),
    )
    outputs = [*values, *(ca.vec(ca.densify(m)) for m in (g, rows))]
    names = [*(f"value{k}" for k in range(len(values))), "G", "R"]
    return ca.Function("softcurve_xdot_passes", [x, u, p], outputs, ["x", "u", "p"], names)
