"""Entries of an experiment's initial state as named parameters, and the actuator lag.

A trajectory fit starts each experiment from ``x0 = (q, qd, lam)`` (coordinates, rates,
creep states) and, with an input lag, the actuator states ``u`` after it. Any entry can
be estimated by naming it in ``free`` (usually with ``per_experiment=True``):

- ``"x0.q[i]"``, ``"x0.qd[i]"``: coordinate ``i`` and its rate [m, 1/m, 1/m per s...];
- ``"x0.lam[i]"``: creep state ``i`` (same unit as the coordinate it creeps);
- ``"x0.u[i]"``: the lagged actuator input ``i`` at the first sample [unit of the
  input, e.g. Pa].

Its starting value is the entry of that experiment's ``x0`` (for ``x0.u``, the first
input sample: the actuator settled). The same names in ``extra`` set an entry without
fitting it, e.g. ``extra={"x0.lam[1][b42]": 0.2}`` for experiment ``b42``.

The *input lag* (``fit_trajectory(input_lag=...)``) passes every measured input through
a first-order lag ``u_a' = (u - u_a) / T`` before the input map; its time constant ``T``
[s] is the extra parameter :data:`LAG`, so it can be fitted like any other.
"""

from __future__ import annotations

import re

import casadi as ca
import numpy as np

from softcurve.base.validation import ParameterError

LAG = "input_lag"
"""Name of the extra parameter holding the input lag's time constant [s]."""

_ENTRY = re.compile(r"^x0\.(q|qd|lam|u)\[(\d+)\]$")


def is_state_entry(name: str) -> bool:
    """Whether ``name`` names an initial-state entry (``x0.q[i]``...).

    Parameters
    ----------
    name : str
        A parameter name.
    """
    return _ENTRY.match(name) is not None


def state_index(model, name: str, n_inputs: int) -> int:
    """Position of the entry ``name`` in the (augmented) initial state.

    Parameters
    ----------
    model : Model
        Gives ``n`` coordinates and ``n_state - 2 n`` creep states.
    name : str
        ``x0.q[i]``, ``x0.qd[i]``, ``x0.lam[i]`` or ``x0.u[i]``.
    n_inputs : int
        Lagged actuator states after the model's state (0 without an input lag).
    """
    kind, i = _ENTRY.match(name).groups()
    i = int(i)
    n, n_creep = model.n, model.n_state - 2 * model.n
    size = {"q": n, "qd": n, "lam": n_creep, "u": n_inputs}[kind]
    if i >= size:
        raise ParameterError(
            f"{name!r}: the state has {size} {kind} entries"
            + (" (the input lag is off: input_lag=None)" if kind == "u" and size == 0 else "")
        )
    return {"q": 0, "qd": n, "lam": 2 * n, "u": model.n_state}[kind] + i


def start_values(model, x0, first_input, names, lagged: bool) -> dict:
    """The starting value of every state entry in ``names`` for one experiment.

    Parameters
    ----------
    model : Model
        The model.
    x0 : array_like, shape (n_state,), or callable
        The experiment's initial state (a callable is evaluated at the nominal extras by
        the caller and must then be given as an array here).
    first_input : ndarray, shape (m,)
        The experiment's first input sample (initial lagged inputs).
    names : iterable of str
        Parameter names; those that are not state entries are ignored.
    lagged : bool
        Whether the inputs pass through the lag (``x0.u[i]`` allowed).
    """
    entries = [n for n in names if is_state_entry(n)]
    if not entries:
        return {}
    if callable(x0):
        raise ParameterError(f"{entries}: give x0 as an array (not a callable) to name its entries")
    state = np.concatenate([np.asarray(x0, dtype=np.float64).ravel(), first_input])
    m = first_input.size if lagged else 0
    return {n: float(state[state_index(model, n, m)]) for n in entries}


def initial_state(model, x0, values: dict, first_input, lagged: bool):
    """The initial state (MX) with every state entry named in ``values`` substituted.

    Parameters
    ----------
    model : Model
        The model.
    x0 : array_like, shape (n_state,), or callable
        The initial state ``(q, qd, lam)``, or ``x0(values)`` returning it.
    values : dict
        Extra parameters (CasADi expressions) by name.
    first_input : ndarray, shape (m,)
        First input sample: the lagged inputs' start unless named in ``values``.
    lagged : bool
        Whether to append the lagged inputs.
    """
    start = x0(values) if callable(x0) else ca.DM(np.asarray(x0, dtype=np.float64))
    start = ca.MX(start) if not isinstance(start, ca.MX) else start
    if start.shape != (model.n_state, 1):
        raise ParameterError(
            f"x0 must have {model.n_state} entries (q, qd, lam), got shape {start.shape}"
        )
    entries = ca.vertsplit(ca.vertcat(start, ca.MX(ca.DM(first_input))) if lagged else start)
    m = first_input.size if lagged else 0
    for name, value in values.items():
        if is_state_entry(name):
            entries[state_index(model, name, m)] = ca.MX(value)
    return ca.vertcat(*entries)
