"""Quasi-static maps of an actuated robot: input sweeps.

An *input sweep* follows the equilibrium ``N(q) = H(q) u`` (plus any other load of
:class:`~softcurve.analysis.loads.StaticLoad`) along a path of actuator inputs ``u``
(pressures, tensions) by continuation: each point starts the equilibrium solver from the
previous one, so the branch is followed and its stability is tracked (compare the
paper's Fig. 3, which maps pressure to deformation through the fitted stiffness).
Inverse statics, the bounded inputs that put the tip closest to a target, is
:mod:`softcurve.analysis.inverse_statics`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from softcurve.analysis.loads import (
    rest_configuration,
)
from softcurve.analysis.statics import equilibrium
from softcurve.base.status import Result, Status
from softcurve.base.validation import ParameterError, real_array
from softcurve.description.actuator import Actuator
from softcurve.figures import plot_input_sweep


@dataclass(frozen=True, eq=False)
class InputSweep(Result):
    """Equilibria along a path of actuator inputs.

    Attributes
    ----------
    inputs : ndarray, shape (k, m)
        The path [the actuator's ``input_unit``, e.g. Pa].
    q : ndarray, shape (k, n)
        Equilibria [m, 1/m, 1/m].
    tip : ndarray, shape (k, 3)
        World tip positions [m].
    converged : ndarray, shape (k,), bool
        Whether each point met the solver's tolerance inside the model's and the
        actuator's domain (its equilibrium's ``success``).
    stability : tuple of str
        Classification of each point (see :mod:`softcurve.analysis.statics`).
    status : Status
        SUCCESS when every point converged, PARTIAL when some did not, else the first
        point's status (NOT_CONVERGED, or LEFT_DOMAIN when it lies outside the domain).
    message : str
        How many points failed, and the first.
    curvature : ndarray, shape (k, N)
        Bending curvature ``|kappa|`` [1/m] of each element along the path (0 for a
        rigid body).
    input_name, input_unit : str
        The actuator's :attr:`~softcurve.Actuator.input_name` and ``input_unit``, for
        labels (``"tensions"``, ``"N"``).
    """

    inputs: np.ndarray
    q: np.ndarray
    tip: np.ndarray
    converged: np.ndarray
    stability: tuple[str, ...]
    status: Status
    message: str
    curvature: np.ndarray
    input_name: str = "inputs"
    input_unit: str = ""

    def plot(self, ax=None, *, x=None, x_label: str | None = None):
        """Tip position and curvature along the sweep, points that are not stable marked.

        Parameters
        ----------
        ax : None or sequence of matplotlib.axes.Axes, shape (2,)
            Panels for the tip position and the curvature; None draws a new figure.
        x : array_like, shape (k,), optional
            The abscissa (default: the input that varies most, pressures in kPa).
        x_label : str, optional
            Label of the abscissa, with its unit (default: the input's, none for ``x``).

        Returns
        -------
        matplotlib.figure.Figure
            Write it with :func:`softcurve.figures.save_figure`.
        """
        return plot_input_sweep(self, ax, x=x, x_label=x_label)


def input_sweep(model, actuator: Actuator, inputs, *, q0=None, **loads) -> InputSweep:
    """Follow the equilibrium along a path of actuator ``inputs`` (k, m) by continuation.

    Parameters
    ----------
    model : Model
        The compiled model.
    actuator : Actuator
        The actuator the inputs drive.
    inputs : array_like, shape (k, m)
        Path of inputs [the actuator's ``input_unit``, e.g. Pa], within its bounds.
    q0 : array_like, shape (n,), optional
        Initial guess for the first point [m, 1/m, 1/m] (default: the rest
        configuration).
    **loads
        Further loads of :class:`~softcurve.analysis.loads.StaticLoad` (``gravity``,
        ``tip_force``...).
    """
    path = np.asarray(inputs, dtype=np.float64)
    if path.ndim != 2 or path.shape[1] != actuator.n_inputs:
        raise ParameterError(f"inputs must have shape (k, {actuator.n_inputs}), got {path.shape}")
    q = rest_configuration(model.robot) if q0 is None else real_array("q0", q0, (model.n,))
    qs, tips, converged, stability, failures = [], [], [], [], []
    for u in path:
        e = equilibrium(model, q, actuator=actuator, inputs=u, **loads)
        if e.success:
            q = e.q
        qs.append(e.q)
        tips.append(e.tip_position)
        converged.append(e.success)
        stability.append(e.stability)
        if not e.success:
            failures.append(e)
    converged = np.array(converged)
    failed = np.flatnonzero(~converged)
    if not failed.size:
        status, message = Status.SUCCESS, f"{len(path)} equilibria followed"
    else:
        # every point's state went through the domain check of equilibrium()
        left = all(e.status is Status.LEFT_DOMAIN for e in failures)
        status = Status.PARTIAL if failed.size < len(path) else failures[0].status
        what = "left the model's domain" if left else "failed"
        message = (
            f"{failed.size} of {len(path)} points {what} (first: point {failed[0]}, "
            f"{failures[0].status.value}: {failures[0].message})"
        )
    return InputSweep(
        inputs=path,
        q=np.array(qs),
        tip=np.array(tips),
        converged=converged,
        stability=tuple(stability),
        status=status,
        message=message,
        curvature=model.robot.bending_curvature(np.array(qs)),
        input_name=actuator.input_name,
        input_unit=actuator.input_unit,
    )
