"""The robot description: immutable, validated parameters and nothing numeric.

A :class:`Robot` is a serial chain of ``N >= 1`` constant-curvature :class:`Segment`
objects; segment ``i`` has coordinates ``q[3i:3i+3] = (l, kx, ky)`` and starts at the
tip frame of segment ``i - 1``. Every field is checked once, when the object is
built, and a bad value raises :class:`ParameterError` naming it.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from softcurve.base.validation import (
    FLOAT_MAX,
    ParameterError,
    positive_definite,
    real_array,
    real_scalar,
)
from softcurve.description.layout import ParameterLayout
from softcurve.description.materials import Creep, LinearStiffness, TanhStiffness

StiffnessLaw = LinearStiffness | TanhStiffness

MAX_STRETCH = 10.0
"""Longest segment allowed, in rest lengths: the model's domain has ``l <= MAX_STRETCH *
l0``. The most stretchable silicone rubbers of soft robots break at an elongation of
about 900 % (Ecoflex 00-30 and Dragon Skin 10 datasheets), that is at ten rest lengths: a
longer segment has torn, and such a state is a numerical runaway (a robot too soft for
its loads, an initial rate too large), not a motion."""

MAX_BEND = 2.0 * math.pi
"""Largest bending angle ``|kappa| l`` of a segment [rad] in the model's domain: a full
turn. Beyond it the arc overlaps itself, which a solid segment cannot do. The backbone
quadrature is at round-off up to pi per segment with the default 11 nodes and within
1e-13 relative at 2 pi (docs/model.md, "Quadrature"), so the whole domain is computed
accurately."""

MAX_REST_LENGTH = FLOAT_MAX**0.25 / MAX_STRETCH
"""Longest rest length [m] (about 1.2e76 m): the mass matrix's bending entries grow as
the fourth power of a segment's length (``m l^4``), and a segment reaches
``MAX_STRETCH`` rest lengths, so beyond it they overflow float64 in the model's domain
(measured: the paper's segment at rest simulates at ``l0 = 1e77`` m, and at 1e78 m its
linearization holds infinities)."""


def segment_inside(length, kx, ky, longest, hypot=np.hypot):
    """The domain's rule for one segment's coordinates, written once: ``0 < l <= longest``
    and a bending angle ``l |kappa| <= MAX_BEND`` (NaN fails every comparison). Works on
    floats (with ``hypot=math.hypot``, several times faster for a few segments) and,
    elementwise, on arrays.

    Parameters
    ----------
    length, kx, ky : float or ndarray
        The segment's length [m] and curvatures [1/m].
    longest : float or ndarray
        The longest length in the domain, ``MAX_STRETCH l0`` [m].
    hypot : callable
        ``math.hypot`` for floats, ``numpy.hypot`` (default) for arrays.
    """
    return (length > 0) & (length <= longest) & (length * hypot(kx, ky) <= MAX_BEND)


def in_domain(q, rest_lengths) -> np.ndarray:
    """Whether configurations lie in the model's domain: every ``l`` in ``(0, MAX_STRETCH
    l0]``, every bending angle ``|kappa| l <= MAX_BEND``, every entry finite (NaN fails
    every comparison). Vectorized; the check run at a simulation's output times.

    Parameters
    ----------
    q : array_like, shape (..., n)
        Configurations ``(l, kx, ky)`` per segment [m, 1/m, 1/m].
    rest_lengths : array_like, shape (N,) or (..., N)
        Rest length ``l0`` [m] of each segment (per configuration where it differs).

    Returns
    -------
    ndarray of bool, shape (...)
    """
    q = np.asarray(q, dtype=np.float64)
    length, kx, ky = q[..., 0::3], q[..., 1::3], q[..., 2::3]
    limit = MAX_STRETCH * np.asarray(rest_lengths, dtype=np.float64)
    with np.errstate(invalid="ignore", over="ignore"):
        return np.all(segment_inside(length, kx, ky, limit), axis=-1)


def domain_problem(q, rest_lengths, *, entry: str = "entry") -> str | None:
    """What puts the configuration ``q`` outside the model's domain (see
    :func:`in_domain`), naming the coordinate, its value and the allowed range; None
    inside.

    Parameters
    ----------
    q : array_like, shape (n,)
        One configuration [m, 1/m, 1/m].
    rest_lengths : array_like, shape (N,)
        Rest length ``l0`` [m] of each segment.
    entry : str
        How an index into ``q`` is named in the message (e.g. ``"q[3]"``); default
        ``"entry 3"``.
    """
    q = np.asarray(q, dtype=np.float64)

    def place(index: int) -> str:
        return f"{entry} {index}" if entry == "entry" else f"{entry}[{index}]"

    for i, l0 in enumerate(np.asarray(rest_lengths, dtype=np.float64)):
        length, kx, ky = (float(v) for v in q[3 * i : 3 * i + 3])
        for k, (name, value) in enumerate((("l", length), ("kx", kx), ("ky", ky))):
            if not math.isfinite(value):
                return (
                    f"entries must be finite: {name} of segment {i + 1} ({place(3 * i + k)}) "
                    f"= {value}"
                )
        if not 0 < length <= MAX_STRETCH * l0:
            return (
                f"lengths l must be in the model's domain 0 < l <= {MAX_STRETCH:g} rest lengths "
                f"({MAX_STRETCH * l0:.6g} m): l of segment {i + 1} ({place(3 * i)}) = "
                f"{length:.6g} m"
            )
        bend = length * math.hypot(kx, ky)
        if not bend <= MAX_BEND:
            return (
                f"bending angles |kappa| l must be <= 2 pi rad (a full turn, the model's "
                f"domain): segment {i + 1} bends {bend:.6g} rad (l = {length:.6g} m, "
                f"kx = {kx:.6g} 1/m, ky = {ky:.6g} 1/m)"
            )
    return None


@dataclass(frozen=True, eq=False)
class Segment:
    """One constant-curvature segment.

    Parameters
    ----------
    rest_length : float
        Undeformed arc length ``l0`` [m], in ``(0, MAX_REST_LENGTH]`` (about 1.2e76 m).
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
        if self.rest_length > MAX_REST_LENGTH:
            raise ParameterError(
                f"rest_length must be in (0, {MAX_REST_LENGTH:.3g}] m (beyond it the mass "
                f"matrix's l^4 terms overflow float64), got {self.rest_length!r}"
            )
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
    """Damping may be zero (a conservative model) but otherwise symmetric positive
    definite: the damping force ``R qd`` takes the power ``qd^T R qd`` from the robot,
    which must be >= 0 for every motion (else the damper is a source of energy), and
    the code requires > 0 for every nonzero ``qd`` (no undamped direction hidden in a
    damped segment)."""
    a = np.asarray(value, dtype=np.float64)
    if a.shape == (3,) and np.all(a == 0) or a.shape == (3, 3) and np.all(a == 0):
        return real_array("damping", np.zeros((3, 3)), (3, 3))
    try:
        return positive_definite("damping", value, 3)
    except ParameterError as exc:
        raise ParameterError(
            f"{exc}. Rule: the damping force R qd dissipates the power qd^T R qd, so R must be "
            "symmetric positive definite (qd^T R qd > 0 for every motion qd) or exactly zero; "
            "a negative entry makes the robot active (it creates energy)"
        ) from None


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

    @cached_property
    def rest_lengths(self) -> np.ndarray:
        """Rest length ``l0`` [m] of each segment, shape (N,)."""
        lengths = np.array([s.rest_length for s in self.segments])
        lengths.setflags(write=False)
        return lengths

    @cached_property
    def _length_limits(self) -> list[float]:
        return [MAX_STRETCH * s.rest_length for s in self.segments]

    def check_configuration(self, q, name: str = "q0") -> np.ndarray:
        """``q`` as a float64 array of shape (n,), checked to lie in the model's domain.

        The domain, the one check of every configuration a user gives (``simulate``,
        ``simulate_batch``, statics, the compiled model's methods, scenario files): every
        segment length ``0 < l <= MAX_STRETCH * l0``, every bending angle ``|kappa| l <=
        MAX_BEND`` (2 pi), every entry finite. Simulations stop where the state leaves it
        (status ``LEFT_DOMAIN``).

        Parameters
        ----------
        q : array_like, shape (n,)
            Coordinates ``(l, kx, ky)`` per segment [m, 1/m, 1/m].
        name : str
            The argument's name, for the message.

        Raises
        ------
        ParameterError
            Naming the argument, the coordinate, its value and the allowed range.
        """
        q = np.asarray(q, dtype=np.float64)
        if q.shape != (self.n,):
            raise ParameterError(f"{name} must have shape ({self.n},), got {q.shape}")
        # plain floats: for a few segments ~1 us, several times faster than NumPy's
        # reductions; NaN fails every comparison
        values = q.tolist()
        for i, limit in enumerate(self._length_limits):
            if not segment_inside(*values[3 * i : 3 * i + 3], limit, math.hypot):
                break
        else:
            return q
        problem = domain_problem(q, self.rest_lengths, entry=name)
        raise ParameterError(f"{name}: {problem}")

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
