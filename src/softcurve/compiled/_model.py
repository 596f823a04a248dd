"""The compiled model: the physics of a robot, NumPy in, NumPy out.

:class:`Model` adds the equation of motion's terms, energies and poses to
:class:`~softcurve.compiled._functions.CompiledFunctions`, which compiles the robot's
CasADi Functions to C (through :mod:`softcurve.compiled._build` and its on-disk cache),
loads and calls them, and owns the per-model cache :meth:`Model.cached`.

Units, per segment: coordinates ``q = (l, kx, ky)`` [m, 1/m, 1/m], rates ``qd``
[m/s, 1/(m s), 1/(m s)], accelerations ``qdd`` [m/s^2, 1/(m s^2), 1/(m s^2)] and
generalized forces ``tau`` [N, N m^2, N m^2] (their products with ``qd`` are powers in W).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from softcurve.base.docs import shared_parameters
from softcurve.compiled._functions import CompiledFunctions


@dataclass(frozen=True)
class Pose:
    """A frame in the world frame; unpacks as ``rotation, position = pose``.

    Parameters
    ----------
    rotation : ndarray, shape (3, 3)
        Orientation: the frame's axes as columns, in world coordinates.
    position : ndarray, shape (3,)
        Origin [m] in world coordinates.
    """

    rotation: np.ndarray
    position: np.ndarray

    def __iter__(self):  # allows ``R, p = model.pose(q, s)``
        return iter((self.rotation, self.position))


@dataclass(frozen=True)
class DynamicsTerms:
    """The terms of ``D qdd + C qd + G + K + R qd = tau + K_c^T lam`` at one state.

    Parameters
    ----------
    mass_matrix : ndarray, shape (n, n)
        ``D(q)``, symmetric positive definite.
    coriolis_force : ndarray, shape (n,)
        ``C(q, qd) qd`` [N, N m^2, N m^2 per segment].
    gravity_force : ndarray, shape (n,)
        ``G(q) = dV_g/dq`` [N, N m^2, N m^2 per segment].
    elastic_force : ndarray, shape (n,)
        ``K(q) = dV_e/dq`` [N, N m^2, N m^2 per segment].
    damping_force : ndarray, shape (n,)
        ``R qd`` [N, N m^2, N m^2 per segment].
    creep_force : ndarray, shape (n,)
        ``K_c^T lam`` [N, N m^2, N m^2 per segment].
    contact_force : ndarray, shape (n,), optional
        Generalized contact force ``sum J^T F`` [N, N m^2, N m^2 per segment]; None
        for a model without environment.
    """

    mass_matrix: np.ndarray
    coriolis_force: np.ndarray
    gravity_force: np.ndarray
    elastic_force: np.ndarray
    damping_force: np.ndarray
    creep_force: np.ndarray
    contact_force: np.ndarray | None = None

    def inverse_dynamics(self, qdd) -> np.ndarray:
        """``tau`` that produces the accelerations ``qdd`` at this state.

        Parameters
        ----------
        qdd : array_like, shape (n,)
            Accelerations [m/s^2, 1/(m s^2), 1/(m s^2) per segment].
        """
        return (
            self.mass_matrix @ qdd
            + self.coriolis_force
            + self.gravity_force
            + self.elastic_force
            + self.damping_force
            - self.creep_force
            - (0.0 if self.contact_force is None else self.contact_force)
        )


@shared_parameters
class Model(CompiledFunctions):
    """The dynamics of a robot, compiled.

    Parameters
    ----------
    robot : Robot
        The robot description; its numbers are bound to every method below.
    environment : Environment, optional
        Obstacles and contact law (docs/contact.md); their forces enter every method
        below. Without it (default) the model is the free robot's.
    quadrature_nodes : int, optional
        Gauss-Legendre nodes per segment for the backbone integrals (default 11,
        round-off accuracy for bending angles up to pi per segment; see
        docs/model.md).
    compile : bool, optional
        Compile to C (default). With False, or when no C compiler works, the
        functions run in CasADi's virtual machine.

    Notes
    -----
    Every numeric method takes float64 arrays of shape ``(n,)`` for ``q``, ``qd``,
    ``qdd`` and ``tau`` (``n = 3 N``, units in the module docstring) and
    ``(n_creep,)`` for ``lam`` (omit it or pass None for zeros), and returns float64
    arrays. A ``q`` outside the model's domain raises :class:`ParameterError`
    (:meth:`Robot.check_configuration`); ``state_derivative`` and ``rhs`` do not check.

    Examples
    --------
    >>> import numpy as np
    >>> import softcurve as sc
    >>> model = sc.Model(sc.presets.ifac2020())  # compiled once, then loaded from disk
    >>> model.n, model.n_creep
    (3, 3)
    >>> q = np.array([0.064, 25.0, 0.0])  # length [m], curvatures kx, ky [1/m]
    >>> qd = np.array([0.0, 0.0, 1500.0])  # their rates
    >>> model.mass_matrix(q).shape
    (3, 3)
    >>> qdd = model.forward_dynamics(q, qd)  # creep states at zero
    >>> np.allclose(model.inverse_dynamics(q, qd, qdd), 0.0, atol=1e-9)
    True
    >>> model.tip_pose(q).position.round(4)  # [m]
    array([0.0412, 0.    , 0.04  ])
    """

    # -- dynamics ------------------------------------------------------------------
    def dynamics_terms(self, q, qd, lam=None) -> DynamicsTerms:
        """Every term of eq. (16) at one state, from one compiled evaluation.

        Parameters
        ----------
        q, qd : array_like, shape (n,)
            Coordinates and their rates.
        lam : array_like, shape (n_creep,), optional
            Creep states (default zeros).
        """
        values = self._call(
            "dynamics_terms",
            self.robot.check_configuration(q, "q"),
            self._vector("qd", qd, self.n),
            self._vector("lam", lam, self.n_creep),
        )
        return DynamicsTerms(*values)

    def mass_matrix(self, q) -> np.ndarray:
        """Inertia matrix ``D(q)``, shape (n, n), symmetric positive definite.

        Parameters
        ----------
        %(q)s
        """
        return self.dynamics_terms(q, np.zeros(self.n)).mass_matrix

    def coriolis_matrix(self, q, qd) -> np.ndarray:
        """``C(q, qd)`` with Christoffel symbols of ``D``, shape (n, n); ``Ddot - 2C`` is
        skew-symmetric. Evaluated in CasADi's virtual machine (analysis, not a hot path).

        Parameters
        ----------
        q, qd : array_like, shape (n,)
            Coordinates and their rates.
        """
        out = self.symbolic["coriolis_matrix"](
            self.robot.check_configuration(q, "q"), self._vector("qd", qd, self.n), self.parameters
        )
        return np.array(out, dtype=np.float64)

    def coriolis_force(self, q, qd) -> np.ndarray:
        """``C(q, qd) qd``, shape (n,).

        Parameters
        ----------
        q, qd : array_like, shape (n,)
            Coordinates and their rates.
        """
        return self.dynamics_terms(q, qd).coriolis_force

    def gravity_force(self, q) -> np.ndarray:
        """``dV_g/dq``, shape (n,).

        Parameters
        ----------
        %(q)s
        """
        return self.dynamics_terms(q, np.zeros(self.n)).gravity_force

    def elastic_force(self, q) -> np.ndarray:
        """``dV_e/dq``, shape (n,).

        Parameters
        ----------
        %(q)s
        """
        return self.dynamics_terms(q, np.zeros(self.n)).elastic_force

    def potential_force(self, q) -> np.ndarray:
        """``N(q) = dV/dq``, gravity plus elastic (minus the contact force at rest, the
        penalty's gradient, with an environment), shape (n,).

        Parameters
        ----------
        %(q)s
        """
        zero = np.zeros(self.n)  # at rest, without creep: inverse dynamics is G + K - Fc
        return self.dynamics_terms(q, zero).inverse_dynamics(zero)

    def potential_energy(self, q) -> float:
        """``V(q)`` [J], gravitational plus elastic (plus the penalty energy of the
        contact, with an environment).

        Parameters
        ----------
        %(q)s
        """
        parts = self._call("potential_energy", self.robot.check_configuration(q, "q"))
        return float(sum(part[0] for part in parts))

    def kinetic_energy(self, q, qd) -> float:
        """``T(q, qd) = qd' D(q) qd / 2`` [J].

        Parameters
        ----------
        q, qd : array_like, shape (n,)
            Coordinates and their rates.
        """
        qd = self._vector("qd", qd, self.n)
        return float(0.5 * qd @ self.mass_matrix(q) @ qd)

    def energy(self, q, qd) -> float:
        """Total mechanical energy ``T + V`` [J].

        Parameters
        ----------
        q, qd : array_like, shape (n,)
            Coordinates and their rates.
        """
        return self.kinetic_energy(q, qd) + self.potential_energy(q)

    def forward_dynamics(self, q, qd, tau=None, lam=None) -> np.ndarray:
        """Accelerations ``qdd`` solving eq. (16) for the given forces, shape (n,).

        Parameters
        ----------
        q, qd : array_like, shape (n,)
            Coordinates and their rates.
        tau : array_like, shape (n,), optional
            Generalized input forces (default zeros).
        lam : array_like, shape (n_creep,), optional
            Creep states (default zeros).
        """
        x = np.concatenate(
            [
                self.robot.check_configuration(q, "q"),
                self._vector("qd", qd, self.n),
                self._vector("lam", lam, self.n_creep),
            ]
        )
        return self.state_derivative(x, tau)[self.n : 2 * self.n]

    def inverse_dynamics(self, q, qd, qdd, lam=None) -> np.ndarray:
        """Generalized forces ``tau`` that produce ``qdd``, shape (n,).

        Parameters
        ----------
        q, qd, qdd : array_like, shape (n,)
            Coordinates, their rates and accelerations.
        lam : array_like, shape (n_creep,), optional
            Creep states (default zeros).
        """
        return self.dynamics_terms(q, qd, lam).inverse_dynamics(self._vector("qdd", qdd, self.n))

    def creep_rate(self, qd, lam) -> np.ndarray:
        """``lambda'`` of eq. (19), shape (n_creep,).

        Parameters
        ----------
        qd : array_like, shape (n,)
            Coordinate rates.
        lam : array_like, shape (n_creep,)
            Creep states.
        """
        return self._call(
            "creep_rate", self._vector("qd", qd, self.n), self._vector("lam", lam, self.n_creep)
        )[0]

    def state_derivative(self, x, tau=None) -> np.ndarray:
        """``xdot`` for the state ``x = (q, qd, lam)``, shape (n_state,).

        Parameters
        ----------
        x : array_like, shape (n_state,)
            State ``(q, qd, lam)``.
        tau : array_like, shape (n,), optional
            Generalized input forces (default zeros).
        """
        tau = np.zeros(self.n) if tau is None else self._vector("tau", tau, self.n)
        return self._call("rhs", self._vector("x", x, self.n_state), tau)[0]

    def rhs(self, tau=None):
        """A SciPy-style right-hand side ``f(t, x) -> xdot`` for constant ``tau``.

        Parameters
        ----------
        tau : array_like, shape (n,), optional
            Constant generalized input forces (default zero).
        """
        tau = np.zeros(self.n) if tau is None else self._vector("tau", tau, self.n)

        def f(t, x):
            return self._call("rhs", x, tau)[0]

        return f

    def casadi_rhs(self) -> ca.Function:
        """``rhs(x, tau, p) -> xdot`` as a symbolic CasADi Function, for optimal control."""
        return self.symbolic["rhs"]

    # -- kinematics ----------------------------------------------------------------
    def _s(self, s) -> float:
        s = float(s)
        if not 0.0 <= s <= 1.0:
            raise ValueError(f"s must be in [0, 1], got {s!r}")
        return s

    def pose(self, q, s) -> Pose:
        """World pose at material coordinate ``s`` of the whole robot.

        Segment ``i`` covers ``[i/N, (i+1)/N]``; ``s = 1`` is the tip.

        Parameters
        ----------
        %(q)s
        s : float
            Material coordinate in [0, 1], dimensionless.
        """
        rotation, position = self._call("pose", self.robot.check_configuration(q, "q"), self._s(s))
        return Pose(rotation, position)

    def tip_pose(self, q) -> Pose:
        """World pose of the tip (``s = 1``).

        Parameters
        ----------
        %(q)s
        """
        return self.pose(q, 1.0)

    def jacobian(self, q, s) -> np.ndarray:
        """Geometric Jacobian (6, n) at ``s``: rows 0-2 linear velocity, rows 3-5 angular
        velocity, both in the world frame, per unit ``qd``.

        Parameters
        ----------
        %(q)s
        s : float
            Material coordinate in [0, 1], dimensionless.
        """
        return self._call("jacobian", self.robot.check_configuration(q, "q"), self._s(s))[0]

    def body_twist(self, q, qd, s) -> np.ndarray:
        """Twist (6,) of the material point at ``s`` in its own frame: linear [m/s] then
        angular [rad/s].

        Parameters
        ----------
        q, qd : array_like, shape (n,)
            Coordinates and their rates.
        s : float
            Material coordinate in [0, 1], dimensionless.
        """
        q = self.robot.check_configuration(q, "q")
        rotation, _ = self.pose(q, s)
        twist = self.jacobian(q, s) @ self._vector("qd", qd, self.n)
        return np.concatenate([rotation.T @ twist[:3], rotation.T @ twist[3:]])

    def backbone(self, q, points: int = 50) -> np.ndarray:
        """Positions (points, 3) [m] along the backbone, from base to tip.

        Parameters
        ----------
        %(q)s
        points : int
            Number of points, >= 2, equally spaced in the material coordinate.
        """
        if not (isinstance(points, int | np.integer) and points >= 2):
            raise ValueError(f"points must be an integer >= 2, got {points!r}")
        q = self.robot.check_configuration(q, "q")
        return np.array([self.pose(q, s).position for s in np.linspace(0.0, 1.0, points)])
