"""The compiled model: NumPy in, NumPy out, over CasADi functions compiled to C.

:class:`Model` builds the symbolic expressions of :mod:`softcurve.dynamics` once,
turns them into CasADi Functions of ``(state..., p)`` where ``p`` is the robot's
parameter vector, generates C for all of them in one library, compiles it with the
system C compiler and loads it. The library is cached on disk under a key made of
the generated source and the compiler command, so a second process with a robot of
the same structure (any parameter values) starts without compiling. Without a C
compiler the same Functions run in CasADi's virtual machine, with one warning.

Code generation and the on-disk cache live in :mod:`softcurve.compiled.build`; the
per-model cache of CasADi objects built on a model (integrators, maps, load functions)
is :meth:`Model.cached`.
"""

from __future__ import annotations

import ctypes
import threading
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

from softcurve.base.validation import ParameterError
from softcurve.compiled.build import COMPILED_FUNCTIONS, compiled_library
from softcurve.compiled.native import NativeFunction
from softcurve.description.robot import Robot
from softcurve.symbolic.dynamics import (
    DEFAULT_QUADRATURE_NODES,
    DynamicsExpressions,
    build_dynamics,
)
from softcurve.symbolic.functions import symbolic_functions


@dataclass(frozen=True)
class Pose:
    """Orientation ``rotation`` (3, 3) and ``position`` (3,) [m] in the world frame."""

    rotation: np.ndarray
    position: np.ndarray

    def __iter__(self):  # allows ``R, p = model.pose(q, s)``
        return iter((self.rotation, self.position))


@dataclass(frozen=True)
class DynamicsTerms:
    """The terms of ``D qdd + C qd + G + K + R qd = tau + K_c^T lam`` at one state.

    Attributes: ``mass_matrix`` (n, n), ``coriolis_force``, ``gravity_force``,
    ``elastic_force``, ``damping_force`` (``R qd``) and ``creep_force`` (``K_c^T lam``),
    each (n,).
    """

    mass_matrix: np.ndarray
    coriolis_force: np.ndarray
    gravity_force: np.ndarray
    elastic_force: np.ndarray
    damping_force: np.ndarray
    creep_force: np.ndarray

    def inverse_dynamics(self, qdd) -> np.ndarray:
        """``tau`` that produces the accelerations ``qdd`` at this state."""
        return (
            self.mass_matrix @ qdd
            + self.coriolis_force
            + self.gravity_force
            + self.elastic_force
            + self.damping_force
            - self.creep_force
        )


CACHED_PER_MODEL = 64
"""Entries of :meth:`Model.cached` per model; a batch or identification builds a few
integrators and maps per output grid, so 64 covers every study in the docs."""


class Model:
    """The dynamics of a robot, compiled.

    Parameters
    ----------
    robot : Robot
        The robot description; its numbers are bound to every method below.
    quadrature_nodes : int, optional
        Gauss-Legendre nodes per segment for the backbone integrals (default 11,
        round-off accuracy for bending angles up to pi per segment; see
        docs/model.md).
    compile : bool, optional
        Compile to C (default). With False, or when no C compiler works, the
        functions run in CasADi's virtual machine.

    Notes
    -----
    Every numeric method takes float64 arrays of shape ``(n,)`` for ``q``, ``qd``,
    ``qdd`` and ``tau`` (``n = 3 N``) and ``(n_creep,)`` for ``lam`` (omit it or
    pass None for zeros), and returns float64 arrays.
    """

    def __init__(
        self,
        robot: Robot,
        *,
        quadrature_nodes: int = DEFAULT_QUADRATURE_NODES,
        compile: bool = True,
    ):
        if not isinstance(robot, Robot):
            raise ParameterError(f"robot must be a Robot, got {type(robot).__name__}")
        if not (isinstance(quadrature_nodes, int) and 1 <= quadrature_nodes <= 64):
            raise ParameterError(
                f"quadrature_nodes must be an integer in [1, 64], got {quadrature_nodes!r}"
            )
        self.robot = robot
        self.n = robot.n
        self.n_creep = robot.n_creep
        self.n_state = 2 * self.n + self.n_creep
        self.quadrature_nodes = quadrature_nodes
        self.parameters = robot.parameter_vector()
        self._structure = robot.structure()
        self._symbolic: dict[str, ca.Function] | None = None
        self._native: dict[str, NativeFunction] | None = None
        self._cache: dict = {}
        self._cache_lock = threading.Lock()
        self.compiled_library: Path | None = None
        if compile:
            library = compiled_library(self._structure, quadrature_nodes, lambda: self.symbolic)
            if library is not None:
                handle = ctypes.CDLL(str(library))
                self._native = {name: NativeFunction(handle, name) for name in COMPILED_FUNCTIONS}
                self.compiled_library = library

    @property
    def expressions(self) -> DynamicsExpressions:
        """The symbolic equation of motion (built on first use)."""
        if self._expressions is None:
            self._expressions = build_dynamics(self._structure, self.quadrature_nodes)
        return self._expressions

    _expressions: DynamicsExpressions | None = None

    @property
    def symbolic(self) -> dict[str, ca.Function]:
        """Every numeric entry point as a CasADi SX Function whose last input is ``p``."""
        if self._symbolic is None:
            self._symbolic = symbolic_functions(self.expressions)
        return self._symbolic

    # -- the per-model cache -------------------------------------------------------
    def cached(self, key, build):
        """``build()`` once per ``key`` for this model, kept while the model lives.

        The one cache of CasADi objects built on a model (integrators, maps, load
        functions): CasADi builds derivative functions and integrator memory on first
        use, so rebuilding them per call would cost milliseconds. At most
        :data:`CACHED_PER_MODEL` entries; the oldest half is dropped beyond that.
        """
        with self._cache_lock:
            if key in self._cache:
                return self._cache[key]
        value = build()
        with self._cache_lock:
            if len(self._cache) >= CACHED_PER_MODEL:
                for old in list(self._cache)[: CACHED_PER_MODEL // 2]:
                    del self._cache[old]
            return self._cache.setdefault(key, value)

    def function(self, name: str, options: dict | None = None) -> ca.Function:
        """The model's function ``name(..., p)`` as a CasADi Function: the compiled one,
        loaded as a CasADi ``external`` with ``options``, when the model has a library and
        compiles ``name``; else the symbolic one (see :attr:`symbolic`)."""
        if self.compiled_library is not None and name in COMPILED_FUNCTIONS:
            return ca.external(name, str(self.compiled_library), options or {})
        return self.symbolic[name]

    def evaluate_along(self, name: str, *columns) -> list[np.ndarray]:
        """Evaluate the function ``name`` at many points in one compiled call.

        Parameters
        ----------
        name : str
            A key of :attr:`symbolic`, e.g. ``"pose"`` or ``"potential_energy"``.
        *columns : array_like, shape (T, k), or scalar
            Per-point inputs (one row per point) or a value shared by all points, in the
            order of the function's inputs before ``p``.

        Returns
        -------
        list of ndarray, each shape (T, size of the output)
            One array per output of the function, flattened per point (column major).
        """
        count = next(np.shape(c)[0] for c in columns if np.ndim(c) == 2)

        def build():
            function = self.function(name)
            return function, function.map(count)

        function, mapped = self.cached(("map", name, count), build)
        inputs = [np.asarray(c, dtype=np.float64).T if np.ndim(c) == 2 else c for c in columns]
        outputs = mapped(*inputs, self.parameters)
        if not isinstance(outputs, tuple | list):
            outputs = (outputs,)
        result = []
        for i, o in enumerate(outputs):
            rows, cols = function.size1_out(i), function.size2_out(i)
            dense = np.asarray(o, dtype=np.float64)  # (rows, cols * count), column blocks
            per_point = dense.reshape(rows, count, cols)
            result.append(per_point.transpose(1, 0, 2).reshape(count, rows * cols))
        return result

    # -- state helpers -------------------------------------------------------------
    def _vector(self, name: str, value, size: int) -> np.ndarray:
        if value is None and name == "lam":
            return np.zeros(size)
        a = np.asarray(value, dtype=np.float64)
        if a.shape != (size,):
            raise ValueError(f"{name} must have shape ({size},), got {a.shape}")
        return a

    def _call(self, name: str, *args) -> list[np.ndarray]:
        if self._native is not None and name in self._native:
            return self._native[name](*args, self.parameters)
        out = self.symbolic[name](*args, self.parameters)
        if not isinstance(out, tuple | list):
            out = (out,)
        arrays = [np.array(o, dtype=np.float64) for o in out]
        return [a.ravel() if a.shape[1] == 1 else a for a in arrays]

    def split_state(self, x):
        """``(q, qd, lam)`` views of a state vector ``x`` of shape (n_state,)."""
        x = self._vector("x", x, self.n_state)
        n = self.n
        return x[:n], x[n : 2 * n], x[2 * n :]

    # -- dynamics ------------------------------------------------------------------
    def dynamics_terms(self, q, qd, lam=None) -> DynamicsTerms:
        """Every term of eq. (16) at one state, from one compiled evaluation."""
        values = self._call(
            "dynamics_terms",
            self._vector("q", q, self.n),
            self._vector("qd", qd, self.n),
            self._vector("lam", lam, self.n_creep),
        )
        return DynamicsTerms(*values)

    def mass_matrix(self, q) -> np.ndarray:
        """Inertia matrix ``D(q)``, shape (n, n), symmetric positive definite."""
        return self.dynamics_terms(q, np.zeros(self.n)).mass_matrix

    def coriolis_matrix(self, q, qd) -> np.ndarray:
        """``C(q, qd)`` with Christoffel symbols of ``D``, shape (n, n); ``Ddot - 2C`` is
        skew-symmetric. Evaluated in CasADi's virtual machine (analysis, not a hot path)."""
        out = self.symbolic["coriolis_matrix"](
            self._vector("q", q, self.n), self._vector("qd", qd, self.n), self.parameters
        )
        return np.array(out, dtype=np.float64)

    def coriolis_force(self, q, qd) -> np.ndarray:
        """``C(q, qd) qd``, shape (n,)."""
        return self.dynamics_terms(q, qd).coriolis_force

    def gravity_force(self, q) -> np.ndarray:
        """``dV_g/dq``, shape (n,) [N or N m]."""
        return self.dynamics_terms(q, np.zeros(self.n)).gravity_force

    def elastic_force(self, q) -> np.ndarray:
        """``dV_e/dq``, shape (n,)."""
        return self.dynamics_terms(q, np.zeros(self.n)).elastic_force

    def potential_force(self, q) -> np.ndarray:
        """``N(q) = dV/dq``, gravity plus elastic, shape (n,)."""
        return self.gravity_force(q) + self.elastic_force(q)

    def potential_energy(self, q) -> float:
        """``V(q)`` [J], gravitational plus elastic."""
        g, e = self._call("potential_energy", self._vector("q", q, self.n))
        return float(g[0] + e[0])

    def kinetic_energy(self, q, qd) -> float:
        """``T(q, qd) = qd' D(q) qd / 2`` [J]."""
        qd = self._vector("qd", qd, self.n)
        return float(0.5 * qd @ self.mass_matrix(q) @ qd)

    def energy(self, q, qd) -> float:
        """Total mechanical energy ``T + V`` [J]."""
        return self.kinetic_energy(q, qd) + self.potential_energy(q)

    def forward_dynamics(self, q, qd, tau=None, lam=None) -> np.ndarray:
        """Accelerations ``qdd`` solving eq. (16) for the given forces, shape (n,)."""
        x = np.concatenate(
            [
                self._vector("q", q, self.n),
                self._vector("qd", qd, self.n),
                self._vector("lam", lam, self.n_creep),
            ]
        )
        return self.state_derivative(x, tau)[self.n : 2 * self.n]

    def inverse_dynamics(self, q, qd, qdd, lam=None) -> np.ndarray:
        """Generalized forces ``tau`` that produce ``qdd``, shape (n,)."""
        return self.dynamics_terms(q, qd, lam).inverse_dynamics(self._vector("qdd", qdd, self.n))

    def creep_rate(self, qd, lam) -> np.ndarray:
        """``lambda'`` of eq. (19), shape (n_creep,)."""
        return self._call(
            "creep_rate", self._vector("qd", qd, self.n), self._vector("lam", lam, self.n_creep)
        )[0]

    def state_derivative(self, x, tau=None) -> np.ndarray:
        """``xdot`` for the state ``x = (q, qd, lam)``, shape (n_state,)."""
        tau = np.zeros(self.n) if tau is None else self._vector("tau", tau, self.n)
        return self._call("rhs", self._vector("x", x, self.n_state), tau)[0]

    def rhs(self, tau=None):
        """A SciPy-style right-hand side ``f(t, x) -> xdot`` for constant ``tau``.

        Parameters
        ----------
        tau : array_like, shape (n,), optional
            Constant generalized input forces (default zero).
        """
        tau = np.zeros(self.n) if tau is None else self._vector("tau", tau, self.n)

        def f(t, x):
            return self._call("rhs", x, tau)[0]

        return f

    def casadi_rhs(self) -> ca.Function:
        """``rhs(x, tau, p) -> xdot`` as a symbolic CasADi Function, for optimal control."""
        return self.symbolic["rhs"]

    # -- kinematics ----------------------------------------------------------------
    def _s(self, s) -> float:
        s = float(s)
        if not 0.0 <= s <= 1.0:
            raise ValueError(f"s must be in [0, 1], got {s!r}")
        return s

    def pose(self, q, s) -> Pose:
        """World pose at material coordinate ``s`` in [0, 1] of the whole robot.

        Segment ``i`` covers ``[i/N, (i+1)/N]``; ``s = 1`` is the tip.
        """
        rotation, position = self._call("pose", self._vector("q", q, self.n), self._s(s))
        return Pose(rotation, position)

    def tip_pose(self, q) -> Pose:
        """World pose of the tip (``s = 1``)."""
        return self.pose(q, 1.0)

    def jacobian(self, q, s) -> np.ndarray:
        """Geometric Jacobian (6, n) at ``s``: rows 0-2 linear velocity, rows 3-5 angular
        velocity, both in the world frame, per unit ``qd``."""
        return self._call("jacobian", self._vector("q", q, self.n), self._s(s))[0]

    def body_twist(self, q, qd, s) -> np.ndarray:
        """Twist (6,) of the material point at ``s`` in its own frame: linear then angular."""
        q = self._vector("q", q, self.n)
        rotation, _ = self.pose(q, s)
        twist = self.jacobian(q, s) @ self._vector("qd", qd, self.n)
        return np.concatenate([rotation.T @ twist[:3], rotation.T @ twist[3:]])

    def backbone(self, q, points: int = 50) -> np.ndarray:
        """Positions (points, 3) [m] along the backbone, from base to tip."""
        if not (isinstance(points, int | np.integer) and points >= 2):
            raise ValueError(f"points must be an integer >= 2, got {points!r}")
        q = self._vector("q", q, self.n)
        return np.array([self.pose(q, s).position for s in np.linspace(0.0, 1.0, points)])
