"""The state derivative of a robot driven by forces or by an actuator, as a CasADi
function: the one definition behind CVODES's scaled DAE
(``softcurve.simulation.solvers._cvodes.scaled_dae``) and the fixed-step stepper
(``softcurve.simulation.stepper._scheme.state_derivative``).
"""

from __future__ import annotations

import casadi as ca


def actuated_derivative(model, inputs, rhs: ca.Function) -> ca.Function:
    """``(x, u, p) -> xdot`` on the model's right-hand side ``rhs``: ``u`` is the force
    ``tau`` without ``inputs``; with them, the actuator's inputs, whose force is
    ``H(q) u``, or, when they lag, their commands: the inputs are then states after
    ``(q, qd, lam)`` with ``u' = (clip(command, lower, upper) - u) / time_constant``.

    Parameters
    ----------
    model : Model
        The model (its sizes).
    inputs : ActuatorInput or None
        The actuator's input, or None for generalized forces.
    rhs : casadi.Function
        ``(x, tau, p) -> xdot`` of the model (compiled or symbolic).
    """
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
    xdot = ca.vertcat(rhs(x[:n_state], tau, p), *rates)
    return ca.Function("softcurve_xdot", [x, u, p], [xdot], ["x", "u", "p"], ["xdot"])
