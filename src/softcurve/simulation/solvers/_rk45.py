"""SciPy's RK45 and Radau as engines of :func:`~softcurve.simulation.simulate`: the
integrator's question (``softcurve.simulation.solvers._cvodes``) answered by stepping
SciPy's explicit Runge-Kutta 4(5), or its Radau IIA where the C driver's cannot run, from
Python, with the step budget and the domain stop of the C driver."""

from __future__ import annotations

import numpy as np
from scipy.integrate import RK45, Radau

from softcurve.simulation.solvers._cvodes import PiecewiseSolver
from softcurve.simulation.solvers._policy import LEFT_DOMAIN, TOO_MUCH_WORK, IntegrationFailure


class ScipyEngine(PiecewiseSolver):
    """SciPy's explicit Runge-Kutta 4(5) (Dormand-Prince, like MATLAB's ode45), stepped
    from Python over the model's compiled right-hand side.

    Parameters
    ----------
    problem : Problem
        The integration (:class:`~softcurve.simulation.solvers.Problem`).
    multistep, native : None
        Unused: the arguments every solver of ``METHODS`` takes.
    """

    name = "rk45"
    method = "rk45"
    route = "rk45"
    scheme = RK45
    """SciPy's ``OdeSolver`` class stepped."""

    def __init__(self, problem, multistep=None, native=None):
        self.model = problem.model
        self.inputs = problem.inputs
        self.rtol = problem.rtol
        self.atol = problem.atol
        self.max_steps = int(problem.max_steps)
        self.counts = {"steps": 0, "rhs_evaluations": 0, "jacobian_evaluations": 0}

    def _constant(self, x, h, tout, tau) -> np.ndarray:
        out = np.empty((tout.size, x.size))
        if self.inputs is None:
            rhs = self.model.rhs(tau)
        else:
            rhs = lambda t, y: self.inputs.state_derivative(self.model, y, tau)  # noqa: E731
        # SciPy's solvers keep references to earlier derivatives: give them arrays of their own
        self._run(lambda t, y: np.array(rhs(t, y)), x, 0.0, h * tout, out)
        return out

    def _run(self, f, x, t0, times, out) -> np.ndarray:
        """Step the scheme from ``x`` at ``t0`` through ``times``, filling ``out``; at most
        ``max_steps`` steps between two outputs (the step that passes an output counts
        for its interval, as in CVODES's C driver), and a stop at the first output
        outside the model's domain (the C driver's rule): outside it the motion can need
        steps a million times shorter, and the run would go on for hours."""
        solver = self.scheme(f, t0, x, times[-1], rtol=self.rtol, atol=self.atol)
        n, robot = self.model.n, self.model.robot
        i, taken = 0, 0
        while i < times.size and solver.status == "running":
            if taken == self.max_steps:
                self.counts["rhs_evaluations"] += solver.nfev
                raise IntegrationFailure(
                    f"{self.scheme.__name__}: {TOO_MUCH_WORK}: {self.max_steps} steps reached t = "
                    f"{solver.t:.6g} s, short of the output at {times[i]:.6g} s",
                    out[:i].copy(),
                )
            message = solver.step()
            self.counts["steps"] += 1
            taken += 1
            if solver.status == "failed" or not np.all(np.isfinite(solver.y)):
                self.counts["rhs_evaluations"] += solver.nfev
                what = message or "non-finite state"
                reason = f"{self.scheme.__name__}: {what} at t = {solver.t:.6g} s"
                raise IntegrationFailure(reason, out[:i].copy())
            if solver.t >= times[i]:
                dense = solver.dense_output()
                while i < times.size and solver.t >= times[i]:
                    out[i] = solver.y if times[i] == solver.t else dense(times[i])
                    i += 1
                    if not robot.inside(out[i - 1, :n]):
                        self.counts["rhs_evaluations"] += solver.nfev
                        raise IntegrationFailure(LEFT_DOMAIN, out[:i].copy())
                taken = 0
        self.counts["rhs_evaluations"] += solver.nfev
        return out[-1].copy()


class ScipyRadauEngine(ScipyEngine):
    """SciPy's Radau IIA of order 5 stepped from Python (its Jacobian by its own finite
    differences), with the arguments of :class:`ScipyEngine`: the route of
    ``method="radau"`` where the C driver cannot run."""

    name, method, route, scheme = "radau", "radau-scipy", "scipy-radau", Radau
