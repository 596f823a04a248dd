"""Radau IIA of order 5: the L-stable one-step method of the C driver (``c/radau.c``) and
its engine on the route ``"driver-radau"``.

The method's constants are derived here from their definition, not typed in: the three
nodes are the zeros of the Radau polynomial ``d^2/dx^2 [x^2 (x - 1)^3]``, the matrix ``A``
satisfies the collocation conditions ``sum_j a_ij c_j^(k-1) = c_i^k / k``, and the
transformation ``T`` that splits the Newton iteration into one real and one complex system
is made of the eigenvectors of ``A^-1`` (Hairer and Wanner, Solving Ordinary Differential
Equations II, Sect. IV.8). ``tests/test_radau.py`` checks them against their defining
conditions and the published values.

Why Radau IIA: its stability function vanishes at infinity (L-stable) and it has order 5
at every stiffness, so its steps follow the accuracy the outputs need, where CVODES's
multistep methods of order above two are held by the stability of lightly damped fast
modes (``benchmarks/study_implicit_steps.py``; ``docs/performance.md``). Being one-step,
it restarts at a change of the input without a new order ramp.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.polynomial import polynomial as P

from softcurve.simulation.solvers import _driver as c_driver
from softcurve.simulation.solvers._cvodes import CvodesEngine
from softcurve.simulation.solvers._policy import TOO_MUCH_WORK

STAGES = 3
"""Stages of the method (order ``2 STAGES - 1 = 5``)."""

REASONS = {
    "CV_TOO_MUCH_WORK": TOO_MUCH_WORK,
    "CV_ERR_FAILURE": "the error test failed repeatedly (step size became too small)",
    "CV_CONV_FAILURE": "the Newton iteration failed repeatedly (step size became too small)",
    "CV_LSETUP_FAIL": "the Newton matrix's Jacobian failed, or its matrices stayed singular "
    "down to the smallest step size",
    "CV_RHSFUNC_FAIL": "the right-hand side failed (non-finite values)",
    "CV_FIRST_RHSFUNC_ERR": "the right-hand side failed (non-finite values) at a start",
}
"""What the driver's Radau IIA reports under each CVODES flag name (``radau.c`` returns the
flag of the same meaning)."""


@dataclass(frozen=True)
class RadauTableau:
    """The constants of Radau IIA with :data:`STAGES` stages.

    Parameters
    ----------
    nodes : ndarray, shape (3,)
        ``c``: the stages' times in the step, fractions of it; the last is 1.
    matrix : ndarray, shape (3, 3)
        ``A``: stage ``i`` is ``y + h sum_j a_ij f(Y_j)``.
    transform : ndarray, shape (3, 3)
        ``T``, with ``T^-1 A^-1 T = [[gamma, 0, 0], [0, alpha, -beta], [0, beta, alpha]]``.
    gamma, alpha, beta : float
        The real eigenvalue of ``A^-1`` and the complex pair ``alpha +- i beta``.
    error : ndarray, shape (3,)
        ``E``: the error estimate is ``(gamma / h - J)^-1 (f(y) + sum_i E_i Z_i / h)``
        for the stage increments ``Z_i = Y_i - y`` (the embedded formula of order 3 with
        weight ``1 / gamma`` on ``f(y)``).
    dense : ndarray, shape (3, 3)
        ``P``: the collocation polynomial is ``y + sum_k x^(k+1) sum_i P[k, i] Z_i`` at
        ``t + x h``.
    """

    nodes: np.ndarray
    matrix: np.ndarray
    transform: np.ndarray
    gamma: float
    alpha: float
    beta: float
    error: np.ndarray
    dense: np.ndarray

    @property
    def inverse_transform(self) -> np.ndarray:
        """``T^-1``, shape (3, 3)."""
        return np.linalg.inv(self.transform)

    @property
    def weights(self) -> np.ndarray:
        """``b``, the last row of ``A`` (the method is stiffly accurate), shape (3,)."""
        return self.matrix[-1]


def radau_tableau() -> RadauTableau:
    """Radau IIA's constants, derived from the collocation conditions (module notes).

    Returns
    -------
    RadauTableau
    """
    s = STAGES
    radau_polynomial = P.polymul(P.polypow([0.0, 1.0], s - 1), P.polypow([-1.0, 1.0], s))
    nodes = np.sort(P.polyroots(P.polyder(radau_polynomial, s - 1)).real)
    nodes[-1] = 1.0  # the zero at 1 exactly, as the method's last stage is the step's end
    k = np.arange(1, s + 1)
    powers = nodes[:, None] ** (k - 1)  # [j, k] = c_j^(k-1)
    matrix = np.linalg.solve(powers.T, (nodes[:, None] ** k / k).T).T
    eigenvalues, vectors = np.linalg.eig(np.linalg.inv(matrix))
    real = int(np.argmin(np.abs(eigenvalues.imag)))
    pair = int(np.argmin(eigenvalues.imag))  # alpha - i beta: its vector u gives the block
    u = vectors[:, pair]
    transform = np.column_stack([vectors[:, real].real, u.real, u.imag])
    gamma = float(eigenvalues[real].real)
    # the embedded formula: weight 1 / gamma on f(y) and b_hat on the stages, of order 3
    b_hat = np.linalg.solve(powers.T, 1.0 / k - (k == 1) / gamma)
    error = gamma * np.linalg.solve(matrix.T, b_hat - matrix[-1])
    dense = np.linalg.inv(nodes[:, None] ** k)
    return RadauTableau(
        nodes=nodes, matrix=matrix, transform=transform, gamma=gamma,
        alpha=float(eigenvalues[pair].real), beta=float(-eigenvalues[pair].imag),
        error=error, dense=dense,
    )  # fmt: skip


def radau_constants() -> np.ndarray:
    """The constants in the layout the driver reads (``RADAU_*`` of
    ``softcurve_driver.h``), read-only; one array per process, which every call of the
    driver points to.

    Returns
    -------
    ndarray, shape (RADAU_CONSTANTS,)
    """
    return _CONSTANTS


def _layout() -> np.ndarray:
    tableau, at = radau_tableau(), c_driver.DECLARATIONS.constants
    out = np.empty(at["RADAU_CONSTANTS"])
    for name, value in (
        ("C", tableau.nodes), ("T", tableau.transform), ("TI", tableau.inverse_transform),
        ("GAMMA", tableau.gamma), ("ALPHA", tableau.alpha), ("BETA", tableau.beta),
        ("E", tableau.error), ("P", tableau.dense),
    ):  # fmt: skip
        flat = np.ravel(value)  # row-major
        out[at[f"RADAU_{name}"] : at[f"RADAU_{name}"] + flat.size] = flat
    out.flags.writeable = False
    return out


_CONSTANTS = _layout()


class RadauEngine(CvodesEngine):
    """Radau IIA of order 5 in the C driver (``c/radau.c``): error-controlled, with dense
    output, its Newton matrices factored once per step size and Jacobian and kept while
    the iteration converges, the Jacobian exact or by forward differences
    (``SimulationSettings.jacobian``).

    Parameters
    ----------
    problem : Problem
        The integration (:class:`~softcurve.simulation.solvers.Problem`).
    multistep : str, optional
        Unused: the argument every solver of ``METHODS`` takes.
    native : DriverProblem
        The driver's problem (:func:`~softcurve.simulation.solvers.choose_route`).
    """

    name = "radau"

    def __init__(self, problem, multistep=None, native=None):
        if native is None:
            raise ValueError("Radau IIA runs in the C driver: give its problem (native)")
        super().__init__(problem, "radau", native)
        self.route = "driver-radau"

    @property
    def method(self) -> str:
        """``"radau"``."""
        return "radau"

    def use(self, multistep: str) -> None:
        """One method throughout: a multistep family asked for is ignored."""
        self.multistep = "radau"

    @staticmethod
    def failure_reason(flag: int) -> str:
        """The driver's failure ``flag`` in a sentence.

        Parameters
        ----------
        flag : int
            A negative flag of the driver's Radau IIA (a CVODES flag of the same meaning).
        """
        name = c_driver.reason(flag)
        return f"Radau IIA {name}: {REASONS[name]}" if name in REASONS else f"Radau IIA: {name}"
