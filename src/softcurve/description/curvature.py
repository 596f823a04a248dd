"""The constant-curvature segment, the paper's element: coordinates ``(l, kx, ky)``.

At material coordinate ``s`` in [0, 1] the frame is the rotation ``exp([w]x)`` with
rotation vector ``w = s l (-ky, kx, 0)`` (eq. 3 of the paper) and the position is
``s l Jl(w) e_z`` (eq. 4), ``Jl`` the left Jacobian of SO(3). The body angular velocity
is ``Jr(w) dw/dt``: the exact time derivative of the pose at a fixed material point
(docs/model.md, "Kinematics"), not the paper's eq. (10). It is the constant-strain
segment of strains (bend x, bend y, stretch) in other coordinates
(:class:`~softcurve.StrainSegment`), with the paper's energy: the stiffness laws act on
the elongation ``l - l0`` and the bending angle ``kappa l``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from softcurve.base.validation import FLOAT_MAX, ParameterError, real_scalar
from softcurve.description.kind import (
    E_Z,
    Element,
    Margin,
    SoftModel,
    check_creep,
    creep_fields,
    creep_of,
    damping_matrix,
    element_parameters,
    failed,
    finite_problem,
    law_field,
    margins_hold,
    matrix_field,
    scalar_field,
)
from softcurve.description.materials import (
    LAW_UNITS,
    STIFFNESS_LAWS,
    Creep,
    LinearStiffness,
    TanhStiffness,
)

StiffnessLaw = LinearStiffness | TanhStiffness

COORDINATES = ("l", "kx", "ky")
UNITS = ("m", "1/m", "1/m")
DAMPING_UNITS = (
    "N s/m",
    "N m s",
    "N m s",
    "N m s",
    "N m^3 s",
    "N m^3 s",
    "N m s",
    "N m^3 s",
    "N m^3 s",
)
"""Units of a damping matrix's entries, row by row: generalized force [N, N m^2, N m^2]
per coordinate rate [m/s, 1/(m s), 1/(m s)]."""

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


def curvature_margins(length, kx, ky, longest) -> list[Margin]:
    """The domain's rule for one segment's coordinates, written once: ``0 < l <=
    longest`` and a bending angle ``l |kappa| <= MAX_BEND``, as margins (squared: no
    square root, exact at zero curvature). Arithmetic alone, so floats, NumPy arrays
    (elementwise) and CasADi symbols all take it: the Python rule and the compiled
    model's ``domain`` Function (:class:`CurvatureModel`) evaluate the same expression.

    Parameters
    ----------
    length, kx, ky : float, ndarray or casadi.SX
        The segment's length [m] and curvatures [1/m].
    longest : float, ndarray or casadi.SX
        The longest length in the domain, ``MAX_STRETCH l0`` [m].
    """
    return [
        Margin("length", length, strict=True),
        Margin("length", longest - length),
        Margin("bend", MAX_BEND * MAX_BEND - length * length * (kx * kx + ky * ky)),
    ]


def segment_inside(length, kx, ky, longest):
    """Whether one segment's coordinates lie in the domain (:func:`curvature_margins`;
    NaN fails): on floats, or elementwise on arrays.

    Parameters
    ----------
    length, kx, ky : float or ndarray
        The segment's length [m] and curvatures [1/m].
    longest : float or ndarray
        The longest length in the domain, ``MAX_STRETCH l0`` [m].
    """
    return margins_hold(curvature_margins(length, kx, ky, longest))


def segment_problem(q, rest_length: float, index: int, place) -> str | None:
    """What puts one segment's ``q = (l, kx, ky)`` outside the domain (see
    :func:`curvature_margins`), naming the coordinate, its value and the allowed range;
    None inside.

    Parameters
    ----------
    q : array_like, shape (3,)
        The segment's coordinates [m, 1/m, 1/m].
    rest_length : float
        Its rest length ``l0`` [m].
    index : int
        The segment's position in the chain (0 first).
    place : callable
        ``place(k)`` names entry ``k`` of the segment's coordinates (e.g. ``"q[3]"``).
    """
    length, kx, ky = (float(v) for v in q)
    problem = finite_problem((length, kx, ky), COORDINATES, index, place)
    if problem is not None:
        return problem
    longest = MAX_STRETCH * rest_length
    with np.errstate(over="ignore", invalid="ignore"):
        margins = curvature_margins(np.float64(length), kx, ky, longest)
    if failed(margins, "length"):
        return (
            f"lengths l must be in the model's domain 0 < l <= {MAX_STRETCH:g} rest lengths "
            f"({longest:.6g} m): l of segment {index + 1} ({place(0)}) = {length:.6g} m"
        )
    if failed(margins, "bend"):
        bend = length * math.hypot(kx, ky)
        return (
            f"bending angles |kappa| l must be <= 2 pi rad (a full turn, the model's "
            f"domain): segment {index + 1} bends {bend:.6g} rad (l = {length:.6g} m, "
            f"kx = {kx:.6g} 1/m, ky = {ky:.6g} 1/m)"
        )
    return None


@dataclass(frozen=True, eq=False)
class Segment(Element):
    """One constant-curvature segment: coordinates ``(l, kx, ky)``, the paper's model.

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
        object.__setattr__(self, "damping", damping_matrix(self.damping, self.coordinate_names))
        check_creep(self.creep, self.coordinate_names, "coordinate")

    kind = "constant_curvature"

    def signature(self) -> tuple:
        """``("constant_curvature", elongation law kind, bending law kind, has creep)``."""
        return (
            self.kind,
            self.elongation_stiffness.kind,
            self.bending_stiffness.kind,
            self.creep is not None,
        )

    @property
    def coordinate_names(self) -> tuple[str, ...]:
        """``("l", "kx", "ky")``."""
        return COORDINATES

    @property
    def coordinate_units(self) -> tuple[str, ...]:
        """``("m", "1/m", "1/m")``."""
        return UNITS

    def rest_configuration(self) -> np.ndarray:
        """``(l0, 0, 0)``."""
        return np.array([self.rest_length, 0.0, 0.0])

    def coordinate_scale(self) -> np.ndarray:
        """``(l0, 1/l0, 1/l0)``: a length and a 1 rad bend."""
        return np.array([self.rest_length, 1.0 / self.rest_length, 1.0 / self.rest_length])

    extent_index = 0

    planar_pairs = ((1, 2, (1.0, 0.0)),)
    """``(kx, ky)`` turns with the robot; a representative bends toward +x."""

    @element_parameters
    def bent_toward(self, q, curvature: float, azimuth: float) -> np.ndarray:
        """``(kx, ky) = curvature (cos azimuth, sin azimuth)``.

        Parameters
        ----------
        %(q)s
        %(curvature)s
        %(azimuth)s
        """
        q = np.array(q, dtype=np.float64)
        q[1:3] = curvature * np.cos(azimuth), curvature * np.sin(azimuth)
        return q

    @element_parameters
    def bending_curvature(self, q) -> np.ndarray:
        """``hypot(kx, ky)``.

        Parameters
        ----------
        %(q)s
        """
        q = np.asarray(q, dtype=np.float64)
        return np.hypot(q[..., 1], q[..., 2])

    def search_bounds(self) -> np.ndarray:
        """``l`` in ``[0.5, 1.5] l0`` and ``|kx|, |ky| <= pi / l0`` (bending angles up to
        half a turn)."""
        k = np.pi / self.rest_length
        return np.array([(0.5 * self.rest_length, 1.5 * self.rest_length), (-k, k), (-k, k)])

    def inside(self, q, rest_length=None) -> np.ndarray:
        q = np.asarray(q, dtype=np.float64)
        rest = self.rest_length if rest_length is None else np.asarray(rest_length)
        with np.errstate(invalid="ignore", over="ignore"):
            return segment_inside(q[..., 0], q[..., 1], q[..., 2], MAX_STRETCH * rest)

    def domain_problem(self, q, index: int, place, rest_length=None) -> str | None:
        rest = self.rest_length if rest_length is None else float(rest_length)
        return segment_problem(q, rest, index, place)

    def with_values(self, values: dict) -> Segment:
        creep = None if self.creep is None else creep_of(values)
        laws = {
            mode: type(getattr(self, mode))(*values[mode])
            for mode in ("elongation_stiffness", "bending_stiffness")
        }
        scalars = {n: float(values[n]) for n in ("rest_length", "mass", "radius")}
        return self.replace(**scalars, damping=values["damping"], creep=creep, **laws)


class CurvatureModel(SoftModel):
    """The symbolic constant-curvature segment of a signature ``("constant_curvature",
    elongation law kind, bending law kind, has creep)``; geometry ``(mass, radius)``."""

    def __init__(self, signature: tuple):
        _, self.elongation, self.bending, has_creep = signature
        self.signature = signature
        self.nq = 3
        self.n_creep = 3 if has_creep else 0

    def fields(self):
        specs = [
            scalar_field("rest_length", "m"),
            scalar_field("mass", "kg"),
            scalar_field("radius", "m"),
            law_field("elongation_stiffness", self.elongation, LAW_UNITS["elongation_stiffness"]),
            law_field("bending_stiffness", self.bending, LAW_UNITS["bending_stiffness"]),
            matrix_field("damping", 3, DAMPING_UNITS),
        ]
        return specs + (creep_fields(3) if self.n_creep else [])

    def geometry(self, part):
        return ca.vertcat(part["mass"], part["radius"])

    def domain_margins(self, q, part):
        return curvature_margins(q[0], q[1], q[2], MAX_STRETCH * part["rest_length"])

    def rotation_vector(self, q, s, g):
        return s * q[0] * ca.vertcat(-q[2], q[1], 0)

    def translation(self, q, s, g):
        return s * q[0] * ca.DM(E_Z)

    def mass(self, g):
        return g[0]

    def slice_inertia(self, g):
        return g[1] ** 2 * ca.DM([0.25, 0.25, 0.5])

    def elastic(self, q, part):
        """The paper's energy ``int k_e(x) x dx + int k_b(x) x dx`` over the elongation
        and the bending angle, and its gradient in closed form: ``beta dbeta/dq =
        d(beta^2)/dq / 2 = (l kappa^2, l^2 kx, l^2 ky)``, smooth at zero curvature where
        ``beta`` itself is not."""
        length, kx, ky = q[0], q[1], q[2]
        eps = length - part["rest_length"]
        kappa2 = kx**2 + ky**2
        beta2 = length**2 * kappa2
        k_e = STIFFNESS_LAWS[self.elongation]
        k_b = STIFFNESS_LAWS[self.bending]
        elongation, bending = part["elongation_stiffness"], part["bending_stiffness"]
        kb = k_b.coefficient(beta2, bending)
        force = ca.vertcat(
            k_e.coefficient(eps**2, elongation) * eps + kb * length * kappa2,
            kb * length**2 * kx,
            kb * length**2 * ky,
        )
        energy = k_e.energy(eps**2, elongation) + k_b.energy(beta2, bending)
        return energy, force
