"""Actuator elements as offset fibers of the robot's elements, and their domain.

A tendon or a bellow at distance ``rho`` and azimuth ``phi`` (from +x toward +y in each
element's base frame) runs through an element as the material fiber at the body-frame
offset ``r = rho (cos phi, sin phi, 0)`` from the backbone. Its length per element kind:

- **constant strain** (:class:`~softcurve.StrainSegment`, strain twist ``xi = (u, v)``):
  the fiber's material tangent ``t = v + u x r`` is constant along the segment (``d/dX
  (p + R r) = R (v + u x r)``), so its length is exactly ``L = L0 |v + u x r|``. With
  twist the fiber is a helix around the backbone, with shear it leans; the formula
  covers both;
- **constant curvature** (:class:`~softcurve.Segment`, ``(l, kx, ky)``): the same with
  ``u = sigma (-ky, kx, 0)``, ``v = (0, 0, sigma)``, ``sigma = l / L0``, i.e.
  ``L = l (1 - rho (kx cos phi + ky sin phi))``, a polynomial in ``q``;
- **rigid body** (:class:`~softcurve.RigidBody`): the fiber runs straight from the hole at
  the body's base (``r``) to the hole at its tip (``tip_position + tip_rotation r``, the
  next element's ``r``): ``L = |tip_position + tip_rotation r - r|``, a constant, so a
  tendon passes a rigid link between soft sections (or ends at a gripper) and does no
  work on it. A chamber holds no gas in a rigid body: bellows run through soft segments
  only.

:func:`offset_fiber_length` and :func:`offset_fiber_gradient` give the length and
``dL/dq`` symbolically (CasADi), :func:`offset_fiber_turn` the angle the fiber turns
through (the capstan law's), :func:`fiber_lengths` the lengths numerically.

The domain: in every soft element the fiber must run forward along the sections'
normal, ``L0 (v + u x r)_z > 0`` (for constant curvature this is the length ``l (1 -
rho kappa_phi) > 0``: the fiber has not crossed the centre of curvature); at ``<= 0``
the material at the fiber is folded through its section, and a tendon of length
``<= 0``, a chamber of volume ``A L <= 0``, is no geometry. :func:`fibers_inside`,
:func:`fiber_problem`.

A routing is inside the body when ``rho <= r``, ``r`` the ``radius`` of each element it
runs through (the radius of the body's cross-section, which also gives a segment's
rotary inertia and every element's drawn and contact radius): a tendon may run on the
surface, not beyond it, and a chamber lies in the body. :func:`routing_problem` refuses
the rest.
"""

from __future__ import annotations

from typing import NamedTuple

import casadi as ca
import numpy as np

from softcurve.base.docs import parameters_from
from softcurve.description.elements import RigidBody, Segment, StrainSegment


def _offset_length(length, kx, ky, azimuth, distance, xp):
    """``l (1 - rho (kx cos phi + ky sin phi))`` with the ``cos`` and ``sin`` of the array
    module ``xp`` (``numpy`` or ``casadi``): the one statement of the offset fiber's length
    in a constant-curvature segment."""
    return length * (1 - distance * (kx * xp.cos(azimuth) + ky * xp.sin(azimuth)))


def _strain(element: StrainSegment, coordinates) -> list:
    """The full strain ``(ux, uy, uz, vx, vy, vz)`` of a constant-strain segment: its
    ``coordinates`` (a sequence of scalars, CasADi entries or arrays) at the chosen
    strains, the element's rest strains elsewhere."""
    entries = [float(x) for x in element.rest_strain]
    for i, k in enumerate(element.indices):
        entries[k] = coordinates[i]
    return entries


def _tangent(xi, azimuth, distance, xp) -> list:
    """The fiber's body-frame material tangent ``v + u x r`` (3 entries), ``r = rho (cos
    phi, sin phi, 0)``: the one statement of the offset fiber in a constant-strain
    segment."""
    ux, uy, uz, vx, vy, vz = xi
    rx, ry = distance * xp.cos(azimuth), distance * xp.sin(azimuth)
    return [vx - uz * ry, vy + uz * rx, vz + ux * ry - uy * rx]


def _rigid_length(element: RigidBody, azimuth, distance, xp):
    """``|tip_position + (tip_rotation - I) r|`` [m]: a straight fiber through a rigid body."""
    r = [distance * xp.cos(azimuth), distance * xp.sin(azimuth), 0]
    chord = [
        element.tip_position[a]
        + sum((element.tip_rotation[a, b] - (a == b)) * r[b] for b in (0, 1))
        for a in range(3)
    ]
    return xp.sqrt(sum(c * c for c in chord))


def _place(q, segment: int, element, offset):
    """The element (None: a constant-curvature segment) and its coordinates in ``q``."""
    start = 3 * segment if offset is None else offset
    size = 3 if element is None else element.n_coordinates
    return [q[start + k] for k in range(size)], start


_symbolic_parameters = parameters_from(
    {
        "q": ("casadi.SX or casadi.MX, shape (n,)", "Generalized coordinates."),
        "segment": ("int", "Index ``j`` of the element in the chain."),
        "azimuth": ("float or casadi.SX or casadi.MX", "``phi`` [rad], from +x toward +y."),
        "distance": ("float or casadi.SX or casadi.MX", "``rho`` [m]."),
        "element": (
            "Segment, StrainSegment or RigidBody, optional",
            "The element (None: a constant-curvature segment).",
        ),
        "offset": (
            "int, optional",
            "Index of the element's first coordinate in ``q`` (default ``3 segment``, the "
            "stride of a robot of constant-curvature segments).",
        ),
    }
)


@_symbolic_parameters
def offset_fiber_length(q, segment: int, azimuth, distance, element=None, offset=None):
    """Length [m] of the fiber at ``distance`` ``rho`` and ``azimuth`` ``phi`` from the
    backbone in one element (CasADi; exact for every kind, module docstring).

    Parameters
    ----------
    %(q)s
    %(segment)s
    %(azimuth)s
    %(distance)s
    %(element)s
    %(offset)s
    """
    coordinates, _ = _place(q, segment, element, offset)
    if element is None or isinstance(element, Segment):
        return _offset_length(*coordinates, azimuth, distance, ca)
    if isinstance(element, RigidBody):
        return _rigid_length(element, azimuth, distance, ca)
    t = _tangent(_strain(element, coordinates), azimuth, distance, ca)
    return element.rest_length * ca.sqrt(sum(x * x for x in t))


@_symbolic_parameters
def offset_fiber_gradient(q, segment: int, azimuth, distance, element=None, offset=None) -> list:
    """``dL/dq`` of :func:`offset_fiber_length` as a list of n CasADi entries, in closed
    form, so ``q`` may be any expression, not only a symbol: for constant curvature
    ``1 - rho k_phi``, ``-l rho cos phi``, ``-l rho sin phi``; for constant strain ``L0
    (r x t, t)`` at the chosen strains, ``t`` the unit tangent (``dL/du = L0 r x t``,
    ``dL/dv = L0 t``); zero elsewhere (a rigid body's fiber is constant).

    Parameters
    ----------
    %(q)s
    %(segment)s
    %(azimuth)s
    %(distance)s
    %(element)s
    %(offset)s
    """
    gradient = [0] * q.shape[0]
    coordinates, start = _place(q, segment, element, offset)
    if element is None or isinstance(element, Segment):
        length, kx, ky = coordinates
        c, s = ca.cos(azimuth), ca.sin(azimuth)
        gradient[start] = 1 - distance * (kx * c + ky * s)
        gradient[start + 1] = -length * distance * c
        gradient[start + 2] = -length * distance * s
        return gradient
    if isinstance(element, RigidBody):
        return gradient
    t = _tangent(_strain(element, coordinates), azimuth, distance, ca)
    norm = ca.sqrt(sum(x * x for x in t))
    unit = [element.rest_length * x / norm for x in t]
    rx, ry = distance * ca.cos(azimuth), distance * ca.sin(azimuth)
    full = [ry * unit[2], -rx * unit[2], rx * unit[1] - ry * unit[0], *unit]  # (r x t, t)
    for i, k in enumerate(element.indices):
        gradient[start + i] = full[k]
    return gradient


@_symbolic_parameters
def offset_fiber_turn(q, segment: int, azimuth, distance, element=None, offset=None):
    """Squared angle [rad^2] the fiber turns through in one element (CasADi): the bending
    angle ``(l kappa)^2`` of a constant-curvature segment; ``L0^2 |u x t|^2 / |t|^2`` of a
    constant-strain segment (its world tangent ``R t`` turns at the rate ``|u x t| / |t|``
    per unit ``X``); zero in a rigid body (straight).

    Parameters
    ----------
    %(q)s
    %(segment)s
    %(azimuth)s
    %(distance)s
    %(element)s
    %(offset)s
    """
    coordinates, _ = _place(q, segment, element, offset)
    if element is None or isinstance(element, Segment):
        length, kx, ky = coordinates
        return length**2 * (kx**2 + ky**2)
    if isinstance(element, RigidBody):
        return 0.0
    xi = _strain(element, coordinates)
    t = ca.vertcat(*_tangent(xi, azimuth, distance, ca))
    turning = ca.cross(ca.vertcat(*xi[:3]), t)
    return element.rest_length**2 * ca.dot(turning, turning) / ca.dot(t, t)


class Fiber(NamedTuple):
    """One actuator element's piece in one element of the chain: an offset fiber.

    Attributes
    ----------
    part : str
        The actuator's element, as its field names it (``"tendons[1]"``, ``"bellows[0]"``).
    kind : str
        ``"tendon"`` (checked by length) or ``"chamber"`` (checked by volume).
    segment : int
        Index of the chain's element it runs through.
    azimuth : float
        ``phi`` [rad].
    distance : float
        ``rho`` [m].
    area : float or None
        Chamber cross-section [m^2]; None for a tendon.
    element : Segment, StrainSegment, RigidBody or None
        The element it runs through; None: a constant-curvature segment.
    offset : int or None
        Index of the element's first coordinate in ``q``; None: ``3 segment``.
    """

    part: str
    kind: str
    segment: int
    azimuth: float
    distance: float
    area: float | None = None
    element: Segment | StrainSegment | RigidBody | None = None
    offset: int | None = None


_fiber_parameters = parameters_from(
    {
        "fibers": ("sequence of Fiber", "The pieces."),
        "q": ("array_like, shape (..., n)", "Configurations."),
    }
)


def _extents(fiber: Fiber, q: np.ndarray):
    """The piece's length [m] and its extent along the sections' normal [m] (the domain's
    quantity; None in a rigid body), elementwise over ``q[..., n]``."""
    coordinates, _ = _place(np.moveaxis(q, -1, 0), fiber.segment, fiber.element, fiber.offset)
    element, phi, rho = fiber.element, fiber.azimuth, fiber.distance
    if element is None or isinstance(element, Segment):
        length = _offset_length(*coordinates, phi, rho, np)
        return length, length
    if isinstance(element, RigidBody):
        return np.broadcast_to(_rigid_length(element, phi, rho, np), q.shape[:-1]), None
    t = _tangent(_strain(element, coordinates), phi, rho, np)
    length = element.rest_length * np.sqrt(sum(x * x for x in t))
    return length, element.rest_length * t[2]


@_fiber_parameters
def fiber_lengths(fibers, q) -> np.ndarray:
    """Lengths [m] of the fibers' pieces, shape (..., len(fibers)).

    Parameters
    ----------
    %(fibers)s
    %(q)s
    """
    q = np.asarray(q, dtype=np.float64)
    with np.errstate(invalid="ignore", over="ignore"):
        lengths = [_extents(f, q)[0] for f in fibers]
    return np.stack(lengths, axis=-1) if lengths else np.zeros((*q.shape[:-1], 0))


@_fiber_parameters
def fibers_inside(fibers, q) -> np.ndarray:
    """Whether every piece runs forward along the sections' normal in its element (for
    constant curvature: has positive length; NaN fails), shape (...).

    Parameters
    ----------
    %(fibers)s
    %(q)s
    """
    q = np.asarray(q, dtype=np.float64)
    inside = np.ones(q.shape[:-1], dtype=bool)
    with np.errstate(invalid="ignore", over="ignore"):
        for fiber in fibers:
            extent = _extents(fiber, q)[1]
            if extent is not None:
                inside &= extent > 0
    return inside


@_fiber_parameters
def fiber_problem(fibers, q) -> str | None:
    """What puts ``q`` (n,) outside the fibers' domain, naming the element, the segment,
    the value and the allowed range; None inside.

    Parameters
    ----------
    %(fibers)s
    q : array_like, shape (n,)
        One configuration.
    """
    q = np.asarray(q, dtype=np.float64)
    for fiber in fibers:
        with np.errstate(invalid="ignore", over="ignore"):
            length, extent = _extents(fiber, q)
        if extent is None or extent > 0:
            continue
        where = f"{fiber.part} in segment {fiber.segment + 1}"
        if isinstance(fiber.element, StrainSegment):
            what = "chamber" if fiber.kind == "chamber" else "tendon"
            return (
                f"{where}: the {what}'s fiber runs {float(extent):.6g} m along the sections' "
                f"normal (L0 (v + u x r)_z, length {float(length):.6g} m); allowed > 0 (the "
                f"material at distance rho = {fiber.distance:g} m is folded through its "
                "section: the bending toward it, times rho, must stay below the stretch)"
            )
        if fiber.kind == "chamber":
            what = f"{where}: chamber volume {fiber.area * float(length):.6g} m^3"
        else:
            what = f"{where}: tendon length {float(length):.6g} m"
        return (
            f"{what}; allowed > 0 (its distance rho = {fiber.distance:g} m times the "
            f"curvature toward it must stay < 1, i.e. the curvature < {1 / fiber.distance:.6g} "
            "1/m)"
        )
    return None


@_fiber_parameters
def routing_problem(fibers, robot) -> str | None:
    """What of the routing lies outside the body (``rho > r`` of an element it runs
    through), naming the field, its value and the allowed range; None if all inside.

    Parameters
    ----------
    %(fibers)s
    robot : Robot
        Supplies each element's radius ``r`` [m].
    """
    for fiber in fibers:
        element = robot.segments[fiber.segment]
        radius = element.radius
        if fiber.distance > radius:
            kind = type(element).__name__
            return (
                f"{fiber.part}.distance = {fiber.distance:g} m routes it outside the body: "
                f"segment {fiber.segment + 1} has radius {radius:g} m ({kind}.radius); "
                f"allowed 0 < distance <= {radius:g} m. Route it inside the cross-section, "
                "or give the element its real radius"
            )
    return None
