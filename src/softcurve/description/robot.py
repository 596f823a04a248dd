"""The robot description: immutable, validated parameters and nothing numeric.

A :class:`Robot` is a serial chain of ``N >= 1`` elements
(:mod:`softcurve.description.elements`: constant-curvature :class:`Segment`,
:class:`StrainSegment`, :class:`RigidBody`); element ``i`` starts at the tip frame of
element ``i - 1`` and owns the coordinates ``q[offsets[i] : offsets[i] + sizes[i]]``
(Pinocchio's ``idx_q`` and ``nq``). Every field is checked once, when the object is
built, and a bad value raises :class:`ParameterError` naming it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from softcurve.base.validation import ParameterError, real_array
from softcurve.description.elements import (
    MAX_BEND,
    MAX_REST_LENGTH,
    MAX_STRETCH,
    Element,
    RigidBody,
    Segment,
    StrainSegment,
    rotation_matrix,
    segment_inside,
    segment_problem,
)
from softcurve.description.layout import ParameterLayout

__all__ = [
    "MAX_BEND",
    "MAX_REST_LENGTH",
    "MAX_STRETCH",
    "RigidBody",
    "Robot",
    "Segment",
    "StrainSegment",
    "domain_problem",
    "in_domain",
    "segment_inside",
]


def in_domain(q, rest_lengths) -> np.ndarray:
    """Whether configurations of a robot of constant-curvature segments lie in the
    model's domain: every ``l`` in ``(0, MAX_STRETCH l0]``, every bending angle ``|kappa|
    l <= MAX_BEND``, every entry finite (NaN fails every comparison). Vectorized, with
    rest lengths per configuration where they differ (a batch's members); a robot of
    other elements checks with :meth:`Robot.inside`.

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
    _check_curvature_shape(q, rest_lengths)
    length, kx, ky = q[..., 0::3], q[..., 1::3], q[..., 2::3]
    limit = MAX_STRETCH * np.asarray(rest_lengths, dtype=np.float64)
    with np.errstate(invalid="ignore", over="ignore"):
        return np.all(segment_inside(length, kx, ky, limit), axis=-1)


def _check_curvature_shape(q, rest_lengths) -> None:
    """The rule of constant-curvature robots reads ``(l, kx, ky)`` per rest length: any
    other count of coordinates is another robot's (:meth:`Robot.inside`)."""
    count = np.shape(rest_lengths)[-1] if np.ndim(rest_lengths) else 1
    if q.shape[-1] != 3 * count:
        raise ParameterError(
            f"q has {q.shape[-1]} coordinates, not (l, kx, ky) for each of {count} "
            "constant-curvature segments: check a robot of other elements with Robot.inside "
            "and Robot.domain_problem"
        )


def _place(entry: str):
    def place(index: int) -> str:
        return f"{entry} {index}" if entry == "entry" else f"{entry}[{index}]"

    return place


def domain_problem(q, rest_lengths, *, entry: str = "entry") -> str | None:
    """What puts the configuration ``q`` of a robot of constant-curvature segments outside
    the model's domain (see :func:`in_domain`), naming the coordinate, its value and the
    allowed range; None inside. A robot of other elements: :meth:`Robot.domain_problem`.

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
    _check_curvature_shape(q, rest_lengths)
    place = _place(entry)
    for i, l0 in enumerate(np.asarray(rest_lengths, dtype=np.float64)):
        problem = segment_problem(q[3 * i : 3 * i + 3], l0, i, lambda k, i=i: place(3 * i + k))
        if problem is not None:
            return problem
    return None


@dataclass(frozen=True, eq=False)
class Robot:
    """A serial chain of elements under gravity: constant-curvature segments,
    constant-strain segments and rigid bodies.

    Parameters
    ----------
    segments : sequence of Segment, StrainSegment or RigidBody
        At least one element; element ``i`` starts at the tip frame of element ``i - 1``
        and owns the coordinates ``q[offsets[i] : offsets[i] + sizes[i]]``.
    gravity : array_like, shape (3,)
        Gravitational acceleration [m/s^2] in the world frame. The default
        ``(0, 0, -9.81)`` with the default base rotation is an upright robot;
        ``(0, 0, 9.81)`` a robot hanging from its base.
    base_rotation : array_like, shape (3, 3)
        Orientation of the base frame in the world frame (a rotation matrix).
        The base frame has its origin at the base of the first element and ``z``
        along the undeformed backbone; poses are reported in the world frame,
        which is the base frame when this is the identity and ``base_position`` zero.
    base_position : array_like, shape (3,)
        Position of the base frame's origin in the world frame [m]; default zero.
    spans : array_like, shape (N,), optional
        Each element's share of the whole robot's material coordinate ``s`` in [0, 1]
        (weights > 0, dimensionless, normalized to sum 1): element ``i`` covers
        ``[c_i, c_(i+1)]`` with ``c`` their cumulative sum. Default equal shares, element
        ``i`` of ``N`` covering ``[i/N, (i+1)/N]``; e.g. the rest lengths
        (``spans=robot.rest_lengths``) make ``s`` the share of the rest length.

    Examples
    --------
    A two-segment robot hanging from its base, built from the paper's segment:

    >>> import numpy as np
    >>> import softcurve as sc
    >>> segment = sc.presets.ifac2020().segments[0]
    >>> robot = sc.Robot(segments=(segment, segment), gravity=[0.0, 0.0, 9.81])
    >>> robot.n, robot.n_creep
    (6, 6)
    >>> robot.offsets, robot.sizes
    ((0, 3), (3, 3))
    >>> round(robot.rest_length, 4)  # [m]
    0.1288
    >>> robot.with_segments(3).n_segments
    3
    >>> p = robot.parameter_vector()
    >>> robot.with_parameter_vector(p).mass == robot.mass
    True
    """

    segments: tuple[Element, ...]
    gravity: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -9.81]))
    base_rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    base_position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    spans: np.ndarray | None = None

    def __post_init__(self):
        if isinstance(self.segments, Element):
            object.__setattr__(self, "segments", (self.segments,))
        segments = tuple(self.segments)
        if not segments:
            raise ParameterError("segments must hold at least one Segment, got none")
        for i, s in enumerate(segments):
            if not isinstance(s, Segment | StrainSegment | RigidBody):
                raise ParameterError(
                    f"segments[{i}] must be a Segment, StrainSegment or RigidBody, got "
                    f"{type(s).__name__}"
                )
        if all(isinstance(s, RigidBody) for s in segments):
            raise ParameterError(
                "segments must hold at least one Segment or StrainSegment: a robot of rigid "
                "bodies alone has no coordinates"
            )
        object.__setattr__(self, "segments", segments)
        object.__setattr__(self, "gravity", real_array("gravity", self.gravity, (3,)))
        rotation = rotation_matrix("base_rotation", self.base_rotation)
        object.__setattr__(self, "base_rotation", rotation)
        position = real_array("base_position", self.base_position, (3,))
        object.__setattr__(self, "base_position", position)
        if self.spans is not None:
            spans = real_array("spans", self.spans, (len(segments),))
            if not np.all(spans > 0):
                raise ParameterError(
                    f"spans must be > 0 for every element (their shares of the material "
                    f"coordinate s), got {spans.tolist()}"
                )
            spans.setflags(write=False)
            object.__setattr__(self, "spans", spans)

    @property
    def span_weights(self) -> np.ndarray:
        """The elements' shares of ``s`` as given (all ones by default), shape (N,)."""
        return np.ones(len(self.segments)) if self.spans is None else self.spans

    @cached_property
    def span_bounds(self) -> np.ndarray:
        """Where each element begins and ends in ``s``, shape (N + 1,): ``0``, the
        normalized cumulative :attr:`span_weights`, ``1``."""
        ends = np.cumsum(self.span_weights) / np.sum(self.span_weights)
        ends[-1] = 1.0
        bounds = np.concatenate([[0.0], ends])
        bounds.setflags(write=False)
        return bounds

    @property
    def n_segments(self) -> int:
        """Number of elements ``N`` (segments and rigid bodies)."""
        return len(self.segments)

    @property
    def element_word(self) -> str:
        """What the robot's parts are called in messages: ``"segment"`` when every
        element is a constant-curvature segment, else ``"element"`` (a chain with rigid
        bodies or constant-strain segments; :attr:`n_segments` counts them all)."""
        return "segment" if self.constant_curvature else "element"

    def counted(self) -> str:
        """The number of elements in words, ``"2 segments"``, ``"3 elements"``,
        ``"1 element"``."""
        n = self.n_segments
        return f"{n} {self.element_word}{'s' if n != 1 else ''}"

    @cached_property
    def sizes(self) -> tuple[int, ...]:
        """Number of coordinates of each element (Pinocchio's ``nq``)."""
        return tuple(s.n_coordinates for s in self.segments)

    @cached_property
    def offsets(self) -> tuple[int, ...]:
        """Index of each element's first coordinate in ``q`` (Pinocchio's ``idx_q``)."""
        starts, k = [], 0
        for size in self.sizes:
            starts.append(k)
            k += size
        return tuple(starts)

    @property
    def n(self) -> int:
        """Number of generalized coordinates (``3 N`` for constant-curvature segments)."""
        return sum(self.sizes)

    @property
    def n_creep(self) -> int:
        """Number of creep states: one per coordinate of each element with creep."""
        return sum(s.n_creep for s in self.segments)

    @property
    def constant_curvature(self) -> bool:
        """Whether every element is a constant-curvature :class:`Segment` (the paper's
        robots, which the C driver's and the actuators' closed forms are written for)."""
        return all(isinstance(s, Segment) for s in self.segments)

    @property
    def rest_length(self) -> float:
        """Total undeformed length [m] (a rigid body's: base to tip)."""
        return sum(s.rest_length for s in self.segments)

    @property
    def mass(self) -> float:
        """Total mass [kg]."""
        return sum(s.mass for s in self.segments)

    def structure(self) -> tuple:
        """What the compiled model depends on besides parameter values: each element's
        signature."""
        return tuple(s.signature() for s in self.segments)

    def coordinate_names(self) -> list[str]:
        """The name of each coordinate, e.g. ``"segments[0].l"`` or
        ``"segments[1].twist"``."""
        return [
            f"segments[{i}].{name}"
            for i, s in enumerate(self.segments)
            for name in s.coordinate_names
        ]

    def coordinate_units(self) -> list[str]:
        """The unit of each coordinate (``"m"``, ``"1/m"``; ``""`` for a strain)."""
        return [unit for s in self.segments for unit in s.coordinate_units]

    def rest_configuration(self) -> np.ndarray:
        """The configuration at rest, shape (n,): each segment at its rest length (or
        rest strains), straight unless precurved."""
        parts = [s.rest_configuration() for s in self.segments]
        return np.concatenate(parts)

    def coordinate_scale(self) -> np.ndarray:
        """A positive scale per coordinate, shape (n,): the size of a typical motion
        (``l0`` for a length, ``1/l0`` for a curvature: a 1 rad bend, 1 for a strain)."""
        return np.concatenate([s.coordinate_scale() for s in self.segments])

    def bending_curvature(self, q) -> np.ndarray:
        """Each element's bending curvature ``|kappa|`` [1/m] at configurations ``q``
        (0 for a rigid body), shape (..., N).

        Parameters
        ----------
        q : array_like, shape (..., n)
            Configurations.
        """
        q = np.asarray(q, dtype=np.float64)
        columns = [s.bending_curvature(self.element_coordinates(q, i))
                   for i, s in enumerate(self.segments)]  # fmt: skip
        return np.stack(columns, axis=-1)

    def element_coordinates(self, q, i: int):
        """The coordinates of element ``i`` in ``q[..., n]``.

        Parameters
        ----------
        q : array_like, shape (..., n)
            Configurations.
        i : int
            The element.
        """
        start = self.offsets[i]
        return np.asarray(q)[..., start : start + self.sizes[i]]

    @cached_property
    def rest_lengths(self) -> np.ndarray:
        """Rest length ``l0`` [m] of each element, shape (N,)."""
        lengths = np.array([s.rest_length for s in self.segments])
        lengths.setflags(write=False)
        return lengths

    @cached_property
    def _length_limits(self) -> list[float]:
        return [MAX_STRETCH * s.rest_length for s in self.segments]

    def inside(self, q, rest_lengths=None) -> np.ndarray:
        """Whether configurations lie in the model's domain (every element's rule, every
        entry finite), shape (...). Vectorized: the check run at a simulation's outputs.

        Parameters
        ----------
        q : array_like, shape (..., n)
            Configurations.
        rest_lengths : array_like, shape (N,) or (..., N), optional
            Each element's rest length [m] per configuration where it differs from the
            robot's (the members of a batch).
        """
        q = np.asarray(q, dtype=np.float64)
        rest = self.rest_lengths if rest_lengths is None else np.asarray(rest_lengths)
        if self.constant_curvature:
            return in_domain(q, rest)
        inside = np.all(np.isfinite(q), axis=-1)
        for i, s in enumerate(self.segments):
            if self.sizes[i]:
                inside &= s.inside(self.element_coordinates(q, i), rest[..., i])
        return inside

    def domain_problem(self, q, *, entry: str = "entry", rest_lengths=None) -> str | None:
        """What puts ``q`` (n,) outside the model's domain, naming the coordinate, its
        value and the allowed range; None inside.

        Parameters
        ----------
        q : array_like, shape (n,)
            One configuration.
        entry : str
            How an index into ``q`` is named in the message (e.g. ``"q[3]"``); default
            ``"entry 3"``.
        rest_lengths : array_like, shape (N,), optional
            Each element's rest length [m] where it differs from the robot's.
        """
        q = np.asarray(q, dtype=np.float64)
        rest = self.rest_lengths if rest_lengths is None else np.asarray(rest_lengths)
        place = _place(entry)
        for i, s in enumerate(self.segments):
            start = self.offsets[i]
            problem = s.domain_problem(
                q[start : start + self.sizes[i]],
                i,
                lambda k, start=start: place(start + k),
                rest[i],
            )
            if problem is not None:
                return problem
        return None

    def check_configuration(self, q, name: str = "q0") -> np.ndarray:
        """``q`` as a float64 array of shape (n,), checked to lie in the model's domain.

        The domain, the one check of every configuration a user gives (``simulate``,
        ``simulate_batch``, statics, the compiled model's methods, scenario files): for a
        constant-curvature segment ``0 < l <= MAX_STRETCH * l0`` and a bending angle
        ``|kappa| l <= MAX_BEND`` (2 pi); for a constant-strain segment its stretch,
        bending, twist and shear bounds (:mod:`softcurve.description.elements`); every
        entry finite. Simulations stop where the state leaves it (status
        ``LEFT_DOMAIN``).

        Parameters
        ----------
        q : array_like, shape (n,)
            Coordinates of each element (``(l, kx, ky)`` per constant-curvature segment
            [m, 1/m, 1/m]).
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
        if self.constant_curvature:
            # plain floats: for a few segments ~1 us, several times faster than NumPy's
            # reductions; NaN fails every comparison
            values = q.tolist()
            for i, limit in enumerate(self._length_limits):
                if not segment_inside(*values[3 * i : 3 * i + 3], limit):
                    break
            else:
                return q
        elif self.inside(q):
            return q
        problem = self.domain_problem(q, entry=name)
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
        pick = [i % self.n_segments for i in range(count)]
        spans = None if self.spans is None else self.spans[pick]
        return self.replace(segments=tuple(self.segments[i] for i in pick), spans=spans)
