"""Compiled functions evaluated along the members of a batch: one CasADi ``map`` over
members (split over threads) of a ``map`` over output times, in blocks of members that
bound the memory. Used by :func:`~softcurve.simulation.batch.simulate_batch` and its
:class:`~softcurve.simulation.results.BatchTrajectory`, and (:func:`mapped`) by the
planners' stages (:func:`~softcurve.control.optimize_trajectory`)."""

from __future__ import annotations

import casadi as ca
import numpy as np

from softcurve.base.docs import shared_parameters


@shared_parameters
def mapped(function: ca.Function, size: int, threads: int) -> ca.Function:
    """``function`` mapped over ``size`` calls, on ``threads`` threads.

    CasADi's own map over threads rather than :func:`softcurve.base.shares.run_shares`:
    the functions mapped here (CasADi's integrator of a batch on the route
    "casadi-cvodes", the tip, energy and right-hand side along a batch, a plan's stages
    and their derivatives) are CasADi Functions, evaluated inside CasADi, not foreign
    calls through ctypes; what threads of Python calls into CasADi would gain is not
    measured (``run_shares`` serves the ctypes calls of the C driver and the stepper).

    Parameters
    ----------
    function : casadi.Function
        One call.
    size : int
        Number of calls.
    %(threads)s
    """
    if size == 1:
        return function
    return function.map(size, "thread", threads) if threads > 1 else function.map(size)


BLOCK_DOUBLES = 1 << 22
"""Members per compiled call are limited so that one call's arrays hold about this many
doubles (32 MB): the transient copies CasADi and NumPy make stay small next to the result."""


def blocks(size: int, count: int, width: int, granularity: int = 1) -> list[slice]:
    """Consecutive member ranges of at most ``BLOCK_DOUBLES / (count * width)`` members,
    rounded down to a multiple of ``granularity`` (at least one such multiple).

    Parameters
    ----------
    size : int
        Number of members.
    count : int
        Number of time points per member.
    width : int
        Number of doubles per time point.
    granularity : int
        Members that must stay in one block together (the driver's groups).
    """
    step = min(size, BLOCK_DOUBLES // max(1, count * width))
    step = max(granularity, step - step % granularity)
    return [slice(a, min(size, a + step)) for a in range(0, size, step)]


def chunks(kinds: np.ndarray, granularity: int, count: int) -> list[np.ndarray]:
    """The members split into at most ``count`` chunks of whole runs: ``granularity``
    consecutive members of one kind (actuator), in the order of that kind's members, the
    last run of a kind shorter. The driver groups each kind's members in such runs, so a
    chunk integrated alone groups them as the whole batch does.

    Parameters
    ----------
    kinds : ndarray of int, shape (B,)
        Each member's kind: members of one kind are integrated together.
    granularity : int
        Members of one kind that stay together (the driver's groups).
    count : int
        Chunks wanted (at least 1).

    Returns
    -------
    list of ndarray of int
        Each chunk's member indices, ascending; the chunks are ordered by their first
        member.
    """
    runs = [
        members[a : a + granularity]
        for kind in np.unique(kinds)
        for members in [np.flatnonzero(kinds == kind)]
        for a in range(0, members.size, granularity)
    ]
    runs.sort(key=lambda run: run[0])
    edges = np.linspace(0, len(runs), min(count, len(runs)) + 1).astype(int)
    return [np.sort(np.concatenate(runs[a:b])) for a, b in zip(edges[:-1], edges[1:], strict=True)]


@shared_parameters
def along(model, name, build, columns, parameters, threads) -> list[np.ndarray]:
    """Evaluate ``build() -> Function(*per_point_inputs, p)`` at every (member, time):
    ``columns`` are (B, T, k) arrays, ``parameters`` (B, n_p); returns (B, T, m) arrays.

    Parameters
    ----------
    %(model)s
    name : str
        Cache key of the point function.
    build : callable
        ``build() -> casadi.Function(*per_point_inputs, p)``.
    columns : list of ndarray, shape (B, T, k)
        The per-point inputs.
    %(parameters)s
    %(threads)s
    """
    size, count = columns[0].shape[:2]
    point = model.cached(name, build)
    shared = [point.n_in() - 1]  # p: one per member, shared by its time points
    over_time = model.cached(
        (name, count), lambda: point.map(f"{name}_along", "serial", count, shared, [])
    )
    width = sum(c.shape[2] for c in columns) + point.nnz_out()
    pieces = []
    for block in blocks(size, count, width):
        members = block.stop - block.start
        function = mapped(over_time, members, threads)
        inputs = [np.ascontiguousarray(c[block].reshape(members * count, -1).T) for c in columns]
        outputs = function(*inputs, parameters[block].T)
        outputs = outputs if isinstance(outputs, tuple | list) else (outputs,)
        pieces.append([np.asarray(o).T.reshape(members, count, -1) for o in outputs])
    return [np.concatenate(parts) for parts in zip(*pieces, strict=True)]


@shared_parameters
def tip_along(model, q, parameters, threads) -> np.ndarray:
    """Tip positions [m] at coordinates ``q`` (B, T, n) of members with ``parameters``
    (B, n_p): (B, T, 3).

    Parameters
    ----------
    %(model)s
    q : ndarray, shape (B, T, n)
        Coordinates [m, 1/m, 1/m].
    %(parameters)s
    %(threads)s
    """

    def build():
        pose = model.function("pose")
        qs, p = ca.MX.sym("q", model.n), ca.MX.sym("p", model.parameters.size)
        return ca.Function("tip", [qs, p], [pose(qs, 1.0, p)[1]])

    return along(model, "tip", build, [q], parameters, threads)[0]


@shared_parameters
def energy_along(model, q, qd, parameters, threads) -> np.ndarray:
    """Mechanical energy [J] at ``q``, ``qd`` (B, T, n) of members with ``parameters``
    (B, n_p): (B, T).

    Parameters
    ----------
    %(model)s
    q : ndarray, shape (B, T, n)
        Coordinates [m, 1/m, 1/m].
    qd : ndarray, shape (B, T, n)
        Rates [m/s, 1/(m s), 1/(m s)].
    %(parameters)s
    %(threads)s
    """

    def build():
        terms, potential = (
            model.function("dynamics_terms"),
            model.function("potential_energy"),
        )
        qs, qds = ca.MX.sym("q", model.n), ca.MX.sym("qd", model.n)
        p = ca.MX.sym("p", model.parameters.size)
        mass = terms(qs, qds, ca.MX.zeros(model.n_creep), p)[0]
        parts = potential(qs, p)  # gravity, elastic (and penalty, with an environment)
        potential_energy = sum(parts) if isinstance(parts, list | tuple) else parts
        return ca.Function(
            "energy", [qs, qds, p], [0.5 * ca.dot(qds, mass @ qds) + potential_energy]
        )

    return along(model, "energy", build, [q, qd], parameters, threads)[0][..., 0]


@shared_parameters
def rhs_along(model, x, tau, parameters, threads) -> np.ndarray:
    """The state derivative at states ``x`` (B, K, n_state) with inputs ``tau`` (B, K, n).

    Parameters
    ----------
    %(model)s
    x : ndarray, shape (B, K, n_state)
        States.
    tau : ndarray, shape (B, K, n)
        Input forces [N, N m^2, N m^2].
    %(parameters)s
    %(threads)s
    """

    def build():
        rhs = model.function("rhs")
        xs, u = ca.MX.sym("x", model.n_state), ca.MX.sym("u", model.n)
        p = ca.MX.sym("p", model.parameters.size)
        return ca.Function("rhs_point", [xs, u, p], [rhs(xs, u, p)])

    return along(model, "rhs_point", build, [x, np.array(tau)], parameters, threads)[0]
