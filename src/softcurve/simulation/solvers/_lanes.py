"""The state derivative over lanes for CVODES's driver: the members of a batch
integrated in groups (``groups.c`` of
``softcurve.simulation.solvers._library.C_FOLDER``) evaluate it
``softcurve.compiled._lanes.LANE_WIDTH`` at a time.

The function is the one the scalar driver evaluates (the model's ``rhs`` with the
actuator's force and lag, :func:`~softcurve.simulation.solvers.actuated_derivative`),
generated over lanes by ``softcurve.compiled._lanes`` with every input per member
(members of a batch may have their own parameters).
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass
from functools import partial

from softcurve.compiled import (
    LANE_WIDTH,
    c_template,
    compile_lanes,
    lanes_function,
    lanes_prelude,
    lanes_work,
)
from softcurve.simulation.solvers._actuated import actuated_derivative

ENTRY = "softcurve_lanes_xdot"
"""The C entry point: ``(x, u, p, xdot, w) -> 0``, every array lanes-interleaved (entry
``j`` of member ``l`` at ``[j * width + l]``) and aligned to 64 bytes."""


def xdot_source(f, vector_math: bool) -> str:
    """The C source of :data:`ENTRY`: the state derivative ``f`` over lanes.

    Parameters
    ----------
    f : casadi.Function
        ``(x, u, p) -> xdot`` as an SX function
        (:func:`~softcurve.simulation.solvers.actuated_derivative`, expanded).
    vector_math : bool
        Use glibc's vector math library where compiled for AVX2
        (:func:`~softcurve.compiled.lanes_prelude`).

    Returns
    -------
    str
        The C source.

    Raises
    ------
    NotImplementedError
        If ``f`` has an operation without lanes code.
    """
    return "\n".join(
        [
            lanes_prelude(LANE_WIDTH, vector_math),
            lanes_function(f, "sc_xdot", (False, False, False)),
            c_template("lanes_xdot.c", {"SC_ENTRY": ENTRY}),
        ]
    )


@dataclass(frozen=True)
class LanesDerivative:
    """A compiled :func:`xdot_source`.

    Parameters
    ----------
    entry : ctypes function
        :data:`ENTRY` (kept so that its library stays loaded).
    width : int
        Members per call.
    work : int
        Rows of ``width`` doubles of the work array ``w``.
    vector_math : bool
        Whether it was linked with glibc's vector math library.
    """

    entry: object
    width: int
    work: int
    vector_math: bool

    @property
    def address(self) -> int:
        """The entry's address, for the driver's function table."""
        return ctypes.cast(self.entry, ctypes.c_void_p).value


def lanes_derivative(model, inputs=None) -> LanesDerivative | None:
    """The compiled state derivative over lanes, kept with the model (and cached on disk).

    Parameters
    ----------
    model : Model
        The compiled model.
    inputs : ActuatorInput, optional
        The actuator's inputs (None: generalized forces).

    Returns
    -------
    LanesDerivative or None
        None where no C compiler builds it or the model has an operation without lanes
        code (the driver then integrates every member alone).
    """

    def build():
        f = actuated_derivative(model, inputs, model.symbolic["rhs"]).expand()
        built = compile_lanes("driver_lanes", partial(xdot_source, f), ENTRY, [ctypes.c_void_p] * 5)
        if built is None:
            return None
        return LanesDerivative(built.entry, LANE_WIDTH, lanes_work(f), built.vector_math)

    return model.cached(("driver-lanes", None if inputs is None else inputs.key), build)
