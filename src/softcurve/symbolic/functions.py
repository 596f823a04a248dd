"""The numeric entry points of a model as CasADi Functions of ``(inputs..., p)``.

Built from :class:`~softcurve.symbolic.dynamics.DynamicsExpressions`; the compiled model
generates C for some of them (``softcurve.compiled._build.COMPILED_FUNCTIONS``) and
keeps the rest for users who build on CasADi.
"""

from __future__ import annotations

import casadi as ca

from softcurve.description.elements import coordinate_slices, element_model, margins_hold
from softcurve.description.layout import ParameterLayout
from softcurve.symbolic.kinematics import inline_calls, kinematic_chain, point_at

DYNAMICS_TERMS = (
    ("D", "mass_matrix"),
    ("Cqd", "coriolis_force"),
    ("G", "gravity_force"),
    ("K", "elastic_force"),
    ("Rqd", "damping_force"),
    ("KcT_lam", "creep_force"),
)
"""The outputs of ``dynamics_terms``: each output's name and the expression (attribute
of the expressions) it returns."""


def dynamics_terms_spec(e, *more) -> tuple:
    """The ``dynamics_terms`` entry of a spec of :func:`build_functions`: inputs ``(q,
    qd, lam)``, outputs :data:`DYNAMICS_TERMS` followed by ``more``.

    Parameters
    ----------
    e : DynamicsExpressions
        The symbolic equation of motion (or an extension of it).
    *more : tuple of (str, str)
        Further ``(output name, attribute)`` pairs.
    """
    terms = (*DYNAMICS_TERMS, *more)
    return (
        [e.q, e.qd, e.lam],
        ["q", "qd", "lam"],
        [getattr(e, attribute) for _, attribute in terms],
        [name for name, _ in terms],
    )


def configuration_only(e, expression):
    """``expression`` of ``e`` (a function of ``q`` alone, such as ``D``) freed of the
    symbol ``qd``, which reaches it only through the inputs of the segments' Functions.

    Parameters
    ----------
    e : DynamicsExpressions
        The expressions ``expression`` belongs to.
    expression : casadi.SX
        Independent of ``qd`` in value.
    """
    return ca.substitute(expression, e.qd, ca.SX.zeros(e.qd.shape[0]))


def common_subexpressions(expression, n_segments: int):
    """``expression`` with its common subexpressions eliminated where the segments'
    Functions are inlined (:func:`~softcurve.symbolic.kinematics.inline_calls`), as it
    is otherwise.

    Around calls there is little to share (the called Functions eliminate their own),
    and CasADi's ``cse`` of an expression holding calls is slow: at ten segments 0.13 s
    for 2 % fewer operations of the forward dynamics, 12 s for 9 % fewer of the
    Christoffel matrix (45 s at twenty; ``python benchmarks/bench_chain.py --cse``).

    Parameters
    ----------
    expression : casadi.SX
        Any expression of a model's symbols.
    n_segments : int
        The model's number of segments N.
    """
    return ca.cse(expression) if inline_calls(n_segments) else expression


def build_functions(spec: dict, p, n_segments: int) -> dict[str, ca.Function]:
    """One SX Function per entry of ``spec``, ``p`` appended to its inputs, each output
    through :func:`common_subexpressions`.

    Parameters
    ----------
    spec : dict
        Name -> ``(inputs, input names, outputs, output names)``.
    p : casadi.SX
        The parameter vector, the last input of every Function.
    n_segments : int
        The model's number of segments N.
    """
    functions = {}
    for name, (inputs, in_names, outputs, out_names) in spec.items():
        outputs = [common_subexpressions(o, n_segments) for o in outputs]
        functions[name] = ca.Function(name, [*inputs, p], outputs, [*in_names, "p"], out_names)
    return functions


def domain_expression(structure: tuple, q, p):
    """1 where the configuration ``q`` lies in every element's domain, else 0 (NaN: 0):
    each element's :meth:`~softcurve.description.elements.ElementModel.domain_margins`,
    the rule its Python side evaluates too, with its own parameters read from ``p`` (a
    batch's members each check their own rest lengths).

    Parameters
    ----------
    structure : tuple
        ``Robot.structure()``.
    q : casadi.SX, shape (n,)
        The coordinates.
    p : casadi.SX, shape (n_p,)
        The parameter vector.
    """
    inside = margins_hold(domain_margins(structure, q, p))
    return ca.SX(1.0) if inside is True else inside


def domain_margins(structure: tuple, q, p) -> list:
    """Every element's :meth:`~softcurve.description.elements.ElementModel.domain_margins`
    at ``q``, in the chain's order: inside the model's domain where all hold.

    Parameters
    ----------
    structure : tuple
        ``Robot.structure()``.
    q : casadi.SX or casadi.MX, shape (n,)
        The coordinates.
    p : casadi.SX or casadi.MX, shape (n_p,)
        The parameter vector.

    Returns
    -------
    list of Margin
    """
    parts = ParameterLayout.of_structure(structure).element_parts(p)
    margins = []
    for signature, part, k in zip(structure, parts, coordinate_slices(structure), strict=True):
        margins.extend(element_model(signature).domain_margins(q[k], part))
    return margins


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
    elements = kinematic_chain(e.structure, p)
    weights = ParameterLayout.of_structure(e.structure).split(p)["span_weights"]
    ends = ca.cumsum(weights) / ca.sum1(weights)
    bounds = [0, *(ends[i] for i in range(weights.shape[0] - 1)), 1]
    frame = point_at(q, elements, e.base_rotation, s, e.base_position, bounds)
    spec = {
        "dynamics_terms": dynamics_terms_spec(e),
        "mass_matrix": ([q], ["q"], [configuration_only(e, e.mass_matrix)], ["D"]),
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
        "jacobian": ([q, s], ["q", "s"], [frame.jacobian], ["J"]),
        "domain": ([q], ["q"], [domain_expression(e.structure, q, p)], ["inside"]),
    }
    return build_functions(spec, p, e.n_segments)
