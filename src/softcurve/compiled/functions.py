"""A robot's CasADi Functions, compiled and loaded: the machinery under :class:`Model`.

:class:`CompiledFunctions` builds the symbolic expressions of
:mod:`softcurve.symbolic.dynamics` once, turns them into CasADi Functions of
``(inputs..., p)`` where ``p`` is the robot's parameter vector, has
:mod:`softcurve.compiled.build` compile them to one cached C library, loads it, and calls
it with NumPy arrays. It also owns the one per-model cache (:meth:`~CompiledFunctions.cached`).
The physical quantities (dynamics, energies, poses) are the methods of its subclass
:class:`softcurve.compiled.model.Model`.
"""

from __future__ import annotations

import hashlib
import threading
from pathlib import Path

import casadi as ca
import numpy as np

from softcurve.base.validation import ParameterError
from softcurve.compiled.build import COMPILED_FUNCTIONS, compiled_library
from softcurve.compiled.native import NativeFunction
from softcurve.compiled.source import load_library
from softcurve.description.environment import Environment
from softcurve.description.robot import Robot
from softcurve.symbolic.contact import contact_functions, with_contact
from softcurve.symbolic.dynamics import (
    DEFAULT_QUADRATURE_NODES,
    DynamicsExpressions,
    build_dynamics,
)
from softcurve.symbolic.functions import symbolic_functions

CACHED_PER_MODEL = 64
"""Entries of :meth:`CompiledFunctions.cached` per model; a batch or identification builds
a few integrators and maps per output grid, so 64 covers every study in the docs."""

POINTS_PER_CALL = 1024
"""Points of one compiled call of :meth:`CompiledFunctions.evaluate_along`: the fastest
width of CasADi's map of the pose (building a map costs more than linear in its width;
300 000 points cost 4 s in one map, 0.5 s in maps of 1024), and short enough that a
Ctrl-C, which Python sees only between two calls, acts within milliseconds."""


def _block(column: np.ndarray, start: int, width: int) -> np.ndarray:
    """Rows ``start .. start + width`` of ``column`` (T, k) as CasADi's map takes them,
    (k, width); past the end the last row is repeated (those outputs are dropped)."""
    part = column[start : start + width]
    if part.shape[0] < width:
        part = np.concatenate([part, np.repeat(part[-1:], width - part.shape[0], axis=0)])
    return part.T


def _load(library: Path) -> dict[str, NativeFunction]:
    """The compiled functions of a verified library (ctypes raises OSError if it cannot be
    loaded; :func:`~softcurve.compiled.build.compiled_library` then rebuilds it once)."""
    handle = load_library(library)
    return {name: NativeFunction(handle, name) for name in COMPILED_FUNCTIONS}


class CompiledFunctions:
    """The numeric entry points of one robot, compiled to C or in CasADi's virtual machine.

    Built as its subclass :class:`~softcurve.compiled.model.Model`, whose docstring gives
    the constructor's parameters.
    """

    def __init__(
        self,
        robot: Robot,
        *,
        environment: Environment | None = None,
        quadrature_nodes: int = DEFAULT_QUADRATURE_NODES,
        compile: bool = True,
    ):
        if not isinstance(robot, Robot):
            raise ParameterError(f"robot must be a Robot, got {type(robot).__name__}")
        if not (isinstance(quadrature_nodes, int) and 1 <= quadrature_nodes <= 64):
            raise ParameterError(
                f"quadrature_nodes must be an integer in [1, 64], got {quadrature_nodes!r}"
            )
        if environment is not None:
            if not isinstance(environment, Environment):
                raise ParameterError(
                    f"environment must be an Environment or None, got {type(environment).__name__}"
                )
            environment.check_robot(robot)
        self.robot = robot
        self.environment = environment
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
            loaded = compiled_library(
                self._cache_structure(), quadrature_nodes, lambda: self.symbolic, load=_load
            )
            if loaded is not None:
                self.compiled_library, self._native = loaded

    def _cache_structure(self) -> tuple:
        """What the compiled library depends on besides the symbolic layer's sources:
        the robot's structure alone without environment (the free model's key is the same
        as before environments existed), else also the environment's numbers (compiled in
        as constants) and the sources of the contact modules."""
        if self.environment is None:
            return self._structure
        digest = hashlib.sha256()
        package = Path(__file__).parent.parent
        for name in ("description/environment.py", "symbolic/contact.py"):
            digest.update((package / name).read_bytes())
        return (self._structure, "environment", self.environment.key(), digest.hexdigest())

    @property
    def expressions(self) -> DynamicsExpressions:
        """The symbolic equation of motion (built on first use); a
        :class:`~softcurve.symbolic.contact.ContactExpressions` with an environment."""
        if self._expressions is None:
            e = build_dynamics(self._structure, self.quadrature_nodes)
            if self.environment is not None:
                e = with_contact(e, self._structure, self.environment)
            self._expressions = e
        return self._expressions

    _expressions: DynamicsExpressions | None = None

    @property
    def symbolic(self) -> dict[str, ca.Function]:
        """Every numeric entry point as a CasADi SX Function whose last input is ``p``."""
        if self._symbolic is None:
            e = self.expressions
            self._symbolic = (
                symbolic_functions(e) if self.environment is None else contact_functions(e)
            )
        return self._symbolic

    # -- the per-model cache -------------------------------------------------------
    def cached(self, key, build):
        """``build()`` once per ``key`` for this model, kept while the model lives.

        The one cache of CasADi objects built on a model (integrators, maps, load
        functions): CasADi builds derivative functions and integrator memory on first
        use, so rebuilding them per call would cost milliseconds. At most
        :data:`CACHED_PER_MODEL` entries; the oldest half is dropped beyond that.

        Parameters
        ----------
        key : hashable
            What is built, e.g. ``("map", "pose", 100)``; equal keys share one value.
        build : callable
            Called without arguments, only when ``key`` is not cached yet.

        Returns
        -------
        object
            The value of ``build()`` stored under ``key``.
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
        """The model's function ``name(..., p)`` as a CasADi Function.

        Parameters
        ----------
        name : str
            A key of :attr:`symbolic`, e.g. ``"rhs"`` or ``"pose"``.
        options : dict, optional
            CasADi options of the ``external`` that loads a compiled function.

        Returns
        -------
        casadi.Function
            The compiled one, loaded as a CasADi ``external``, when the model has a
            library that compiles ``name``; else the symbolic one.
        """
        if self.compiled_library is not None and name in COMPILED_FUNCTIONS:
            return ca.external(name, str(self.compiled_library), options or {})
        return self.symbolic[name]

    def evaluate_along(self, name: str, *columns) -> list[np.ndarray]:
        """Evaluate the function ``name`` at many points, :data:`POINTS_PER_CALL` per
        compiled call.

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
        width = max(1, min(count, POINTS_PER_CALL))

        def build():
            function = self.function(name)
            return function, function.map(width)

        function, mapped = self.cached(("map", name, width), build)
        columns = [np.asarray(c, dtype=np.float64) if np.ndim(c) == 2 else c for c in columns]
        blocks = []
        for start in range(0, count, width):  # between two calls an interrupt is seen
            inputs = [_block(c, start, width) if np.ndim(c) == 2 else c for c in columns]
            outputs = mapped(*inputs, self.parameters)
            blocks.append(outputs if isinstance(outputs, tuple | list) else (outputs,))
        result = []
        for i in range(function.n_out()):
            rows, cols = function.size1_out(i), function.size2_out(i)
            # (rows, cols * width) per call, column blocks; the last call padded
            parts = [np.asarray(b[i], dtype=np.float64) for b in blocks]
            dense = np.hstack(parts) if parts else np.empty((rows, 0))
            per_point = dense.reshape(rows, -1, cols)[:, :count]
            result.append(per_point.transpose(1, 0, 2).reshape(count, rows * cols))
        return result

    def split_state(self, x):
        """``(q, qd, lam)`` views of a state vector.

        Parameters
        ----------
        x : array_like, shape (n_state,)
            State ``(q, qd, lam)``, ``n_state = 2 n + n_creep``.
        """
        x = self._vector("x", x, self.n_state)
        n = self.n
        return x[:n], x[n : 2 * n], x[2 * n :]

    def contact(self, q, qd=None) -> dict[str, np.ndarray]:
        """The contact with the environment at one state (CasADi's virtual machine).

        Parameters
        ----------
        q : array_like, shape (n,)
            Generalized coordinates ``(l, kx, ky)`` of each segment [m, 1/m, 1/m].
        qd : array_like, shape (n,), optional
            Their rates [m/s, 1/(m s), 1/(m s)] (default zero: the elastic part only).

        Returns
        -------
        dict of str to ndarray
            ``"generalized"`` (n,): the generalized contact force [N, N m^2, N m^2];
            ``"energy"`` (): the penalty energy [J]; ``"forces"`` (n_obstacles, 3): the
            force [N] of each obstacle on the robot, base frame; ``"points"``
            (n_obstacles, 3): its point of application [m], NaN out of contact.
        """
        if self.environment is None:
            raise ParameterError("this model has no environment: Model(robot, environment=...)")
        q = self.robot.check_configuration(q, "q")
        qd = np.zeros(self.n) if qd is None else self._vector("qd", qd, self.n)
        out = self.symbolic["contact"](q, qd, self.parameters)
        forces, points = np.array(out[2]).T, np.array(out[3]).T
        points[~np.any(forces != 0.0, axis=1)] = np.nan
        return {
            "generalized": np.array(out[0]).ravel(),
            "energy": np.array(float(out[1])),
            "forces": forces,
            "points": points,
        }

    # -- NumPy in, NumPy out -------------------------------------------------------
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
