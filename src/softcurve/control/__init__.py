"""Control: feedback controllers (``controllers``), the linear MPC (``mpc``), references
(``references``), and planning over the robot's transcription: :class:`Transcription`
(the dynamics, one step, the gaps and the domain as CasADi Functions) and
:func:`optimize_trajectory` (IPOPT over it, its result :class:`TrajectoryPlan`)."""

from softcurve.control._planning import PLAN_METHODS as PLAN_METHODS
from softcurve.control._planning import ConfigurationTarget as ConfigurationTarget
from softcurve.control._planning import TipTarget as TipTarget
from softcurve.control._planning import TrajectoryPlan as TrajectoryPlan
from softcurve.control._planning import optimize_trajectory as optimize_trajectory
from softcurve.control._transcription import Transcription as Transcription

__all__ = [
    "PLAN_METHODS",
    "ConfigurationTarget",
    "TipTarget",
    "TrajectoryPlan",
    "Transcription",
    "optimize_trajectory",
]
