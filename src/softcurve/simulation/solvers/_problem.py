"""One description of an integration (:class:`Problem`) and the one interface of its
solvers (:class:`Solver`), with the table :data:`METHODS` of the solver behind each route
of one member (like SciPy's ``solve_ivp`` ``METHODS``).

A problem is the model's right-hand side with its parameters, the actuator's input (its
force ``H(q) u`` and lag), the state scale, the tolerances and step budget, and the output
grid with the model's domain; a solver answers the one question of
:mod:`softcurve.simulation.solvers._cvodes` on it (``advance``), and the route's
:class:`~softcurve.simulation.solvers._routes.Route` says which solver runs. A batch
(:func:`~softcurve.simulation.simulate_batch`) is one problem whose state scales and
parameters are per member; a single member is the batch of one.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Protocol

import numpy as np

from softcurve.base.validation import real_array
from softcurve.simulation.solvers import _policy
from softcurve.simulation.solvers._cvodes import ActuatorInput, CvodesEngine
from softcurve.simulation.solvers._driver import options as driver_options
from softcurve.simulation.solvers._policy import MAX_ORDER, cvodes_options
from softcurve.simulation.solvers._radau import RadauEngine, radau_constants
from softcurve.simulation.solvers._rk45 import ScipyEngine, ScipyRadauEngine
from softcurve.symbolic.gaps import check_start


def initial_state(model, q0, qd0, lam0=None) -> np.ndarray:
    """``(q0, qd0, lam0)`` checked and stacked into the state ``x0`` (n_state,); ``lam0``
    None is zero.

    Parameters
    ----------
    model : Model
        The compiled model.
    q0 : array_like, shape (n,)
        Coordinates [m, 1/m, 1/m], in the model's domain
        (:meth:`~softcurve.Robot.check_configuration`).
    qd0 : array_like, shape (n,)
        Rates [m/s, 1/(m s), 1/(m s)].
    lam0 : array_like, shape (n_creep,), optional
        Creep states (default zero).
    """
    n = model.n
    q0 = model.robot.check_configuration(real_array("q0", q0, (n,)), "q0")
    if model.environment is not None:
        check_start(model.environment, model.robot, q0)  # not inside an obstacle
    x0 = np.zeros(model.n_state)
    x0[:n] = q0
    x0[n : 2 * n] = real_array("qd0", qd0, (n,))
    if lam0 is not None:
        x0[2 * n :] = real_array("lam0", lam0, (model.n_creep,))
    return x0


@dataclass(frozen=True, eq=False)
class Problem:
    """What one integration is, whatever integrates it: one member, or the members of a
    batch (one robot structure; per-member state scales and parameters).

    Parameters
    ----------
    model : Model
        The compiled model: the right-hand side and its default parameter vector.
    inputs : ActuatorInput or None
        The actuator's input (force ``H(q) u``, bounds, lag), or None for forces.
    nominal : ndarray, shape (N,) or (B, N)
        State scale (> 0), :func:`~softcurve.simulation.solvers.state_scale`; per member
        in a batch of ``B``.
    atol : ndarray, shape (k,), k <= N, or None
        Absolute tolerance of the first ``k`` states, in the states' units. The states
        after them (all of them with None) are held relative, ``rtol * nominal``: their
        scaled state's tolerance is ``rtol`` itself. RK45 takes it per state (k = N).
    rtol : float
        Relative tolerance.
    max_steps : int
        Internal steps allowed between two output times.
    grid : ndarray, shape (T,)
        Output times [s].
    parameters : ndarray, shape (n_p,) or (B, n_p), optional
        Parameter vector (per member in a batch), in the order of
        ``model.robot.layout.names``; default the model's.
    """

    model: object
    inputs: ActuatorInput | None
    nominal: np.ndarray
    atol: np.ndarray | None
    rtol: float
    max_steps: int
    grid: np.ndarray
    parameters: np.ndarray | None = None

    @property
    def members(self) -> int:
        """How many members the problem integrates, ``B`` (1 for one robot)."""
        return 1 if np.ndim(self.nominal) == 1 else len(self.nominal)

    @cached_property
    def member_nominal(self) -> np.ndarray:
        """The state scale of every member, shape (B, N)."""
        return np.atleast_2d(self.nominal)

    @cached_property
    def member_parameters(self) -> np.ndarray:
        """The parameter vector of every member, shape (B, n_p)."""
        vector = self.model.parameters if self.parameters is None else self.parameters
        return np.broadcast_to(vector, (self.members, np.shape(vector)[-1]))

    @property
    def scaled_atol(self) -> float:
        """The one absolute tolerance of the scaled state ``x / nominal`` that CVODES takes:
        the tightest ``atol / nominal`` over the states and members, so every state meets
        its own tolerance (``rtol`` for the states held relative, :attr:`atol`)."""
        if self.atol is None:
            return float(self.rtol)
        tightest = float((self.atol / self.member_nominal[:, : self.atol.size]).min())
        held_relative = self.atol.size < self.member_nominal.shape[1]
        return min(tightest, self.rtol) if held_relative else tightest

    def cvodes_options(self, multistep: str) -> dict:
        """CasADi's CVODES options of this problem
        (:func:`~softcurve.simulation.solvers.cvodes_options`, order cap
        :data:`~softcurve.simulation.solvers.MAX_ORDER`).

        Parameters
        ----------
        multistep : {"adams", "bdf"}
            The family.
        """
        return cvodes_options(multistep, self.rtol, self.scaled_atol, self.max_steps)

    def driver_options(self, family: int = 1, max_order: int = MAX_ORDER, settled_ratio=None):
        """The C driver's settings (the header's ``sc_options``) of this problem: by
        default those of CasADi's route (:meth:`cvodes_options`), the same order cap, the
        settled switch, and Radau IIA's constants
        (:func:`~softcurve.simulation.solvers.radau_constants`) for members of that family.

        Parameters
        ----------
        family : int
            1 Adams, 2 BDF.
        max_order : int
            The method's largest order (default
            :data:`~softcurve.simulation.solvers.MAX_ORDER`; 0: CVODES's own).
        settled_ratio : float, optional
            The settled switch's ratio (dimensionless; default
            :data:`~softcurve.simulation.solvers.SETTLED_RATIO`; 0: no switch).
        """
        ratio = _policy.SETTLED_RATIO if settled_ratio is None else settled_ratio
        return driver_options(
            self.rtol, self.scaled_atol, self.max_steps, family=family, max_order=max_order,
            settled_ratio=ratio, radau=radau_constants(),
        )  # fmt: skip


class Solver(Protocol):
    """What every solver of one member implements once (:data:`METHODS`)."""

    name: str
    """The algorithm's family: "cvodes", "radau" or "rk45"."""
    route: str
    """The route it runs (a key of ``ROUTES`` of :mod:`softcurve.simulation.solvers`)."""
    counts: dict
    """Counters of the work done (steps, right-hand sides, ...)."""

    @property
    def method(self) -> str:
        """The integrator as results name it, e.g. "cvodes-adams+bdf"."""

    def advance(self, x, h, tout, taus) -> np.ndarray:
        """States (len(tout), N) at ``t0 + h * tout`` from ``x`` at ``t0``, with
        ``taus[k]`` applied on ``(tout[k-1], tout[k]]``."""


METHODS = {
    "driver": CvodesEngine,
    "casadi-cvodes": CvodesEngine,
    "driver-radau": RadauEngine,
    "scipy-radau": ScipyRadauEngine,
    "rk45": ScipyEngine,
}
"""The solver class behind each route of one member."""


def solver(route, problem: Problem, multistep: str = "adams") -> Solver:
    """The solver of ``route`` on ``problem`` (:data:`METHODS`).

    Parameters
    ----------
    route : Route
        The route (:func:`~softcurve.simulation.solvers.choose_route`); its ``built`` (the
        driver's problem on "driver" and "driver-radau", else None) goes to the solver.
    problem : Problem
        The integration.
    multistep : {"adams", "bdf"}
        CVODES's family at the start (unused by Radau IIA and RK45).
    """
    return METHODS[route.name](problem, multistep, route.built)
