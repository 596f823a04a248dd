"""The one owner of the parameter vector's layout: which number of a robot sits where.

The compiled model reads every number of a robot (geometry, masses, stiffness laws,
damping, creep, gravity, base rotation) from one run-time vector ``p``, so that one
compiled library serves every robot of the same :meth:`Robot.structure`. Everything
that reads or writes ``p`` (the robot, the symbolic model, static loads, sweeps,
identification) asks a :class:`ParameterLayout` where a field lies instead of counting.

Matrices (damping, creep compliance, inertia, rotations) are stored row by row.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass

import casadi as ca
import numpy as np

from softcurve.base.validation import ParameterError
from softcurve.description.elements import element_model

_VECTOR3 = ("[0]", "[1]", "[2]")
_MATRIX3 = tuple(f"[{i},{j}]" for i in range(3) for j in range(3))


@dataclass(frozen=True)
class ParameterField:
    """One named block of the parameter vector.

    Parameters
    ----------
    name : str
        Field path, e.g. ``"segments[0].damping"`` or ``"gravity"``.
    start : int
        Index of its first entry in the vector.
    shape : tuple of int
        ``()`` for a scalar, ``(k,)`` for a vector, ``(k, k)`` for a matrix (row major).
    labels : tuple of str
        Suffix of each entry's name: ``""`` for a scalar, ``".k0"`` for a stiffness-law
        parameter, ``"[0]"`` or ``"[0,1]"`` for vector and matrix entries.
    units : tuple of str
        Each entry's unit (``"N/m"``; ``""`` for a number without one, or whose unit is
        the user's choice, as a creep state's).
    """

    name: str
    start: int
    shape: tuple[int, ...]
    labels: tuple[str, ...]
    units: tuple[str, ...]

    @property
    def size(self) -> int:
        """Number of entries."""
        return len(self.labels)

    @property
    def slice(self) -> slice:
        """Where the field lies in the vector."""
        return slice(self.start, self.start + self.size)

    @property
    def entry_names(self) -> tuple[str, ...]:
        """The names of its entries, e.g. ``("gravity[0]", "gravity[1]", "gravity[2]")``."""
        return tuple(self.name + label for label in self.labels)


class ParameterLayout:
    """Names and slices of the parameter vector of one robot structure.

    Parameters
    ----------
    structure : tuple
        :meth:`Robot.structure`: each element's signature; the element kinds'
        models (:func:`~softcurve.description.elements.element_model`) list their
        fields.

    Examples
    --------
    >>> import softcurve as sc
    >>> layout = sc.presets.ifac2020().layout
    >>> layout.slice("gravity")
    slice(33, 36, None)
    >>> layout.names[3]
    'segments[0].elongation_stiffness.a1'
    """

    def __init__(self, structure: tuple):
        fields: list[ParameterField] = []

        def add(name, shape, labels, units):
            start = fields[-1].start + fields[-1].size if fields else 0
            labels = tuple(labels)
            units = (units,) * len(labels) if isinstance(units, str) else tuple(units)
            fields.append(ParameterField(name, start, shape, labels, units))

        for k, signature in enumerate(structure):
            for spec in element_model(signature).fields():
                add(f"segments[{k}].{spec.name}", spec.shape, spec.labels, spec.units)
        add("gravity", (3,), _VECTOR3, "m/s^2")
        add("base_rotation", (3, 3), _MATRIX3, "")
        add("base_position", (3,), _VECTOR3, "m")
        count = len(structure)
        add("span_weights", (count,), tuple(f"[{i}]" for i in range(count)), "")
        self.structure = structure
        self.fields: tuple[ParameterField, ...] = tuple(fields)
        self.size: int = fields[-1].start + fields[-1].size
        self.names: tuple[str, ...] = tuple(n for f in fields for n in f.entry_names)
        self.units: tuple[str, ...] = tuple(u for f in fields for u in f.units)
        self._fields = {f.name: f for f in fields}
        self._entries = {name: i for i, name in enumerate(self.names)}

    @classmethod
    @functools.lru_cache(maxsize=64)
    def of_structure(cls, structure: tuple) -> ParameterLayout:
        """The layout of ``structure``, built once per structure.

        Parameters
        ----------
        structure : tuple
            :meth:`Robot.structure`.
        """
        return cls(structure)

    def __repr__(self) -> str:
        return f"ParameterLayout({len(self.fields)} fields, {self.size} entries)"

    # -- look-ups ------------------------------------------------------------------------
    def field(self, name: str) -> ParameterField:
        """The field called ``name``; ParameterError if none.

        Parameters
        ----------
        name : str
            A field path, e.g. ``"segments[1].mass"`` or ``"gravity"``.
        """
        try:
            return self._fields[name]
        except KeyError:
            raise ParameterError(self._unknown("field", name, list(self._fields))) from None

    def index(self, name: str) -> int:
        """Position of the entry ``name`` in the vector; ParameterError if none.

        Parameters
        ----------
        name : str
            An entry of :attr:`names`, e.g. ``"gravity[2]"``.
        """
        try:
            return self._entries[name]
        except KeyError:
            raise ParameterError(self._unknown("parameter", name, list(self.names))) from None

    def unit(self, name: str) -> str:
        """The unit of the entry ``name`` (``""`` where it has none or the user chooses
        it); ParameterError if there is no such entry.

        Parameters
        ----------
        name : str
            An entry of :attr:`names`, e.g. ``"segments[0].elongation_stiffness.a1"``.

        Returns
        -------
        str
            E.g. ``"N/m"``.
        """
        return self.units[self.index(name)]

    def label(self, name: str) -> str:
        """The entry ``name`` in words with its unit, for an axis or a table.

        Parameters
        ----------
        name : str
            An entry of :attr:`names`.

        Returns
        -------
        str
            E.g. ``"segment 0: elongation stiffness a1 [N/m]"`` for
            ``"segments[0].elongation_stiffness.a1"``.

        Examples
        --------
        >>> import softcurve as sc
        >>> layout = sc.presets.ifac2020().layout
        >>> layout.label("segments[0].bending_stiffness.a3"), layout.label("gravity[2]")
        ('segment 0: bending stiffness a3 [1/rad]', 'gravity[2] [m/s^2]')
        """
        unit = self.unit(name)
        words = re.sub(r"^segments\[(\d+)\]\.", r"segment \1: ", name)
        words = re.sub(r"\.(?=[a-z])", " ", words).replace("_", " ")
        return f"{words} [{unit}]" if unit else words

    def slice(self, name: str) -> slice:
        """Where a field or a single entry lies in the vector.

        Parameters
        ----------
        name : str
            A field (``"gravity"``) or an entry (``"gravity[2]"``).
        """
        if name in self._fields:
            return self._fields[name].slice
        i = self.index(name)
        return slice(i, i + 1)

    def __contains__(self, name: str) -> bool:
        return name in self._entries or name in self._fields

    @staticmethod
    def _unknown(kind: str, name: str, known: list[str]) -> str:
        close = [k for k in known if name.split("[")[0].split(".")[-1] in k][:3]
        hint = f"; did you mean {', '.join(map(repr, close))}?" if close else ""
        return (
            f"{name!r} is not a {kind} of this robot (the robot's parameter_names() lists "
            f"the {len(known)} entries){hint}"
        )

    # -- vectors -------------------------------------------------------------------------
    def split(self, p) -> dict:
        """Each field's part of ``p``, matrices as 3 x 3, scalars as one-entry parts.

        Parameters
        ----------
        p : ndarray or casadi.SX, shape (size,)
            A parameter vector, numeric or symbolic.

        Returns
        -------
        dict
            ``{field name: part}``.
        """
        parts = {}
        for f in self.fields:
            part = p[f.slice]
            if len(f.shape) == 2:
                rows, columns = f.shape
                part = (
                    part.reshape(rows, columns)
                    if isinstance(part, np.ndarray)
                    else ca.reshape(part, columns, rows).T
                )
            parts[f.name] = part
        return parts

    def element_parts(self, p) -> list[dict]:
        """Each element's fields of ``p`` by their names on the element (``"mass"``,
        ``"creep.rate"``), as :meth:`split` gives them.

        Parameters
        ----------
        p : ndarray or casadi.SX, shape (size,)
            A parameter vector.
        """
        part = self.split(p)
        elements = []
        for k in range(len(self.structure)):
            head = f"segments[{k}]."
            elements.append({n[len(head) :]: v for n, v in part.items() if n.startswith(head)})
        return elements

    def pack(self, robot) -> np.ndarray:
        """The parameter vector of ``robot``, shape (size,).

        Parameters
        ----------
        robot : Robot
            A robot whose structure is this layout's.
        """
        self._check_structure(robot)
        vector = np.empty(self.size)
        for f in self.fields:
            vector[f.slice] = np.ravel(_read(robot, f.name))
        return vector

    def unpack(self, vector, robot):
        """The robot of ``robot``'s structure whose parameter vector is ``vector``.

        Segments, stiffness-law types and creep stay; every number is taken from
        ``vector`` and validated again by the robot's constructors.

        Parameters
        ----------
        vector : array_like, shape (size,)
            Values in the order of :attr:`names`.
        robot : Robot
            A robot whose structure is this layout's.
        """
        self._check_structure(robot)
        vector = np.asarray(vector, dtype=np.float64)
        if vector.shape != (self.size,):
            raise ParameterError(
                f"a parameter vector must have shape ({self.size},), got {vector.shape}"
            )
        value = {f.name: vector[f.slice].reshape(f.shape) for f in self.fields}
        segments = []
        for k, s in enumerate(robot.segments):
            head = f"segments[{k}]."
            own = {name[len(head) :]: v for name, v in value.items() if name.startswith(head)}
            segments.append(s.with_values(own))
        spans = value["span_weights"]
        if robot.spans is None and np.all(spans == 1):
            spans = None  # equal spans stay the default, whatever the elements become
        return robot.replace(
            segments=tuple(segments),
            gravity=value["gravity"],
            base_rotation=value["base_rotation"],
            base_position=value["base_position"],
            spans=spans,
        )

    def _check_structure(self, robot) -> None:
        if robot.structure() != self.structure:
            raise ParameterError(
                f"the robot's structure {robot.structure()} is not this layout's {self.structure}"
            )


def _read(robot, name: str):
    """The value of the field ``name`` of ``robot`` (e.g. ``"segments[0].creep.rate"``)."""
    if name.startswith("segments["):
        index, path = name[len("segments[") :].split("].", 1)
        owner = robot.segments[int(index)]
    else:
        owner, path = robot, name
    for attribute in path.split("."):
        owner = getattr(owner, attribute)
    return owner.parameters() if hasattr(owner, "parameters") else owner
