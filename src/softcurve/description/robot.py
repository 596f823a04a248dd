"""The robot description: immutable, validated parameters and nothing numeric.

A :class:`Robot` is a serial chain of ``N >= 1`` constant-curvature :class:`Segment`
objects; segment ``i`` has coordinates ``q[3i:3i+3] = (l, kx, ky)`` and starts at the
tip frame of segment ``i - 1``. Every field is checked once, when the object is
built, and a bad value raises :class:`ParameterError` naming it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from softcurve.base.validation import ParameterError, positive_definite, real_array, real_scalar
from softcurve.description.layout import ParameterLayout
from softcurve.description.materials import Creep, LinearStiffness, TanhStiffness

StiffnessLaw = LinearStiffness | TanhStiffness


@dataclass(frozen=True, eq=False)
class Segment:
    """One constant-curvature segment.

    Parameters
    ----------
    rest_length : float
        Undeformed arc length ``l0`` [m], > 0.
    mass : float
        Total mass ``m`` [kg], > 0, spread uniformly along the backbone.
    radius : float
        Radius ``r`` [m], > 0, of the thin disk that models each slice's rotary inertia.
    elongation_stiffness : LinearStiffness or TanhStiffness
        ``k_e(eps)`` [N/m] of the elongation ``eps = l - l0``.
    bending_stiffness : LinearStiffness or TanhStiffness
        ``k_b(beta)`` [N m/rad] of the bending angle ``beta = kappa l``.
    damping : array_like, shape (3, 3) or (3,)
        ``R`` in ``F = R qd``, symmetric positive definite; a vector is a diagonal
        ``(N s/m, N m s, N m s)``.
    creep : Creep or None
        Kelvin-Voigt creep (three creep states), or None for none.

    Examples
    --------
    >>> import softcurve as sc
    >>> segment = sc.Segment(
    ...     rest_length=0.0644,
    ...     mass=0.0494,
    ...     radius=0.0235,
    ...     elongation_stiffness=sc.LinearStiffness(500.0),
    ...     bending_stiffness=sc.TanhStiffness(0.423, 0.399, -0.229),
    ...     damping=[0.12, 5.93e-7, 5.93e-7],
    ... )
    >>> segment.damping.diagonal()
    array([1.2e-01, 5.93e-07, 5.93e-07])
    >>> segment.replace(mass=0.06).mass
    0.06
    """

    rest_length: float
    mass: float
    radius: float
    elongation_stiffness: StiffnessLaw
    bending_stiffness: StiffnessLaw
    damping: np.ndarray = field(default_factory=lambda: np.zeros(3))
    creep: Creep | None = None

    def __post_init__(self):
        for name in ("rest_length", "mass", "radius"):
            object.__setattr__(self, name, real_scalar(name, getattr(self, name), positive=True))
        for name in ("elongation_stiffness", "bending_stiffness"):
            law = getattr(self, name)
            if not isinstance(law, LinearStiffness | TanhStiffness):
                raise ParameterError(
                    f"{name} must be a LinearStiffness or TanhStiffness, got {type(law).__name__}"
                )
        object.__setattr__(self, "damping", _damping(self.damping))
        if self.creep is not None and not isinstance(self.creep, Creep):
            raise ParameterError(f"creep must be a Creep or None, got {type(self.creep).__name__}")

    def replace(self, **changes) -> Segment:
        """A copy with some fields changed (validated again).

        Parameters
        ----------
        **changes
            New values of fields, by name (e.g. ``mass=0.06``).
        """
        return dataclasses.replace(self, **changes)


def _damping(value) -> np.ndarray:
    """Damping may be zero (a conservative model) but otherwise positive definite."""
    a = np.asarray(value, dtype=np.float64)
    if a.shape == (3,) and np.all(a == 0) or a.shape == (3, 3) and np.all(a == 0):
        return real_array("damping", np.zeros((3, 3)), (3, 3))
    return positive_definite("damping", value, 3)


@dataclass(frozen=True, eq=False)
class Robot:
    """A serial chain of constant-curvature segments under gravity.

    Parameters
    ----------
    segments : sequence of Segment
        At least one; segment ``i`` starts at the tip frame of segment ``i - 1``.
    gravity : array_like, shape (3,)
        Gravitational acceleration [m/s^2] in the world frame. The default
        ``(0, 0, -9.81)`` with the default base rotation is an upright robot;
        ``(0, 0, 9.81)`` a robot hanging from its base.
    base_rotation : array_like, shape (3, 3)
        Orientation of the base frame in the world frame (a rotation matrix).
        The base frame has its origin at the base of the first segment and ``z``
        along the undeformed backbone; poses are reported in the world frame,
        which is the base frame when this is the identity.

    Examples
    --------
    A two-segment robot hanging from its base, built from the paper's segment:

    >>> import numpy as np
    >>> import softcurve as sc
    >>> segment = sc.presets.ifac2020().segments[0]
    >>> robot = sc.Robot(segments=(segment, segment), gravity=[0.0, 0.0, 9.81])
    >>> robot.n, robot.n_creep
    (6, 6)
    >>> round(robot.rest_length, 4)  # [m]
    0.1288
    >>> robot.with_segments(3).n_segments
    3
    >>> p = robot.parameter_vector()
    >>> robot.with_parameter_vector(p).mass == robot.mass
    True
    """

    segments: tuple[Segment, ...]
    gravity: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -9.81]))
    base_rotation: np.ndarray = field(default_factory=lambda: np.eye(3))

    def __post_init__(self):
        if isinstance(self.segments, Segment):
            object.__setattr__(self, "segments", (self.segments,))
        segments = tuple(self.segments)
        if not segments:
            raise ParameterError("segments must hold at least one Segment, got none")
        for i, s in enumerate(segments):
            if not isinstance(s, Segment):
                raise ParameterError(f"segments[{i}] must be a Segment, got {type(s).__name__}")
        object.__setattr__(self, "segments", segments)
        object.__setattr__(self, "gravity", real_array("gravity", self.gravity, (3,)))
        rotation = real_array("base_rotation", self.base_rotation, (3, 3))
        if not (
            np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-9) and np.linalg.det(rotation) > 0
        ):
            raise ParameterError(
                "base_rotation must be a rotation matrix (orthonormal, determinant +1), "
                f"got {rotation.tolist()}"
            )
        object.__setattr__(self, "base_rotation", rotation)

    @property
    def n_segments(self) -> int:
        """Number of segments ``N``."""
        return len(self.segments)

    @property
    def n(self) -> int:
        """Number of generalized coordinates, ``3 N``."""
        return 3 * len(self.segments)

    @property
    def n_creep(self) -> int:
        """Number of creep states: three for each segment with creep."""
        return 3 * sum(s.creep is not None for s in self.segments)

    @property
    def rest_length(self) -> float:
        """Total undeformed length [m]."""
        return sum(s.rest_length for s in self.segments)

    @property
    def mass(self) -> float:
        """Total mass [kg]."""
        return sum(s.mass for s in self.segments)

    def structure(self) -> tuple:
        """What the compiled model depends on besides parameter values."""
        return tuple(
            (s.elongation_stiffness.kind, s.bending_stiffness.kind, s.creep is not None)
            for s in self.segments
        )

    @property
    def layout(self) -> ParameterLayout:
        """Names and slices of :meth:`parameter_vector` (one per structure)."""
        return ParameterLayout.of_structure(self.structure())

    def parameter_vector(self) -> np.ndarray:
        """All numbers of the robot, in the order the compiled model reads them.

        ``parameter_names()`` names each entry; :attr:`layout` says where each field lies.
        """
        return self.layout.pack(self)

    def parameter_names(self) -> list[str]:
        """Names of the entries of ``parameter_vector()``, e.g.
        ``"segments[0].bending_stiffness.a1"`` or ``"gravity[2]"``."""
        return list(self.layout.names)

    def replace(self, **changes) -> Robot:
        """A copy with some fields changed (validated again).

        Parameters
        ----------
        **changes
            New values of fields, by name (e.g. ``gravity=[0, 0, 9.81]``).
        """
        return dataclasses.replace(self, **changes)

    def with_parameter_vector(self, vector) -> Robot:
        """The robot of this structure whose :meth:`parameter_vector` is ``vector``.

        The inverse of :meth:`parameter_vector`: segments, stiffness-law types and creep
        stay; every number is taken from ``vector`` and validated again.

        Parameters
        ----------
        vector : array_like, shape (n_p,)
            Values in the order of :meth:`parameter_names`.

        Raises
        ------
        ParameterError
            If ``vector`` has the wrong shape or a value is outside its allowed range
            (the message names the field).
        """
        return self.layout.unpack(vector, self)

    def with_segments(self, count: int) -> Robot:
        """The same robot with its segment list repeated to ``count`` segments.

        Parameters
        ----------
        count : int
            Number of segments, >= 1; segment ``i`` is a copy of segment
            ``i % n_segments``.
        """
        if count < 1:
            raise ParameterError(f"count must be >= 1, got {count}")
        return self.replace(
            segments=tuple(self.segments[i % self.n_segments] for i in range(count))
        )
