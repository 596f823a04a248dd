"""Actuator elements as offset fibers of the constant-curvature arcs, and their domain.

A tendon or a bellow at distance ``rho`` and azimuth ``phi`` (from +x toward +y in the
segment's cross-section) runs through a segment as an offset fiber of its arc, of
length ``L = l (1 - rho (kx cos phi + ky sin phi))`` (exact for constant curvature, a
polynomial in ``q``). :func:`offset_fiber_length` and :func:`offset_fiber_gradient` give
it symbolically (CasADi), :func:`fiber_lengths` numerically.

The domain: ``L`` must stay > 0 in every segment (a tendon or a chamber of length <= 0,
a chamber of volume ``A L <= 0``, is no geometry: the fiber has crossed the centre of
curvature, ``rho kappa_phi >= 1``): :func:`fibers_inside`, :func:`fiber_problem`.

A routing is inside the body when ``rho <= r``, ``r`` the ``radius`` of
the :class:`~softcurve.description.robot.Segment` (the radius of the body's
cross-section, which also gives its rotary inertia and its drawn and contact radius):
a tendon may run on the surface, not beyond it, and a chamber lies in the body.
:func:`routing_problem` refuses the rest.
"""

from __future__ import annotations

from typing import NamedTuple

import casadi as ca
import numpy as np

from softcurve.base.docs import parameters_from


def _offset_length(length, kx, ky, azimuth, distance, xp):
    """``l (1 - rho (kx cos phi + ky sin phi))`` with the ``cos`` and ``sin`` of the array
    module ``xp`` (``numpy`` or ``casadi``): the one statement of the offset fiber's length."""
    return length * (1 - distance * (kx * xp.cos(azimuth) + ky * xp.sin(azimuth)))


def offset_fiber_length(q, segment: int, azimuth, distance):
    """Length [m] of the fiber at ``distance`` ``rho`` and ``azimuth`` ``phi`` from the
    backbone of one constant-curvature segment: ``l (1 - rho (kx cos phi + ky sin phi))``
    (CasADi; exact, and a polynomial in ``q``).

    Parameters
    ----------
    q : casadi.SX or casadi.MX, shape (n,)
        Generalized coordinates [m, 1/m, 1/m].
    segment : int
        Index ``j`` of the segment (coordinates ``q[3j : 3j + 3]``).
    azimuth : float or casadi.SX or casadi.MX
        ``phi`` [rad], from +x toward +y in the segment's cross-section.
    distance : float or casadi.SX or casadi.MX
        ``rho`` [m].
    """
    length, kx, ky = q[3 * segment], q[3 * segment + 1], q[3 * segment + 2]
    return _offset_length(length, kx, ky, azimuth, distance, ca)


def offset_fiber_gradient(q, segment: int, azimuth, distance) -> list:
    """``dL/dq`` of :func:`offset_fiber_length` as a list of n CasADi entries, in closed
    form (``1 - rho k_phi``, ``-l rho cos phi``, ``-l rho sin phi`` at the segment's
    coordinates, zero elsewhere), so ``q`` may be any expression, not only a symbol.

    Parameters
    ----------
    q : casadi.SX or casadi.MX, shape (n,)
        Generalized coordinates [m, 1/m, 1/m].
    segment : int
        Index ``j`` of the segment.
    azimuth : float or casadi.SX or casadi.MX
        ``phi`` [rad].
    distance : float or casadi.SX or casadi.MX
        ``rho`` [m].
    """
    gradient = [0] * q.shape[0]
    length, kx, ky = q[3 * segment], q[3 * segment + 1], q[3 * segment + 2]
    c, s = ca.cos(azimuth), ca.sin(azimuth)
    gradient[3 * segment] = 1 - distance * (kx * c + ky * s)
    gradient[3 * segment + 1] = -length * distance * c
    gradient[3 * segment + 2] = -length * distance * s
    return gradient


class Fiber(NamedTuple):
    """One actuator element's piece in one segment: an offset fiber of its arc.

    Attributes
    ----------
    part : str
        The element, as its field names it (``"tendons[1]"``, ``"bellows[0]"``).
    kind : str
        ``"tendon"`` (checked by length) or ``"chamber"`` (checked by volume).
    segment : int
        Index of the segment.
    azimuth : float
        ``phi`` [rad].
    distance : float
        ``rho`` [m].
    area : float or None
        Chamber cross-section [m^2]; None for a tendon.
    """

    part: str
    kind: str
    segment: int
    azimuth: float
    distance: float
    area: float | None = None


_fiber_parameters = parameters_from(
    {
        "fibers": ("sequence of Fiber", "The pieces."),
        "q": ("array_like, shape (..., n)", "Configurations [m, 1/m, 1/m]."),
    }
)


@_fiber_parameters
def fiber_lengths(fibers, q) -> np.ndarray:
    """Lengths [m] of the fibers' pieces, shape (..., len(fibers)).

    Parameters
    ----------
    %(fibers)s
    %(q)s
    """
    q = np.asarray(q, dtype=np.float64)
    if not fibers:
        return np.zeros((*q.shape[:-1], 0))
    j = np.array([3 * f.segment for f in fibers])
    phi = np.array([f.azimuth for f in fibers])
    rho = np.array([f.distance for f in fibers])
    with np.errstate(invalid="ignore", over="ignore"):
        return _offset_length(q[..., j], q[..., j + 1], q[..., j + 2], phi, rho, np)


@_fiber_parameters
def fibers_inside(fibers, q) -> np.ndarray:
    """Whether every piece has positive length (NaN fails), shape (...).

    Parameters
    ----------
    %(fibers)s
    %(q)s
    """
    return np.all(fiber_lengths(fibers, q) > 0, axis=-1)


@_fiber_parameters
def fiber_problem(fibers, q) -> str | None:
    """What puts ``q`` (n,) outside the fibers' domain, naming the element, the segment,
    the value and the allowed range; None inside.

    Parameters
    ----------
    %(fibers)s
    q : array_like, shape (n,)
        One configuration [m, 1/m, 1/m].
    """
    lengths = fiber_lengths(fibers, q)
    for fiber, length in zip(fibers, lengths.tolist(), strict=True):
        if length > 0:
            continue
        where = f"{fiber.part} in segment {fiber.segment + 1}"
        if fiber.kind == "chamber":
            what = f"{where}: chamber volume {fiber.area * length:.6g} m^3"
        else:
            what = f"{where}: tendon length {length:.6g} m"
        return (
            f"{what}; allowed > 0 (its distance rho = {fiber.distance:g} m times the "
            f"curvature toward it must stay < 1, i.e. the curvature < {1 / fiber.distance:.6g} "
            "1/m)"
        )
    return None


@_fiber_parameters
def routing_problem(fibers, robot) -> str | None:
    """What of the routing lies outside the body (``rho > r`` of a segment it runs
    through), naming the field, its value and the allowed range; None if all inside.

    Parameters
    ----------
    %(fibers)s
    robot : Robot
        Supplies each segment's radius ``r`` [m].
    """
    for fiber in fibers:
        radius = robot.segments[fiber.segment].radius
        if fiber.distance > radius:
            return (
                f"{fiber.part}.distance = {fiber.distance:g} m routes it outside the body: "
                f"segment {fiber.segment + 1} has radius {radius:g} m (Segment.radius); "
                f"allowed 0 < distance <= {radius:g} m. Route it inside the cross-section, "
                "or give the segment its real radius"
            )
    return None
