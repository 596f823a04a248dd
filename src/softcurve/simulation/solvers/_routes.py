"""Which route integrates a problem: the one choice of :func:`choose_route`, the table of
route names :data:`ROUTES` (``docs/architecture.md`` lists it too) and the one warning
:class:`RouteWarning` where a fast route should build and does not.

A route is an algorithm (CVODES, RK45, the stepper's fixed-step schemes) on one
execution path (softcurve's C driver, CasADi's integrator, SciPy, generated lane code).
Every result records the route that ran in ``stats["route"]`` (a batch also per member,
``stats["routes"]``); a progress bar never changes it.
"""

from __future__ import annotations

import threading
import warnings
from dataclasses import dataclass, field

from softcurve.compiled import LANE_WIDTH
from softcurve.simulation.solvers import _driver as c_driver
from softcurve.simulation.solvers._driver import SWITCHED_OFF

ROUTES = {
    "driver": "CVODES in softcurve's C driver, one member per system, the whole output "
    "grid in one call (restarts and the switch to BDF inside it)",
    "driver-lanes": f"CVODES in the C driver, a batch's members in groups of {LANE_WIDTH} "
    "as one system on the state derivative over vector lanes",
    "casadi-cvodes": "CVODES inside CasADi's integrator on the scaled DAE (a batch: one "
    "integrator mapped over the members)",
    "driver-radau": "Radau IIA of order 5 in softcurve's C driver, one member per system, "
    "the whole output grid in one call",
    "scipy-radau": "SciPy's Radau IIA of order 5 stepped from Python (method='radau' "
    "where the C driver cannot run)",
    "rk45": "SciPy's explicit Runge-Kutta 4(5) stepped from Python",
    "sensitivity-driver": "the C driver's forward sensitivities (staggered corrector), on "
    "one thread",
    "sensitivity-driver-split": "the C driver's forward sensitivities, the columns' "
    "right-hand side in two parts on two threads",
    "sensitivity-casadi": "CasADi's CVODES on the augmented system (state and columns)",
    "stepper-lanes": f"the stepper's whole period generated as C over lanes of {LANE_WIDTH} "
    "members, shares of members on threads",
    "stepper-threads": "the stepper's compiled period called per member through ctypes, "
    "shares of members on threads",
    "stepper-casadi": "the stepper's period in CasADi, mapped over the members",
    "mixed": 'a batch whose members took different routes (each member\'s in stats["routes"])',
}
"""Every route name a result can carry in ``stats["route"]``, with what runs."""

COMPILED_ACTUATORS = 8
"""Largest number of distinct actuators (parameter vectors) in a batch integrated by the C
driver: each needs its ``H(q) u`` compiled once (about 0.3 s, then cached on disk); a
batch with more uses CasADi's integrator, which needs no compilation."""


class RouteWarning(UserWarning):
    """A fast route that should have built did not (issued once per process and reason):
    the run goes on, slower, on the route its ``stats["route"]`` names."""


@dataclass(frozen=True)
class Route:
    """A route chosen by :func:`choose_route`.

    Parameters
    ----------
    name : str
        A key of :data:`ROUTES`.
    reason : str
        Why this route, in a phrase.
    built : object, optional
        What the route runs on, where choosing it built it: the driver's problem
        (:func:`softcurve.simulation.solvers.driver_problem`) or a stepper's compiled
        members; None otherwise.
    """

    name: str
    reason: str
    built: object = field(default=None, compare=False, repr=False)

    def __post_init__(self):
        if self.name not in ROUTES:
            raise ValueError(f"unknown route {self.name!r}: not in ROUTES")


_WARNED: set = set()
_WARNED_LOCK = threading.Lock()
_ASKED = (c_driver.CASADI_ONLY, SWITCHED_OFF)  # the user chose these: no warning


def warn_once(reason: str, route: str) -> None:
    """A :class:`RouteWarning` naming ``reason`` and the ``route`` taken instead, once per
    process and reason.

    Parameters
    ----------
    reason : str
        Why the fast route did not build.
    route : str
        The route taken instead (a key of :data:`ROUTES`).
    """
    with _WARNED_LOCK:
        if reason in _WARNED:
            return
        _WARNED.add(reason)
    warnings.warn(
        f"softcurve's fast route is unavailable: {reason}; integrating on {route!r} "
        "(slower; docs/architecture.md, the table of routes)",
        RouteWarning,
        stacklevel=3,
    )


def _driver_missing(model) -> tuple[str | None, bool]:
    """``(why the C driver cannot integrate model, whether the user asked for that)``;
    ``(None, False)`` where it can."""
    why = c_driver.unavailable()
    if why is not None:
        return why, why in _ASKED
    if model.compiled_library is None:
        return "the model is not compiled (compile=False, or no C compiler)", True
    return None, False


def choose_route(task: str, method: str = "cvodes", *, model=None, inputs=None, members=1,
                 lanes=False, actuators=1, options_known=True, threads=1,
                 builders=None, jacobian="differences") -> Route:  # fmt: skip
    """The route of one integration, with the reason, warning once (:class:`RouteWarning`)
    where a fast route should build and does not.

    The rules, in order: ``method="rk45"`` runs SciPy's RK45; ``method="radau"`` runs the
    C driver's Radau IIA where the driver runs (as below), one member per system, else
    SciPy's for ``simulate`` and CasADi's CVODES (the batch then takes BDF) for a batch;
    CVODES runs in the C driver
    where it loads, the model is compiled and the actuator's force compiles (and a batch
    has at most :data:`COMPILED_ACTUATORS` actuators), in groups over lanes where a batch
    of ``lanes`` fills one and the lane code builds; else in CasADi's integrator. The
    sensitivities take the driver where it loads and knows every option, split over two
    threads with ``threads >= 2``. The stepper takes its lane code, else its compiled
    period per member, else CasADi.

    Parameters
    ----------
    task : {"simulate", "batch", "sensitivity", "stepper"}
        What integrates.
    method : str
        The settings' method ("cvodes", "adams", "bdf", "radau" or "rk45").
    model : Model, optional
        The compiled model (simulate, batch).
    inputs : ActuatorInput, optional
        The actuator's input (None: forces).
    members : int
        Members integrated together (a batch's members of one actuator).
    lanes : bool
        Whether a batch may group members over lanes.
    actuators : int
        Distinct actuators of a batch.
    options_known : bool
        Whether the driver understands every CVODES option given (sensitivities).
    threads : int
        Threads of one evaluation (sensitivities).
    builders : dict, optional
        ``route name -> build()`` returning what the route runs on, or None where it does
        not build: the sensitivities' compiled columns (``"sensitivity-driver"``), the
        stepper's lane code and per-member period (``"stepper-lanes"``,
        ``"stepper-threads"``).
    jacobian : {"differences", "exact"}
        The Jacobian of the driver's Newton matrix (``SimulationSettings.jacobian``) or of
        the stepper's (``Stepper(jacobian=)``, per member); the driver's lanes and the
        other routes take their own.

    Returns
    -------
    Route
        The route, its reason and what it runs on.
    """
    builders = builders or {}
    if task == "stepper":
        exact = ", the model's exact Jacobian" if jacobian == "exact" else ""
        for name in ("stepper-lanes", "stepper-threads"):
            built = builders[name]() if name in builders else None
            if built is not None:
                return Route(name, "compiled code over the members" + exact, built)
        return Route("stepper-casadi", "the model is not compiled, or compiled=False" + exact)
    if task == "sensitivity":
        why = c_driver.unavailable() or (None if options_known else "a CVODES option only "
                                       "CasADi's integrator knows")  # fmt: skip
        built = None if why else builders["sensitivity-driver"]()
        if built is None:
            why = why or "the sensitivity functions did not compile"
            if why not in _ASKED and options_known:
                warn_once(why, "sensitivity-casadi")
            return Route("sensitivity-casadi", why)
        name = "sensitivity-driver-split" if threads > 1 else "sensitivity-driver"
        return Route(name, f"the C driver on {min(threads, 2)} thread(s)", built)
    if method == "rk45":
        return Route("rk45", "method='rk45' was asked")
    radau = method == "radau"
    why, asked = _driver_missing(model)
    if why is None and actuators > COMPILED_ACTUATORS:
        why, asked = f"{actuators} actuators, more than {COMPILED_ACTUATORS} to compile", True
    grouped = task == "batch" and lanes and members >= LANE_WIDTH and not radau
    problem = None if why else c_driver.problem(model, inputs, grouped, jacobian == "exact")
    if why is None and problem is None:
        why, asked = "the actuator's force H(q) u did not compile", False
    if why is not None:
        # SciPy's Radau steps one member; a batch takes CasADi's integrator, with BDF
        instead = "scipy-radau" if radau and task == "simulate" else "casadi-cvodes"
        if not asked:
            warn_once(why, instead)
        return Route(instead, why)
    if problem.width > 1:
        return Route("driver-lanes", f"{members} members in groups of {problem.width}", problem)
    if grouped:
        warn_once("the state derivative over lanes did not compile", "driver")
        return Route("driver", "the lane code did not build", problem)
    reason = "lanes=False" if task == "batch" and not lanes else "one member per system"
    if radau:
        reason = "method='radau' was asked, one member per system"
    name = "driver-radau" if radau else "driver"
    if jacobian == "exact":
        if problem.exact:
            reason += ", the model's exact Jacobian"
        else:
            warn_once("the exact Jacobian did not compile", name)
            reason += ", forward-difference Jacobians (the exact one did not compile)"
    return Route(name, reason, problem)


def batch_route(names) -> str:
    """The route of a batch whose members took the routes ``names``: theirs where they
    agree, else ``"mixed"``.

    Parameters
    ----------
    names : sequence of str
        Each member's route.
    """
    distinct = set(names)
    return distinct.pop() if len(distinct) == 1 else "mixed"
