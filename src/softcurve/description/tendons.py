"""Tendon actuators: from tendon tensions to generalized forces, ``tau = H(q) T``.

A :class:`Tendon` runs parallel to the backbone at distance ``rho`` and azimuth ``phi``
(in each element's base frame, from +x toward +y, like the bellows) through the elements
``0 .. anchor`` of the chain and is tied to the tip of element ``anchor``
(docs/tendons.md, "The model"). In element ``j`` it is an offset fiber
(:mod:`softcurve.description.fibers`): in a constant-curvature segment of length::

    L_j = l_j (1 - rho (kx_j cos phi + ky_j sin phi))

exact and a polynomial in ``q`` (smooth at zero curvature); in a constant-strain segment
``L_j = L0 |v + u x r|`` (a helix when it twists, leaning when it shears); through a
rigid body (a rigid link between soft sections, a gripper) a straight run of constant
length from hole to hole, which does no work. A
tension ``T >= 0`` [N] pulled at the base does the work ``-T dL``, so the tendon
shortens the robot and bends it TOWARD itself (``kx > 0`` for ``phi = 0``)::

    tau = -T sum_j dL_j/dq

Tensions are bounded to ``[t_min, t_max]`` with ``t_min >= 0`` (a tendon cannot push;
slack is tension zero). Without friction the tendon is conservative, of potential
``T L(q)``.

**Friction (optional, off by default).** A tendon pulled through its guides loses
tension along the routing by the capstan (Euler-Eytelwein) law ``T(theta) = T
exp(-mu theta)``, ``theta`` the angle the tendon has turned through since the base;
Kato et al. (IEEE/ASME Trans. Mechatronics 20(5), 2015) validated this tension
propagation on a tendon-driven continuum robot. The offset fiber of an arc is a
concentric arc, so in segment ``j`` the tendon turns through the segment's bending
angle ``beta_j = l_j kappa_j``; in a constant-strain segment through ``L0 |u x t| / |t|``
(``t = v + u x r``, its tangent; the helix's total curvature), in a rigid body not at
all. Because the tension varies along a segment while its
virtual elongation is uniform in the material coordinate, segment ``j`` sees the mean
tension::

    T_j = T exp(-mu Theta_(j-1)) (1 - exp(-mu beta_j)) / (mu beta_j)

with ``Theta_(j-1)`` the angle turned in segments ``0 .. j-1``. The law describes a
tendon being pulled in (loading); friction makes the tendon non-conservative
(:attr:`TendonActuator.conservative` is False). ``|beta|`` has a kink at zero
curvature (Coulomb friction switches on there), so the angle is rounded off as
``sqrt(beta^2 + eps^2) - eps`` with ``eps = Tendon.wrap_smoothing`` [rad], keeping
``tau`` differentiable at a straight robot, as a regularized Coulomb law does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from softcurve.base.deprecation import renamed
from softcurve.base.validation import ParameterError, real_scalar, whole_count
from softcurve.description.actuator import Actuator, chain_elements
from softcurve.description.fibers import offset_fiber_turn

DEFAULT_AZIMUTHS = (0.0, 2.0 * math.pi / 3.0, 4.0 * math.pi / 3.0)
"""Three tendons evenly spaced, measured from +x toward +y [rad]."""

WRAP_SMOOTHING = 1e-3
"""Default rounding of the wrap angle [rad] under friction: below about a milliradian
of bending the friction is shaded off smoothly (1 mrad changes the capstan factor of a
tendon with mu = 0.3 by 3e-4, below what tendon-friction experiments resolve)."""


SERIES_LIMIT = 1e-3
"""Below this ``x`` the mean capstan factor ``(1 - exp(-x)) / x`` is its five-term
series, whose truncation error ``x^5 / 720`` is then under 2e-18 (round-off)."""


def _mean_capstan_factor(x):
    """``(1 - exp(-x)) / x`` (CasADi), exact to round-off for every ``x >= 0`` and smooth
    through ``x = 0``, where it is 1 (the mean of ``exp(-x s)`` over ``s`` in [0, 1])."""
    series = 1 - x / 2 + x**2 / 6 - x**3 / 24 + x**4 / 120
    return ca.if_else(x < SERIES_LIMIT, series, -ca.expm1(-x) / ca.fmax(x, SERIES_LIMIT))


@dataclass(frozen=True)
class Tendon:
    """One tendon routed parallel to the backbone from the base to a segment's tip.

    Parameters
    ----------
    azimuth : float
        Angle ``phi`` [rad] of the tendon in each segment's cross-section, from +x
        toward +y.
    distance : float
        ``rho`` [m], > 0, from the backbone to the tendon.
    t_max : float
        Upper tension bound [N], > t_min.
    t_min : float
        Lower tension bound [N], >= 0 (a pretension; default 0, a slack tendon).
    anchor : int
        Index of the element at whose tip the tendon is tied; it runs through elements
        ``0 .. anchor`` (default 0, the first segment only), rigid bodies included.
    friction : float
        Capstan friction coefficient ``mu`` >= 0 of the routing, dimensionless (default
        0: none).
    wrap_smoothing : float
        Rounding ``eps`` [rad] > 0 of the wrap angle under friction (module docstring).
    """

    azimuth: float
    distance: float
    t_max: float
    t_min: float = 0.0
    anchor: int = 0
    friction: float = 0.0
    wrap_smoothing: float = WRAP_SMOOTHING

    def __post_init__(self):
        set_ = object.__setattr__  # frozen dataclass: normalize fields once here
        set_(self, "azimuth", real_scalar("Tendon.azimuth", self.azimuth))
        set_(self, "distance", real_scalar("Tendon.distance", self.distance, positive=True))
        t_min = real_scalar("Tendon.t_min", self.t_min)
        if t_min < 0:
            raise ParameterError(
                f"Tendon.t_min must be >= 0 N (a tendon cannot push), got {t_min!r}"
            )
        t_max = real_scalar("Tendon.t_max", self.t_max)
        if not t_max > t_min:
            raise ParameterError(f"Tendon.t_max must be > t_min = {t_min!r} N, got {t_max!r}")
        set_(self, "t_min", t_min)
        set_(self, "t_max", t_max)
        set_(self, "anchor", whole_count("Tendon.anchor", self.anchor, 0))
        friction = real_scalar("Tendon.friction", self.friction)
        if friction < 0:
            raise ParameterError(f"Tendon.friction must be >= 0, got {friction!r}")
        set_(self, "friction", friction)
        set_(
            self,
            "wrap_smoothing",
            real_scalar("Tendon.wrap_smoothing", self.wrap_smoothing, positive=True),
        )

    @property
    def segments(self) -> tuple[int, ...]:
        """Indices of the segments the tendon runs through, ``0 .. anchor``."""
        return tuple(range(self.anchor + 1))


@dataclass(frozen=True, eq=False)
class TendonActuator(Actuator):
    """Tendons whose ``H(q)`` follows from the virtual work of their tensions.

    Parameters
    ----------
    tendons : sequence of Tendon
        The tendons, in the order of the tension vector.
    n_segments : int, optional
        Number of constant-curvature segments of the robot driven (``n = 3 n_segments``,
        default 1); every ``Tendon.anchor`` must be below it. Leave it out with
        ``elements``.
    time_constant : float or None
        First-order lag of the tensions behind their commands [s], or None.
    elements : Robot or sequence of elements, optional
        The robot (or its ``segments``) the tendons run along, for a chain of other
        elements than constant-curvature segments (constant strain, rigid bodies): its
        elements give the coordinates and each fiber's length. None (default):
        ``n_segments`` constant-curvature segments.

    Examples
    --------
    >>> import numpy as np
    >>> import softcurve as sc
    >>> tendon = sc.Tendon(azimuth=0.0, distance=0.01, t_max=10.0)
    >>> actuator = sc.TendonActuator([tendon])
    >>> actuator.tendon_lengths([0.2, 0.0, 0.0])  # straight: the segment's length [m]
    array([0.2])
    >>> actuator.generalized_force([0.2, 0.0, 0.0], [2.0])  # shortens, bends toward +x
    array([-2.   ,  0.004,  0.   ])
    """

    tendons: tuple[Tendon, ...]
    n_segments: int | None = None
    time_constant: float | None = None
    elements: tuple | None = None
    input_name = "tensions"
    input_unit = "N"
    _parts_field = "tendons"
    _fiber_kind = "tendon"
    _part_parameters = ("azimuth", "distance", "friction")

    def __post_init__(self):
        def beyond(tendon, n_segments):
            if tendon.anchor < n_segments:
                return None
            return (
                f"anchor = {tendon.anchor} is beyond the robot's last segment "
                f"(n_segments = {n_segments}, anchors 0 .. {n_segments - 1})"
            )

        self._init_parts(Tendon, beyond, ("t_min", "t_max"))

    @classmethod
    def three_per_segment(
        cls,
        *,
        distance: float,
        t_max: float,
        t_min: float = 0.0,
        n_segments: int | None = None,
        azimuths=DEFAULT_AZIMUTHS,
        friction: float = 0.0,
        time_constant: float | None = None,
        elements=None,
    ) -> TendonActuator:
        """Identical tendons at ``azimuths``, one set tied to the tip of every segment
        (``len(azimuths) N`` tensions, proximal set first); a distal set runs through
        every element before its anchor. With ``elements``, a set per soft segment (none
        tied to a rigid body).

        Parameters
        ----------
        distance : float
            ``rho`` [m] of every tendon.
        t_max, t_min : float
            Tension bounds [N].
        n_segments : int, optional
            Number of constant-curvature segments (default 1); each gets its own
            tendons. Leave it out with ``elements``.
        azimuths : sequence of float
            Azimuths [rad] of the tendons of each set.
        friction : float
            Capstan friction coefficient ``mu`` >= 0 of every tendon, dimensionless.
        time_constant : float or None
            First-order tension lag [s], or None.
        elements : Robot or sequence of elements, optional
            The chain the tendons run along (see :class:`TendonActuator`).
        """
        if np.ndim(azimuths) != 1 or not len(azimuths):
            raise ParameterError(f"azimuths must be a sequence of angles [rad], got {azimuths!r}")
        angles = [real_scalar(f"azimuths[{i}]", phi) for i, phi in enumerate(azimuths)]
        chain = chain_elements(elements)
        if chain is None:
            anchors = range(whole_count("n_segments", 1 if n_segments is None else n_segments))
        else:
            anchors = [k for k, e in enumerate(chain) if e.n_coordinates]
        tendons = tuple(
            Tendon(phi, distance, t_max, t_min, k, friction) for k in anchors for phi in angles
        )
        return cls(tendons, n_segments, time_constant, chain)

    @property
    def conservative(self) -> bool:
        """True without friction: the tensions' work is ``-T . L(q)``."""
        return all(t.friction == 0 for t in self.tendons)

    # -- symbolic --------------------------------------------------------------------
    def tension_factors_symbolic(self, q, theta=None) -> list[list]:
        """Mean tension in segment ``j`` per unit tension at the base (capstan law, module
        docstring); exactly 1 for a tendon without friction.

        Parameters
        ----------
        q : casadi.SX or casadi.MX, shape (n,)
            Generalized coordinates.
        theta : casadi.SX or casadi.MX, shape (3 m,), optional
            ``(azimuth, distance, friction)`` of each tendon, replacing their values.
        """
        factors = []
        for i, tendon in enumerate(self.tendons):
            phi, rho, mu = self._part_values(i, theta)
            if theta is None and tendon.friction == 0:
                factors.append([1] * len(tendon.segments))
                continue
            eps, turned, row = tendon.wrap_smoothing, 0, []
            for j in tendon.segments:
                squared = offset_fiber_turn(q, j, phi, rho, **self._place(j))
                beta = ca.sqrt(squared + eps**2) - eps
                # (1 - exp(-x)) / x, written with expm1 so that it stays exact as x -> 0
                row.append(ca.exp(-mu * turned) * _mean_capstan_factor(mu * beta))
                turned = turned + beta
            factors.append(row)
        return factors

    def input_matrix_symbolic(self, q, theta=None):
        factors = self.tension_factors_symbolic(q, theta)
        weights = [[-factor for factor in row] for row in factors]
        return self._fiber_matrix_symbolic(q, theta, weights)

    def input_work_symbolic(self, q, inputs):
        # Without friction exact: dW/dq = H(q) T. With friction there is no potential;
        # this is the frictionless work, used only to order equilibria.
        return -ca.dot(inputs, self.fiber_lengths_symbolic(q))

    # -- numeric ---------------------------------------------------------------------
    tendon_lengths_symbolic = renamed(Actuator.fiber_lengths_symbolic, "tendon_lengths_symbolic")

    def tendon_lengths(self, q) -> np.ndarray:
        """Lengths ``L_i(q)`` (m,) [m] of the tendons from the base to their anchors.

        Parameters
        ----------
        q : array_like, shape (n,)
            Generalized coordinates.
        """
        q = self._coordinates(q)
        return np.array(ca.DM(self.fiber_lengths_symbolic(ca.DM(q)))).ravel()
