"""The actuator interface: bounded inputs ``u`` (m,) acting on a robot as ``tau = H(q) u``.

:class:`Actuator` is the one route by which actuator inputs reach the robot, in
simulation, statics, linearization, quasi-static maps, control and C export. A kind of
actuator says what its inputs are (``input_name``, ``input_unit``), gives ``H(q)``
symbolically (:meth:`Actuator.input_matrix_symbolic`) and the work ``W(q)`` of constant
inputs (:meth:`Actuator.input_work_symbolic`, whose gradient is ``H(q) u``), and holds
its bounds ``lower <= u <= upper`` and an optional first-order lag of the inputs behind
their commands. Pneumatic chambers (:mod:`softcurve.description.bellows`, pressures
[Pa]) implement it; tendons (``tau = -J_L(q)^T T``, tensions ``T >= 0`` [N], work
``-L(q) . T``) fit the same methods.
"""

from __future__ import annotations

import dataclasses
import math

import casadi as ca
import numpy as np

from softcurve.base.docs import parameters_from
from softcurve.base.validation import ParameterError, real_array, real_scalar, whole_count
from softcurve.description.elements import Element
from softcurve.description.fibers import (
    Fiber,
    fiber_problem,
    fibers_inside,
    offset_fiber_gradient,
    offset_fiber_length,
    routing_problem,
)


def chain_elements(value) -> tuple | None:
    """The elements an actuator runs along: ``None`` (constant-curvature segments), a
    :class:`~softcurve.Robot` (its ``segments``) or a sequence of elements, checked.

    Parameters
    ----------
    value : Robot, sequence of Element or None
        What was given as ``elements``.
    """
    if value is None:
        return None
    value = getattr(value, "segments", value)
    try:
        elements = tuple(value)
    except TypeError:
        raise ParameterError(
            f"elements must be a Robot or a sequence of its elements, got {type(value).__name__}"
        ) from None
    if not elements:
        raise ParameterError("elements must hold at least one element, got none")
    for i, e in enumerate(elements):
        if not isinstance(e, Element):
            raise ParameterError(
                f"elements[{i}] must be a Segment, StrainSegment or RigidBody, got "
                f"{type(e).__name__}"
            )
    return elements


_FIBER_FIELDS = {"constant_strain": ("rest_length", "rest_strain"),
                 "rigid_body": ("tip_position", "tip_rotation")}  # fmt: skip
"""The numbers of an element a fiber's length depends on, per kind (a constant-curvature
segment's length is a coordinate)."""


def _elements_problem(elements, robot) -> str | None:
    """Why the actuator's ``elements`` do not describe ``robot``'s chain, or None."""
    if elements is None:
        if robot.constant_curvature:
            return None
        return (
            "the actuator was built for constant-curvature segments (no elements=), but the "
            "robot has other elements: build it with elements=robot"
        )
    structure = tuple(e.signature()[0] for e in elements)
    if structure != tuple(s[0] for s in robot.structure()) or tuple(
        e.n_coordinates for e in elements
    ) != tuple(robot.sizes):
        return (
            f"the actuator's elements {structure} are not the robot's "
            f"{tuple(s[0] for s in robot.structure())}: build it with elements=robot"
        )
    for i, (mine, theirs) in enumerate(zip(elements, robot.segments, strict=True)):
        if getattr(mine, "strains", None) != getattr(theirs, "strains", None):
            return f"elements[{i}] chooses strains {mine.strains}, the robot's {theirs.strains}"
        for name in _FIBER_FIELDS.get(mine.kind, ()):
            if not np.array_equal(getattr(mine, name), getattr(theirs, name)):
                return (
                    f"elements[{i}].{name} = {np.asarray(getattr(mine, name)).tolist()} differs "
                    f"from the robot's {np.asarray(getattr(theirs, name)).tolist()}: the fibers' "
                    "lengths depend on it; build the actuator with elements=robot"
                )
    return None


def optional_time_constant(value) -> float | None:
    """A first-order lag [s] > 0, or None for inputs that follow their command at once.

    Parameters
    ----------
    value : float or None
        The lag [s], checked.
    """
    return None if value is None else real_scalar("time_constant", value, positive=True)


_symbolic_parameters = parameters_from(
    {
        "q": (
            "casadi.SX or casadi.MX, shape (n,)",
            "Generalized coordinates (each element's, e.g. [m, 1/m, 1/m] of a segment).",
        ),
        "theta": (
            "casadi.SX or casadi.MX, shape (k,), optional",
            "Symbols replacing :meth:`parameter_vector` (e.g. to identify areas).",
        ),
    }
)


@_symbolic_parameters
class Actuator:
    """An actuator: bounded inputs ``u`` (m,) acting on the robot as ``tau = H(q) u``.

    Subclasses set the attributes below (in ``__post_init__`` of a frozen dataclass) and
    implement :meth:`input_matrix_symbolic`, :meth:`input_work_symbolic`,
    :meth:`parameter_vector` and :meth:`parameter_names` (the last two come from the
    parts for an actuator made of parts, ``_parts_field``).

    Attributes
    ----------
    n : int
        Number of generalized coordinates (``3 N`` for constant-curvature segments, the
        sum of the elements' otherwise).
    n_inputs : int
        Number of inputs ``m``.
    lower, upper : ndarray, shape (m,)
        Input bounds [``input_unit``].
    time_constant : float or None
        First-order lag of the inputs behind their commands [s]; None for inputs that
        follow their command at once.
    input_name : str
        What the inputs are (``"pressures"``, ``"tensions"``), for messages.
    input_unit : str
        Their unit (``"Pa"``, ``"N"``).
    """

    n: int
    n_inputs: int
    lower: np.ndarray
    upper: np.ndarray
    time_constant: float | None
    input_name: str = "inputs"
    input_unit: str = ""
    conservative: bool = True
    """True when constant inputs do the work :meth:`input_work_symbolic` exactly (no
    friction); statics then classify equilibria by a symmetric Hessian."""

    # -- the map ---------------------------------------------------------------------
    def input_matrix_symbolic(self, q, theta=None):
        """``H(q)`` (n, m) as a CasADi expression: the generalized force per unit input,
        [N, N m^2, N m^2] per ``input_unit`` (for pressures [m^2, m^4, m^4]).

        Parameters
        ----------
        %(q)s
        %(theta)s
        """
        raise NotImplementedError

    def input_work_symbolic(self, q, inputs):
        """``W(q)`` [J] with ``dW/dq = H(q) u`` at constant inputs ``u`` (CasADi scalar).

        Constant inputs are conservative: ``-W`` is their potential, and its Hessian
        enters the stability of an equilibrium (:mod:`softcurve.analysis.statics`).

        Parameters
        ----------
        %(q)s
        inputs : casadi.SX or casadi.MX, shape (m,)
            Constant inputs [``input_unit``].
        """
        raise NotImplementedError

    def parameter_vector(self) -> np.ndarray:
        """The numbers ``H`` depends on, named by :meth:`parameter_names`; of an actuator
        made of parts, each part's ``_part_parameters`` in turn."""
        if not self._parts_field:
            raise NotImplementedError
        return np.array(
            [getattr(p, name) for p in self._parts() for name in self._part_parameters],
            dtype=np.float64,
        )

    def parameter_names(self) -> list[str]:
        """Names of the entries of :meth:`parameter_vector`."""
        if not self._parts_field:
            raise NotImplementedError
        return [
            f"{self._parts_field}[{i}].{n}"
            for i in range(len(self._parts()))
            for n in self._part_parameters
        ]

    def with_parameter_vector(self, vector) -> Actuator:
        """This actuator with its :meth:`parameter_vector` replaced by ``vector``,
        validated as a new actuator (a distance must stay > 0, ...); the actuator itself
        when ``vector`` equals its own.

        Parameters
        ----------
        vector : array_like, shape (k,)
            Values in the order of :meth:`parameter_names`, each in its unit.
        """
        names = self.parameter_names()
        vector = real_array("actuator parameters", vector, (len(names),))
        if np.array_equal(vector, self.parameter_vector()):
            return self
        return self._rebuilt(vector)

    # Actuators made of parts (bellows, tendons) name the field that holds the parts and
    # the parts' fields that are parameters; the three methods below then need no more.
    _parts_field: str = ""
    _part_parameters: tuple[str, ...] = ()
    _fiber_kind: str = ""  # "tendon" (checked by length) or "chamber" (by volume)

    def _init_parts(self, part_type: type, beyond, bounds: tuple[str, str]) -> None:
        """Check and store the parts (a single part or a non-empty sequence of
        ``part_type``), ``elements`` and ``n_segments``, then set ``time_constant``, ``n``,
        ``n_inputs``, ``lower`` and ``upper`` (from the parts' fields ``bounds``).
        ``beyond(part, n_segments)`` says what of a part lies beyond the robot's last
        segment (``"anchor = 2 is beyond ..."``), or None."""
        field, given = self._parts_field, getattr(self, self._parts_field)
        parts = (given,) if isinstance(given, part_type) else given
        kind = part_type.__name__
        try:
            parts = tuple(parts)
        except TypeError:
            raise ParameterError(
                f"{field} must be a sequence of {kind}, got {type(given).__name__}"
            ) from None
        if not parts:
            raise ParameterError(f"{field} must hold at least one {kind}, got none")
        for i, part in enumerate(parts):
            if not isinstance(part, part_type):
                raise ParameterError(f"{field}[{i}] must be a {kind}, got {type(part).__name__}")
        elements = chain_elements(self.elements)
        if elements is None:
            n_segments = whole_count(
                "n_segments", 1 if self.n_segments is None else self.n_segments
            )
            n = 3 * int(n_segments)
        else:
            n_segments = len(elements)
            if self.n_segments is not None and self.n_segments != n_segments:
                raise ParameterError(
                    f"n_segments = {self.n_segments!r} differs from the {n_segments} elements "
                    "given (elements=); leave n_segments out"
                )
            n = sum(e.n_coordinates for e in elements)
        for i, part in enumerate(parts):
            problem = beyond(part, n_segments)
            if problem is not None:
                raise ParameterError(f"{field}[{i}].{problem}")
        set_ = object.__setattr__  # frozen dataclasses: normalized once, here
        set_(self, field, parts)
        set_(self, "elements", elements)
        set_(self, "n_segments", int(n_segments))
        set_(self, "time_constant", optional_time_constant(self.time_constant))
        set_(self, "n", n)
        set_(self, "n_inputs", len(parts))
        for name, attribute in zip(("lower", "upper"), bounds, strict=True):
            values = [getattr(part, attribute) for part in parts]
            set_(self, name, real_array(attribute, values, (len(parts),)))

    def _place(self, j: int) -> dict:
        """Element ``j`` and the index of its first coordinate, as the fiber functions
        take them (``{}``: a constant-curvature segment at ``3 j``)."""
        if self.elements is None:
            return {}
        offset = sum(e.n_coordinates for e in self.elements[:j])
        return {"element": self.elements[j], "offset": offset}

    def _parts(self) -> tuple:
        return getattr(self, self._parts_field)

    def _part_values(self, i: int, theta) -> tuple:
        """The ``_part_parameters`` of part ``i``: its fields, or with ``theta`` (the
        symbols replacing :meth:`parameter_vector`) the entries standing for them."""
        if theta is None:
            part = self._parts()[i]
            return tuple(getattr(part, name) for name in self._part_parameters)
        k = len(self._part_parameters)
        return tuple(theta[k * i + c] for c in range(k))

    # Parts that are offset fibers (bellows, tendons) have the fields ``azimuth`` and
    # ``distance`` first among their parameters and run through ``part.segments``.
    def segment_lengths_symbolic(self, q, theta=None) -> list[list]:
        """Lengths ``L_ij(q)`` [m] of part ``i`` in each segment ``j`` of its
        ``segments`` (CasADi), one list per part.

        Parameters
        ----------
        %(q)s
        %(theta)s
        """
        lengths = []
        for i, part in enumerate(self._parts()):
            phi, rho = self._part_values(i, theta)[:2]
            lengths.append(
                [offset_fiber_length(q, j, phi, rho, **self._place(j)) for j in part.segments]
            )
        return lengths

    def fiber_lengths_symbolic(self, q, theta=None):
        """Lengths ``L_i(q)`` (m,) [m] of the parts, summed over their segments (CasADi).

        Parameters
        ----------
        %(q)s
        %(theta)s
        """
        return ca.vertcat(*[sum(parts) for parts in self.segment_lengths_symbolic(q, theta)])

    def _fiber_matrix_symbolic(self, q, theta, weights):
        """``H(q)`` whose column ``i`` is ``sum_j w_ij dL_ij/dq``, ``weights[i][k]`` the
        generalized force per unit input of part ``i`` along the ``k``-th of its
        ``segments`` (its area, minus its tension factor)."""
        columns = []
        for i, (part, row) in enumerate(zip(self._parts(), weights, strict=True)):
            phi, rho = self._part_values(i, theta)[:2]
            column = [0] * self.n
            for j, weight in zip(part.segments, row, strict=True):
                gradient = offset_fiber_gradient(q, j, phi, rho, **self._place(j))
                for k, g in enumerate(gradient):
                    if not isinstance(g, int):  # an int entry is a structural zero
                        column[k] = column[k] + weight * g
            columns.append(ca.vertcat(*column))
        return ca.horzcat(*columns)

    def _rebuilt(self, vector: np.ndarray) -> Actuator:
        """A new actuator of this kind with parameter vector ``vector`` (checked shape):
        each part rebuilt with its parameters replaced, so its own checks apply."""
        if not self._parts_field:
            raise NotImplementedError
        rebuilt = []
        values = vector.reshape(-1, len(self._part_parameters))
        for i, (part, row) in enumerate(zip(getattr(self, self._parts_field), values, strict=True)):
            try:
                rebuilt.append(
                    dataclasses.replace(part, **dict(zip(self._part_parameters, row, strict=True)))
                )
            except ParameterError as exc:
                raise ParameterError(f"{self._parts_field}[{i}]: {exc}") from None
        return dataclasses.replace(self, **{self._parts_field: tuple(rebuilt)})

    def input_matrix(self, q) -> np.ndarray:
        """``H(q)``, shape (n, m), mapping inputs to generalized forces.

        Parameters
        ----------
        q : array_like, shape (n,)
            Generalized coordinates [m, 1/m, 1/m].
        """
        q = self._coordinates(q)
        function = self.__dict__.get("_matrix_function")
        if function is None:
            symbol = ca.SX.sym("q", self.n)
            function = ca.Function("H", [symbol], [ca.densify(self.input_matrix_symbolic(symbol))])
            object.__setattr__(self, "_matrix_function", function)  # a cache, not state
        return np.array(function(q), dtype=np.float64)

    def generalized_force(self, q, inputs) -> np.ndarray:
        """``tau = H(q) u``, shape (n,); the inputs must lie within the bounds.

        Parameters
        ----------
        q : array_like, shape (n,)
            Generalized coordinates [m, 1/m, 1/m].
        inputs : array_like, shape (m,)
            Actuator inputs [``input_unit``].
        """
        return self.input_matrix(q) @ self.check_inputs(inputs)

    # -- the inputs ------------------------------------------------------------------
    def check_inputs(self, inputs, name: str | None = None) -> np.ndarray:
        """``inputs`` as a float64 array (m,), or :class:`ParameterError` if any is
        outside ``[lower, upper]`` or not finite.

        Parameters
        ----------
        inputs : array_like, shape (m,)
            Actuator inputs [``input_unit``].
        name : str, optional
            Name used in the error message (default :attr:`input_name`).
        """
        name = self.input_name if name is None else name
        u = real_array(name, inputs, (self.n_inputs,))
        bad = np.flatnonzero((u < self.lower) | (u > self.upper))
        if bad.size:
            i, unit = int(bad[0]), f" {self.input_unit}" if self.input_unit else ""
            raise ParameterError(
                f"{name}[{i}] = {float(u[i])!r}{unit} is outside its bounds "
                f"[{float(self.lower[i])!r}, {float(self.upper[i])!r}]{unit}"
            )
        return u

    def lag_start(self, state=None, name: str = "actuator_state") -> np.ndarray:
        """The inputs (m,) at which this actuator's first-order lag starts: ``state``
        checked against the bounds, or zero clipped into them.

        Parameters
        ----------
        state : array_like, shape (m,), optional
            The inputs at the start [``input_unit``].
        name : str
            Name used in the error messages.
        """
        if self.time_constant is None and state is not None:
            raise ParameterError(
                f"{name} is the initial state of a lagging actuator: give an actuator "
                "with a time_constant (without one its inputs follow their commands at once)"
            )
        if state is None:
            return np.clip(0.0, self.lower, self.upper)
        return self.check_inputs(state, name)

    def clip(self, inputs) -> np.ndarray:
        """Saturate inputs to ``[lower, upper]``.

        Parameters
        ----------
        inputs : array_like, shape (m,)
            Actuator inputs [``input_unit``].
        """
        u = np.asarray(inputs, dtype=np.float64)
        if u.shape != (self.n_inputs,):
            raise ValueError(f"{self.input_name} must have shape ({self.n_inputs},), got {u.shape}")
        return np.clip(u, self.lower, self.upper)

    def rest_inputs(self) -> np.ndarray:
        """The inputs at rest, zero saturated to the bounds, shape (m,)."""
        return self.clip(np.zeros(self.n_inputs))

    def input_rate(self, inputs, command) -> np.ndarray:
        """``u' = (c - u) / time_constant`` with the command ``c`` saturated first.

        Parameters
        ----------
        inputs : array_like, shape (m,)
            Current inputs [``input_unit``].
        command : array_like, shape (m,)
            Commanded inputs [``input_unit``].
        """
        if self.time_constant is None:
            raise ParameterError("input_rate needs a time_constant (this actuator has none)")
        return (self.clip(command) - np.asarray(inputs, dtype=np.float64)) / self.time_constant

    def input_step(self, inputs, command, dt: float) -> np.ndarray:
        """Exact inputs after holding ``command`` (saturated) for ``dt`` seconds.

        ``u(dt) = c + (u(0) - c) exp(-dt / time_constant)``; without a time constant the
        inputs equal the saturated command.

        Parameters
        ----------
        inputs : array_like, shape (m,)
            Inputs at the start [``input_unit``].
        command : array_like, shape (m,)
            Command held over the interval [``input_unit``].
        dt : float
            Length of the interval [s], >= 0.
        """
        c = self.clip(command)
        if self.time_constant is None:
            return c
        dt = real_scalar("dt", dt)
        if dt < 0:
            raise ParameterError(f"dt must be >= 0, got {dt!r}")
        u = np.asarray(inputs, dtype=np.float64)
        return c + (u - c) * math.exp(-dt / self.time_constant)

    # -- the domain (softcurve.description.domain) ------------------------------------
    def fibers(self) -> tuple:
        """The actuator's elements as offset fibers, one
        :class:`~softcurve.description.fibers.Fiber` per element and segment it runs
        through; none for an actuator without geometry (a constant map)."""
        if not self._parts_field:
            return ()
        return tuple(
            Fiber(
                f"{self._parts_field}[{i}]",
                self._fiber_kind,
                j,
                part.azimuth,
                part.distance,
                getattr(part, "area", None),
                **self._place(j),
            )
            for i, part in enumerate(self._parts())
            for j in part.segments
        )

    def in_domain(self, q) -> np.ndarray:
        """Whether every tendon length and chamber volume is > 0 at ``q``, vectorized.

        Parameters
        ----------
        q : array_like, shape (..., n)
            Configurations [m, 1/m, 1/m].

        Returns
        -------
        ndarray of bool, shape (...)
        """
        return fibers_inside(self.fibers(), q)

    def domain_problem(self, q) -> str | None:
        """What puts ``q`` outside the actuator's domain (the element, segment, value and
        allowed range), or None.

        Parameters
        ----------
        q : array_like, shape (n,)
            One configuration [m, 1/m, 1/m].
        """
        return fiber_problem(self.fibers(), self._coordinates(q))

    # -- helpers ---------------------------------------------------------------------
    def fiber_fields(self, robot) -> tuple[str, ...]:
        """The robot's parameter fields the actuator's fibers depend on, as they were when
        it was built (a constant-strain segment's rest length and rest strain, a rigid
        body's tip; e.g. ``"segments[0].rest_length"``): numbers a fit may not free, nor a
        batch vary, while this actuator drives the robot.

        Parameters
        ----------
        robot : Robot
            The robot driven.
        """
        if not self._parts_field:
            return ()
        return tuple(
            f"segments[{i}].{name}"
            for i, element in enumerate(robot.segments)
            for name in _FIBER_FIELDS.get(element.kind, ())
        )

    def check_robot(self, robot) -> None:
        """Raise :class:`ParameterError` unless the actuator fits ``robot``: its
        coordinates, its elements (an actuator built without ``elements`` drives
        constant-curvature segments only; one built with them, elements whose kinds and
        fiber geometry are the robot's) and its routing inside the body (every distance
        ``rho`` at most the radius of each element it runs through;
        :func:`~softcurve.description.fibers.routing_problem`).

        Parameters
        ----------
        robot : Robot
            The robot driven.
        """
        if robot.n != self.n:
            raise ParameterError(
                f"the actuator acts on n = {self.n} coordinates but the robot has "
                f"n = {robot.n} ({robot.n_segments} segments)"
            )
        if self._parts_field:
            problem = _elements_problem(getattr(self, "elements", None), robot)
            if problem is not None:
                raise ParameterError(problem)
        problem = routing_problem(self.fibers(), robot)
        if problem is not None:
            raise ParameterError(problem)

    def _coordinates(self, q) -> np.ndarray:
        q = np.asarray(q, dtype=np.float64)
        if q.shape != (self.n,):
            raise ValueError(f"q must have shape ({self.n},), got {q.shape}")
        return q
