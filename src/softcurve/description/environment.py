"""Rigid obstacles around the robot and the law of the contact with them (docs/contact.md).

Obstacles are fixed and given in the robot's base frame (origin at the base of the first
segment, z along the undeformed backbone; the world frame when ``Robot.base_rotation``
is the identity):

- :class:`Plane`: the half-space behind a plane, ``(x - point) . normal <= 0``;
- :class:`Sphere`: a ball;
- :class:`Capsule`: a segment ``a``-``b`` swept by a ball (a cylinder with round ends).

The body of segment ``i`` is its backbone swept by a ball of its contact radius (by
default its slice radius ``r``); the penetration at a backbone point is that radius
minus the point's distance to the obstacle. The :class:`ContactLaw` turns penetrations
into forces: a penalty per unit of backbone rest length, so that the force converges
as ``points_per_segment`` grows (docs/contact.md has the table). An
:class:`Environment` holds the obstacles, the law and the contact radii, and is given to
``softcurve.Model(robot, environment=...)``. Every number here is validated when the
object is built; nothing numeric happens here (the geometry is in
:mod:`softcurve.symbolic.contact`). Self-contact between segments is not modelled.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from softcurve.base.validation import ParameterError, real_array, real_scalar


def _point(name: str, value) -> np.ndarray:
    return real_array(name, value, (3,))


def _positive(name: str, value) -> float:
    return real_scalar(name, value, positive=True)


def unit_direction(name: str, vector: np.ndarray) -> tuple[np.ndarray, float]:
    """``vector`` normalized, and its length, for every obstacle that takes a direction.

    The vector is first divided by its largest component, so that its squares neither
    overflow (``[1e200, 1e200, 0]``) nor underflow (``[1e-200, 0, 0]``) on the way to
    the norm: only the zero vector and a non-finite one are refused.

    Parameters
    ----------
    name : str
        The field's name, for the message.
    vector : ndarray, shape (3,)
        The direction, any length [m or -].

    Returns
    -------
    unit : ndarray, shape (3,)
        Read-only, of length 1 [-].
    length : float
        ``|vector|`` (inf where it exceeds the largest float) [m or -].
    """
    largest = float(np.max(np.abs(vector)))
    if not np.isfinite(largest):
        raise ParameterError(f"{name} must be finite, got {vector.tolist()}")
    if not largest > 0:
        raise ParameterError(f"{name} must be a nonzero vector, got {vector.tolist()}")
    scaled = vector / largest  # largest component +-1: the norm is in [1, sqrt(3)]
    norm = float(np.linalg.norm(scaled))
    unit = scaled / norm
    unit.setflags(write=False)
    return unit, largest * norm


@dataclass(frozen=True, eq=False)
class Plane:
    """A half-space: every point ``x`` with ``(x - point) . normal <= 0`` is solid.

    Parameters
    ----------
    point : array_like, shape (3,)
        A point of the boundary plane [m], base frame.
    normal : array_like, shape (3,)
        Outward normal (pointing into free space), any nonzero length [-]; stored
        normalized.
    """

    point: np.ndarray
    normal: np.ndarray

    def __post_init__(self):
        set_ = object.__setattr__  # frozen dataclass: normalize fields once here
        set_(self, "point", _point("Plane.point", self.point))
        set_(self, "normal", unit_direction("Plane.normal", _point("Plane.normal", self.normal))[0])

    def key(self) -> tuple:
        """The obstacle as a tuple of plain numbers (part of the compiled model's cache key)."""
        return ("plane", *self.point.tolist(), *self.normal.tolist())


@dataclass(frozen=True, eq=False)
class Sphere:
    """A solid ball.

    Parameters
    ----------
    center : array_like, shape (3,)
        Its centre [m], base frame.
    radius : float
        Its radius [m], > 0.
    """

    center: np.ndarray
    radius: float

    def __post_init__(self):
        object.__setattr__(self, "center", _point("Sphere.center", self.center))
        object.__setattr__(self, "radius", _positive("Sphere.radius", self.radius))

    def key(self) -> tuple:
        """The obstacle as a tuple of plain numbers (part of the compiled model's cache key)."""
        return ("sphere", *self.center.tolist(), self.radius)


@dataclass(frozen=True, eq=False)
class Capsule:
    """A solid capsule: the segment from ``a`` to ``b`` swept by a ball of ``radius``.

    Parameters
    ----------
    a, b : array_like, shape (3,)
        End points of its axis [m], base frame; distinct (a point is a :class:`Sphere`).
    radius : float
        Its radius [m], > 0.

    Attributes
    ----------
    axis : ndarray, shape (3,)
        The unit vector from ``a`` to ``b`` [-].
    length : float
        ``|b - a|`` [m], > 0.
    """

    a: np.ndarray
    b: np.ndarray
    radius: float
    axis: np.ndarray = field(init=False, repr=False)
    length: float = field(init=False, repr=False)

    def __post_init__(self):
        set_ = object.__setattr__
        set_(self, "a", _point("Capsule.a", self.a))
        set_(self, "b", _point("Capsule.b", self.b))
        set_(self, "radius", _positive("Capsule.radius", self.radius))
        # with gradual underflow, b - a is zero only where b equals a
        if np.array_equal(self.a, self.b):
            raise ParameterError(
                f"Capsule.b must differ from Capsule.a (axis length > 0), got a = b = "
                f"{self.a.tolist()}; use a Sphere for a ball"
            )
        with np.errstate(over="ignore"):
            axis = self.b - self.a
        name = f"Capsule axis b - a (a = {self.a.tolist()}, b = {self.b.tolist()})"
        unit, length = unit_direction(name, axis)
        set_(self, "axis", unit)
        set_(self, "length", length)

    def key(self) -> tuple:
        """The obstacle as a tuple of plain numbers (part of the compiled model's cache key)."""
        return ("capsule", *self.a.tolist(), *self.b.tolist(), self.radius)


OBSTACLES = (Plane, Sphere, Capsule)
"""The obstacle kinds an :class:`Environment` accepts."""


@dataclass(frozen=True)
class ContactLaw:
    """Penalty contact with Hunt-Crossley damping and regularized Coulomb friction.

    Per unit of backbone rest length, a backbone point that penetrates the obstacle by
    ``x`` [m] (contact radius minus distance) feels the normal force density::

        f_n = k h(x)^e max(0, 1 + d dx/dt)            [N/m]

    along the obstacle's outward normal, where ``h`` is ``x`` with its corner at 0
    rounded over the width ``w`` (``h = 0`` for ``x <= 0``, ``x^2 / (2 w)`` for
    ``0 < x < w``, ``x - w/2`` beyond): the force and its derivative are continuous and
    exactly zero out of contact. Its elastic part ``k h^e`` derives from the penalty
    energy (per unit length) ``U(x) = int_0^x k h^e``; the damping part never adds
    energy. Friction opposes the point's tangential velocity ``v_t``::

        f_t = -mu f_n v_t / sqrt(|v_t|^2 + v_s^2)      [N/m]

    which is Coulomb's law ``|f_t| = mu f_n`` for ``|v_t| >> v_s`` and viscous below:
    a point "sticking" under a tangential load ``F < mu N`` creeps at
    ``v_s F / sqrt(mu^2 N^2 - F^2)``.

    Parameters
    ----------
    stiffness : float
        ``k`` [N m^-(1+e)], > 0: normal force per metre of backbone rest length per
        metre^e of penetration (``N/m^2.5`` for ``e = 1.5``).
    exponent : float
        ``e`` [-] in [1, 3]; 1.5 (default) is Hertz's exponent, 1 a linear spring.
    damping : float
        Hunt-Crossley coefficient ``d`` [s/m] >= 0 (default 0: elastic contact); the
        coefficient of restitution of a slow impact is about ``1 - 2 d v / 3`` for an
        impact speed ``v`` [m/s] (Hunt and Crossley 1975, with ``e = 1.5``).
    friction : float
        Coulomb coefficient ``mu`` [-] >= 0 (default 0: frictionless).
    slip_velocity : float
        Regularization velocity ``v_s`` [m/s] > 0 of the friction law (default 1e-3).
    smoothing : float
        Width ``w`` [m] > 0 over which the penetration's corner is rounded (default
        1e-5 m, well below the penetrations of useful stiffnesses).
    points_per_segment : int
        ``K`` >= 1 [-]: the contact is integrated along each segment by the trapezoidal
        rule on ``K + 1`` equally spaced material points (both ends included, default 8).
    """

    stiffness: float
    exponent: float = 1.5
    damping: float = 0.0
    friction: float = 0.0
    slip_velocity: float = 1e-3
    smoothing: float = 1e-5
    points_per_segment: int = 8

    def __post_init__(self):
        set_ = object.__setattr__
        set_(self, "stiffness", _positive("ContactLaw.stiffness", self.stiffness))
        exponent = real_scalar("ContactLaw.exponent", self.exponent)
        if not 1.0 <= exponent <= 3.0:
            raise ParameterError(f"ContactLaw.exponent must be in [1, 3], got {exponent!r}")
        set_(self, "exponent", exponent)
        for name in ("damping", "friction"):
            value = real_scalar(f"ContactLaw.{name}", getattr(self, name))
            if value < 0:
                raise ParameterError(f"ContactLaw.{name} must be >= 0, got {value!r}")
            set_(self, name, value)
        set_(self, "slip_velocity", _positive("ContactLaw.slip_velocity", self.slip_velocity))
        set_(self, "smoothing", _positive("ContactLaw.smoothing", self.smoothing))
        k = self.points_per_segment
        if isinstance(k, bool) or not isinstance(k, int | np.integer) or not 1 <= k <= 200:
            raise ParameterError(
                f"ContactLaw.points_per_segment must be an integer in [1, 200], got {k!r}"
            )
        set_(self, "points_per_segment", int(k))

    def key(self) -> tuple:
        """The law as a tuple of plain numbers (part of the compiled model's cache key)."""
        return (
            self.stiffness,
            self.exponent,
            self.damping,
            self.friction,
            self.slip_velocity,
            self.smoothing,
            self.points_per_segment,
        )


@dataclass(frozen=True)
class Environment:
    """The obstacles around a robot and the contact law, for ``Model(robot, environment=)``.

    Parameters
    ----------
    obstacles : sequence of Plane, Sphere or Capsule
        The obstacles (at least one), in the robot's base frame.
    law : ContactLaw
        The contact law shared by all obstacles.
    contact_radius : sequence of float or None, shape (N,), optional
        Per segment, the radius [m] > 0 of the ball that sweeps its backbone; None (for
        all, or for one segment) means the segment's slice radius ``r``.
    """

    obstacles: tuple
    law: ContactLaw
    contact_radius: tuple | None = None

    def __post_init__(self):
        try:
            obstacles = tuple(self.obstacles)
        except TypeError:
            raise ParameterError(
                f"Environment.obstacles must be a sequence of Plane, Sphere or Capsule, "
                f"got {self.obstacles!r}"
            ) from None
        if not obstacles:
            raise ParameterError("Environment.obstacles must hold at least one obstacle, got ()")
        for i, obstacle in enumerate(obstacles):
            if not isinstance(obstacle, OBSTACLES):
                raise ParameterError(
                    f"Environment.obstacles[{i}] must be a Plane, Sphere or Capsule, "
                    f"got {type(obstacle).__name__}"
                )
        object.__setattr__(self, "obstacles", obstacles)
        if not isinstance(self.law, ContactLaw):
            raise ParameterError(f"Environment.law must be a ContactLaw, got {self.law!r}")
        if self.contact_radius is not None:
            radii = []
            for i, r in enumerate(np.atleast_1d(np.asarray(self.contact_radius, dtype=object))):
                radii.append(None if r is None else _positive(f"contact_radius[{i}]", r))
            object.__setattr__(self, "contact_radius", tuple(radii))

    def check_robot(self, robot) -> None:
        """Raise :class:`ParameterError` unless the contact radii fit ``robot``.

        Parameters
        ----------
        robot : Robot
            The robot the environment is given to.
        """
        if self.contact_radius is not None and len(self.contact_radius) != robot.n_segments:
            raise ParameterError(
                f"Environment.contact_radius must have one entry per segment "
                f"({robot.n_segments}), got {len(self.contact_radius)}"
            )

    def radii(self, slice_radii) -> list:
        """The contact radius of each segment: ``contact_radius[i]``, or where that is
        None (or not given) the segment's slice radius.

        Parameters
        ----------
        slice_radii : sequence, shape (N,)
            The segments' slice radii [m] (numbers, or CasADi symbols of the model's
            parameters).
        """
        given = self.contact_radius or (None,) * len(slice_radii)
        return [r if c is None else c for r, c in zip(slice_radii, given, strict=True)]

    def key(self) -> tuple:
        """The environment as a tuple of plain values: the compiled model's cache key holds
        it, since its numbers are compiled into the code."""
        return (
            tuple(o.key() for o in self.obstacles),
            self.law.key(),
            self.contact_radius,
        )
