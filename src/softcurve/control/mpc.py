"""Model-predictive control with bounded actuator inputs, re-linearized at every sample.

At each sample the loaded dynamics are linearized about the measured state and the
inputs currently applied (:func:`softcurve.analysis.linear.linearize` with
``wrt="actuator"``, exact CasADi derivatives), and discretized exactly for a zero-order
hold of the input changes, affine term included::

    x_(k+1) - x_0 = Ad (x_k - x_0) + Bd (u_k - u_0) + c,   [Ad Bd c] from expm

Over ``horizon`` samples the controller minimizes::

    sum_k |W (q_k - q_r(t + k Ts))|^2 + rate_weight sum_k |(u_k - u_(k-1)) / span|^2

with ``W = diag(1/l0, l0, l0)`` (one meter of length weighs like one radian of bending),
subject to ``lower <= u_k <= upper``. The predictions are linear in the inputs, so
this is a bounded linear least-squares problem, solved exactly by SciPy's BVLS; the
first inputs are returned (run it with ``simulate(..., actuator=...)``). The nonlinear
model enters through the re-linearization at every sample (a linear time-varying MPC);
an input lag is not modeled.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.optimize

from softcurve.analysis.linear import linearize
from softcurve.analysis.loads import coordinate_scale
from softcurve.base.validation import ParameterError, real_scalar
from softcurve.control.controllers import SampledController
from softcurve.control.references import Reference, checked_reference
from softcurve.description.actuator import Actuator


class ActuatorMPC(SampledController):
    """Bounded-input MPC of a reference ``q_r(t)``, re-linearized at every sample.

    Returns the actuator's inputs (m,); logged per sample: ``t``, ``inputs``, ``tau``
    (``H(q) u``), the solver's ``status`` and the ``cost``.

    Parameters
    ----------
    model : Model
        The controller's model.
    actuator : Actuator
        The actuator whose inputs are chosen.
    reference : Reference
        ``q_r(t)`` to track.
    horizon : int
        Samples predicted (>= 1).
    sample_time : float
        Time between two samples [s]; also the prediction step.
    rate_weight : float
        Weight (>= 0) of the input increments, normalized by the input range
        (dimensionless).
    """

    def __init__(
        self,
        model,
        actuator: Actuator,
        reference: Reference,
        *,
        horizon: int = 20,
        sample_time: float = 0.01,
        rate_weight: float = 1e-4,
    ):
        super().__init__(sample_time)
        actuator.check_robot(model.robot)
        reference = checked_reference(reference, model.robot)
        if not (isinstance(horizon, int) and horizon >= 1):
            raise ParameterError(f"horizon must be an integer >= 1, got {horizon!r}")
        self.rate_weight = real_scalar("rate_weight", rate_weight)
        if self.rate_weight < 0:
            raise ParameterError(f"rate_weight must be >= 0, got {rate_weight!r}")
        self.model, self.actuator, self.reference, self.horizon = (
            model,
            actuator,
            reference,
            horizon,
        )
        self.weights = 1.0 / coordinate_scale(model.robot)
        self.reset()

    def reset(self) -> None:
        """Forget the record; the inputs start at rest."""
        super().reset()
        self._applied = self.actuator.rest_inputs()

    def _discretize(self, q, qd, lam):
        """``Ad, Bd, c`` of one sample about the state and the applied inputs."""
        p0 = self._applied
        lin = linearize(self.model, q, qd, lam, actuator=self.actuator, inputs=p0, wrt="actuator")
        x = lin.x
        drift = self.model.state_derivative(x, self.actuator.input_matrix(q) @ p0)
        n_x, m = lin.B.shape
        augmented = np.zeros((n_x + m + 1, n_x + m + 1))
        augmented[:n_x, :n_x], augmented[:n_x, n_x : n_x + m] = lin.A, lin.B
        augmented[:n_x, -1] = drift
        transition = scipy.linalg.expm(augmented * self.sample_time)
        return transition[:n_x, :n_x], transition[:n_x, n_x : n_x + m], transition[:n_x, -1]

    def __call__(self, t, q, qd, lam=None) -> np.ndarray:
        lam = np.zeros(self.model.n_creep) if lam is None else np.asarray(lam, dtype=float)
        ad, bd, c = self._discretize(q, qd, lam)
        n, m, horizon = self.model.n, self.actuator.n_inputs, self.horizon
        p0 = self._applied
        # q_k - q = G_k (P - p0 repeated) + h_k: predictions linear in the inputs
        rows, offsets = [], []
        state_gain = np.zeros((ad.shape[0], horizon * m))
        state_offset = np.zeros(ad.shape[0])
        for k in range(horizon):
            state_gain = ad @ state_gain
            state_gain[:, k * m : (k + 1) * m] += bd
            state_offset = ad @ state_offset + c
            target = self.reference(t + (k + 1) * self.sample_time).q
            rows.append(self.weights[:, None] * state_gain[:n])
            offsets.append(self.weights * (target - q - state_offset[:n]))
        span = self.actuator.upper - self.actuator.lower
        difference = np.eye(horizon * m) - np.eye(horizon * m, k=-m)
        rate = np.sqrt(self.rate_weight) * difference / np.tile(span, horizon)[:, None]
        matrix = np.vstack([*rows, rate])
        repeated = np.tile(p0, horizon)
        # unknown: P - p0 repeated; the first increment is measured from the applied p0
        rhs = np.concatenate([*offsets, np.zeros(horizon * m)])
        lower = np.tile(self.actuator.lower, horizon) - repeated
        upper = np.tile(self.actuator.upper, horizon) - repeated
        scale = np.tile(span, horizon)
        solution = scipy.optimize.lsq_linear(
            matrix * scale, rhs, bounds=(lower / scale, upper / scale), method="bvls"
        )
        inputs = self.actuator.clip(p0 + scale[:m] * solution.x[:m])
        self._applied = inputs
        tau = self.actuator.input_matrix(q) @ inputs
        self.log.append(
            {"t": t, "tau": tau, "inputs": inputs, "status": solution.status,
             "cost": float(2 * solution.cost)}
        )  # fmt: skip
        return inputs.copy()
