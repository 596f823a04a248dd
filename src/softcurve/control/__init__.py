"""Control: feedback controllers (``controllers``), the linear MPC (``mpc``), references
(``references``), and planning over the robot's transcription: :class:`Transcription`
(the dynamics, one step, the gaps and the domain as CasADi Functions),
:func:`optimize_trajectory` (IPOPT over it, its result :class:`TrajectoryPlan`),
:class:`PredictiveController` (the same problem re-solved at every sample) and
:func:`gradient` (the exact gradient of a cost of a simulated trajectory, its result
:class:`RolloutGradient`)."""

from softcurve.control._gradient import ADAMS_TOLERANCE as ADAMS_TOLERANCE
from softcurve.control._gradient import ADAMS_WITHIN as ADAMS_WITHIN
from softcurve.control._gradient import GRADIENT_METHODS as GRADIENT_METHODS
from softcurve.control._gradient import GRADIENT_TOLERANCES as GRADIENT_TOLERANCES
from softcurve.control._gradient import RADAU_TOLERANCE as RADAU_TOLERANCE
from softcurve.control._gradient import WITH_RESPECT_TO as WITH_RESPECT_TO
from softcurve.control._gradient import RolloutGradient as RolloutGradient
from softcurve.control._gradient import RolloutSymbols as RolloutSymbols
from softcurve.control._gradient import gradient as gradient
from softcurve.control._planning import PLAN_HESSIANS as PLAN_HESSIANS
from softcurve.control._planning import PLAN_METHODS as PLAN_METHODS
from softcurve.control._planning import TrajectoryPlan as TrajectoryPlan
from softcurve.control._planning import optimize_trajectory as optimize_trajectory
from softcurve.control._predictive import PREDICTIVE_HESSIANS as PREDICTIVE_HESSIANS
from softcurve.control._predictive import REAL_TIME_OPTIONS as REAL_TIME_OPTIONS
from softcurve.control._predictive import PredictiveController as PredictiveController
from softcurve.control._problem import LBFGS_HISTORY as LBFGS_HISTORY
from softcurve.control._problem import PLAN_ITERATIONS as PLAN_ITERATIONS
from softcurve.control._problem import ConfigurationTarget as ConfigurationTarget
from softcurve.control._problem import TipTarget as TipTarget
from softcurve.control._transcription import STAGE_JACOBIAN_ROUTES as STAGE_JACOBIAN_ROUTES
from softcurve.control._transcription import Transcription as Transcription

__all__ = [
    "GRADIENT_METHODS",
    "ADAMS_TOLERANCE",
    "ADAMS_WITHIN",
    "GRADIENT_TOLERANCES",
    "RADAU_TOLERANCE",
    "LBFGS_HISTORY",
    "PLAN_HESSIANS",
    "PLAN_ITERATIONS",
    "PLAN_METHODS",
    "PREDICTIVE_HESSIANS",
    "PredictiveController",
    "REAL_TIME_OPTIONS",
    "STAGE_JACOBIAN_ROUTES",
    "WITH_RESPECT_TO",
    "ConfigurationTarget",
    "TipTarget",
    "RolloutGradient",
    "RolloutSymbols",
    "TrajectoryPlan",
    "Transcription",
    "gradient",
    "optimize_trajectory",
]
