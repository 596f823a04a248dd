"""Contact with rigid obstacles as generalized forces (docs/contact.md, "The law"), symbolic.

The contact is integrated along every segment by the trapezoidal rule on ``K + 1``
equally spaced material points (``K = ContactLaw.points_per_segment``), weights
``l0 / K`` (half at both ends) in rest length, so the penalty is a density per unit of
backbone rest length and the force converges as ``K`` grows. At each point ``x`` (base
frame) and for each obstacle:

- the signed distance ``g(x)`` to the obstacle's surface and its gradient ``n`` (the
  unit outward normal) are exact; the distance to a sphere centre or capsule axis is
  ``sqrt(|d|^2 + EPS^2)``, which differs from ``|d|`` by at most ``EPS^2 / (2 |d|)``
  and keeps the normal finite for a backbone point on the centre itself;
- the penetration ``x_p = r_c - g`` (``r_c`` the contact radius) is rounded by the
  ramp ``h`` of :class:`~softcurve.description.environment.ContactLaw`: piecewise
  polynomial, continuously differentiable, exactly zero out of contact. A softplus
  or ``(x + sqrt(x^2 + w^2)) / 2`` would be analytic, but never zero: far from every
  obstacle the model would differ from the free model, and the penalty energy would
  not vanish. With the ramp the model far from the obstacles equals the free model
  bit for bit (``0 * J^T`` adds exact zeros);
- the elastic normal force ``k h^e n``, the Hunt-Crossley factor
  ``max(0, 1 + d dx_p/dt)`` and the regularized Coulomb friction act at the point and
  map to generalized forces through its Jacobian, ``J^T F`` (reverse mode, one
  sweep per point).

The conservative part (``qd = 0``) is exactly ``-dV_c/dq`` of the penalty energy
``V_c = sum_points weight * U(x_p)`` with ``U`` the closed-form integral of ``k h^e``,
so statics, equilibria and energy balances see it.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from softcurve.description.environment import Capsule, Environment, Plane, Sphere
from softcurve.description.layout import ParameterLayout
from softcurve.symbolic.dynamics import DynamicsExpressions, unpack_parameters
from softcurve.symbolic.functions import build_functions, dynamics_terms_spec, symbolic_functions
from softcurve.symbolic.kinematics import kinematic_chain, segment_frames

EPS = 1e-9
"""Length [m] under the square root of the distance to a sphere centre or capsule axis."""


def signed_distance(obstacle, x):
    """Signed distance [m] from point ``x`` to the obstacle's surface (> 0 outside).

    Parameters
    ----------
    obstacle : Plane, Sphere or Capsule
        The obstacle, base frame.
    x : casadi.SX, shape (3,)
        The point [m], base frame.
    """
    if isinstance(obstacle, Plane):
        return ca.dot(x - ca.DM(obstacle.point), ca.DM(obstacle.normal))
    if isinstance(obstacle, Sphere):
        d = x - ca.DM(obstacle.center)
        return ca.sqrt(ca.dot(d, d) + EPS**2) - obstacle.radius
    if isinstance(obstacle, Capsule):
        a, axis = ca.DM(obstacle.a), ca.DM(obstacle.axis)
        along = ca.fmin(ca.fmax(ca.dot(x - a, axis), 0.0), obstacle.length)  # [m]
        d = x - a - along * axis
        return ca.sqrt(ca.dot(d, d) + EPS**2) - obstacle.radius
    raise TypeError(f"not an obstacle: {type(obstacle).__name__}")


def ramp(x, width: float, exponent: float = 1.0):
    """The rounded penetration ``h(x)`` [m] raised to ``exponent``: ``h`` is 0 for
    ``x <= 0``, ``x^2 / (2 w)`` on ``(0, w)``, ``x - w/2`` beyond; continuously
    differentiable. The power is written on each piece (``x^(2 e) / (2 w)^e`` near the
    surface) rather than as ``h^e``, whose second derivative ``e (e - 1) h^(e - 2) h'^2``
    is NaN (0 times infinity) at the contact's onset for Hertz's ``e = 1.5``: an
    optimizer's Hessian of the dynamics stays finite there.

    Parameters
    ----------
    x : casadi.SX
        Penetration [m] (contact radius minus distance).
    width : float
        ``w`` [m] > 0.
    exponent : float
        ``e`` [-], >= 1.
    """
    inner = ca.fmin(ca.fmax(x, 0.0), width)
    if exponent == 1.0:
        return inner**2 / (2.0 * width) + ca.fmax(x - width, 0.0)
    near = inner ** (2.0 * exponent) / (2.0 * width) ** exponent
    far = (ca.fmax(x - width, 0.0) + width / 2.0) ** exponent
    return ca.if_else(x < width, near, far)


def penalty_energy(x, law):
    """``U(x) = int_0^x k h(y)^e dy`` [J/m], the penalty energy per unit length, closed form.

    Parameters
    ----------
    x : casadi.SX
        Penetration [m].
    law : ContactLaw
        Supplies ``k``, ``e`` and ``w``.
    """
    k, e, w = law.stiffness, law.exponent, law.smoothing
    inner = ca.fmin(ca.fmax(x, 0.0), w)
    outer = ca.fmax(x - w, 0.0)
    near = inner ** (2 * e + 1) / ((2 * w) ** e * (2 * e + 1))
    far = ((outer + w / 2) ** (e + 1) - (w / 2) ** (e + 1)) / (e + 1)
    return k * (near + far)


@dataclass(frozen=True)
class ContactExpressions(DynamicsExpressions):
    """:class:`DynamicsExpressions` of a robot in an environment: ``forward_dynamics`` and
    ``inverse_dynamics`` include the contact force, and the fields below describe it.

    Parameters
    ----------
    contact_force : casadi.SX, shape (n,)
        Generalized contact force ``sum J^T F`` of ``q`` and ``qd``.
    contact_static_force : casadi.SX, shape (n,)
        Its conservative part (``qd = 0``), ``-dV_c/dq``.
    contact_energy : casadi.SX
        Penalty energy ``V_c(q)`` [J].
    obstacle_forces : casadi.SX, shape (3, n_obstacles)
        Total force [N] each obstacle exerts on the robot, base frame.
    obstacle_points : casadi.SX, shape (3, n_obstacles)
        Its point of application [m]: the force-weighted mean of the contact points
        (the base when out of contact).
    """

    contact_force: ca.SX = None
    contact_static_force: ca.SX = None
    contact_energy: ca.SX = None
    obstacle_forces: ca.SX = None
    obstacle_points: ca.SX = None


def contact_points(structure: tuple, environment: Environment):
    """Trapezoidal points along the robot: ``(segment, s, weight / l0)`` triples.

    Segment 0's base is fixed (no work, constant energy) and left out.

    Parameters
    ----------
    structure : tuple
        ``Robot.structure()``.
    environment : Environment
        Supplies ``points_per_segment``.
    """
    k = environment.law.points_per_segment
    points = []
    for i in range(len(structure)):
        for j in range(0 if i else 1, k + 1):
            points.append((i, j / k, (0.5 if j in (0, k) else 1.0) / k))
    return points


def _length(part):
    """An element's length [m] along which its contact points are spread: the rest
    length of a segment, base to tip of a rigid body."""
    if "rest_length" in part:
        return part["rest_length"]
    return ca.norm_2(part["tip_position"])


def with_contact(e: DynamicsExpressions, structure: tuple, environment: Environment):
    """The equation of motion ``e`` with the environment's contact forces added.

    Parameters
    ----------
    e : DynamicsExpressions
        The free robot's expressions (:func:`~softcurve.symbolic.dynamics.build_dynamics`).
    structure : tuple
        ``Robot.structure()`` of the same robot.
    environment : Environment
        Obstacles and contact law; its numbers become constants of the expressions.

    Returns
    -------
    ContactExpressions
        ``e`` with the contact in ``forward_dynamics`` and ``inverse_dynamics``.
    """
    law = environment.law
    segments, _, _, _ = unpack_parameters(e.p, ParameterLayout.of_structure(structure))
    radii = environment.radii([seg["radius"] for seg in segments])
    points = contact_points(structure, environment)
    frames = segment_frames(
        e.q, kinematic_chain(structure, e.p), ca.SX.eye(3), [(i, s) for i, s, _ in points]
    )
    y = ca.SX.sym("y", 3)
    geometry = []
    for obstacle in environment.obstacles:
        distance = signed_distance(obstacle, y)
        geometry.append(ca.Function("g", [y], [distance, ca.gradient(distance, y)]))
    n_obstacles = len(environment.obstacles)
    total, static, energy = ca.SX.zeros(e.q.shape[0]), ca.SX.zeros(e.q.shape[0]), 0
    forces = [ca.SX.zeros(3) for _ in range(n_obstacles)]
    moments = [ca.SX.zeros(3) for _ in range(n_obstacles)]
    magnitudes = [ca.SX(0) for _ in range(n_obstacles)]
    for (i, _, fraction), frame in zip(points, frames, strict=True):
        x = frame.position
        velocity = ca.jtimes(x, e.q, e.qd)
        weight = fraction * _length(segments[i])
        force, elastic_force = ca.SX.zeros(3), ca.SX.zeros(3)
        for o, g in enumerate(geometry):
            distance, normal = g(x)
            penetration = radii[i] - distance
            elastic = weight * law.stiffness * ramp(penetration, law.smoothing, law.exponent)
            energy += weight * penalty_energy(penetration, law)
            normal_force = elastic
            if law.damping:
                rate = -ca.dot(normal, velocity)
                normal_force = elastic * ca.fmax(1.0 + law.damping * rate, 0.0)
            on_point = normal_force * normal
            if law.friction:
                slip = velocity - ca.dot(normal, velocity) * normal
                speed = ca.sqrt(ca.dot(slip, slip) + law.slip_velocity**2)
                on_point -= law.friction * normal_force * slip / speed
            force += on_point
            elastic_force += elastic * normal
            forces[o] += on_point
            size = ca.norm_2(on_point)
            moments[o] += size * x
            magnitudes[o] += size
        total += ca.jtimes(x, e.q, force, True)
        static += ca.jtimes(x, e.q, elastic_force, True)
    where = [
        ca.if_else(m > 0, w / ca.fmax(m, 1e-300), ca.SX.zeros(3))
        for w, m in zip(moments, magnitudes, strict=True)
    ]
    fields = {name: getattr(e, name) for name in e.__dataclass_fields__}
    fields["forward_dynamics"] = ca.substitute(e.forward_dynamics, e.tau, e.tau + total)
    fields["inverse_dynamics"] = e.inverse_dynamics - total
    fields["generalized_force"] = e.generalized_force + total
    return ContactExpressions(
        **fields,
        contact_force=total,
        contact_static_force=static,
        contact_energy=energy,
        obstacle_forces=ca.horzcat(*forces),
        obstacle_points=ca.horzcat(*where),
    )


def contact_statics(e) -> tuple | None:
    """``(conservative generalized contact force (n,), penalty energy)`` of ``e``, or None
    for a robot without environment.

    Parameters
    ----------
    e : DynamicsExpressions
        Expressions of a model, with or without environment.
    """
    if isinstance(e, ContactExpressions):
        return e.contact_static_force, e.contact_energy
    return None


def contact_functions(e: ContactExpressions) -> dict[str, ca.Function]:
    """:func:`~softcurve.symbolic.functions.symbolic_functions` of a robot in an
    environment: ``dynamics_terms`` gains the output ``Fc`` (the generalized contact
    force), ``potential_energy`` the output ``Vc`` (penalty energy), and ``contact``
    gives ``Fc``, ``Vc`` and, per obstacle, the force on the robot and its point.

    Parameters
    ----------
    e : ContactExpressions
        From :func:`with_contact`.

    Returns
    -------
    dict of str to casadi.Function
        By name, the entries of ``symbolic_functions`` with the changes above.
    """
    functions = symbolic_functions(e)
    q, qd, p = e.q, e.qd, e.p
    spec = {
        "dynamics_terms": dynamics_terms_spec(e, ("Fc", "contact_force")),
        "potential_energy": (
            [q],
            ["q"],
            [e.gravity_energy, e.elastic_energy, e.contact_energy],
            ["Vg", "Ve", "Vc"],
        ),
        "contact": (
            [q, qd],
            ["q", "qd"],
            [e.contact_force, e.contact_energy, e.obstacle_forces, e.obstacle_points],
            ["Fc", "Vc", "forces", "points"],
        ),
    }
    functions.update(build_functions(spec, p, e.n_segments))
    return functions
