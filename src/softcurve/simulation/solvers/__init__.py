"""The integration methods behind :func:`softcurve.simulate` and the batches.

One problem (:class:`Problem`: the model's state derivative with an actuator's force and
lag, state scales, the domain), one solver interface (:class:`Solver`, :data:`METHODS`),
the route chosen in one function (:func:`choose_route`, :data:`ROUTES`), the method policy
(Adams or BDF, the settled switch, restarts, failure advice), CasADi's CVODES, SciPy's
RK45 and Radau, and softcurve's driver in C (``c/``) of CVODES and of its own Radau IIA.
"""

from softcurve.simulation.solvers._actuated import actuated_derivative as actuated_derivative
from softcurve.simulation.solvers._actuated import actuated_jacobian as actuated_jacobian
from softcurve.simulation.solvers._actuated import (
    actuated_passes as actuated_passes,
)
from softcurve.simulation.solvers._adjoint import ADAMS_ATOL as ADAMS_ATOL
from softcurve.simulation.solvers._adjoint import ADAMS_DECAYED as ADAMS_DECAYED
from softcurve.simulation.solvers._adjoint import ADAMS_DECAYED_FLOOR as ADAMS_DECAYED_FLOOR
from softcurve.simulation.solvers._adjoint import ADAMS_STATISTICS as ADAMS_STATISTICS
from softcurve.simulation.solvers._adjoint import ADJOINT_STATISTICS as ADJOINT_STATISTICS
from softcurve.simulation.solvers._adjoint import Taped as Taped
from softcurve.simulation.solvers._adjoint import adams_backward as adams_backward
from softcurve.simulation.solvers._adjoint import adams_forward as adams_forward
from softcurve.simulation.solvers._adjoint import adjoint_backward as adjoint_backward
from softcurve.simulation.solvers._adjoint import adjoint_forward as adjoint_forward
from softcurve.simulation.solvers._adjoint import vjp_function as vjp_function
from softcurve.simulation.solvers._along import blocks as blocks
from softcurve.simulation.solvers._along import chunks as chunks
from softcurve.simulation.solvers._along import energy_along as energy_along
from softcurve.simulation.solvers._along import mapped as mapped
from softcurve.simulation.solvers._along import rhs_along as rhs_along
from softcurve.simulation.solvers._along import tip_along as tip_along
from softcurve.simulation.solvers._cvodes import ActuatorInput as ActuatorInput
from softcurve.simulation.solvers._cvodes import BufferedCall as BufferedCall
from softcurve.simulation.solvers._cvodes import CvodesEngine as CvodesEngine
from softcurve.simulation.solvers._cvodes import cvodes_integrator as cvodes_integrator
from softcurve.simulation.solvers._driver import FAMILIES as DRIVER_FAMILIES
from softcurve.simulation.solvers._driver import FLAGS as DRIVER_FLAGS
from softcurve.simulation.solvers._driver import DriverProblem as DriverProblem
from softcurve.simulation.solvers._driver import casadi_only as casadi_only
from softcurve.simulation.solvers._driver import driver as driver
from softcurve.simulation.solvers._driver import entry as driver_entry
from softcurve.simulation.solvers._driver import force_jacobian as force_jacobian
from softcurve.simulation.solvers._driver import integrate as driver_integrate
from softcurve.simulation.solvers._driver import library as driver_library
from softcurve.simulation.solvers._driver import newton_jacobian as driver_newton_jacobian
from softcurve.simulation.solvers._driver import options as driver_options
from softcurve.simulation.solvers._driver import problem as driver_problem
from softcurve.simulation.solvers._driver import reason as driver_reason
from softcurve.simulation.solvers._driver import unavailable as driver_unavailable
from softcurve.simulation.solvers._grid import Domain as Domain
from softcurve.simulation.solvers._grid import State as State
from softcurve.simulation.solvers._grid import Stopped as Stopped
from softcurve.simulation.solvers._grid import actuator_exit as actuator_exit
from softcurve.simulation.solvers._grid import change_interval as change_interval
from softcurve.simulation.solvers._grid import domain_reason as domain_reason
from softcurve.simulation.solvers._grid import grid_inputs as grid_inputs
from softcurve.simulation.solvers._grid import input_changes as input_changes
from softcurve.simulation.solvers._grid import outside_domain as outside_domain
from softcurve.simulation.solvers._grid import run_on_grid as run_on_grid
from softcurve.simulation.solvers._grid import run_sampled as run_sampled
from softcurve.simulation.solvers._policy import AUTO_INTERVAL as AUTO_INTERVAL
from softcurve.simulation.solvers._policy import MAX_ORDER as MAX_ORDER
from softcurve.simulation.solvers._policy import RESTART_INTERVAL as RESTART_INTERVAL
from softcurve.simulation.solvers._policy import SETTLED_RATIO as SETTLED_RATIO
from softcurve.simulation.solvers._policy import STIFFNESS_RATIO as STIFFNESS_RATIO
from softcurve.simulation.solvers._policy import auto_method as auto_method
from softcurve.simulation.solvers._policy import cvodes_options as cvodes_options
from softcurve.simulation.solvers._policy import cvodes_reason as cvodes_reason
from softcurve.simulation.solvers._policy import difference_eigenvalues as difference_eigenvalues
from softcurve.simulation.solvers._policy import difference_points as difference_points
from softcurve.simulation.solvers._policy import failure_message as failure_message
from softcurve.simulation.solvers._policy import failure_status as failure_status
from softcurve.simulation.solvers._policy import lag_scale as lag_scale
from softcurve.simulation.solvers._policy import linear_rates as linear_rates
from softcurve.simulation.solvers._policy import linearization_rates as linearization_rates
from softcurve.simulation.solvers._policy import method_name as method_name
from softcurve.simulation.solvers._policy import multistep_family as multistep_family
from softcurve.simulation.solvers._policy import nominal_scale as nominal_scale
from softcurve.simulation.solvers._policy import restart_segments as restart_segments
from softcurve.simulation.solvers._policy import settled as settled
from softcurve.simulation.solvers._policy import state_scale as state_scale
from softcurve.simulation.solvers._policy import success_message as success_message
from softcurve.simulation.solvers._problem import METHODS as METHODS
from softcurve.simulation.solvers._problem import Problem as Problem
from softcurve.simulation.solvers._problem import Solver as Solver
from softcurve.simulation.solvers._problem import initial_state as initial_state
from softcurve.simulation.solvers._problem import solver as solver
from softcurve.simulation.solvers._radau import RadauEngine as RadauEngine
from softcurve.simulation.solvers._radau import RadauTableau as RadauTableau
from softcurve.simulation.solvers._radau import radau_constants as radau_constants
from softcurve.simulation.solvers._radau import radau_tableau as radau_tableau
from softcurve.simulation.solvers._rk45 import ScipyEngine as ScipyEngine
from softcurve.simulation.solvers._rk45 import ScipyRadauEngine as ScipyRadauEngine
from softcurve.simulation.solvers._routes import COMPILED_ACTUATORS as COMPILED_ACTUATORS
from softcurve.simulation.solvers._routes import ROUTES as ROUTES
from softcurve.simulation.solvers._routes import Route as Route
from softcurve.simulation.solvers._routes import RouteWarning as RouteWarning
from softcurve.simulation.solvers._routes import batch_route as batch_route
from softcurve.simulation.solvers._routes import choose_route as choose_route

__all__ = [
    "actuated_derivative",
    "actuated_jacobian",
    "actuated_passes",
    "ADAMS_ATOL",
    "ADAMS_DECAYED",
    "ADAMS_DECAYED_FLOOR",
    "ADAMS_STATISTICS",
    "ADJOINT_STATISTICS",
    "Taped",
    "adams_backward",
    "adams_forward",
    "adjoint_backward",
    "adjoint_forward",
    "vjp_function",
    "blocks",
    "chunks",
    "energy_along",
    "mapped",
    "rhs_along",
    "tip_along",
    "ActuatorInput",
    "BufferedCall",
    "CvodesEngine",
    "cvodes_integrator",
    "DriverProblem",
    "casadi_only",
    "driver",
    "driver_entry",
    "force_jacobian",
    "driver_integrate",
    "driver_problem",
    "driver_newton_jacobian",
    "driver_reason",
    "driver_unavailable",
    "Domain",
    "State",
    "Stopped",
    "actuator_exit",
    "domain_reason",
    "input_changes",
    "change_interval",
    "outside_domain",
    "run_on_grid",
    "run_sampled",
    "AUTO_INTERVAL",
    "MAX_ORDER",
    "SETTLED_RATIO",
    "auto_method",
    "cvodes_options",
    "cvodes_reason",
    "difference_eigenvalues",
    "difference_points",
    "failure_message",
    "failure_status",
    "linear_rates",
    "linearization_rates",
    "method_name",
    "multistep_family",
    "lag_scale",
    "nominal_scale",
    "state_scale",
    "restart_segments",
    "settled",
    "success_message",
    "METHODS",
    "Problem",
    "Solver",
    "solver",
    "RadauEngine",
    "RadauTableau",
    "radau_constants",
    "radau_tableau",
    "ScipyEngine",
    "ScipyRadauEngine",
    "COMPILED_ACTUATORS",
    "ROUTES",
    "Route",
    "RouteWarning",
    "batch_route",
    "choose_route",
    "DRIVER_FAMILIES",
    "DRIVER_FLAGS",
    "driver_options",
    "driver_library",
    "initial_state",
    "RESTART_INTERVAL",
    "STIFFNESS_RATIO",
]
