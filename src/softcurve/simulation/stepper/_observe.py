"""What the stepper reports besides the state: the tip position and the total contact
force of the environment, generated with the period function
(``softcurve.simulation.stepper._scheme``) or evaluated on their own.
"""

from __future__ import annotations

import casadi as ca


def observation(model, x, p):
    """``(tip position (3,), total contact force (3,))`` at the state ``x``, both in the
    world frame, as SX; the force is zero without an environment.

    Parameters
    ----------
    model : Model
        The model.
    x : casadi.SX, shape (n_state,)
        The state ``(q, qd, lam)``.
    p : casadi.SX, shape (n_p,)
        Robot parameters.
    """
    n = model.n
    tip = model.symbolic["pose"](x[:n], 1.0, p)[1]
    if model.environment is None:
        return tip, ca.SX.zeros(3)
    e = model.expressions
    rotation = ca.Function("base_rotation", [e.p], [e.base_rotation])(p)
    per_obstacle = model.symbolic["contact"](x[:n], x[n : 2 * n], p)[2]  # (3, k), base frame
    return tip, rotation @ ca.sum2(per_obstacle)


def observer(model, symbolic: bool) -> ca.Function:
    """``(x, p) -> (tip position, total contact force)`` stacked (6,), world frame, for
    ``x = (q, qd, lam)``: without environment on the model's compiled ``pose``; with one,
    in CasADi's virtual machine (the compiled stepper generates its own; this one serves
    the few states a step does not advance and
    :meth:`~softcurve.simulation.stepper.Stepper.tip`), kept with the model.

    Parameters
    ----------
    model : Model
        The model.
    symbolic : bool
        An SX function (to be generated as C with the stepper).
    """

    def build():
        if symbolic or model.environment is not None:
            x = ca.SX.sym("x", model.n_state)
            p = ca.SX.sym("p", model.parameters.size)
            return ca.Function("observe", [x, p], [ca.vertcat(*observation(model, x, p))])
        pose = model.function("pose")
        x, p = ca.MX.sym("x", model.n_state), ca.MX.sym("p", model.parameters.size)
        out = ca.vertcat(pose(x[: model.n], 1.0, p)[1], ca.MX.zeros(3))
        return ca.Function("softcurve_observe", [x, p], [out])

    return model.cached(("stepper-observe", symbolic), build)
