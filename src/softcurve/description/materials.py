"""Material models of section 3 of the paper: hyper-elastic stiffness laws and creep.

A stiffness law ``k(x)`` maps a generalized strain ``x`` (elongation ``eps = l - l0``
in m, or bending angle ``beta = kappa * l`` in rad) to a stiffness (N/m or N m/rad);
the generalized elastic force is ``k(x) x`` and the stored energy
``int_0^x k(t) t dt``. Laws are even in ``x``, so the symbolic forms here take the
squared strain ``z = x**2``: that keeps the bending force smooth at zero curvature,
where ``beta = l * sqrt(kx**2 + ky**2)`` is not. Nothing here knows about geometry.

Each law is an immutable value validated at construction. Its numbers enter the
compiled model as run-time parameters (``parameters()``), so that one compiled
library serves every robot of the same structure and gradients with respect to the
material are available for identification.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from softcurve.base import smooth as _smooth
from softcurve.base.docs import parameters_from
from softcurve.base.validation import ParameterError, real_array, real_scalar

_LAW_PARAMETERS = {
    "x": ("float or array_like", "Strain: elongation ``l - l0`` [m] or bending angle [rad]."),
    "z": ("casadi.SX or float", "Squared strain [m^2 or rad^2]."),
    "p": (
        "casadi.SX, shape (n_parameters,)",
        "The law's parameters, in the order of :meth:`parameters`.",
    ),
}


@parameters_from(_LAW_PARAMETERS)
class _StiffnessLaw:
    """The interface of every stiffness law; a law supplies the formulas ``_stiffness(x)``
    on a float64 array and the symbolic ``_coefficient(z, p)`` and ``_energy(z, p)``."""

    def stiffness(self, x):
        """``k(x)`` for a float or array ``x``.

        Parameters
        ----------
        %(x)s
        """
        return self._stiffness(np.asarray(x, dtype=np.float64))

    def force(self, x):
        """Generalized elastic force ``k(x) x`` [N or N m].

        Parameters
        ----------
        %(x)s
        """
        return self.stiffness(x) * np.asarray(x, dtype=np.float64)

    @classmethod
    def coefficient(cls, z, p):
        """Symbolic ``k(sqrt(z))``, smooth at ``z = 0``.

        Parameters
        ----------
        %(z)s
        %(p)s
        """
        return cls._coefficient(z, p)

    @classmethod
    def energy(cls, z, p):
        """Symbolic ``int_0^sqrt(z) k(t) t dt`` [J], smooth at ``z = 0``.

        Parameters
        ----------
        %(z)s
        %(p)s
        """
        return cls._energy(z, p)


@dataclass(frozen=True)
class LinearStiffness(_StiffnessLaw):
    """Hookean law ``k(x) = k0``.

    Parameters
    ----------
    k0 : float
        Stiffness, > 0 ([N/m] for elongation, [N m/rad] for bending).
    """

    k0: float
    kind: ClassVar[str] = "linear"
    n_parameters: ClassVar[int] = 1
    parameter_labels: ClassVar[tuple[str, ...]] = ("k0",)
    parameter_quantities: ClassVar[tuple[str, ...]] = ("stiffness",)

    def __post_init__(self):
        object.__setattr__(self, "k0", real_scalar("k0", self.k0, positive=True))

    def parameters(self) -> tuple[float, ...]:
        """The law's numbers as they enter the parameter vector: ``(k0,)``."""
        return (self.k0,)

    def _stiffness(self, x):
        return np.full_like(x, self.k0)

    @staticmethod
    def _coefficient(z, p):
        return p[0] + 0 * z

    @staticmethod
    def _energy(z, p):
        return 0.5 * p[0] * z


@dataclass(frozen=True)
class TanhStiffness(_StiffnessLaw):
    """The paper's hyper-elastic ansatz, eqs. (17)-(18): ``k(x) = a1 + a2 (tanh(a3 x)**2 - 1)``.

    ``k`` runs from ``a1 - a2`` at ``x = 0`` to ``a1`` as ``|x| -> inf``; with ``a2 > 0`` it
    stiffens with strain (strain hardening). It is positive for every ``x`` if and only
    if ``a1 > 0`` and ``a1 > a2`` (the paper's ``alpha_1 > alpha_2``). The sign of ``a3``
    does not matter; ``a3 = 0`` is the linear law ``a1 - a2`` and must be written as
    :class:`LinearStiffness`.

    Parameters
    ----------
    a1 : float
        Stiffness at large strain, > 0 ([N/m] for elongation, [N m/rad] for bending).
    a2 : float
        Softening at zero strain, < a1 ([N/m] or [N m/rad], as ``a1``).
    a3 : float
        Inverse strain scale of the transition ([1/m] or [1/rad]), nonzero.

    Examples
    --------
    >>> law = TanhStiffness(2.23e3, 1.74e3, -4.55e2)  # the paper's elongation law
    >>> float(law.stiffness(0.0))  # a1 - a2 [N/m]
    490.0
    >>> float(law.force(0.01))  # [N]
    22.29...
    """

    a1: float
    a2: float
    a3: float
    kind: ClassVar[str] = "tanh"
    n_parameters: ClassVar[int] = 3
    parameter_labels: ClassVar[tuple[str, ...]] = ("a1", "a2", "a3")
    parameter_quantities: ClassVar[tuple[str, ...]] = ("stiffness", "stiffness", "1/strain")

    def __post_init__(self):
        a1 = real_scalar("a1", self.a1, positive=True)
        a2 = real_scalar("a2", self.a2)
        a3 = real_scalar("a3", self.a3, nonzero=True)
        if not a1 > a2:
            raise ParameterError(
                f"a2 must be < a1 so that k(x) = a1 + a2 (tanh(a3 x)^2 - 1) > 0 for every x, "
                f"got a1={a1!r}, a2={a2!r}"
            )
        for name, value in (("a1", a1), ("a2", a2), ("a3", a3)):
            object.__setattr__(self, name, value)

    def parameters(self) -> tuple[float, ...]:
        """The law's numbers as they enter the parameter vector: ``(a1, a2, a3)``."""
        return (self.a1, self.a2, self.a3)

    def _stiffness(self, x):
        return self.a1 + self.a2 * (np.tanh(self.a3 * x) ** 2 - 1.0)

    @staticmethod
    def _coefficient(z, p):
        a1, a2, a3 = p[0], p[1], p[2]
        return a1 - a2 + a2 * _smooth.tanh_squared(a3**2 * z)

    @staticmethod
    def _energy(z, p):
        # int_0^y t tanh(c t)^2 dt = y^2/2 + (log cosh(c y) - c y tanh(c y)) / c^2
        a1, a2, a3 = p[0], p[1], p[2]
        w = a3**2 * z
        return 0.5 * a1 * z + a2 * (_smooth.log_cosh(w) - _smooth.y_tanh(w)) / a3**2


STIFFNESS_LAWS = {law.kind: law for law in (LinearStiffness, TanhStiffness)}
"""Stiffness laws by their ``kind`` name, as used in configuration files."""

LAW_UNITS = {
    "elongation_stiffness": {"strain": "m", "force": "N", "stiffness": "N/m", "1/strain": "1/m"},
    "bending_stiffness": {
        "strain": "rad", "force": "N m", "stiffness": "N m/rad", "1/strain": "1/rad"
    },
}  # fmt: skip
"""The units of a law's strain, its force ``k(x) x`` and each quantity of its
parameters (``parameter_quantities``), by the strain it acts on: the elongation
``l - l0`` [m] or the bending angle [rad]."""


PASSIVITY_TOLERANCE = 1e-12
"""Relative tolerance of the passivity test of :class:`Creep`: ``P = K G^-1`` counts as
symmetric when ``|P - P^T| <= PASSIVITY_TOLERANCE * max |P|``, and a matrix as positive
semidefinite when its smallest eigenvalue is ``>= -PASSIVITY_TOLERANCE`` times its
largest magnitude. A ``K`` computed as ``P G`` from a symmetric ``P`` differs from
symmetry by a few units of round-off (1e-16), far inside; a real violation is of the
order of the entries themselves."""


def passivity_problem(rate, gain, compliance) -> str | None:
    """Why creep with these numbers is not passive (see :class:`Creep`), or None.

    Parameters
    ----------
    rate : ndarray, shape (3,)
        Decay rates [1/s], > 0.
    gain : ndarray, shape (3,)
        Couplings to the coordinate rates.
    compliance : ndarray, shape (3, 3)
        ``K``.
    """
    driven = gain != 0
    for j in np.flatnonzero(~driven):
        pushing = np.flatnonzero(driven & (compliance[:, j] != 0))
        if pushing.size:
            i = int(pushing[0])
            return (
                f"creep state {i} (gain {gain[i]:.6g}) pushes coordinate {j} through "
                f"compliance[{i}, {j}] = {compliance[i, j]:.6g}, but gain[{j}] = 0: that "
                "coordinate's motion never charges it"
            )
    p = compliance[np.ix_(driven, driven)] / gain[driven]
    if p.size == 0:
        return None
    size = np.max(np.abs(p))
    if np.max(np.abs(p - p.T), initial=0.0) > PASSIVITY_TOLERANCE * size:
        return f"P = K G^-1 = {p.tolist()} is not symmetric"
    p = 0.5 * (p + p.T)
    r = np.diag(rate[driven])
    for label, matrix in (("P = K G^-1", p), ("P R + R P", p @ r + r @ p)):
        eigenvalues = np.linalg.eigvalsh(matrix)
        if eigenvalues[0] < -PASSIVITY_TOLERANCE * np.max(np.abs(eigenvalues)):
            return f"{label} has the negative eigenvalue {eigenvalues[0]:.6g}"
    return None


@dataclass(frozen=True, eq=False)
class Creep:
    """Kelvin-Voigt creep of one segment, eq. (19) of the paper.

    ``lambda_i' = -rate_i lambda_i - gain_i qd_i`` and the creep force on the
    segment's coordinates is ``K^T lambda``.

    Creep must be passive: it may store the energy the robot's motion puts into it and
    give it back, never create energy. With ``R = diag(rate)``, ``G = diag(gain)`` and
    ``K = compliance``, take the storage ``S = lambda^T P lambda / 2``. Along any motion
    ``dS/dt = -lambda^T P R lambda - lambda^T P G qd``, and the creep force delivers the
    power ``qd^T K^T lambda = lambda^T K qd`` to the robot. The two cross terms cancel
    exactly when ``P G = K``, that is ``P = K G^-1``, and then

    ``d(E + S)/dt = -lambda^T P R lambda - qd^T R_damping qd + qd^T tau``,

    so the robot's energy ``E`` plus ``S`` never grows without input work if and only
    if ``S >= 0`` and ``-lambda^T P R lambda <= 0`` for every ``lambda``: ``P``
    symmetric positive semidefinite and ``P R + R P`` positive semidefinite (the
    Kalman-Yakubovich-Popov conditions for this storage; ``P`` is the only
    candidate, as ``P G = K`` fixes it). Construction raises :class:`ParameterError`
    otherwise, stating this rule. For a diagonal ``K`` the rule reads
    ``compliance_i / gain_i >= 0``: a negative compliance with a positive gain makes
    the robot active. A semidefinite ``P`` is allowed: a creep state whose row of
    ``K`` is zero exerts no force and stores nothing (the zero-compliance creep of an
    energy test).

    A zero gain ``gain_j = 0`` leaves creep state ``j`` undriven: it decays from its
    initial value, ``lambda_j(t) = lambda_j(0) exp(-rate_j t)``, whatever the robot does.
    Its force ``K[j]^T lambda_j`` is then a load given in advance, like ``tau``: it is
    zero from the default ``lam0 = 0`` (so a zero gain switches that creep mode off, as
    the validation example does), and from a nonzero ``lam0_j`` it does the work of a
    relaxing pre-stress, counted as input work, not created by the motion. So undriven
    states are accepted with any row of ``K``; the rule applies to the driven states
    (``gain != 0``): ``P G = K`` restricted to their rows needs ``K[i, j] = 0`` for
    driven ``i`` and undriven ``j`` (a driven state pushing a coordinate that does not
    charge it would create energy), and ``P = K_dd G_d^-1`` on the driven block must
    pass both tests. The symmetry and eigenvalue tests are relative to
    ``PASSIVITY_TOLERANCE``.

    Parameters
    ----------
    rate : array_like, shape (k,)
        Decay rates ``(gamma_1, gamma_3, gamma_5)`` [1/s], each > 0: one per coordinate of
        the segment it acts on (three for a constant-curvature segment, one per chosen
        strain for a :class:`~softcurve.StrainSegment`).
    gain : array_like, shape (k,)
        Couplings to the coordinate rates ``(gamma_2, gamma_4, gamma_6)``
        [creep-state unit per coordinate unit].
    compliance : array_like, shape (k, k) or (k,)
        ``K``, mapping creep states to generalized forces; a vector is a diagonal.
    """

    rate: np.ndarray
    gain: np.ndarray
    compliance: np.ndarray

    def __post_init__(self):
        shapes = [np.shape(v) for v in (self.rate, self.gain, self.compliance)]
        size = shapes[1][0] if len(shapes[1]) == 1 and shapes[1][0] > 0 else 3
        if shapes[0] != (size,):
            raise ParameterError(
                f"creep.rate must have shape (k,), with gain (k,) and compliance (k, k) or "
                f"(k,) of one size k (the segment's coordinates): got rate {shapes[0]}, "
                f"gain {shapes[1]}, compliance {shapes[2]}"
            )
        rate = real_array("creep.rate", self.rate, (size,))
        if not np.all(rate > 0):
            raise ParameterError(f"creep.rate must be > 0 in every entry, got {rate.tolist()}")
        compliance = np.asarray(self.compliance, dtype=np.float64)
        if compliance.shape == (size,):
            compliance = np.diag(compliance)
        object.__setattr__(self, "rate", rate)
        object.__setattr__(self, "gain", real_array("creep.gain", self.gain, (size,)))
        compliance = real_array("creep.compliance", compliance, (size, size))
        object.__setattr__(self, "compliance", compliance)
        problem = passivity_problem(rate, self.gain, self.compliance)
        if problem is not None:
            raise ParameterError(
                f"creep makes the robot active (it can create energy): {problem}. Rule: with "
                "R = diag(rate), G = diag(gain), K = compliance, P = K G^-1 must be symmetric "
                "positive semidefinite and P R + R P positive semidefinite (for a diagonal K: "
                "compliance_i / gain_i >= 0), on the states with gain != 0; K[i, j] = 0 where "
                "gain_i != 0 and gain_j = 0"
            )

    @property
    def size(self) -> int:
        """Number of creep states ``k``."""
        return self.rate.shape[0]

    @classmethod
    def from_gamma(cls, gamma, compliance) -> Creep:
        """Build from the paper's ``gamma = (gamma_1, ..., gamma_6)`` and ``K``.

        Parameters
        ----------
        gamma : array_like, shape (6,)
            ``(rate_1, gain_1, rate_2, gain_2, rate_3, gain_3)``, interleaved as in the
            paper's eq. (19).
        compliance : array_like, shape (3, 3) or (3,)
            ``K``; a vector is a diagonal.
        """
        gamma = real_array("creep.gamma", gamma, (6,))
        return cls(rate=gamma[0::2], gain=gamma[1::2], compliance=compliance)

    def parameters(self) -> tuple[float, ...]:
        """The numbers as they enter the parameter vector: rate, gain, compliance (row major)."""
        return (*self.rate, *self.gain, *self.compliance.ravel())

    @property
    def n_parameters(self) -> int:
        """Number of its numbers in the parameter vector, ``2 k + k^2``."""
        return self.size * (self.size + 2)
