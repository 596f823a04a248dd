"""The methods of :class:`~softcurve.simulation.stepper.Stepper` by their coefficients:
the Rosenbrock-W methods ROS2 and ROS34PW2 (:class:`Tableau`, L-stable, for any robot)
and the explicit classical Runge-Kutta method RK4 (:class:`ExplicitTableau`, for robots
without stiff modes: no Jacobian, no solve), with the measured default steps of each
kind. docs/stepping.md compares them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Tableau:
    """A Rosenbrock(-W) method in its published form ``(alpha, Gamma, b)`` (Hairer and
    Wanner, Solving ODEs II, IV.7), for ``x' = f(x)``, with ``gamma = Gamma_ii``:

    - stages: ``(I - gamma h J) k_i = f(x + h sum_j alpha_ij k_j) + h J sum_{j<i}
      gamma_ij k_j``;
    - step: ``x_next = x + h sum_i b_i k_i``.

    Parameters
    ----------
    name : str
        Its name.
    order : int
        Its order with any matrix ``J`` (a W-method).
    alpha : tuple of tuple of float
        Strictly lower triangular (s x s).
    gamma : tuple of tuple of float
        Lower triangular with the constant diagonal ``gamma`` (s x s).
    b : tuple of float
        Weights (s,).
    """

    name: str
    order: int
    alpha: tuple
    gamma: tuple
    b: tuple

    def transformed(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """``(a, c, m, gamma)`` of the form without matrix-vector products, in stage
        variables ``v_i`` (Hairer and Wanner's ``u_i / (gamma h)``): stages
        ``(I - gamma h J) v_i = f(x + h sum_j a_ij v_j) + sum_j c_ij v_j``, step
        ``x_next = x + h sum_i m_i v_i``."""
        alpha, big, b = (np.array(v, dtype=np.float64) for v in (self.alpha, self.gamma, self.b))
        gamma = big[0, 0]
        # a = alpha Gamma^-1, c = 1/gamma - Gamma^-1, m = b Gamma^-1 (solves, no inverse)
        a = np.linalg.solve(big.T, alpha.T).T
        inverse_rows = np.linalg.solve(big.T, np.eye(big.shape[0])).T
        c = np.diag(np.full(big.shape[0], 1 / gamma)) - inverse_rows
        m = np.linalg.solve(big.T, b)
        return gamma * np.tril(a, -1), gamma * np.tril(c, -1), gamma * m, gamma


_G2 = 1.0 + 1.0 / math.sqrt(2.0)
ROS2 = Tableau("ROS2", 2, ((0.0, 0.0), (1.0, 0.0)), ((_G2, 0.0), (-2.0 * _G2, _G2)), (0.5, 0.5))
"""Verwer, Spee, Blom and Hundsdorfer (SIAM J. Sci. Comput. 20(4), 1999): two stages,
order 2 with any ``J``, L-stable with ``gamma = 1 + 1/sqrt(2)``."""

_G4 = 0.43586652150845900
ROS34PW2 = Tableau(
    "ROS34PW2",
    3,
    (
        (0.0, 0.0, 0.0, 0.0),
        (8.7173304301691801e-01, 0.0, 0.0, 0.0),
        (8.4457060015369423e-01, -1.1299064236484185e-01, 0.0, 0.0),
        (0.0, 0.0, 1.0, 0.0),
    ),
    (
        (_G4, 0.0, 0.0, 0.0),
        (-8.7173304301691801e-01, _G4, 0.0, 0.0),
        (-9.0338057013044082e-01, 5.4180672388095326e-02, _G4, 0.0),
        (2.4212380706095346e-01, -1.2232505839045147e00, 5.4526025533510214e-01, _G4),
    ),
    (2.4212380706095346e-01, -1.2232505839045147e00, 1.5452602553351020e00, _G4),
)
"""Rang and Angermann (BIT 45, 2005): four stages, order 3 with any ``J`` (a W-method),
L-stable and stiffly accurate."""


@dataclass(frozen=True)
class ExplicitTableau:
    """An explicit Runge-Kutta method ``(a, b)`` for ``x' = f(x)`` (the inputs held):
    stages ``k_i = f(x + h sum_{j<i} a_ij k_j)``, step ``x_next = x + h sum_i b_i k_i``.

    Parameters
    ----------
    name : str
        Its name.
    order : int
        Its order.
    a : tuple of tuple of float
        Strictly lower triangular (s x s).
    b : tuple of float
        Weights (s,).
    stability_radius : float
        Radius of the largest half-disk of the left half-plane, centred at 0, inside its
        region of absolute stability ``|R(z)| <= 1`` (dimensionless): a step ``h`` is
        stable for every mode ``lambda`` with ``Re(lambda) <= 0`` and ``h |lambda|``
        below it.
    """

    name: str
    order: int
    a: tuple
    b: tuple
    stability_radius: float

    def stability_function(self, z) -> np.ndarray:
        """``R(z)``: one step of the method on ``x' = lambda x`` multiplies ``x`` by
        ``R(h lambda)``.

        Parameters
        ----------
        z : array_like, complex
            ``h lambda`` (dimensionless).
        """
        z = np.asarray(z, dtype=np.complex128)
        a, b = np.array(self.a, dtype=np.float64), np.array(self.b, dtype=np.float64)
        stages = []
        for i in range(len(b)):
            stages.append(1 + z * sum(a[i, j] * stages[j] for j in range(i)))
        return 1 + z * sum(b[i] * stages[i] for i in range(len(b)))


RK4 = ExplicitTableau(
    "RK4",
    4,
    ((0.0, 0.0, 0.0, 0.0), (0.5, 0.0, 0.0, 0.0), (0.0, 0.5, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0)),
    (1 / 6, 1 / 3, 1 / 3, 1 / 6),
    2.615,
)
"""The classical Runge-Kutta method of Kutta (1901): four stages, order 4, explicit: no
Jacobian and no linear solve, for robots whose fastest mode the step resolves. Its
``stability_radius``, 2.615, is where the boundary of ``|1 + z + z^2/2 + z^3/6 + z^4/24|
<= 1`` comes nearest to 0 in the left half-plane (at 122 deg from the positive real
axis; 2.785 on the negative real axis, 2.828 on the imaginary one)."""

METHODS = {t.name: t for t in (ROS2, ROS34PW2, RK4)}
"""The methods by name."""

DEFAULT_METHOD = "ROS34PW2"
"""The Rosenbrock-W method when ``method`` is not given: order 3 with the Jacobian of the
period's start; ROS2 (order 2) needs 64 steps per 20 ms for the error ROS34PW2 reaches
with 16 (docs/stepping.md), twice the right-hand sides."""

DEFAULT_SUBSTEPS = 16
"""Steps per period when ``substeps`` is not given, measured for a 20 ms period
(``benchmarks/bench_stepper.py``, docs/stepping.md): the paper's robot under random
pressure commands held 20 ms each over 2 s (the harshest input a policy gives) stays
within 1 mm (1 % of the tip's travel) of ``simulate`` at ``rtol = 1e-10``; 12 steps
give 2.2 mm, 8 give 6 mm (the error falls as ``substeps**-3``). A longer period needs
proportionally more: the default keeps this step, :data:`DEFAULT_STEP`."""

DEFAULT_STEP = 0.02 / DEFAULT_SUBSTEPS
"""The longest step [s] when ``substeps`` is not given (1.25 ms): ``substeps =
ceil(period / DEFAULT_STEP)``, 16 at 20 ms. With 16 steps at any period the error grew
with it: 3.4 mm (6 % of the travel) at 100 ms against 0.13 mm at 20 ms (the same robot
and inputs, a review's check)."""

DEFAULT_EXPLICIT_STEP = 0.02 / 6
"""The longest step [s] of the explicit RK4 when ``substeps`` is not given (3.3 ms, 6
steps per 20 ms), measured as :data:`DEFAULT_SUBSTEPS`: the paper's robot stays within
0.58 mm (0.6 % of the travel) of ``simulate`` over the 2 s of random pressures (0.21 mm
with 8 steps, 0.94 with 5; docs/stepping.md)."""


def default_substeps(period: float, method: str) -> int:
    """Steps per ``period`` [s] of ``method`` when ``substeps`` is not given: steps of
    at most :data:`DEFAULT_STEP`, or :data:`DEFAULT_EXPLICIT_STEP` for an explicit method.

    Parameters
    ----------
    period : float
        Control period [s].
    method : str
        A key of :data:`~softcurve.simulation.stepper.METHODS`.
    """
    explicit = isinstance(METHODS[method], ExplicitTableau)
    longest = DEFAULT_EXPLICIT_STEP if explicit else DEFAULT_STEP
    return max(1, math.ceil(period / longest - 1e-9))
