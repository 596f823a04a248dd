"""Linearisation of the loaded dynamics about any state: ``A``, ``B``, modes.

The loads of :class:`~softcurve.loads.StaticLoad` are part of the vector field, so their
configuration dependence (``H(q) p``, ``J(q)^T w``) enters ``A``. At an equilibrium the
undamped modes solve ``K v = w^2 D v`` with ``K`` the tangent stiffness of the loads.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from softcurve.analysis.loads import StaticLoad, linear_function
from softcurve.base.validation import ParameterError, real_array


@dataclass(frozen=True, eq=False)
class Linearization:
    """``dx' = A dx + B du`` about ``(x, u)``, and the modes of ``D v'' + K v = 0``.

    Attributes
    ----------
    x : ndarray, shape (n_state,)
        The state linearised about, ``(q, qd, lam)``.
    A : ndarray, shape (n_state, n_state)
    B : ndarray, shape (n_state, n_u)
        Input ``"tau"`` (generalized forces) or ``"pressures"`` [Pa], see ``inputs``.
    inputs : str
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
    A: np.ndarray
    B: np.ndarray
    inputs: str
    eigenvalues: np.ndarray
    mass_matrix: np.ndarray
    stiffness: np.ndarray
    omega_squared: np.ndarray
    frequencies: np.ndarray
    modes: np.ndarray

    @property
    def asymptotically_stable(self) -> bool:
        return bool(np.all(self.eigenvalues.real < 0))

    @property
    def damping_ratios(self) -> np.ndarray:
        """``-Re(s) / |s|`` of each eigenvalue of ``A`` (1 for real negative ones)."""
        magnitude = np.abs(self.eigenvalues)
        ratio = np.ones_like(magnitude)
        nonzero = magnitude > 0
        ratio[nonzero] = -self.eigenvalues.real[nonzero] / magnitude[nonzero]
        return ratio


def linearize(model, q, qd=None, lam=None, *, inputs: str = "tau", **loads) -> Linearization:
    """Linearise the loaded dynamics about the state ``(q, qd, lam)``.

    The loads (see :class:`StaticLoad`) are part of the vector field, so their
    configuration dependence (``H(q) p``, ``J(q)^T w``) enters ``A``. Any state may be
    given; at an equilibrium with ``qd = 0`` the modes are the small oscillations.

    Parameters
    ----------
    model : Model
    q, qd, lam : array_like
        The state; ``qd`` and ``lam`` default to zeros.
    inputs : {"tau", "pressures"}
        What ``B`` maps: extra generalized forces, or extra pressures through
        ``H(q)`` (needs ``actuator``).
    **loads
        ``tau``, ``actuator``, ``pressures``, ``tip_force``, ``tip_moment``, ``gravity``.
    """
    if inputs not in ("tau", "pressures"):
        raise ParameterError(f"inputs must be 'tau' or 'pressures', got {inputs!r}")
    actuator = loads.get("actuator")
    if inputs == "pressures" and actuator is None:
        raise ParameterError("inputs='pressures' needs an actuator")
    if actuator is not None and loads.get("pressures") is None:
        loads["pressures"] = np.clip(np.zeros(actuator.n_inputs), actuator.lower, actuator.upper)
    load = StaticLoad(model, **loads)
    q = real_array("q", q, (model.n,))
    qd = real_array("qd", np.zeros(model.n) if qd is None else qd, (model.n,))
    lam = real_array("lam", np.zeros(model.n_creep) if lam is None else lam, (model.n_creep,))
    x = np.concatenate([q, qd, lam])
    a, b, d, k = (
        np.array(v, dtype=np.float64)
        for v in linear_function(model, load.actuator)(x, *load.arguments())
    )
    if inputs == "pressures":
        b = b @ actuator.input_matrix(q)
    if load.conservative:  # K is a Hessian, symmetric up to rounding
        omega2, modes = scipy.linalg.eigh(0.5 * (k + k.T), d)
    else:
        values, modes = scipy.linalg.eig(k, d)
        order = np.argsort(values.real)
        omega2, modes = values.real[order], modes[:, order].real
        modes = modes / np.sqrt(np.einsum("ij,ik,kj->j", modes, d, modes))
    eigenvalues = np.linalg.eigvals(a)
    eigenvalues = eigenvalues[np.argsort(-eigenvalues.real, kind="stable")]
    return Linearization(
        x=x,
        A=a,
        B=b,
        inputs=inputs,
        eigenvalues=eigenvalues,
        mass_matrix=d,
        stiffness=k,
        omega_squared=omega2,
        frequencies=np.sqrt(np.abs(omega2)) / (2.0 * np.pi),
        modes=modes,
    )
