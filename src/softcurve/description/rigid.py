"""The rigid body: a gripper, a payload, a camera, a rigid link between soft sections.

It adds no coordinates. Its frame is its base (the tip frame of the element before it,
or the robot's base); it carries its mass at its centre with its inertia tensor, and
places the next element's base at the fixed transform ``(tip_rotation, tip_position)``
(a fixed placement, as a body and its child joint's placement in Pinocchio).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from softcurve.base.validation import ParameterError, real_array, real_scalar
from softcurve.description.kind import (
    Body,
    Element,
    ElementModel,
    matrix_field,
    scalar_field,
    vector_field,
)

JOINT_ROUNDING = 1e-12
"""How close to 1 a rigid body's local coordinate counts as its tip: the robot's
``s N - i`` at an element's end ``s = (i + 1) / N`` rounds a few ulps short of 1 (4.4e-16
at ``N = 22``), and there the point is the next element's base, the tip frame. Chains of
thousands of elements stay within it; no drawing resolves 1e-12 of a body."""

ROTATION_TOLERANCE = 1e-9
"""How far ``R^T R`` may be from the identity: the base rotation's tolerance, for a
rotation matrix written with nine or more digits."""


def rotation_matrix(name: str, value) -> np.ndarray:
    """``value`` as a rotation matrix (orthonormal, determinant +1), or ParameterError
    naming ``name``.

    Parameters
    ----------
    name : str
        The field's name.
    value : array_like, shape (3, 3)
        The matrix.
    """
    rotation = real_array(name, value, (3, 3))
    if not (
        np.allclose(rotation.T @ rotation, np.eye(3), atol=ROTATION_TOLERANCE)
        and np.linalg.det(rotation) > 0
    ):
        raise ParameterError(
            f"{name} must be a rotation matrix (orthonormal, determinant +1), "
            f"got {rotation.tolist()}"
        )
    return rotation


@dataclass(frozen=True, eq=False)
class RigidBody(Element):
    """A rigid body in the chain, between segments or at the tip.

    Parameters
    ----------
    mass : float
        Its mass [kg], >= 0 (0: a massless placement, such as a rigid offset).
    tip_position : array_like, shape (3,)
        Where the next element's base (or the robot's tip) lies [m], in the body's base
        frame.
    tip_rotation : array_like, shape (3, 3)
        The orientation of that frame in the body's base frame (a rotation matrix);
        default the identity.
    centre_of_mass : array_like, shape (3,)
        [m], base frame; default halfway to the tip.
    inertia : array_like, shape (3, 3) or (3,)
        Rotational inertia about the centre of mass [kg m^2], base frame, symmetric
        positive semidefinite; a vector is a diagonal; default zero (a point mass).
    radius : float
        [m], > 0: the body's radius for contact and drawing (a capsule from base to
        tip); default a tenth of its length, or 1 mm for a body of no length.

    Examples
    --------
    A 50 g gripper 3 cm long at the tip of a segment:

    >>> import numpy as np
    >>> import softcurve as sc
    >>> gripper = sc.RigidBody(mass=0.05, tip_position=[0, 0, 0.03], inertia=[2e-6, 2e-6, 1e-6])
    >>> robot = sc.Robot(segments=(sc.presets.ifac2020().segments[0], gripper))
    >>> robot.n, robot.offsets, robot.sizes
    (3, (0, 3), (3, 0))
    """

    mass: float
    tip_position: np.ndarray
    tip_rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    centre_of_mass: np.ndarray | None = None
    inertia: np.ndarray | None = None
    radius: float | None = None

    kind = "rigid_body"

    def __post_init__(self):
        set_ = object.__setattr__
        mass = real_scalar("mass", self.mass)
        if not mass >= 0:
            raise ParameterError(f"mass must be >= 0 [kg], got {mass!r}")
        set_(self, "mass", mass)
        tip = real_array("tip_position", self.tip_position, (3,))
        set_(self, "tip_position", tip)
        set_(self, "tip_rotation", rotation_matrix("tip_rotation", self.tip_rotation))
        centre = 0.5 * tip if self.centre_of_mass is None else self.centre_of_mass
        set_(self, "centre_of_mass", real_array("centre_of_mass", centre, (3,)))
        inertia = np.zeros((3, 3)) if self.inertia is None else np.asarray(self.inertia, float)
        if inertia.shape == (3,):
            inertia = np.diag(inertia)
        inertia = real_array("inertia", inertia, (3, 3))
        scale = max(np.max(np.abs(inertia)), np.finfo(float).tiny)
        principal = np.linalg.eigvalsh(0.5 * (inertia + inertia.T))
        if (
            not np.allclose(inertia, inertia.T, rtol=0, atol=1e-12 * scale)
            or np.min(principal) < -1e-12 * scale
            or 2 * np.max(principal) > principal.sum() + 1e-12 * scale
        ):
            raise ParameterError(
                "inertia must be symmetric positive semidefinite with each principal moment at "
                f"most the sum of the other two (a body's) [kg m^2], got {inertia.tolist()}"
            )
        set_(self, "inertia", 0.5 * (inertia + inertia.T))
        length = float(np.linalg.norm(tip))
        radius = (0.1 * length if length > 0 else 1e-3) if self.radius is None else self.radius
        set_(self, "radius", real_scalar("radius", radius, positive=True))

    @property
    def rest_length(self) -> float:
        """Distance from base to tip [m]."""
        return float(np.linalg.norm(self.tip_position))

    def signature(self) -> tuple:
        """``("rigid_body",)``."""
        return (self.kind,)

    @property
    def coordinate_names(self) -> tuple[str, ...]:
        """None: a rigid body adds no coordinates."""
        return ()

    @property
    def coordinate_units(self) -> tuple[str, ...]:
        """None."""
        return ()

    def rest_configuration(self) -> np.ndarray:
        return np.zeros(0)

    def coordinate_scale(self) -> np.ndarray:
        return np.zeros(0)

    def search_bounds(self) -> np.ndarray:
        return np.zeros((0, 2))

    def inside(self, q, rest_length=None) -> np.ndarray:
        return np.ones(np.shape(q)[:-1], dtype=bool)

    def domain_problem(self, q, index: int, place, rest_length=None) -> str | None:
        return None

    def with_values(self, values: dict) -> RigidBody:
        return self.replace(
            mass=float(values["mass"]),
            centre_of_mass=values["centre_of_mass"],
            inertia=values["inertia"],
            tip_position=values["tip_position"],
            tip_rotation=values["tip_rotation"],
            radius=float(values["radius"]),
        )


class RigidModel(ElementModel):
    """The symbolic rigid body; geometry ``(mass, centre (3), inertia (9, row major),
    tip rotation (9, row major), tip position (3))``."""

    def __init__(self, signature: tuple):
        self.signature = signature
        self.nq = 0
        self.n_creep = 0

    def fields(self):
        return [
            scalar_field("mass", "kg"),
            vector_field("centre_of_mass", 3, "m"),
            matrix_field("inertia", 3, "kg m^2"),
            vector_field("tip_position", 3, "m"),
            matrix_field("tip_rotation", 3, ""),
            scalar_field("radius", "m"),
        ]

    def geometry(self, part):
        return ca.vertcat(
            part["mass"],
            part["centre_of_mass"],
            ca.vec(part["inertia"].T),
            ca.vec(part["tip_rotation"].T),
            part["tip_position"],
        )

    @staticmethod
    def _matrix(g, start):
        return ca.reshape(g[start : start + 9], 3, 3).T

    def point_pose(self, q, s, g):
        # the body's points share its base frame's orientation; s = 1 is the tip frame
        at_tip = s >= 1 - JOINT_ROUNDING
        return ca.if_else(at_tip, self._matrix(g, 13), ca.SX.eye(3)), s * g[22:25]

    def angular_jacobian(self, q, s, g):
        return ca.SX(3, 0)

    def bodies(self, g, quadrature_nodes: int) -> list[Body]:
        return [Body(None, g[0], self._matrix(g, 4), g[1:4])]

    def elastic(self, q, part):
        return ca.SX(0), ca.SX(0, 1)
