"""Linearization of the loaded dynamics about any state: ``A``, ``B``, modes.

The loads of :class:`~softcurve.analysis.loads.StaticLoad` are part of the vector field,
so their configuration dependence (``H(q) u``, ``J(q)^T w``) enters ``A``. At an equilibrium the
undamped modes solve ``K v = w^2 D v`` with ``K`` the tangent stiffness of the loads.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from softcurve.analysis.loads import StaticLoad, linear_function
from softcurve.base.status import Result, Status
from softcurve.base.validation import ParameterError, real_array
from softcurve.figures import plot_eigenvalues
from softcurve.figures.shapes import result_figure_options

WITH_RESPECT_TO = ("tau", "actuator")
"""What ``B`` maps: generalized forces, or the actuator's inputs through ``H(q)``."""


@dataclass(frozen=True, eq=False)
class Linearization(Result):
    """``dx' = A dx + B dv`` about ``(x, v)``, and the modes of ``D v'' + K v = 0``.

    Attributes
    ----------
    x : ndarray, shape (n_state,)
        The state linearized about, ``(q, qd, lam)``.
    status : Status
        SUCCESS, or LEFT_DOMAIN when the derivatives are not finite there.
    message : str
        Whether the state is asymptotically stable, and the largest real part.
    A : ndarray, shape (n_state, n_state)
        Jacobian of the state derivative with respect to the state at ``(x, v)``.
    B : ndarray, shape (n_state, n) or (n_state, m)
        With respect to generalized forces (``wrt="tau"``) or to the actuator's inputs
        (``wrt="actuator"``, per unit of its ``input_unit``).
    wrt : str
        ``"tau"`` or ``"actuator"``.
    eigenvalues : ndarray, shape (n_state,), complex
        Of ``A``, ordered by real part (largest first): ``Re < 0`` everywhere is
        asymptotic stability.
    mass_matrix, stiffness : ndarray, shape (n, n)
        ``D(q)`` and the tangent stiffness ``K(q)`` of the loads.
    omega_squared : ndarray, shape (n,)
        Generalized eigenvalues of ``K v = w^2 D v`` [rad^2/s^2], ascending; a negative
        value is a divergent (statically unstable) mode.
    frequencies : ndarray, shape (n,)
        Undamped natural frequencies ``sqrt(|w^2|) / 2 pi`` [Hz]; see ``omega_squared``
        for their sign.
    modes : ndarray, shape (n, n)
        Mode shapes (columns, ``v^T D v = 1``), in the order of ``omega_squared``.
    """

    x: np.ndarray
    status: Status
    message: str
    A: np.ndarray
    B: np.ndarray
    wrt: str
    eigenvalues: np.ndarray
    mass_matrix: np.ndarray
    stiffness: np.ndarray
    omega_squared: np.ndarray
    frequencies: np.ndarray
    modes: np.ndarray

    @property
    def asymptotically_stable(self) -> bool:
        """Whether every eigenvalue of ``A`` has a negative real part."""
        return bool(np.all(self.eigenvalues.real < 0))

    @property
    def damping_ratios(self) -> np.ndarray:
        """``-Re(s) / |s|`` of each eigenvalue of ``A`` (1 for real negative ones)."""
        magnitude = np.abs(self.eigenvalues)
        ratio = np.ones_like(magnitude)
        nonzero = magnitude > 0
        ratio[nonzero] = -self.eigenvalues.real[nonzero] / magnitude[nonzero]
        return ratio

    @result_figure_options
    def plot(self, ax=None):
        """The eigenvalues of ``A`` in the complex plane [1/s], the stable half-plane
        ``Re(s) < 0`` shaded, those not in it in red.

        Parameters
        ----------
        ax : None or matplotlib.axes.Axes, shape (1,)
            Where to draw; None draws a new figure.

        """
        return plot_eigenvalues(self, ax)


def linearize(model, q, qd=None, lam=None, *, wrt: str = "tau", **loads) -> Linearization:
    """Linearize the loaded dynamics about the state ``(q, qd, lam)``.

    The loads (see :class:`~softcurve.analysis.loads.StaticLoad`) are part of the vector
    field, so their configuration dependence (``H(q) u``, ``J(q)^T w``) enters ``A``.
    Any state may be given; at an equilibrium with ``qd = 0`` the modes are the small
    oscillations.

    Parameters
    ----------
    model : Model
        The compiled model.
    q : array_like, shape (n,)
        Configuration [m, 1/m, 1/m].
    qd : array_like, shape (n,), optional
        Rates [m/s, 1/(m s), 1/(m s)]; default zero.
    lam : array_like, shape (n_creep,), optional
        Creep states; default zero.
    wrt : {"tau", "actuator"}
        What ``B`` maps: extra generalized forces, or extra actuator inputs through
        ``H(q)`` (needs ``actuator``).
    **loads
        ``tau``, ``actuator``, ``inputs`` (default: the actuator's rest inputs),
        ``tip_force``, ``tip_moment``, ``gravity``.

    Returns
    -------
    Linearization

    Examples
    --------
    >>> import numpy as np
    >>> import softcurve as sc
    >>> model = sc.Model(sc.presets.ifac2020())
    >>> e = sc.equilibrium(model, [0.0644, 0.0, 0.0])
    >>> lin = sc.linearize(model, e.q)
    >>> lin.success, lin.asymptotically_stable, lin.A.shape
    (True, True, (9, 9))
    >>> bool(np.all(lin.frequencies > 0))
    True
    """
    if wrt not in WITH_RESPECT_TO:
        raise ParameterError(f"wrt must be one of {WITH_RESPECT_TO}, got {wrt!r}")
    actuator = loads.get("actuator")
    if wrt == "actuator" and actuator is None:
        raise ParameterError("wrt='actuator' needs an actuator")
    if actuator is not None and loads.get("inputs") is None:
        loads["inputs"] = actuator.rest_inputs()
    load = StaticLoad(model, **loads)
    q = model.robot.check_configuration(real_array("q", q, (model.n,)), "q")
    qd = real_array("qd", np.zeros(model.n) if qd is None else qd, (model.n,))
    lam = real_array("lam", np.zeros(model.n_creep) if lam is None else lam, (model.n_creep,))
    x = np.concatenate([q, qd, lam])
    a, b, d, k = (
        np.array(v, dtype=np.float64)
        for v in linear_function(model, load.actuator)(x, *load.arguments())
    )
    if wrt == "actuator":
        b = b @ actuator.input_matrix(q)
    if not all(np.all(np.isfinite(v)) for v in (a, b, d, k)):
        return _not_finite(x, a, b, d, k, wrt)
    if load.conservative:  # K is a Hessian, symmetric up to rounding
        omega2, modes = scipy.linalg.eigh(0.5 * (k + k.T), d)
    else:
        values, modes = scipy.linalg.eig(k, d)
        order = np.argsort(values.real)
        omega2, modes = values.real[order], modes[:, order].real
        modes = modes / np.sqrt(np.einsum("ij,ik,kj->j", modes, d, modes))
    eigenvalues = np.linalg.eigvals(a)
    eigenvalues = eigenvalues[np.argsort(-eigenvalues.real, kind="stable")]
    largest = float(eigenvalues.real[0])
    stable = "asymptotically stable" if largest < 0 else "not asymptotically stable"
    return Linearization(
        x=x,
        status=Status.SUCCESS,
        message=f"{stable}: largest real part of an eigenvalue of A {largest:.4g} 1/s",
        A=a,
        B=b,
        wrt=wrt,
        eigenvalues=eigenvalues,
        mass_matrix=d,
        stiffness=k,
        omega_squared=omega2,
        frequencies=np.sqrt(np.abs(omega2)) / (2.0 * np.pi),
        modes=modes,
    )


def _not_finite(x, a, b, d, k, wrt) -> Linearization:
    n = d.shape[0]
    nan = np.full(n, np.nan)
    return Linearization(
        x=x,
        status=Status.LEFT_DOMAIN,
        message="the derivatives are not finite at this state (a length at or below zero?)",
        A=a,
        B=b,
        wrt=wrt,
        eigenvalues=np.full(a.shape[0], np.nan, dtype=complex),
        mass_matrix=d,
        stiffness=k,
        omega_squared=nan,
        frequencies=nan,
        modes=np.full((n, n), np.nan),
    )
