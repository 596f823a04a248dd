"""What a fit estimates: free parameters, extra parameters and binding rules.

A free parameter is an entry of the robot's parameter vector, looked up in its
:class:`~softcurve.description.layout.ParameterLayout` (``robot.layout``), or a *named
extra* parameter of an output map, an input map, the initial state or a ``bind`` rule
that writes robot parameters as expressions of extra ones (e.g. the well-posed
re-parametrization of a tanh law, :func:`tanh_parameters`).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from softcurve.base.validation import ParameterError
from softcurve.compiled import Model
from softcurve.description.robot import Robot


@dataclass(frozen=True)
class Free:
    """A parameter to estimate.

    Parameters
    ----------
    name : str or tuple of str
        A robot parameter (``"segments[0].damping[1,1]"``) or a named extra parameter;
        a tuple ties several robot parameters to one value (e.g. both bending dampings).
    lower, upper : float
        Bounds [unit of the parameter] (default: none).
    initial : float, optional
        Starting value [unit of the parameter] (default: the current value).
    scale : float, optional
        Typical magnitude, for conditioning [unit of the parameter] (default:
        ``|initial|``, or 1 if zero).
    per_experiment : bool
        In a fit of several experiments, one value per experiment (reported as
        ``name[experiment]``) instead of one shared by all: sensor offsets, initial
        states (``"x0.lam[1]"``, ``softcurve.identification.fits._initial``), initial
        actuator states. Only extra parameters and initial-state entries can be per
        experiment (the robot is one).
    """

    name: str | tuple[str, ...]
    lower: float = -np.inf
    upper: float = np.inf
    initial: float | None = None
    scale: float | None = None
    per_experiment: bool = False

    @property
    def label(self) -> str:
        return self.name if isinstance(self.name, str) else "=".join(self.name)

    @property
    def targets(self) -> tuple[str, ...]:
        return (self.name,) if isinstance(self.name, str) else tuple(self.name)


def tanh_parameters(robot: Robot, law: str):
    """A well-posed re-parametrization of a tanh stiffness law for fitting.

    ``k(0) = a1 - a2`` and ``k(inf) = a1`` are positive for every admissible law, so
    box bounds ``> 0`` on them keep the law well posed (``a1 > 0, a1 > a2``) throughout.

    Parameters
    ----------
    robot : Robot
        The robot whose law is re-parametrized (its current values are returned).
    law : str
        Prefix of the law, e.g. ``"segments[0].bending_stiffness"`` (must be a tanh law).

    Returns
    -------
    values : dict
        Extra parameters ``law + ".k_zero"``, ``law + ".k_inf"``, ``law + ".rate"`` (= a3).
    bind : dict
        Rules writing ``a1, a2, a3`` from them, for the fits' ``bind`` argument.
    """
    layout, p = robot.layout, robot.parameter_vector()
    if f"{law}.a2" not in layout:
        raise ParameterError(f"{law!r} is not a tanh stiffness law of this robot")
    a1, a2, a3 = (float(p[layout.index(f"{law}.{k}")]) for k in ("a1", "a2", "a3"))
    zero, inf, rate = f"{law}.k_zero", f"{law}.k_inf", f"{law}.rate"
    values = {zero: a1 - a2, inf: a1, rate: a3}
    bind = {
        f"{law}.a1": lambda v: v[inf],
        f"{law}.a2": lambda v: v[inf] - v[zero],
        f"{law}.a3": lambda v: v[rate],
    }
    return values, bind


class FreeParameters:
    """Maps the free vector ``theta`` to the robot vector ``p`` and the extra values.

    Robot parameters are looked up in the robot's
    :class:`~softcurve.description.layout.ParameterLayout`.

    Parameters
    ----------
    model : Model
        The compiled model; its robot's layout names the robot parameters.
    free : sequence of Free or str
        What is estimated.
    extra : dict
        Named extra parameters and their values.
    bind : dict
        Robot parameter name -> ``rule(values)``.
    p : array_like, shape (P,), optional
        Robot parameter vector to start from (default ``model.parameters``).
    """

    def __init__(self, model: Model, free, extra: dict, bind: dict, p=None):
        self.layout = layout = model.robot.layout
        self.p0 = model.parameters if p is None else np.asarray(p, dtype=np.float64)
        self.extra = {str(k): float(v) for k, v in extra.items()}
        self.bind = dict(bind)
        self.free = [f if isinstance(f, Free) else Free(f) for f in free]
        for name in self.bind:
            if name not in layout:
                raise ParameterError(f"bind: {name!r} is not a robot parameter")
        seen = set()
        for f in self.free:
            for t in f.targets:
                if t in seen:
                    raise ParameterError(f"free: {t!r} is listed twice")
                seen.add(t)
                if t in self.bind:
                    raise ParameterError(f"free: {t!r} is bound by a rule; free its arguments")
                if t not in layout and t not in self.extra:
                    raise ParameterError(
                        f"free: {t!r} is neither a robot parameter (robot.parameter_names()) "
                        f"nor an extra parameter ({sorted(self.extra)})"
                    )
            if len(f.targets) > 1 and any(t in self.extra for t in f.targets):
                raise ParameterError(f"free: only robot parameters can be tied, got {f.name}")
            if f.per_experiment and any(t not in self.extra for t in f.targets):
                raise ParameterError(
                    f"free {f.label!r}: per_experiment=True needs an extra parameter or an "
                    "initial-state entry (x0.q[i], x0.qd[i], x0.lam[i], x0.u[i]); the robot's "
                    "parameters are shared by all experiments"
                )
            if not f.lower < f.upper:
                raise ParameterError(f"free {f.label!r}: lower must be < upper")
        self.theta0 = np.array(
            [self._current(f.targets[0]) if f.initial is None else f.initial for f in self.free]
        )
        bad = [
            f.label
            for f, v in zip(self.free, self.theta0, strict=True)
            if not f.lower <= v <= f.upper
        ]
        if bad:
            raise ParameterError(f"free: initial values outside their bounds: {bad}")
        given = [f.scale for f in self.free]
        self.scale = np.array(
            [
                s if s is not None else (abs(v) if v != 0 else 1.0)
                for s, v in zip(given, self.theta0, strict=True)
            ]
        )
        self.lower = np.array([f.lower for f in self.free]) / self.scale
        self.upper = np.array([f.upper for f in self.free]) / self.scale
        self.names = tuple(f.label for f in self.free)
        # a robot parameter's unit from the layout; an extra parameter's is the user's
        self.units = tuple(
            layout.unit(f.targets[0]) if f.targets[0] in layout else "" for f in self.free
        )

    def _current(self, name: str) -> float:
        if name in self.extra:
            return self.extra[name]
        return float(self.p0[self.layout.index(name)])

    def expressions(self, theta):
        """``(p, values)`` as CasADi expressions of ``theta`` (MX).

        Parameters
        ----------
        theta : casadi.MX, shape (k,)
            The free parameters, in the units of each.
        """
        values = dict(self.extra)
        entries = [ca.MX(v) for v in self.p0]
        for i, f in enumerate(self.free):
            for t in f.targets:
                if t in self.extra:
                    values[t] = theta[i]
                else:
                    entries[self.layout.index(t)] = theta[i]
        for name, rule in self.bind.items():
            entries[self.layout.index(name)] = rule(values)
        return ca.vertcat(*entries), values

    def evaluate(self, theta_value):
        """Numeric ``(p, values)`` at a numeric ``theta``.

        Parameters
        ----------
        theta_value : array_like, shape (k,)
            The free parameters, in the units of each.
        """
        theta = ca.MX.sym("theta", len(self.free))
        p, values = self.expressions(theta)
        keys = sorted(values)
        f = ca.Function("values", [theta], [p, *(ca.MX(values[k]) for k in keys)])
        out = f(np.asarray(theta_value, dtype=np.float64))
        out = out if isinstance(out, tuple | list) else [out]
        return np.array(out[0]).ravel(), {k: float(v) for k, v in zip(keys, out[1:], strict=True)}
