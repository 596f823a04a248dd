"""Pneumatic actuators: from chamber pressures to generalized forces, ``tau = H(q) p``.

Both implement :class:`~softcurve.description.actuator.Actuator` (the inputs ``u`` are
the gauge pressures ``p``):

- :class:`PneumaticActuator`, a set of :class:`Bellows`, derives ``H(q)`` from the
  virtual work of the chamber pressures (docs/control.md, "Pneumatic actuation"). A bellow
  at azimuth ``phi`` (from +x toward +y in the segment's cross-section) and distance
  ``rho`` from the backbone is an offset fiber (:mod:`softcurve.description.fibers`): of
  the constant-curvature arc, of length ``L = l (1 - rho (kx cos phi + ky sin phi))``; of
  a constant-strain segment, ``L = L0 |v + u x r|``. Its volume is ``V = A L`` and a
  gauge pressure ``p`` does the work ``p dV``, so ``tau = sum_i p_i A_i dL_i/dq``; for
  constant curvature::

      dL/dl  = 1 - rho (kx cos phi + ky sin phi)
      dL/dkx = -l rho cos phi
      dL/dky = -l rho sin phi

  A pressurized bellow lengthens the robot and bends it AWAY from itself (the bellow
  at ``phi = 0`` pushes ``kx`` negative). The offset fiber has positive length while
  ``rho kappa < 1``.
- :class:`ConstantPressureMap` is a user-given constant ``H`` (``n x m``), e.g. the
  authors' fitted form (:meth:`ConstantPressureMap.authors_fit`).

A bellow acts on the segments in ``Bellows.segments``; pressures are gauge pressures
[Pa] within ``[p_min, p_max]``, with an optional first-order lag (docs/control.md).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from softcurve.base.validation import ParameterError, real_array, real_scalar
from softcurve.description.actuator import (
    Actuator,
    chain_elements,
    optional_time_constant,
)

ATMOSPHERIC_PRESSURE = 101325.0
"""Standard atmosphere [Pa]: no gauge pressure can be below ``-ATMOSPHERIC_PRESSURE``."""

DEFAULT_AZIMUTHS = (0.0, 2.0 * math.pi / 3.0, 4.0 * math.pi / 3.0)
"""Three bellows evenly spaced, measured from +x toward +y [rad]."""


def _bounds(name: str, p_min: float, p_max: float) -> tuple[float, float]:
    p_min = real_scalar(f"{name}.p_min", p_min)
    p_max = real_scalar(f"{name}.p_max", p_max)
    if p_min < -ATMOSPHERIC_PRESSURE:
        raise ParameterError(
            f"{name}.p_min must be >= -{ATMOSPHERIC_PRESSURE:g} Pa (absolute vacuum, gauge), "
            f"got {p_min!r}"
        )
    if not p_max > p_min:
        raise ParameterError(f"{name}.p_max must be > p_min = {p_min!r}, got {p_max!r}")
    return p_min, p_max


@dataclass(frozen=True)
class Bellows:
    """One pneumatic chamber parallel to the backbone.

    Parameters
    ----------
    azimuth : float
        Angle ``phi`` [rad] of the chamber's center line in the cross-section, from +x
        toward +y.
    distance : float
        ``rho`` [m], > 0, from the backbone to the chamber's center line.
    area : float
        Effective cross-section ``A`` [m^2], > 0.
    p_max : float
        Upper pressure bound [Pa, gauge], > p_min.
    p_min : float
        Lower pressure bound [Pa, gauge], default 0; negative only for vacuum actuation,
        never below ``-ATMOSPHERIC_PRESSURE``.
    segments : tuple of int
        Indices of the segments the chamber runs through (default ``(0,)``); soft
        segments only (a rigid body holds no chamber).
    """

    azimuth: float
    distance: float
    area: float
    p_max: float
    p_min: float = 0.0
    segments: tuple[int, ...] = (0,)

    def __post_init__(self):
        object.__setattr__(self, "azimuth", real_scalar("azimuth", self.azimuth))
        object.__setattr__(self, "distance", real_scalar("distance", self.distance, positive=True))
        object.__setattr__(self, "area", real_scalar("area", self.area, positive=True))
        p_min, p_max = _bounds("bellows", self.p_min, self.p_max)
        object.__setattr__(self, "p_min", p_min)
        object.__setattr__(self, "p_max", p_max)
        segments = self.segments
        if isinstance(segments, int | np.integer) and not isinstance(segments, bool):
            segments = (segments,)
        try:
            segments = tuple(segments)
        except TypeError:
            raise ParameterError(
                f"segments must be a tuple of ints, got {self.segments!r}"
            ) from None
        if not segments or not all(
            isinstance(j, int | np.integer) and not isinstance(j, bool) and j >= 0 for j in segments
        ):
            raise ParameterError(
                f"segments must be a non-empty tuple of segment indices >= 0, got {self.segments!r}"
            )
        if len(set(segments)) != len(segments):
            raise ParameterError(f"segments must not repeat an index, got {self.segments!r}")
        object.__setattr__(self, "segments", tuple(int(j) for j in segments))


@dataclass(frozen=True, eq=False)
class PneumaticActuator(Actuator):
    """Bellows whose ``H(q)`` follows from the virtual work of their pressures.

    Parameters
    ----------
    bellows : sequence of Bellows
        The chambers, in the order of the pressure vector.
    n_segments : int, optional
        Number of constant-curvature segments of the robot driven (``n = 3
        n_segments``, default 1); every ``Bellows.segments`` index must be below it.
        Leave it out with ``elements``.
    time_constant : float or None
        First-order pressure lag [s], or None.
    elements : Robot or sequence of elements, optional
        The robot (or its ``segments``) the chambers lie in, for a chain of other
        elements than constant-curvature segments: its elements give the coordinates and
        each chamber's length. None (default): ``n_segments`` constant-curvature
        segments.
    """

    bellows: tuple[Bellows, ...]
    n_segments: int | None = None
    time_constant: float | None = None
    elements: tuple | None = None
    input_name = "pressures"
    input_unit = "Pa"
    _parts_field = "bellows"
    _fiber_kind = "chamber"
    _part_parameters = ("azimuth", "distance", "area")

    def __post_init__(self):
        def beyond(chamber, n_segments):
            if max(chamber.segments) < n_segments:
                return None
            return (
                f"segments = {chamber.segments} refers to a segment beyond "
                f"n_segments = {n_segments}"
            )

        self._init_parts(Bellows, beyond, ("p_min", "p_max"))
        for i, chamber in enumerate(self.bellows):
            for j in chamber.segments:
                if self.elements is not None and not self.elements[j].n_coordinates:
                    raise ParameterError(
                        f"bellows[{i}].segments = {chamber.segments} holds element {j}, a "
                        f"{type(self.elements[j]).__name__}: a chamber lies in a soft segment"
                    )

    @classmethod
    def three_bellows(
        cls,
        *,
        distance: float,
        area: float,
        p_max: float,
        p_min: float = 0.0,
        n_segments: int | None = None,
        azimuths=DEFAULT_AZIMUTHS,
        time_constant: float | None = None,
        elements=None,
    ) -> PneumaticActuator:
        """Identical bellows at ``azimuths`` in every segment (3 N pressures, segment by
        segment), each acting on its own segment; with ``elements``, in every soft
        segment.

        Parameters
        ----------
        distance : float
            ``rho`` [m] of every bellow (see :class:`Bellows`).
        area : float
            Effective cross-section of every bellow [m^2].
        p_max, p_min : float
            Pressure bounds [Pa, gauge].
        n_segments : int, optional
            Number of constant-curvature segments (default 1); each gets its own
            bellows. Leave it out with ``elements``.
        azimuths : sequence of float
            Azimuths [rad] of the bellows in each segment.
        time_constant : float or None
            First-order pressure lag [s], or None.
        elements : Robot or sequence of elements, optional
            The chain (see :class:`PneumaticActuator`).
        """
        chain = chain_elements(elements)
        if chain is None:
            soft = range(1 if n_segments is None else n_segments)
        else:
            soft = [j for j, e in enumerate(chain) if e.n_coordinates]
        bellows = tuple(
            Bellows(float(phi), distance, area, p_max, p_min, (j,))
            for j in soft
            for phi in azimuths
        )
        return cls(bellows, n_segments, time_constant, chain)

    def input_work_symbolic(self, q, inputs):
        areas = ca.DM([b.area for b in self.bellows])
        return ca.dot(inputs * areas, self.fiber_lengths_symbolic(q))

    def volumes(self, q) -> np.ndarray:
        """Chamber volumes ``V_i = A_i L_i(q)`` (m,) [m^3].

        Parameters
        ----------
        q : array_like, shape (n,)
            Generalized coordinates.
        """
        q = self._coordinates(q)
        lengths = np.array(ca.DM(self.fiber_lengths_symbolic(ca.DM(q)))).ravel()
        return np.array([b.area for b in self.bellows]) * lengths

    def input_matrix_symbolic(self, q, theta=None):
        areas = [self._part_values(i, theta)[2] for i in range(self.n_inputs)]
        weights = [[area] * len(b.segments) for area, b in zip(areas, self.bellows, strict=True)]
        return self._fiber_matrix_symbolic(q, theta, weights)


@dataclass(frozen=True, eq=False)
class ConstantPressureMap(Actuator):
    """A constant ``H`` (n x m) [N/Pa and N m^2/Pa], e.g. identified from experiments.

    Parameters
    ----------
    constant : array_like, shape (n, m)
        ``H``: ``tau = H p`` in every configuration; ``n`` must be a multiple of 3.
    p_max : float or array_like, shape (m,)
        Upper pressure bounds [Pa, gauge].
    p_min : float or array_like, shape (m,)
        Lower pressure bounds [Pa, gauge], default 0 (see :class:`Bellows`).
    time_constant : float or None
        First-order pressure lag [s], or None.
    """

    constant: np.ndarray
    p_max: float | np.ndarray
    p_min: float | np.ndarray = 0.0
    time_constant: float | None = None
    input_name = "pressures"
    input_unit = "Pa"

    def __post_init__(self):
        h = np.asarray(self.constant, dtype=np.float64) if not np.isscalar(self.constant) else None
        if h is None or h.ndim != 2 or h.shape[0] % 3 or 0 in h.shape:
            raise ParameterError(
                "matrix must be a 2-D array with 3 N rows (N segments) and one column per "
                f"pressure, got {np.shape(self.constant)}"
            )
        h = real_array("matrix", h, h.shape)
        m = h.shape[1]
        lower = np.broadcast_to(np.asarray(self.p_min, dtype=np.float64), (m,))
        upper = np.broadcast_to(np.asarray(self.p_max, dtype=np.float64), (m,))
        for i in range(m):
            _bounds(f"pressure[{i}]", lower[i], upper[i])
        object.__setattr__(self, "constant", h)
        object.__setattr__(self, "time_constant", optional_time_constant(self.time_constant))
        object.__setattr__(self, "n", h.shape[0])
        object.__setattr__(self, "n_inputs", m)
        object.__setattr__(self, "lower", real_array("p_min", lower, (m,)))
        object.__setattr__(self, "upper", real_array("p_max", upper, (m,)))

    @classmethod
    def authors_fit(
        cls,
        *,
        a_e: float = 2.34e-7,
        a_k: float = 1.6e-8,
        p_max: float,
        p_min: float = 0.0,
        azimuths=DEFAULT_AZIMUTHS,
        time_constant: float | None = None,
    ) -> ConstantPressureMap:
        """The authors' fitted form ``H = [[a_e]*3, [a_k sin phi_i], [-a_k cos phi_i]]``.

        Defaults are their values for their 17 g robot (pressures in Pa). In softcurve's
        convention this is the bending direction of bellows at azimuths ``phi_i + pi/2``.

        Parameters
        ----------
        a_e : float
            Elongation gain [N/Pa].
        a_k : float
            Bending gain [N m^2/Pa].
        p_max, p_min : float
            Pressure bounds [Pa, gauge].
        azimuths : sequence of float
            ``phi_i`` [rad], one per pressure.
        time_constant : float or None
            First-order pressure lag [s], or None.
        """
        a_e, a_k = real_scalar("a_e", a_e), real_scalar("a_k", a_k)
        phi = np.asarray(azimuths, dtype=np.float64)
        h = np.vstack([np.full_like(phi, a_e), a_k * np.sin(phi), -a_k * np.cos(phi)])
        return cls(h, p_max=p_max, p_min=p_min, time_constant=time_constant)

    def parameter_vector(self) -> np.ndarray:
        return self.constant.ravel().copy()

    def parameter_names(self) -> list[str]:
        return [f"matrix[{i},{j}]" for i in range(self.n) for j in range(self.n_inputs)]

    def _rebuilt(self, vector: np.ndarray) -> ConstantPressureMap:
        return dataclasses.replace(self, constant=vector.reshape(self.n, self.n_inputs))

    def input_work_symbolic(self, q, inputs):
        return ca.dot(q, ca.DM(self.constant) @ inputs)

    def input_matrix_symbolic(self, q, theta=None):
        if theta is None:
            return ca.DM(self.constant)
        return ca.reshape(theta, self.n_inputs, self.n).T
