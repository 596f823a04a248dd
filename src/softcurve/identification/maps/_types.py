"""The two kinds of map a fit uses: :class:`OutputMap` (state -> measured signals) and
:class:`InputMap` (measured inputs -> generalized forces).

Both are plain containers of a CasADi-building function, the names and units of what it
gives or reads, and the named *extra* parameters it reads with their nominal values.
The fits of :mod:`softcurve.identification.fits` estimate any extra parameter that
is listed in their ``free`` argument and hold the others at their nominal values (or at
the values given in their ``extra`` argument). The built-in maps are in
:mod:`softcurve.identification.maps` and
:mod:`softcurve.identification.maps`; ``docs/identify.md`` writes one by hand.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field


@dataclass(frozen=True)
class OutputMap:
    """Measured signals as a function of the state: ``y = function(q, qd, values, p)``.

    Built by :func:`~softcurve.identification.maps.bending_angle_map`,
    :func:`~softcurve.identification.maps.curvature_map`,
    :func:`~softcurve.identification.maps.marker_position_map`,
    :func:`~softcurve.identification.maps.tip_position_map` and
    :func:`~softcurve.identification.maps.imu_orientation_map`, or by hand for
    another sensor.

    Parameters
    ----------
    function : callable
        ``function(q, qd, values, p) -> y``: CasADi expressions (SX or MX) of the
        coordinates ``q`` (n,) [m, 1/m, 1/m], their rates ``qd`` (n,), the dict
        ``values`` of named extra parameters (one scalar expression each) and the robot's
        parameter vector ``p`` (laid out as ``robot.layout``); returns the (k,) outputs.
    names : tuple of str
        Labels of the k outputs, in order (the experiment's signal names by default).
    units : tuple of str
        Unit of each output (e.g. ``"deg"``, ``"1/m"``, ``"mm"``), in order.
    parameters : dict of str to float
        The named extra parameters ``function`` reads, with nominal values [unit of
        each parameter].
    robot_problem : callable, optional
        ``robot_problem(robot) -> str or None``: why the map cannot be used with a
        robot (it reads coordinates the robot does not have where it looks), checked
        by the fits before any work; None for a map that fits every robot.
    """

    function: Callable
    names: tuple[str, ...]
    units: tuple[str, ...]
    parameters: dict
    robot_problem: Callable | None = None


@dataclass(frozen=True)
class InputMap:
    """Generalized forces from measured inputs: ``tau = function(q, u, values)``.

    Built by :func:`~softcurve.identification.maps.bellows_input_map`,
    :func:`~softcurve.identification.maps.tendon_input_map`,
    :func:`~softcurve.identification.maps.constant_input_map` and
    :func:`~softcurve.identification.maps.actuator_input_map`, or by hand.

    Parameters
    ----------
    function : callable
        ``function(q, u, values) -> tau``: CasADi expressions of the coordinates ``q``
        [m, 1/m, 1/m], the measured inputs ``u`` (m,) in the experiment's input order
        and the dict ``values`` of named extra parameters; returns the (n,) generalized
        forces [N, N m^2, N m^2] per segment.
    parameters : dict of str to float
        The named extra parameters ``function`` reads, with nominal values [unit of
        each parameter].
    units : tuple of str
        The unit each input must be in (e.g. ``("Pa", "Pa", "Pa")``), checked against
        the experiment's units by
        :func:`~softcurve.identification.experiments.check_units`; empty when unspecified.
    actuator : Actuator or None
        The actuator of fixed geometry the inputs act through, whose domain (tendon
        lengths, chamber volumes > 0) every fitted equilibrium must lie in
        (:func:`~softcurve.description.domain.states_inside`); None when unknown or
        when its geometry is identified (then only the robot's domain is checked).
    robot_problem : callable, optional
        ``robot_problem(robot) -> str or None``: why the map cannot drive ``robot`` (a
        map written for constant-curvature segments on a robot of other kinds), checked
        by every fit before any work.
    fixed_fields : callable, optional
        ``fixed_fields(robot) -> tuple of str``: the robot's parameter fields the map's
        geometry was built with (an actuator's fibers along a strain segment), which a fit
        may not free.
    """

    function: Callable
    parameters: dict
    units: tuple[str, ...] = field(default=())
    actuator: object = None
    robot_problem: Callable | None = None
    fixed_fields: Callable | None = None
