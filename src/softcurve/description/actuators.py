"""Pneumatic actuation: from chamber pressures to generalized forces, ``tau = H(q) p``.

Two maps share one interface (:class:`Actuator`):

- :class:`PneumaticActuator`, a set of :class:`Bellows`, derives ``H(q)`` from the
  virtual work of the chamber pressures (MODEL.md, "Pneumatic actuation"). A bellow
  at azimuth ``phi`` (from +x toward +y in the segment's cross-section) and distance
  ``rho`` from the backbone is an offset fibre of the constant-curvature arc, of length
  ``L = l (1 - rho (kx cos phi + ky sin phi))``; its volume is ``V = A L`` and a gauge
  pressure ``p`` does the work ``p dV``, so ``tau = sum_i p_i A_i dL_i/dq``::

      dL/dl  = 1 - rho (kx cos phi + ky sin phi)
      dL/dkx = -l rho cos phi
      dL/dky = -l rho sin phi

  A pressurised bellow lengthens the robot and bends it AWAY from itself (the bellow
  at ``phi = 0`` pushes ``kx`` negative). The offset fibre has positive length while
  ``rho kappa < 1``.
- :class:`ConstantPressureMap` is a user-given constant ``H`` (``n x m``), e.g. the
  authors' fitted form (:meth:`ConstantPressureMap.authors_fit`).

Multi-segment robots: a bellow belongs to the segments listed in ``Bellows.segments``
(default ``(0,)``). The usual design, one module with its own chambers per segment, is
``PneumaticActuator.three_bellows(..., n_segments=N)``: three bellows per segment, each
acting on its own segment's coordinates only. A chamber that runs through several
segments (``segments=(0, 1)``) has the volume ``A sum_j L(q_j)`` and acts on all of them;
the azimuth is measured in each segment's cross-section, which is continuous along the
chain because the PCC frames do not twist.

Pressures are gauge pressures [Pa], bounded to ``[p_min, p_max]``; ``p_min`` is 0 for
the usual positive-pressure robot and may go down to ``-ATMOSPHERIC_PRESSURE`` for a
vacuum-driven one. An optional first-order lag ``p' = (p_cmd - p) / time_constant``
models the valves and tubing; :meth:`Actuator.input_step` gives its exact response
to a command held over an interval.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import casadi as ca
import numpy as np

from softcurve.base.validation import ParameterError, real_array, real_scalar

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


def _time_constant(value) -> float | None:
    return None if value is None else real_scalar("time_constant", value, positive=True)


@dataclass(frozen=True)
class Bellows:
    """One pneumatic chamber parallel to the backbone.

    Parameters
    ----------
    azimuth : float
        Angle ``phi`` [rad] of the chamber's centre line in the cross-section, from +x
        toward +y.
    distance : float
        ``rho`` [m], > 0, from the backbone to the chamber's centre line.
    area : float
        Effective cross-section ``A`` [m^2], > 0.
    p_max : float
        Upper pressure bound [Pa, gauge], > p_min.
    p_min : float
        Lower pressure bound [Pa, gauge], default 0; negative only for vacuum actuation,
        never below ``-ATMOSPHERIC_PRESSURE``.
    segments : tuple of int
        Indices of the segments the chamber runs through (default ``(0,)``).
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


class Actuator:
    """An actuator: bounded inputs ``u`` (m,) acting on the robot as ``tau = H(q) u``.

    The one interface through which inputs drive a robot, in simulation, statics,
    linearization, control and code export: pressures [Pa] for
    :class:`PneumaticActuator` and :class:`ConstantPressureMap`; any other actuator
    (tendons) implements the same methods.

    Attributes
    ----------
    n : int
        Number of generalized coordinates (``3 N``).
    n_inputs : int
        Number of pressures ``m``.
    lower, upper : ndarray, shape (m,)
        Pressure bounds [Pa, gauge].
    time_constant : float or None
        First-order pressure lag [s]; None for pressures that follow their command at once.
    """

    n: int
    n_inputs: int
    lower: np.ndarray
    upper: np.ndarray
    time_constant: float | None

    # -- the map ---------------------------------------------------------------------
    def input_matrix_symbolic(self, q, theta=None):
        """``H(q)`` (n, m) as a CasADi expression of ``q``; ``theta`` may replace
        :meth:`parameter_vector` by symbols (e.g. to identify areas)."""
        raise NotImplementedError

    def input_work_symbolic(self, q, pressures):
        """``W(q)`` with ``dW/dq = H(q) p`` at constant pressures ``p`` (CasADi scalar) [J].

        Constant pressures are conservative: ``-W`` is their potential, and its Hessian
        enters the stability of an equilibrium (:mod:`softcurve.statics`).
        """
        raise NotImplementedError

    def parameter_vector(self) -> np.ndarray:
        """The numbers ``H`` depends on, named by :meth:`parameter_names`."""
        raise NotImplementedError

    def parameter_names(self) -> list[str]:
        raise NotImplementedError

    def input_matrix(self, q) -> np.ndarray:
        """``H(q)``, shape (n, m), mapping pressures [Pa] to generalized forces."""
        q = self._coordinates(q)
        function = self.__dict__.get("_matrix_function")
        if function is None:
            symbol = ca.SX.sym("q", self.n)
            function = ca.Function("H", [symbol], [ca.densify(self.input_matrix_symbolic(symbol))])
            object.__setattr__(self, "_matrix_function", function)  # a cache, not state
        return np.array(function(q), dtype=np.float64)

    def generalized_force(self, q, pressures) -> np.ndarray:
        """``tau = H(q) p``, shape (n,); the pressures must lie within the bounds."""
        return self.input_matrix(q) @ self.check_inputs(pressures)

    # -- pressures -------------------------------------------------------------------
    def check_inputs(self, pressures, name: str = "pressures") -> np.ndarray:
        """``pressures`` as a float64 array (m,), or :class:`ParameterError` if any is
        outside ``[lower, upper]`` or not finite."""
        p = real_array(name, pressures, (self.n_inputs,))
        bad = np.flatnonzero((p < self.lower) | (p > self.upper))
        if bad.size:
            i = int(bad[0])
            raise ParameterError(
                f"{name}[{i}] = {float(p[i])!r} Pa is outside its bounds "
                f"[{float(self.lower[i])!r}, {float(self.upper[i])!r}] Pa"
            )
        return p

    def clip(self, pressures) -> np.ndarray:
        """Saturate pressures (m,) to ``[lower, upper]``."""
        p = np.asarray(pressures, dtype=np.float64)
        if p.shape != (self.n_inputs,):
            raise ValueError(f"pressures must have shape ({self.n_inputs},), got {p.shape}")
        return np.clip(p, self.lower, self.upper)

    def input_rate(self, pressures, command) -> np.ndarray:
        """``p' = (p_cmd - p) / time_constant`` with the command saturated first [Pa/s]."""
        if self.time_constant is None:
            raise ParameterError("input_rate needs a time_constant (this map has none)")
        return (self.clip(command) - np.asarray(pressures, dtype=np.float64)) / self.time_constant

    def input_step(self, pressures, command, dt: float) -> np.ndarray:
        """Exact pressures after holding ``command`` (saturated) for ``dt`` seconds.

        ``p(dt) = c + (p(0) - c) exp(-dt / time_constant)``; without a time constant the
        pressures equal the saturated command.
        """
        c = self.clip(command)
        if self.time_constant is None:
            return c
        dt = real_scalar("dt", dt)
        if dt < 0:
            raise ParameterError(f"dt must be >= 0, got {dt!r}")
        p = np.asarray(pressures, dtype=np.float64)
        return c + (p - c) * math.exp(-dt / self.time_constant)

    # -- helpers ---------------------------------------------------------------------
    def check_robot(self, robot) -> None:
        """Raise :class:`ParameterError` unless the map fits ``robot``'s coordinates."""
        if robot.n != self.n:
            raise ParameterError(
                f"the pressure map acts on n = {self.n} coordinates but the robot has "
                f"n = {robot.n} ({robot.n_segments} segments)"
            )

    def _coordinates(self, q) -> np.ndarray:
        q = np.asarray(q, dtype=np.float64)
        if q.shape != (self.n,):
            raise ValueError(f"q must have shape ({self.n},), got {q.shape}")
        return q


@dataclass(frozen=True, eq=False)
class PneumaticActuator(Actuator):
    """Bellows whose ``H(q)`` follows from the virtual work of their pressures.

    Parameters
    ----------
    bellows : sequence of Bellows
        The chambers, in the order of the pressure vector.
    n_segments : int
        Number of segments of the robot driven (``n = 3 n_segments``); every
        ``Bellows.segments`` index must be below it.
    time_constant : float or None
        First-order pressure lag [s], or None.
    """

    bellows: tuple[Bellows, ...]
    n_segments: int = 1
    time_constant: float | None = None

    def __post_init__(self):
        if isinstance(self.bellows, Bellows):
            object.__setattr__(self, "bellows", (self.bellows,))
        bellows = tuple(self.bellows)
        if not bellows:
            raise ParameterError("bellows must hold at least one Bellows, got none")
        for i, b in enumerate(bellows):
            if not isinstance(b, Bellows):
                raise ParameterError(f"bellows[{i}] must be a Bellows, got {type(b).__name__}")
        if not (isinstance(self.n_segments, int | np.integer) and self.n_segments >= 1):
            raise ParameterError(f"n_segments must be an integer >= 1, got {self.n_segments!r}")
        for i, b in enumerate(bellows):
            if max(b.segments) >= self.n_segments:
                raise ParameterError(
                    f"bellows[{i}].segments = {b.segments} refers to a segment beyond "
                    f"n_segments = {self.n_segments}"
                )
        object.__setattr__(self, "bellows", bellows)
        object.__setattr__(self, "n_segments", int(self.n_segments))
        object.__setattr__(self, "time_constant", _time_constant(self.time_constant))
        object.__setattr__(self, "n", 3 * self.n_segments)
        object.__setattr__(self, "n_inputs", len(bellows))
        for name, values in (
            ("lower", [b.p_min for b in bellows]),
            ("upper", [b.p_max for b in bellows]),
        ):
            object.__setattr__(self, name, real_array(name, values, (len(bellows),)))

    @classmethod
    def three_bellows(
        cls,
        *,
        distance: float,
        area: float,
        p_max: float,
        p_min: float = 0.0,
        n_segments: int = 1,
        azimuths=DEFAULT_AZIMUTHS,
        time_constant: float | None = None,
    ) -> PneumaticActuator:
        """Identical bellows at ``azimuths`` in every segment (3 N pressures, segment by
        segment), each acting on its own segment."""
        bellows = tuple(
            Bellows(float(phi), distance, area, p_max, p_min, (j,))
            for j in range(n_segments)
            for phi in azimuths
        )
        return cls(bellows, n_segments=n_segments, time_constant=time_constant)

    def parameter_vector(self) -> np.ndarray:
        return np.array(
            [v for b in self.bellows for v in (b.azimuth, b.distance, b.area)], dtype=np.float64
        )

    def parameter_names(self) -> list[str]:
        return [
            f"bellows[{i}].{name}"
            for i in range(self.n_inputs)
            for name in ("azimuth", "distance", "area")
        ]

    def fibre_lengths_symbolic(self, q, theta=None):
        """Lengths ``L_i(q)`` (m,) [m] of the chambers' centre lines (CasADi)."""
        lengths = []
        for i, b in enumerate(self.bellows):
            phi, rho, _ = self._geometry(i, theta)
            total = 0
            for j in b.segments:
                length, kx, ky = q[3 * j], q[3 * j + 1], q[3 * j + 2]
                total += length * (1 - rho * (kx * ca.cos(phi) + ky * ca.sin(phi)))
            lengths.append(total)
        return ca.vertcat(*lengths)

    def input_work_symbolic(self, q, pressures):
        areas = ca.DM([b.area for b in self.bellows])
        return ca.dot(pressures * areas, self.fibre_lengths_symbolic(q))

    def volumes(self, q) -> np.ndarray:
        """Chamber volumes ``V_i = A_i L_i(q)`` (m,) [m^3]."""
        q = self._coordinates(q)
        lengths = np.array(ca.DM(self.fibre_lengths_symbolic(ca.DM(q)))).ravel()
        return np.array([b.area for b in self.bellows]) * lengths

    def input_matrix_symbolic(self, q, theta=None):
        # Closed form of A dL/dq (module docstring); tests check it against dV/dq.
        columns = []
        for i, b in enumerate(self.bellows):
            phi, rho, area = self._geometry(i, theta)
            column = [0] * self.n
            c, s = ca.cos(phi), ca.sin(phi)
            for j in b.segments:
                length, kx, ky = q[3 * j], q[3 * j + 1], q[3 * j + 2]
                column[3 * j] = area * (1 - rho * (kx * c + ky * s))
                column[3 * j + 1] = -area * length * rho * c
                column[3 * j + 2] = -area * length * rho * s
            columns.append(ca.vertcat(*column))
        return ca.horzcat(*columns)

    def _geometry(self, i: int, theta):
        if theta is None:
            b = self.bellows[i]
            return b.azimuth, b.distance, b.area
        return theta[3 * i], theta[3 * i + 1], theta[3 * i + 2]


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
        object.__setattr__(self, "time_constant", _time_constant(self.time_constant))
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
        """
        a_e, a_k = real_scalar("a_e", a_e), real_scalar("a_k", a_k)
        phi = np.asarray(azimuths, dtype=np.float64)
        h = np.vstack([np.full_like(phi, a_e), a_k * np.sin(phi), -a_k * np.cos(phi)])
        return cls(h, p_max=p_max, p_min=p_min, time_constant=time_constant)

    def parameter_vector(self) -> np.ndarray:
        return self.constant.ravel().copy()

    def parameter_names(self) -> list[str]:
        return [f"matrix[{i},{j}]" for i in range(self.n) for j in range(self.n_inputs)]

    def input_matrix(self, q) -> np.ndarray:
        self._coordinates(q)
        return self.constant.copy()

    def input_work_symbolic(self, q, pressures):
        return ca.dot(q, ca.DM(self.constant) @ pressures)

    def input_matrix_symbolic(self, q, theta=None):
        if theta is None:
            return ca.DM(self.constant)
        return ca.reshape(theta, self.n_inputs, self.n).T


_BELLOWS_KEYS = {"azimuth", "distance", "area", "p_min", "p_max", "segments"}
_KEYS = {
    "bellows": {
        "kind",
        "distance",
        "area",
        "azimuths",
        "p_min",
        "p_max",
        "time_constant",
        "bellows",
    },
    "constant": {"kind", "matrix", "p_min", "p_max", "time_constant"},
    "authors_fit": {"kind", "a_e", "a_k", "azimuths", "p_min", "p_max", "time_constant"},
}


def from_mapping(mapping: Mapping, *, n_segments: int = 1, where: str = "actuation") -> Actuator:
    """A pressure map from a configuration table (e.g. TOML ``[actuation]``).

    ``kind = "bellows"`` (default): either ``distance``, ``area``, ``p_max`` (and optional
    ``azimuths`` [rad], ``p_min``) for three bellows per segment, or a list ``bellows`` of
    tables with keys ``azimuth, distance, area, p_max, p_min, segments``.
    ``kind = "constant"``: ``matrix`` (n x m), ``p_max``, ``p_min``.
    ``kind = "authors_fit"``: ``a_e``, ``a_k``, ``p_max``, ``p_min``, ``azimuths``.
    Every kind accepts ``time_constant`` [s]. Unknown keys raise :class:`ParameterError`
    naming them, as does any bad value (prefixed by ``where``).
    """
    if not isinstance(mapping, Mapping):
        raise ParameterError(f"{where} must be a table, got {type(mapping).__name__}")
    kind = mapping.get("kind", "bellows")
    if kind not in _KEYS:
        raise ParameterError(f"{where}.kind must be one of {sorted(_KEYS)}, got {kind!r}")
    unknown = sorted(set(mapping) - _KEYS[kind])
    if unknown:
        raise ParameterError(
            f"{where}: unknown key(s) {unknown} for kind {kind!r}; allowed: {sorted(_KEYS[kind])}"
        )
    args = {k: v for k, v in mapping.items() if k != "kind"}
    required = {"constant": ("matrix", "p_max"), "authors_fit": ("p_max",)}.get(
        kind, () if "bellows" in args else ("distance", "area", "p_max")
    )
    missing = [k for k in required if k not in args]
    if missing:
        raise ParameterError(f"{where}: missing required key(s) {missing} for kind {kind!r}")
    try:
        if kind == "constant":
            args["constant"] = args.pop("matrix")
            result = ConstantPressureMap(**args)
        elif kind == "authors_fit":
            result = ConstantPressureMap.authors_fit(**args)
        elif "bellows" in args:
            extra = sorted(set(args) - {"bellows", "time_constant"})
            if extra:
                raise ParameterError(f"keys {extra} are not allowed next to a 'bellows' list")
            tables = args["bellows"]
            chambers = []
            for i, table in enumerate(tables):
                if not isinstance(table, Mapping):
                    raise ParameterError(f"bellows[{i}] must be a table")
                bad = sorted(set(table) - _BELLOWS_KEYS)
                if bad:
                    raise ParameterError(
                        f"bellows[{i}]: unknown key(s) {bad}; allowed: {sorted(_BELLOWS_KEYS)}"
                    )
                try:
                    chambers.append(Bellows(**table))
                except TypeError as exc:
                    raise ParameterError(f"bellows[{i}]: {exc}") from None
            result = PneumaticActuator(
                tuple(chambers), n_segments=n_segments, time_constant=args.get("time_constant")
            )
        else:
            result = PneumaticActuator.three_bellows(n_segments=n_segments, **args)
    except ParameterError as exc:
        raise ParameterError(f"{where}: {exc}") from None
    if result.n != 3 * n_segments:
        raise ParameterError(
            f"{where}: the map acts on n = {result.n} coordinates, the robot has {3 * n_segments}"
        )
    return result
