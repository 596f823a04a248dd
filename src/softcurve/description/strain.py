"""The constant-strain segment (piecewise constant strain, PCS): a segment that chooses
any subset of the six Cosserat strains, each constant along it.

A segment of reference length ``L0`` carries the strain twist ``xi = (u, v)`` in its body
frame (``z`` along the backbone): ``u = (u_x, u_y, u_z)`` the angular strain [1/m]
(bending about x, bending about y, twist), ``v = (v_x, v_y, v_z)`` the linear strain [-]
(shear along x, shear along y, stretch). Its coordinates are the strains it chooses,
in that order; the others stay at their rest values ``xi*`` (default ``(0, 0, 0, 0, 0,
1)``, a straight unstretched rod; others make a precurved or pretwisted segment). The
pose of material point ``X = s L0`` is ``exp(X xi^)``, the SE(3) exponential in closed
form: rotation ``exp(X [u]x)``, position ``Jl(X u) X v``.

Energy: each group of strains (bending, torsion, shear, stretch) has a stiffness law
``k(x)`` on the magnitude ``e`` of its deviation from rest (``|(u_x, u_y) - (u*_x,
u*_y)|`` for bending, ``|u_z - u*_z|`` for torsion, ``|(v_x, v_y) - (v*_x, v*_y)|``
for shear, ``|v_z - v*_z|`` for stretch), ``V_e = L0 int_0^e k(x) x dx``: for linear laws
``V_e = 1/2 int_0^L0 (xi - xi*)^T K (xi - xi*) dX`` with ``K = diag(EI, EI, GJ, kGA,
kGA, EA)`` (:func:`~softcurve.section_properties` gives them from a material and a
section). The strains (bend x, bend y, stretch) with ``xi* = (0, 0, 0, 0, 0, 1)`` are
the constant-curvature segment in other coordinates: ``u = sigma (-ky, kx, 0)``,
``v = (0, 0, sigma)``, ``sigma = l / L0``, and its laws map as ``k_b = EI / L0``,
``k_e = EA / L0`` (``tests/test_strains.py`` checks the two against each other).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from softcurve.base.validation import ParameterError, real_array, real_scalar
from softcurve.description.curvature import MAX_BEND, MAX_REST_LENGTH, MAX_STRETCH
from softcurve.description.kind import (
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
    vector_field,
)
from softcurve.description.materials import STIFFNESS_LAWS, Creep, LinearStiffness, TanhStiffness
from softcurve.description.sections import section_properties

STRAINS = ("bend_x", "bend_y", "twist", "shear_x", "shear_y", "stretch")
"""The six Cosserat strains in their order in ``xi = (u, v)``."""

STRAIN_UNITS = ("1/m", "1/m", "1/m", "", "", "")
"""Units of the strains (``""``: dimensionless)."""

REST_STRAIN = (0.0, 0.0, 0.0, 0.0, 0.0, 1.0)
"""The straight, unstretched rod."""

GROUPS = {
    "bending_stiffness": (0, 1),
    "torsion_stiffness": (2,),
    "shear_stiffness": (3, 4),
    "stretch_stiffness": (5,),
}
"""Each stiffness law's strains (indices into :data:`STRAINS`)."""

_GROUP_UNITS = {
    "bending_stiffness": {"stiffness": "N m^2", "1/strain": "m"},
    "torsion_stiffness": {"stiffness": "N m^2", "1/strain": "m"},
    "shear_stiffness": {"stiffness": "N", "1/strain": ""},
    "stretch_stiffness": {"stiffness": "N", "1/strain": ""},
}
_FORCE_UNITS = ("N m^2", "N m^2", "N m^2", "N", "N", "N")
_DAMPING_UNITS = {
    ("N m^2", "1/m"): "N m^3 s",
    ("N m^2", ""): "N m^2 s",
    ("N", "1/m"): "N m s",
    ("N", ""): "N s",
}

TRIANGLE = 1.0 + 1e-12
"""Slack of the triangle inequality of principal moments ``I_1 <= I_2 + I_3``, relative:
a thin section's moments meet it with equality (``2 I = I + I``), up to round-off."""

MAX_TWIST = 2.0 * math.pi
"""Largest twist angle ``|u_z| L0`` of a segment [rad] in the model's domain: a full turn,
as :data:`MAX_BEND` for bending (the quadrature's accuracy is the same)."""

MAX_SHEAR = 1.0
"""Largest shear ``|(v_x, v_y)|`` relative to the stretch ``v_z``: the backbone then runs
at 45 degrees to the sections' normal. Timoshenko's shear model is for small shear
angles (a thick soft segment shears by a few degrees, a quarter of its deflection at
most); a state beyond it is a runaway, as a segment stretched beyond
:data:`MAX_STRETCH`."""


def strain_margins(xi, rest_length) -> list[Margin]:
    """The domain's rule for a full strain, written once: stretch ``0 < v_z <=
    MAX_STRETCH``, bending angle ``L0 |(u_x, u_y)| <= MAX_BEND``, twist angle ``L0 |u_z|
    <= MAX_TWIST``, shear ``|(v_x, v_y)| <= MAX_SHEAR v_z``, as margins (squared where
    a norm is bounded: no square root). Arithmetic alone, so floats, NumPy arrays
    (elementwise) and CasADi symbols all take it: the Python rule and the compiled
    model's ``domain`` Function (:class:`StrainModel`) evaluate the same expression.

    Parameters
    ----------
    xi : sequence of 6 (float, ndarray or casadi.SX)
        ``(u_x, u_y, u_z, v_x, v_y, v_z)``, chosen strains and rest values.
    rest_length : float, ndarray or casadi.SX
        ``L0`` [m].
    """
    ux, uy, uz, vx, vy, vz = xi
    bend_x, bend_y, twist = rest_length * ux, rest_length * uy, rest_length * uz
    shear = MAX_SHEAR * vz
    return [
        Margin("stretch", vz, strict=True),
        Margin("stretch", MAX_STRETCH - vz),
        Margin("bend", MAX_BEND * MAX_BEND - (bend_x * bend_x + bend_y * bend_y)),
        Margin("twist", MAX_TWIST * MAX_TWIST - twist * twist),
        Margin("shear", shear * shear - (vx * vx + vy * vy)),
    ]


def strain_problem(xi, rest_length: float, index: int) -> str | None:
    """What puts a full strain ``xi`` (6,) of a segment outside the domain
    (:func:`strain_margins`), naming the strain and its value, or None.

    Parameters
    ----------
    xi : array_like, shape (6,)
        ``(u, v)``, chosen strains and rest values.
    rest_length : float
        ``L0`` [m].
    index : int
        The segment's position in the chain (0 first).
    """
    ux, uy, uz, vx, vy, vz = (float(v) for v in xi)
    where = f"segment {index + 1}"
    with np.errstate(over="ignore", invalid="ignore"):
        margins = strain_margins(np.asarray(xi, dtype=np.float64), np.float64(rest_length))
    if failed(margins, "stretch"):
        return (
            f"stretch must be in the model's domain 0 < stretch <= {MAX_STRETCH:g}: "
            f"{where} has stretch {vz:.6g}"
        )
    if failed(margins, "bend"):
        bend = rest_length * math.hypot(ux, uy)
        return (
            f"bending angles |(bend_x, bend_y)| L0 must be <= 2 pi rad (a full turn, the "
            f"model's domain): {where} bends {bend:.6g} rad (bend_x = {ux:.6g} 1/m, bend_y = "
            f"{uy:.6g} 1/m, L0 = {rest_length:.6g} m)"
        )
    if failed(margins, "twist"):
        twist = rest_length * abs(uz)
        return (
            f"twist angles |twist| L0 must be <= 2 pi rad (a full turn, the model's domain): "
            f"{where} twists {twist:.6g} rad (twist = {uz:.6g} 1/m, L0 = {rest_length:.6g} m)"
        )
    if failed(margins, "shear"):
        shear = math.hypot(vx, vy)
        return (
            f"shear |(shear_x, shear_y)| must be <= {MAX_SHEAR:g} stretch (45 degrees, the "
            f"model's domain): {where} shears {shear:.6g} at stretch {vz:.6g}"
        )
    return None


def strains_inside(xi, rest_length):
    """Elementwise :func:`strain_margins` all holding over ``xi[..., 6]``.

    Parameters
    ----------
    xi : ndarray, shape (..., 6)
        Full strains.
    rest_length : float or ndarray, shape (...)
        ``L0`` [m].
    """
    return margins_hold(strain_margins([xi[..., k] for k in range(6)], rest_length))


def _chosen(strains) -> tuple[str, ...]:
    if isinstance(strains, str):
        strains = (strains,)
    try:
        strains = tuple(strains)
    except TypeError:
        raise ParameterError(
            f"strains must be a sequence of names among {STRAINS}, got {strains!r}"
        ) from None
    unknown = [s for s in strains if s not in STRAINS]
    if unknown or not strains or len(set(strains)) != len(strains):
        raise ParameterError(
            f"strains must be distinct names among {STRAINS} (at least one), got {strains!r}"
        )
    return tuple(s for s in STRAINS if s in strains)


@dataclass(frozen=True, eq=False)
class StrainSegment(Element):
    """A segment of piecewise constant strain that chooses its strains.

    Parameters
    ----------
    rest_length : float
        Reference length ``L0`` [m], in ``(0, MAX_REST_LENGTH]``.
    mass : float
        Total mass [kg], > 0, uniform per reference length.
    radius : float
        Radius [m], > 0: of the body for contact and drawing, and of the thin disc that
        models a slice's rotary inertia unless ``slice_inertia`` is given.
    strains : sequence of str
        The strains the segment's coordinates are, among :data:`STRAINS`
        (``"bend_x"``, ``"bend_y"``, ``"twist"``, ``"shear_x"``, ``"shear_y"``,
        ``"stretch"``); its coordinates are these strains in that order, whatever the
        order given.
    bending_stiffness, torsion_stiffness : LinearStiffness or TanhStiffness or None
        Laws [N m^2] of the bending and the twist, on the curvature [1/m] away from rest:
        required where a strain of theirs is chosen, None otherwise. Linear: ``EI``
        and ``GJ``.
    shear_stiffness, stretch_stiffness : LinearStiffness or TanhStiffness or None
        Laws [N] of the shear and the stretch (dimensionless strains): required where
        chosen, None otherwise. Linear: ``k G A`` and ``E A``.
    rest_strain : array_like, shape (6,)
        ``xi*`` [1/m, 1/m, 1/m, -, -, -], default ``(0, 0, 0, 0, 0, 1)``; in the domain.
    slice_inertia : array_like, shape (3,), optional
        Rotary inertia per unit mass of a slice in its frame [m^2], each > 0 and each at
        most the sum of the other two (``(I, I, 2 I) / A`` of a section: the polar moment
        about the axis); default ``radius^2 (1/4, 1/4, 1/2)``, a disc.
    damping : array_like, shape (k, k) or (k,)
        ``R`` on the rates of the chosen strains, zero or symmetric positive definite; a
        vector is a diagonal.
    creep : Creep or None
        Kelvin-Voigt creep on the chosen strains (``k`` states), or None.

    Examples
    --------
    A soft segment that bends, twists, shears and stretches:

    >>> import softcurve as sc
    >>> seg = sc.StrainSegment(
    ...     rest_length=0.1,
    ...     mass=0.03,
    ...     radius=0.01,
    ...     strains=sc.STRAINS,
    ...     bending_stiffness=sc.LinearStiffness(7.9e-3),
    ...     torsion_stiffness=sc.LinearStiffness(5.2e-3),
    ...     shear_stiffness=sc.LinearStiffness(89.0),
    ...     stretch_stiffness=sc.LinearStiffness(314.0),
    ... )
    >>> seg.coordinate_names
    ('bend_x', 'bend_y', 'twist', 'shear_x', 'shear_y', 'stretch')
    >>> seg.rest_configuration()
    array([0., 0., 0., 0., 0., 1.])
    """

    rest_length: float
    mass: float
    radius: float
    strains: tuple[str, ...] = STRAINS
    bending_stiffness: LinearStiffness | TanhStiffness | None = None
    torsion_stiffness: LinearStiffness | TanhStiffness | None = None
    shear_stiffness: LinearStiffness | TanhStiffness | None = None
    stretch_stiffness: LinearStiffness | TanhStiffness | None = None
    rest_strain: np.ndarray = field(default_factory=lambda: np.array(REST_STRAIN))
    slice_inertia: np.ndarray | None = None
    damping: np.ndarray | None = None
    creep: Creep | None = None

    kind = "constant_strain"

    def __post_init__(self):
        set_ = object.__setattr__
        for name in ("rest_length", "mass", "radius"):
            set_(self, name, real_scalar(name, getattr(self, name), positive=True))
        if self.rest_length > MAX_REST_LENGTH:
            raise ParameterError(
                f"rest_length must be in (0, {MAX_REST_LENGTH:.3g}] m, got {self.rest_length!r}"
            )
        set_(self, "strains", _chosen(self.strains))
        for name, indices in GROUPS.items():
            law, wanted = getattr(self, name), any(STRAINS[k] in self.strains for k in indices)
            if wanted and not isinstance(law, LinearStiffness | TanhStiffness):
                raise ParameterError(
                    f"{name} must be a LinearStiffness or TanhStiffness where the segment "
                    f"chooses {' or '.join(STRAINS[k] for k in indices)}, got "
                    f"{type(law).__name__}"
                )
            if not wanted and law is not None:
                raise ParameterError(
                    f"{name} must be None: the segment chooses none of "
                    f"{', '.join(STRAINS[k] for k in indices)} (strains {self.strains})"
                )
        rest = real_array("rest_strain", self.rest_strain, (6,))
        problem = strain_problem(rest, self.rest_length, 0)
        if problem is not None:
            raise ParameterError(f"rest_strain {rest.tolist()} is outside the domain: {problem}")
        set_(self, "rest_strain", rest)
        inertia = self.radius**2 * np.array([0.25, 0.25, 0.5])
        if self.slice_inertia is not None:
            inertia = real_array("slice_inertia", self.slice_inertia, (3,))
            if not np.all(inertia > 0) or not np.all(2 * inertia <= inertia.sum() * TRIANGLE):
                raise ParameterError(
                    f"slice_inertia must be > 0 in every entry and each at most the sum of the "
                    f"other two (a body's principal moments) [m^2], got {inertia.tolist()}"
                )
        set_(self, "slice_inertia", inertia)
        damping = np.zeros(self.n_coordinates) if self.damping is None else self.damping
        set_(self, "damping", damping_matrix(damping, self.coordinate_names))
        check_creep(self.creep, self.strains, "chosen strain")

    @classmethod
    def from_material(
        cls,
        material,
        section,
        rest_length: float,
        strains=STRAINS,
        *,
        rest_strain=REST_STRAIN,
        damping=None,
        creep: Creep | None = None,
    ) -> StrainSegment:
        """The segment of a material and a section: linear laws ``EI``, ``GJ``, ``k G
        A``, ``E A`` on the chosen strains, mass ``rho A L0``, slice inertia ``(I, I, 2 I) /
        A``, radius the section's (or ``sqrt(A / pi)`` where it has none).

        Parameters
        ----------
        material : Material
            Young's modulus, shear modulus and density.
        section : Section
            Area, second and polar moments, shear coefficient.
        rest_length : float
            ``L0`` [m].
        strains : sequence of str
            The chosen strains (default all six).
        rest_strain : array_like, shape (6,)
            ``xi*``.
        damping : array_like, shape (k, k) or (k,), optional
            ``R`` on the chosen strains' rates (e.g. [N m^3 s] for a bend).
        creep : Creep, optional
            Creep on the chosen strains.
        """
        properties = section_properties(material, section)
        chosen = _chosen(strains)
        values = dict(zip(STRAINS, properties.stiffness, strict=True))
        laws = {
            name: LinearStiffness(values[STRAINS[indices[0]]])
            for name, indices in GROUPS.items()
            if any(STRAINS[k] in chosen for k in indices)
        }
        radius = section.radius if section.radius is not None else math.sqrt(section.area / math.pi)
        return cls(
            rest_length=rest_length,
            mass=properties.mass_per_length * rest_length,
            radius=radius,
            strains=chosen,
            rest_strain=rest_strain,
            slice_inertia=properties.slice_inertia,
            damping=damping,
            creep=creep,
            **laws,
        )

    @property
    def indices(self) -> tuple[int, ...]:
        """Each coordinate's index into :data:`STRAINS`."""
        return tuple(STRAINS.index(s) for s in self.strains)

    def signature(self) -> tuple:
        """``("constant_strain", strains, ((law field, law kind), ...), has creep)``."""
        laws = tuple(
            (name, getattr(self, name).kind) for name in GROUPS if getattr(self, name) is not None
        )
        return (self.kind, self.strains, laws, self.creep is not None)

    @property
    def coordinate_names(self) -> tuple[str, ...]:
        """The chosen strains."""
        return self.strains

    @property
    def coordinate_units(self) -> tuple[str, ...]:
        """``1/m`` for bending and twist, ``""`` (dimensionless) for shear and stretch."""
        return tuple(STRAIN_UNITS[k] for k in self.indices)

    def rest_configuration(self) -> np.ndarray:
        """The rest strains of the chosen strains."""
        return self.rest_strain[list(self.indices)].copy()

    def coordinate_scale(self) -> np.ndarray:
        """``1/L0`` for curvatures (a 1 rad bend or twist), 1 for shear and stretch."""
        return np.array([1.0 / self.rest_length if k < 3 else 1.0 for k in self.indices])

    @property
    def planar_pairs(self):
        """``(bend_x, bend_y)`` and ``(shear_x, shear_y)`` turn with the robot (the strain
        twist's ``u`` and ``v`` are vectors); a representative bends toward +x (``bend_y >
        0``) or, unbent, shears toward +x. None where a pair is chosen in part."""
        pairs = []
        for (a, b), reference in ((("bend_x", "bend_y"), (0.0, 1.0)),
                                  (("shear_x", "shear_y"), (1.0, 0.0))):  # fmt: skip
            chosen = (a in self.strains, b in self.strains)
            if chosen == (True, True):
                pairs.append((self.strains.index(a), self.strains.index(b), reference))
            elif any(chosen):
                return None
        return tuple(pairs)

    @element_parameters
    def bent_toward(self, q, curvature: float, azimuth: float) -> np.ndarray:
        """``(bend_x, bend_y) = curvature (-sin azimuth, cos azimuth)`` where chosen (the
        curvature vector ``(kx, ky)`` of a constant-curvature segment is ``(bend_y,
        -bend_x)``).

        Parameters
        ----------
        %(q)s
        %(curvature)s
        %(azimuth)s
        """
        q = np.array(q, dtype=np.float64)
        values = {"bend_x": -curvature * np.sin(azimuth), "bend_y": curvature * np.cos(azimuth)}
        for k, name in enumerate(self.strains):
            if name in values:
                q[k] = values[name]
        return q

    @element_parameters
    def bending_curvature(self, q) -> np.ndarray:
        """The backbone's curvature [1/m] per unit of its arc length,
        ``|v x (u x v)| / |v|^3`` of the full strain (rest values where not chosen):
        ``hypot(bend_x, bend_y) / stretch`` without shear, as a constant-curvature
        segment's ``hypot(kx, ky)``.

        Parameters
        ----------
        %(q)s
        """
        xi = self.full_strain(q)
        u, v = xi[..., :3], xi[..., 3:]
        normal = np.cross(v, np.cross(u, v))
        return np.linalg.norm(normal, axis=-1) / np.linalg.norm(v, axis=-1) ** 3

    @property
    def extent_index(self) -> int | None:
        """The stretch's coordinate, where it is chosen."""
        return self.strains.index("stretch") if "stretch" in self.strains else None

    def search_bounds(self) -> np.ndarray:
        """About the rest strains: bending and twist within ``pi / L0`` (half a turn),
        shear within 0.25 (14 degrees) and stretch within half of its rest value, each
        clipped to the strain's own bound (a full turn, ``MAX_STRETCH``)."""
        rest = self.rest_configuration()
        half = np.array([np.pi / self.rest_length] * 3 + [0.25, 0.25, 0.0])[list(self.indices)]
        lower, upper = rest - half, rest + half
        turn = np.array([MAX_BEND / self.rest_length, MAX_BEND / self.rest_length,
                         MAX_TWIST / self.rest_length, np.inf, np.inf, np.inf])  # fmt: skip
        bound = turn[list(self.indices)]
        lower, upper = np.maximum(lower, -bound), np.minimum(upper, bound)
        if "stretch" in self.strains:
            k = self.extent_index
            lower[k], upper[k] = 0.5 * rest[k], min(1.5 * rest[k], MAX_STRETCH)
        return np.column_stack([lower, upper])

    def full_strain(self, q) -> np.ndarray:
        """``xi`` (..., 6): the chosen strains from ``q[..., k]``, the rest values else.

        Parameters
        ----------
        q : array_like, shape (..., k)
            The segment's coordinates.
        """
        q = np.asarray(q, dtype=np.float64)
        xi = np.broadcast_to(self.rest_strain, (*q.shape[:-1], 6)).copy()
        xi[..., list(self.indices)] = q
        return xi

    def inside(self, q, rest_length=None) -> np.ndarray:
        rest = self.rest_length if rest_length is None else np.asarray(rest_length)
        with np.errstate(invalid="ignore", over="ignore"):
            return strains_inside(self.full_strain(q), rest)

    def domain_problem(self, q, index: int, place, rest_length=None) -> str | None:
        problem = finite_problem(q, self.strains, index, place)
        if problem is not None:
            return problem
        rest = self.rest_length if rest_length is None else float(rest_length)
        return strain_problem(self.full_strain(q), rest, index)

    def with_values(self, values: dict) -> StrainSegment:
        creep = None if self.creep is None else creep_of(values)
        laws = {
            name: type(getattr(self, name))(*values[name])
            for name in GROUPS
            if getattr(self, name) is not None
        }
        scalars = {n: float(values[n]) for n in ("rest_length", "mass", "radius")}
        return self.replace(
            **scalars,
            **laws,
            rest_strain=values["rest_strain"],
            slice_inertia=values["slice_inertia"],
            damping=values["damping"],
            creep=creep,
        )


class StrainModel(SoftModel):
    """The symbolic constant-strain segment of a signature ``("constant_strain", strains,
    laws, has creep)``; geometry ``(mass, slice inertia (3), L0, rest strain (6))``."""

    def __init__(self, signature: tuple):
        _, self.strains, self.laws, has_creep = signature
        self.signature = signature
        self.indices = tuple(STRAINS.index(s) for s in self.strains)
        self.nq = len(self.strains)
        self.n_creep = self.nq if has_creep else 0

    def fields(self):
        units = [STRAIN_UNITS[k] for k in self.indices]
        forces = [_FORCE_UNITS[k] for k in self.indices]
        damping_units = [_DAMPING_UNITS[(f, u)] for f in forces for u in units]
        specs = [
            scalar_field("rest_length", "m"),
            scalar_field("mass", "kg"),
            scalar_field("radius", "m"),
            vector_field("slice_inertia", 3, "m^2"),
            vector_field("rest_strain", 6, STRAIN_UNITS),
            *(law_field(name, kind, _GROUP_UNITS[name]) for name, kind in self.laws),
            matrix_field("damping", self.nq, damping_units),
        ]
        return specs + (creep_fields(self.nq) if self.n_creep else [])

    def geometry(self, part):
        return ca.vertcat(
            part["mass"], part["slice_inertia"], part["rest_length"], part["rest_strain"]
        )

    def strain(self, q, rest):
        """The full strain ``xi`` (6,): ``q`` at the chosen strains, ``rest`` elsewhere."""
        entries = [rest[k] for k in range(6)]
        for i, k in enumerate(self.indices):
            entries[k] = q[i]
        return ca.vertcat(*entries)

    def domain_margins(self, q, part):
        xi = self.strain(q, part["rest_strain"])
        return strain_margins([xi[k] for k in range(6)], part["rest_length"])

    def rotation_vector(self, q, s, g):
        xi = self.strain(q, g[5:11])
        return s * g[4] * xi[:3]

    def translation(self, q, s, g):
        xi = self.strain(q, g[5:11])
        return s * g[4] * xi[3:]

    def mass(self, g):
        return g[0]

    def slice_inertia(self, g):
        return g[1:4]

    def elastic(self, q, part):
        """``V_e = L0 int_0^e k(x) x dx`` per group, ``e^2`` the squared deviation; the
        force is its gradient (smooth: the laws are functions of ``e^2``)."""
        deviation = self.strain(q, part["rest_strain"]) - part["rest_strain"]
        energy = 0
        for name, kind in self.laws:
            squared = sum(deviation[k] ** 2 for k in GROUPS[name])
            energy += part["rest_length"] * STIFFNESS_LAWS[kind].energy(squared, part[name])
        return energy, ca.gradient(energy, q)
