"""The compiled model: NumPy in, NumPy out, over CasADi functions compiled to C.

:class:`Model` builds the symbolic expressions of :mod:`softcurve.dynamics` once,
turns them into CasADi Functions of ``(state..., p)`` where ``p`` is the robot's
parameter vector, generates C for all of them in one library, compiles it with the
system C compiler and loads it. The library is cached on disk under a key made of
the generated source and the compiler command, so a second process with a robot of
the same structure (any parameter values) starts without compiling. Without a C
compiler the same Functions run in CasADi's virtual machine, with one warning.

This is the only module that knows about code generation and caching.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import platform
import shlex
import shutil
import subprocess
import sys
import tempfile
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

from ._native import NativeFunction
from ._validate import ParameterError
from .dynamics import DEFAULT_QUADRATURE_NODES, DynamicsExpressions, build_dynamics
from .kinematics import frame_at
from .robot import Robot


class CompilerWarning(UserWarning):
    """No C compiler was found or it failed: the model runs in CasADi's virtual machine."""


_COMPILE_FLAGS = ("-O2", "-fPIC", "-fvisibility=hidden", "-DGCC_HASCLASSVISIBILITY")
_NATIVE_FLAGS = ("-march=native",)
"""Added when the compiler accepts them and ``SOFTCURVE_PORTABLE`` is not set: the code
then uses this CPU's vector and fused multiply-add instructions, 9-16 % faster
(``benchmarks/bench_model.py``). The cache key holds the CPU's identity, so a cache
shared by different machines keeps one library per CPU type. Results then differ
between CPU types at round-off (as NumPy's, whose BLAS also picks kernels per CPU);
``SOFTCURVE_PORTABLE=1`` builds portable, bitwise reproducible code instead."""


def cache_directory() -> Path:
    """Where compiled models are kept: ``$SOFTCURVE_CACHE_DIR``, else the user cache."""
    env = os.environ.get("SOFTCURVE_CACHE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "softcurve"


def _compiler() -> list[str] | None:
    env = os.environ.get("CC")
    if env:
        return shlex.split(env)
    for name in ("cc", "gcc", "clang"):
        path = shutil.which(name)
        if path:
            return [path]
    return None


def _cpu_identity() -> str:
    """The CPU model and instruction-set flags (Linux), else what the platform reports."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as cpuinfo:
            first = cpuinfo.read().split("\n\n")[0]
    except OSError:
        return f"{platform.machine()} {platform.processor()}"
    fields = {}
    for line in first.splitlines():
        key, _, value = line.partition(":")
        fields[key.strip()] = value.strip()
    keys = ("vendor_id", "model name", "flags", "Features", "CPU part")
    return f"{platform.machine()} " + " ".join(fields.get(k, "") for k in keys)


def _compile_flags() -> tuple[str, ...]:
    """The model's compiler flags: :data:`_COMPILE_FLAGS`, plus :data:`_NATIVE_FLAGS`
    unless ``SOFTCURVE_PORTABLE`` is set (to anything but "0")."""
    if os.environ.get("SOFTCURVE_PORTABLE", "0") not in ("", "0"):
        return _COMPILE_FLAGS
    return _COMPILE_FLAGS + _NATIVE_FLAGS


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
        self.compiled_library: Path | None = None
        if compile:
            library = _compiled_library(self._structure, quadrature_nodes, lambda: self.symbolic)
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
            self._symbolic = _symbolic_functions(self.expressions)
        return self._symbolic

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


def _symbolic_functions(e) -> dict[str, ca.Function]:
    """All numeric entry points as SX Functions whose last input is ``p``."""
    q, qd, qdd, tau, lam, p = e.q, e.qd, e.qdd, e.tau, e.lam, e.p
    x = ca.vertcat(q, qd, lam)
    xs = ca.SX.sym("x", x.shape[0])
    rhs = ca.vertcat(qd, e.forward_dynamics, e.creep_rate)
    rhs = ca.substitute(rhs, x, xs)
    s = ca.SX.sym("s")
    frame = frame_at(q, e.n_segments, e.base_rotation, s)
    jacobian = ca.vertcat(ca.jacobian(frame.position, q), frame.rotation @ frame.angular_jacobian)
    spec = {
        "dynamics_terms": (
            [q, qd, lam],
            ["q", "qd", "lam"],
            [
                e.mass_matrix,
                e.coriolis_force,
                e.gravity_force,
                e.elastic_force,
                e.damping_force,
                e.creep_force,
            ],
            ["D", "Cqd", "G", "K", "Rqd", "KcT_lam"],
        ),
        "mass_matrix": ([q], ["q"], [e.mass_matrix], ["D"]),
        "coriolis_matrix": ([q, qd], ["q", "qd"], [e.coriolis_matrix], ["C"]),
        "coriolis_force": ([q, qd], ["q", "qd"], [e.coriolis_force], ["Cqd"]),
        "gravity_force": ([q], ["q"], [e.gravity_force], ["G"]),
        "elastic_force": ([q], ["q"], [e.elastic_force], ["K"]),
        "potential_energy": ([q], ["q"], [e.gravity_energy, e.elastic_energy], ["Vg", "Ve"]),
        "kinetic_energy": ([q, qd], ["q", "qd"], [e.kinetic_energy], ["T"]),
        "forward_dynamics": (
            [q, qd, tau, lam],
            ["q", "qd", "tau", "lam"],
            [e.forward_dynamics],
            ["qdd"],
        ),
        "inverse_dynamics": (
            [q, qd, qdd, lam],
            ["q", "qd", "qdd", "lam"],
            [e.inverse_dynamics],
            ["tau"],
        ),
        "creep_rate": ([qd, lam], ["qd", "lam"], [e.creep_rate], ["lamd"]),
        "rhs": ([xs, tau], ["x", "tau"], [rhs], ["xdot"]),
        "pose": ([q, s], ["q", "s"], [frame.rotation, frame.position], ["rotation", "position"]),
        "jacobian": ([q, s], ["q", "s"], [jacobian], ["J"]),
    }
    functions = {}
    for name, (inputs, in_names, outputs, out_names) in spec.items():
        functions[name] = ca.Function(
            name, [*inputs, p], [ca.cse(o) for o in outputs], [*in_names, "p"], out_names
        )
    return functions


COMPILED_FUNCTIONS = (
    "dynamics_terms",
    "potential_energy",
    "creep_rate",
    "rhs",
    "pose",
    "jacobian",
)
"""Compiled to C: every term of the equation of motion comes from ``dynamics_terms`` and
the accelerations from ``rhs``, so the large expressions are compiled twice, not once per
method; ``coriolis_matrix`` (for analysis, several times larger than ``C qd``) runs in
CasADi's virtual machine. The other entries of ``symbolic`` are for users who build on
CasADi (optimal control, code generation)."""
_SYMBOLIC_SOURCES = ("_smooth.py", "materials.py", "kinematics.py", "dynamics.py", "model.py")


def _cache_key(structure: tuple, quadrature_nodes: int, command: list[str]) -> str:
    """Everything the generated code depends on: structure, node count, the source of the
    symbolic layer, CasADi's version, the compiler command and flags, and the CPU when the
    code is built for it."""
    digest = hashlib.sha256()
    flags = _compile_flags()
    digest.update(repr((structure, quadrature_nodes, command, flags)).encode())
    if _NATIVE_FLAGS[0] in flags:
        digest.update(_cpu_identity().encode())
    digest.update(f"{ca.__version__} {sys.platform} {sys.implementation.cache_tag}".encode())
    here = Path(__file__).parent
    for name in _SYMBOLIC_SOURCES:
        digest.update((here / name).read_bytes())
    return digest.hexdigest()[:24]


def _compiled_library(structure, quadrature_nodes, symbolic) -> Path | None:
    """The cached library for this structure, compiling it first if needed; None on failure."""
    compiler = _compiler()
    if compiler is None:
        warnings.warn(
            "no C compiler found (set CC, or install gcc or clang): softcurve runs in "
            "CasADi's virtual machine, about 10x slower to simulate",
            CompilerWarning,
            stacklevel=3,
        )
        return None
    library = cache_directory() / f"model_{_cache_key(structure, quadrature_nodes, compiler)}.so"
    if library.exists():
        return library
    try:
        functions = symbolic()
        selected = {name: functions[name] for name in COMPILED_FUNCTIONS}
        try:
            _compile(selected, compiler, library, _compile_flags())
        except subprocess.CalledProcessError:
            if _compile_flags() == _COMPILE_FLAGS:
                raise
            _compile(selected, compiler, library)  # a compiler without -march=native
    except (OSError, subprocess.CalledProcessError) as exc:
        detail = getattr(exc, "stderr", None) or str(exc)
        warnings.warn(
            f"compiling the model with {compiler[0]} failed ({str(detail).strip()[:400]}): "
            "softcurve runs in CasADi's virtual machine",
            CompilerWarning,
            stacklevel=3,
        )
        return None
    return library


def _compile(
    functions: dict[str, ca.Function],
    compiler: list[str],
    library: Path,
    flags: tuple[str, ...] = _COMPILE_FLAGS,
) -> None:
    """One C file per function, compiled in parallel, linked into ``library`` atomically."""
    library.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        jobs = []
        for name, f in functions.items():
            generator = ca.CodeGenerator(f"{name}.c", {"with_header": False})
            generator.add(f)
            generator.generate(tmp + os.sep)
            jobs.append([*compiler, *flags, "-c", f"{name}.c", "-o", f"{name}.o"])
        with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
            list(pool.map(lambda job: _run(job, tmp), jobs))
        partial = Path(tmp, "model.so")
        objects = [f"{name}.o" for name in functions]
        _run([*compiler, "-shared", "-o", str(partial), *objects, "-lm"], tmp)
        staged = library.parent / f".{library.name}.{os.getpid()}"
        shutil.copyfile(partial, staged)
        os.replace(staged, library)  # atomic: other processes see all or nothing


def compile_function(function: ca.Function, optimisation: str = "-O1") -> ca.Function:
    """``function`` generated as C, compiled, cached on disk by its content and loaded.

    For CasADi functions built on a model's expressions (the identification's
    sensitivity equations, say) that are evaluated often: the same compiler and cache as
    :class:`Model`, keyed by the serialised function, so a second process loads it.

    Parameters
    ----------
    function : casadi.Function
        An SX or MX function without Python callbacks.
    optimisation : str
        The compiler's optimisation flag; ``-O1`` compiles large generated files several
        times faster than ``-O2`` at a small cost in speed.

    Returns
    -------
    casadi.Function
        The compiled function as a CasADi ``external`` (derivatives by finite
        differences), or ``function`` itself when no C compiler works (then it runs in
        CasADi's virtual machine).
    """
    compiler = _compiler()
    if compiler is None:
        return function
    digest = hashlib.sha256(function.serialize().encode())
    digest.update(f"{ca.__version__} {sys.platform} {compiler} {optimisation}".encode())
    library = cache_directory() / f"function_{digest.hexdigest()[:24]}.so"
    if not library.exists():
        try:
            _compile({function.name(): function}, compiler, library, (optimisation, "-fPIC"))
        except (OSError, subprocess.CalledProcessError):
            return function
    return ca.external(function.name(), str(library), {"enable_fd": True})


def _run(command: list[str], directory: str) -> None:
    subprocess.run(command, cwd=directory, check=True, capture_output=True, text=True)
