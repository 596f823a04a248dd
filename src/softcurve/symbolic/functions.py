"""The numeric entry points of a model as CasADi Functions of ``(inputs..., p)``.

Built from :class:`~softcurve.symbolic.dynamics.DynamicsExpressions`; the compiled model
generates C for some of them (``softcurve.compiled._build.COMPILED_FUNCTIONS``) and
keeps the rest for users who build on CasADi.
"""

from __future__ import annotations

import casadi as ca

from softcurve.symbolic.kinematics import frame_at


def symbolic_functions(e) -> dict[str, ca.Function]:
    """All numeric entry points as SX Functions whose last input is ``p``.

    Parameters
    ----------
    e : DynamicsExpressions
        The symbolic equation of motion of one robot structure.

    Returns
    -------
    dict of str to casadi.Function
        By name: ``"rhs"``, ``"pose"``, ``"mass_matrix"`` and the others below.
    """
    q, qd, qdd, tau, lam, p = e.q, e.qd, e.qdd, e.tau, e.lam, e.p
    x = ca.vertcat(q, qd, lam)
    xs = ca.SX.sym("x", x.shape[0])
    rhs = ca.vertcat(qd, e.forward_dynamics, e.creep_rate)
    rhs = ca.substitute(rhs, x, xs)
    s = ca.SX.sym("s")
    frame = frame_at(q, e.n_segments, e.base_rotation, s)
    jacobian = ca.vertcat(ca.jacobian(frame.position, q), frame.rotation @ frame.angular_jacobian)
    spec = {
        "dynamics_terms": (
            [q, qd, lam],
            ["q", "qd", "lam"],
            [
                e.mass_matrix,
                e.coriolis_force,
                e.gravity_force,
                e.elastic_force,
                e.damping_force,
                e.creep_force,
            ],
            ["D", "Cqd", "G", "K", "Rqd", "KcT_lam"],
        ),
        "mass_matrix": ([q], ["q"], [e.mass_matrix], ["D"]),
        "coriolis_matrix": ([q, qd], ["q", "qd"], [e.coriolis_matrix], ["C"]),
        "coriolis_force": ([q, qd], ["q", "qd"], [e.coriolis_force], ["Cqd"]),
        "gravity_force": ([q], ["q"], [e.gravity_force], ["G"]),
        "elastic_force": ([q], ["q"], [e.elastic_force], ["K"]),
        "potential_energy": ([q], ["q"], [e.gravity_energy, e.elastic_energy], ["Vg", "Ve"]),
        "kinetic_energy": ([q, qd], ["q", "qd"], [e.kinetic_energy], ["T"]),
        "forward_dynamics": (
            [q, qd, tau, lam],
            ["q", "qd", "tau", "lam"],
            [e.forward_dynamics],
            ["qdd"],
        ),
        "inverse_dynamics": (
            [q, qd, qdd, lam],
            ["q", "qd", "qdd", "lam"],
            [e.inverse_dynamics],
            ["tau"],
        ),
        "creep_rate": ([qd, lam], ["qd", "lam"], [e.creep_rate], ["lamd"]),
        "rhs": ([xs, tau], ["x", "tau"], [rhs], ["xdot"]),
        "pose": ([q, s], ["q", "s"], [frame.rotation, frame.position], ["rotation", "position"]),
        "jacobian": ([q, s], ["q", "s"], [jacobian], ["J"]),
    }
    functions = {}
    for name, (inputs, in_names, outputs, out_names) in spec.items():
        functions[name] = ca.Function(
            name, [*inputs, p], [ca.cse(o) for o in outputs], [*in_names, "p"], out_names
        )
    return functions
