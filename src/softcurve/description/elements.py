"""The kinds of element a robot's chain is made of, one module per kind, as Pinocchio's
joint models: the constant-curvature :class:`Segment` (the paper's;
:mod:`softcurve.description.curvature`), the :class:`StrainSegment` of piecewise
constant strain that chooses among the six Cosserat strains
(:mod:`softcurve.description.strain`), and the :class:`RigidBody` that adds no
coordinates (:mod:`softcurve.description.rigid`). Each declares its coordinates (count,
names, units), rest state, scale, domain and parameter fields, and its model
(:func:`element_model`) the pose and Jacobians, mass, energy, damping and creep as
CasADi expressions (:mod:`softcurve.description.kind` says what every kind declares).
This module is their table: the kinds by name, and the names others import.
"""

from softcurve.description.curvature import (
    DAMPING_UNITS,
    MAX_BEND,
    MAX_REST_LENGTH,
    MAX_STRETCH,
    CurvatureModel,
    Segment,
    curvature_margins,
    segment_inside,
    segment_problem,
)
from softcurve.description.kind import (
    Body,
    Element,
    ElementModel,
    FieldSpec,
    Margin,
    SoftModel,
    margins_hold,
)
from softcurve.description.rigid import RigidBody, RigidModel, rotation_matrix
from softcurve.description.strain import (
    GROUPS,
    MAX_SHEAR,
    MAX_TWIST,
    REST_STRAIN,
    STRAIN_UNITS,
    STRAINS,
    StrainModel,
    StrainSegment,
    strain_margins,
)

KINDS = {
    Segment.kind: (Segment, CurvatureModel),
    StrainSegment.kind: (StrainSegment, StrainModel),
    RigidBody.kind: (RigidBody, RigidModel),
}
"""Each kind's name (the first entry of its signature): its element and model classes."""


def element_model(signature: tuple) -> ElementModel:
    """The model of the element of ``signature`` (:meth:`Element.signature`).

    Parameters
    ----------
    signature : tuple
        ``(kind, ...)``.
    """
    return KINDS[signature[0]][1](signature)


def coordinate_slices(structure: tuple) -> tuple[slice, ...]:
    """Where each element's coordinates lie in ``q``, from a structure alone (the robot's
    own table is :attr:`Robot.offsets` and :attr:`Robot.sizes`): Pinocchio's ``idx_q``
    and ``nq`` as slices; the last one's ``stop`` is the number of coordinates ``n``.

    Parameters
    ----------
    structure : tuple
        ``Robot.structure()``: each element's signature.
    """
    slices, start = [], 0
    for signature in structure:
        size = element_model(signature).nq
        slices.append(slice(start, start + size))
        start += size
    return tuple(slices)


__all__ = [
    "DAMPING_UNITS",
    "GROUPS",
    "KINDS",
    "MAX_BEND",
    "MAX_REST_LENGTH",
    "MAX_SHEAR",
    "MAX_STRETCH",
    "MAX_TWIST",
    "REST_STRAIN",
    "STRAINS",
    "STRAIN_UNITS",
    "Body",
    "CurvatureModel",
    "Element",
    "ElementModel",
    "FieldSpec",
    "Margin",
    "RigidBody",
    "RigidModel",
    "Segment",
    "SoftModel",
    "StrainModel",
    "StrainSegment",
    "curvature_margins",
    "coordinate_slices",
    "element_model",
    "margins_hold",
    "rotation_matrix",
    "segment_inside",
    "segment_problem",
    "strain_margins",
]
