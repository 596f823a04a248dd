"""The state an experiment starts from: the equilibrium at its first input.

A recording usually starts with the robot at rest under the first measured input.
:func:`initial_equilibrium` solves the static balance ``N(q) = tau(q, u_0)`` there, with
the same input map (and extra parameter values) a fit uses, by the package's one
equilibrium solver (:mod:`softcurve.analysis.solver`), and returns the state
``x0 = (q, 0, 0)`` (at rest, creep relaxed) for :func:`~softcurve.simulate` and for
``fit_trajectory(x0=...)``, with the first inputs as the initial state of a lagging
actuator (``simulate(..., actuator_state=...)``).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from softcurve.analysis.loads import coordinate_scale, residual_reference, rest_configuration
from softcurve.analysis.solver import solve_equilibrium
from softcurve.base.status import Result, Status
from softcurve.base.validation import ParameterError, real_array
from softcurve.compiled import Model
from softcurve.description.actuator import Actuator
from softcurve.figures import plot_configuration
from softcurve.figures.shapes import result_figure_options
from softcurve.identification.experiments import Experiment, check_units
from softcurve.identification.fits._equilibria import EQUILIBRIUM_TOLERANCE, MAX_EVALUATIONS
from softcurve.identification.maps import InputMap, actuator_input_map


@dataclass(frozen=True, eq=False)
class InitialState(Result):
    """The equilibrium at one sample of an experiment, as a starting state.

    Attributes
    ----------
    q : ndarray, shape (n,)
        The equilibrium configuration [m, 1/m, 1/m].
    x0 : ndarray, shape (n_state,)
        The state ``(q, qd = 0, lam = 0)`` for ``simulate`` or ``fit_trajectory``.
    inputs : ndarray, shape (m,)
        The experiment's inputs at that sample, in its units (SI): the initial state of
        a lagging actuator (``simulate(..., actuator_state=...)``).
    residual : ndarray, shape (n,)
        ``N(q) - tau(q, u)`` [N, N m^2, N m^2].
    time : float
        The time of the sample [s].
    status : Status
        SUCCESS when the scaled residual met the tolerance, else NOT_CONVERGED or
        EVALUATION_LIMIT.
    message : str
        What the solver reached.
    """

    q: np.ndarray
    x0: np.ndarray
    inputs: np.ndarray
    residual: np.ndarray
    time: float
    status: Status
    message: str

    @result_figure_options
    def plot(self, ax=None, *, model, measured=None):
        """The backbone of the initial state, from the side (x-z) and from above (x-y),
        its tip marked, and the point measured at that sample where one is given.

        Parameters
        ----------
        ax : None or sequence of matplotlib.axes.Axes, shape (2,)
            Panels for the side and the top view; None draws a new figure.
        %(model)s
        measured : array_like, shape (3,), optional
            A world point measured at the sample (e.g. the tip from a tracker) [m].

        """
        return plot_configuration(
            model,
            self.q,
            ax,
            marks=None if measured is None else {"measured": measured},
            title=f"initial state at t = {self.time:g} s ({self.status.value})",
        )


def initial_equilibrium(
    model: Model,
    experiment: Experiment,
    input_map: InputMap | Actuator | None = None,
    *,
    extra: dict | None = None,
    parameters=None,
    q0=None,
    sample: int = 0,
    tol: float = EQUILIBRIUM_TOLERANCE,
    max_evaluations: int = MAX_EVALUATIONS,
) -> InitialState:
    """The static equilibrium under the experiment's inputs at one sample (the first).

    Parameters
    ----------
    model : Model
        The model (``compile=False`` suffices: only its symbolic forces are used).
    experiment : Experiment
        The recording; all its inputs, in order, feed ``input_map``.
    input_map : InputMap or Actuator, optional
        How the inputs act (an actuator acts through
        :func:`~softcurve.identification.maps.actuator_input_map`); None for
        the robot under gravity alone.
    extra : dict, optional
        Values of the map's extra parameters, overriding their nominal values (e.g. a
        fit's ``report.extra["values"]``).
    parameters : array_like, shape (P,), optional
        Robot parameter vector (default ``model.parameters``; e.g. a fit's
        ``report.extra["parameters"]``).
    q0 : array_like, shape (n,), optional
        Initial guess [m, 1/m, 1/m] (default: straight at rest length).
    sample : int
        Index of the sample (default 0, the first).
    tol : float
        Tolerance on the scaled residual (dimensionless, see
        :mod:`softcurve.analysis.solver`).
    max_evaluations : int
        Budget of residual evaluations.
    """
    if not isinstance(model, Model):
        raise ParameterError(f"model must be a softcurve.Model, got {type(model).__name__}")
    if not isinstance(experiment, Experiment):
        raise ParameterError(f"experiment must be an Experiment, got {type(experiment).__name__}")
    if isinstance(input_map, Actuator):
        input_map = actuator_input_map(input_map)
    if input_map is not None and not isinstance(input_map, InputMap):
        raise ParameterError(
            f"input_map must be an InputMap, an Actuator or None, got {type(input_map).__name__}"
        )
    if not -experiment.t.size <= sample < experiment.t.size:
        raise ParameterError(
            f"sample must be an index in [0, {experiment.t.size - 1}], got {sample!r}"
        )
    check_units(experiment, input_map=input_map)
    p = model.parameters if parameters is None else real_array("parameters", parameters,
                                                               model.parameters.shape)  # fmt: skip
    q0 = rest_configuration(model.robot) if q0 is None else real_array("q0", q0, (model.n,))
    inputs = experiment.input_matrix()[sample]
    values = {**(input_map.parameters if input_map else {}), **(extra or {})}
    q = ca.SX.sym("q", model.n)
    tau = ca.SX.zeros(model.n)
    if input_map is not None:
        tau = input_map.function(q, ca.DM(inputs), {k: ca.SX(float(v)) for k, v in values.items()})
    forces = model.symbolic["gravity_force"](q, p) + model.symbolic["elastic_force"](q, p)
    residual = forces - tau
    balance = ca.Function("balance", [q], [residual, ca.jacobian(residual, q)])

    def system(q_value):
        r, k = balance(q_value)
        return np.array(r, dtype=np.float64).ravel(), np.array(k, dtype=np.float64)

    root = solve_equilibrium(
        system,
        q0,
        scale=coordinate_scale(model.robot),
        reference=residual_reference(model),
        tol=tol,
        max_evaluations=max_evaluations,
    )
    x0 = np.concatenate([root.q, np.zeros(model.n), np.zeros(model.n_creep)])
    return InitialState(
        q=root.q,
        x0=x0,
        inputs=np.array(inputs),
        residual=system(root.q)[0],
        time=float(experiment.t[sample]),
        status=root.status,
        message=f"equilibrium at t = {experiment.t[sample]:g} s: {root.message}",
    )
