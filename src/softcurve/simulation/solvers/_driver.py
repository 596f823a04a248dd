"""CVODES driven from C: softcurve's own driver (the C files of
``softcurve/simulation/solvers/c``, declared to Python by ``softcurve_driver.h``) of the
SUNDIALS CVODES that ships inside CasADi, and of its own Radau IIA (``radau.c``;
``softcurve.simulation.solvers.RadauEngine``), on the model's compiled right-hand side.

Why not CasADi's ``integrator``: on the paper's 10 s case it spends more time around the
right-hand side than in it (``docs/performance.md``): every evaluation goes through
CasADi's virtual machine (the scaled DAE is an MX graph around the compiled ``rhs``) and
reads the process CPU clock (a system call; threads of one process contend for it), and
the Newton matrix's Jacobian is recomputed by finite differences at every linear-solver
setup. The driver calls the compiled function directly, keeps the Jacobian while CVODES
allows (``jok``), factors the Newton matrix itself and integrates every member of a batch
in one call, on threads that do not contend.

:func:`problem` describes a model (and optionally an actuator's force) to the driver;
:func:`integrate` runs it, with the settings of :func:`options`, the one place that fills
the header's ``sc_options``. Both return None / are unused where the driver cannot be
built (no C compiler, an uncompiled model, a CasADi outside :data:`CASADI_VERIFIED` or
whose SUNDIALS has another interface) or ``SOFTCURVE_NATIVE_CVODES=0`` is set; the
engines then use CasADi's integrator, and :func:`unavailable` says why.

The C is in ``softcurve/simulation/solvers/c`` (package data, :data:`C_FOLDER`):
``softcurve_driver.h`` declares what Python calls (the structs ``sc_function`` and
``sc_options`` and the exported functions, in the restricted form that
:func:`softcurve.compiled.read_header` reads into the ctypes declarations),
``sundials2.h`` the SUNDIALS 2.x of CasADi's private CVODES plugin, which ships no
headers. :func:`library` builds and loads it once per process.

The members of a batch are integrated in groups (``groups.c``) on the state derivative
over lanes (:func:`lanes_derivative`): the function the scalar driver evaluates (the
model's ``rhs`` with the actuator's force and lag,
:func:`~softcurve.simulation.solvers.actuated_derivative`), generated over lanes of
``softcurve.compiled.LANE_WIDTH`` members with every input per member (members of a
batch may have their own parameters).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import re
import threading
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import casadi as ca
import numpy as np

from softcurve.base.shares import run_shares, share_bounds
from softcurve.compiled import (
    LANE_WIDTH,
    NativeFunction,
    c_template,
    compile_files,
    compile_lanes,
    compile_source,
    lanes_function,
    lanes_prelude,
    lanes_work,
    load_library,
    read_header,
)
from softcurve.simulation.solvers._actuated import actuated_derivative

STATISTICS = ("steps", "rhs_evaluations", "jacobian_evaluations", "linear_solver_setups",
              "error_test_failures", "newton_failures")  # fmt: skip
"""The counters the driver returns per member, in its order."""

CHUNKS_PER_THREAD = 4
"""Members of a batch are handed to the threads in this many chunks per thread, taken as
threads finish: members differ in cost (a violent transient takes more steps)."""


def driver():
    """The driver's entry point ``softcurve_integrate`` (ctypes), built and loaded once per
    process; None where it cannot be (see the module notes) or inside :func:`casadi_only`."""
    loaded = library()
    return None if loaded is None or _BYPASS else loaded.softcurve_integrate


def unavailable() -> str | None:
    """Why :func:`driver` is None, in a phrase (None where the driver is loaded): inside
    :func:`casadi_only` (:data:`CASADI_ONLY`), ``SOFTCURVE_NATIVE_CVODES=0``
    (``SWITCHED_OFF``), or why the library does not load."""
    if driver() is not None:
        return None
    return CASADI_ONLY if _BYPASS else library_unavailable()


CASADI_ONLY = "casadi_only() was asked"
"""Why the driver is unused inside :func:`casadi_only` (the user's choice)."""


_BYPASS: list = []


def entry(name: str):
    """The driver library's function ``name`` (after :func:`driver` succeeded).

    Parameters
    ----------
    name : str
        An exported function of :data:`HEADER`.
    """
    return getattr(library(), name)


@contextlib.contextmanager
def casadi_only():
    """Within this context, new engines and batches use CasADi's integrator (the previous
    route, for comparisons: ``benchmarks/bench_simulate.py``, the tests)."""
    _BYPASS.append(True)
    try:
        yield
    finally:
        _BYPASS.pop()


def options(rtol, atol, max_steps, *, max_order=0, family=1, settled_ratio=0.0,
            columns_tested=False, helper=False, radau=None):  # fmt: skip
    """The settings of a call of the driver, as the header's ``sc_options``: the one place
    that fills it.

    Parameters
    ----------
    rtol : float
        Relative tolerance.
    atol : float
        Absolute tolerance of the integrated state (the scaled state of
        :func:`integrate`, the state's units of the sensitivities).
    max_steps : int
        Steps allowed per output.
    max_order : int, optional
        The method's largest order (0 or None: CVODES's own).
    family : int
        1 Adams, 2 BDF, 3 Radau IIA (the sensitivities; :func:`integrate` takes one per member,
        :data:`FAMILIES`).
    settled_ratio : float
        ``softcurve.simulation.solvers._policy.SETTLED_RATIO`` (dimensionless), with a
        member's fastest rate.
    columns_tested : bool
        The sensitivity columns in the error test too.
    helper : bool
        With two parts of the columns' right-hand side, a helper thread shares the second.
    radau : ndarray, shape (RADAU_CONSTANTS,), optional
        Radau IIA's constants (:func:`~softcurve.simulation.solvers.radau_constants`), for
        members of the family ``FAMILY_RADAU``; the array must outlive the call.

    Returns
    -------
    Options
    """
    constants = DECLARATIONS.constants
    return Options(
        rtol=rtol,
        atol=atol,
        max_steps=max_steps,
        max_order=max_order or 0,
        family=family,
        settled_ratio=settled_ratio,
        columns_tested=int(columns_tested),
        helper=constants["HELPER_SHARED"] if helper else constants["HELPER_NONE"],
        radau=None if radau is None else radau.ctypes.data,
    )


class DriverProblem:
    """A model's right-hand side (and an actuator's force) described to the driver.

    Parameters
    ----------
    rhs : NativeFunction
        The model's compiled ``rhs(x, tau, p)``.
    n_state, n, n_parameters : int
        Sizes of ``x``, ``tau`` and ``p``.
    force : NativeFunction, optional
        ``H(q) v`` of an actuator, compiled.
    inputs : ActuatorInput, optional
        The actuator's input (bounds, lag), with ``force``.
    lanes : LanesDerivative, optional
        The same state derivative over lanes
        (``softcurve.simulation.solvers._driver.lanes_derivative``): members are then
        integrated in groups of its width, ``self.width`` (else 1).
    domain : NativeFunction, optional
        The model's compiled ``domain(q, p)`` (1 inside, 0 outside), which the driver
        calls at its outputs with each member's parameters; None: no configuration is
        outside (an entry not finite still is).
    jacobian : NativeFunction, optional
        The model's compiled exact Jacobian ``rhs_jacobian(x, tau, p) -> (J_x, D)``
        (:meth:`~softcurve.Model.compiled_jacobian`) for the Newton matrix; None:
        forward differences of ``rhs``.
    force_jacobian : NativeFunction, optional
        With ``jacobian`` and ``force``, the force's exact derivatives
        ``(q, v) -> (d tau / d q, H(q))`` (:func:`force_jacobian`); None: forward
        differences of ``force``.
    """

    def __init__(self, rhs, n_state, n, n_parameters, force=None, inputs=None, lanes=None,
                 domain=None, jacobian=None, force_jacobian=None):  # fmt: skip
        functions = [f for f in (rhs, force, domain, jacobian, force_jacobian) if f is not None]
        self.exact = jacobian is not None
        self._keep = [*functions, lanes]  # the functions and bounds outlive the struct
        self.width = 1 if lanes is None else lanes.width
        lag = inputs is not None and inputs.time_constant is not None
        self.bounds = (
            (np.array(inputs.lower, dtype=np.float64), np.array(inputs.upper, dtype=np.float64))
            if inputs is not None else (np.zeros(1), np.zeros(1))
        )  # fmt: skip
        sizes = np.max([f.work_sizes for f in functions], axis=0).tolist()
        self.struct = ProblemStruct(
            f=rhs.address,
            force=None if force is None else force.address,
            domain=None if domain is None else domain.address,
            jacobian=None if jacobian is None else jacobian.address,
            force_jacobian=None if force_jacobian is None else force_jacobian.address,
            nx=n_state,
            nu=n,
            np=n_parameters,
            m=0 if inputs is None else inputs.n_inputs,
            lag=int(lag),
            **dict(zip(("sz_arg", "sz_res", "sz_iw", "sz_w"), sizes, strict=True)),
            lower=self.bounds[0].ctypes.data,
            upper=self.bounds[1].ctypes.data,
            time_constant=inputs.time_constant if lag else 1.0,
            lanes=None if lanes is None else lanes.address,
            width=self.width,
            sz_lanes_w=0 if lanes is None else lanes.work,
        )


def problem(model, inputs=None, lanes: bool = False, exact: bool = False) -> DriverProblem | None:
    """The :class:`DriverProblem` of ``model`` driven by forces or by ``inputs`` (an
    :class:`~softcurve.simulation.solvers.ActuatorInput`, whose force ``H(q) u`` is
    compiled once per actuator and cached on disk), cached with the model; None where the
    driver is not available.

    Parameters
    ----------
    model : Model
        The model.
    inputs : ActuatorInput, optional
        The actuator's input, or None for forces.
    lanes : bool
        Integrate members in groups on the state derivative over lanes (compiled at the
        first such call); where it cannot be built, the problem integrates them alone.
    exact : bool
        The Newton matrix from the model's exact Jacobian and the force's
        (:func:`force_jacobian`; each compiled at the first such call), where they
        compile; else from forward differences.
    """
    rhs = model.compiled_function("rhs")
    if driver() is None or rhs is None:
        return None

    def build():
        force = None
        if inputs is not None:
            force = _compiled_force(inputs.force)
            if force is None:
                return None
        vectors = lanes_derivative(model, inputs) if lanes else None
        domain = model.compiled_function("domain")
        jacobian = model.compiled_jacobian() if exact else None
        along_q = None
        if jacobian is not None and inputs is not None:
            along_q = _compiled_force(force_jacobian(inputs.force))
        return DriverProblem(rhs, model.n_state, model.n, model.parameters.size, force,
                             inputs, vectors, domain, jacobian, along_q)  # fmt: skip

    key = ("native problem", None if inputs is None else inputs.key, lanes, exact)
    return model.cached(key, build)


def force_jacobian(force: ca.Function) -> ca.Function:
    """``(q, v) -> (d tau / d q, H(q))``: the exact derivatives of an actuator's force
    ``tau = H(q) v`` along the coordinates and the inputs, what the driver's exact Newton
    matrix takes (``softcurve_driver.h``'s ``force_jacobian``).

    Parameters
    ----------
    force : casadi.Function
        ``(q, v) -> tau`` (``ActuatorInput.force``).
    """
    q, v = (ca.SX.sym(name, force.sparsity_in(i)) for i, name in enumerate("qv"))
    tau = force(q, v)
    along = [ca.densify(ca.jacobian(tau, s)) for s in (q, v)]
    return ca.Function(f"{force.name()}_jacobian", [q, v], along)


def _compiled_force(force: ca.Function) -> NativeFunction | None:
    """``force`` generated as C, compiled (cached on disk by its code) and loaded, or None."""
    generator = ca.CodeGenerator("force.c", {"with_header": False})
    generator.add(force)
    built = compile_source("actuator_force", generator.dump(), symbols=(force.name(),))
    return None if built is None else NativeFunction(built, force.name())


def integrate(problem, lmm, x0, u, p, nominal, times, segments, settings, *, fastest=None,
              check_domain=False, threads=1, out=None) -> tuple:  # fmt: skip
    """Integrate members from ``x0`` at ``times[0]`` over the output ``times``, with one
    constant input per member and segment: CVODES restarts at the end of every segment,
    Radau IIA only steps to it where the input changes there; CVODES's members in groups
    of ``problem.width`` consecutive members of one family (``groups.c``).

    Parameters
    ----------
    problem : DriverProblem
        What to integrate.
    lmm : array_like of int, shape (B,)
        Family per member, a value of :data:`FAMILIES` (1 Adams, 2 BDF, 3 Radau IIA).
    x0 : ndarray, shape (B, N)
        Initial states (``N`` = n_state, plus the lagging inputs).
    u : ndarray, shape (B, S, k)
        Input per member and segment: forces [N, N m^2, N m^2] or the actuator's inputs
        (commands).
    p : ndarray, shape (B, n_p)
        Parameter vector per member.
    nominal : ndarray, shape (B, N)
        State scales (> 0).
    times : ndarray, shape (T,)
        Output times [s], increasing; ``x0`` is at ``times[0]``.
    segments : tuple
        ``(ends (S,), restart (S,))``: the output index where each segment ends (the last
        is ``T - 1``), and whether it begins a restart interval, where a member with
        ``fastest`` switches to BDF once settled
        (``softcurve.simulation.solvers._policy.SETTLED_RATIO``) and back to its own family.
    settings : Options
        The call's settings, :func:`options` (rtol, the absolute tolerance of the scaled
        state, steps per output, largest order, the settled switch's ratio).
    fastest : ndarray, shape (B,), optional
        Fastest rate of each member's initial linearization [1/s] (0 or None: no switch).
    check_domain : bool
        A member stops at its first output whose configuration lies outside the model's
        domain, by the model's compiled ``domain(q, p)`` with the member's own ``p`` (the
        rule of :mod:`softcurve.description.elements`); at any output with an entry not
        finite in any case.
    threads : int
        Threads over the members.
    out : ndarray, shape (B, T, N), optional
        Where to write the outputs (C-contiguous float64; row 0 of each member is set
        to ``x0``): a caller's own array saves the copy of a long run's outputs (default:
        a new array).

    Returns
    -------
    tuple
        ``(states (B, T, N), reached (B,), flags (B,), counts (B, 6), used_bdf (B,))``:
        outputs, how many were computed (the first outside the domain included), the flag
        (0: success, 1: outside the domain, else CVODES's or Radau IIA's as the CVODES flag
        of the same meaning, :data:`FLAGS`), the counters of
        :data:`STATISTICS` and whether BDF was used.
    """
    count, width = x0.shape
    if out is None:
        out = np.zeros((count, times.size, width))
    elif out.shape != (count, times.size, width) or not (
        out.flags.c_contiguous and out.dtype == np.float64
    ):
        raise ValueError(f"out must be C-contiguous float64 of shape {(count, times.size, width)}")
    out[:, 0] = x0
    ends, restart = (np.ascontiguousarray(a, dtype=np.int32) for a in segments)
    fastest = np.zeros(count) if fastest is None else fastest
    arrays = [np.ascontiguousarray(a, dtype=np.float64) for a in (fastest, u, p, nominal)]
    lmm = np.ascontiguousarray(lmm, dtype=np.int32)
    times = np.ascontiguousarray(times, dtype=np.float64)
    reached, flags, used = (np.zeros(count, dtype=np.int32) for _ in range(3))
    counts = np.zeros((count, len(STATISTICS)), dtype=np.int64)
    call = driver()

    def run(a: int, b: int) -> None:
        fast, uu, pp, nom = (arr[a:b].ctypes.data for arr in arrays)
        call(ctypes.byref(problem.struct), ctypes.byref(settings), b - a, lmm[a:].ctypes.data,
             fast, uu, pp, nom, int(check_domain), times.ctypes.data, times.size,
             ends.ctypes.data, restart.ctypes.data, ends.size, out[a:b].ctypes.data,
             reached[a:].ctypes.data, flags[a:].ctypes.data, used[a:].ctypes.data,
             counts[a:b].ctypes.data)  # fmt: skip

    threads = max(1, min(threads, count))
    # shares of whole groups: the grouping, hence every result, is that of one thread
    shares = 1 if threads == 1 else CHUNKS_PER_THREAD * threads
    run_shares(run, share_bounds(count, shares, problem.width), threads)
    return out, reached, flags, counts, used.astype(bool)


def evaluate(problem, x, u, p) -> np.ndarray:
    """The right-hand side at many states in one call: ``xdot`` (K, N) at states ``x``
    (K, N) with inputs ``u`` (K, k) and the parameter vector ``p`` (n_p,).

    Parameters
    ----------
    problem : DriverProblem
        What to evaluate.
    x : ndarray, shape (K, N)
        States.
    u : ndarray, shape (K, k)
        Inputs: forces [N, N m^2, N m^2] or the actuator's inputs.
    p : ndarray, shape (n_p,)
        Parameter vector.
    """
    x, u, p = (np.ascontiguousarray(a, dtype=np.float64) for a in (x, u, p))
    out = np.empty_like(x)
    function = entry("softcurve_rhs")
    if function(ctypes.byref(problem.struct), x.shape[0], x.ctypes.data, u.ctypes.data,
                p.ctypes.data, out.ctypes.data):  # fmt: skip
        raise RuntimeError("the compiled right-hand side failed")
    return out


def newton_jacobian(problem, x, u, p, nominal) -> np.ndarray:
    """The Jacobian that the driver's Newton matrix takes at one state: that of the
    integrated scaled state ``x / nominal``, from the problem's exact Jacobian where it
    has one, else from forward differences.

    Parameters
    ----------
    problem : DriverProblem
        What to differentiate.
    x : ndarray, shape (N,)
        State (``n_state`` plus the lagging inputs).
    u : ndarray, shape (k,)
        Inputs: forces [N, N m^2, N m^2] or the actuator's inputs.
    p : ndarray, shape (n_p,)
        Parameter vector.
    nominal : ndarray, shape (N,)
        State scales (> 0).

    Returns
    -------
    ndarray, shape (N, N)
        ``d (xdot_i / nominal_i) / d (x_j / nominal_j)``.
    """
    x, u, p, nominal = (np.ascontiguousarray(a, dtype=np.float64) for a in (x, u, p, nominal))
    fn = problem.struct
    states = fn.nx + (fn.m if fn.lag else 0)
    sizes = {"x": states, "u": fn.m if fn.force else fn.nu, "p": fn.np, "nominal": states}
    for name, value in zip(sizes, (x, u, p, nominal), strict=True):
        if value.shape != (sizes[name],):
            raise ValueError(f"{name} must have shape ({sizes[name]},), got {value.shape}")
    out = np.empty((x.size, x.size), order="F")
    function = entry("softcurve_newton_jacobian")
    if function(ctypes.byref(problem.struct), x.ctypes.data, u.ctypes.data, p.ctypes.data,
                nominal.ctypes.data, out.ctypes.data):  # fmt: skip
        raise RuntimeError("the Newton matrix's Jacobian failed")
    return out


def reason(flag: int) -> str:
    """CVODES's ``flag`` as the name :func:`~softcurve.simulation.solvers.cvodes_reason`
    explains.

    Parameters
    ----------
    flag : int
        A negative return flag of CVODES.
    """
    return FLAGS.get(int(flag), f"CVODES flag {int(flag)}")


PLUGIN = "libcasadi_integrator_cvodes.so"
"""CasADi's CVODES plugin, which holds SUNDIALS CVODES (the 2.x interface: ``CVSpgmr``)."""

C_FOLDER = Path(__file__).resolve().parent / "c"
"""The driver's C files (package data): every ``.c`` there is compiled into its library."""

HEADER = C_FOLDER / "softcurve_driver.h"
"""The header that declares the driver's structs and exported functions."""

DECLARATIONS = read_header(HEADER)
"""The ctypes declarations of :data:`HEADER`
(``softcurve.compiled._declarations.Declarations``)."""

ProblemStruct = DECLARATIONS.structs["sc_function"]
"""The header's ``sc_function``: a model described to the driver."""

Options = DECLARATIONS.structs["sc_options"]
"""The header's ``sc_options``: the settings of a call
(:func:`softcurve.simulation.solvers.driver_options`)."""

FAMILIES = {
    name: DECLARATIONS.constants[f"FAMILY_{name.upper()}"] for name in ("adams", "bdf", "radau")
}
"""The driver's integration families by name (``FAMILY_*`` of ``softcurve_driver.h``)."""

FLAGS = {
    -1: "CV_TOO_MUCH_WORK", -2: "CV_TOO_MUCH_ACC", -3: "CV_ERR_FAILURE",
    -4: "CV_CONV_FAILURE", -5: "CV_LINIT_FAIL", -6: "CV_LSETUP_FAIL", -7: "CV_LSOLVE_FAIL",
    -8: "CV_RHSFUNC_FAIL", -9: "CV_FIRST_RHSFUNC_ERR", -10: "CV_REPTD_RHSFUNC_ERR",
    -11: "CV_UNREC_RHSFUNC_ERR", -20: "CV_MEM_FAIL", -22: "CV_ILL_INPUT",
    -27: "CV_TOO_CLOSE", -100: "the solver could not be set up",
    DECLARATIONS.constants["COLUMNS_FAILURE"]: "the sensitivity columns' iteration did not "
    "converge, on a fresh Jacobian either (tighten rtol, or use Adams)",
}  # fmt: skip
"""CVODES's return flags (SUNDIALS 2.x ``cvodes.h``) by value, and the driver's own."""

CASADI_VERIFIED = ">=3.8,<3.9"
"""The CasADi versions whose private CVODES plugin the driver was verified with (the
requirement of ``pyproject.toml``, which a test checks equal): the driver declares the
plugin's SUNDIALS by hand (``sundials2.h``) and refuses to load with another CasADi
(:func:`version_verified`)."""


def _release(version: str) -> tuple[int, ...]:
    """The numeric release of a version string: ``"3.8.2"`` -> ``(3, 8, 2)``."""
    numbers = []
    for part in version.split("."):
        digits = re.match(r"\d*", part).group()
        if digits:
            numbers.append(int(digits))
        if not digits or digits != part:  # "3.8.2rc1" -> (3, 8, 2)
            break
    return tuple(numbers)


def version_verified(version: str, requirement: str = CASADI_VERIFIED) -> bool:
    """Whether the CasADi ``version`` meets ``requirement`` (comma-separated ``>=``,
    ``>``, ``<=``, ``<``, ``==``, ``!=`` clauses on release numbers).

    Parameters
    ----------
    version : str
        A CasADi version, e.g. ``casadi.__version__``.
    requirement : str
        The versions allowed (default :data:`CASADI_VERIFIED`).

    Returns
    -------
    bool

    Examples
    --------
    >>> version_verified("3.8.2"), version_verified("3.9.0"), version_verified("3.7.1")
    (True, False, False)
    """
    have = _release(version)
    compare = {
        ">=": lambda a, b: a >= b, "<=": lambda a, b: a <= b, "==": lambda a, b: a == b,
        "!=": lambda a, b: a != b, ">": lambda a, b: a > b, "<": lambda a, b: a < b,
    }  # fmt: skip
    for clause in requirement.split(","):
        clause = clause.strip()
        operator = clause[:2] if clause[:2] in compare else clause[:1]
        wanted = _release(clause[len(operator) :].strip())
        width = max(len(have), len(wanted))
        padded = [v + (0,) * (width - len(v)) for v in (have, wanted)]
        if not compare[operator](*padded):
            return False
    return True


_LIBRARIES: dict = {}  # the driver's library by its defines (or why not, a str), per process
_LOCK = threading.Lock()


def library(defines: tuple[str, ...] = ()):
    """The driver's library built from :data:`C_FOLDER` with the macros ``defines``, its
    functions declared from :data:`HEADER`; built and loaded once per process and
    ``defines``; None where it cannot be: no C compiler, a CasADi outside
    :data:`CASADI_VERIFIED` or whose SUNDIALS has another interface, or
    ``SOFTCURVE_NATIVE_CVODES=0``.

    Parameters
    ----------
    defines : tuple of str
        Macros defined for the build (tests build variants; the product defines none).

    Returns
    -------
    ctypes.CDLL or None
    """
    loaded = _loaded(defines)
    return None if isinstance(loaded, str) else loaded


def library_unavailable(defines: tuple[str, ...] = ()) -> str | None:
    """Why :func:`library` is None, in a phrase (None where it loads).

    Parameters
    ----------
    defines : tuple of str
        Macros defined for the build, as :func:`library` takes them.
    """
    loaded = _loaded(defines)
    return loaded if isinstance(loaded, str) else None


SWITCHED_OFF = "SOFTCURVE_NATIVE_CVODES=0 is set"
"""Why the driver is unused under ``SOFTCURVE_NATIVE_CVODES=0`` (the user's choice)."""


def _loaded(defines: tuple[str, ...]):
    """The library of ``defines`` or why not (a str), loaded once per process."""
    with _LOCK:
        if defines not in _LIBRARIES:
            _LIBRARIES[defines] = _load(defines)
        return _LIBRARIES[defines]


def _load(defines: tuple[str, ...]):
    """The loaded library, or why it cannot be loaded (a str)."""
    if os.environ.get("SOFTCURVE_NATIVE_CVODES", "1") in ("0", ""):
        return SWITCHED_OFF
    if not version_verified(ca.__version__):
        return f"CasADi {ca.__version__} is outside the verified {CASADI_VERIFIED}"
    directory = Path(ca.__file__).parent
    try:
        if not hasattr(load_library(directory / PLUGIN), "CVSpgmr"):  # SUNDIALS >= 3: other API
            return f"CasADi's {PLUGIN} lacks the SUNDIALS 2.x interface (CVSpgmr)"
    except OSError as exc:
        return f"CasADi's {PLUGIN} cannot be loaded ({exc})"
    link = (f"-L{directory}", f"-l:{PLUGIN}", f"-Wl,-rpath,{directory}", "-pthread")
    loaded = compile_files("cvodes_driver", C_FOLDER, link, defines, tuple(DECLARATIONS.functions))
    if loaded is None:
        return "the driver's C source did not compile (no C compiler, or the build failed)"
    bound = DECLARATIONS.bind(loaded)
    try:
        bound.softcurve_use_lapack(*lapack_addresses(), LAPACK_FROM)
    except (ImportError, AttributeError, KeyError, ValueError):
        pass  # a SciPy without these capsules: the driver's own loops at every size
    return bound


LAPACK_FROM = 32
"""Newton matrices of this many states and more are factored and solved by LAPACK
(SciPy's ``dgetf2`` and ``dgetrs``, and for Radau IIA's complex ones ``zgetf2`` and
``zgetrs``, :func:`lapack_addresses`); smaller ones by the driver's own loops. Measured
on the real routines: 1 s of the hanging chain ran as fast on LAPACK at 18, 27 and 36
states, and 5 and 11 % faster at 72 and 144; a batch of two members on two threads 4 and
8 % faster there (``python benchmarks/bench_lapack.py``, best of seven, OpenBLAS's
default threads)."""

LAPACK_SIGNATURES = {
    "dgetf2": "void (int *, int *, __pyx_t_5scipy_6linalg_13cython_lapack_d *, int *, int *, "
    "int *)",
    "dgetrs": "void (char *, int *, int *, __pyx_t_5scipy_6linalg_13cython_lapack_d *, int *, "
    "int *, __pyx_t_5scipy_6linalg_13cython_lapack_d *, int *, int *)",
    "zgetf2": "void (int *, int *, __pyx_t_double_complex *, int *, int *, int *)",
    "zgetrs": "void (char *, int *, int *, __pyx_t_double_complex *, int *, int *, "
    "__pyx_t_double_complex *, int *, int *)",
}
"""The C signatures of the routines the driver calls, as SciPy's capsules name them: C
``int`` for every integer (not 64-bit LAPACK), ``double`` and C99's ``double complex``
(two doubles) for the numbers."""


def lapack_addresses() -> tuple[int, ...]:
    """The addresses of LAPACK's ``dgetf2``, ``dgetrs``, ``zgetf2`` and ``zgetrs`` in SciPy
    (``scipy.linalg.cython_lapack``, whose Cython API exports them as capsules in
    ``__pyx_capi__``: the mechanism ``cimport`` uses), each checked against
    :data:`LAPACK_SIGNATURES` (``tests/test_native_cvodes.py`` checks the pin).

    Returns
    -------
    tuple of int
        ``(dgetf2, dgetrs, zgetf2, zgetrs)``.

    Raises
    ------
    ValueError
        Where a capsule's signature is not the one the driver calls.
    """
    from scipy.linalg import cython_lapack

    py_object, text, address = ctypes.py_object, ctypes.c_char_p, ctypes.c_void_p
    api = ctypes.pythonapi
    name = ctypes.PYFUNCTYPE(text, py_object)(("PyCapsule_GetName", api))
    pointer = ctypes.PYFUNCTYPE(address, py_object, text)(("PyCapsule_GetPointer", api))
    addresses = []
    for routine, signature in LAPACK_SIGNATURES.items():
        capsule = cython_lapack.__pyx_capi__[routine]
        if name(capsule) != signature.encode():
            raise ValueError(f"SciPy's {routine} is {name(capsule)!r}, not {signature!r}")
        addresses.append(pointer(capsule, name(capsule)))
    return tuple(addresses)


ENTRY = "softcurve_lanes_xdot"
"""The C entry point: ``(x, u, p, xdot, w) -> 0``, every array lanes-interleaved (entry
``j`` of member ``l`` at ``[j * width + l]``) and aligned to 64 bytes."""


def xdot_source(f, vector_math: bool) -> str:
    """The C source of :data:`ENTRY`: the state derivative ``f`` over lanes.

    Parameters
    ----------
    f : casadi.Function
        ``(x, u, p) -> xdot`` as an SX function
        (:func:`~softcurve.simulation.solvers.actuated_derivative`, expanded).
    vector_math : bool
        Use glibc's vector math library where compiled for AVX2
        (:func:`~softcurve.compiled.lanes_prelude`).

    Returns
    -------
    str
        The C source.

    Raises
    ------
    NotImplementedError
        If ``f`` has an operation without lanes code.
    """
    return "\n".join(
        [
            lanes_prelude(LANE_WIDTH, vector_math),
            lanes_function(f, "sc_xdot", (False, False, False)),
            c_template("lanes_xdot.c", {"SC_ENTRY": ENTRY}),
        ]
    )


@dataclass(frozen=True)
class LanesDerivative:
    """A compiled :func:`xdot_source`.

    Parameters
    ----------
    entry : ctypes function
        :data:`ENTRY` (kept so that its library stays loaded).
    width : int
        Members per call.
    work : int
        Rows of ``width`` doubles of the work array ``w``.
    vector_math : bool
        Whether it was linked with glibc's vector math library.
    """

    entry: object
    width: int
    work: int
    vector_math: bool

    @property
    def address(self) -> int:
        """The entry's address, for the driver's function table."""
        return ctypes.cast(self.entry, ctypes.c_void_p).value


def lanes_derivative(model, inputs=None) -> LanesDerivative | None:
    """The compiled state derivative over lanes, kept with the model (and cached on disk).

    Parameters
    ----------
    model : Model
        The compiled model.
    inputs : ActuatorInput, optional
        The actuator's inputs (None: generalized forces).

    Returns
    -------
    LanesDerivative or None
        None where no C compiler builds it or the model has an operation without lanes
        code (the driver then integrates every member alone).
    """

    def build():
        f = actuated_derivative(model, inputs, model.symbolic["rhs"]).expand()
        built = compile_lanes("driver_lanes", partial(xdot_source, f), ENTRY, [ctypes.c_void_p] * 5)
        if built is None:
            return None
        return LanesDerivative(built.entry, LANE_WIDTH, lanes_work(f), built.vector_math)

    return model.cached(("driver-lanes", None if inputs is None else inputs.key), build)
