"""A solid's material and cross-section, and the properties per length they give a rod.

A :class:`Material` (an isotropic linear elastic solid: Young's modulus, shear modulus or
Poisson's ratio, density) and a :class:`Section` (area, second moment, torsion constant,
shear coefficient) give, through :func:`section_properties`, a rod's mass per length,
the rotary inertia of its slices and its stiffness for each of the six strains in the
order ``(bend_x, bend_y, twist, shear_x, shear_y, stretch)``:
``K = diag(E I, E I, G J, k G A, k G A, E A)``. The elastic energy of a segment of rest
length ``L0`` is then ``1/2 int_0^L0 (xi - xi*)^T K (xi - xi*) dX``; for a segment of
constant curvature it is the paper's, with the stiffness of the bending angle
``E I / L0`` and of the elongation ``E A / L0``
(:meth:`SectionProperties.bending_angle_stiffness`,
:meth:`SectionProperties.elongation_stiffness`).

The shear coefficients of circles and tubes are Cowper's: G. R. Cowper, "The shear
coefficient in Timoshenko's beam theory", Journal of Applied Mechanics 33(2):335-340
(1966), Table 1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from softcurve.base.validation import ParameterError, real_array, real_scalar

CONSISTENCY_TOLERANCE = 1e-12
"""Relative tolerance of the identities checked between numbers a user gives: a shear
modulus given with a Poisson's ratio must equal ``E / (2 (1 + nu))``, and a section's
torsion constant and second moment must satisfy their inequalities, to this tolerance.
Numbers computed from one another in float64 differ by a few units of round-off
(1e-16), far inside; a wrong number differs by its own size."""

INCOMPRESSIBLE = 0.5
"""Poisson's ratio of an incompressible solid [-], the usual value for the silicone
rubbers of soft robots and the default of :meth:`Section.circle` and
:meth:`Section.tube` (Cowper's shear coefficient of a circle is then 0.9)."""


def _poisson_ratio(value) -> float:
    nu = real_scalar("poisson_ratio [-]", value)
    if not -1.0 < nu <= INCOMPRESSIBLE:
        raise ParameterError(
            f"poisson_ratio [-] must be in (-1, 0.5] (an isotropic elastic solid; 0.5 is "
            f"incompressible), got {nu!r}"
        )
    return nu


def _agree(a: float, b: float) -> bool:
    return abs(a - b) <= CONSISTENCY_TOLERANCE * max(abs(a), abs(b))


@dataclass(frozen=True)
class Material:
    """An isotropic linear elastic solid.

    Give the shear modulus or Poisson's ratio; the other follows from
    ``G = E / (2 (1 + nu))``, and both are attributes of the material. Both may be given
    when they agree (to :data:`CONSISTENCY_TOLERANCE`, as in the material's ``repr``).
    An isotropic solid has ``-1 < nu <= 0.5`` (a positive shear and bulk modulus), that
    is ``G >= E / 3``; 0.5 is incompressible, the usual value for silicone rubbers.
    For a hyper-elastic rubber, ``E`` is the small-strain (initial) Young's modulus;
    the 100 % modulus of a datasheet is a secant at large strain and is not ``E``.

    Parameters
    ----------
    youngs_modulus : float
        Young's modulus ``E`` [Pa], > 0.
    density : float
        Mass density ``rho`` [kg/m^3], > 0.
    shear_modulus : float, optional
        Shear modulus ``G`` [Pa], ``>= E / 3``.
    poisson_ratio : float, optional
        Poisson's ratio ``nu`` [-], in (-1, 0.5].

    Examples
    --------
    >>> silicone = Material(youngs_modulus=1e6, density=1070.0, poisson_ratio=0.5)
    >>> silicone.shear_modulus  # E / (2 (1 + nu)) [Pa]
    333333.33...
    >>> Material(youngs_modulus=54e9, density=6450.0, shear_modulus=20e9).poisson_ratio
    0.35
    """

    youngs_modulus: float
    density: float
    shear_modulus: float | None = None
    poisson_ratio: float | None = None

    def __post_init__(self):
        e = real_scalar("youngs_modulus [Pa]", self.youngs_modulus, positive=True)
        rho = real_scalar("density [kg/m^3]", self.density, positive=True)
        if self.shear_modulus is None and self.poisson_ratio is None:
            raise ParameterError(
                "a Material needs shear_modulus [Pa] or poisson_ratio [-], got neither"
            )
        if self.poisson_ratio is not None:
            nu = _poisson_ratio(self.poisson_ratio)
            g = e / (2.0 * (1.0 + nu))
        if self.shear_modulus is not None:
            given = real_scalar("shear_modulus [Pa]", self.shear_modulus, positive=True)
            if self.poisson_ratio is None:
                if given < e / 3.0:
                    raise ParameterError(
                        f"shear_modulus [Pa] must be >= youngs_modulus / 3 = {e / 3.0!r} (an "
                        f"isotropic elastic solid: Poisson's ratio E / (2 G) - 1 <= 0.5), "
                        f"got {given!r}"
                    )
                # G >= E / 3 means nu <= 0.5 exactly; the min keeps the rounding of
                # E / (2 G) from ever stating more (none found at G = E / 3 for 1e5 E)
                nu = min(e / (2.0 * given) - 1.0, INCOMPRESSIBLE)
            elif not _agree(given, g):
                raise ParameterError(
                    f"shear_modulus [Pa] = {given!r} and poisson_ratio [-] = {nu!r} disagree: "
                    f"E / (2 (1 + nu)) = {g!r}; give one of them"
                )
            g = given
        for name, value in (
            ("youngs_modulus", e),
            ("density", rho),
            ("shear_modulus", g),
            ("poisson_ratio", nu),
        ):
            object.__setattr__(self, name, value)


def _cowper(poisson_ratio: float, inner_ratio: float) -> float:
    """Cowper's (1966, Table 1) shear coefficient of a tube whose inner radius is
    ``inner_ratio`` times its outer radius (0: a solid circle, ``6 (1 + nu) / (7 + 6 nu)``)."""
    nu, m2 = poisson_ratio, inner_ratio**2
    s = (1.0 + m2) ** 2
    return 6.0 * (1.0 + nu) * s / ((7.0 + 6.0 * nu) * s + (20.0 + 12.0 * nu) * m2)


@dataclass(frozen=True)
class Section:
    """A rod's cross-section, the same about both bending axes (``I_x = I_y``).

    Build a circle or a tube with :meth:`circle` and :meth:`tube`, or give the constants
    of any other section whose second moments about x and y are equal (a square, a
    regular polygon, a ring of chambers with that symmetry). Two inequalities hold for
    every section and are checked (to :data:`CONSISTENCY_TOLERANCE`), to catch a number
    in the wrong unit: the torsion constant is at most the polar moment,
    ``J <= I_x + I_y = 2 I`` (Saint-Venant; equal for circles and tubes), and a disk has
    the least polar moment for its area, ``I >= A^2 / (4 pi)``.

    Parameters
    ----------
    area : float
        Area ``A`` [m^2], > 0.
    second_moment : float
        Second moment of area ``I`` about each bending axis through the centroid [m^4],
        > 0 and ``>= A^2 / (4 pi)``.
    polar_moment : float
        Torsion constant ``J`` [m^4] (``G J`` is the torsional stiffness), > 0 and
        ``<= 2 I``: for a circle or a tube the polar moment ``I_x + I_y``, for any other
        shape less (Saint-Venant's torsion constant).
    shear_coefficient : float
        Timoshenko's shear coefficient ``k`` [-], in (0, 1] (``k G A`` is the shear
        stiffness).
    radius : float, optional
        The outer radius [m], > 0, where the section has one (circles and tubes): the
        radius for contact and drawing. None: the section has none.

    Examples
    --------
    >>> rod = Section.circle(0.01)  # radius [m]; nu = 0.5 by default
    >>> rod.area, rod.shear_coefficient  # [m^2], [-]
    (0.000314159..., 0.9)
    >>> Section.circle(0.01, poisson_ratio=0.3).shear_coefficient  # 7.8 / 8.8
    0.886363...
    """

    area: float
    second_moment: float
    polar_moment: float
    shear_coefficient: float
    radius: float | None = None

    def __post_init__(self):
        a = real_scalar("area [m^2]", self.area, positive=True)
        i = real_scalar("second_moment [m^4]", self.second_moment, positive=True)
        j = real_scalar("polar_moment [m^4]", self.polar_moment, positive=True)
        k = real_scalar("shear_coefficient [-]", self.shear_coefficient, positive=True)
        if k > 1.0:
            raise ParameterError(f"shear_coefficient [-] must be in (0, 1], got {k!r}")
        if j > 2.0 * i and not _agree(j, 2.0 * i):
            raise ParameterError(
                f"polar_moment [m^4] must be <= 2 second_moment = {2.0 * i!r} (a section's "
                f"torsion constant is at most its polar moment I_x + I_y), got {j!r}"
            )
        least = a**2 / (4.0 * math.pi)
        if i < least and not _agree(i, least):
            raise ParameterError(
                f"second_moment [m^4] must be >= area^2 / (4 pi) = {least!r} (a disk has the "
                f"least second moment for its area), got {i!r}"
            )
        radius = None
        if self.radius is not None:
            radius = real_scalar("radius [m]", self.radius, positive=True)
        for name, value in (
            ("area", a),
            ("second_moment", i),
            ("polar_moment", j),
            ("shear_coefficient", k),
            ("radius", radius),
        ):
            object.__setattr__(self, name, value)

    @classmethod
    def circle(cls, radius: float, poisson_ratio: float = INCOMPRESSIBLE) -> Section:
        """A solid circle: ``A = pi r^2``, ``I = pi r^4 / 4``, ``J = pi r^4 / 2`` and
        Cowper's shear coefficient ``k = 6 (1 + nu) / (7 + 6 nu)`` (0.9 at ``nu = 0.5``,
        0.886 at 0.3).

        Parameters
        ----------
        radius : float
            Radius ``r`` [m], > 0.
        poisson_ratio : float
            Poisson's ratio ``nu`` [-] of the material, in (-1, 0.5] (default
            :data:`INCOMPRESSIBLE`, 0.5); it sets the shear coefficient only.
        """
        r = real_scalar("radius [m]", radius, positive=True)
        return cls._annulus(r, 0.0, _poisson_ratio(poisson_ratio))

    @classmethod
    def tube(
        cls, outer_radius: float, inner_radius: float, poisson_ratio: float = INCOMPRESSIBLE
    ) -> Section:
        """A tube: ``A = pi (a^2 - b^2)``, ``I = pi (a^4 - b^4) / 4``,
        ``J = pi (a^4 - b^4) / 2`` and Cowper's shear coefficient of a hollow circle,
        ``k = 6 (1 + nu) (1 + m^2)^2 / ((7 + 6 nu) (1 + m^2)^2 + (20 + 12 nu) m^2)`` with
        ``m = b / a``; an inner radius 0 is :meth:`circle`.

        Parameters
        ----------
        outer_radius : float
            Outer radius ``a`` [m], > 0.
        inner_radius : float
            Inner radius ``b`` [m], ``0 <= b < a``.
        poisson_ratio : float
            Poisson's ratio ``nu`` [-] of the material, in (-1, 0.5] (default
            :data:`INCOMPRESSIBLE`, 0.5); it sets the shear coefficient only.
        """
        a = real_scalar("outer_radius [m]", outer_radius, positive=True)
        b = real_scalar("inner_radius [m]", inner_radius)
        if not 0.0 <= b < a:
            raise ParameterError(
                f"inner_radius [m] must be in [0, outer_radius) = [0, {a!r}), got {b!r}"
            )
        return cls._annulus(a, b, _poisson_ratio(poisson_ratio))

    @classmethod
    def _annulus(cls, a: float, b: float, nu: float) -> Section:
        quartic = math.pi * (a**4 - b**4)
        return cls(
            area=math.pi * (a**2 - b**2),
            second_moment=quartic / 4.0,
            polar_moment=quartic / 2.0,
            shear_coefficient=_cowper(nu, b / a),
            radius=a,
        )


@dataclass(frozen=True, eq=False)
class SectionProperties:
    """What a material and a section give a rod, per length (:func:`section_properties`).

    Attributes
    ----------
    mass_per_length : float
        ``rho A`` [kg/m], > 0.
    slice_inertia : ndarray, shape (3,)
        Rotary inertia of a slice per unit mass in the slice's frame (z along the
        backbone), ``(I, I, 2 I) / A`` [m^2]: the second moments about the slice's x and
        y axes and the polar moment ``I_x + I_y`` about z, each over the area.
    stiffness : ndarray, shape (6,)
        ``(E I, E I, G J, k G A, k G A, E A)`` in the strain order ``(bend_x, bend_y,
        twist, shear_x, shear_y, stretch)`` [N m^2, N m^2, N m^2, N, N, N], each > 0.
    """

    mass_per_length: float
    slice_inertia: np.ndarray
    stiffness: np.ndarray

    def __post_init__(self):
        mass = real_scalar("mass_per_length [kg/m]", self.mass_per_length, positive=True)
        for name, size in (("slice_inertia", 3), ("stiffness", 6)):
            values = real_array(name, getattr(self, name), (size,))
            if not np.all(values > 0):
                raise ParameterError(f"{name} must be > 0 in every entry, got {values.tolist()}")
            object.__setattr__(self, name, values)
        object.__setattr__(self, "mass_per_length", mass)

    @property
    def bending(self) -> float:
        """Bending stiffness ``E I`` [N m^2], about x and y alike."""
        return float(self.stiffness[0])

    @property
    def torsion(self) -> float:
        """Torsional stiffness ``G J`` [N m^2]."""
        return float(self.stiffness[2])

    @property
    def shear(self) -> float:
        """Shear stiffness ``k G A`` [N], along x and y alike."""
        return float(self.stiffness[3])

    @property
    def stretch(self) -> float:
        """Axial stiffness ``E A`` [N]."""
        return float(self.stiffness[5])

    def bending_angle_stiffness(self, rest_length: float) -> float:
        """The paper's stiffness of the bending angle ``beta = kappa l`` of a segment of
        constant curvature, ``k_b = E I / L0`` [N m/rad].

        The segment's angular strain is ``|u| = beta / L0`` (an angle per reference
        length), so the rod's bending energy ``1/2 E I |u|^2 L0`` is exactly
        ``1/2 k_b beta^2``.

        Parameters
        ----------
        rest_length : float
            The segment's rest length ``L0`` [m], > 0.
        """
        return self.bending / real_scalar("rest_length [m]", rest_length, positive=True)

    def elongation_stiffness(self, rest_length: float) -> float:
        """The paper's stiffness of the elongation ``l - L0`` of a segment of constant
        curvature, ``k_e = E A / L0`` [N/m]: the stretch is ``v_z = l / L0``, so the rod's
        axial energy ``1/2 E A (v_z - 1)^2 L0`` is exactly ``1/2 k_e (l - L0)^2``.

        Parameters
        ----------
        rest_length : float
            The segment's rest length ``L0`` [m], > 0.
        """
        return self.stretch / real_scalar("rest_length [m]", rest_length, positive=True)


def section_properties(material: Material, section: Section) -> SectionProperties:
    """The mass per length, slice inertia and stiffness a material gives a section.

    Parameters
    ----------
    material : Material
        The solid.
    section : Section
        Its cross-section.

    Returns
    -------
    SectionProperties
        ``rho A`` [kg/m]; ``(I, I, 2 I) / A`` [m^2]; ``(E I, E I, G J, k G A, k G A,
        E A)`` [N m^2, N m^2, N m^2, N, N, N].

    Examples
    --------
    >>> silicone = Material(youngs_modulus=1e6, density=1070.0, poisson_ratio=0.5)
    >>> rod = section_properties(silicone, Section.circle(0.01))
    >>> rod.bending, rod.torsion  # E I, G J [N m^2]
    (0.00785398..., 0.00523598...)
    >>> rod.shear, rod.stretch  # k G A, E A [N]
    (94.2477..., 314.159...)
    >>> rod.mass_per_length  # rho A [kg/m]
    0.33615...
    >>> rod.bending_angle_stiffness(0.2), rod.elongation_stiffness(0.2)  # [N m/rad], [N/m]
    (0.0392699..., 1570.79...)
    """
    e, g, rho = material.youngs_modulus, material.shear_modulus, material.density
    a, i, j = section.area, section.second_moment, section.polar_moment
    k = section.shear_coefficient
    return SectionProperties(
        mass_per_length=rho * a,
        slice_inertia=np.array([i, i, 2.0 * i]) / a,
        stiffness=np.array([e * i, e * i, g * j, k * g * a, k * g * a, e * a]),
    )
