"""The integration of a batch: one CVODES integrator on the compiled right-hand side,
mapped over members in compiled code (:class:`MemberRun`), failures isolated to their
members; and the per-member linearization that chooses Adams or BDF."""

from __future__ import annotations

import contextlib
import io
from dataclasses import replace

import numpy as np

from softcurve.base.status import Status
from softcurve.simulation.solvers import (
    DRIVER_FAMILIES,
    BufferedCall,
    RadauEngine,
    blocks,
    cvodes_integrator,
    cvodes_reason,
    domain_reason,
    driver_integrate,
    driver_reason,
    failure_message,
    failure_status,
    mapped,
    method_name,
    outside_domain,
    restart_segments,
)


class MemberRun:
    """One batch integration: the compiled map over members, with failures isolated.

    Parameters
    ----------
    problem : Problem
        The batch's integration (:class:`~softcurve.simulation.solvers.Problem`, forces:
        ``inputs`` None): model, grid, tolerances and step budget, and each member's state
        scale ``nominal`` (B, n_state [+ m]; with lagging inputs theirs after
        ``(q, qd, lam)``) and ``parameters`` (B, n_p). CasADi's options
        (:meth:`Problem.cvodes_options`) and the C driver's settings
        (:meth:`Problem.driver_options`) are both its own.
    threads : int
        Threads of the compiled map.
    tau : ndarray, shape (B, n) or (B, m)
        Constant input per member: the force [N, N m^2, N m^2], or with ``drives`` the
        actuator's inputs (commands when they lag) [their unit].
    states : ndarray, shape (B, T, n_state [+ m])
        Filled in place (NaN after a member's failure).
    rest_lengths : ndarray, shape (B, N)
        Rest length of each member's segments [m], for the domain check of the outputs.
    drives : Drives, optional
        The actuator of each member (``softcurve.simulation.batch._inputs``): each group's
        problem is ``problem`` with the group's ``inputs``; the members integrated in one
        call share one.

    Notes
    -----
    Every member is a row of the one problem, but the batch is no loop around one
    member's solver (:func:`~softcurve.simulation.solvers.solver` per member): on the C
    route (:func:`integrate_native`) all members go to the driver in one call, on
    threads that do not contend (it reads no clock), in groups of four on the state
    derivative over vector lanes, which share CVODES's work per step. Measured by
    ``python benchmarks/bench_batch.py --size 64 --loop 8 --repeat 2`` (paper case, 10 s,
    2 cores), simulated s per wall s: a loop of ``simulate()`` 2,808; the members alone
    in one call 3,282 on 1 thread (the loop without Python between members) and 5,680 on
    2; in groups of four 7,076 on 1 thread and 10,544 on 2 (3.8x the loop); CasADi's
    mapped integrator (:meth:`integrate`, the route without the driver) 1,891 on 2.
    ``docs/performance.md`` has the 200-member batch (groups 2.3-2.4x the members alone).
    """

    def __init__(self, problem, threads, tau, states, rest_lengths, drives=None):
        self.problem, self.threads, self.tau, self.states = problem, threads, tau, states
        self.rest_lengths, self.drives = rest_lengths, drives
        self.model, self.grid = problem.model, problem.grid
        self.params, self.nominal = problem.member_parameters, problem.member_nominal
        self.problems = [problem] if drives is None else [
            replace(problem, inputs=inputs) for inputs in drives.inputs]  # fmt: skip
        size = states.shape[0]
        self.reached = np.full(size, self.grid.size)
        self.status = np.full(size, Status.SUCCESS, dtype=object)
        self.messages = [""] * size

    def _p(self, members, h) -> np.ndarray:
        count = len(members)
        return np.hstack([self.params[members], np.full((count, 1), h), self.nominal[members]]).T

    def group_problem(self, member: int):
        """The :class:`~softcurve.simulation.solvers.Problem` of ``member``'s actuator group
        (the batch's own when forces drive it).

        Parameters
        ----------
        member : int
            The member's index in the batch.
        """
        return self.problems[0 if self.drives is None else self.drives.group[member]]

    def _mapped_integrator(self, multistep, tout, count, problem):
        """The integrator of ``problem`` (a group's) mapped over ``count`` members, cached
        with the model."""
        threads = min(self.threads, count)
        options, drive = problem.cvodes_options(multistep), problem.inputs
        key = ("batch", tuple(sorted(options.items())), tout.tobytes(), count, threads,
               None if drive is None else drive.key)  # fmt: skip

        def build():
            integrator = cvodes_integrator(self.model, tout, options, drive)
            return BufferedCall(mapped(integrator, count, threads))

        return self.model.cached(key, build)

    def integrate(self, multistep, members, k0, k1) -> None:
        """Fill ``states[members, k0+1 : k1+1]`` from ``states[members, k0]``; a failing map
        is split in halves until the failing members are found, which are then integrated
        output by output."""
        grid, states = self.grid[k0 : k1 + 1], self.states
        h = grid[-1] - grid[0]
        tout = (grid[1:] - grid[0]) / h
        count, outputs = len(members), tout.size
        problem = self.group_problem(int(members[0]))
        # column-major CasADi matrices: one member's (or one output's) column after another
        x0 = np.ascontiguousarray(states[members, k0] / self.nominal[members])
        p = np.ascontiguousarray(self._p(members, h).T)
        u = np.repeat(self.tau[members], outputs, axis=0)
        xf = np.zeros((count, outputs, states.shape[2]))
        # on a failure, CasADi's map prints every input of the batch to sys.stderr; the
        # reason is kept from the member integrated alone (below)
        with contextlib.redirect_stderr(io.StringIO()):
            integrator = self._mapped_integrator(multistep, tout, count, problem)
            failure, _ = integrator({0: x0, 2: p, 3: u}, xf)
        if failure is not None:
            if count > 1:
                half = count // 2
                for part in (members[:half], members[half:]):
                    self.integrate(multistep, part, k0, k1)
            else:
                self._one_by_one(multistep, int(members[0]), k0, k1)
            return
        states[members, k0 + 1 : k1 + 1] = xf * self.nominal[members, None, :]
        rest = self.rest_lengths[members]
        bad = outside_domain(states[members, k0 + 1 : k1 + 1], self.model.robot, rest[:, None, :])
        for j in np.flatnonzero(np.any(bad, axis=1)):
            self._outside(int(members[j]), k0 + 1 + int(np.argmax(bad[j])), multistep)

    def _one_by_one(self, multistep, b, k0, k1) -> None:
        """Output interval by output interval, to keep every output reached before a failure."""
        integrator = self._mapped_integrator(multistep, np.ones(1), 1, self.group_problem(b))
        nominal, states = self.nominal[b], self.states
        for k in range(k0 + 1, k1 + 1):
            h = self.grid[k] - self.grid[k - 1]
            x0 = np.ascontiguousarray(states[b, k - 1] / nominal)
            p = np.ascontiguousarray(self._p([b], h).T)
            xf = np.zeros(states.shape[2])
            u = np.ascontiguousarray(self.tau[b])
            failure, _ = integrator({0: x0, 2: p, 3: u}, xf)
            if failure is not None:
                self._fail(b, k, cvodes_reason(failure), multistep)
                return
            states[b, k] = xf * nominal
            if outside_domain(states[b, k], self.model.robot, self.rest_lengths[b]):
                self._outside(b, k, multistep)
                return

    def _outside(self, b, k, multistep) -> None:
        """Member ``b`` left the model's domain at output ``k``."""
        robot = self.model.robot
        reason = domain_reason(self.states[b, k], robot, self.grid[k], self.rest_lengths[b])
        self._fail(b, k, reason, multistep)

    def _fail(self, b, k, reason, multistep) -> None:
        """Member ``b`` failed reaching output ``k``: keep outputs ``0 .. k-1``."""
        self.states[b, k:] = np.nan
        self.reached[b] = k
        self.status[b] = failure_status(reason)
        self.messages[b] = failure_message(reason, self.grid, k, method_name(multistep))


def integrate_native(run: MemberRun, initial, fastest, problems) -> np.ndarray:
    """The whole batch of ``run`` with the C driver (CVODES, or Radau IIA;
    ``softcurve.simulation.solvers._driver``): one call per group of members that
    share an actuator, every restart segment inside it, members on ``run.threads``
    threads. Fills ``run.states`` and the failures as
    :meth:`MemberRun.integrate` does; returns which members used BDF.

    Parameters
    ----------
    run : MemberRun
        The batch (its states hold the initial states).
    initial : ndarray of str, shape (B,)
        Each member's family, "adams", "bdf" or "radau".
    fastest : ndarray, shape (B,) or None
        Fastest rate of each member's initial linearization [1/s]: members that start with
        Adams switch to BDF at a restart once settled (None: no switch).
    problems : list
        The driver's problem of each actuator group (the ``built`` of its route,
        :func:`~softcurve.simulation.solvers.choose_route`): with lanes, consecutive
        members are integrated in groups on the state derivative over lanes
        (the driver's ``groups.c``).
    """
    grid, states = run.grid, run.states
    segments = restart_segments(grid)
    ends = [k1 for _, k1 in segments]
    restart = [True] * len(ends)
    used_bdf = np.zeros(states.shape[0], bool)
    lmm = np.array([DRIVER_FAMILIES[family] for family in initial], dtype=np.int32)
    settle = np.zeros(states.shape[0]) if fastest is None else np.where(lmm == 1, fastest, 0.0)
    settings = run.problem.driver_options()
    for g, problem in enumerate(problems):
        group = np.arange(states.shape[0]) if run.drives is None else (
            np.flatnonzero(run.drives.group == g))  # fmt: skip
        for block in blocks(group.size, grid.size, states.shape[2], problem.width):
            members = group[block]
            u = np.repeat(run.tau[members][:, None, :], len(ends), axis=1)
            out, reached, flags, _, used = driver_integrate(
                problem, lmm[members], states[members, 0], u, run.params[members],
                run.nominal[members], grid, (ends, restart), settings, fastest=settle[members],
                check_domain=True, threads=run.threads,
            )  # fmt: skip
            used_bdf[members] = used
            states[members, 1:] = out[:, 1:]
            for j in np.flatnonzero(flags):
                b, done = int(members[j]), int(reached[j])
                if flags[j] == 1:
                    run._outside(b, done - 1, "adams+bdf" if used[j] else initial[b])
                elif initial[b] == "radau":
                    run._fail(b, done, RadauEngine.failure_reason(flags[j]), "radau")
                else:
                    reason = cvodes_reason(driver_reason(flags[j]))
                    run._fail(b, done, reason, "adams+bdf" if used[j] else initial[b])
    return used_bdf
