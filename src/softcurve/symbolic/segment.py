"""What one element contributes to the dynamics of the chain, written once as CasADi
Functions of the element's own coordinates, for every element kind.

An element (a segment of coordinates ``q_i``, e.g. ``(l, kx, ky)``, or a rigid body of
none; :mod:`softcurve.description.elements`) is a body between two frames:
its base frame ``i`` and its tip frame ``i + 1`` (the next segment's base). Its
quadrature slices (``DEFAULT_QUADRATURE_NODES`` of :mod:`softcurve.symbolic.dynamics`,
Gauss-Legendre nodes in the material coordinate) move with the base frame and with
``q_i``, and everything downstream moves rigidly with its tip frame. The chain
algorithms (:mod:`softcurve.symbolic.chain`) need of each segment only the linear maps
between these quantities, all in the coordinates of the frame they belong to:

- accelerations ``A = (alpha, a)`` of a frame: angular acceleration and acceleration of
  its origin (classical, not spatial: the velocity terms are in the biases);
- wrenches ``W = (moment about the origin, force)``;
- the tip frame's acceleration ``A_tip = X A + S qdd_i + c``;
- the wrench the base must exert on the segment and all it carries,
  ``W = M A + H qdd_i + X^T W_tip + w``;
- the segment's generalized force ``tau_i = H^T A + D_i qdd_i + S^T W_tip + b``.

``X`` (6x6) is the rigid transform from the base to the tip frame, ``S`` (6 x n_i) the
tip's acceleration per unit ``qdd_i``, ``M`` (6x6) the element's spatial inertia about
its base, ``H`` (6 x n_i) its momentum per unit ``qd_i``, ``D_i`` (n_i x n_i) its own
mass matrix; the
biases ``c``, ``w``, ``b`` hold the velocity terms and depend on ``qd_i`` and on the base
frame's angular velocity. They are derived from one Newton-Euler pass over the slices,
each slice's share its relations' exact derivatives and their values at rest, so that
the chain's mass matrix, Coriolis terms and forward dynamics are one algebra.

Each quantity is an SX Function (:func:`segment_functions`), called once per element,
which calls one Function per slice: the generated code holds one copy of an element
kind's work and of a slice's however many elements and slices. A robot of one structure
calls the same Functions with each element's numbers (its model's ``geometry``: mass,
radius, rest strains ...).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca

from softcurve.description.elements import ElementModel


@dataclass(frozen=True)
class _Point:
    """A material point or rigid body of an element, in the element's base frame:
    rotation, position, their Jacobians w.r.t. the element's coordinates (linear
    ``dp/dq_i``; angular in the point's own frame), its mass and rotational inertia (3x3,
    its own frame)."""

    rotation: ca.SX
    position: ca.SX
    linear: ca.SX
    angular: ca.SX
    mass: ca.SX
    inertia: ca.SX


def _point(model: ElementModel, q_i, g, s, mass=0.0, inertia=None, tip=False) -> _Point:
    rotation, position = model.tip_pose(q_i, g) if tip else model.point_pose(q_i, s, g)
    inertia = ca.SX.zeros(3, 3) if inertia is None else inertia
    return _Point(
        rotation,
        position,
        ca.jacobian(position, q_i),
        model.angular_jacobian(q_i, s, g),
        mass,
        inertia,
    )


def _fixed(q_i, body) -> _Point:
    zero = ca.SX(3, q_i.shape[0])
    return _Point(ca.SX.eye(3), body.centre, zero, zero, body.mass, body.inertia)


def _velocity_bias(point, q_i, qd_i):
    """``(d/dt J) qd`` and ``(d/dt A) qd`` at fixed ``qd``: the point's relative
    acceleration and angular acceleration when ``qdd = 0``.

    Computed as derivatives along the line ``q + t qd`` in the scalar ``t`` (second
    derivative of the position, first of ``A qd``): one derivative direction instead of
    the three of ``jtimes(J qd, q, qd)``, which differentiates the Jacobian itself. On the
    paper's robot this cuts the compiled right-hand side by a third; both forms agree to
    round-off (``tests/test_dynamics.py`` checks the dynamics against energy and
    finite-difference identities).
    """
    t = ca.SX.sym("t")
    line = q_i + t * qd_i
    position = ca.substitute(point.position, q_i, line)
    linear_bias = ca.substitute(ca.jacobian(ca.jacobian(position, t), t), t, 0)
    relative_omega = ca.substitute(point.angular @ qd_i, q_i, line)
    angular_bias = ca.substitute(ca.jacobian(relative_omega, t), t, 0)
    return linear_bias, angular_bias


def _point_motion(point, q_i, qd_i, qdd_i, omega, alpha, accel):
    """Acceleration of a material point (segment-frame coordinates), and the angular
    velocity and acceleration of its slice (slice coordinates), given the segment frame's
    angular velocity ``omega``, angular acceleration ``alpha`` and origin acceleration
    ``accel`` (segment-frame coordinates)."""
    rate = point.linear @ qd_i  # velocity relative to the segment frame
    relative_omega = point.angular @ qd_i
    linear_bias, angular_bias = _velocity_bias(point, q_i, qd_i)
    r = point.position
    linear_accel = (
        accel
        + ca.cross(alpha, r)
        + ca.cross(omega, ca.cross(omega, r))
        + 2 * ca.cross(omega, rate)
        + point.linear @ qdd_i
        + linear_bias
    )
    frame_omega = point.rotation.T @ omega
    body_omega = frame_omega + relative_omega
    body_alpha = (
        point.rotation.T @ alpha
        - ca.cross(relative_omega, frame_omega)
        + point.angular @ qdd_i
        + angular_bias
    )
    return linear_accel, body_omega, body_alpha


def _point_wrench(point, q_i, qd_i, qdd_i, omega, acceleration):
    """A point's share of the Newton-Euler relations: its generalized force (n_i,) and
    the wrench (6,) the base exerts on it (moment about the base's origin, force; base
    coordinates), given the base frame's angular velocity and acceleration ``A``."""
    linear_accel, body_omega, body_alpha = _point_motion(
        point, q_i, qd_i, qdd_i, omega, acceleration[:3], acceleration[3:]
    )
    force = point.mass * linear_accel
    moment = point.inertia @ body_alpha + ca.cross(body_omega, point.inertia @ body_omega)
    generalized = point.linear.T @ force + point.angular.T @ moment
    wrench = ca.vertcat(ca.cross(point.position, force) + point.rotation @ moment, force)
    return generalized, wrench


def _rotational_inertia(point):
    """A point's rotational inertia about the element's base, base coordinates,
    ``R I R^T + m (|r|^2 1 - r r^T)``: its lower triangle."""
    r, rotation = point.position, point.rotation
    shift = point.mass * (ca.dot(r, r) * ca.SX.eye(3) - r @ r.T)
    return ca.tril(rotation @ point.inertia @ rotation.T + shift)


def _spatial_inertia(rotational, moment, mass):
    """``M`` of ``W = M A`` at rest from the rotational inertia ``J`` about the base's
    origin (its lower triangle), the first moment ``h`` and the mass:
    ``[[J, h^], [-h^, m 1]]`` (the derivative of the wrench by ``A``, written out)."""
    skew = ca.SX(3, 3)  # not ca.skew, which stores its zero diagonal as entries of M
    for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):  # h^ a = h x a
        skew[i, j], skew[j, i] = -moment[k], moment[k]
    return ca.blockcat([[ca.tril2symm(rotational), skew], [-skew, mass * ca.SX.eye(3)]])


@dataclass(frozen=True)
class _Symbols:
    """The symbols of one element's terms: coordinates, rates and accelerations
    (n_i,), the base frame's angular velocity (3,) and acceleration ``A`` (6,), the
    element's numbers (n_g,)."""

    q: ca.SX
    qd: ca.SX
    qdd: ca.SX
    omega: ca.SX
    acceleration: ca.SX
    geometry: ca.SX

    def at_rest(self, expression):
        """``expression`` at ``qdd = 0``, ``A = 0``."""
        accelerations = ca.vertcat(self.qdd, self.acceleration)
        return ca.substitute(expression, accelerations, ca.SX.zeros(accelerations.shape[0]))


def _symbols(model: ElementModel) -> _Symbols:
    q, qd, qdd = (ca.SX.sym(name, model.nq) for name in ("q", "qd", "qdd"))
    return _Symbols(
        q, qd, qdd, ca.SX.sym("omega", 3), ca.SX.sym("A", 6),
        ca.SX.sym("g", model.geometry_size()),
    )  # fmt: skip


def _point_terms(point, x: _Symbols, triangle: bool) -> list:
    """A point's share of ``(J, h, H, D_i, w, b)``: its rotational inertia about the base
    and first moment (which make its share of ``M``), and the derivatives of its
    relations (linear in ``qdd`` and ``A``) and their values at rest; the symmetric
    ``J`` by its lower triangle, ``D_i`` too where ``triangle``."""
    generalized, wrench = _point_wrench(point, x.q, x.qd, x.qdd, x.omega, x.acceleration)
    own = ca.jacobian(generalized, x.qdd)
    return [
        _rotational_inertia(point),
        point.mass * point.position,
        ca.jacobian(wrench, x.qdd),
        ca.tril(own) if triangle else own,
        x.at_rest(wrench),
        x.at_rest(generalized),
    ]


def _with_derivative(shares, x: _Symbols) -> list:
    """``shares`` and, last, their derivatives stacked column by column (``vec``) by the
    local variables ``(q_i, qd_i, omega)``."""
    wrt = ca.vertcat(x.q, x.qd, x.omega)
    return [*shares, ca.jacobian(ca.vertcat(*map(ca.vec, shares)), wrt)]


def _slice_function(
    model: ElementModel,
    pattern: ca.Sparsity,
    options: dict,
    name: str,
    triangle: bool,
    local: bool = False,
):
    """``(q_i, qd_i, omega, g, s, m, I) -> (J_k, h_k, H_k, D_k, w_k, b_k)``, a slice's share
    at material coordinate ``s`` of mass ``m`` and rotational inertia ``I`` (of sparsity
    ``pattern``); ``J_k``, and ``D_k`` where ``triangle``, by their lower triangles. One
    Function called per slice, not a segment's slices written out: a ten-segment
    robot of six strains then compiles with a third fewer compiler CPU seconds
    (``benchmarks/bench_chain.py``, with the articulated step's factor). Inlined (a
    robot of one segment), it costs what the slices written out cost.

    With ``local``, a last output ``dS``: the derivatives of the shares, stacked column by
    column (``vec``), by ``(q_i, qd_i, omega)``, written out here where the share is (a
    forward derivative of the call would take one pass per direction)."""
    x = _symbols(model)
    s, mass, inertia = ca.SX.sym("s"), ca.SX.sym("m"), ca.SX.sym("I", pattern)
    point = _point(model, x.q, x.geometry, s, mass, inertia)
    shares, names = _point_terms(point, x, triangle), ["J", "h", "H", "D", "w", "b"]
    if local:
        shares, names = _with_derivative(shares, x), [*names, "dS"]
    return ca.Function(
        f"{name}_slice_local" if local else f"{name}_slice",
        [x.q, x.qd, x.omega, x.geometry, s, mass, inertia],
        shares,
        ["q", "qd", "omega", "g", "s", "m", "I"],
        names,
        options,
    )


@dataclass(frozen=True)
class SegmentFunctions:
    """One segment's terms as CasADi Functions (see the module's docstring for the
    symbols).

    Parameters
    ----------
    frame : casadi.Function
        ``(q_i, g) -> (R_tip (3, 3), r_tip (3,), moment (3,), mass)``: the tip frame's
        pose [m] and the first moment of mass [kg m] in the base frame, and the mass [kg].
    motion : casadi.Function
        ``(q_i, qd_i, omega, g) -> (X, S, M, H, D_i, omega_tip, c, w, b)``:
        the configuration's linear maps and the velocity terms. One Function for both:
        the maps and the velocity terms share the slices' poses and Jacobians, and a
        library holding a second Function of the maps alone compiles for as long again
        (the maps of a configuration alone are ``motion`` at ``qd_i = 0``).
    make_local : callable
        ``make_local() -> Function``, :meth:`local`'s builder.
    """

    frame: ca.Function
    motion: ca.Function
    make_local: Callable[[], ca.Function]

    def local(self) -> ca.Function:
        """``(q_i, qd_i, omega, g) -> (the outputs of motion..., L)``: the terms and ``L``,
        the derivatives of their nonzeros (column by column of each output) by
        ``(q_i, qd_i, omega)``, shape (nnz, 2 n_i + 3): each slice's share differentiated
        where it is written (one call per slice, as ``motion``'s), then carried through
        the sums. Built on first use (for the exact Jacobian,
        :mod:`softcurve.symbolic.derivatives`)."""
        return self.make_local()


INERTIA_OUTPUTS = ("X", "S", "M", "H", "D")
"""Names of the linear maps of a segment, the first outputs of
``SegmentFunctions.motion``."""

BIAS_OUTPUTS = ("omega_tip", "c", "w", "b")
"""Names of the velocity terms, the last outputs of ``SegmentFunctions.motion``."""

TERM_NAMES = (*INERTIA_OUTPUTS, *BIAS_OUTPUTS)
"""Names of all the outputs of ``SegmentFunctions.motion``, in order."""


def nonzeros(parts) -> ca.SX:
    """The nonzeros of the matrices ``parts`` in one column, matrix by matrix, each column
    by column (the order of ``SegmentFunctions.local``'s ``L``).

    Parameters
    ----------
    parts : sequence of casadi.SX
        The matrices.
    """
    columns = [part.nz[:] for part in parts if part.nnz()]
    return ca.vertcat(*columns) if columns else ca.SX(0, 1)


def _assembled(x: _Symbols, tip, totals, mass, triangle: bool) -> list:
    """The outputs of ``motion`` from the tip's motion and the bodies' summed shares
    ``totals = (J, h, H, D_i, w, b)``."""
    tip_accel, tip_omega, tip_alpha = _point_motion(
        tip, x.q, x.qd, x.qdd, x.omega, x.acceleration[:3], x.acceleration[3:]
    )
    tip_acceleration = ca.vertcat(tip_alpha, tip.rotation.T @ tip_accel)
    rotational, first_moment, momentum, own, wrench_bias, force_bias = totals
    spatial = _spatial_inertia(rotational, first_moment, mass)
    own = ca.tril2symm(own) if triangle else 0.5 * (own + own.T)  # the latter: round-off
    return [
        ca.jacobian(tip_acceleration, x.acceleration),
        ca.jacobian(tip_acceleration, x.qdd),
        spatial,
        momentum,
        own,
        tip_omega,
        x.at_rest(tip_acceleration),
        wrench_bias,
        force_bias,
    ]


def segment_functions(
    model: ElementModel, quadrature_nodes: int, inline: bool = False, name: str = "segment"
) -> SegmentFunctions:
    """The Functions of an element kind (segments of ``quadrature_nodes`` slices).

    The tip's motion gives ``X``, ``S``, ``c`` and ``omega_tip`` (its acceleration's
    derivatives by ``A`` and ``qdd_i``, and its value at rest); each slice (or the rigid
    body) its share of ``M``, ``H``, ``D_i``, ``w`` and ``b``, summed: what the tip
    carries enters the chain through ``X`` and ``S`` alone.

    Parameters
    ----------
    model : ElementModel
        The element kind's model.
    quadrature_nodes : int
        Gauss-Legendre nodes along the segment.
    name : str
        The Functions' prefix, unique per kind within a model (generated C names them).
    inline : bool
        Whether the Functions are inlined where they are called (False: they stay calls,
        so generated code and derivatives hold one copy per Function). Inlined, a model's
        Functions count every operation in ``n_instructions()``.

    Notes
    -----
    Built anew for each model: CasADi keeps the derivatives it makes of a Function, and
    a shared Function would make a model's generated code (and so its round-off) depend
    on what the process built before.
    """
    options = {"never_inline": not inline, "cse": True}
    # D_i's upper triangle is the transpose of its lower one; called per segment, the
    # lower alone takes 4 % off a ten-segment chain's time, while in the one expression
    # of an inlined segment GCC's schedule of it ran a six-strain segment 21 % slower
    # than the full product (the C loops of benchmarks/bench_chain.py timed in turns)
    triangle = not inline
    x = _symbols(model)
    tip = _point(model, x.q, x.geometry, 1.0, tip=True)
    bodies = model.bodies(x.geometry, quadrature_nodes)
    slices = [body for body in bodies if body.s is not None]
    n = model.nq
    empty = [ca.SX(3, 3), ca.SX(3, 1), ca.SX(6, n), ca.SX(n, n), ca.SX(6, 1), ca.SX(n, 1)]
    pattern = None
    if slices:
        pattern = slices[0].inertia.sparsity()
        # a call projects an argument onto the input's sparsity without a word
        if any(body.inertia.sparsity() != pattern for body in slices):
            raise ValueError(f"the slices of {name} must share one sparsity of inertia")
        slice_terms = _slice_function(model, pattern, options, name, triangle)
    terms, moment, mass = list(empty), ca.SX.zeros(3), 0  # for frame, which takes (q, g)
    for body in bodies:
        if body.s is None:
            position, shares = body.centre, _point_terms(_fixed(x.q, body), x, triangle)
        else:
            _, position = model.point_pose(x.q, body.s, x.geometry)
            shares = slice_terms(x.q, x.qd, x.omega, x.geometry, body.s, body.mass, body.inertia)
        terms = [total + share for total, share in zip(terms, shares, strict=True)]
        moment += body.mass * position
        mass += body.mass
    inputs, input_names = [x.q, x.qd, x.omega, x.geometry], ["q", "qd", "omega", "g"]
    outputs = _assembled(x, tip, terms, mass, triangle)

    def make_local() -> ca.Function:
        # each share's derivative where the share is written, summed; the tip's and the
        # assembly's by the chain rule through the sums
        wrt = ca.vertcat(x.q, x.qd, x.omega)
        shared_derivative = ca.SX(sum(t.numel() for t in empty), wrt.shape[0])
        totals = list(empty)
        if slices:
            local_slice = _slice_function(model, pattern, options, name, triangle, local=True)
        for body in bodies:
            if body.s is None:
                *shares, shares_derivative = _with_derivative(
                    _point_terms(_fixed(x.q, body), x, triangle), x
                )
            else:
                *shares, shares_derivative = local_slice(
                    x.q, x.qd, x.omega, x.geometry, body.s, body.mass, body.inertia
                )
            totals = [total + share for total, share in zip(totals, shares, strict=True)]
            shared_derivative += shares_derivative
        # the shares' derivatives are by entries (vec); the sums are read by nonzeros
        rows, offset = [], 0
        for total in totals:
            rows += [offset + i for i in total.sparsity().find()]
            offset += total.numel()
        sums = [ca.SX.sym(f"total{k}", t.sparsity()) for k, t in enumerate(totals)]
        assembled = [
            ca.project(a, o.sparsity())
            for a, o in zip(_assembled(x, tip, sums, mass, triangle), outputs, strict=True)
        ]
        through_sums = ca.jacobian(nonzeros(assembled), nonzeros(sums))
        local = ca.jacobian(nonzeros(assembled), wrt) + through_sums @ shared_derivative[rows, :]
        values = ca.substitute([*assembled, local], [nonzeros(sums)], [nonzeros(totals)])
        return ca.Function(
            f"{name}_local", inputs, values, input_names,
            [*TERM_NAMES, "L"], options,
        )  # fmt: skip

    return SegmentFunctions(
        frame=ca.Function(
            f"{name}_frame",
            [x.q, x.geometry],
            [tip.rotation, tip.position, moment, mass],
            ["q", "g"],
            ["R_tip", "r_tip", "moment", "mass"],
            options,
        ),
        motion=ca.Function(
            f"{name}_motion",
            inputs,
            outputs,
            input_names,
            list(TERM_NAMES),
            options,
        ),
        make_local=functools.cache(make_local),
    )
