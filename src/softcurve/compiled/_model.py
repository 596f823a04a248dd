"""The compiled model: the physics of a robot, NumPy in, NumPy out.

:class:`Model` builds the symbolic expressions of :mod:`softcurve.symbolic.dynamics` once,
turns them into CasADi Functions of ``(inputs..., p)`` where ``p`` is the robot's
parameter vector, has the compiler (``_build``, with its on-disk cache) compile them to
one C library, loads it and calls it with NumPy arrays; its methods are the equation of
motion's terms, energies and poses. It owns the one per-model cache (:meth:`Model.cached`).

Units, per segment: coordinates ``q = (l, kx, ky)`` [m, 1/m, 1/m], rates ``qd``
[m/s, 1/(m s), 1/(m s)], accelerations ``qdd`` [m/s^2, 1/(m s^2), 1/(m s^2)] and
generalized forces ``tau`` [N, N m^2, N m^2] (their products with ``qd`` are powers in W).
"""

from __future__ import annotations

import hashlib
import threading
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

from softcurve.base.docs import shared_parameters
from softcurve.base.validation import ParameterError
from softcurve.compiled._build import (
    COMPILED_FUNCTIONS,
    JACOBIAN_FUNCTIONS,
    cache_directory,
    cached_model_library,
    compiled_library,
)
from softcurve.compiled._native import NativeFunction
from softcurve.compiled._source import load_library
from softcurve.description.environment import Environment
from softcurve.description.robot import Robot
from softcurve.symbolic.contact import contact_functions, with_contact
from softcurve.symbolic.derivatives import JacobianPasses, state_jacobian
from softcurve.symbolic.dynamics import (
    DEFAULT_QUADRATURE_NODES,
    DynamicsExpressions,
    build_dynamics,
)
from softcurve.symbolic.functions import symbolic_functions
from softcurve.symbolic.kinematics import inline_calls

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
    loaded; ``softcurve.compiled._build.compiled_library`` then rebuilds it once)."""
    handle = load_library(library)
    return {name: NativeFunction(handle, name) for name in COMPILED_FUNCTIONS}


def _load_jacobian(library: Path) -> NativeFunction:
    """The exact Jacobian of a verified library (:func:`_load`'s counterpart)."""
    (name,) = JACOBIAN_FUNCTIONS
    return NativeFunction(load_library(library), name)


def _check_arguments(robot, environment, quadrature_nodes) -> None:
    """What :class:`Model` and :meth:`Model.is_cached` accept, each argument named in the
    :class:`ParameterError`."""
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


def _library_structure(structure: tuple, environment: Environment | None) -> tuple:
    """What the compiled library depends on besides the symbolic layer's sources: the
    robot's structure alone without environment (the free model's key is the same as
    before environments existed), else also the environment's numbers (compiled in as
    constants) and the sources of the contact modules."""
    if environment is None:
        return structure
    digest = hashlib.sha256()
    package = Path(__file__).parent.parent
    for name in ("description/environment.py", "symbolic/contact.py"):
        digest.update((package / name).read_bytes())
    return (structure, "environment", environment.key(), digest.hexdigest())


@dataclass(frozen=True)
class Pose:
    """A frame in the world frame; unpacks as ``rotation, position = pose``.

    Parameters
    ----------
    rotation : ndarray, shape (3, 3)
        Orientation: the frame's axes as columns, in world coordinates.
    position : ndarray, shape (3,)
        Origin [m] in world coordinates.
    """

    rotation: np.ndarray
    position: np.ndarray

    def __iter__(self):  # allows ``R, p = model.pose(q, s)``
        return iter((self.rotation, self.position))


@dataclass(frozen=True)
class DynamicsTerms:
    """The terms of ``D qdd + C qd + G + K + R qd = tau + K_c^T lam`` at one state.

    Parameters
    ----------
    mass_matrix : ndarray, shape (n, n)
        ``D(q)``, symmetric positive definite.
    coriolis_force : ndarray, shape (n,)
        ``C(q, qd) qd`` [N, N m^2, N m^2 per segment].
    gravity_force : ndarray, shape (n,)
        ``G(q) = dV_g/dq`` [N, N m^2, N m^2 per segment].
    elastic_force : ndarray, shape (n,)
        ``K(q) = dV_e/dq`` [N, N m^2, N m^2 per segment].
    damping_force : ndarray, shape (n,)
        ``R qd`` [N, N m^2, N m^2 per segment].
    creep_force : ndarray, shape (n,)
        ``K_c^T lam`` [N, N m^2, N m^2 per segment].
    contact_force : ndarray, shape (n,), optional
        Generalized contact force ``sum J^T F`` [N, N m^2, N m^2 per segment]; None
        for a model without environment.
    """

    mass_matrix: np.ndarray
    coriolis_force: np.ndarray
    gravity_force: np.ndarray
    elastic_force: np.ndarray
    damping_force: np.ndarray
    creep_force: np.ndarray
    contact_force: np.ndarray | None = None

    def inverse_dynamics(self, qdd) -> np.ndarray:
        """``tau`` that produces the accelerations ``qdd`` at this state.

        Parameters
        ----------
        qdd : array_like, shape (n,)
            Accelerations [m/s^2, 1/(m s^2), 1/(m s^2) per segment].
        """
        return (
            self.mass_matrix @ qdd
            + self.coriolis_force
            + self.gravity_force
            + self.elastic_force
            + self.damping_force
            - self.creep_force
            - (0.0 if self.contact_force is None else self.contact_force)
        )


@shared_parameters
class Model:
    """The dynamics of a robot, compiled.

    Parameters
    ----------
    robot : Robot
        The robot description; its numbers are bound to every method below.
    environment : Environment, optional
        Obstacles and contact law (docs/contact.md); their forces enter every method
        below. Without it (default) the model is the free robot's.
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
    ``qdd`` and ``tau`` (``n = 3 N``, units in the module docstring) and
    ``(n_creep,)`` for ``lam`` (omit it or pass None for zeros), and returns float64
    arrays. A ``q`` outside the model's domain raises :class:`ParameterError`
    (:meth:`Robot.check_configuration`); ``state_derivative`` and ``rhs`` do not check.

    Examples
    --------
    >>> import numpy as np
    >>> import softcurve as sc
    >>> model = sc.Model(sc.presets.ifac2020())  # compiled once, then loaded from disk
    >>> model.n, model.n_creep
    (3, 3)
    >>> q = np.array([0.064, 25.0, 0.0])  # length [m], curvatures kx, ky [1/m]
    >>> qd = np.array([0.0, 0.0, 1500.0])  # their rates
    >>> model.mass_matrix(q).shape
    (3, 3)
    >>> qdd = model.forward_dynamics(q, qd)  # creep states at zero
    >>> np.allclose(model.inverse_dynamics(q, qd, qdd), 0.0, atol=1e-9)
    True
    >>> model.tip_pose(q).position.round(4)  # [m]
    array([0.0412, 0.    , 0.04  ])
    """

    def __init__(
        self,
        robot: Robot,
        *,
        environment: Environment | None = None,
        quadrature_nodes: int = DEFAULT_QUADRATURE_NODES,
        compile: bool = True,
    ):
        _check_arguments(robot, environment, quadrature_nodes)
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
            segments = robot.counted()
            obstacles = "" if environment is None else " and its obstacles"
            loaded = compiled_library(
                self._cache_structure(),
                quadrature_nodes,
                lambda: self.symbolic,
                load=_load,
                what=f"the model of {segments}{obstacles}",
            )
            if loaded is not None:
                self.compiled_library, self._native = loaded

    def _cache_structure(self) -> tuple:
        """What the compiled library depends on besides the symbolic layer's sources
        (:func:`_library_structure`)."""
        return _library_structure(self._structure, self.environment)

    @staticmethod
    def is_cached(
        robot: Robot,
        *,
        environment: Environment | None = None,
        quadrature_nodes: int = DEFAULT_QUADRATURE_NODES,
    ) -> bool:
        """Whether ``Model(robot, environment=..., quadrature_nodes=...)`` finds its compiled
        library in the cache (:meth:`cache_folder`), intact and built for this structure,
        so that it loads it in milliseconds instead of compiling it (seconds to minutes,
        more with more segments or obstacles). Nothing is built, loaded or compiled; the
        library's bytes are read once to check their checksum.

        Parameters
        ----------
        robot : Robot
            The robot; its structure (segments, creep, materials' laws), not its numbers,
            selects the library.
        environment : Environment, optional
            Obstacles and contact law, compiled in (default: the free robot).
        quadrature_nodes : int, optional
            Gauss-Legendre nodes per segment (default 11).

        Returns
        -------
        bool
            True when the library is cached; False when constructing the model compiles
            it (or, without a C compiler, runs in CasADi's virtual machine).
        """
        _check_arguments(robot, environment, quadrature_nodes)
        structure = _library_structure(robot.structure(), environment)
        return cached_model_library(structure, quadrature_nodes) is not None

    @staticmethod
    def cache_folder() -> Path:
        """The folder of the compiled libraries: ``$SOFTCURVE_CACHE_DIR``, else
        ``$XDG_CACHE_HOME/softcurve`` or ``~/.cache/softcurve``.

        Returns
        -------
        pathlib.Path
        """
        return cache_directory()

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
    def inlined(self) -> bool:
        """Whether the model's expressions inline its elements' Functions, as for a robot
        of one element (:func:`~softcurve.symbolic.kinematics.inline_calls`), or keep
        them as calls, one copy of an element's work however many elements."""
        return inline_calls(len(self._structure))

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
    def compiled_function(self, name: str) -> NativeFunction | None:
        """The compiled C function ``name`` of the model's library (for code that calls C
        directly, such as the CVODES driver), or None where the model runs in CasADi's
        virtual machine.

        Parameters
        ----------
        name : str
            One of the compiled entry points (``"rhs"``, ``"dynamics_terms"``, ...).
        """
        return None if self._native is None else self._native.get(name)

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

    # -- dynamics ------------------------------------------------------------------
    def dynamics_terms(self, q, qd, lam=None) -> DynamicsTerms:
        """Every term of eq. (16) at one state, from one compiled evaluation.

        Parameters
        ----------
        q, qd : array_like, shape (n,)
            Coordinates and their rates.
        lam : array_like, shape (n_creep,), optional
            Creep states (default zeros).
        """
        values = self._call(
            "dynamics_terms",
            self.robot.check_configuration(q, "q"),
            self._vector("qd", qd, self.n),
            self._vector("lam", lam, self.n_creep),
        )
        return DynamicsTerms(*values)

    def mass_matrix(self, q) -> np.ndarray:
        """Inertia matrix ``D(q)``, shape (n, n), symmetric positive definite.

        Parameters
        ----------
        %(q)s
        """
        return self.dynamics_terms(q, np.zeros(self.n)).mass_matrix

    def coriolis_matrix(self, q, qd) -> np.ndarray:
        """``C(q, qd)`` with Christoffel symbols of ``D``, shape (n, n); ``Ddot - 2C`` is
        skew-symmetric. Evaluated in CasADi's virtual machine (analysis, not a hot path).

        Parameters
        ----------
        q, qd : array_like, shape (n,)
            Coordinates and their rates.
        """
        out = self.symbolic["coriolis_matrix"](
            self.robot.check_configuration(q, "q"), self._vector("qd", qd, self.n), self.parameters
        )
        return np.array(out, dtype=np.float64)

    def coriolis_force(self, q, qd) -> np.ndarray:
        """``C(q, qd) qd``, shape (n,).

        Parameters
        ----------
        q, qd : array_like, shape (n,)
            Coordinates and their rates.
        """
        return self.dynamics_terms(q, qd).coriolis_force

    def gravity_force(self, q) -> np.ndarray:
        """``dV_g/dq``, shape (n,).

        Parameters
        ----------
        %(q)s
        """
        return self.dynamics_terms(q, np.zeros(self.n)).gravity_force

    def elastic_force(self, q) -> np.ndarray:
        """``dV_e/dq``, shape (n,).

        Parameters
        ----------
        %(q)s
        """
        return self.dynamics_terms(q, np.zeros(self.n)).elastic_force

    def potential_force(self, q) -> np.ndarray:
        """``N(q) = dV/dq``, gravity plus elastic (minus the contact force at rest, the
        penalty's gradient, with an environment), shape (n,).

        Parameters
        ----------
        %(q)s
        """
        zero = np.zeros(self.n)  # at rest, without creep: inverse dynamics is G + K - Fc
        return self.dynamics_terms(q, zero).inverse_dynamics(zero)

    def potential_energy(self, q) -> float:
        """``V(q)`` [J], gravitational plus elastic (plus the penalty energy of the
        contact, with an environment).

        Parameters
        ----------
        %(q)s
        """
        parts = self._call("potential_energy", self.robot.check_configuration(q, "q"))
        return float(sum(part[0] for part in parts))

    def kinetic_energy(self, q, qd) -> float:
        """``T(q, qd) = qd' D(q) qd / 2`` [J].

        Parameters
        ----------
        q, qd : array_like, shape (n,)
            Coordinates and their rates.
        """
        qd = self._vector("qd", qd, self.n)
        return float(0.5 * qd @ self.mass_matrix(q) @ qd)

    def energy(self, q, qd) -> float:
        """Total mechanical energy ``T + V`` [J].

        Parameters
        ----------
        q, qd : array_like, shape (n,)
            Coordinates and their rates.
        """
        return self.kinetic_energy(q, qd) + self.potential_energy(q)

    def forward_dynamics(self, q, qd, tau=None, lam=None) -> np.ndarray:
        """Accelerations ``qdd`` solving eq. (16) for the given forces, shape (n,).

        Parameters
        ----------
        q, qd : array_like, shape (n,)
            Coordinates and their rates.
        tau : array_like, shape (n,), optional
            Generalized input forces (default zeros).
        lam : array_like, shape (n_creep,), optional
            Creep states (default zeros).
        """
        x = np.concatenate(
            [
                self.robot.check_configuration(q, "q"),
                self._vector("qd", qd, self.n),
                self._vector("lam", lam, self.n_creep),
            ]
        )
        return self.state_derivative(x, tau)[self.n : 2 * self.n]

    def inverse_dynamics(self, q, qd, qdd, lam=None) -> np.ndarray:
        """Generalized forces ``tau`` that produce ``qdd``, shape (n,).

        Parameters
        ----------
        q, qd, qdd : array_like, shape (n,)
            Coordinates, their rates and accelerations.
        lam : array_like, shape (n_creep,), optional
            Creep states (default zeros).
        """
        return self.dynamics_terms(q, qd, lam).inverse_dynamics(self._vector("qdd", qdd, self.n))

    def creep_rate(self, qd, lam) -> np.ndarray:
        """``lambda'`` of eq. (19), shape (n_creep,).

        Parameters
        ----------
        qd : array_like, shape (n,)
            Coordinate rates.
        lam : array_like, shape (n_creep,)
            Creep states.
        """
        return self._call(
            "creep_rate", self._vector("qd", qd, self.n), self._vector("lam", lam, self.n_creep)
        )[0]

    def state_derivative(self, x, tau=None) -> np.ndarray:
        """``xdot`` for the state ``x = (q, qd, lam)``, shape (n_state,).

        Parameters
        ----------
        x : array_like, shape (n_state,)
            State ``(q, qd, lam)``.
        tau : array_like, shape (n,), optional
            Generalized input forces (default zeros).
        """
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

    def rhs_jacobian(self, x, tau=None) -> np.ndarray:
        """The exact Jacobian ``d xdot / dx`` of the state derivative (:meth:`rhs`) at one
        state, for constant ``tau``: the derivatives of the chain algorithms
        (:mod:`softcurve.symbolic.derivatives`), compiled on first use into a library of
        its own (cached on disk as the model's), else evaluated by CasADi.

        Parameters
        ----------
        x : array_like, shape (n_state,)
            The state ``(q, qd, lam)``.
        tau : array_like, shape (n,), optional
            Constant generalized input forces (default zero).

        Returns
        -------
        ndarray, shape (n_state, n_state)
            Row ``i``, column ``j``: ``d xdot_i / d x_j`` (units of ``xdot_i`` per unit of
            ``x_j``).
        """
        x = self._vector("x", x, self.n_state)
        tau = np.zeros(self.n) if tau is None else self._vector("tau", tau, self.n)
        native = self.compiled_jacobian()
        if native is not None:
            return native(x, tau, self.parameters)[0]
        return np.array(self.casadi_jacobian()(x, tau, self.parameters)[0])

    def jacobian_passes(self) -> JacobianPasses:
        """The passes and tangents of the exact Jacobian through the segments' calls
        (:class:`softcurve.symbolic.derivatives.JacobianPasses`), built on first use and
        kept with the model: what :meth:`casadi_jacobian`, the stepper's period and the
        planners' stage Jacobians are built on."""
        return self.cached(
            ("jacobian-passes",),
            lambda: JacobianPasses(self.expressions, self.quadrature_nodes),
        )

    def casadi_jacobian(self) -> ca.Function:
        """``rhs_jacobian(x, tau, p) -> (J_x, D)`` as a CasADi Function: the exact
        Jacobian of :meth:`casadi_rhs` by the state (n_state, n_state) and the mass matrix
        (n, n), ``d qdd / d tau`` being ``D^-1`` (:mod:`softcurve.symbolic.derivatives`).
        Built on first use."""
        return self.cached(
            ("casadi", "rhs_jacobian"), lambda: state_jacobian(self.jacobian_passes())
        )

    def compiled_jacobian(self) -> NativeFunction | None:
        """:meth:`casadi_jacobian` compiled (on first use, into its own library cached on
        disk as the model's), or None where the model is not compiled or the Jacobian
        does not compile."""
        if self._native is None:
            return None

        def build():
            segments = self.robot.counted()
            loaded = compiled_library(
                self._cache_structure(),
                self.quadrature_nodes,
                lambda: {"rhs_jacobian": self.casadi_jacobian()},
                load=_load_jacobian,
                what=f"the exact Jacobian of the model of {segments}",
                kind="jacobian",
            )
            return None if loaded is None else loaded[1]

        return self.cached(("compiled", "rhs_jacobian"), build)

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
        """World pose at material coordinate ``s`` of the whole robot.

        Element ``i`` covers ``[i/N, (i+1)/N]`` (``robot.span_bounds[i : i + 2]`` where the
        robot gives its ``spans``); ``s = 1`` is the tip.

        Parameters
        ----------
        %(q)s
        s : float
            Material coordinate in [0, 1], dimensionless.
        """
        rotation, position = self._call("pose", self.robot.check_configuration(q, "q"), self._s(s))
        return Pose(rotation, position)

    def tip_pose(self, q) -> Pose:
        """World pose of the tip (``s = 1``).

        Parameters
        ----------
        %(q)s
        """
        return self.pose(q, 1.0)

    def jacobian(self, q, s) -> np.ndarray:
        """Geometric Jacobian (6, n) at ``s``: rows 0-2 linear velocity, rows 3-5 angular
        velocity, both in the world frame, per unit ``qd``.

        Parameters
        ----------
        %(q)s
        s : float
            Material coordinate in [0, 1], dimensionless.
        """
        return self._call("jacobian", self.robot.check_configuration(q, "q"), self._s(s))[0]

    def body_twist(self, q, qd, s) -> np.ndarray:
        """Twist (6,) of the material point at ``s`` in its own frame: linear [m/s] then
        angular [rad/s].

        Parameters
        ----------
        q, qd : array_like, shape (n,)
            Coordinates and their rates.
        s : float
            Material coordinate in [0, 1], dimensionless.
        """
        q = self.robot.check_configuration(q, "q")
        rotation, _ = self.pose(q, s)
        twist = self.jacobian(q, s) @ self._vector("qd", qd, self.n)
        return np.concatenate([rotation.T @ twist[:3], rotation.T @ twist[3:]])

    def backbone(self, q, points: int = 50) -> np.ndarray:
        """Positions (points, 3) [m] along the backbone, from base to tip.

        Parameters
        ----------
        %(q)s
        points : int
            Number of points, >= 2, equally spaced in the material coordinate.
        """
        if not (isinstance(points, int | np.integer) and points >= 2):
            raise ValueError(f"points must be an integer >= 2, got {points!r}")
        q = self.robot.check_configuration(q, "q")
        return np.array([self.pose(q, s).position for s in np.linspace(0.0, 1.0, points)])
