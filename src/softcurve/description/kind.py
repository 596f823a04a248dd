"""What every element kind declares, and the kinematics the soft kinds share.

An element of the chain is a body between its base frame and its tip frame (the next
element's base), as a joint and its body in Pinocchio: it declares its coordinates
(count, names, units), their rest values, scales and domain, its parameter fields, and,
as CasADi expressions of its coordinates and of its numbers, the pose of its material
points, its mass distribution, its elastic energy, damping and creep. The chain
algorithms (:mod:`softcurve.symbolic.chain`) see nothing else of a kind.

Two halves, as Pinocchio's joint model and its data: the *element* (a frozen, validated
description holding numbers, e.g. :class:`~softcurve.Segment`) and its *model*
(:class:`ElementModel`, built from the element's :meth:`Element.signature`, holding no
number: the compiled model reads the numbers from the parameter vector, so one library
serves every robot of the same structure).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import casadi as ca
import numpy as np

from softcurve.base import smooth as _smooth
from softcurve.base.docs import parameters_from
from softcurve.base.validation import ParameterError, positive_definite, real_array
from softcurve.description.materials import STIFFNESS_LAWS, Creep

E_Z = np.array([0.0, 0.0, 1.0])

ELEMENT_PARAMETERS = {
    "q": (
        "array_like, shape (..., n_i)",
        "Configurations of the element's coordinates (e.g. ``(l, kx, ky)`` [m, 1/m, 1/m]); "
        "one, shape (n_i,), where one is asked for.",
    ),
    "rest_length": (
        "float or array_like, optional",
        "Replaces the element's rest length [m] (per configuration: the members of a batch).",
    ),
    "index": ("int", "The element's position in the chain (0 first), for the message."),
    "place": ("callable", '``place(k)`` names entry ``k`` of its coordinates (``"q[3]"``).'),
    "values": ("dict", "Field name -> array, the element's numbers (its layout's fields)."),
    "curvature": ("float", "The bending curvature [1/m] of the arc."),
    "azimuth": ("float", "Where the tip moves, an azimuth [rad] of the element's base frame."),
    "name": ("str", 'The field\'s attribute path on the element (``"mass"``).'),
    "size": ("int", "Number of entries (rows and columns of a matrix)."),
    "units": ("str or sequence of str", "One unit for every entry, or one per entry."),
}
"""The parameters the element kinds' methods share."""

element_parameters = parameters_from(ELEMENT_PARAMETERS)
"""Decorator: ``%(q)s`` and the others of :data:`ELEMENT_PARAMETERS`."""


@dataclass(frozen=True)
class FieldSpec:
    """One named block of an element's parameters, as the layout lists it.

    Parameters
    ----------
    name : str
        Attribute path on the element, e.g. ``"mass"`` or ``"creep.rate"``.
    shape : tuple of int
        ``()``, ``(k,)`` or ``(k, k)`` (row major).
    labels : tuple of str
        Suffix of each entry's name (``""``, ``".k0"``, ``"[0]"``, ``"[0,1]"``).
    units : tuple of str
        Each entry's unit.
    """

    name: str
    shape: tuple[int, ...]
    labels: tuple[str, ...]
    units: tuple[str, ...]


@element_parameters
def scalar_field(name: str, unit: str) -> FieldSpec:
    """A scalar field of unit ``unit``.

    Parameters
    ----------
    %(name)s
    unit : str
        Its unit.
    """
    return FieldSpec(name, (), ("",), (unit,))


@element_parameters
def vector_field(name: str, size: int, units) -> FieldSpec:
    """A vector field.

    Parameters
    ----------
    %(name)s
    %(size)s
    %(units)s
    """
    units = (units,) * size if isinstance(units, str) else tuple(units)
    return FieldSpec(name, (size,), tuple(f"[{i}]" for i in range(size)), units)


@element_parameters
def matrix_field(name: str, size: int, units) -> FieldSpec:
    """A ``size x size`` matrix field, row major.

    Parameters
    ----------
    %(name)s
    %(size)s
    %(units)s
    """
    labels = tuple(f"[{i},{j}]" for i in range(size) for j in range(size))
    units = (units,) * len(labels) if isinstance(units, str) else tuple(units)
    return FieldSpec(name, (size, size), labels, units)


@element_parameters
def law_field(name: str, kind: str, units: dict) -> FieldSpec:
    """The field of a stiffness law.

    Parameters
    ----------
    %(name)s
    kind : str
        The law's kind (``"linear"``, ``"tanh"``).
    units : dict
        The law's parameter quantities (``"stiffness"``, ``"1/strain"``) to units.
    """
    law = STIFFNESS_LAWS[kind]
    labels = tuple("." + x for x in law.parameter_labels)
    quantities = law.parameter_quantities
    return FieldSpec(name, (len(labels),), labels, tuple(units[q] for q in quantities))


@element_parameters
def creep_fields(size: int) -> list[FieldSpec]:
    """The fields of creep (the state's unit is the user's: gain and compliance carry it).

    Parameters
    ----------
    %(size)s
    """
    return [
        vector_field("creep.rate", size, "1/s"),
        vector_field("creep.gain", size, ""),
        matrix_field("creep.compliance", size, ""),
    ]


def damping_matrix(value, names: tuple[str, ...]) -> np.ndarray:
    """A damping matrix over coordinates ``names``: zero (a conservative element) or
    symmetric positive definite; a vector is a diagonal.

    The damping force ``R qd`` takes the power ``qd^T R qd`` from the robot, which must
    be >= 0 for every motion (else the damper is a source of energy), and the code
    requires > 0 for every nonzero ``qd`` (no undamped direction hidden in a damped
    element).

    Parameters
    ----------
    value : array_like, shape (k, k) or (k,)
        The matrix or its diagonal.
    names : tuple of str
        The coordinates' names, ``k`` of them.
    """
    size = len(names)
    a = np.asarray(value, dtype=np.float64)
    if a.shape in ((size,), (size, size)) and np.all(a == 0):
        return real_array("damping", np.zeros((size, size)), (size, size))
    try:
        return positive_definite("damping", value, size)
    except ParameterError as exc:
        raise ParameterError(
            f"{exc}. Rule: the damping force R qd dissipates the power qd^T R qd, so R must be "
            "symmetric positive definite (qd^T R qd > 0 for every motion qd) or exactly zero; "
            "a negative entry makes the robot active (it creates energy)"
        ) from None


class Element:
    """The description side of an element kind (a frozen dataclass subclasses it).

    Each kind sets ``kind`` (its name in structures and files) and defines
    :meth:`signature`, the coordinates' names, units, rest values and scales, the
    domain, and :meth:`with_values`.
    """

    kind: str = ""

    def signature(self) -> tuple:
        """What the compiled model depends on besides numbers: ``(kind, ...)``."""
        raise NotImplementedError

    @property
    def coordinate_names(self) -> tuple[str, ...]:
        """Names of the element's coordinates, in order."""
        raise NotImplementedError

    @property
    def n_coordinates(self) -> int:
        """Number of coordinates ``n_i`` (Pinocchio's ``nq``)."""
        return len(self.coordinate_names)

    @property
    def n_creep(self) -> int:
        """Number of creep states."""
        creep = getattr(self, "creep", None)
        return 0 if creep is None else creep.size

    def rest_configuration(self) -> np.ndarray:
        """The coordinates at rest, shape (n_i,)."""
        raise NotImplementedError

    def coordinate_scale(self) -> np.ndarray:
        """A positive scale per coordinate (m, 1/m or 1), the size of a typical motion:
        the floor of the integrator's state scale."""
        raise NotImplementedError

    @element_parameters
    def bending_curvature(self, q) -> np.ndarray:
        """The magnitude of the element's bending curvature ``|kappa|`` [1/m], shape
        (...): 0 for a body that does not bend.

        Parameters
        ----------
        %(q)s
        """
        return np.zeros(np.shape(q)[:-1])

    @property
    def planar_pairs(self) -> tuple[tuple[int, int, tuple[float, float]], ...] | None:
        """How the element's coordinates turn when the whole robot turns about its base
        axis (the conjugation by a rotation about z, which leaves an element's own frame
        conventions alone): pairs ``(i, j, reference)`` of coordinates that turn as a
        vector of the base's xy plane, each with the unit vector ``reference`` that a ring's
        representative aligns the first nonzero pair with; the others stay. None where a
        turned configuration cannot be written in the element's coordinates (a pair of
        which one coordinate alone is chosen). A body without coordinates: ``()`` (whether
        it is symmetric, the residual at the turned configurations tells)."""
        return ()

    @element_parameters
    def bent_toward(self, q, curvature: float, azimuth: float) -> np.ndarray:
        """``q`` (n_i,) with the element bent as an arc of ``curvature`` whose tip moves
        toward ``azimuth`` (a guess of the statics); unchanged for a body that does not
        bend.

        Parameters
        ----------
        %(q)s
        %(curvature)s
        %(azimuth)s
        """
        return np.array(q, dtype=np.float64)

    def search_bounds(self) -> np.ndarray:
        """The box of the element's coordinates that the multi-start search of equilibria
        samples by default (``softcurve.analysis.statics.default_bounds``), shape (n_i, 2)."""
        raise NotImplementedError

    extent_index: int | None = None
    """Which coordinate sets the element's length (a length, a stretch), or None: the
    search's box is checked to keep it in the domain at both ends."""

    @element_parameters
    def inside(self, q, rest_length=None) -> np.ndarray:
        """Whether configurations of the element lie in its domain (NaN fails),
        elementwise over the leading axes, shape (...).

        Parameters
        ----------
        %(q)s
        %(rest_length)s
        """
        raise NotImplementedError

    @element_parameters
    def domain_problem(self, q, index: int, place, rest_length=None) -> str | None:
        """What puts ``q`` outside the domain, naming the coordinate, its value and the
        allowed range; None inside.

        Parameters
        ----------
        %(q)s
        %(index)s
        %(place)s
        %(rest_length)s
        """
        raise NotImplementedError

    @element_parameters
    def with_values(self, values: dict) -> Element:
        """The element of this signature whose numbers are ``values``, validated again.

        Parameters
        ----------
        %(values)s
        """
        raise NotImplementedError

    def replace(self, **changes):
        """A copy with some fields changed (validated again).

        Parameters
        ----------
        **changes
            New values of fields, by name (e.g. ``mass=0.06``).
        """
        return dataclasses.replace(self, **changes)


@dataclass(frozen=True)
class Margin:
    """One inequality of an element's domain, ``value > 0`` (strict) or ``value >= 0``.

    A kind writes its domain once as margins, with arithmetic alone, so that the same
    function evaluates them on floats, on NumPy arrays (elementwise) and on CasADi
    symbols: the Python rule (:meth:`Element.inside`, :meth:`Element.domain_problem`) and
    the compiled model's ``domain`` Function, which the C driver calls at its outputs,
    are one rule. NaN fails both comparisons, so a non-finite coordinate is outside.

    Parameters
    ----------
    what : str
        Which bound it is (the kind's messages name it): ``"length"``, ``"bend"`` ...
    value : float, ndarray or casadi.SX
        The margin; in the domain where it is > 0 (``strict``) or >= 0.
    strict : bool
        ``value > 0`` rather than ``value >= 0``.
    """

    what: str
    value: object
    strict: bool = False

    def holds(self):
        """Whether the margin holds: bool (array) on numbers, 0/1 on CasADi symbols."""
        return self.value > 0 if self.strict else self.value >= 0


def margins_hold(margins):
    """Whether every margin of ``margins`` holds: a bool, a bool array (elementwise) or
    a CasADi expression of value 1 or 0 (True where there are none).

    Parameters
    ----------
    margins : sequence of Margin
        An element's domain, :meth:`ElementModel.domain_margins` or a kind's function.
    """
    held = True
    for margin in margins:
        ok = margin.holds()
        if isinstance(ok, ca.SX | ca.MX):
            held = ok if held is True else ca.logic_and(held, ok)
        else:
            held = held & ok
    return held


def failed(margins, what: str) -> bool:
    """Whether a margin named ``what`` of ``margins`` (of one configuration, floats)
    fails: the test the kinds' messages are worded from, so that a message is written
    exactly where the rule puts a configuration outside.

    Parameters
    ----------
    margins : sequence of Margin
        One configuration's margins.
    what : str
        Which bound (``"length"``, ``"bend"`` ...).
    """
    return not all(bool(m.holds()) for m in margins if m.what == what)


def check_creep(creep, names: tuple[str, ...], what: str) -> None:
    """ParameterError unless ``creep`` is None or a :class:`Creep` of one state per
    coordinate.

    Parameters
    ----------
    creep : Creep or None
        The element's creep.
    names : tuple of str
        The element's coordinates.
    what : str
        What a coordinate is, for the message (``"coordinate"``, ``"chosen strain"``).
    """
    if creep is None:
        return
    if not isinstance(creep, Creep):
        raise ParameterError(f"creep must be a Creep or None, got {type(creep).__name__}")
    if creep.size != len(names):
        raise ParameterError(
            f"creep must have {len(names)} states (one per {what}: {', '.join(names)}), "
            f"got {creep.size}"
        )


@element_parameters
def creep_of(values: dict):
    """The creep of an element's numbers ``values`` (its ``creep.rate``, ``creep.gain``
    and ``creep.compliance`` fields), validated again.

    Parameters
    ----------
    %(values)s
    """
    return Creep(*(values[f"creep.{n}"] for n in ("rate", "gain", "compliance")))


@element_parameters
def finite_problem(q, names, index: int, place) -> str | None:
    """The first non-finite coordinate of an element, worded, or None.

    Parameters
    ----------
    %(q)s
    names : sequence of str
        The coordinates' names.
    %(index)s
    %(place)s
    """
    for k, (name, value) in enumerate(zip(names, q, strict=True)):
        if not np.isfinite(value):
            return f"entries must be finite: {name} of segment {index + 1} ({place(k)}) = {value}"
    return None


@dataclass(frozen=True)
class Body:
    """A rigid slice or body of an element, for the Newton-Euler pass.

    Parameters
    ----------
    s : float or None
        Material coordinate of a slice (its pose and Jacobians from the element's
        kinematics), or None for a body fixed in the element's base frame.
    mass : casadi.SX
        Its mass [kg].
    inertia : casadi.SX, shape (3, 3)
        Its rotational inertia [kg m^2] about its centre, in its own frame.
    centre : casadi.SX, shape (3,), or None
        The centre of a fixed body [m], base frame.
    """

    s: float | None
    mass: ca.SX
    inertia: ca.SX
    centre: ca.SX | None = None


class ElementModel:
    """The symbolic side of an element kind: built from a signature, no numbers.

    Attributes
    ----------
    signature : tuple
        The element's :meth:`Element.signature`.
    nq : int
        Number of coordinates.
    n_creep : int
        Number of creep states.
    """

    signature: tuple = ()
    nq: int = 0
    n_creep: int = 0

    def fields(self) -> list[FieldSpec]:
        """The element's parameter fields, in their order in ``p``."""
        raise NotImplementedError

    def geometry(self, part: dict) -> ca.SX:
        """The numbers the element's Functions take, one column, from its fields'
        symbols ``part`` (field name -> SX)."""
        raise NotImplementedError

    def geometry_size(self) -> int:
        """Length of :meth:`geometry`."""
        part = {f.name: ca.SX.sym(f.name, *f.shape) for f in self.fields()}
        return self.geometry(part).shape[0]

    def point_pose(self, q, s, g):
        """Rotation (3, 3) and position (3,) [m] of material point ``s`` in [0, 1], in
        the element's base frame."""
        raise NotImplementedError

    def angular_jacobian(self, q, s, g):
        """Body-frame angular velocity per unit ``qd`` (3, nq) of point ``s``."""
        raise NotImplementedError

    def tip_pose(self, q, g):
        """Rotation and position of the tip frame in the base frame."""
        return self.point_pose(q, 1.0, g)

    def bodies(self, g, quadrature_nodes: int) -> list[Body]:
        """The element's mass as slices (or one fixed body)."""
        raise NotImplementedError

    def elastic(self, q, part):
        """Elastic energy [J] and force (nq,) of the element."""
        raise NotImplementedError

    def domain_margins(self, q, part) -> list[Margin]:
        """The element's domain as :class:`Margin` s of its coordinates ``q`` (nq,) and its
        fields' symbols ``part``: inside where all hold (:func:`margins_hold`). The same
        rule as :meth:`Element.inside` (the kind's one function evaluates both); an
        element without coordinates has none."""
        return []

    def damping(self, part):
        """Damping matrix (nq, nq)."""
        return part["damping"] if self.nq else ca.SX(0, 0)

    def creep(self, part):
        """``(rate, gain, compliance)`` of the element's creep, or None."""
        if not self.n_creep:
            return None
        return part["creep.rate"], part["creep.gain"], part["creep.compliance"]


class SoftModel(ElementModel):
    """Kinematics shared by the soft kinds: a material point ``s`` is reached by the
    SE(3) exponential of a constant twist, rotation vector ``w(q, s)`` and translation
    ``t(q, s)`` (both linear in ``s``): rotation ``exp([w]x)``, position ``Jl(w) t``
    with ``Jl`` the left Jacobian of SO(3), since ``int_0^1 exp(x [w]x) dx = Jl(w)``.
    The body angular velocity is ``Jr(w) dw/dt``, ``Jr`` the right Jacobian. The
    trigonometric factors are smooth functions of ``|w|^2`` (:mod:`softcurve.base.smooth`),
    exact at zero strain: nothing is added to the state.

    Slices: Gauss-Legendre nodes, uniform mass, rotational inertia per unit mass
    :meth:`slice_inertia` (m^2) in the slice's frame.
    """

    def rotation_vector(self, q, s, g):
        """``w`` (3,) [rad] of point ``s``."""
        raise NotImplementedError

    def translation(self, q, s, g):
        """``t`` (3,) [m] of point ``s``: the body-frame displacement per unit ``Jl``."""
        raise NotImplementedError

    def mass(self, g):
        """The element's mass [kg]."""
        raise NotImplementedError

    def slice_inertia(self, g):
        """Rotational inertia per unit mass (3,) [m^2] of a slice, its own frame."""
        raise NotImplementedError

    def point_pose(self, q, s, g):
        w = self.rotation_vector(q, s, g)
        wx, z = ca.skew(w), ca.dot(w, w)
        wx2 = wx @ wx
        rotation = ca.SX.eye(3) + _smooth.sinc(z) * wx + _smooth.cosc(z) * wx2
        left_jacobian = ca.SX.eye(3) + _smooth.cosc(z) * wx + _smooth.sinc3(z) * wx2
        return rotation, left_jacobian @ self.translation(q, s, g)

    def angular_jacobian(self, q, s, g):
        w = self.rotation_vector(q, s, g)
        wx, z = ca.skew(w), ca.dot(w, w)
        right_jacobian = ca.SX.eye(3) - _smooth.cosc(z) * wx + _smooth.sinc3(z) * (wx @ wx)
        return right_jacobian @ ca.jacobian(w, q)

    def bodies(self, g, quadrature_nodes: int) -> list[Body]:
        nodes, weights = np.polynomial.legendre.leggauss(quadrature_nodes)
        mass, inertia = self.mass(g), ca.diag(self.slice_inertia(g))
        return [
            Body(0.5 * (x + 1.0), 0.5 * w * mass, 0.5 * w * mass * inertia)
            for x, w in zip(nodes, weights, strict=True)
        ]
